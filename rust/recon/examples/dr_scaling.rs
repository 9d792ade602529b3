//! How DR's time and memory grow with the number of strands, of views and the image height: one
//! whole `dr::optimize` run (the reparameterization built, guide steps, child steps, the final
//! clean-up) on synthetic strands, so that no capture needs rendering.
//!
//! ```text
//! cargo run --release -p hairrecon-recon --example dr_scaling -- STRANDS VIEWS HEIGHT [GUIDE_STEPS CHILD_STEPS [STRIDE]]
//! ```
//!
//! The ground truth is `STRANDS` strands of 100 segments, 25 cm long, rooted on a sphere of radius
//! 9 cm; DR starts from other strands of the same kind, 22 cm long, with a tenth of them as guides.
//! `VIEWS` cameras of `HEIGHT` × 2/3·`HEIGHT` px look at the sphere from 0.5 m, spread over the
//! upper half of a sphere of directions; their targets are the ground truth's coverage and
//! orientation. DR renders four of them per step, as the library does. Prints one line: the
//! seconds per guide step and per child step (means over the steps), the whole run's seconds, and
//! the process's peak resident memory (targets included). `STRIDE` is `DrOptions::stride` (default:
//! the library's).

use std::time::Instant;

use glam::Vec3;
use hairrecon_core::{Bvh, Camera, TriMesh};
use hairrecon_raster::synthetic::sphere_strands;
use hairrecon_recon::dr::{optimize, DrOptions, DrStage};
use hairrecon_recon::progress::NoProgress;

#[path = "../benches/dr_data.rs"]
mod dr_data;
use dr_data::{targets, WIDTH_M};

const RADIUS: f32 = 0.09;

/// `n` cameras on a golden-angle spiral over the upper half of the sphere of directions.
fn cameras(n: usize, height: u32) -> Vec<Camera> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let z = 0.9 * (i as f32 + 0.5) / n as f32 - 0.2;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f32;
            let eye = Vec3::new(r * a.cos(), r * a.sin(), z) * 0.5;
            let up = if z.abs() > 0.99 { Vec3::Y } else { Vec3::Z };
            Camera::look_at(eye, Vec3::new(0.0, 0.0, -0.02), up, 0.8, height * 2 / 3, height).expect("camera")
        })
        .collect()
}

/// A UV sphere of radius `r`: the scalp the roots sit on.
fn sphere(r: f32, rings: u32, segs: u32) -> TriMesh {
    let mut vertices = Vec::new();
    for i in 0..=rings {
        let polar = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segs {
            let az = std::f32::consts::TAU * j as f32 / segs as f32;
            vertices.push(Vec3::new(polar.sin() * az.cos(), polar.sin() * az.sin(), polar.cos()) * r);
        }
    }
    let mut triangles = Vec::new();
    for i in 0..rings {
        for j in 0..segs {
            let (a, b) = (i * segs + j, i * segs + (j + 1) % segs);
            let (c, d) = (a + segs, b + segs);
            triangles.extend([[a, c, b], [b, c, d]]);
        }
    }
    TriMesh { vertices, triangles, normals: None, uvs: None }
}

/// The process's peak resident memory in MiB (Linux; 0 elsewhere).
fn peak_rss_mib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let kb = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok());
    kb.unwrap_or(0.0) / 1024.0
}

fn main() {
    let args: Vec<usize> = std::env::args().skip(1).map(|a| a.parse().expect("integer arguments")).collect();
    let [strands, views, height] = args[..3] else {
        eprintln!("usage: dr_scaling STRANDS VIEWS HEIGHT [GUIDE_STEPS CHILD_STEPS [STRIDE]]");
        std::process::exit(2);
    };
    let (guide_steps, child_steps) = (args.get(3).copied().unwrap_or(6), args.get(4).copied().unwrap_or(3));
    let gt = sphere_strands(strands, 100, RADIUS, 0.25, 7);
    let init = sphere_strands(strands, 100, RADIUS, 0.22, 8);
    let guides = init.select(&(0..init.num_strands()).step_by(10).collect::<Vec<_>>());
    let targets = targets(&gt, &cameras(views, height as u32));
    drop(gt);
    let scalp = Bvh::new(sphere(RADIUS, 64, 128));
    let opts = DrOptions {
        iterations_guides: guide_steps,
        iterations_children: child_steps,
        width_m: WIDTH_M,
        stride: args.get(5).copied().unwrap_or(DrOptions::default().stride),
        ..DrOptions::default()
    };
    let segments = init.num_points() - init.num_strands();
    let t = Instant::now();
    let r = optimize(guides, init, &targets, &scalp, None, &opts, &NoProgress).expect("optimize");
    let seconds = t.elapsed().as_secs_f64();
    let per_step = |stage: DrStage| {
        let s: Vec<f32> = r.loss_curve.iter().filter(|l| l.stage == stage).map(|l| l.seconds).collect();
        s.iter().sum::<f32>() / s.len().max(1) as f32
    };
    println!(
        "strands {strands}, segments {}, views {views}, {}x{height} px: guide step {:.2} s, child step {:.2} s, \
         DR {seconds:.1} s ({guide_steps} + {child_steps} steps, stride {}), peak {:.0} MiB",
        segments,
        height * 2 / 3,
        per_step(DrStage::Guides),
        per_step(DrStage::Children),
        opts.stride,
        peak_rss_mib()
    );
}
