//! The error type of the synth crate: every variant says what went wrong and what to do.

use std::path::PathBuf;

use hairrecon_core::formats::FormatError;
use hairrecon_core::scalp::ScalpError;
use hairrecon_core::{MeshError, StrandError};
use thiserror::Error;

/// Why a fixture or a hairstyle could not be made.
#[derive(Debug, Error)]
pub enum SynthError {
    #[error("{what} not found at {path}; {hint}")]
    MissingFile { what: &'static str, path: PathBuf, hint: &'static str },
    #[error(
        "{path} has sha256 {got} but the head fixture is made from {expected}; \
         use the woman_head.ply described in /work/shared/data/README.md"
    )]
    Checksum { path: PathBuf, expected: &'static str, got: String },
    #[error("invalid parameter: {0}")]
    Param(String),
    #[error(
        "the scalp rule selected no triangle of the head; the head is not the normalised fixture \
         (metres, Z up, face toward -Y)"
    )]
    EmptyScalp,
    #[error(transparent)]
    Format(#[from] FormatError),
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error(transparent)]
    Scalp(#[from] ScalpError),
    #[error(transparent)]
    Strands(#[from] StrandError),
    #[error("could not write image {path}: {source}")]
    Image { path: PathBuf, source: image::ImageError },
    #[error("could not read {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
}
