//! The ringlet axes of curly hair ([`hairrecon_recon::curl::ringlet_axes`]) from the directed points
//! that `hairrecon reconstruct CAPTURE --out DIR --stop-after direction` (or later) saved: prints the
//! time, the points' mean downward component before and after, and (with ground truth) the
//! `axes` metric of the points' own directions and of the axes. `save=PATH` writes the axes as a
//! points PLY (`examples/init_stage` grows from it when it is `OUT/points_directed.ply`);
//! `scan=1` prints the downward component and the metric for pitch angles 0-80° and both hands.
//!
//! `cargo run --release -p hairrecon-recon --example curl_stage -- CAPTURE DIR [key=value ...]`
//! keys: `radius` (mm, 6.5), `period` (mm, 22), `hand` (1 or -1), `normal_sigma`, `axis_sigma` (mm),
//! `save`, `scan`.

use std::path::PathBuf;
use std::time::Instant;

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_mesh, read_strands};
use hairrecon_recon::curl::{hang, mean_down, ringlet_axes, Curl, CurlOptions};
use hairrecon_recon::metrics::{gt_axes, score_axes};
use hairrecon_recon::pipeline::load_points;
use hairrecon_recon::points3d::OrientedPoints;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: curl_stage CAPTURE DIR [key=value ...]");
        std::process::exit(2);
    }
    let capture = Capture::load(&args[0])?;
    let dir = PathBuf::from(&args[1]);
    let mut curl = Curl { radius: 0.0065, period: 0.022, hand: 1.0 };
    let mut opts = CurlOptions::default();
    let (mut save, mut scan) = (None, false);
    for kv in &args[2..] {
        let (k, v) = kv.split_once('=').ok_or("arguments are key=value")?;
        match k {
            "save" => save = Some(PathBuf::from(v)),
            "scan" => scan = v == "1",
            _ => {
                let f: f32 = v.parse()?;
                match k {
                    "radius" => curl.radius = f / 1000.0,
                    "period" => curl.period = f / 1000.0,
                    "hand" => curl.hand = f,
                    "normal_sigma" => opts.normal_sigma = f / 1000.0,
                    "axis_sigma" => opts.axis_sigma = f / 1000.0,
                    _ => return Err(format!("unknown key {k}").into()),
                }
            }
        }
    }
    curl.validate()?;
    let points = load_points(&dir, "points_directed.ply")?;
    let raw = read_mesh(&capture.raw_mesh)?;
    let turn_arc = curl.period / curl.pitch_angle().cos();
    let gt = match capture.gt_strands.as_ref() {
        Some(p) => Some(gt_axes(&read_strands(p)?, turn_arc, 0.001)),
        None => None,
    };
    let report = |name: &str, p: &OrientedPoints| {
        print!("{name:<28} down {:6.3}", mean_down(p));
        if let Some(g) = &gt {
            let s = score_axes(&p.positions, &p.directions, g, 0.002);
            print!(
                "  axes within 20°: {:5.1}% (directed {:5.1}%), median {:5.1}°, judged {}",
                s.within_20, s.directed_within_20, s.median_deg, s.judged
            );
        }
        println!();
    };
    println!("{} points; ground-truth axes over {:.1} mm of arc", points.len(), turn_arc * 1000.0);
    report("tangents", &points);
    let t = Instant::now();
    let axes = ringlet_axes(&points, &raw, &curl, &opts).ok_or("the grid would be too large")?;
    println!("axes: {:.2} s", t.elapsed().as_secs_f64());
    report(&format!("axes {curl:?}"), &axes);
    let mut hung = axes.clone();
    hang(&mut hung);
    report("axes, hung (curl::hang)", &hung);
    if scan {
        for hand in [1.0f32, -1.0] {
            for deg in [20.0f32, 40.0, 50.0, 55.0, 62.0, 70.0, 80.0] {
                let c = Curl { radius: curl.period * deg.to_radians().tan() / std::f32::consts::TAU, hand, ..curl };
                let a = ringlet_axes(&points, &raw, &c, &opts).ok_or("grid")?;
                report(&format!("hand {hand:+} pitch {deg}°"), &a);
            }
        }
    }
    if let Some(path) = save {
        axes.save_ply(&path)?;
        println!("axes -> {}", path.display());
    }
    Ok(())
}
