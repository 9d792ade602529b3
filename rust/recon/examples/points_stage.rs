//! Re-runs the oriented 3D points stage (line MVS, [`hairrecon_recon::points3d`]) on the 2D
//! orientation maps that `hairrecon reconstruct CAPTURE --out DIR --stop-after orient2d` saved,
//! with parameters given as `key=value`, and prints the time, the number of points, their
//! precision and coverage at 2 mm/20° (the pipeline's `orient3d` metric) and where the misses are
//! (position or direction). For tuning the stage without re-running the others.
//!
//! `cargo run --release -p hairrecon-recon --example points_stage -- CAPTURE DIR [key=value ...]`
//! keys: every numeric field of `LineMvsParams` (`depth_offsets` as `lo:hi:step` in mm), plus
//! - `surface_every=n`: coverage over every n-th visible ground-truth point only (default 10; the
//!   pipeline uses all, 1);
//! - `gt_orient=1`: use the capture's `gt/orientation` maps instead of DIR's (the 2D error's share);
//! - `oracle=1`: also score the ground-truth depth maps back-projected at every hair pixel with the
//!   nearest ground-truth tangent (the coverage that perfect points at every pixel would reach);
//! - `save=PATH`: write the points as a PLY.

use std::path::PathBuf;
use std::time::Instant;

use glam::{Vec2, Vec3};
use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_mesh, read_strands};
use hairrecon_core::Bvh;
use hairrecon_recon::metrics::{score_points, PointIndex};
use hairrecon_recon::orient2d::{GrayImage, OrientationMap};
use hairrecon_recon::pipeline::{load_gt_orient2d, load_orient2d};
use hairrecon_recon::points3d::{estimate, LineMvsParams, MvsView};
use hairrecon_recon::progress::NoProgress;
use hairrecon_recon::raw_mesh::load_depth_views;
use rayon::prelude::*;

const DIST: f32 = 0.002;
const SURFACE_BAND: f32 = 0.003;

/// Share of points whose nearest ground-truth point is beyond `DIST`, and of those within it whose
/// best direction is off by more than 20°, plus the median distance (mm).
fn miss_breakdown(pos: &[Vec3], dir: &[Vec3], gt: &PointIndex) -> (f64, f64, f64) {
    let cmin = 20f32.to_radians().cos();
    let r: Vec<(f32, bool)> = pos
        .par_iter()
        .zip(dir)
        .map(|(p, d)| {
            let near = gt.nearest(*p, 1).first().map_or(f32::INFINITY, |n| n.1);
            let dir_ok = gt.within(*p, DIST).into_iter().any(|i| gt.tangents[i].dot(*d).abs() >= cmin);
            (near, dir_ok)
        })
        .collect();
    let n = r.len().max(1) as f64;
    let far = r.iter().filter(|x| x.0 > DIST).count() as f64;
    let bad_dir = r.iter().filter(|x| x.0 <= DIST && !x.1).count() as f64;
    let mut d: Vec<f32> = r.iter().map(|x| x.0).collect();
    d.sort_by(f32::total_cmp);
    let med = d.get(d.len() / 2).copied().unwrap_or(f32::NAN) as f64 * 1e3;
    (100.0 * far / n, 100.0 * bad_dir / n, med)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: points_stage CAPTURE DIR [key=value ...]");
        std::process::exit(2);
    }
    let capture = Capture::load(&args[0])?;
    let dir = PathBuf::from(&args[1]);
    let mut p = LineMvsParams::default();
    let (mut surface_every, mut gt_orient, mut oracle, mut save) = (10usize, false, false, None);
    for kv in &args[2..] {
        let (k, v) = kv.split_once('=').ok_or("arguments are key=value")?;
        if k == "save" {
            save = Some(PathBuf::from(v));
            continue;
        }
        if k == "depth_offsets" {
            let r: Vec<f32> = v.split(':').map(str::parse).collect::<Result<_, _>>()?;
            let [lo, hi, step] = r[..] else { return Err("depth_offsets=lo:hi:step (mm)".into()) };
            let n = ((hi - lo) / step).round() as i32;
            p.depth_offsets = (0..=n).map(|k| (lo + k as f32 * step) * 1e-3).collect();
            continue;
        }
        let f: f32 = v.parse()?;
        match k {
            "stride" => p.stride = f as usize,
            "neighbours" => p.neighbours = f as usize,
            "max_view_angle_deg" => p.max_view_angle_deg = f,
            "depth_prior" => p.depth_prior = f,
            "angle_steps" => p.angle_steps = f as usize,
            "min_confidence" => p.min_confidence = f,
            "max_cost" => p.max_cost = f,
            "min_agree" => p.min_agree = f as usize,
            "agree_angle_deg" => p.agree_angle_deg = f,
            "visibility_margin" => p.visibility_margin = f,
            "segment_half_px" => p.segment_half_px = f,
            "fit_direction" => p.fit_direction = f != 0.0,
            "segment_samples" => p.segment_samples = f as usize,
            "patchmatch_iters" => p.patchmatch_iters = f as usize,
            "patchmatch_photo" => p.patchmatch_photo = f,
            "bilinear_orientation" => p.bilinear_orientation = f != 0.0,
            "surface_every" => surface_every = (f as usize).max(1),
            "gt_orient" => gt_orient = f != 0.0,
            "oracle" => oracle = f != 0.0,
            _ => return Err(format!("unknown key {k}").into()),
        }
    }
    let raw = Bvh::new(read_mesh(&capture.raw_mesh)?);
    let maps: Vec<OrientationMap> =
        if gt_orient { load_gt_orient2d(&capture)? } else { load_orient2d(&capture, &dir)? };
    let images: Vec<GrayImage> = capture.views.iter().map(|v| GrayImage::load(&v.image)).collect::<Result<_, _>>()?;
    let views = MvsView::for_capture(&capture, &maps, &images);

    let t = Instant::now();
    let pts = estimate(&views, &raw, &p, &NoProgress)?;
    let secs = t.elapsed().as_secs_f64();
    if let Some(path) = &save {
        pts.save_ply(path)?;
    }

    let strands = read_strands(capture.gt_strands.as_ref().ok_or("the capture has no gt_strands")?)?;
    let gt = PointIndex::from_strands(&strands, 0.001);
    let surface: Vec<usize> = (0..gt.len())
        .into_par_iter()
        .filter(|&i| i % surface_every == 0)
        .filter(|&i| raw.signed_distance(gt.points[i], 0.02).is_some_and(|d| d > -SURFACE_BAND))
        .collect();
    let angle = 20f32.to_radians();
    let s = score_points(&pts.positions, &pts.directions, &gt, &surface, DIST, angle);
    let (far, bad_dir, med) = miss_breakdown(&pts.positions, &pts.directions, &gt);
    println!(
        "points {} precision {:.2} coverage {:.2} (surface 1/{surface_every}: {}) time {secs:.1} s",
        s.points, s.precision, s.coverage, s.surface_points
    );
    println!("misses: {far:.1}% farther than 2 mm, {bad_dir:.1}% near but off by > 20°; median distance {med:.2} mm");

    if oracle {
        let depths = load_depth_views(&capture.dir, None)?;
        let mut op = Vec::new();
        for ((_, dv), m) in depths.iter().zip(&maps) {
            let w = m.width as usize;
            for (i, &d) in dv.depth.iter().enumerate() {
                if m.confidence[i] > 0.0 && d.is_finite() && d > 0.0 {
                    op.push(dv.camera.back_project(Vec2::new((i % w) as f32, (i / w) as f32), d));
                }
            }
        }
        let od: Vec<Vec3> =
            op.par_iter().map(|p| gt.nearest(*p, 1).first().map_or(Vec3::X, |n| gt.tangents[n.0])).collect();
        let s = score_points(&op, &od, &gt, &surface, DIST, angle);
        println!(
            "oracle (gt depth at every hair pixel): points {} precision {:.2} coverage {:.2}",
            s.points, s.precision, s.coverage
        );
    }
    Ok(())
}
