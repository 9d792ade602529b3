//! What each pixel of a view sees of the capture's surfaces: one ray through the pixel's centre
//! against the raw mesh and the fitted head (the head fills the raw mesh's holes, so that a hole
//! in the face does not show the hair at the back of the head). The same buffers give the raw
//! mesh's visibility in each view (its vertices' colours) and the hair region's silhouette.

use glam::{Vec2, Vec3};
use hairrecon_core::{Bvh, Camera};
use rayon::prelude::*;

/// How far (metres) the fitted head must lie in front of the raw mesh to hide it.
pub const HEAD_SLACK: f32 = 0.01;

/// Which surface a pixel's ray met first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Surface {
    None,
    Raw,
    Head,
}

/// The first hit of one pixel's ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelHit {
    /// Depth along the camera's optical axis (`f32::INFINITY` when the ray met nothing).
    pub depth: f32,
    pub surface: Surface,
    /// The triangle of `surface` and the barycentric weights of its corners 1 and 2.
    pub triangle: u32,
    pub u: f32,
    pub v: f32,
}

impl PixelHit {
    const MISS: Self = Self { depth: f32::INFINITY, surface: Surface::None, triangle: u32::MAX, u: 0.0, v: 0.0 };
}

/// The first hits of every pixel of one view, row-major, top row first.
#[derive(Debug, Clone)]
pub struct ViewHits {
    pub width: u32,
    pub height: u32,
    pub hits: Vec<PixelHit>,
}

impl ViewHits {
    /// Casts a ray through every pixel centre of `camera` against `raw` and, if given, `head`.
    pub fn cast(camera: &Camera, raw: &Bvh, head: Option<&Bvh>) -> Self {
        let (w, h) = (camera.width(), camera.height());
        let origin = camera.center();
        let axis = camera.r().row(2);
        let hits: Vec<PixelHit> = (0..h)
            .into_par_iter()
            .flat_map_iter(|y| {
                (0..w).map(move |x| {
                    let dir = camera.ray_direction(Vec2::new(x as f32, y as f32));
                    let first = |bvh: &Bvh, surface: Surface, t_max: f32| {
                        bvh.ray_cast(origin, dir, 0.0, t_max).map(|r| (r, surface))
                    };
                    let mut best = first(raw, Surface::Raw, f32::INFINITY);
                    if let Some(head) = head {
                        // The head counts only where it is clearly in front of the raw mesh (a
                        // hole): where it pokes through by a few millimetres, the raw mesh is
                        // what the photo shows.
                        let t_max = best.map_or(f32::INFINITY, |(r, _)| r.t - HEAD_SLACK);
                        if let Some(hit) = first(head, Surface::Head, t_max) {
                            best = Some(hit);
                        }
                    }
                    match best {
                        Some((r, surface)) => {
                            PixelHit { depth: r.t * dir.dot(axis), surface, triangle: r.triangle, u: r.u, v: r.v }
                        }
                        None => PixelHit::MISS,
                    }
                })
            })
            .collect();
        Self { width: w, height: h, hits }
    }

    /// The hit at the pixel nearest to `pixel` (`None` outside the image).
    pub fn at(&self, pixel: Vec2) -> Option<&PixelHit> {
        let (x, y) = (pixel.x.round(), pixel.y.round());
        if x < 0.0 || y < 0.0 || x >= self.width as f32 || y >= self.height as f32 {
            return None;
        }
        self.hits.get(y as usize * self.width as usize + x as usize)
    }
}

/// Whether the raw-mesh point `p` (with outward normal `n`) is seen by `camera`: in front of it,
/// facing it, and not hidden by a nearer surface in `hits` (within `tolerance` metres plus one and a
/// half pixels' footprint). Returns the pixel and how squarely the surface faces the camera.
pub fn seen(camera: &Camera, hits: &ViewHits, p: Vec3, n: Vec3, tolerance: f32) -> Option<(Vec2, f32)> {
    let pr = camera.project(p)?;
    let facing = -n.dot((p - camera.center()).normalize_or_zero());
    if facing <= 0.1 {
        return None;
    }
    let hit = hits.at(pr.pixel)?;
    let fx = camera.k().col(0).x;
    let slack = tolerance + 1.5 * pr.depth / fx / facing.max(0.2);
    (hit.surface == Surface::Raw && (pr.depth - hit.depth).abs() <= slack).then_some((pr.pixel, facing))
}

#[cfg(test)]
mod tests {
    use super::*;
    use hairrecon_core::mesh::unit_cube;

    #[test]
    fn a_cube_seen_from_the_front_hides_its_back_and_shows_its_front() {
        let cube = unit_cube().transformed(glam::Affine3A::from_scale(Vec3::splat(0.2)));
        let cam = Camera::look_at(Vec3::new(0.0, -1.0, 0.0), Vec3::ZERO, Vec3::Z, 0.5, 64, 64).unwrap();
        let raw = Bvh::new(cube);
        let hits = ViewHits::cast(&cam, &raw, None);
        let centre = hits.at(Vec2::new(31.5, 31.5)).unwrap();
        assert_eq!(centre.surface, Surface::Raw);
        // The front face of a cube of side 0.2 centred at the origin is 0.9 from the camera.
        assert!((centre.depth - 0.9).abs() < 1e-4, "{}", centre.depth);
        assert_eq!(hits.at(Vec2::new(1.0, 1.0)).unwrap().surface, Surface::None);
        let front = Vec3::new(0.0, -0.1, 0.0);
        let back = Vec3::new(0.0, 0.1, 0.0);
        assert!(seen(&cam, &hits, front, -Vec3::Y, 0.002).is_some());
        assert!(seen(&cam, &hits, back, Vec3::Y, 0.002).is_none());
        // Facing the camera but behind the front face: hidden.
        assert!(seen(&cam, &hits, back, -Vec3::Y, 0.002).is_none());
    }
}
