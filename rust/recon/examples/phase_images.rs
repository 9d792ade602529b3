//! Can the images fix the helices' phases? Each strand of `STRANDS` becomes a helix of the given
//! curl about its own centreline (`curl::sweep_helices_at`), at the phase (of `phases` tried) whose
//! visible samples agree best with the 2D orientation maps: in each of `views` views, a helix sample
//! counts where it lies within `tol` mm of the visible surface's depth (the capture's `gt/depth`
//! maps: oracle visibility) and scores confidence × cos 2Δ, Δ the angle between its projected
//! tangent and the map's orientation. A strand none of whose samples is seen keeps a random phase.
//! Writes the helices at the fitted phases to `OUT` (and, with `random=PATH`, at random phases).
//!
//! `cargo run --release -p hairrecon-recon --example phase_images -- CAPTURE DIR STRANDS OUT
//! [key=value ...]` (`DIR`: a `hairrecon reconstruct` output with `orient2d/`) keys: `radius`,
//! `period` (mm; 6.5, 22), `hand` (1), `window` (mm of arc for the centreline; 46.4 = one turn of
//! 6.5 / 22, for strands that are helices already), `views` (16), `phases` (16), `tol` (mm; 1),
//! `gt_orient=1` (the capture's `gt/orientation` maps instead of DIR's Gabor maps), `random=PATH`.
//! A study tool (docs/curly-study.md, session 25), not part of the pipeline.

use std::path::PathBuf;
use std::time::Instant;

use glam::Vec3;
use hairrecon_core::camera::Camera;
use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_strands, write_strands};
use hairrecon_core::image_io::read_gray_f32;
use hairrecon_core::StrandSet;
use hairrecon_recon::curl::{sweep_helices_at, Curl, CurlOptions};
use hairrecon_recon::orient2d::OrientationMap;
use hairrecon_recon::pipeline::{load_gt_orient2d, load_orient2d};
use rayon::prelude::*;

struct SeenView {
    camera: Camera,
    depth: Vec<f32>,
    map: OrientationMap,
}

impl SeenView {
    /// Agreement (confidence × cos 2Δ) of a helix sample at `p` with unit tangent `t`, if it lies
    /// on the visible surface.
    fn agreement(&self, p: Vec3, t: Vec3, tol: f32) -> Option<f32> {
        let a = self.camera.project(p)?;
        let b = self.camera.project(p + t * 1e-3)?;
        let (w, h) = (self.camera.width() as i64, self.camera.height() as i64);
        let (xi, yi) = ((a.pixel.x + 0.5).floor() as i64, (a.pixel.y + 0.5).floor() as i64);
        if xi < 0 || yi < 0 || xi >= w || yi >= h {
            return None;
        }
        let z = self.depth[(yi * w + xi) as usize];
        if !(z.is_finite() && z > 0.0 && (a.depth - z).abs() < tol) {
            return None;
        }
        let (theta, conf) = self.map.sample(a.pixel.x, a.pixel.y);
        let d = (b.pixel - a.pixel).try_normalize()?;
        let (s, c) = theta.sin_cos();
        let cross = d.x * s - d.y * c;
        Some(conf * (1.0 - 2.0 * cross * cross))
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 4 {
        eprintln!("usage: phase_images CAPTURE DIR STRANDS OUT [key=value ...]");
        std::process::exit(2);
    }
    let capture = Capture::load(&args[0])?;
    let dir = PathBuf::from(&args[1]);
    let mut curl = Curl { radius: 0.0065, period: 0.022, hand: 1.0 };
    let mut co = CurlOptions { centre_window: 0.0464, ..CurlOptions::default() };
    let (mut nviews, mut nphases, mut tol, mut gt_orient) = (16usize, 16usize, 0.001f32, false);
    let mut random: Option<PathBuf> = None;
    for kv in &args[4..] {
        let (k, v) = kv.split_once('=').ok_or("arguments are key=value")?;
        match k {
            "radius" => curl.radius = v.parse::<f32>()? / 1000.0,
            "period" => curl.period = v.parse::<f32>()? / 1000.0,
            "hand" => curl.hand = v.parse()?,
            "window" => co.centre_window = v.parse::<f32>()? / 1000.0,
            "views" => nviews = v.parse()?,
            "phases" => nphases = v.parse()?,
            "tol" => tol = v.parse::<f32>()? / 1000.0,
            "gt_orient" => gt_orient = v == "1",
            "random" => random = Some(PathBuf::from(v)),
            _ => return Err(format!("unknown key {k}").into()),
        }
    }
    curl.validate()?;
    let maps = if gt_orient { load_gt_orient2d(&capture)? } else { load_orient2d(&capture, &dir)? };
    let nv = capture.views.len();
    let k = nviews.clamp(1, nv);
    let mut seen = Vec::new();
    for (i, map) in maps.into_iter().enumerate() {
        if !(0..k).any(|j| j * nv / k == i) {
            continue;
        }
        let v = &capture.views[i];
        let path = v.gt_depth.as_ref().ok_or_else(|| format!("view {} has no gt_depth", v.name))?;
        let depth = read_gray_f32(path)?.data;
        seen.push(SeenView { camera: v.camera, depth, map });
    }
    let all = read_strands(&args[2])?;
    let t = Instant::now();
    let one = |i: usize, phi: f32| -> Option<Vec<Vec3>> {
        let s = all.strand(i);
        let set = StrandSet::new(s.to_vec(), vec![s.len() as u32]).ok()?;
        let h = sweep_helices_at(&set, &curl, &co, 0, Some(&[Some(phi)])).ok()?;
        Some(h.points().to_vec())
    };
    let phases: Vec<Option<f32>> = (0..all.num_strands())
        .into_par_iter()
        .map(|i| {
            let mut best: Option<(f32, f32)> = None;
            for j in 0..nphases {
                let phi = j as f32 * std::f32::consts::TAU / nphases as f32;
                let h = one(i, phi)?;
                let (mut score, mut n) = (0.0f32, 0usize);
                for q in 1..h.len().saturating_sub(1) {
                    let Some(tq) = (h[q + 1] - h[q - 1]).try_normalize() else { continue };
                    for v in &seen {
                        if let Some(a) = v.agreement(h[q], tq, tol) {
                            score += a;
                            n += 1;
                        }
                    }
                }
                if n > 0 && best.is_none_or(|(s, _)| score > s) {
                    best = Some((score, phi));
                }
            }
            best.filter(|b| b.0 > 0.0).map(|b| b.1)
        })
        .collect();
    let fitted = phases.iter().filter(|p| p.is_some()).count();
    println!(
        "phases from the images for {fitted} of {} strands ({} views, {nphases} phases, {:.1} s)",
        all.num_strands(),
        seen.len(),
        t.elapsed().as_secs_f64()
    );
    write_strands(&args[3], &sweep_helices_at(&all, &curl, &co, 0, Some(&phases))?)?;
    println!("fitted -> {}", args[3]);
    if let Some(p) = random {
        write_strands(&p, &sweep_helices_at(&all, &curl, &co, 0, None)?)?;
        println!("random phases -> {}", p.display());
    }
    Ok(())
}
