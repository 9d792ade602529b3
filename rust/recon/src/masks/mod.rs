//! Hair masks without ground truth.

pub mod matting;
pub mod trimap;
