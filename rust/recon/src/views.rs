//! What a view sees, shared by the stages that judge strands against the views (the partings,
//! the visual hull, DR): the head's depth per pixel, and whether a hair mask is solid.

use glam::Vec2;
use hairrecon_core::{Bvh, Camera};
use rayon::prelude::*;

/// The head's depth per pixel seen by `camera`, by ray casting (`f32::INFINITY` where the ray
/// misses).
pub fn head_depth_map(camera: &Camera, head: &Bvh) -> Vec<f32> {
    let (w, h) = (camera.width() as usize, camera.height() as usize);
    let c = camera.center();
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let px = Vec2::new((i % w) as f32, (i / w) as f32);
            let d = camera.ray_direction(px);
            match head.ray_cast(c, d, 0.0, f32::INFINITY) {
                Some(hit) => camera.to_camera(c + d * hit.t).z,
                None => f32::INFINITY,
            }
        })
        .collect()
}

/// Whether the median of the coverages above 1% is at least `min_solid` (false without any).
pub fn solid(coverage: &[f32], min_solid: f32) -> bool {
    let mut c: Vec<f32> = coverage.iter().copied().filter(|&x| x > 0.01).collect();
    if c.is_empty() {
        return false;
    }
    let mid = c.len() / 2;
    let (_, m, _) = c.select_nth_unstable_by(mid, f32::total_cmp);
    *m >= min_solid
}
