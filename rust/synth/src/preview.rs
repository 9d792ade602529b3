//! Quick pictures of a hairstyle on the head: orthographic front, side and back views.
//!
//! In: the head mesh and a strand set (metres, Z up, face toward −Y). Out: an RGB image with the
//! three views side by side. The head is rasterized with a depth buffer and Lambert shading; each
//! strand segment is drawn as a one-pixel line (DDA) with the same depth test, its colour varied per
//! strand and shaded by how much the segment faces the light, like a cheap Kajiya–Kay term.

use glam::{Vec2, Vec3};
use hairrecon_core::{StrandSet, TriMesh};
use image::{Rgb, RgbImage};

/// One orthographic view: image right, image up and toward-the-viewer axes.
#[derive(Debug, Clone, Copy)]
struct View {
    right: Vec3,
    up: Vec3,
    toward: Vec3,
}

const VIEWS: [View; 3] = [
    // Front: the viewer stands at −Y.
    View { right: Vec3::X, up: Vec3::Z, toward: Vec3::NEG_Y },
    // Side: the viewer stands at +X (the head's left), the face on the right.
    View { right: Vec3::NEG_Y, up: Vec3::Z, toward: Vec3::X },
    // Back: the viewer stands at +Y.
    View { right: Vec3::NEG_X, up: Vec3::Z, toward: Vec3::Y },
];

/// Renders front, side and back views, each `height` pixels high.
pub fn render_preview(head: &TriMesh, strands: &StrandSet, height: u32) -> RgbImage {
    let (mut lo, mut hi) = head.bbox();
    if let Some((a, b)) = strands.bbox() {
        lo = lo.min(a);
        hi = hi.max(b);
    }
    let margin = 0.01;
    let (lo, hi) = (lo - margin, hi + margin);
    // One scale for all views: the horizontal half-width is the largest of the X and Y extents.
    let half_w = (hi.x - lo.x).max(hi.y - lo.y) * 0.5;
    let centre_h = 0.5 * (lo + hi);
    let scale = height as f32 / (hi.z - lo.z);
    let width = (2.0 * half_w * scale).ceil() as u32;
    let mut img = RgbImage::from_pixel(width * 3, height, Rgb([24, 26, 30]));
    for (vi, v) in VIEWS.iter().enumerate() {
        let x0 = vi as u32 * width;
        let mut depth = vec![f32::NEG_INFINITY; (width * height) as usize];
        let project = |p: Vec3| {
            let c = centre_h.dot(v.right);
            Vec3::new((p.dot(v.right) - c + half_w) * scale, (hi.z - p.dot(v.up)) * scale, p.dot(v.toward))
        };
        // Head.
        let light = (v.toward * 0.8 + Vec3::Z * 0.5).normalize();
        for i in 0..head.triangles.len() {
            let nrm = head.face_normal(i);
            let shade = 0.25 + 0.65 * nrm.dot(light).max(0.0);
            let col = Rgb([(225.0 * shade) as u8, (200.0 * shade) as u8, (185.0 * shade) as u8]);
            let [a, b, c] = head.corners(i).map(project);
            fill_triangle(&mut img, &mut depth, x0, width, height, [a, b, c], col);
        }
        // Strands.
        for (si, s) in strands.iter().enumerate() {
            let h = hash(si as u64);
            let tone = 0.75 + 0.5 * ((h & 0xff) as f32 / 255.0);
            for w in s.windows(2) {
                let t = (w[1] - w[0]).normalize_or_zero();
                let spec = 1.0 - t.dot(light).abs();
                let k = tone * (0.55 + 0.45 * spec);
                let col = Rgb([(110.0 * k).min(255.0) as u8, (72.0 * k) as u8, (40.0 * k) as u8]);
                draw_line(&mut img, &mut depth, x0, width, height, project(w[0]), project(w[1]), col);
            }
        }
    }
    img
}

fn hash(x: u64) -> u64 {
    hairrecon_core::scalp::splitmix64(x)
}

fn fill_triangle(img: &mut RgbImage, depth: &mut [f32], x0: u32, w: u32, h: u32, p: [Vec3; 3], col: Rgb<u8>) {
    let [a, b, c] = p.map(|q| Vec2::new(q.x, q.y));
    let area = (b - a).perp_dot(c - a);
    if area.abs() < 1e-12 {
        return;
    }
    let lo = a.min(b).min(c).floor().max(Vec2::ZERO);
    let hi = a.max(b).max(c).ceil().min(Vec2::new(w as f32 - 1.0, h as f32 - 1.0));
    if lo.x > hi.x || lo.y > hi.y {
        return;
    }
    for y in lo.y as u32..=hi.y as u32 {
        for x in lo.x as u32..=hi.x as u32 {
            let q = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let w0 = (b - q).perp_dot(c - q) / area;
            let w1 = (c - q).perp_dot(a - q) / area;
            let w2 = 1.0 - w0 - w1;
            if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                continue;
            }
            let z = w0 * p[0].z + w1 * p[1].z + w2 * p[2].z;
            let i = (y * w + x) as usize;
            if z > depth[i] {
                depth[i] = z;
                img.put_pixel(x0 + x, y, col);
            }
        }
    }
}

fn draw_line(img: &mut RgbImage, depth: &mut [f32], x0: u32, w: u32, h: u32, a: Vec3, b: Vec3, col: Rgb<u8>) {
    let steps = ((b.x - a.x).abs().max((b.y - a.y).abs()).ceil() as usize).max(1);
    for k in 0..=steps {
        let p = a.lerp(b, k as f32 / steps as f32);
        if p.x < 0.0 || p.y < 0.0 || p.x >= w as f32 || p.y >= h as f32 {
            continue;
        }
        let i = (p.y as u32 * w + p.x as u32) as usize;
        if p.z > depth[i] {
            depth[i] = p.z;
            img.put_pixel(x0 + p.x as u32, p.y as u32, col);
        }
    }
}
