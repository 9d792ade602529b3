//! Computes the 2D orientation maps ([`hairrecon_recon::orient2d`]) of a capture with Gabor
//! parameters given as `key=value` and prints their error against the capture's
//! `gt/orientation` maps (the pipeline's `orient2d` metric), and the time. For tuning the bank.
//!
//! `cargo run --release -p hairrecon-recon --example orient2d_stage -- CAPTURE [key=value ...]`
//! keys: `orientations`, `sigma`, `lambda`, `gamma`, `smooth` (the fields of `GaborParams`),
//! `mask_threshold` (default 0.1, as the pipeline), `views_every=n` (every n-th view only),
//! `out=DIR` (save the maps as `DIR/orient2d/<view>.exr`, as `hairrecon reconstruct` does, so
//! that the `points_stage` example can read them; needs `views_every=1`).

use std::path::PathBuf;
use std::time::Instant;

use hairrecon_core::capture::Capture;
use hairrecon_recon::orient2d::{
    load_mask, orientation_errors, summarize_errors, GaborBank, GaborParams, GrayImage, OrientationMap,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.is_empty() {
        eprintln!("usage: orient2d_stage CAPTURE [key=value ...]");
        std::process::exit(2);
    }
    let capture = Capture::load(&args[0])?;
    let mut g = GaborParams::default();
    let (mut thr, mut every, mut out) = (0.1f32, 1usize, None);
    for kv in &args[1..] {
        let (k, v) = kv.split_once('=').ok_or("arguments are key=value")?;
        if k == "out" {
            out = Some(PathBuf::from(v));
            continue;
        }
        let f: f32 = v.parse()?;
        match k {
            "orientations" => g.orientations = f as usize,
            "sigma" => g.sigma = f,
            "lambda" => g.lambda = f,
            "gamma" => g.gamma = f,
            "smooth" => g.smooth = f,
            "mask_threshold" => thr = f,
            "views_every" => every = (f as usize).max(1),
            _ => return Err(format!("unknown key {k}").into()),
        }
    }
    if out.is_some() && every != 1 {
        return Err("out= needs views_every=1".into());
    }
    if let Some(o) = &out {
        std::fs::create_dir_all(o.join("orient2d"))?;
    }
    let bank = GaborBank::new(g);
    let (mut errs, mut secs) = (Vec::new(), 0.0);
    for v in capture.views.iter().step_by(every) {
        let img = GrayImage::load(&v.image)?;
        let mask = match &v.mask {
            Some(m) => Some(load_mask(m, img.width, img.height, thr)?),
            None => None,
        };
        let t = Instant::now();
        let map = bank.compute(&img, mask.as_deref());
        secs += t.elapsed().as_secs_f64();
        if let Some(g) = &v.gt_orientation {
            errs.extend(orientation_errors(&map, &OrientationMap::load_exr(g)?));
        }
        if let Some(o) = &out {
            map.save_exr(&o.join("orient2d").join(format!("{}.exr", v.name)))?;
        }
    }
    let s = summarize_errors(errs);
    println!(
        "{g:?}: mean {:.2}°, confident half {:.2}°, {} px, filtering {secs:.1} s",
        s.mean_deg, s.mean_confident_half_deg, s.pixels
    );
    Ok(())
}
