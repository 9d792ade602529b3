//! The ringlet axes of curly hair ([`hairrecon_recon::curl::ringlet_axes`]) from the directed points
//! that `hairrecon reconstruct CAPTURE --out DIR --stop-after direction` (or later) saved: prints the
//! time, the points' mean downward component before and after, and (with ground truth) the
//! `axes` metric of the points' own directions and of the axes. `save=PATH` writes the axes as a
//! points PLY (`examples/init_stage` grows from it when it is `OUT/points_directed.ply`);
//! `scan=1` prints the downward component and the metric for pitch angles 0-80° and both hands;
//! `onto=R1,R2,...` (mm; needs ground truth) moves the hung axes' points onto the axes
//! ([`hairrecon_recon::curl::onto_axes`]) at each radius (0: not moved; a negative one moves them
//! the wrong way) and prints how far they lie from the centreline (over one turn) of the
//! ground-truth strand each was seen on (the nearest within 1.5 mm whose tangent lies within 20°).
//!
//! `cargo run --release -p hairrecon-recon --example curl_stage -- CAPTURE DIR [key=value ...]`
//! keys: `radius` (mm, 6.5), `period` (mm, 22), `hand` (1 or -1), `normal_sigma`, `axis_sigma` (mm),
//! `project=1` (flatten the tangents onto the surface before turning them: `CurlOptions::project_axes`),
//! `save`, `scan`, `onto`, `moved=1` (save the hung axes moved onto the axes at `radius`: what the
//! pipeline grows from).

use std::path::PathBuf;
use std::time::Instant;

use glam::Vec3;
use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_mesh, read_strands};
use hairrecon_core::StrandSet;
use hairrecon_recon::curl::{centreline, hang, mean_down, onto_axes, ringlet_axes, Curl, CurlOptions};
use hairrecon_recon::metrics::{gt_axes, score_axes, PointIndex};
use hairrecon_recon::pipeline::load_points;
use hairrecon_recon::points3d::OrientedPoints;
use rayon::prelude::*;

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
    let (mut save, mut scan, mut onto, mut moved) = (None, false, Vec::new(), false);
    for kv in &args[2..] {
        let (k, v) = kv.split_once('=').ok_or("arguments are key=value")?;
        match k {
            "save" => save = Some(PathBuf::from(v)),
            "moved" => moved = v == "1",
            "scan" => scan = v == "1",
            "onto" => {
                onto = v.split(',').map(|r| r.trim().parse::<f32>().map(|r| r / 1000.0)).collect::<Result<_, _>>()?
            }
            _ => {
                let f: f32 = v.parse()?;
                match k {
                    "radius" => curl.radius = f / 1000.0,
                    "period" => curl.period = f / 1000.0,
                    "hand" => curl.hand = f,
                    "normal_sigma" => opts.normal_sigma = f / 1000.0,
                    "axis_sigma" => opts.axis_sigma = f / 1000.0,
                    "project" => opts.project_axes = f != 0.0,
                    _ => return Err(format!("unknown key {k}").into()),
                }
            }
        }
    }
    curl.validate()?;
    let points = load_points(&dir, "points_directed.ply")?;
    let raw = read_mesh(&capture.raw_mesh)?;
    let turn_arc = curl.period / curl.pitch_angle().cos();
    let gt_strands = match capture.gt_strands.as_ref() {
        Some(p) => Some(read_strands(p)?),
        None => None,
    };
    let gt = gt_strands.as_ref().map(|s| gt_axes(s, turn_arc, 0.001));
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
    if !onto.is_empty() {
        let gt = gt_strands.as_ref().ok_or("onto= needs the capture's ground-truth strands")?;
        let own = OwnCentrelines::new(gt, turn_arc);
        let seen = own.seen_on(&points);
        let n_seen = seen.iter().filter(|s| s.is_some()).count();
        println!(
            "onto: {n_seen} of {} points seen on a ground-truth strand (1.5 mm, 20°); their distance to its centreline:",
            points.len()
        );
        for r in onto {
            let mut moved = hung.clone();
            onto_axes(&points, &mut moved, &Curl { radius: r.abs(), hand: curl.hand * r.signum(), ..curl });
            let mut d: Vec<f32> =
                seen.par_iter().zip(&moved.positions).filter_map(|(s, q)| s.map(|i| own.distance(i, *q))).collect();
            d.sort_by(f32::total_cmp);
            let share = |x: f32| 100.0 * d.partition_point(|v| *v < x) as f64 / d.len().max(1) as f64;
            println!(
                "  moved {:+5.1} mm: median {:5.2} mm, within 1 / 2 / 3 mm {:5.1} / {:5.1} / {:5.1}%",
                -r * 1000.0,
                d.get(d.len() / 2).copied().unwrap_or(f32::NAN) * 1000.0,
                share(0.001),
                share(0.002),
                share(0.003)
            );
        }
    }
    if let Some(path) = save {
        // `moved=1`: what the pipeline grows from (hung, moved onto the axes at the curl's radius).
        let axes = if moved {
            let mut m = hung.clone();
            onto_axes(&points, &mut m, &curl);
            m
        } else {
            axes
        };
        axes.save_ply(&path)?;
        println!("axes -> {}", path.display());
    }
    Ok(())
}

/// The ground truth's strands sampled every millimetre, each sample knowing its strand, and every
/// strand's centreline over one turn.
struct OwnCentrelines {
    index: PointIndex,
    strand_of: Vec<u32>,
    centres: Vec<Vec<Vec3>>,
}

impl OwnCentrelines {
    fn new(gt: &StrandSet, turn_arc: f32) -> Self {
        let (mut points, mut tangents, mut strand_of, mut centres) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for s in gt.iter() {
            let Some(c) = centreline(s, turn_arc, 0.001) else { continue };
            let Ok(one) = StrandSet::new(s.to_vec(), vec![s.len() as u32]).and_then(|x| x.resample_by_arclength(0.001))
            else {
                continue;
            };
            let r = one.points();
            for k in 0..r.len() {
                let (a, b) = (k.saturating_sub(1), (k + 1).min(r.len() - 1));
                points.push(r[k]);
                tangents.push((r[b] - r[a]).normalize_or_zero());
                strand_of.push(centres.len() as u32);
            }
            centres.push(c);
        }
        Self { index: PointIndex::new(points, tangents), strand_of, centres }
    }

    /// For each point, the strand it was seen on: the nearest of its 8 nearest samples within 1.5 mm
    /// whose tangent lies within 20° of the point's (undirected).
    fn seen_on(&self, points: &OrientedPoints) -> Vec<Option<u32>> {
        let c20 = 20f32.to_radians().cos();
        points
            .positions
            .par_iter()
            .zip(&points.directions)
            .map(|(p, d)| {
                self.index
                    .nearest(*p, 8)
                    .into_iter()
                    .find(|&(i, r)| r <= 0.0015 && self.index.tangents[i].dot(*d).abs() >= c20)
                    .map(|(i, _)| self.strand_of[i])
            })
            .collect()
    }

    /// Distance from `q` to the nearest sample of strand `i`'s centreline.
    fn distance(&self, i: u32, q: Vec3) -> f32 {
        self.centres[i as usize].iter().map(|c| c.distance(q)).fold(f32::INFINITY, f32::min)
    }
}
