//! hairrecon-recon: the reconstruction pipeline, one stage per module, data flowing one way:
//! capture → orientation maps → oriented 3D points → partings → directed points → initial
//! strands → strands optimized by differentiable rendering.
//!
//! The method, stage by stage (each module's doc names its reference):
//! - [`head_fit`]: the similarity from a raw mesh's frame to the canonical one, by registering the head
//!   template (coarse search, trimmed ICP).
//! - [`orient2d`]: 2D orientation maps by a Gabor filter bank.
//! - [`points3d`]: oriented 3D points by line-based MVS on the raw mesh ([`oriented_points`]).
//! - [`parting`]: partings, where the views see the scalp's skin; S turns away from them.
//! - [`direction`]: the points' root-to-tip directions (least squares from the scalp) or the
//!   gravity heuristic.
//! - [`roots`]: the scalp with S(p_s), and roots on it.
//! - [`laplace`]: the interior flow of the hair volume by Laplace's equation.
//! - [`grow`]: guide strands grown through the flow, children interpolated.
//! - [`curl`] and [`curl_choice`]: curly hair: ringlet axes, the curl, helices about grown strands.
//! - [`hull`]: the visual hull of the hair; strands cut where a view sees no hair.
//! - [`dr`]: strand optimization by differentiable rendering of line segments.
//!
//! Around them:
//! - [`config`]: every parameter, as one serde config; [`stages`]: each stage's typed output that
//!   saves and reloads itself; [`runner`]: the stages in order ([`runner::reconstruct`]).
//! - [`eval`]: scores against ground truth, beside the run; [`report`]: `report.json`.
//! - [`raw_mesh`]: the fallback raw mesh, TSDF fusion of depth maps.
//! - [`progress`]: how a long stage reports progress and learns it was cancelled.
//! - [`views`]: what a view sees (the head's depth, solid masks), shared by the stages.

pub mod config;
pub mod curl;
pub mod curl_choice;
pub mod direction;
pub mod dr;
pub mod error;
pub mod eval;
pub mod grow;
pub mod head_fit;
pub mod hull;
pub mod laplace;
pub mod masks;
pub mod orient2d;
pub mod oriented_points;
pub mod parting;
pub mod points3d;
pub mod preflight;
pub mod progress;
pub mod raw_mesh;
pub mod report;
pub mod roots;
pub mod run_folder;
pub mod runner;
pub mod stages;
pub mod views;

pub use config::{Plan, ReconstructConfig, Stage};
pub use error::ReconError;
pub use runner::{reconstruct, ReconstructOutput};
