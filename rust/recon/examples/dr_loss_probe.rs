//! Does the DR objective prefer the ground truth? Evaluates the image terms of the DR loss (`L_m`,
//! `L_o`, as `optimize` sees them, width 0.2 mm) on several strand sets over every view of a
//! capture, without optimizing, and prints their means. If the ground truth's loss is not clearly
//! below the init's, DR has nothing to descend toward.
//!
//! `cargo run --release -p hairrecon-recon --example dr_loss_probe -- CAPTURE DIR SET... [gt_orient=1]`
//! (`DIR`: a `hairrecon reconstruct` output with `orient2d/`; `SET`: `.hair` files, `gt` for the
//! capture's ground truth; `gt_orient=1` scores against the capture's `gt/orientation` maps instead
//! of DIR's Gabor maps).

use std::path::PathBuf;

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_mesh, read_strands};
use hairrecon_core::Bvh;
use hairrecon_recon::dr::optimize::image_terms;
use hairrecon_recon::dr::{DrOptions, DrTargets};
use hairrecon_recon::orient2d::OrientationMap;
use hairrecon_recon::pipeline::{load_gt_orient2d, load_orient2d};
use hairrecon_recon::progress::Progress;

struct Quiet;

impl Progress for Quiet {
    fn update(&self, _stage: &str, _fraction: f32, _message: &str) {}
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        eprintln!("usage: dr_loss_probe CAPTURE DIR SET... [gt_orient=1]");
        std::process::exit(2);
    }
    let capture = Capture::load(&args[0])?;
    let dir = PathBuf::from(&args[1]);
    let gt_orient = args.iter().any(|a| a == "gt_orient=1");
    let sets: Vec<&String> = args[2..].iter().filter(|a| !a.contains('=')).collect();
    let maps: Vec<OrientationMap> =
        if gt_orient { load_gt_orient2d(&capture)? } else { load_orient2d(&capture, &dir)? };
    let head = match &capture.head_mesh {
        Some(h) => Some(Bvh::new(read_mesh(h)?)),
        None => None,
    };
    let targets = DrTargets::from_capture(&capture, &maps, head.as_ref(), &Quiet)?;
    let opts = DrOptions::default();
    let nv = targets.views.len();
    let all_views: Vec<usize> = (0..nv).collect();
    println!("{} views, orientation targets: {}", nv, if gt_orient { "gt/orientation" } else { "DIR/orient2d" });
    println!("{:<48} {:>10} {:>12} {:>12} {:>10}", "set", "strands", "L_m", "L_o", "L_m+L_o");
    for s in sets {
        let path = if s == "gt" {
            capture.gt_strands.clone().ok_or("the capture has no ground-truth strands")?
        } else {
            PathBuf::from(s)
        };
        let set = read_strands(&path)?;
        let (lm, lo) = image_terms(&set, &targets, &all_views, &opts)?;
        println!("{:<48} {:>10} {:>12.2} {:>12.2} {:>10.2}", s, set.num_strands(), lm, lo, lm + lo);
    }
    Ok(())
}
