//! Curly study (docs/curly-study.md, session 26): do centrelines come nearer the ringlets' axes when
//! each of their samples is moved toward the local mean of the points moved onto the axes
//! (`points_axes.ply`), across the strand (a mean shift toward the ridge of the points' density)?
//!
//! `cargo run --release -p hairrecon-recon --example centre_refine -- AXES.ply CENTRES OUT [key=value ...]`
//! (`CENTRES`: centrelines, e.g. `scripts/curl_resynth.py STRANDS CENTRES 46.4 6.5 22 hand=0`) keys:
//! `radius` (mm, 2.5: the neighbourhood), `angle` (degrees, 30: points whose axis is this close to
//! the strand's tangent count), `iters` (5), `rate` (1: the share of the mean offset taken per
//! iteration), `smooth` (mm, 4: the offsets are averaged along the strand over a Gaussian of this
//! σ), `min_weight` (1: less support and the sample stays), `gt=GT_CENTRES` also prints how far the
//! axes' points lie from the ground truth's centrelines (1 mm / 10° precision and recall); with
//! `gt`, `split=1` prints instead how `CENTRES` match the ground truth's centrelines by distance to
//! the axes' points (seen or hidden), and their angles to the axes and to the ground truth;
//! `pca=R1,R2,...` (mm) how far the axes' directions and the main direction of their points within
//! each radius lie from the ground truth's centrelines; `oracle=OUT.ply:NEAR` (mm) writes the ground
//! truth's centreline samples (every 2nd, those within NEAR of an axes' point; 0: all) as directed
//! points for `examples/init_stage`. Score OUT with `hairrecon eval --pred OUT --gt GT_CENTRES`.
//! Findings: docs/curly-study.md, session 26.

use std::path::PathBuf;
use std::time::Instant;

use glam::Vec3;
use hairrecon_core::formats::{read_strands, write_strands};
use hairrecon_core::StrandSet;
use hairrecon_recon::metrics::PointIndex;
use hairrecon_recon::points3d::OrientedPoints;
use rayon::prelude::*;

struct Params {
    radius: f32,
    cos_min: f32,
    iters: usize,
    rate: f32,
    smooth: f32,
    min_weight: f32,
}

fn tangents(s: &[Vec3]) -> Vec<Vec3> {
    let n = s.len();
    (0..n).map(|i| (s[(i + 1).min(n - 1)] - s[i.saturating_sub(1)]).normalize_or_zero()).collect()
}

/// Gaussian average of `v` along the strand (σ in samples), each sample's own weight `w`.
fn smooth_along(v: &[Vec3], w: &[f32], sigma: f32) -> Vec<Vec3> {
    if sigma <= 0.0 {
        return v.to_vec();
    }
    let half = (3.0 * sigma).ceil() as isize;
    let n = v.len() as isize;
    (0..n)
        .map(|i| {
            let (mut acc, mut ws) = (Vec3::ZERO, 0.0f32);
            for j in (i - half).max(0)..=(i + half).min(n - 1) {
                let d = (j - i) as f32 / sigma;
                let g = (-0.5 * d * d).exp() * w[j as usize];
                acc += g * v[j as usize];
                ws += g;
            }
            if ws > 0.0 {
                acc / ws
            } else {
                Vec3::ZERO
            }
        })
        .collect()
}

fn refine(s: &[Vec3], index: &PointIndex, conf: &[f32], p: &Params, step: f32) -> Vec<Vec3> {
    let mut s = s.to_vec();
    let n = s.len();
    for _ in 0..p.iters {
        let t = tangents(&s);
        let mut off = vec![Vec3::ZERO; n];
        let mut wt = vec![0.0f32; n];
        for i in 1..n {
            let (mut acc, mut ws) = (Vec3::ZERO, 0.0f32);
            for k in index.within(s[i], p.radius) {
                let c = index.tangents[k].dot(t[i]).abs();
                if c < p.cos_min {
                    continue;
                }
                let d = index.points[k] - s[i];
                let across = d - d.dot(t[i]) * t[i];
                let g = (-0.5 * d.length_squared() / (0.5 * p.radius).powi(2)).exp() * conf[k];
                acc += g * across;
                ws += g;
            }
            if ws >= p.min_weight {
                off[i] = acc / ws;
                wt[i] = 1.0;
            }
        }
        let off = smooth_along(&off, &wt, p.smooth / step);
        // The root stays: the move grows over the first centimetre.
        for i in 1..n {
            let ramp = (i as f32 * step / 0.01).min(1.0);
            s[i] += p.rate * ramp * off[i];
        }
    }
    s
}

/// How far the axes' directions, and the main direction of the axes' points within each radius
/// of `radii`, lie from the ground truth's centrelines (their samples within 1 mm).
fn print_pca(a: &PointIndex, g: &PointIndex, radii: &[f32]) {
    let report = |name: &str, dirs: &[Vec3]| {
        let mut ang: Vec<f32> =
            a.points.par_iter().zip(dirs).step_by(7).filter_map(|(p, t)| to_min_angle(g, *p, *t)).collect();
        let within10 = ang.iter().filter(|&&x| x <= 10.0).count() as f32 / ang.len().max(1) as f32;
        let n = ang.len();
        println!(
            "{name}: {n} points near a GT centreline; angle {}, within 10° {:.1}%",
            quantiles(&mut ang),
            100.0 * within10
        );
    };
    report("axes' directions", &a.tangents);
    for &r in radii {
        let dirs: Vec<Vec3> = a
            .points
            .par_iter()
            .zip(&a.tangents)
            .map(|(p, t)| {
                let nb = a.within(*p, r);
                let c = nb.iter().map(|&k| a.points[k]).sum::<Vec3>() / nb.len().max(1) as f32;
                let mut m = glam::Mat3::ZERO;
                for &k in &nb {
                    let d = a.points[k] - c;
                    m += glam::Mat3::from_cols(d * d.x, d * d.y, d * d.z);
                }
                // Power iteration from the axis direction.
                let mut v = *t;
                for _ in 0..20 {
                    v = (m * v).normalize_or(*t);
                }
                v
            })
            .collect();
        report(&format!("main direction within {:.1} mm", 1000.0 * r), &dirs);
    }
}

/// The share of `from`'s points that one of `to` matches at 1 mm/10°, undirected.
fn matched_share(from: &PointIndex, to: &PointIndex) -> f32 {
    let a10 = 10f32.to_radians();
    let n = from
        .points
        .par_iter()
        .zip(&from.tangents)
        .filter(|(q, d)| to.match_undirected(**q, **d, 0.001, a10).is_some())
        .count();
    n as f32 / from.len().max(1) as f32
}

/// "quartiles a / b / c°, 90% d°" of `v` (sorted in place).
fn quantiles(v: &mut [f32]) -> String {
    v.sort_by(f32::total_cmp);
    let q = |f: f32| v.get(((v.len().max(1) - 1) as f32 * f) as usize).copied().unwrap_or(f32::NAN);
    format!("quartiles {:.1} / {:.1} / {:.1}°, 90% {:.1}°", q(0.25), q(0.5), q(0.75), q(0.9))
}

/// The smallest angle (degrees, undirected) between `t` and the tangents of `g`'s samples within 1 mm of `p`.
fn to_min_angle(g: &PointIndex, p: Vec3, t: Vec3) -> Option<f32> {
    g.within(p, 0.001)
        .into_iter()
        .map(|k| g.tangents[k].dot(t).abs().min(1.0).acos().to_degrees())
        .min_by(f32::total_cmp)
}

/// Precision and recall at 1 mm/10° of the centrelines `c` against the ground truth's `g`, split by
/// how far each sample lies from the nearest point of the axes (`a`): near the seen surface or not.
fn print_split(a: &PointIndex, g: &PointIndex, c: &PointIndex) {
    let edges = [0.0f32, 0.002, 0.004, 0.008, 1.0];
    let a10 = 10f32.to_radians();
    let bucket = |p: Vec3| {
        let d = a.nearest(p, 1).first().map_or(1.0, |n| n.1);
        edges.windows(2).position(|w| d >= w[0] && d < w[1]).unwrap_or(edges.len() - 2)
    };
    let mut ang: Vec<f32> = c.points.par_iter().zip(&c.tangents).filter_map(|(p, t)| to_min_angle(g, *p, *t)).collect();
    let mut to_axes: Vec<f32> = c
        .points
        .par_iter()
        .zip(&c.tangents)
        .step_by(5)
        .filter_map(|(p, t)| {
            let nb = a.within(*p, 0.0015);
            let m = nb.iter().map(|&k| a.tangents[k] * a.tangents[k].dot(*t).signum()).sum::<Vec3>();
            (nb.len() >= 3).then(|| m.normalize_or(*t).dot(*t).abs().min(1.0).acos().to_degrees())
        })
        .collect();
    println!(
        "our samples with 3+ axes' points within 1.5 mm ({}): angle to their mean direction, {}",
        to_axes.len(),
        quantiles(&mut to_axes)
    );
    println!(
        "our samples with a GT sample within 1 mm ({}): smallest angle to one, {}",
        ang.len(),
        quantiles(&mut ang)
    );
    for (name, from, to) in [("recall (GT samples)", g, c), ("precision (our samples)", c, g)] {
        let hits: Vec<(usize, bool, bool)> = from
            .points
            .par_iter()
            .zip(&from.tangents)
            .map(|(p, t)| {
                (bucket(*p), to.match_undirected(*p, *t, 0.001, a10).is_some(), !to.within(*p, 0.001).is_empty())
            })
            .collect();
        println!("{name}, by distance to the nearest axes' point:");
        for b in 0..edges.len() - 1 {
            let n = hits.iter().filter(|h| h.0 == b).count();
            let k = hits.iter().filter(|h| h.0 == b && h.1).count();
            let kp = hits.iter().filter(|h| h.0 == b && h.2).count();
            println!(
                "  {:>3.0}-{:<4.0} mm: {:5.1}% of samples, {:5.1}% matched at 1 mm/10°, {:5.1}% within 1 mm",
                1000.0 * edges[b],
                1000.0 * edges[b + 1],
                100.0 * n as f32 / hits.len() as f32,
                100.0 * k as f32 / n.max(1) as f32,
                100.0 * kp as f32 / n.max(1) as f32
            );
        }
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        eprintln!("usage: centre_refine AXES.ply CENTRES OUT [key=value ...]");
        std::process::exit(2);
    }
    let axes = OrientedPoints::load_ply(&PathBuf::from(&args[0]))?;
    let centres = read_strands(&args[1])?;
    let out = PathBuf::from(&args[2]);
    let mut p = Params {
        radius: 0.0025,
        cos_min: 30f32.to_radians().cos(),
        iters: 5,
        rate: 1.0,
        smooth: 0.004,
        min_weight: 1.0,
    };
    let mut gt: Option<PathBuf> = None;
    let mut split = false;
    let mut pca: Vec<f32> = Vec::new();
    let mut oracle: Option<(PathBuf, f32)> = None;
    for kv in &args[3..] {
        let (k, v) = kv.split_once('=').ok_or("arguments are key=value")?;
        match k {
            "radius" => p.radius = v.parse::<f32>()? / 1000.0,
            "angle" => p.cos_min = v.parse::<f32>()?.to_radians().cos(),
            "iters" => p.iters = v.parse()?,
            "rate" => p.rate = v.parse()?,
            "smooth" => p.smooth = v.parse::<f32>()? / 1000.0,
            "min_weight" => p.min_weight = v.parse()?,
            "gt" => gt = Some(PathBuf::from(v)),
            "oracle" => {
                let (path, near) = v.split_once(':').ok_or("oracle=OUT.ply:NEAR_MM")?;
                oracle = Some((PathBuf::from(path), near.parse::<f32>()? / 1000.0));
            }
            "split" => split = v == "1",
            "pca" => pca = v.split(',').map(|x| x.parse::<f32>().map(|r| r / 1000.0)).collect::<Result<_, _>>()?,
            _ => return Err(format!("unknown key {k}").into()),
        }
    }
    let index = PointIndex::new(axes.positions.clone(), axes.directions.clone());
    if let Some(gt) = gt {
        let g = PointIndex::from_strands(&read_strands(&gt)?, 0.001);
        if let Some((path, near)) = oracle {
            // The ground truth's centreline samples as directed points (every 2nd, so about as
            // dense as the line MVS's), those within `near` of an axes' point (0: all).
            let keep: Vec<usize> = (0..g.len())
                .into_par_iter()
                .step_by(2)
                .filter(|&i| near <= 0.0 || !index.within(g.points[i], near).is_empty())
                .collect();
            let pts = OrientedPoints {
                positions: keep.iter().map(|&i| g.points[i]).collect(),
                directions: keep.iter().map(|&i| g.tangents[i]).collect(),
                confidence: vec![1.0; keep.len()],
            };
            pts.save_ply(&path)?;
            println!("{} oracle points -> {}", pts.len(), path.display());
            return Ok(());
        }
        if !pca.is_empty() {
            print_pca(&index, &g, &pca);
            return Ok(());
        }
        if split {
            print_split(&index, &g, &PointIndex::from_strands(&centres, 0.001));
            return Ok(());
        }
        let (prec, rec) = (matched_share(&index, &g), matched_share(&g, &index));
        println!(
            "axes' points vs GT centrelines at 1 mm/10°: precision {:.1}%, recall {:.1}%",
            100.0 * prec,
            100.0 * rec
        );
    }
    let step = 0.001;
    let centres = centres.resample_by_arclength(step)?;
    let t0 = Instant::now();
    let refined: Vec<Vec<Vec3>> = (0..centres.num_strands())
        .into_par_iter()
        .map(|i| refine(centres.strand(i), &index, &axes.confidence, &p, step))
        .collect();
    let counts = refined.iter().map(|s| s.len() as u32).collect();
    let set = StrandSet::new(refined.into_iter().flatten().collect(), counts)?;
    let moved: f32 = set.points().iter().zip(centres.points()).map(|(a, b)| (*a - *b).length()).sum::<f32>()
        / set.num_points() as f32;
    println!(
        "{} strands refined in {:.1} s; mean move {:.2} mm",
        set.num_strands(),
        t0.elapsed().as_secs_f32(),
        1000.0 * moved
    );
    write_strands(&out, &set)?;
    Ok(())
}
