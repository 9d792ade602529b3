//! Oracle points for the init stage: directed points made from the ground truth instead of the
//! line MVS, to tell how much of the init's loss comes from the points and how much from growth
//! and interpolation (README, "where curly loses, by oracle points"). Writes
//! `OUT/points_directed.ply`, which `examples/init_stage CAPTURE OUT OUT2` then grows from.
//!
//! `cargo run --release -p hairrecon-recon --example oracle_points -- CAPTURE DIR OUT MODE`
//! (`DIR`: a `hairrecon reconstruct --stop-after direction` output). MODE:
//! - `all`: ground-truth points (every 2 mm along the strands, root to tip), thinned by a stride to
//!   at most 1,000,000;
//! - `near_mesh`: those within 1.5 mm of the raw mesh, thinned the same way;
//! - `near_ours`: those within 1 mm of one of `DIR/points_directed.ply`;
//! - `gt_tangents`: our positions, each with the tangent of the nearest ground-truth point;
//! - `gt_signs`: our positions and axes, each signed to agree with the nearest ground-truth point.

use std::path::PathBuf;

use glam::Vec3;
use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_mesh, read_strands};
use hairrecon_core::Bvh;
use hairrecon_recon::metrics::PointIndex;
use hairrecon_recon::pipeline::load_points;
use hairrecon_recon::points3d::OrientedPoints;
use rayon::prelude::*;

const MAX_POINTS: usize = 1_000_000;

fn thinned(points: Vec<Vec3>, tangents: Vec<Vec3>) -> OrientedPoints {
    let stride = points.len().div_ceil(MAX_POINTS).max(1);
    let positions: Vec<Vec3> = points.into_iter().step_by(stride).collect();
    let directions: Vec<Vec3> = tangents.into_iter().step_by(stride).collect();
    let confidence = vec![1.0; positions.len()];
    OrientedPoints { positions, directions, confidence }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() != 4 {
        eprintln!("usage: oracle_points CAPTURE DIR OUT all|near_mesh|near_ours|gt_tangents|gt_signs");
        std::process::exit(2);
    }
    const MODES: [&str; 5] = ["all", "near_mesh", "near_ours", "gt_tangents", "gt_signs"];
    if !MODES.contains(&args[3].as_str()) {
        return Err(format!("unknown mode {}; use one of {}", args[3], MODES.join(", ")).into());
    }
    let capture = Capture::load(&args[0])?;
    let dir = PathBuf::from(&args[1]);
    let out = PathBuf::from(&args[2]);
    let gt = read_strands(capture.gt_strands.as_ref().ok_or("the capture has no ground truth")?)?;
    let gt = PointIndex::from_strands(&gt, 0.002);
    let ours = || load_points(&dir, "points_directed.ply");
    let keep = |f: &(dyn Fn(Vec3) -> bool + Sync)| {
        let (p, t): (Vec<Vec3>, Vec<Vec3>) =
            (0..gt.len()).into_par_iter().filter(|&i| f(gt.points[i])).map(|i| (gt.points[i], gt.tangents[i])).unzip();
        println!("{} of {} ground-truth points kept", p.len(), gt.len());
        thinned(p, t)
    };
    let result = match args[3].as_str() {
        "all" => keep(&|_| true),
        "near_mesh" => {
            let raw = Bvh::new(read_mesh(&capture.raw_mesh)?);
            keep(&|p| raw.closest_point(p, 0.0015).is_some())
        }
        "near_ours" => {
            let o = ours()?;
            let index = PointIndex::new(o.positions, o.directions);
            keep(&|p| index.nearest(p, 1).first().is_some_and(|&(_, d)| d <= 0.001))
        }
        mode @ ("gt_tangents" | "gt_signs") => {
            let mut o = ours()?;
            let signs_only = mode == "gt_signs";
            o.directions = o
                .positions
                .par_iter()
                .zip(&o.directions)
                .map(|(&p, &d)| match gt.nearest(p, 1).first() {
                    Some(&(i, _)) if signs_only => {
                        if d.dot(gt.tangents[i]) < 0.0 {
                            -d
                        } else {
                            d
                        }
                    }
                    Some(&(i, _)) => gt.tangents[i],
                    None => d,
                })
                .collect();
            o
        }
        _ => unreachable!("modes are checked above"),
    };
    std::fs::create_dir_all(&out)?;
    result.save_ply(&out.join("points_directed.ply"))?;
    println!("{} points written to {}", result.positions.len(), out.join("points_directed.ply").display());
    Ok(())
}
