//! Re-runs the global direction stage ([`hairrecon_recon::direction`]) on the oriented 3D points
//! that `hairrecon reconstruct CAPTURE --out DIR --stop-after orient3d` (or later) saved in
//! `DIR/points3d.ply`, with parameters given as `key=value`; writes `OUT/points_directed.ply` and
//! prints the time, the solver's statistics and the pipeline's `direction` metric (the share of the
//! points matched undirected at 2 mm/20° whose direction agrees with the ground truth). For tuning
//! the stage without re-running the others; `examples/init_stage CAPTURE OUT OUT2` then grows from
//! its output (copy or link `DIR/roots.ply` beside it if the init needs it).
//!
//! `cargo run --release -p hairrecon-recon --example direction_stage -- CAPTURE DIR OUT [key=value ...]`
//! keys: `k`, `max_edge`, `anchor_dist`, `anchor_min_cos`, `anchor_weight`, `gravity_weight`,
//! `gravity_min`, `side_weight`, `edge_scale`.

use std::path::PathBuf;
use std::time::Instant;

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_mesh, read_strands};
use hairrecon_core::scalp::Scalp;
use hairrecon_recon::direction::{global_directions, DirectionParams};
use hairrecon_recon::metrics::{score_directions, PointIndex};
use hairrecon_recon::points3d::OrientedPoints;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        eprintln!("usage: direction_stage CAPTURE DIR OUT [key=value ...]");
        std::process::exit(2);
    }
    let capture = Capture::load(&args[0])?;
    let dir = PathBuf::from(&args[1]);
    let out = PathBuf::from(&args[2]);
    std::fs::create_dir_all(&out)?;
    let mut p = DirectionParams::default();
    for kv in &args[3..] {
        let (k, v) = kv.split_once('=').ok_or("arguments are key=value")?;
        let f: f32 = v.parse()?;
        match k {
            "k" => p.k = f as usize,
            "max_edge" => p.max_edge = f,
            "anchor_dist" => p.anchor_dist = f,
            "anchor_min_cos" => p.anchor_min_cos = f,
            "anchor_weight" => p.anchor_weight = f,
            "gravity_weight" => p.gravity_weight = f,
            "gravity_min" => p.gravity_min = f,
            "side_weight" => p.side_weight = f,
            "edge_scale" => p.edge_scale = f,
            _ => return Err(format!("unknown key {k}").into()),
        }
    }
    println!("{p:?}");
    let points = OrientedPoints::load_ply(&dir.join("points3d.ply"))?;
    let scalp_path = capture.scalp_mesh.as_ref().ok_or("the capture has no scalp mesh")?;
    let scalp = Scalp::new(read_mesh(scalp_path)?)?;
    let t = Instant::now();
    let (directed, stats) = global_directions(&points, &scalp, &p);
    println!("direction: {:.1} s, {stats:?}", t.elapsed().as_secs_f64());
    directed.save_ply(&out.join("points_directed.ply"))?;
    if let Some(gt) = capture.gt_strands.as_ref() {
        let index = PointIndex::from_strands(&read_strands(gt)?, 0.001);
        let s = score_directions(&directed.positions, &directed.directions, &index, 0.002, 20f32.to_radians());
        println!("direction agreement {:.2}% of {} judged points", s.agreement, s.judged);
    }
    Ok(())
}
