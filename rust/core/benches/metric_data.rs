//! Benchmark data shared by `benches/metric.rs` and `examples/metric_timing.rs`: strands rooted on a
//! sphere of radius 9 cm, 100 points each, 20 cm long, falling down and outward with a gentle wave;
//! `jitter` displaces each strand by a per-strand offset and bend of up to that size.

use glam::Vec3;
use hairrecon_core::StrandSet;

fn lcg(state: &mut u64) -> f32 {
    *state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    ((*state >> 40) as f32) / (1u64 << 24) as f32
}

pub fn head_like(n: usize, points: usize, seed: u64, jitter: f32) -> StrandSet {
    let mut s = seed;
    let mut pts = Vec::with_capacity(n * points);
    for i in 0..n {
        // Fibonacci sphere cap for the roots (upper half).
        let z = 1.0 - (i as f32 + 0.5) / n as f32;
        let phi = i as f32 * 2.399_963;
        let r = (1.0 - z * z).sqrt();
        let root = 0.09 * Vec3::new(r * phi.cos(), r * phi.sin(), z);
        let out = Vec3::new(root.x, root.y, 0.0).normalize_or_zero();
        let off = jitter * Vec3::new(lcg(&mut s) - 0.5, lcg(&mut s) - 0.5, lcg(&mut s) - 0.5);
        let bend = jitter * (lcg(&mut s) - 0.5);
        for j in 0..points {
            let t = j as f32 / (points - 1) as f32;
            let len = 0.2 * t;
            let wave = 0.004 * (len * 120.0).sin();
            pts.push(root + out * (0.02 * t + wave + bend * t) - Vec3::Z * len + off * t.min(1.0));
        }
    }
    StrandSet::new(pts, vec![points as u32; n]).expect("valid strands")
}
