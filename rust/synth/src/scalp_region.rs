//! The scalp region of the bundled head: where roots grow (top, sides above the ears, back down to
//! the nape; not the face, the ears or the neck).
//!
//! In: the normalised head of [`crate::head`] (metres, Z up, face toward −Y, bounding box centred on
//! the origin). Out: the scalp submesh (the head's triangles whose three corners pass
//! [`is_scalp`], with their normals and UVs) and its mask in UV space.
//!
//! The rule, on a vertex `(x, y, z)` in metres (chosen by looking at renders of the head, see
//! `blend_fixtures/README.md`):
//! - above a tilted hairline surface: `z > 0.047 − 0.676 y + 2.5 x²`. It runs high over the
//!   forehead (front, −Y), passes just above the ears at the sides and reaches the nape at the back
//!   (+Y); the `x²` term rounds the front hairline at the temples and narrows the nape;
//! - outside both ear ellipsoids, centred at `(±0.085, 0.027, 0.039)` with semi-axes
//!   `(0.030, 0.030, 0.045)`: a band of bare skin around each ear.

use glam::{Vec2, Vec3};
use hairrecon_core::TriMesh;
use image::GrayImage;

use crate::error::SynthError;

/// Height of the hairline surface at the origin, metres.
pub const HAIRLINE_Z0: f32 = 0.047;
/// Rise of the hairline per metre toward the face (−Y).
pub const HAIRLINE_SLOPE: f32 = 0.676;
/// Curvature of the hairline across the head, 1/m.
pub const HAIRLINE_CURVE: f32 = 2.5;
/// Centre of the right ear's ellipsoid (the left one is mirrored in X), metres.
pub const EAR_CENTRE: Vec3 = Vec3::new(0.085, 0.027, 0.039);
/// Semi-axes of the ear ellipsoids, metres.
pub const EAR_RADII: Vec3 = Vec3::new(0.030, 0.030, 0.045);

/// Whether a point of the normalised head lies in the scalp region.
pub fn is_scalp(p: Vec3) -> bool {
    let above = p.z > HAIRLINE_Z0 - HAIRLINE_SLOPE * p.y + HAIRLINE_CURVE * p.x * p.x;
    let in_ear = |c: Vec3| ((p - c) / EAR_RADII).length_squared() < 1.0;
    above && !in_ear(EAR_CENTRE) && !in_ear(EAR_CENTRE * Vec3::new(-1.0, 1.0, 1.0))
}

/// The triangles of `head` whose three corners pass [`is_scalp`], as a compact mesh that keeps the
/// head's normals and UVs.
pub fn scalp_submesh(head: &TriMesh) -> Result<TriMesh, SynthError> {
    let inside: Vec<bool> = head.vertices.iter().map(|&p| is_scalp(p)).collect();
    let mut remap = vec![u32::MAX; head.vertices.len()];
    let mut keep = Vec::new();
    let mut triangles = Vec::new();
    for t in &head.triangles {
        if t.iter().all(|&v| inside[v as usize]) {
            let mut nt = [0u32; 3];
            for (k, &v) in t.iter().enumerate() {
                if remap[v as usize] == u32::MAX {
                    remap[v as usize] = keep.len() as u32;
                    keep.push(v as usize);
                }
                nt[k] = remap[v as usize];
            }
            triangles.push(nt);
        }
    }
    if triangles.is_empty() {
        return Err(SynthError::EmptyScalp);
    }
    let pick3 = |a: &Vec<Vec3>| keep.iter().map(|&i| a[i]).collect::<Vec<_>>();
    let vertices = pick3(&head.vertices);
    let normals = head.normals.as_ref().map(pick3);
    let uvs = head.uvs.as_ref().map(|a| keep.iter().map(|&i| a[i]).collect::<Vec<Vec2>>());
    Ok(TriMesh::new(vertices, triangles, normals, uvs)?)
}

/// A `size × size` mask of `mesh`'s triangles in UV space: 255 where a pixel centre is covered,
/// else 0. Row 0 is `v = 1` (image convention, as Blender shows textures); UVs outside `[0, 1]` are
/// clipped. A mesh without UVs gives an empty mask.
pub fn uv_mask(mesh: &TriMesh, size: u32) -> GrayImage {
    let mut img = GrayImage::new(size, size);
    let Some(uvs) = &mesh.uvs else { return img };
    let s = size as f32;
    let to_px = |uv: Vec2| Vec2::new(uv.x * s - 0.5, (1.0 - uv.y) * s - 0.5);
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| to_px(uvs[i as usize]));
        let area = (b - a).perp_dot(c - a);
        if area.abs() < 1e-12 {
            continue;
        }
        let lo = a.min(b).min(c).floor().max(Vec2::ZERO);
        let hi = a.max(b).max(c).ceil().min(Vec2::splat(s - 1.0));
        if lo.x > hi.x || lo.y > hi.y {
            continue;
        }
        for y in lo.y as u32..=hi.y as u32 {
            for x in lo.x as u32..=hi.x as u32 {
                let p = Vec2::new(x as f32, y as f32);
                let w0 = (b - p).perp_dot(c - p) / area;
                let w1 = (c - p).perp_dot(a - p) / area;
                let w2 = 1.0 - w0 - w1;
                let e = -1e-4;
                if w0 >= e && w1 >= e && w2 >= e {
                    img.put_pixel(x, y, image::Luma([255]));
                }
            }
        }
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rule_keeps_crown_and_back_and_drops_face_ears_neck() {
        // Crown, the back above the nape, the sides above the ears: scalp.
        for p in [Vec3::new(0.0, 0.02, 0.165), Vec3::new(0.0, 0.11, 0.04), Vec3::new(0.075, 0.0, 0.11)] {
            assert!(is_scalp(p), "{p:?}");
        }
        // Forehead, cheek, ear, neck at the back: not scalp.
        for p in [
            Vec3::new(0.0, -0.095, 0.08),
            Vec3::new(0.06, -0.06, 0.0),
            Vec3::new(0.09, 0.027, 0.04),
            Vec3::new(0.0, 0.06, -0.06),
        ] {
            assert!(!is_scalp(p), "{p:?}");
        }
    }

    #[test]
    fn submesh_and_mask_of_a_quad() {
        let v = vec![Vec3::new(-0.01, 0.0, 0.15), Vec3::new(0.01, 0.0, 0.15), Vec3::new(0.0, 0.01, 0.15), Vec3::ZERO];
        let uv = vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0), Vec2::ONE];
        let head = TriMesh::new(v, vec![[0, 1, 2], [1, 3, 2]], None, Some(uv)).unwrap();
        let s = scalp_submesh(&head).unwrap();
        assert_eq!(s.triangles.len(), 1);
        assert_eq!(s.vertices.len(), 3);
        let m = uv_mask(&s, 64);
        let on = m.pixels().filter(|p| p.0[0] == 255).count();
        // Half of the square in UV space: 64² / 2 = 2048 pixels, give or take the diagonal.
        assert!((on as i32 - 2048).abs() <= 64, "{on}");
        assert_eq!(m.get_pixel(2, 61).0[0], 255); // near uv (0, 0): bottom-left
        assert_eq!(m.get_pixel(61, 2).0[0], 0); // near uv (1, 1): top-right
    }
}
