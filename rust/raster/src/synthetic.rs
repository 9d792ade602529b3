//! Deterministic test geometry for benchmarks and tests: strands grown on a sphere ("a head").
//!
//! Roots are spread over the upper 70% of a sphere of the given radius (Fibonacci lattice); each
//! strand leaves along the normal and bends down under a gravity-like pull, with a small seeded
//! wobble, in equal segments. Z is up (Blender's frame).

use glam::Vec3;
use hairrecon_core::StrandSet;

/// `n_strands` strands of `n_segments` segments each, `length` metres long, on a sphere of `radius`
/// metres centred at the origin.
pub fn sphere_strands(n_strands: usize, n_segments: usize, radius: f32, length: f32, seed: u64) -> StrandSet {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut rnd = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    };
    let golden = std::f32::consts::PI * (3.0 - 5.0f32.sqrt());
    let step = length / n_segments as f32;
    let mut points = Vec::with_capacity(n_strands * (n_segments + 1));
    for i in 0..n_strands {
        // z from 1 down to -0.4 (the upper part of the head).
        let z = 1.0 - 1.4 * (i as f32 + 0.5) / n_strands as f32;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = i as f32 * golden;
        let n = Vec3::new(r * phi.cos(), r * phi.sin(), z);
        let mut p = n * radius;
        let mut dir = (n + Vec3::new(rnd(), rnd(), rnd()) * 0.3).normalize();
        points.push(p);
        for _ in 0..n_segments {
            dir = (dir + Vec3::new(rnd() * 0.2, rnd() * 0.2, -0.12)).normalize();
            let mut q = p + dir * step;
            // Stay outside the head.
            if q.length() < radius * 1.02 {
                q = q.normalize() * radius * 1.02;
            }
            p = q;
            points.push(p);
        }
    }
    StrandSet::new(points, vec![(n_segments + 1) as u32; n_strands]).unwrap_or_else(|_| StrandSet::empty())
}
