//! Where along the strands the metric is won and lost: precision of the predicted points and recall
//! of the ground-truth points at 2 mm/20°, directed and undirected, per bin of arc length from the
//! root (points resampled every 1 mm, as the metric does).
//!
//! `cargo run --release -p hairrecon-core --example metric_by_arc -- PRED GT [BIN_CM]` (default bins
//! of 4 cm). A bin's precision is the share of the predicted points in it that some ground-truth point
//! matches; its recall the share of the ground-truth points in it that some predicted point matches;
//! the overall figures are those of `hairrecon eval` at 2 mm/20°. Environment: `DIST_MM`, `ANGLE_DEG`
//! (another threshold), `MAX_CM` (only the bins below; the overall line then covers those bins).

use glam::Vec3;
use hairrecon_core::formats::read_strands;
use hairrecon_core::metric::{OrientedPoints, Threshold};
use hairrecon_core::StrandSet;

/// Oriented points per arc-length bin (the resampled strands' points, bin = index × step / bin).
/// With `by_root` (environment `BY_ROOT=1`), points within the first `bin` of arc are binned instead
/// by their root's place: 8 sectors of azimuth about the roots' centre (0: +x, counter-clockwise
/// seen from +z) times 3 bands of height.
fn by_bin(
    set: &StrandSet,
    step: f32,
    bin: f32,
    by_root: bool,
) -> Result<Vec<OrientedPoints>, Box<dyn std::error::Error>> {
    let r = set.resample_by_arclength(step)?;
    let t = r.tangents();
    let roots: Vec<Vec3> = r.iter().map(|s| s[0]).collect();
    let c = roots.iter().copied().sum::<Vec3>() / roots.len().max(1) as f32;
    let (zmin, zmax) = roots.iter().fold((f32::MAX, f32::MIN), |(a, b), p| (a.min(p.z), b.max(p.z)));
    let mut bins: Vec<(Vec<Vec3>, Vec<Vec3>)> = Vec::new();
    for (s, &o) in r.iter().zip(r.offsets()) {
        let d = s[0] - c;
        let sector = (((d.y.atan2(d.x) / std::f32::consts::TAU + 1.0).fract() * 8.0) as usize).min(7);
        let band = (((s[0].z - zmin) / (zmax - zmin).max(1e-6) * 3.0) as usize).min(2);
        for (i, &p) in s.iter().enumerate() {
            if by_root && i as f32 * step >= bin {
                break;
            }
            let b = if by_root { band * 8 + sector } else { (i as f32 * step / bin) as usize };
            if bins.len() <= b {
                bins.resize_with(b + 1, Default::default);
            }
            bins[b].0.push(p);
            bins[b].1.push(t[o + i]);
        }
    }
    Ok(bins.into_iter().map(|(p, t)| OrientedPoints::new(p, t)).collect())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: metric_by_arc PRED GT [BIN_CM]");
        std::process::exit(2);
    }
    let bin = args.get(2).map(|s| s.parse::<f32>()).transpose()?.unwrap_or(4.0) / 100.0;
    let step = 0.001;
    let (pred, gt) = (read_strands(&args[0])?, read_strands(&args[1])?);
    let env = |k: &str, d: f32| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d);
    let th = [Threshold { dist: env("DIST_MM", 2.0) / 1000.0, angle_deg: env("ANGLE_DEG", 20.0) }];
    let max_bins = (env("MAX_CM", 1000.0) / 100.0 / bin).ceil() as usize;
    let pred_all = OrientedPoints::from_strands(&pred, step)?;
    let gt_all = OrientedPoints::from_strands(&gt, step)?;
    let by_root = std::env::var_os("BY_ROOT").is_some();
    let (pb, gb) = (by_bin(&pred, step, bin, by_root)?, by_bin(&gt, step, bin, by_root)?);
    println!("arc (cm)   pred pts   P dir   P und  |   gt pts   R dir   R und");
    let (mut tp, mut tg) = ([0u64; 3], [0u64; 3]);
    let pct = |hit: u64, n: usize| if n == 0 { f64::NAN } else { 100.0 * hit as f64 / n as f64 };
    for b in 0..pb.len().max(gb.len()).min(max_bins) {
        let (np, (pd, pu)) = pb.get(b).map_or((0, (vec![0], vec![0])), |q| (q.len(), gt_all.match_counts(q, &th)));
        let (ng, (rd, ru)) = gb.get(b).map_or((0, (vec![0], vec![0])), |q| (q.len(), pred_all.match_counts(q, &th)));
        tp = [tp[0] + np as u64, tp[1] + pd[0], tp[2] + pu[0]];
        tg = [tg[0] + ng as u64, tg[1] + rd[0], tg[2] + ru[0]];
        if by_root {
            let mean = |q: Option<&OrientedPoints>| {
                q.map_or(Vec3::ZERO, |q| q.tangents.iter().copied().sum::<Vec3>().normalize_or_zero())
            };
            print!("z{} az{} pred {:.2?} gt {:.2?} ", b / 8, b % 8, mean(pb.get(b)), mean(gb.get(b)));
        }
        println!(
            "{:>3}-{:<3}  {np:>10}  {:>6.1}  {:>6.1}  | {ng:>9}  {:>6.1}  {:>6.1}",
            (b as f32 * bin * 100.0).round(),
            ((b + 1) as f32 * bin * 100.0).round(),
            pct(pd[0], np),
            pct(pu[0], np),
            pct(rd[0], ng),
            pct(ru[0], ng)
        );
    }
    let f = |a: u64, b: u64, n: u64, m: u64| {
        let (p, r) = (a as f64 / n.max(1) as f64, b as f64 / m.max(1) as f64);
        100.0 * 2.0 * p * r / (p + r).max(1e-12)
    };
    println!(
        "all        {:>10}  {:>6.1}  {:>6.1}  | {:>9}  {:>6.1}  {:>6.1}   F1 directed {:.1}, undirected {:.1}",
        tp[0],
        pct(tp[1], tp[0] as usize),
        pct(tp[2], tp[0] as usize),
        tg[0],
        pct(tg[1], tg[0] as usize),
        pct(tg[2], tg[0] as usize),
        f(tp[1], tg[1], tp[0], tg[0]),
        f(tp[2], tg[2], tp[0], tg[0]),
    );
    Ok(())
}
