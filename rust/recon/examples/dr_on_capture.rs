//! DR strand optimization on the output of `hairrecon reconstruct CAPTURE --out DIR --stop-after
//! init`: reads `DIR/guides.hair`, `DIR/strands.hair` and `DIR/orient2d/*.exr`, optimizes, writes
//! `OUT/guides.hair` and `OUT/strands.hair`, and prints the metric table before and after (when the
//! capture has ground truth), the time per iteration, and how far the points moved (percentiles of
//! each point's distance from its start, after the finalization, and from its strand's starting
//! polyline: the move across the strand, without the slide along it of the final resampling).
//!
//! `cargo run --release -p hairrecon-recon --example dr_on_capture -- CAPTURE INIT_DIR OUT_DIR
//! [key=value ...]` with keys `guides_iters`, `children_iters`, `lr`, `lr_end`, `lambda`, `k`, `nw`, `width`,
//! `views`, `reparam`, `n`, `guide_opt`, `child_k`, `child_min_guide_fraction`,
//! `child_parting_reach`, `wm`, `wo`, `wc`, `wc_rel` (1: R_c against the stage's starting curvature), `keep_curls` (1: the
//! options the pipeline uses when the init carries curls, `DrOptions::keeping_curls`, applied after
//! the other keys, so it overrides `wc`/`wc_rel` and halves `lr`), `wl`, `seed`, `cg_tol`, `equalize`, `uniform` (0: per-coordinate
//! Adam), `aq` (the uniform Adam's quantile), `eval` (0: no metric table), `quiet` (1: the orientation
//! loss quiet around the partings of `INIT_DIR/partings.ply`, as the pipeline does), and `upscale` (an
//! integer: every view's camera and targets enlarged that many times, nearest neighbour, to time a step at a
//! larger image size, e.g. 2 for the paper preset's 341×512 from the test preset's 171×256).

use std::path::PathBuf;
use std::time::Instant;

use glam::Vec3;
use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_mesh, read_strands, write_strands};
use hairrecon_core::metric::{evaluate, MetricOptions};
use hairrecon_core::{Bvh, StrandSet};
use hairrecon_recon::dr::{optimize, DrOptions, DrTargets};
use hairrecon_recon::pipeline::load_orient2d;
use hairrecon_recon::progress::Progress;

struct Print;

impl Progress for Print {
    fn update(&self, stage: &str, fraction: f32, message: &str) {
        let pct = (fraction * 100.0).round() as u32;
        if pct % 10 == 0 {
            eprintln!("{stage} {pct}% {message}");
        }
    }
}

/// "10th …, median …, 90th …, 99th …, max …" of `d`.
fn percentiles(mut d: Vec<f32>) -> String {
    d.sort_by(f32::total_cmp);
    let q = |f: f64| d.get(((d.len().max(1) - 1) as f64 * f) as usize).copied().unwrap_or(0.0);
    format!("10th {:.3}, median {:.3}, 90th {:.3}, 99th {:.3}, max {:.3}", q(0.1), q(0.5), q(0.9), q(0.99), q(1.0))
}

/// Each point of `after`'s distance (mm) to its own strand's polyline in `before`: the move across
/// the strand. The pointwise distance also counts the slide along the strand of the final even
/// resampling, which leaves the curve (and the metric, which resamples by arc length) as it was: DR
/// with a zero learning rate moves the children of the paper curly init 3.8 mm pointwise at the
/// median and 0.0 mm across (session 31).
fn across_moves(before: &StrandSet, after: &StrandSet) -> Vec<f32> {
    use rayon::prelude::*;
    let strands: Vec<(&[Vec3], &[Vec3])> = before.iter().zip(after.iter()).collect();
    strands
        .par_iter()
        .flat_map_iter(|(s0, s1)| {
            s1.iter().map(move |p| {
                let d = if s0.len() < 2 {
                    s0.first().map_or(0.0, |a| (*p - *a).length())
                } else {
                    s0.windows(2)
                        .map(|w| {
                            let ab = w[1] - w[0];
                            let t = ((*p - w[0]).dot(ab) / ab.length_squared().max(1e-18)).clamp(0.0, 1.0);
                            (*p - (w[0] + ab * t)).length()
                        })
                        .fold(f32::INFINITY, f32::min)
                };
                d * 1e3
            })
        })
        .collect()
}

fn table(pred: &StrandSet, gt: &StrandSet) -> String {
    let opts = MetricOptions::default();
    evaluate(pred, gt, &opts).map(|r| r.table()).unwrap_or_else(|e| e.to_string())
}

/// Every view `s` times larger: K scaled (pixel centres kept), mask and orientation repeated,
/// the head depth cast again.
fn upscaled(t: &DrTargets, s: usize, head: Option<&Bvh>) -> Result<DrTargets, Box<dyn std::error::Error>> {
    use hairrecon_recon::dr::DrView;
    let mut views = Vec::new();
    for (i, v) in t.views.iter().enumerate() {
        let c = &v.camera;
        let (w, h) = (c.width() as usize, c.height() as usize);
        let mut k = c.k_rows();
        let sf = s as f32;
        k[0][0] *= sf;
        k[1][1] *= sf;
        k[0][1] *= sf;
        // Pixel centres at integers: x' = s·x + (s − 1)/2.
        k[0][2] = k[0][2] * sf + (sf - 1.0) / 2.0;
        k[1][2] = k[1][2] * sf + (sf - 1.0) / 2.0;
        let cam = hairrecon_core::Camera::new(k, c.r_rows(), c.t().to_array(), (w * s) as u32, (h * s) as u32)?;
        let (mut mask, mut orient) = (Vec::new(), Vec::new());
        for y in 0..h * s {
            for x in 0..w * s {
                let p = (y / s) * w + x / s;
                mask.push(v.mask[p]);
                orient.push(v.orientation[p]);
            }
        }
        let depth = head.map(|h| DrView::head_depth_map(&cam, h));
        views.push(DrView::new(i, cam, mask, orient, depth)?);
    }
    Ok(DrTargets { views })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        eprintln!("usage: dr_on_capture CAPTURE INIT_DIR OUT_DIR [key=value ...]");
        std::process::exit(2);
    }
    let capture = Capture::load(&args[0])?;
    let init = PathBuf::from(&args[1]);
    let out = PathBuf::from(&args[2]);
    let mut o = DrOptions::default();
    let mut diag = false;
    let mut upscale = 1usize;
    let mut eval = true;
    let mut keep_curls = false;
    let mut quiet = false;
    for kv in &args[3..] {
        let (k, v) = kv.split_once('=').ok_or("arguments are key=value")?;
        let f: f32 = v.parse()?;
        match k {
            "guides_iters" => o.iterations_guides = f as usize,
            "children_iters" => o.iterations_children = f as usize,
            "lr" => o.lr = f,
            "lr_end" => o.lr_end = f,
            "lambda" => o.lambda = f,
            "k" => o.k_neighbors = f as usize,
            "nw" => o.neighbor_weight = f,
            "width" => o.width_m = f,
            "views" => o.views_per_step = f as usize,
            "reparam" => o.reparam = f > 0.5,
            "n" => o.neighbor_reparam = f > 0.5,
            "guide_opt" => o.guide_opt = f > 0.5,
            "child_k" => o.child_blend.k = (f as usize).max(1),
            "child_min_guide_fraction" => o.child_blend.min_guide_fraction = f,
            "child_parting_reach" => o.child_blend.parting_reach = f,
            "wm" => o.weights.mask = f,
            "wo" => o.weights.orientation = f,
            "wc" => o.weights.curvature = f,
            "wl" => o.weights.length = f,
            "wc_rel" => o.curvature_relative = f > 0.5,
            "keep_curls" => keep_curls = f > 0.5,
            "quiet" => quiet = f > 0.5,
            "seed" => o.seed = f as u64,
            "project_every" => o.project_every = f as usize,
            "diag" => diag = f > 0.5,
            "upscale" => upscale = (f as usize).max(1),
            "cg_tol" => o.cg_tolerance = f,
            "eval" => eval = f > 0.5,
            "equalize" => o.equalize_at_end = f > 0.5,
            "uniform" => o.uniform_adam = f > 0.5,
            "aq" => o.adam_quantile = f,
            _ => return Err(format!("unknown key {k}").into()),
        }
    }
    if keep_curls {
        o = o.keeping_curls();
    }
    println!("{o:?}");
    let guides = read_strands(init.join("guides.hair"))?;
    let children = read_strands(init.join("strands.hair"))?;
    let maps = load_orient2d(&capture, &init)?;
    let scalp = Bvh::new(read_mesh(capture.scalp_mesh.as_ref().ok_or("the capture has no scalp mesh")?)?);
    let head = match &capture.head_mesh {
        Some(h) => Some(Bvh::new(read_mesh(h)?)),
        None => None,
    };
    let t = Instant::now();
    let mut targets = DrTargets::from_capture(&capture, &maps, head.as_ref(), &Print)?;
    if upscale > 1 {
        targets = upscaled(&targets, upscale, head.as_ref())?;
    }
    if quiet {
        let skin = hairrecon_recon::pipeline::load_points(&init, "partings.ply")?.positions;
        let p = hairrecon_recon::parting::PartingParams::default();
        let n = targets.quiet_partings(&hairrecon_core::scalp::Partings::new(skin, p.reach, p.strength));
        println!("orientation quiet around the partings: {n} pixels");
    }
    println!("targets: {} views in {:.2} s", targets.views.len(), t.elapsed().as_secs_f64());
    println!(
        "guides {} strands / {} points, children {} strands / {} points",
        guides.num_strands(),
        guides.num_points(),
        children.num_strands(),
        children.num_points()
    );
    if diag {
        // Mean rendered coverage of the initial children against the mean mask, per view.
        use hairrecon_raster::{channel, AaMethod, RasterSettings, Renderer, SegmentShape, Width};
        let segs = hairrecon_raster::strand_segments(&children);
        let settings =
            RasterSettings { width: Width::World(o.width_m), shape: SegmentShape::Quad, direction_3d: false };
        let mut r = Renderer::new(AaMethod::Ours);
        if let Some(h) = &head {
            let diag_deep = std::env::var("DEEP").is_ok();
            let n = children.num_points();
            let inside = children
                .points()
                .iter()
                .filter(|p| {
                    h.signed_distance(**p, 0.05)
                        .is_some_and(|d| d < o.head_clearance - if diag_deep { 0.004 } else { 0.0 })
                })
                .count();
            println!("{inside} of {n} child points are closer than the clearance to the head or inside it");
            for (name, set) in [("guides", &guides), ("children", &children)] {
                let f = hairrecon_recon::dr::finalize(set, &scalp, Some(h), o.head_clearance, false);
                let d: Vec<f32> = f.points().iter().zip(set.points()).map(|(a, b)| (*a - *b).length()).collect();
                let moved = d.iter().filter(|x| **x > 1e-6).count();
                let big = d.iter().filter(|x| **x > 0.003).count();
                let max = d.iter().fold(0.0f32, |a, b| a.max(*b));
                println!("finalize moves {moved} {name} points ({big} by more than 3 mm, at most {:.1} mm)", max * 1e3);
            }
        }
        for (i, v) in targets.views.iter().enumerate().step_by(4) {
            let img = r.forward(&v.camera, children.points(), &segs, settings)?;
            let cov: f32 = img.data.iter().skip(channel::COVERAGE).step_by(img.channels).sum();
            let mask: f32 = v.mask.iter().sum();
            // Alignment: overlap of where strands render (any coverage) and where the mask says hair.
            let (mut inter, mut uni, mut conf_in) = (0u32, 0u32, 0.0f32);
            for (p, m) in v.mask.iter().enumerate() {
                let (a, b) = (img.data[p * img.channels + channel::COVERAGE] > 0.0, *m > 0.1);
                inter += (a && b) as u32;
                uni += (a || b) as u32;
                if a {
                    conf_in += v.orientation[p][2];
                }
            }
            println!(
                "view {i}: rendered coverage {cov:.0} px, mask {mask:.0} px, IoU {:.2}, mean confidence under strands {:.3}",
                inter as f32 / uni.max(1) as f32,
                conf_in / cov.max(1.0)
            );
        }
    }
    let t = Instant::now();
    let r = optimize(&guides, &children, &targets, &scalp, head.as_ref(), &o, &Print)?;
    let secs = t.elapsed().as_secs_f64();
    let iters = r.loss_curve.len().max(1);
    println!(
        "DR: {iters} iterations in {secs:.1} s ({:.3} s per iteration, wall), mean CG iterations {:.1}",
        secs / iters as f64,
        r.mean_cg_iterations
    );
    let curve: Vec<String> = r
        .loss_curve
        .iter()
        .step_by((iters / 15).max(1))
        .map(|l| format!("{}{}:{:.2}", &l.stage.to_string()[..1], l.iteration, l.terms.total()))
        .collect();
    println!("loss curve: {}", curve.join(" "));
    for stage in [hairrecon_recon::dr::DrStage::Guides, hairrecon_recon::dr::DrStage::Children] {
        let s: Vec<f32> = r.loss_curve.iter().filter(|l| l.stage == stage).map(|l| l.seconds).collect();
        if !s.is_empty() {
            println!("{stage}: {} steps, {:.3} s per step (wall)", s.len(), s.iter().sum::<f32>() / s.len() as f32);
        }
    }
    for (name, a, b) in [("guides", &guides, &r.guides), ("children", &children, &r.children)] {
        let pointwise: Vec<f32> = a.points().iter().zip(b.points()).map(|(p, q)| (*p - *q).length() * 1e3).collect();
        println!("{name} points moved (mm): {}", percentiles(pointwise));
        println!("{name} points moved across their strand (mm): {}", percentiles(across_moves(a, b)));
    }
    std::fs::create_dir_all(&out)?;
    write_strands(out.join("guides.hair"), &r.guides)?;
    write_strands(out.join("strands.hair"), &r.children)?;
    hairrecon_recon::dr::report::write_loss_csv(&out.join("loss.csv"), &r.loss_curve)?;
    if let (Some(g), true) = (&capture.gt_strands, eval) {
        let gt = read_strands(g)?;
        println!("before DR (children):\n{}", table(&children, &gt));
        println!("after DR (children):\n{}", table(&r.children, &gt));
    }
    Ok(())
}
