//! Which curl do the images prefer? Sweeps helices of a grid of radii and periods (both hands) about
//! grown strands (`STRANDS`, e.g. `examples/init_stage` grown from `examples/curl_stage`'s axes)
//! and prints the image terms of the DR loss (`L_m`, `L_o`, as `dr_loss_probe` does) on a subset of
//! the strands and views.
//!
//! `cargo run --release -p hairrecon-recon --example curl_select -- CAPTURE DIR STRANDS [key=value ...]`
//! (`DIR`: a `hairrecon reconstruct` output with `orient2d/`) keys: `every` (strand subset, 5),
//! `views` (number of views, evenly spread, 12), `radii` and `periods` (mm, comma-separated);
//! `gt_orient=1` scores against the capture's `gt/orientation` maps instead of DIR's Gabor maps;
//! `plain=PATH` also scores those strands (e.g. the init grown from the points' own directions);
//! `out=PATH radius=R period=P hand=H` writes all the strands swept with that curl instead, at
//! phases fitted to `DIR/points_directed.ply` with `fit=1` (`fit_radius` mm, `fit_angle` degrees,
//! `fit_phases`), else at random phases. `window` (mm) is the arc over which a strand's centreline is
//! averaged (`CurlOptions::centre_window`; to sweep strands that are helices already, give one turn
//! of theirs, e.g. 46.4 for 6.5 mm / 22 mm).

use std::path::PathBuf;
use std::time::Instant;

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_mesh, read_strands};
use hairrecon_core::{Bvh, StrandSet};
use hairrecon_recon::curl::{fit_phases, sweep_helices, sweep_helices_at, Curl, CurlOptions, PointSupport};
use hairrecon_recon::dr::optimize::{image_terms, orientation_misfit};
use hairrecon_recon::dr::{DrOptions, DrTargets};
use hairrecon_recon::pipeline::{load_gt_orient2d, load_orient2d};
use hairrecon_recon::progress::NoProgress;

fn list(v: &str) -> Result<Vec<f32>, std::num::ParseFloatError> {
    v.split(',').map(|x| x.parse::<f32>()).collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        eprintln!("usage: curl_select CAPTURE DIR STRANDS [key=value ...]");
        std::process::exit(2);
    }
    let capture = Capture::load(&args[0])?;
    let dir = PathBuf::from(&args[1]);
    let (mut every, mut nviews) = (5usize, 12usize);
    let (mut radii, mut periods) = (vec![4.0f32, 6.5, 9.0], vec![15.0f32, 22.0, 30.0]);
    let mut out: Option<PathBuf> = None;
    let mut plain: Option<PathBuf> = None;
    let mut one = Curl { radius: 0.0065, period: 0.022, hand: 1.0 };
    let mut fit = false;
    let mut gt_orient = false;
    let mut co = CurlOptions::default();
    for kv in &args[3..] {
        let (k, v) = kv.split_once('=').ok_or("arguments are key=value")?;
        match k {
            "every" => every = v.parse()?,
            "views" => nviews = v.parse()?,
            "radii" => radii = list(v)?,
            "periods" => periods = list(v)?,
            "plain" => plain = Some(PathBuf::from(v)),
            "out" => out = Some(PathBuf::from(v)),
            "radius" => one.radius = v.parse::<f32>()? / 1000.0,
            "period" => one.period = v.parse::<f32>()? / 1000.0,
            "hand" => one.hand = v.parse()?,
            "fit" => fit = v == "1",
            "gt_orient" => gt_orient = v == "1",
            "fit_radius" => co.fit_radius = v.parse::<f32>()? / 1000.0,
            "fit_angle" => co.fit_angle_deg = v.parse()?,
            "fit_phases" => co.fit_phases = v.parse()?,
            "window" => co.centre_window = v.parse::<f32>()? / 1000.0,
            _ => return Err(format!("unknown key {k}").into()),
        }
    }
    let all = read_strands(&args[2])?;
    if let Some(path) = out {
        one.validate()?;
        let t = Instant::now();
        let phases = if fit {
            let pts = hairrecon_recon::pipeline::load_points(&dir, "points_directed.ply")?;
            let support = PointSupport::new(&pts, co.fit_radius, co.fit_angle_deg).ok_or("grid too large")?;
            let ph = fit_phases(&all, &one, &co, &support);
            let n = ph.iter().filter(|p| p.is_some()).count();
            println!("phases fitted for {n} of {} strands ({:.1} s)", ph.len(), t.elapsed().as_secs_f64());
            Some(ph)
        } else {
            None
        };
        let swept = sweep_helices_at(&all, &one, &co, 0, phases.as_deref())?;
        hairrecon_core::formats::write_strands(&path, &swept)?;
        println!("{} strands swept with {one:?} -> {}", swept.num_strands(), path.display());
        return Ok(());
    }
    let pick: Vec<usize> = (0..all.num_strands()).step_by(every.max(1)).collect();
    let strands = all.select(&pick);
    let maps = if gt_orient { load_gt_orient2d(&capture)? } else { load_orient2d(&capture, &dir)? };
    let head = match &capture.head_mesh {
        Some(h) => Some(Bvh::new(read_mesh(h)?)),
        None => None,
    };
    let t = Instant::now();
    let targets = DrTargets::from_capture(&capture, &maps, head.as_ref(), &NoProgress)?;
    let nv = targets.views.len();
    let views: Vec<usize> = (0..nviews.min(nv)).map(|i| i * nv / nviews.min(nv)).collect();
    println!("{} strands, views {views:?}, targets {:.1} s", strands.num_strands(), t.elapsed().as_secs_f64());
    let opts = DrOptions::default();
    let score = |set: &StrandSet| image_terms(set, &targets, &views, &opts);
    let (m, o) = score(&strands)?;
    println!("{:<24} {:>10} {:>10} {:>8}", "set", "L_m", "L_o", "misfit");
    println!(
        "{:<24} {:>10.2} {:>10.2} {:>8.4}",
        "as grown",
        m,
        o,
        orientation_misfit(&strands, &targets, &views, &opts)?
    );
    if let Some(p) = plain {
        let set = read_strands(p)?;
        let set = set.select(&(0..set.num_strands()).step_by(every.max(1)).collect::<Vec<_>>());
        let (m, o) = score(&set)?;
        println!("{:<24} {:>10.2} {:>10.2} {:>8.4}", "plain", m, o, orientation_misfit(&set, &targets, &views, &opts)?);
    }
    for hand in [1.0f32, -1.0] {
        for &r in &radii {
            for &p in &periods {
                let curl = Curl { radius: r / 1000.0, period: p / 1000.0, hand };
                let t = Instant::now();
                let swept = sweep_helices(&strands, &curl, &co, 0)?;
                let (m, o) = score(&swept)?;
                println!(
                    "{:<24} {:>10.2} {:>10.2} {:>8.4}   pitch {:4.1}°  ({:.1} s)",
                    format!("hand {hand:+} r {r} p {p}"),
                    m,
                    o,
                    orientation_misfit(&swept, &targets, &views, &opts)?,
                    curl.pitch_angle().to_degrees(),
                    t.elapsed().as_secs_f64()
                );
            }
        }
    }
    Ok(())
}
