//! DR strand optimization on a synthetic scene: known strands on a sphere ("a head", radius 9 cm),
//! rendered by the raster crate into 8 views (coverage and orientation, hidden where the head
//! occludes); the optimization starts from the same strands cut to 80% of their length (same point
//! count) and bent away smoothly (up to 4 mm at the tip), and must bring them back. Every number is
//! seeded. Measured (this file's settings, `cargo test --release -p hairrecon-recon --test integration
//! dr:: -- --skip pipeline_dr --nocapture`, at commit 584c3fd): start F1 70.4 (directed, 2 mm/20°), tip error 20.5 mm; full
//! DR F1 89.8, tip error 10.8 mm; w/o reparam F1 81.6, 11.7 mm (with the DR defaults before commit
//! 6a05744 91.4 / 10.0 mm and 85.9 / 10.9 mm; w/o N, not run here to keep the test short, measured
//! F1 88.3, 10.6 mm then). The floors are these less a margin.

use glam::{Vec2, Vec3};
use hairrecon_core::metric::{evaluate, MetricOptions, Threshold};
use hairrecon_core::{Bvh, Camera, StrandSet, TriMesh};
use hairrecon_raster::synthetic::sphere_strands;
use hairrecon_raster::{channel, AaMethod, RasterSettings, Renderer, SegmentShape, Width};
use hairrecon_recon::dr::children::ChildMap;
use hairrecon_recon::dr::optimize::Evaluator;
use hairrecon_recon::dr::{optimize, DrOptions, DrResult, DrStage, DrTargets, DrView, LossRecord};
use hairrecon_recon::progress::NoProgress;

const RADIUS: f32 = 0.09;

fn sphere_mesh(radius: f32, rings: usize, sectors: usize) -> TriMesh {
    let mut v = Vec::new();
    for i in 0..=rings {
        let th = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..sectors {
            let ph = 2.0 * std::f32::consts::PI * j as f32 / sectors as f32;
            v.push(Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()) * radius);
        }
    }
    let mut t = Vec::new();
    for i in 0..rings {
        for j in 0..sectors {
            let a = (i * sectors + j) as u32;
            let b = (i * sectors + (j + 1) % sectors) as u32;
            let c = a + sectors as u32;
            let d = b + sectors as u32;
            t.push([a, c, b]);
            t.push([b, c, d]);
        }
    }
    let _ = Vec2::ZERO;
    TriMesh::new(v, t, None, None).unwrap()
}

fn cameras(size: u32) -> Vec<Camera> {
    let dist = 0.45f32;
    let fov = 2.0 * (0.2f32 / dist).atan();
    (0..8)
        .map(|i| {
            let az = i as f32 * std::f32::consts::FRAC_PI_4;
            let el = if i % 2 == 0 { 0.35f32 } else { -0.05 };
            let eye = Vec3::new(az.cos() * el.cos(), az.sin() * el.cos(), el.sin()) * dist;
            Camera::look_at(eye, Vec3::new(0.0, 0.0, -0.01), Vec3::Z, fov, size, size).unwrap()
        })
        .collect()
}

/// Renders `gt` into each view as a target; pixels whose strand is behind the head are background.
fn targets(gt: &StrandSet, cams: &[Camera], head: &Bvh, width_m: f32) -> DrTargets {
    let segs = hairrecon_raster::strand_segments(gt);
    let settings = RasterSettings { width: Width::World(width_m), shape: SegmentShape::Quad, direction_3d: false };
    let mut r = Renderer::new(AaMethod::Ours);
    let views = cams
        .iter()
        .enumerate()
        .map(|(i, cam)| {
            let img = r.forward(cam, gt.points(), &segs, settings).unwrap().clone();
            let depth = hairrecon_recon::views::head_depth_map(cam, head);
            let n = img.num_pixels();
            let mut mask = vec![0.0; n];
            let mut orient = vec![[0.0f32; 3]; n];
            for p in 0..n {
                if r.buffers.depth[p] > depth[p] {
                    continue;
                }
                let c = img.pixel((p % cam.width() as usize) as u32, (p / cam.width() as usize) as u32);
                let cov = c[channel::COVERAGE];
                mask[p] = cov;
                let o = Vec2::new(c[channel::COS2], c[channel::SIN2]);
                if cov > 0.05 && o.length() > 1e-6 {
                    let o = o.normalize();
                    orient[p] = [o.x, o.y, 1.0];
                }
            }
            DrView::new(i, *cam, mask, orient, Some(depth)).unwrap()
        })
        .collect();
    DrTargets { views }
}

/// The first `frac` of each strand's arc length, resampled to the same point count.
fn shortened(s: &StrandSet, frac: f32) -> StrandSet {
    let mut pts = Vec::new();
    for st in s.iter() {
        let n = st.len();
        let lens: Vec<f32> = st.windows(2).map(|w| (w[1] - w[0]).length()).collect();
        let total: f32 = lens.iter().sum();
        for i in 0..n {
            let mut d = total * frac * i as f32 / (n - 1) as f32;
            let mut k = 0;
            while k + 1 < lens.len() && d > lens[k] {
                d -= lens[k];
                k += 1;
            }
            pts.push(st[k].lerp(st[k + 1], (d / lens[k].max(1e-9)).min(1.0)));
        }
    }
    StrandSet::new(pts, s.counts().to_vec()).unwrap()
}

/// Each strand bent away smoothly: point `i` of `n` moves by `amp · (i/(n−1))²` along a random
/// direction per strand (seeded).
fn perturbed(s: &StrandSet, amp: f32, seed: u64) -> StrandSet {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut rnd = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    };
    let mut pts = Vec::new();
    for st in s.iter() {
        let d = Vec3::new(rnd(), rnd(), rnd()).normalize_or_zero();
        let n = st.len();
        for (i, p) in st.iter().enumerate() {
            let t = i as f32 / (n - 1) as f32;
            pts.push(*p + d * amp * t * t);
        }
    }
    StrandSet::new(pts, s.counts().to_vec()).unwrap()
}

struct Scene {
    gt: StrandSet,
    start: StrandSet,
    guides: StrandSet,
    scalp: Bvh,
    head: Bvh,
    targets: DrTargets,
}

fn scene() -> Scene {
    let gt = sphere_strands(240, 16, RADIUS, 0.10, 3);
    let head = Bvh::new(sphere_mesh(RADIUS, 24, 48));
    let scalp = Bvh::new(sphere_mesh(RADIUS, 24, 48));
    let targets = targets(&gt, &cameras(160), &head, 0.001);
    let start = perturbed(&shortened(&gt, 0.8), 0.004, 11);
    let guides = start.select(&(0..start.num_strands()).step_by(4).collect::<Vec<_>>());
    Scene { gt, start, guides, scalp, head, targets }
}

fn opts() -> DrOptions {
    DrOptions {
        iterations_guides: 150,
        iterations_children: 100,
        lr: 2e-3,
        lambda: 10.0,
        neighbor_weight: 0.05,
        width_m: 0.001,
        views_per_step: 4,
        seed: 5,
        // these strands have a point every ~6 mm, not the init's ~1.6 mm: DR moves every one, and
        // the 160 px views are small: the guide stage at full size
        stride: 1,
        guide_stride: 0,
        guide_downsample: 1,
        ..Default::default()
    }
}

/// Directed F1 at 2 mm/20° and the mean tip distance (mm) against the ground truth.
fn score(s: &StrandSet, gt: &StrandSet) -> (f64, f32) {
    let m = MetricOptions { step: 0.001, thresholds: vec![Threshold { dist: 0.002, angle_deg: 20.0 }] };
    let f1 = evaluate(s, gt, &m).unwrap().directed[0].f1;
    let tip: f32 =
        s.iter().zip(gt.iter()).map(|(a, b)| (*a.last().unwrap() - *b.last().unwrap()).length()).sum::<f32>()
            / s.num_strands() as f32;
    (f1, tip * 1000.0)
}

fn run(sc: &Scene, o: &DrOptions) -> DrResult {
    optimize(sc.guides.clone(), sc.start.clone(), &sc.targets, &sc.scalp, Some(&sc.head), o, &NoProgress).unwrap()
}

fn mean_first_last(curve: &[LossRecord], n: usize) -> (f64, f64) {
    let a = curve[..n].iter().map(|c| c.terms.total()).sum::<f64>() / n as f64;
    let b = curve[curve.len() - n..].iter().map(|c| c.terms.total()).sum::<f64>() / n as f64;
    (a, b)
}

#[test]
fn dr_grows_shortened_strands_back_and_reparam_matters() {
    let sc = scene();
    let (f0, t0) = score(&sc.start, &sc.gt);
    if std::env::var("DIAG").is_ok() {
        let o = DrOptions { views_per_step: 8, ..opts() };
        let views: Vec<usize> = (0..8).collect();
        for (name, s) in [("gt", &sc.gt), ("start", &sc.start)] {
            let mut ev = Evaluator::new(s.points(), s.offsets(), None, &sc.targets, &o);
            let mut g = vec![Vec3::ZERO; s.num_points()];
            let l = ev.evaluate(s.points(), s.offsets(), None, &sc.targets, &views, &o, &mut g).unwrap().total();
            println!("loss at {name}: {l:.3}");
        }
    }
    let full = run(&sc, &opts());
    if std::env::var("DIAG").is_ok() {
        let c: Vec<String> =
            full.loss_curve.iter().step_by(25).map(|l| format!("{}:{:.0}", l.iteration, l.terms.total())).collect();
        println!("curve {}", c.join(" "));
    }
    let (f1, t1) = score(&full.children, &sc.gt);
    let n = 10;
    assert!(full.loss_curve[..150].iter().all(|l| l.stage == DrStage::Guides));
    assert!(full.loss_curve[150..].iter().all(|l| l.stage == DrStage::Children));
    let (la, lb) = mean_first_last(&full.loss_curve[150..], n);
    let (ga, gb) = mean_first_last(&full.loss_curve[..150], n);
    println!("start: F1 {f0:.1}, tip error {t0:.1} mm");
    println!("full:  F1 {f1:.1}, tip error {t1:.1} mm; guide loss {ga:.3} → {gb:.3}, child loss {la:.3} → {lb:.3}; CG iterations {:.1}", full.mean_cg_iterations);
    let noreparam = run(&sc, &DrOptions { reparam: false, ..opts() });
    let (f2, t2) = score(&noreparam.children, &sc.gt);
    println!("w/o reparam: F1 {f2:.1}, tip error {t2:.1} mm");
    // Simulation-ready output.
    for s in full.children.iter() {
        assert!(sc.scalp.closest_point(s[0], 1.0).unwrap().distance < 1e-5);
        for p in &s[1..] {
            assert!(p.length() >= RADIUS - 1e-4, "point {p} inside the head");
        }
        let l: Vec<f32> = s.windows(2).map(|w| (w[1] - w[0]).length()).collect();
        let mean = l.iter().sum::<f32>() / l.len() as f32;
        assert!(l.iter().all(|x| (x - mean).abs() < 0.25 * mean), "uneven segments {l:?}");
    }
    assert!(gb < ga && lb < la, "loss must fall");
    assert!(
        f1 > f0 + 12.0 && t1 < 0.7 * t0,
        "DR must bring the strands closer: F1 {f0:.1} → {f1:.1}, tip {t0:.1} → {t1:.1} mm"
    );
    assert!((f2 - f1).abs() > 2.0 || (t2 - t1).abs() > 2.0, "w/o reparam must behave differently");
}

/// The whole loss chain (children from guides → render → L_m + L_o + regularizers) against central
/// finite differences, one guide coordinate at a time, on a tiny scene. Like the raster crate's
/// check, a coordinate counts only if the hard rasters (ids) of every view are the same at ±h (the
/// render is piecewise smooth) and the one-sided differences agree (the AA's edge choice may jump
/// without changing an id).
#[test]
fn loss_chain_matches_finite_differences() {
    let gt = sphere_strands(12, 5, RADIUS, 0.05, 9);
    let head = Bvh::new(sphere_mesh(RADIUS, 12, 24));
    let cams: Vec<Camera> = cameras(48).into_iter().step_by(3).collect();
    let width = 0.004;
    let t = targets(&gt, &cams, &head, width);
    let start = shortened(&gt, 0.7);
    let guides = start.select(&[0, 4, 8]);
    let o = DrOptions { width_m: width, views_per_step: cams.len(), ..Default::default() };
    let mut map = ChildMap::new(
        &guides,
        &start,
        &hairrecon_recon::grow::BlendParams { k: 2, min_guide_fraction: 0.0, parting_reach: 0.0 },
    );
    let mut ev = Evaluator::new(guides.points(), guides.offsets(), Some(&map), &t, &o);
    let views: Vec<usize> = (0..cams.len()).collect();
    let x0 = guides.points().to_vec();
    let mut g = vec![Vec3::ZERO; x0.len()];
    let mut scratch = g.clone();
    let mut eval = |ev: &mut Evaluator, x: &[Vec3], grad: &mut [Vec3]| {
        let l = ev.evaluate(x, guides.offsets(), Some(&mut map), &t, &views, &o, grad).unwrap().total();
        let ids: Vec<u32> = (0..views.len()).flat_map(|v| ev.hard_ids(v).to_vec()).collect();
        (l, ids)
    };
    let (l0, ids0) = eval(&mut ev, &x0, &mut g);
    let (mut checked, mut passed, mut skipped) = (0, 0, 0);
    let mut bad = Vec::new();
    let h = 1e-5f32;
    for i in 0..x0.len() {
        if guides.offsets().contains(&i) {
            continue; // roots are fixed
        }
        for c in 0..3 {
            let (mut xp, mut xm) = (x0.clone(), x0.clone());
            xp[i][c] += h;
            xm[i][c] -= h;
            let (lp, idp) = eval(&mut ev, &xp, &mut scratch);
            let (lm, idm) = eval(&mut ev, &xm, &mut scratch);
            // A jump of the AA's edge choice does not change the ids: skip where the one-sided
            // differences disagree (a kink or a jump between −h and h).
            let (fw, bw) = ((lp - l0) / h as f64, (l0 - lm) / h as f64);
            if idp != ids0 || idm != ids0 || (fw - bw).abs() > 0.2 * fw.abs().max(bw.abs()) + 1e-2 {
                skipped += 1;
                continue;
            }
            checked += 1;
            let fd = (lp - lm) / (2.0 * h as f64);
            let an = g[i][c] as f64;
            if (fd - an).abs() <= 0.05 * fd.abs().max(an.abs()) + 1e-2 {
                passed += 1;
            } else {
                bad.push(format!("point {i} coord {c}: fd {fd:.4} analytic {an:.4}"));
            }
        }
    }
    println!("{passed}/{checked} coordinates pass ({skipped} skipped)\n{}", bad.join("\n"));
    assert!(checked >= 20, "only {checked} coordinates kept the raster");
    assert!(passed as f64 >= 0.9 * checked as f64, "{passed}/{checked} coordinates pass");
}

/// DR with `stride` 2 is DR on the strands thinned to every other point (and the tip), the moves
/// carried to the points between: without the final evening and the head, its kept points are the
/// plain DR's on the thinned strands bit for bit, every point between moves by the mean of its two
/// neighbours' moves, and each strand keeps its point count.
#[test]
fn dr_with_a_stride_is_dr_on_the_thinned_strands_lifted() {
    use hairrecon_recon::dr::coarse::thin;
    let sc = scene();
    let o = DrOptions { iterations_guides: 4, iterations_children: 3, equalize_at_end: false, ..opts() };
    let strided = optimize(
        sc.guides.clone(),
        sc.start.clone(),
        &sc.targets,
        &sc.scalp,
        None,
        &DrOptions { stride: 2, ..o.clone() },
        &NoProgress,
    )
    .unwrap();
    // the roots are snapped to the scalp before the thinning or after it alike
    let (tg, tc) = (thin(&sc.guides, 2), thin(&sc.start, 2));
    let plain = optimize(tg, tc.clone(), &sc.targets, &sc.scalp, None, &o, &NoProgress).unwrap();
    assert_eq!(strided.children.counts(), sc.start.counts());
    assert_eq!(strided.guides.counts(), sc.guides.counts());
    assert!(thin(&strided.children, 2).points() == plain.children.points(), "the kept children differ");
    assert!(thin(&strided.guides, 2).points() == plain.guides.points(), "the kept guides differ");
    assert_eq!(strided.loss_curve.len(), 7);
    let mut between = 0;
    for (i, s) in strided.children.iter().enumerate() {
        let s0 = sc.start.strand(i);
        // the root moved only onto the scalp, before DR
        let moved = |d: usize| if d == 0 { Vec3::ZERO } else { s[d] - s0[d] };
        for d in (1..s.len() - 1).step_by(2) {
            let want = 0.5 * (moved(d - 1) + moved(d + 1));
            assert!((moved(d) - want).length() < 1e-6, "strand {i} point {d}");
            between += 1;
        }
    }
    assert!(between > 1000 && plain.children.points() != tc.points(), "nothing moved");
}

/// The guide stage at half the image scale (`guide_downsample` 2) renders a quarter of the pixels
/// (the image terms, sums over pixels, are about a quarter of the full scale's, a little less where
/// a block's pixels disagree in orientation) and still grows the shortened strands back.
#[test]
fn a_guide_stage_at_half_scale_still_grows_the_strands_back() {
    use hairrecon_recon::dr::downsample;
    let sc = scene();
    let (f0, t0) = score(&sc.start, &sc.gt);
    let o = DrOptions { iterations_children: 50, guide_downsample: 2, ..opts() };
    let views: Vec<usize> = (0..4).collect();
    let image_terms = |t: &DrTargets| {
        let s = &sc.start;
        let mut ev = Evaluator::new(s.points(), s.offsets(), None, t, &o);
        let mut g = vec![Vec3::ZERO; s.num_points()];
        let l = ev.evaluate(s.points(), s.offsets(), None, t, &views, &o, &mut g).unwrap();
        l.mask + l.orientation
    };
    let half_targets = downsample::targets(&sc.targets, 2).unwrap();
    assert_eq!(half_targets.views[0].camera.width(), sc.targets.views[0].camera.width() / 2);
    let ratio = image_terms(&half_targets) / image_terms(&sc.targets);
    let r = run(&sc, &o);
    let (f1, t1) = score(&r.children, &sc.gt);
    println!("image terms, half over full scale: {ratio:.3}; F1 {f0:.1} → {f1:.1}, tip {t0:.1} → {t1:.1} mm");
    assert!((0.15..0.3).contains(&ratio), "half scale must render a quarter of the pixels: ratio {ratio:.3}");
    assert!(
        f1 > f0 + 12.0 && t1 < 0.7 * t0,
        "DR must bring the strands closer: F1 {f0:.1} → {f1:.1}, tip {t0:.1} → {t1:.1} mm"
    );
}

/// With `guide_stride` 2 and `stride` 1, the guide stage is the one DR runs at stride 2 (without a
/// child stage the two give the same bytes), and the child stage then moves every point of the
/// children it leaves.
#[test]
fn a_coarser_guide_stride_runs_the_guide_stage_thinned_and_the_child_stage_on_every_point() {
    let sc = scene();
    let (f0, t0) = score(&sc.start, &sc.gt);
    let o = DrOptions { iterations_guides: 60, iterations_children: 0, ..opts() };
    let split = run(&sc, &DrOptions { guide_stride: 2, ..o.clone() });
    let strided = run(&sc, &DrOptions { stride: 2, ..o.clone() });
    assert!(split.children.points() == strided.children.points(), "the guide stages differ");
    assert!(split.guides.points() == strided.guides.points(), "the guide stages differ");
    let both = run(&sc, &DrOptions { guide_stride: 2, iterations_children: 30, ..o });
    assert_eq!(both.loss_curve.iter().filter(|l| l.stage == DrStage::Children).count(), 30);
    let (f1, t1) = score(&split.children, &sc.gt);
    let (f2, t2) = score(&both.children, &sc.gt);
    println!("F1 {f0:.1} → {f1:.1} (guides) → {f2:.1} (children), tip {t0:.1} → {t1:.1} → {t2:.1} mm");
    assert!(both.children.points() != split.children.points(), "the child stage moved nothing");
    assert!(f2 > f1 + 5.0 && t2 < t1, "the child stage must bring the strands closer: F1 {f1:.1} → {f2:.1}");
    assert!(f2 > f0 + 12.0 && t2 < 0.8 * t0, "DR must bring the strands closer: F1 {f0:.1} → {f2:.1}");
}
