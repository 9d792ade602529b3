//! Whether the directed 3D points can tell a good guide from a bad one: grows the guides in several
//! variants of the growth parameters on the flow and points a `--stop-after direction` (or whole)
//! run saved, scores every guide by its support (the share of its points, resampled every 1 mm, that
//! some directed point matches undirected at 2 mm/20°: no ground truth needed) and by its precision
//! against the ground truth (same threshold), prints how the two correlate, and scores the children
//! of each variant and of the guides picked per root by the highest support (and, as a ceiling, by
//! the ground truth).
//!
//! `cargo run --release -p hairrecon-recon --example guide_select -- CAPTURE DIR OUT VARIANT...`
//! where DIR holds `points_directed.ply` and `flow.bin`, and each VARIANT is `-` (the defaults) or
//! comma-separated `key=value` of `GrowParams` (`trace_weight`, `trace_radius`, `trace_pull`,
//! `trace_min_cos`, `trace_power`, `trace_trumps`, `max_climb`, `climb_after`, `max_turn_deg`, `step`).
//! A VARIANT `file=PATH` reads the guides from a .hair file instead (one per root, in order).
//! Environment: `CHILDREN` (10000), `GT_EVERY` (5), `GUIDES` (2000).

use std::path::PathBuf;

use glam::Vec3;
use rayon::prelude::*;

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_mesh, read_strands, write_strands};
use hairrecon_core::metric::{evaluate, MetricOptions};
use hairrecon_core::StrandSet;
use hairrecon_recon::grow::{grow_guides, interpolate_children, GrowParams};
use hairrecon_recon::laplace::FlowField;
use hairrecon_recon::metrics::{sample_strands, PointIndex};
use hairrecon_recon::pipeline::load_points;
use hairrecon_recon::progress::NoProgress;
use hairrecon_recon::roots::{sample_roots, Scalp};

fn env(k: &str, d: usize) -> usize {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}

fn variant(spec: &str) -> Result<GrowParams, Box<dyn std::error::Error>> {
    let mut gp = GrowParams::default();
    if spec == "-" || spec.starts_with("file=") {
        return Ok(gp);
    }
    for kv in spec.split(',') {
        let (k, v) = kv.split_once('=').ok_or("key=value")?;
        let f: f32 = v.parse()?;
        match k {
            "trace_weight" => gp.trace_weight = f,
            "trace_radius" => gp.trace_radius = f,
            "trace_pull" => gp.trace_pull = f,
            "trace_min_cos" => gp.trace_min_cos = f,
            "trace_power" => gp.trace_power = f,
            "max_climb" => gp.max_climb = f,
            "trace_trumps" => gp.trace_trumps = f,
            "climb_after" => gp.climb_after = f,
            "max_turn_deg" => gp.max_turn = f.to_radians(),
            "step" => gp.step = f,
            _ => return Err(format!("unknown key {k}").into()),
        }
    }
    Ok(gp)
}

/// Share of a strand's 1 mm samples that `index` matches undirected at 2 mm/20°.
fn matched_share(s: &[Vec3], index: &PointIndex) -> f32 {
    let one = StrandSet::new(s.to_vec(), vec![s.len() as u32]).unwrap_or_else(|_| StrandSet::empty());
    let (p, t) = sample_strands(&one, 0.001);
    if p.is_empty() {
        return 0.0;
    }
    let hit = p.iter().zip(&t).filter(|(p, t)| index.match_undirected(**p, **t, 0.002, 20f32.to_radians()).is_some());
    hit.count() as f32 / p.len() as f32
}

fn pearson(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len() as f32;
    let (ma, mb) = (a.iter().sum::<f32>() / n, b.iter().sum::<f32>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt().max(1e-12)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 4 {
        eprintln!("usage: guide_select CAPTURE DIR OUT VARIANT...");
        std::process::exit(2);
    }
    let capture = Capture::load(&args[0])?;
    let dir = PathBuf::from(&args[1]);
    let out = PathBuf::from(&args[2]);
    std::fs::create_dir_all(&out)?;
    let variants: Vec<GrowParams> = args[3..].iter().map(|s| variant(s)).collect::<Result<_, _>>()?;
    let scalp = Scalp::new(read_mesh(capture.scalp_mesh.as_ref().ok_or("no scalp")?)?)?;
    let flow = FlowField::load(&dir.join("flow.bin"))?;
    let points = load_points(&dir, "points_directed.ply")?;
    let trace = PointIndex::new(points.positions.clone(), points.directions.clone());
    let groots = sample_roots(&scalp, env("GUIDES", 2000), 0)?;
    let croots = sample_roots(&scalp, env("CHILDREN", 10000), 1)?;
    let gt_all = read_strands(capture.gt_strands.as_ref().ok_or("no ground truth")?)?;
    let gt_index = PointIndex::from_strands(&gt_all, 0.001);
    let every = env("GT_EVERY", 5).max(1);
    let gt = gt_all.select(&(0..gt_all.num_strands()).step_by(every).collect::<Vec<_>>());
    let opts = MetricOptions::default();
    let f1 = |children: &StrandSet| -> Result<(f64, f64, f64), Box<dyn std::error::Error>> {
        let r = evaluate(children, &gt, &opts)?;
        let s = &r.undirected[1];
        let d = &r.directed[1];
        Ok((s.precision, s.recall, s.f1 - d.f1))
    };
    let mut grown: Vec<StrandSet> = Vec::new();
    let mut support: Vec<Vec<f32>> = Vec::new();
    let mut truth: Vec<Vec<f32>> = Vec::new();
    for (vi, gp) in variants.iter().enumerate() {
        // `file=PATH`: guides read from a .hair file (one per guide root, in the roots' order).
        let guides = match args[3 + vi].strip_prefix("file=") {
            Some(path) => read_strands(path)?,
            None => grow_guides(&flow, Some(&trace), &groots, gp, &NoProgress)?.0,
        };
        if guides.num_strands() != groots.len() {
            return Err(format!("variant {vi}: {} guides for {} roots", guides.num_strands(), groots.len()).into());
        }
        let mean_length =
            (0..guides.num_strands()).map(|g| guides.strand_length(g) as f64).sum::<f64>() / groots.len() as f64;
        let share = |index: &PointIndex| -> Vec<f32> {
            (0..guides.num_strands()).into_par_iter().map(|g| matched_share(guides.strand(g), index)).collect()
        };
        let (sup, tru) = (share(&trace), share(&gt_index));
        let children = interpolate_children(&guides, &croots, Some(&flow), gp, &NoProgress)?;
        let (p, r, gap) = f1(&children)?;
        let f = 2.0 * p * r / (p + r).max(1e-9);
        println!(
            "variant {vi} ({}): mean length {:.3} m, support {:.3}, truth {:.3}, corr {:.3}; children P/R/F1 {p:.1} / {r:.1} / {f:.1} (directed gap {gap:.1})",
            args[3 + vi],
            mean_length,
            sup.iter().sum::<f32>() / sup.len() as f32,
            tru.iter().sum::<f32>() / tru.len() as f32,
            pearson(&sup, &tru),
        );
        write_strands(out.join(format!("guides_{vi}.hair")), &guides)?;
        grown.push(guides);
        support.push(sup);
        truth.push(tru);
    }
    if variants.len() < 2 {
        return Ok(());
    }
    for (name, by) in [("support", &support), ("truth (ceiling)", &truth)] {
        let (mut pts, mut counts) = (Vec::new(), Vec::new());
        let mut picks = vec![0usize; variants.len()];
        for g in 0..groots.len() {
            let v = (0..variants.len()).max_by(|&a, &b| by[a][g].total_cmp(&by[b][g])).unwrap_or(0);
            picks[v] += 1;
            let s = grown[v].strand(g);
            pts.extend_from_slice(s);
            counts.push(s.len() as u32);
        }
        let guides = StrandSet::new(pts, counts)?;
        let children = interpolate_children(&guides, &croots, Some(&flow), &variants[0], &NoProgress)?;
        let (p, r, gap) = f1(&children)?;
        let f = 2.0 * p * r / (p + r).max(1e-9);
        println!("picked by {name}: {picks:?}; children P/R/F1 {p:.1} / {r:.1} / {f:.1} (directed gap {gap:.1})");
    }
    Ok(())
}
