//! hairrecon-recon: the reconstruction pipeline, one stage per module, data flowing one way:
//! capture → orientation maps → oriented 3D points → directed points → initial strands → output.
//!
//! - [`progress`]: how a long stage reports progress and learns it was cancelled.
//! - [`raw_mesh`]: the fallback raw mesh, TSDF fusion of depth maps.
//! - [`orient2d`]: 2D orientation maps by a Gabor filter bank.
//! - [`points3d`]: oriented 3D points by line-based MVS on the raw mesh.
//! - [`direction`]: global direction of the points (MST from the scalp) or the gravity heuristic.
//! - [`roots`]: the scalp with S(p_s), and roots on it.
//! - [`parting`]: partings, where the views see the scalp's skin; S turns away from them.
//! - [`laplace`]: the interior flow of the hair volume by Laplace's equation.
//! - [`grow`]: guide strands grown through the flow, children interpolated.
//! - [`curl`]: curly hair: ringlet axes from the directed points, helices swept about grown strands.
//! - [`hull`]: the visual hull of the hair; strands cut where a view sees no hair.
//! - [`pipeline`]: all of the above in order, with outputs and metrics ([`pipeline::reconstruct`]).
//! - [`metrics`]: per-stage metrics against ground truth.

pub mod curl;
pub mod direction;
pub mod dr;
pub mod grow;
pub mod hull;
pub mod laplace;
pub mod metrics;
pub mod orient2d;
pub mod parting;
pub mod pipeline;
pub mod points3d;
pub mod progress;
pub mod raw_mesh;
pub mod roots;
