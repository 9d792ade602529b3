//! Stage 4: the scalp as later stages query it, and hair roots on it.
//!
//! In: the capture's scalp mesh, prepared by `hairrecon_core::scalp::Scalp` (outward normals, the
//! growth direction S(p_s) of supplement §4.2 / Figure 11, blue-noise root sampling after Yuksel,
//! "Sample Elimination for Generating Poisson Disk Sample Sets", 2015). Out: [`Roots`]: root
//! positions with their outward normal and S(p_s), saved as `roots.ply` (S as the normal); and
//! [`scalp_point`], the closest scalp point with its frame, which the direction and flow stages use
//! to read S(p_s) near the scalp.

use glam::Vec3;
pub use hairrecon_core::scalp::{Scalp, ScalpError};

use crate::points3d::OrientedPoints;

/// A point on the scalp with its frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScalpPoint {
    pub point: Vec3,
    /// Outward unit normal.
    pub normal: Vec3,
    /// Unit growth direction S(p_s).
    pub growth: Vec3,
    pub distance: f32,
}

/// The closest scalp point to `p` within `max_dist`, with its normal and S(p_s).
pub fn scalp_point(scalp: &Scalp, p: Vec3, max_dist: f32) -> Option<ScalpPoint> {
    let cp = scalp.bvh().closest_point(p, max_dist)?;
    let r = scalp.root_at(cp.triangle, cp.bary);
    Some(ScalpPoint { point: cp.point, normal: r.normal, growth: r.direction, distance: cp.distance })
}

/// Hair roots: positions on the scalp with outward normal and growth direction.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Roots {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub growth: Vec<Vec3>,
}

impl Roots {
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// As points (direction = S), for saving as PLY.
    pub fn to_points(&self) -> OrientedPoints {
        OrientedPoints {
            positions: self.positions.clone(),
            directions: self.growth.clone(),
            confidence: vec![1.0; self.len()],
        }
    }
}

/// `n` roots in blue noise on the scalp, deterministic for a given seed.
pub fn sample_roots(scalp: &Scalp, n: usize, seed: u64) -> Result<Roots, ScalpError> {
    let mut roots = Roots::default();
    for r in scalp.sample_roots(n, seed)? {
        roots.positions.push(r.position);
        roots.normals.push(r.normal);
        roots.growth.push(r.direction);
    }
    Ok(roots)
}
