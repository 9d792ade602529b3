//! What cutting strands at the visual hull ([`hairrecon_recon::hull`]) does to a strand set: prints
//! the trim statistics and, with ground truth in the capture, the metric table before and after;
//! writes the cut strands to OUT when given.
//!
//! `cargo run --release -p hairrecon-recon --example hull_check -- CAPTURE STRANDS [OUT] [margin=1]
//! [min_views=1] [mask_threshold=0.1] [near_scalp=0.004] [root_grace=0.02]` (the scalp mesh of the
//! capture, when it has one, spares the points by the roots as in the pipeline).

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_mesh, read_strands, write_strands};
use hairrecon_core::metric::{evaluate, MetricOptions};
use hairrecon_core::Bvh;
use hairrecon_recon::hull::{HullParams, VisualHull};
use hairrecon_recon::progress::NoProgress;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!(
            "usage: hull_check CAPTURE STRANDS [OUT] [margin=1] [min_views=1] [mask_threshold=0.1] \
             [near_scalp=0.004] [root_grace=0.02]"
        );
        std::process::exit(2);
    }
    let capture = Capture::load(&args[0])?;
    let set = read_strands(&args[1])?;
    let mut params = HullParams::default();
    let mut out = None;
    for a in &args[2..] {
        match a.split_once('=') {
            Some(("margin", v)) => params.margin_px = v.parse()?,
            Some(("min_views", v)) => params.min_views = v.parse()?,
            Some(("mask_threshold", v)) => params.mask_threshold = v.parse()?,
            Some(("near_scalp", v)) => params.near_scalp = v.parse()?,
            Some(("root_grace", v)) => params.root_grace = v.parse()?,
            Some((k, _)) => return Err(format!("unknown key {k}").into()),
            None => out = Some(a.clone()),
        }
    }
    let head = capture.head_mesh.as_ref().map(read_mesh).transpose()?.map(Bvh::new);
    let t = std::time::Instant::now();
    let scalp = capture.scalp_mesh.as_ref().map(read_mesh).transpose()?.map(Bvh::new);
    let hull = VisualHull::from_capture(&capture, head.as_ref(), params, "hull", &NoProgress)?
        .ok_or("no view of the capture has a solid hair mask")?
        .with_scalp(scalp);
    let t_build = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let (cut, stats) = hull.trim(&set);
    println!(
        "{params:?}\n{stats:?}: {:.2}% of the points removed; hull {t_build:.1} s, trim {:.1} s",
        100.0 * stats.points_removed as f64 / stats.points.max(1) as f64,
        t.elapsed().as_secs_f64()
    );
    if let Some(o) = out {
        write_strands(&o, &cut)?;
    }
    if let Some(g) = &capture.gt_strands {
        let gt = read_strands(g)?;
        let opts = MetricOptions::default();
        println!("before:\n{}", evaluate(&set, &gt, &opts)?.table());
        println!("after:\n{}", evaluate(&cut, &gt, &opts)?.table());
    }
    Ok(())
}
