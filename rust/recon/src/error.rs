//! Why a reconstruction stopped: one error type for the runner, wrapping each stage's own.

use std::path::PathBuf;

use hairrecon_core::formats::FormatError;
use thiserror::Error;

use crate::config::{ConfigError, Stage};
use crate::dr::DrError;
use crate::hull::HullError;
use crate::orient2d::Orient2dError;
use crate::parting::PartingError;
use crate::points3d::PointsError;
use crate::progress::Cancelled;
use crate::roots::ScalpError;

/// Why a reconstruction stopped.
#[derive(Debug, Error)]
pub enum ReconError {
    /// The user cancelled the run; nothing of the unfinished stage was written.
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
    /// A file could not be read or written.
    #[error(transparent)]
    Format(#[from] FormatError),
    #[error(transparent)]
    Capture(hairrecon_core::capture::CaptureError),
    /// An image or orientation map could not be read or written.
    #[error(transparent)]
    Orient2d(#[from] Orient2dError),
    /// Oriented points could not be saved or loaded.
    #[error(transparent)]
    Points(#[from] PointsError),
    /// The configuration is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The output folder cannot be created.
    #[error("cannot create the output folder {path}: {source}")]
    OutDir { path: PathBuf, source: std::io::Error },
    /// The output folder holds files that are not a hairrecon run's (no `report.json`).
    #[error(
        "the output folder {path} holds files that are not a hairrecon run's ({found}); choose a new or empty folder, \
         or pass --overwrite (Python: overwrite=True) to write the run beside them"
    )]
    ForeignOutDir { path: PathBuf, found: String },
    /// `--from` on a folder that holds a run of another capture.
    #[error(
        "--from {from}: {path} holds a run of the capture {theirs}, not of {ours}; resuming would mix the two. Run \
         the whole pipeline (no --from), or give another --out"
    )]
    OtherCapture { path: PathBuf, theirs: PathBuf, ours: PathBuf, from: Stage },
    /// Another run (another process, or another job of this one) is writing into the output folder.
    #[error(
        "another hairrecon run is writing into {path} now; two runs in one folder would mix their files: wait \
         for it to finish (or cancel it), or give another --out"
    )]
    Busy { path: PathBuf },
    /// A file in the output folder cannot be written or removed.
    #[error("cannot write {path}: {source}")]
    Write { path: PathBuf, source: std::io::Error },
    /// `--from STAGE` needs an output that an earlier stage did not leave in the folder.
    #[error(
        "--from {from}: {path} is missing; it is written by the {needs} stage, so run from there (--from {needs}) \
         or the whole pipeline"
    )]
    MissingStageOutput { from: Stage, needs: Stage, path: PathBuf },
    /// A file an earlier stage saved cannot be read back.
    #[error("{path} cannot be read back: {msg}; run the stage that writes it again (--from {stage})")]
    StageFile { stage: Stage, path: PathBuf, msg: String },
    /// `--from` lies after `--stop-after`.
    #[error("--from {from} comes after --stop-after {stop}: nothing to run")]
    EmptyPlan { from: Stage, stop: Stage },
    /// The capture is not in the canonical frame in metres (an imported capture), and no head fit
    /// has placed it yet.
    #[error(
        "the capture {dir} is in an imported frame (frame {frame:?}, units {units:?}) that no head fit has placed \
         yet; the reconstruction works in metres with Z up and the face toward -Y. Run `hairrecon fit-head {dir} \
         --write` first (it adds the fitted head, the scalp and \"to_canonical\" to capture.json)"
    )]
    NotCanonical { dir: PathBuf, frame: String, units: String },
    /// A mesh or the cameras cannot be of a head in metres ([`crate::preflight`]).
    #[error("{what}: {msg}")]
    Implausible { what: String, msg: String },
    /// A stage made nothing to work on, so the later stages cannot run.
    #[error("the {stage} stage found {what}: {cause}")]
    EmptyStage { stage: Stage, what: &'static str, cause: &'static str },
    /// A stage's strands cannot be hair ([`crate::stages::sanity`]).
    #[error("the {stage} stage made degenerate {msg}")]
    Degenerate { stage: Stage, msg: String },
    /// The head fit (stage `head`) failed.
    #[error("the head fit: {0}")]
    HeadFit(String),
    /// The masks (stage `masks`) could not be made.
    #[error("the hair masks: {0}")]
    Masks(String),
    /// The capture has no scalp mesh.
    #[error("the capture {dir} has no scalp mesh; add \"scalp_mesh\" to its capture.json")]
    NoScalp { dir: PathBuf },
    /// The scalp mesh is unusable.
    #[error("the scalp mesh {path} cannot be used: {source}")]
    Scalp { path: PathBuf, source: ScalpError },
    /// The DR stage failed.
    #[error("strand optimization (DR): {0}")]
    Dr(DrError),
    /// The visual hull failed.
    #[error("the visual hull: {0}")]
    Hull(HullError),
    /// The partings stage failed.
    #[error("the partings (--no-parting skips them): {0}")]
    Parting(PartingError),
    /// The curl grids would be far too large for a head.
    #[error(
        "the curl stage's grids would exceed 64 million cells: the raw mesh or the points span far more than a \
         head (check the raw mesh's units, metres expected), or run with --curl off"
    )]
    CurlGrid,
    /// Strands that a stage made (e.g. the curled ones) are invalid.
    #[error("strands: {0}")]
    Strands(#[from] hairrecon_core::strands::StrandError),
}

impl From<HullError> for ReconError {
    fn from(e: HullError) -> Self {
        match e {
            HullError::Cancelled(c) => ReconError::Cancelled(c),
            e => ReconError::Hull(e),
        }
    }
}

impl From<PartingError> for ReconError {
    fn from(e: PartingError) -> Self {
        match e {
            PartingError::Cancelled(c) => ReconError::Cancelled(c),
            e => ReconError::Parting(e),
        }
    }
}

impl From<DrError> for ReconError {
    fn from(e: DrError) -> Self {
        match e {
            DrError::Cancelled(c) => ReconError::Cancelled(c),
            e => ReconError::Dr(e),
        }
    }
}
