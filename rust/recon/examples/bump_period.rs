//! The curls' period read off the hair surface's bumps ([`hairrecon_recon::curl::bump_period`]), from
//! the directed points that `hairrecon reconstruct CAPTURE --out DIR --stop-after direction` (or
//! later) saved, along the hung ringlet axes at the nominal pitch (as `--curl auto` makes them):
//! prints the time, the correlation by lag and the period.
//!
//! `cargo run --release -p hairrecon-recon --example bump_period -- CAPTURE DIR [key=value ...]`
//! keys: `hand` (1 or -1, default 1), `radius`, `strip` (mm), `samples`.

use std::path::PathBuf;
use std::time::Instant;

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::read_mesh;
use hairrecon_recon::curl::{bump_period, hang, ringlet_axes, BumpOptions, Curl, CurlOptions};
use hairrecon_recon::pipeline::load_points;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: bump_period CAPTURE DIR [key=value ...]");
        std::process::exit(2);
    }
    let capture = Capture::load(&args[0])?;
    let dir = PathBuf::from(&args[1]);
    let co = CurlOptions::default();
    let mut bo = BumpOptions::default();
    let mut hand = 1.0;
    for kv in &args[2..] {
        let (k, v) = kv.split_once('=').ok_or("give key=value")?;
        match k {
            "hand" => hand = v.parse()?,
            "radius" => bo.radius = v.parse::<f32>()? / 1000.0,
            "strip" => bo.strip = v.parse::<f32>()? / 1000.0,
            "samples" => bo.samples = v.parse()?,
            "diff" => bo.diff = v.parse()?,
            _ => return Err(format!("unknown key {k}").into()),
        }
    }
    let points = load_points(&dir, "points_directed.ply")?;
    let raw = read_mesh(&capture.raw_mesh)?;
    let period = co.periods[1];
    let nominal =
        Curl { radius: period * co.nominal_pitch_deg.to_radians().tan() / std::f32::consts::TAU, period, hand };
    let t = Instant::now();
    let mut axes = ringlet_axes(&points, &raw, &nominal, &co).ok_or("the grid would be too large")?;
    hang(&mut axes);
    let t_axes = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let rep = bump_period(&points.positions, &axes.directions, &bo);
    println!("axes {t_axes:.1} s, bumps {:.1} s, {} samples", t.elapsed().as_secs_f64(), rep.samples);
    let c: Vec<String> = rep.correlation.iter().map(|c| format!("{c:.2}")).collect();
    println!("correlation by mm: {}", c.join(" "));
    println!("first minimum {:?} mm, period {:?} mm", rep.first_min.map(|x| x * 1e3), rep.period.map(|x| x * 1e3));
    Ok(())
}
