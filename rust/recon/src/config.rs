//! One configuration for a whole reconstruction: every stage's parameters, defaults resolved,
//! written as `OUT/config.json` by every run and read back by `hairrecon reconstruct --config`.
//!
//! The CLI, the Python module and the Blender add-on all build a [`ReconstructConfig`]; the
//! runner ([`crate::runner`]) hands each stage its own part. [`ConfigFile`] adds the version and
//! the git commit that wrote it, so a run's folder says what made it. JSON numbers round-trip `f32`
//! exactly (shortest representation), so a replayed config gives the same bytes.

use std::path::{Path, PathBuf};
use std::str::FromStr;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::curl::{CurlMode, CurlOptions};
use crate::direction::DirectionParams;
use crate::dr::DrOptions;
use crate::grow::GrowParams;
use crate::hull::HullParams;
use crate::laplace::LaplaceParams;
use crate::masks::MaskOptions;
use crate::orient2d::GaborParams;
use crate::parting::PartingParams;
use crate::points3d::LineMvsParams;

/// The hairrecon version that this library is.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
/// The git commit this library was built from (`unknown` outside a git checkout).
pub const GIT_COMMIT: &str = env!("HAIRRECON_GIT_COMMIT");

/// The stages of a reconstruction, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Stage {
    /// The head fit ([`crate::head_fit`]): the frame, the head and the scalp, for a capture that
    /// lacks them.
    Head,
    /// Hair masks ([`crate::masks`]) for the views that have none.
    Masks,
    /// 2D orientation maps by a Gabor filter bank ([`crate::orient2d`]).
    Orient2d,
    /// Oriented 3D points by line MVS on the raw mesh ([`crate::points3d`]).
    Orient3d,
    /// Partings: the scalp's skin that the views see ([`crate::parting`]).
    Partings,
    /// The points' root-to-tip directions ([`crate::direction`]).
    Direction,
    /// Roots, flow, growth, curls, children, the visual hull's trim: the initial strands.
    Init,
    /// Strand optimization by differentiable rendering ([`crate::dr`]).
    Dr,
}

impl Stage {
    /// Every stage in order.
    pub const ALL: [Stage; 8] = [
        Stage::Head,
        Stage::Masks,
        Stage::Orient2d,
        Stage::Orient3d,
        Stage::Partings,
        Stage::Direction,
        Stage::Init,
        Stage::Dr,
    ];

    /// The first stage.
    pub const FIRST: Stage = Stage::Head;

    pub fn name(self) -> &'static str {
        match self {
            Stage::Head => "head",
            Stage::Masks => "masks",
            Stage::Orient2d => "orient2d",
            Stage::Orient3d => "orient3d",
            Stage::Partings => "partings",
            Stage::Direction => "direction",
            Stage::Init => "init",
            Stage::Dr => "dr",
        }
    }
}

/// Which stages a run makes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Plan {
    /// The first stage run; the earlier ones are reloaded from the output folder.
    pub from: Stage,
    /// The last stage run (`None`: all; without DR in the config, init is the last).
    pub stop_after: Option<Stage>,
    /// Write into a folder that holds files other than a hairrecon run's (`--overwrite`): by
    /// default such a folder is refused ([`crate::runner`]).
    pub overwrite: bool,
}

impl Default for Plan {
    fn default() -> Self {
        Self { from: Stage::FIRST, stop_after: None, overwrite: false }
    }
}

/// A stage name that is not one of [`Stage::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("stage {0:?} is unknown; use one of head, masks, orient2d, orient3d, partings, direction, init, dr")]
pub struct UnknownStage(pub String);

impl FromStr for Stage {
    type Err = UnknownStage;
    fn from_str(s: &str) -> Result<Self, UnknownStage> {
        Stage::ALL.into_iter().find(|st| st.name() == s.to_ascii_lowercase()).ok_or_else(|| UnknownStage(s.into()))
    }
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.name())
    }
}

/// Every parameter of a reconstruction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReconstructConfig {
    /// Guide strands (grown through the flow, optimized first by DR).
    pub guides: usize,
    /// Child strands (blended from their nearest guides).
    pub children: usize,
    /// Global direction optimization (false: the gravity heuristic, "w/o global opt.").
    pub global_opt: bool,
    /// Strand initialization by the Laplace flow (false: straight strands along the normal,
    /// "w/o strand init.").
    pub strand_init: bool,
    /// Seed of every random choice.
    pub seed: u64,
    pub gabor: GaborParams,
    /// A mask pixel is hair when its value (coverage in [0, 1]) is at least this.
    pub mask_threshold: f32,
    pub mvs: LineMvsParams,
    pub direction: DirectionParams,
    pub laplace: LaplaceParams,
    pub grow: GrowParams,
    /// Length of the straight strands of the `strand_init = false` ablation, metres.
    pub straight_length: f32,
    /// Write `orient2d/<view>.png` pictures besides the maps.
    pub write_pictures: bool,
    /// Optimize the strands by differentiable rendering after init (false: the initial strands
    /// are the result).
    pub dr: bool,
    pub dr_options: DrOptions,
    /// When the init carries curls, DR keeps their shape ([`DrOptions::keeping_curls`]); false
    /// optimizes them with `dr_options` as they are.
    pub dr_keep_curls: bool,
    /// Cut the children before DR where a view sees no hair ([`crate::hull`]).
    pub hull_trim: bool,
    pub hull: HullParams,
    /// Partings ([`crate::parting`]; `enabled = false` skips them).
    pub parting: PartingParams,
    /// Curls ([`crate::curl`]): `Auto` lets the images decide ([`crate::curl_choice`]).
    pub curl: CurlMode,
    pub curl_options: CurlOptions,
    /// The head fit of a capture without a scalp, a head or a frame (stage `head`).
    pub head_fit: HeadFitParams,
    /// Make hair masks for the views that have none (stage `masks`); false runs such views with
    /// every pixel counted as hair, as a warning says.
    pub make_masks: bool,
    pub masks: MaskOptions,
}

/// The head fit's part of the configuration ([`crate::head_fit::FitOptions`] has the rest, at
/// its defaults).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HeadFitParams {
    /// Use the cameras (they surround the head and stand upright) in the coarse search.
    pub use_cameras: bool,
    /// Fail when more than this fraction of the template's skin lies outside the raw mesh.
    pub max_exposed_fraction: f64,
    /// Fit the subject's head shape after the similarity ([`crate::head_fit::nonrigid`]). A
    /// config.json written before the option existed has none and replays without it.
    #[serde(default)]
    pub shape: bool,
}

impl Default for HeadFitParams {
    fn default() -> Self {
        Self {
            use_cameras: true,
            max_exposed_fraction: crate::head_fit::FitOptions::default().max_exposed_fraction,
            shape: true,
        }
    }
}

impl Default for ReconstructConfig {
    fn default() -> Self {
        Self {
            guides: 2000,
            children: 50000,
            global_opt: true,
            strand_init: true,
            seed: 0,
            gabor: GaborParams::default(),
            mask_threshold: 0.1,
            mvs: LineMvsParams::default(),
            direction: DirectionParams::default(),
            laplace: LaplaceParams::default(),
            grow: GrowParams::default(),
            straight_length: 0.1,
            write_pictures: true,
            dr: true,
            dr_options: DrOptions::default(),
            dr_keep_curls: true,
            hull_trim: true,
            hull: HullParams::default(),
            parting: PartingParams::default(),
            curl: CurlMode::Auto,
            curl_options: CurlOptions::default(),
            head_fit: HeadFitParams::default(),
            make_masks: true,
            masks: MaskOptions::default(),
        }
    }
}

/// Why a configuration cannot be used.
#[derive(Debug, Error)]
pub enum ConfigError {
    /// The config file cannot be read or written.
    #[error("cannot {action} the config file {path}: {source}")]
    Io { action: &'static str, path: PathBuf, source: std::io::Error },
    /// The config file is not a hairrecon config (JSON with the fields of [`ReconstructConfig`]).
    #[error("{path} is not a hairrecon config: {msg} (write one with `hairrecon reconstruct --print-config`)")]
    Parse { path: PathBuf, msg: String },
    /// A value is out of its range.
    #[error("config: {0}")]
    Invalid(String),
}

impl ReconstructConfig {
    /// Checks the values a stage would otherwise trip on.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.guides == 0 || self.children == 0 {
            return Err(ConfigError::Invalid("guides and children must be at least 1".into()));
        }
        if !(self.mask_threshold.is_finite() && (0.0..=1.0).contains(&self.mask_threshold)) {
            return Err(ConfigError::Invalid(format!("mask_threshold {} is not in [0, 1]", self.mask_threshold)));
        }
        if !(self.grow.step.is_finite() && self.grow.step > 0.0) {
            return Err(ConfigError::Invalid(format!("grow.step {} must be positive", self.grow.step)));
        }
        if !(self.straight_length.is_finite() && self.straight_length > 0.0) {
            return Err(ConfigError::Invalid(format!("straight_length {} must be positive", self.straight_length)));
        }
        if let CurlMode::Fixed(c) | CurlMode::Fine(c) = self.curl {
            c.validate().map_err(|e| ConfigError::Invalid(e.to_string()))?;
        }
        Ok(())
    }
}

/// `OUT/config.json`: the configuration with the version and commit that wrote it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConfigFile {
    pub hairrecon_version: String,
    pub git_commit: String,
    pub config: ReconstructConfig,
}

impl ConfigFile {
    /// This build's version and commit around `config`.
    pub fn new(config: ReconstructConfig) -> Self {
        Self { hairrecon_version: VERSION.into(), git_commit: GIT_COMMIT.into(), config }
    }

    /// Writes the file atomically (a temporary file, then a rename).
    pub fn save(&self, path: &Path) -> Result<(), ConfigError> {
        let text = serde_json::to_string_pretty(self).map_err(|e| ConfigError::Invalid(e.to_string()))?;
        hairrecon_core::formats::atomic_write(path, |w| Ok(std::io::Write::write_all(w, text.as_bytes())?)).map_err(
            |e| ConfigError::Io { action: "write", path: path.into(), source: std::io::Error::other(e.to_string()) },
        )
    }

    /// Reads a file written by [`ConfigFile::save`]; a bare [`ReconstructConfig`] object is
    /// accepted too. Missing fields take their defaults; unknown ones are an error.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            action: "read",
            path: path.into(),
            source,
        })?;
        let value: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| ConfigError::Parse { path: path.into(), msg: e.to_string() })?;
        let parse = |e: serde_json::Error| ConfigError::Parse { path: path.into(), msg: e.to_string() };
        let file = if value.get("config").is_some() {
            serde_json::from_value(value).map_err(parse)?
        } else {
            ConfigFile {
                hairrecon_version: String::new(),
                git_commit: String::new(),
                config: serde_json::from_value(value).map_err(parse)?,
            }
        };
        file.config.validate()?;
        Ok(file)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stages_parse_by_name_in_order() {
        let names: Vec<Stage> = ["head", "Masks", "orient2d", "ORIENT3D", "partings", "direction", "init", "dr"]
            .iter()
            .map(|s| s.parse().unwrap())
            .collect();
        assert_eq!(names, Stage::ALL.to_vec());
        assert!(Stage::Init < Stage::Dr && Stage::Orient2d < Stage::Orient3d && Stage::Masks < Stage::Orient2d);
        assert_eq!(Stage::FIRST, Stage::Head);
        // Padded as a name in a table.
        assert_eq!(format!("[{:>8}]", Stage::Dr), "[      dr]");
        let e = "mvs".parse::<Stage>().unwrap_err();
        assert!(e.to_string().contains("partings"), "{e}");
    }

    #[test]
    fn a_config_round_trips_through_its_file_exactly() {
        let mut cfg = ReconstructConfig { guides: 123, seed: 9, dr: false, ..Default::default() };
        cfg.grow.step = 0.0017;
        cfg.dr_options.lr = 1.234_567e-3;
        cfg.curl = "6.5,22,-1".parse().unwrap();
        let dir = std::env::temp_dir().join(format!("hairrecon-config-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("config.json");
        ConfigFile::new(cfg.clone()).save(&p).unwrap();
        let back = ConfigFile::load(&p).unwrap();
        assert_eq!(back.config, cfg);
        assert_eq!(back.hairrecon_version, VERSION);
        // A bare config with one field takes the defaults for the rest; an unknown field is refused.
        std::fs::write(&p, r#"{"guides": 7}"#).unwrap();
        assert_eq!(ConfigFile::load(&p).unwrap().config, ReconstructConfig { guides: 7, ..Default::default() });
        std::fs::write(&p, r#"{"guides": 7, "guidez": 1}"#).unwrap();
        let e = ConfigFile::load(&p).unwrap_err().to_string();
        assert!(e.contains("guidez") && e.contains("config.json"), "{e}");
        std::fs::write(&p, r#"{"guides": 0}"#).unwrap();
        assert!(ConfigFile::load(&p).unwrap_err().to_string().contains("at least 1"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
