//! Truncated signed distance fusion of depth maps (Curless & Levoy, "A Volumetric Method for
//! Building Complex Models from Range Images", SIGGRAPH 1996).
//!
//! In: depth maps (depth along each camera's optical axis, 0 where a pixel saw nothing) with their
//! cameras. Out: a regular grid of truncated signed distances in units of the truncation distance,
//! in `[-1, 1]` (positive in front of the observed surface, negative behind it), and per-voxel
//! weights (how many views observed the voxel; 0 = never observed).
//!
//! Per voxel centre and view: project it, read the depth `d` of the nearest pixel, and take the
//! projective signed distance `sd = d - z` (z: the voxel's depth). Voxels more than the truncation
//! distance behind the surface are occluded and left alone; the others get
//! `min(1, sd / truncation)` averaged in with weight 1. A pixel that saw nothing (the background)
//! marks the voxels on its ray as empty space (`+1`): space carving, which keeps the fused surface
//! inside every silhouette. Slices of the grid are fused in parallel (rayon).

use glam::{UVec3, Vec2, Vec3};
use hairrecon_core::Camera;
use rayon::prelude::*;

use crate::progress::{Cancelled, Progress};

/// One depth map and its camera. `depth[y * width + x]` is the depth along the optical axis in
/// metres of the pixel centred at (x, y); 0 = the pixel saw no surface (empty space along its ray);
/// negative or not finite = unknown (the pixel does not take part).
#[derive(Debug, Clone)]
pub struct DepthView {
    pub camera: Camera,
    pub depth: Vec<f32>,
}

impl DepthView {
    /// The depth at the pixel nearest to `pixel`: `Some(0.0)` where the pixel saw nothing,
    /// `None` outside the image or where the pixel's depth is unknown (negative or not finite).
    #[inline]
    pub(crate) fn sample(&self, pixel: Vec2) -> Option<f32> {
        if !self.camera.contains(pixel) {
            return None;
        }
        let x = (pixel.x + 0.5) as usize;
        let y = (pixel.y + 0.5) as usize;
        let w = self.camera.width() as usize;
        let d = self.depth[y * w + x];
        (d.is_finite() && d >= 0.0).then_some(d)
    }
}

/// A TSDF voxel grid. Voxel `(i, j, k)` has its centre at `origin + voxel * (i, j, k)` and is
/// stored at `i + dims.x * (j + dims.y * k)`.
#[derive(Debug, Clone)]
pub struct TsdfGrid {
    pub origin: Vec3,
    pub voxel: f32,
    pub dims: UVec3,
    /// Truncated signed distance in units of `truncation`, in [-1, 1].
    pub tsdf: Vec<f32>,
    /// Number of views that updated the voxel.
    pub weight: Vec<f32>,
    /// Truncation distance in metres.
    pub truncation: f32,
}

impl TsdfGrid {
    /// An empty grid covering the box `[lo, hi]` (padded to whole voxels).
    pub fn new(lo: Vec3, hi: Vec3, voxel: f32, truncation: f32) -> Self {
        let dims = ((hi - lo) / voxel - 1e-4).ceil().max(Vec3::ZERO).as_uvec3() + UVec3::ONE;
        let n = dims.x as usize * dims.y as usize * dims.z as usize;
        Self { origin: lo, voxel, dims, tsdf: vec![1.0; n], weight: vec![0.0; n], truncation }
    }

    /// Number of voxels a grid over `[lo, hi]` would have.
    pub fn voxel_count(lo: Vec3, hi: Vec3, voxel: f32) -> u64 {
        let d = ((hi - lo) / voxel - 1e-4).ceil().max(Vec3::ZERO) + Vec3::ONE;
        d.x as u64 * d.y as u64 * d.z as u64
    }

    #[inline]
    pub fn index(&self, i: u32, j: u32, k: u32) -> usize {
        i as usize + self.dims.x as usize * (j as usize + self.dims.y as usize * k as usize)
    }

    #[inline]
    pub fn position(&self, i: u32, j: u32, k: u32) -> Vec3 {
        self.origin + self.voxel * Vec3::new(i as f32, j as f32, k as f32)
    }

    /// Fuses all views into the grid, one z-slice per task. Reports progress per slice and stops
    /// with [`Cancelled`] when asked (the grid is then partly fused).
    pub fn integrate(&mut self, views: &[DepthView], progress: &dyn Progress) -> Result<(), Cancelled> {
        self.integrate_quantile(views, None, progress)
    }

    /// Like [`Self::integrate`], but with `quantile = Some(q)` each voxel takes the q-quantile of
    /// its per-view truncated distances instead of their mean (0.5: the median), which a few
    /// views that see through a sparse structure, or past it at a grazing angle, cannot move.
    pub fn integrate_quantile(
        &mut self,
        views: &[DepthView],
        quantile: Option<f32>,
        progress: &dyn Progress,
    ) -> Result<(), Cancelled> {
        let (nx, ny, nz) = (self.dims.x as usize, self.dims.y as usize, self.dims.z as usize);
        let slice = nx * ny;
        let done = std::sync::atomic::AtomicUsize::new(0);
        let (origin, voxel, trunc) = (self.origin, self.voxel, self.truncation);
        self.tsdf.par_chunks_mut(slice).zip(self.weight.par_chunks_mut(slice)).enumerate().try_for_each(
            |(k, (tsdf, weight))| {
                progress.check()?;
                let mut values = Vec::with_capacity(views.len());
                for j in 0..ny {
                    for i in 0..nx {
                        let p = origin + voxel * Vec3::new(i as f32, j as f32, k as f32);
                        let (mut sum, mut wsum) = (0.0f32, 0.0f32);
                        values.clear();
                        for v in views {
                            let pc = v.camera.to_camera(p);
                            if pc.z <= 1e-6 {
                                continue;
                            }
                            let Some(d) = v.sample(v.camera.camera_to_pixel(pc)) else { continue };
                            let value = if d == 0.0 {
                                1.0 // the pixel saw nothing: free space
                            } else {
                                let sd = d - pc.z;
                                if sd < -trunc {
                                    continue; // occluded
                                }
                                (sd / trunc).min(1.0)
                            };
                            sum += value;
                            wsum += 1.0;
                            values.push(value);
                        }
                        let idx = i + nx * j;
                        if wsum > 0.0 {
                            tsdf[idx] = match quantile {
                                None => sum / wsum,
                                Some(q) => {
                                    let r = ((values.len() - 1) as f32 * q).round() as usize;
                                    *values.select_nth_unstable_by(r, f32::total_cmp).1
                                }
                            };
                            weight[idx] = wsum;
                        }
                    }
                }
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress.update("tsdf", n as f32 / nz as f32, &format!("slice {n}/{nz}"));
                Ok(())
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::NoProgress;

    /// A camera at distance 1 looking down -Z at a plane z = 0 sees depth 1 everywhere; after
    /// fusion, voxels above the plane are positive, below (within truncation) negative, and the
    /// zero crossing is at z = 0 to within the voxel interpolation.
    #[test]
    fn a_plane_seen_from_above_fuses_to_a_zero_crossing_at_the_plane() {
        let cam = Camera::look_at(Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO, Vec3::Y, 0.8, 64, 64).unwrap();
        // Planar depth of the plane z = 0 is exactly 1 for every pixel of this camera.
        let view = DepthView { camera: cam, depth: vec![1.0; 64 * 64] };
        let mut g = TsdfGrid::new(Vec3::new(-0.1, -0.1, -0.05), Vec3::new(0.1, 0.1, 0.05), 0.01, 0.03);
        g.integrate(&[view], &NoProgress).unwrap();
        let (i, j) = (g.dims.x / 2, g.dims.y / 2);
        for k in 0..g.dims.z {
            let z = g.position(i, j, k).z;
            let idx = g.index(i, j, k);
            if z < -0.03 - 1e-4 {
                assert_eq!(g.weight[idx], 0.0, "z {z}: occluded voxels stay unobserved");
            } else {
                let expected = (z / 0.03).min(1.0);
                assert!((g.tsdf[idx] - expected).abs() < 1e-4, "z {z}: {} vs {expected}", g.tsdf[idx]);
            }
        }
    }

    /// Unknown pixels (negative depth) leave the voxels on their rays unobserved, where a pixel
    /// that saw nothing (0) marks them empty.
    #[test]
    fn unknown_pixels_do_not_take_part() {
        let cam = Camera::look_at(Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO, Vec3::Y, 0.8, 64, 64).unwrap();
        let (lo, hi) = (Vec3::new(-0.1, -0.1, -0.05), Vec3::new(0.1, 0.1, 0.05));
        let mut g = TsdfGrid::new(lo, hi, 0.01, 0.03);
        g.integrate(&[DepthView { camera: cam, depth: vec![-1.0; 64 * 64] }], &NoProgress).unwrap();
        assert!(g.weight.iter().all(|&w| w == 0.0));
        let mut g = TsdfGrid::new(lo, hi, 0.01, 0.03);
        g.integrate(&[DepthView { camera: cam, depth: vec![0.0; 64 * 64] }], &NoProgress).unwrap();
        assert!(g.weight.iter().all(|&w| w == 1.0) && g.tsdf.iter().all(|&d| d == 1.0));
    }

    /// Three views of the plane z = 0 from above, one of which sees 2 cm past it (a gap in a sparse
    /// surface): the median keeps the zero crossing at the plane, the mean moves it down.
    #[test]
    fn the_median_ignores_one_view_that_sees_through() {
        let cam = Camera::look_at(Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO, Vec3::Y, 0.8, 64, 64).unwrap();
        let views: Vec<DepthView> =
            [1.0, 1.0, 1.02].into_iter().map(|d| DepthView { camera: cam, depth: vec![d; 64 * 64] }).collect();
        let zero_crossing = |q: Option<f32>| {
            let mut g = TsdfGrid::new(Vec3::new(-0.05, -0.05, -0.05), Vec3::new(0.05, 0.05, 0.05), 0.005, 0.03);
            g.integrate_quantile(&views, q, &NoProgress).unwrap();
            let (i, j) = (g.dims.x / 2, g.dims.y / 2);
            (1..g.dims.z)
                .find_map(|k| {
                    let (a, b) = (g.tsdf[g.index(i, j, k - 1)], g.tsdf[g.index(i, j, k)]);
                    (a < 0.0 && b >= 0.0).then(|| {
                        let (za, zb) = (g.position(i, j, k - 1).z, g.position(i, j, k).z);
                        za + (zb - za) * a / (a - b)
                    })
                })
                .unwrap()
        };
        let median = zero_crossing(Some(0.5));
        let mean = zero_crossing(None);
        assert!(median.abs() < 1e-4, "median zero crossing at z = {median}");
        assert!(mean < -0.005, "mean zero crossing at z = {mean}");
    }
}
