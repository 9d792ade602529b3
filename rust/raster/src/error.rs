//! Errors of the rasterizer: invalid inputs rejected once, at the edge of the crate.

use thiserror::Error;

/// Why a rasterizer input was rejected.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum RasterError {
    #[error("segment {segment} refers to vertex {vertex}, but only {count} vertices were given; fix the segment list")]
    BadSegment { segment: usize, vertex: u32, count: usize },
    #[error("vertex {index} is not finite ({value:?}); remove NaN or infinite coordinates before rendering")]
    NotFinite { index: usize, value: [f32; 3] },
    #[error("strand width must be a positive finite number, got {0}")]
    BadWidth(f32),
    #[error("image of {what} is {got_w}x{got_h}x{got_c}, expected {want_w}x{want_h}x{want_c}; render and compare at one size")]
    SizeMismatch { what: &'static str, got_w: u32, got_h: u32, got_c: usize, want_w: u32, want_h: u32, want_c: usize },
    #[error("could not write the image {path}: {message}")]
    Write { path: String, message: String },
}
