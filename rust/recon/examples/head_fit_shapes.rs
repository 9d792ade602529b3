//! The head fit's metric on heads that differ from the template, as the head-fitting issue asks:
//! the bundled head scaled by up to ±10 % per axis and bent by a smooth random displacement field
//! (up to 1 cm along the normal), with 0.5 mm noise, moved into a random similarity frame; the
//! fitted scalp (the template's, placed by the fit) against the deformed head's true scalp, in
//! millimetres. Prints one row per head (with the fitted frame's rotation error) and the mean.
//!
//! ```text
//! cargo run --release -p hairrecon-recon --example head_fit_shapes [HEADS [FIRST]] [--cut-crown]
//! ```

use std::path::PathBuf;

use glam::{DMat3, DQuat, DVec3, Vec3};
use hairrecon_core::formats::read_mesh;
use hairrecon_core::TriMesh;
use hairrecon_recon::head_fit::compare::surface_error;
use hairrecon_recon::head_fit::nonrigid::{fit_deformation, DeformOptions};
use hairrecon_recon::head_fit::surface::RawSurface;
use hairrecon_recon::head_fit::{fit_similarity, transform_mesh, FitOptions, HeadTemplate, Similarity};

/// SplitMix64.
struct Rng(u64);

impl Rng {
    fn f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn signed(&mut self) -> f64 {
        2.0 * self.f64() - 1.0
    }
}

/// The deformation: per-axis scale, then Gaussian bumps along the direction from the head's centre.
struct Deform {
    scale: DVec3,
    bumps: Vec<(DVec3, f64, f64)>,
}

impl Deform {
    fn new(rng: &mut Rng) -> Self {
        let scale = DVec3::new(1.0 + 0.1 * rng.signed(), 1.0 + 0.1 * rng.signed(), 1.0 + 0.1 * rng.signed());
        let bumps = (0..6)
            .map(|_| {
                let d = DVec3::new(rng.signed(), rng.signed(), rng.signed()).normalize_or(DVec3::Z);
                (d, 0.01 * rng.signed(), 0.5 + 0.5 * rng.f64())
            })
            .collect();
        Self { scale, bumps }
    }
    fn apply(&self, p: Vec3) -> Vec3 {
        let p = p.as_dvec3();
        let dir = p.normalize_or(DVec3::Z);
        let offset: f64 = self.bumps.iter().map(|(d, a, w)| a * (-(1.0 - dir.dot(*d)) / (w * w) * 4.0).exp()).sum();
        ((p + dir * offset.clamp(-0.01, 0.01)) * self.scale).as_vec3()
    }
    fn mesh(&self, m: &TriMesh) -> TriMesh {
        let mut out = m.clone();
        for v in &mut out.vertices {
            *v = self.apply(*v);
        }
        out.normals = None;
        out
    }
}

fn main() {
    let heads: u64 = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(10);
    let first: u64 = std::env::args().nth(2).and_then(|s| s.parse().ok()).unwrap_or(0);
    let crown = std::env::args().any(|a| a == "--cut-crown");
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../blend_fixtures");
    let head = read_mesh(dir.join("head.ply")).expect("head.ply");
    let scalp = read_mesh(dir.join("scalp.ply")).expect("scalp.ply");
    let template = HeadTemplate::new(&head, Some(&scalp), 2000, 7).expect("template");
    println!("| head | axis scales | fit scale | rotation ° | similarity: scalp mean · p95 mm | deformed: scalp mean · p95 mm | scalp · its border on the mesh | deform s |");
    println!("|---:|---|---:|---:|---:|---:|---:|---:|");
    let (mut sum_mean, mut sum_p95, mut def_mean, mut def_p95, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for seed in first..first + heads {
        let mut rng = Rng(seed * 7919 + 1);
        let deform = Deform::new(&mut rng);
        let mut raw = deform.mesh(&head);
        for v in &mut raw.vertices {
            *v += Vec3::new(rng.signed() as f32, rng.signed() as f32, rng.signed() as f32) * 0.0005;
        }
        if crown {
            // The top of the head missing from the raw mesh, as photos from around a head leave it.
            let top = raw.vertices.iter().map(|v| v.z).fold(f32::MIN, f32::max);
            let keep: Vec<bool> = raw.vertices.iter().map(|v| v.z < top - 0.03).collect();
            raw.triangles.retain(|t| t.iter().all(|&i| keep[i as usize]));
        }
        let true_scalp = deform.mesh(&scalp);
        let q = DQuat::from_xyzw(rng.signed(), rng.signed(), rng.signed(), rng.signed()).normalize();
        let frame = Similarity {
            scale: 10f64.powf(2.0 * rng.signed()),
            rotation: DMat3::from_quat(q),
            translation: DVec3::new(rng.signed(), rng.signed(), rng.signed()),
        };
        let raw = transform_mesh(&raw, &frame);
        let fit = match fit_similarity(&template, &raw, None, &FitOptions::default()) {
            Ok(f) => f,
            Err(e) => {
                println!("| {seed} | fit failed: {e} |");
                continue;
            }
        };
        // The template's scalp placed by the fit, back in the canonical frame of the deformed head.
        let placed = transform_mesh(&transform_mesh(&scalp, &fit.to_canonical.inverse()), &frame.inverse());
        let e = surface_error(&placed, &true_scalp, 20_000).expect("areas");
        // The deformation, fitted in the canonical frame to the raw mesh placed there.
        let t0 = std::time::Instant::now();
        let canonical = RawSurface::new(transform_mesh(&raw, &fit.to_canonical), 3);
        let (field, rep) = fit_deformation(&head, &scalp, &canonical, &DeformOptions::default());
        let secs = t0.elapsed().as_secs_f64();
        let placed =
            transform_mesh(&transform_mesh(&field.mesh(&scalp), &fit.to_canonical.inverse()), &frame.inverse());
        let d = surface_error(&placed, &true_scalp, 20_000).expect("areas");
        sum_mean += e.mean;
        sum_p95 += e.p95;
        def_mean += d.mean;
        def_p95 += d.p95;
        n += 1.0;
        // The fitted frame against the true one (raw → canonical, the inverse of `frame`).
        let angle = fit.to_canonical.rotation_angle_to(&frame.inverse());
        println!(
            "| {seed} | {:.3} {:.3} {:.3} | {:.4} | {angle:.1} | {:.2} · {:.2} | {:.2} · {:.2} | {:.0} · {:.0} %{} | {secs:.1} |",
            deform.scale.x,
            deform.scale.y,
            deform.scale.z,
            fit.to_canonical.scale * frame.scale,
            e.mean * 1e3,
            e.p95 * 1e3,
            d.mean * 1e3,
            d.p95 * 1e3,
            100.0 * rep.scalp_on_surface,
            100.0 * rep.border_on_surface,
            if rep.bald { ", bald" } else { "" }
        );
    }
    println!(
        "| mean | | | | {:.2} · {:.2} | {:.2} · {:.2} | | |",
        sum_mean / n * 1e3,
        sum_p95 / n * 1e3,
        def_mean / n * 1e3,
        def_p95 / n * 1e3
    );
}
