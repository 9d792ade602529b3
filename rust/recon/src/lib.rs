//! hairrecon-recon: the reconstruction pipeline, one stage per module, data flowing one way:
//! capture → orientation maps → oriented 3D points → directed points → initial strands → output.
//!
//! - [`progress`]: how a long stage reports progress and learns it was cancelled.
//! - [`raw_mesh`]: the fallback raw mesh, TSDF fusion of depth maps.

pub mod progress;
pub mod raw_mesh;
