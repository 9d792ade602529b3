//! Re-runs the strand initialization (Laplace flow, guide growth, children) on the directed points
//! that `hairrecon reconstruct CAPTURE --out DIR --stop-after direction` saved, with parameters
//! given as `key=value`, and prints the growth statistics, the time and the metric table of the
//! children against the capture's ground truth. For tuning the init stage without re-running the
//! earlier ones.
//!
//! `cargo run --release -p hairrecon-recon --example init_stage -- CAPTURE DIR OUT [key=value ...]`
//! keys: `guides`, `children`, `voxel`, `max_point_dist`, `scalp_dist`, `band`, `outer_margin`,
//! `gravity`, `trace_radius`, `trace_weight`, `trace_pull`, `step`, `max_gap`, `exit_cos`, `max_length`, `grow_budget`, `k`, `root_gap`, `smooth_sigma` (and the other `GrowParams` fields), `gt_every` (score against every n-th
//! ground-truth strand only, for speed). Environment: `GT_VOLUME=1` prints how much of the ground
//! truth lies in the hair volume and inside the raw mesh; `START_ANGLES=1` how guides and ground truth
//! leave the scalp; `DEBUG_ROOTS=1` prints the start of every 200th guide (`DEBUG_EVERY=N`: every N-th); `GT_GUIDES=1` replaces
//! the guides by the ground-truth strands rooted nearest their roots, to score the children's
//! interpolation alone. The tips' histogram by stop reason grows the guides without free starts
//! unless `FREE_STARTS=1` (then as the pipeline does); `TIPS_CSV=PATH` writes each guide's tip and
//! stop reason; `ZIGZAG=1` prints the mean turn between consecutive steps of the grown guides
//! (before smoothing) by depth under the outer surface and clearance from the head.

use std::path::PathBuf;
use std::time::Instant;

use glam::Vec3;

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_mesh, read_strands, write_strands};
use hairrecon_core::metric::{evaluate, MetricOptions};
use hairrecon_core::Bvh;
use hairrecon_recon::grow::{grow_guides, grow_one, interpolate_children, smooth_guides, GrowParams, Stop};
use hairrecon_recon::laplace::{solve_flow, LaplaceParams};
use hairrecon_recon::metrics::PointIndex;
use hairrecon_recon::pipeline::load_points;
use hairrecon_recon::progress::NoProgress;
use hairrecon_recon::roots::{sample_roots, scalp_point, Scalp};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        eprintln!("usage: init_stage CAPTURE DIR OUT [key=value ...]");
        std::process::exit(2);
    }
    let capture = Capture::load(&args[0])?;
    let dir = PathBuf::from(&args[1]);
    let out = PathBuf::from(&args[2]);
    std::fs::create_dir_all(&out)?;
    let (mut guides_n, mut children_n, mut gt_every) = (2000usize, 10000usize, 1usize);
    let mut lp = LaplaceParams::default();
    let mut gp = GrowParams::default();
    for kv in &args[3..] {
        let (k, v) = kv.split_once('=').ok_or("arguments are key=value")?;
        let f: f32 = v.parse()?;
        match k {
            "guides" => guides_n = f as usize,
            "children" => children_n = f as usize,
            "voxel" => lp.voxel = f,
            "max_point_dist" => lp.max_point_dist = f,
            "scalp_dist" => lp.scalp_dist = f,
            "band" => lp.band = f,
            "outer_margin" => lp.outer_margin = f,
            "scalp_tangent" => lp.scalp_tangent = f,
            "gravity" => lp.gravity = f,
            "step" => gp.step = f,
            "grow_outer" => gp.outer_margin = f,
            "max_gap" => gp.max_gap = f,
            "exit_cos" => gp.exit_cos = f,
            "exit_after" => gp.exit_after = f,
            "loop_window" => gp.loop_window = f,
            "loop_distance" => gp.loop_distance = f,
            "escape_length" => gp.escape_length = f,
            "escape_gravity" => gp.escape_gravity = f,
            "max_escapes" => gp.max_escapes = f as u32,
            "trace_radius" => gp.trace_radius = f,
            "trace_weight" => gp.trace_weight = f,
            "trace_pull" => gp.trace_pull = f,
            "trace_min_cos" => gp.trace_min_cos = f,
            "trace_power" => gp.trace_power = f,
            "max_turn_deg" => gp.max_turn = f.to_radians(),
            "max_length" => gp.max_length = f,
            "grow_budget" => gp.grow_budget = f,
            "k" => gp.blend.k = f as usize,
            "min_guide_fraction" => gp.blend.min_guide_fraction = f,
            "parting_reach" => gp.blend.parting_reach = f,
            "smooth_sigma" => gp.smooth_sigma = f,
            "root_gap" => gp.root_gap = f,
            "max_climb" => gp.max_climb = f,
            "trace_trumps" => gp.trace_trumps = f,
            "climb_after" => gp.climb_after = f,
            "smooth_lo" => gp.smooth_angles_deg[0] = f,
            "smooth_hi" => gp.smooth_angles_deg[1] = f,
            "gt_every" => gt_every = (f as usize).max(1),
            _ => return Err(format!("unknown key {k}").into()),
        }
    }
    let raw = Bvh::new(read_mesh(&capture.raw_mesh)?);
    let scalp = Scalp::new(read_mesh(capture.scalp_mesh.as_ref().ok_or("no scalp")?)?)?;
    let inner = match &capture.head_mesh {
        Some(h) => Bvh::new(read_mesh(h)?),
        None => scalp.bvh().clone(),
    };
    let points = load_points(&dir, "points_directed.ply")?;
    if std::env::var_os("SD_LOW").is_some() {
        let mut sd: Vec<f32> = points
            .positions
            .iter()
            .filter(|p| p.z < -0.3)
            .step_by(50)
            .map(|p| raw.signed_distance(*p, 0.04).unwrap_or(1.0))
            .collect();
        sd.sort_by(f32::total_cmp);
        let q = |f: f32| sd[((sd.len() - 1) as f32 * f) as usize];
        println!("sd of low points (n {}): q10 {} q50 {} q90 {}", sd.len(), q(0.1), q(0.5), q(0.9));
    }
    let t = Instant::now();
    let (flow, lstats) = solve_flow(&raw, &inner, &scalp, &points, &lp, &NoProgress)?;
    let t_flow = t.elapsed().as_secs_f64();
    let groots = sample_roots(&scalp, guides_n, 0)?;
    let croots = sample_roots(&scalp, children_n, 1)?;
    let t = Instant::now();
    let trace = (gp.trace_radius > 0.0).then(|| PointIndex::new(points.positions.clone(), points.directions.clone()));
    let (guides, gstats) = grow_guides(&flow, trace.as_ref(), &groots, &gp, &NoProgress)?;
    if std::env::var_os("ZIGZAG").is_some() {
        // The turn between consecutive steps of the grown guides (before smoothing), by the
        // step's depth under the outer surface and its clearance from the head.
        let mut bins = std::collections::BTreeMap::<String, (f64, u64)>::new();
        for g in guides.iter() {
            for w in g.windows(3) {
                let (a, b) = ((w[1] - w[0]).normalize_or_zero(), (w[2] - w[1]).normalize_or_zero());
                let turn = a.dot(b).clamp(-1.0, 1.0).acos().to_degrees() as f64;
                let so = flow.grid.trilinear(&flow.sd_outer, w[1]).unwrap_or(f32::NAN);
                let si = flow.grid.trilinear(&flow.sd_inner, w[1]).unwrap_or(f32::NAN);
                let ko = if so > -0.001 {
                    "outer>-1mm"
                } else if so > -0.004 {
                    "outer -4..-1mm"
                } else {
                    "outer<-4mm"
                };
                let ki = if si < 0.003 { "head<3mm" } else { "head>3mm" };
                let e = bins.entry(format!("{ko:>15} {ki}")).or_default();
                e.0 += turn;
                e.1 += 1;
            }
        }
        for (k, (sum, n)) in &bins {
            println!("  zigzag {k}: {n} steps, mean turn {:.1} deg", sum / (*n).max(1) as f64);
        }
    }
    let (guides, sstats) = smooth_guides(&guides, trace.as_ref(), Some(&flow), &gp);
    println!("smooth: {sstats:?}");
    let gt = capture.gt_strands.as_ref().map(read_strands).transpose()?;
    // `GT_GUIDES=1`: the guides replaced by the ground-truth strand rooted nearest each guide root,
    // moved onto it, to measure what the children's interpolation alone loses.
    let guides = match gt.as_ref().filter(|_| std::env::var_os("GT_GUIDES").is_some()) {
        Some(gt) => {
            let index = PointIndex::new(gt.iter().map(|s| s[0]).collect(), vec![Vec3::Z; gt.num_strands()]);
            let mut pts = Vec::new();
            let mut counts = Vec::new();
            for &r in &groots.positions {
                let (g, _) = index.nearest(r, 1)[0];
                let s = gt.strand(g);
                pts.extend(s.iter().map(|&p| p - s[0] + r));
                counts.push(s.len() as u32);
            }
            hairrecon_core::StrandSet::new(pts, counts)?
        }
        None => guides,
    };
    let children = interpolate_children(&guides, &croots, Some(&flow), &gp, &NoProgress)?;
    let t_grow = t.elapsed().as_secs_f64();
    println!("laplace: {lstats:?} ({t_flow:.1} s)");
    // Where the guides stop, by reason: a histogram of the tip height (10 cm bins from -0.5 m).
    // Tips of the guides as grown without free starts.
    let fixed = if std::env::var_os("FREE_STARTS").is_some() { gp } else { GrowParams { root_gap: 0.0, ..gp } };
    let mut hist = std::collections::BTreeMap::<String, [u32; 8]>::new();
    // `TIPS_CSV=PATH`: every guide's tip and why it stopped (x,y,z,reason,points).
    let mut tips_csv = String::from("x,y,z,reason,points\n");
    for i in 0..groots.len() {
        let (pts, stop) = grow_one(&flow, trace.as_ref(), groots.positions[i], groots.growth[i], &fixed);
        let z = pts.last().map_or(0.0, |p| p.z);
        let b = (((z + 0.5) / 0.1).floor().max(0.0) as usize).min(7);
        let key = match stop {
            Stop::Outside => "outside",
            Stop::NotHair => "not_hair",
            Stop::Grid => "grid",
            Stop::MaxLength => "max_length",
            Stop::Loop => "loop",
        };
        hist.entry(key.into()).or_default()[b] += 1;
        if let Some(t) = pts.last() {
            tips_csv.push_str(&format!("{},{},{},{},{}\n", t.x, t.y, t.z, key, pts.len()));
        }
    }
    if let Some(path) = std::env::var_os("TIPS_CSV") {
        std::fs::write(path, &tips_csv)?;
    }
    for (k, h) in &hist {
        println!("  tips {k:>10} by z from -0.5 m: {h:?}");
    }
    // Where the guides start: roots whose voxel is not hair, or that the raw mesh's signed distance
    // puts outside it (both stop or deflect a guide's first steps). `DEBUG_ROOTS=1` also prints
    // every 200th root: S, normal, field, distances and the first segments of its guide.
    let not_hair = |p: Vec3| flow.grid.voxel_of(p).is_none_or(|v| flow.label[v] == 0);
    let outside_raw = |p: Vec3| flow.grid.trilinear(&flow.sd_outer, p).is_none_or(|d| d > 0.0);
    let no_hair = groots.positions.iter().filter(|&&p| not_hair(p)).count();
    let outside = groots.positions.iter().filter(|&&p| outside_raw(p)).count();
    println!("guide roots: {no_hair} in no hair voxel, {outside} outside the raw mesh, of {}", groots.len());
    if let Some(gt) = gt.as_ref().filter(|_| std::env::var_os("GT_VOLUME").is_some()) {
        // How much of the ground truth the hair volume holds (every 37th point), by distance from
        // the head: in no hair voxel, and outside the raw mesh by the flow's signed distance.
        let (mut n, mut no_hair, mut out) = (0usize, 0usize, 0usize);
        let mut by_depth = [[0usize; 2]; 6];
        for &p in gt.points().iter().step_by(37) {
            let o = outside_raw(p);
            let b = ((flow.grid.trilinear(&flow.sd_inner, p).unwrap_or(1.0) / 0.01).max(0.0) as usize).min(5);
            n += 1;
            no_hair += not_hair(p) as usize;
            out += o as usize;
            by_depth[b][0] += 1;
            by_depth[b][1] += o as usize;
        }
        println!("gt points: {n} sampled, {no_hair} in no hair voxel, {out} outside the raw mesh");
        for (b, c) in by_depth.iter().enumerate() {
            let share = 100.0 * c[1] as f64 / c[0].max(1) as f64;
            println!("  {b}-{} cm from the head: {} points, {share:.1}% outside", b + 1, c[0]);
        }
    }
    if let Some(gt) = gt.as_ref().filter(|_| std::env::var_os("START_ANGLES").is_some()) {
        // How strands leave the scalp: the median angle between S(p_s) at the root and the chord
        // from the root to the point 2 mm and 2 cm along the strand, guides against ground truth.
        let chord_angles = |strands: &hairrecon_core::StrandSet, every: usize| -> [f32; 2] {
            let mut a: [Vec<f32>; 2] = [Vec::new(), Vec::new()];
            for s in strands.iter().step_by(every) {
                let Some(sp) = scalp_point(&scalp, s[0], 0.002) else { continue };
                let mut arc = 0.0;
                let mut done = [false; 2];
                for w in s.windows(2) {
                    arc += w[0].distance(w[1]);
                    for (k, at) in [0.002f32, 0.02].into_iter().enumerate() {
                        if !done[k] && arc >= at - 1e-6 {
                            done[k] = true;
                            a[k].push(
                                (w[1] - s[0]).normalize_or_zero().dot(sp.growth).clamp(-1.0, 1.0).acos().to_degrees(),
                            );
                        }
                    }
                }
            }
            a.map(|mut v| {
                v.sort_by(f32::total_cmp);
                v.get(v.len() / 2).copied().unwrap_or(f32::NAN)
            })
        };
        let [g2, g20] = chord_angles(&guides, 1);
        let [t2, t20] = chord_angles(gt, 10);
        println!("start: median angle of the chord to 2 mm / 2 cm from S(p_s): guides {g2:.1}° / {g20:.1}°, ground truth {t2:.1}° / {t20:.1}°");
    }
    if std::env::var_os("DEBUG_ROOTS").is_some() {
        let every = std::env::var("DEBUG_EVERY").ok().and_then(|v| v.parse().ok()).unwrap_or(200usize);
        for i in (0..groots.len()).step_by(every) {
            let p = groots.positions[i];
            let (pts, _) = grow_one(&flow, trace.as_ref(), p, groots.growth[i], &fixed);
            let field = flow.grid.trilinear(&flow.field, p).unwrap_or(Vec3::ZERO).normalize_or_zero();
            let so = flow.grid.trilinear(&flow.sd_outer, p).unwrap_or(f32::NAN);
            let si = flow.grid.trilinear(&flow.sd_inner, p).unwrap_or(f32::NAN);
            let segs: Vec<String> =
                pts.windows(2).take(4).map(|w| format!("{:.2?}", (w[1] - w[0]).normalize())).collect();
            println!(
                "root {i} at {p:.3?}: S {:.2?} normal {:.2?} field {field:.2?} sd_outer {so:.4} sd_inner {si:.4} segments {}",
                groots.growth[i],
                groots.normals[i],
                segs.join(" ")
            );
        }
    }
    println!("grow: {gstats:?} ({t_grow:.1} s)");
    write_strands(out.join("guides.hair"), &guides)?;
    flow.save(&out.join("flow.bin"))?;
    write_strands(out.join("strands.hair"), &children)?;
    if let Some(gt) = &gt {
        let gt = gt.select(&(0..gt.num_strands()).step_by(gt_every).collect::<Vec<_>>());
        let opts = MetricOptions::default();
        let t = Instant::now();
        let r = evaluate(&children, &gt, &opts)?;
        println!("children vs gt ({:.1} s):\n{}", t.elapsed().as_secs_f64(), r.table());
    }
    Ok(())
}
