//! Tests of the growth, the smoothing and the children.

use super::*;
use crate::laplace::Grid;

/// A 20 cm box of hair (no head, outer surface far away) with `field(p)` per voxel.
fn flow(field: impl Fn(Vec3) -> Vec3) -> FlowField {
    let voxel = 0.004;
    let dims = [51, 51, 151];
    let grid = Grid { origin: Vec3::new(-0.1, -0.1, -0.5), voxel, dims };
    let n = grid.len();
    let field = (0..n).map(|i| field(grid.centre(i))).collect();
    FlowField { grid, field, sd_outer: vec![-0.05; n], sd_inner: vec![0.05; n], label: vec![1; n] }
}

#[test]
fn cut_at_arc_keeps_the_first_max_length_of_each_strand() {
    let long: Vec<Vec3> = (0..=4).map(|i| Vec3::new(0.1 * i as f32, 0.0, 0.0)).collect();
    let short = vec![Vec3::ZERO, Vec3::new(0.0, 0.0, -0.05)];
    let set = StrandSet::new([long, short.clone()].concat(), vec![5, 2]).unwrap();
    let cut = cut_at_arc(&set, 0.25);
    assert_eq!(cut.strand(0).len(), 4);
    assert!(cut.strand(0)[3].distance(Vec3::new(0.25, 0.0, 0.0)) < 1e-6);
    assert!((cut.strand_length(0) - 0.25).abs() < 1e-6);
    assert_eq!(cut.strand(1), &short[..]);
}

#[test]
fn growth_takes_its_budget_and_the_guides_are_cut_at_max_length() {
    // Straight down: the strand grows max_length × grow_budget of steps, and smoothing's cut
    // leaves max_length of arc.
    let f = flow(|_| Vec3::NEG_Z);
    let params = GrowParams { max_length: 0.1, grow_budget: 1.5, ..GrowParams::default() };
    let (pts, stop) = grow_one(&f, None, Vec3::ZERO, Vec3::NEG_Z, &params);
    assert_eq!(stop, Stop::MaxLength);
    let grown: f32 = pts.windows(2).map(|w| w[0].distance(w[1])).sum();
    assert!((grown - 0.15).abs() < 1e-4, "grew {grown} m");
    let set = StrandSet::new(pts, vec![76]).unwrap();
    let (cut, _) = smooth_guides(&set, None, Some(&f), &params);
    assert!((cut.strand_length(0) - 0.1).abs() < 1e-5, "kept {} m", cut.strand_length(0));
}

#[test]
fn a_zig_zag_guide_smoothed_reaches_as_far_as_max_length_allows() {
    // A guide that zig-zags down (2 mm steps 45° either side of straight down, as guides sliding
    // along the outer surface do) over its budget, with coherent points along it: smoothed and
    // cut, it keeps max_length of arc, which reaches about max_length down. Cut at the old
    // budget (the steps of max_length), the same guide reached only cos 45° of that.
    let params = GrowParams { max_length: 0.2, grow_budget: 1.5, ..GrowParams::default() };
    let steps = (params.max_length * params.grow_budget / params.step).round() as usize;
    let h = params.step * std::f32::consts::FRAC_1_SQRT_2;
    let zig: Vec<Vec3> = (0..=steps).map(|i| Vec3::new(if i % 2 == 1 { h } else { 0.0 }, 0.0, -h * i as f32)).collect();
    let points =
        PointIndex::new((0..400).map(|i| Vec3::new(0.5 * h, 0.0, -0.001 * i as f32)).collect(), vec![Vec3::NEG_Z; 400]);
    let reach = |guide: &[Vec3]| {
        let set = StrandSet::new(guide.to_vec(), vec![guide.len() as u32]).unwrap();
        let (out, stats) = smooth_guides(&set, Some(&points), None, &params);
        assert_eq!(stats.full, 1);
        (out.strand_length(0), -out.strand(0).last().unwrap().z)
    };
    let (arc, down) = reach(&zig);
    assert!((arc - 0.2).abs() < 1e-4, "kept {arc} m of arc");
    assert!(down > 0.19, "reached {down} m down");
    let old_budget = (params.max_length / params.step).round() as usize;
    let (_, down_old) = reach(&zig[..=old_budget]);
    assert!(down_old < 0.15, "the old budget reached {down_old} m down");
}

#[test]
fn a_vortex_ends_as_a_loop_and_the_circle_is_cut() {
    // Circles about the z axis: without the loop rule a strand circles until max_length.
    let f = flow(|p| Vec3::new(-p.y, p.x, 0.0).normalize_or(Vec3::X));
    let params = GrowParams { max_escapes: 0, ..GrowParams::default() };
    let root = Vec3::new(0.02, 0.0, 0.0);
    let (pts, stop) = grow_one(&f, None, root, Vec3::Y, &params);
    assert_eq!(stop, Stop::Loop);
    // A 2 cm radius circle is 12.6 cm around: the strand is cut back to where it came round.
    let len: f32 = pts.windows(2).map(|w| w[0].distance(w[1])).sum();
    assert!(len < 0.02, "kept {len} m of a vortex");
    let (_, stop) = grow_one(&f, None, root, Vec3::Y, &GrowParams { loop_window: 0.0, ..params });
    assert_eq!(stop, Stop::MaxLength);
}

#[test]
fn a_strand_escapes_a_vortex_under_gravity_and_keeps_no_circle() {
    // The same vortex, with the default escapes: each time the strand comes round, the circle is
    // cut and it leaves downwards for `escape_length`; it ends far below its root, and nothing
    // of what it kept comes back near itself.
    let f = flow(|p| Vec3::new(-p.y, p.x, 0.0).normalize_or(Vec3::X));
    let params = GrowParams::default();
    let (pts, stop) = grow_one(&f, None, Vec3::new(0.02, 0.0, 0.0), Vec3::Y, &params);
    let low = pts.last().unwrap().z;
    assert!(low < -0.15, "ended at z = {low} ({stop:?})");
    let w = (params.loop_window / params.step).round() as usize;
    for (i, p) in pts.iter().enumerate().skip(w + 1) {
        let back = pts[..i - w].iter().map(|q| q.distance(*p)).fold(f32::MAX, f32::min);
        assert!(back >= params.loop_distance, "point {i} comes back within {back} m");
    }
}

#[test]
fn a_tight_helix_is_not_a_loop() {
    // A helix of radius 5 mm and pitch 1 cm about the z axis, descending.
    let pitch = 0.01f32;
    let r = 0.005f32;
    let f = flow(|p| {
        let tangential = Vec3::new(-p.y, p.x, 0.0).normalize_or(Vec3::X) * (std::f32::consts::TAU * r);
        (tangential - Vec3::Z * pitch).normalize()
    });
    let params = GrowParams { max_length: 0.3, ..GrowParams::default() };
    let (pts, stop) = grow_one(&f, None, Vec3::new(r, 0.0, 0.0), Vec3::new(0.0, 0.95, -0.3), &params);
    assert_eq!(stop, Stop::MaxLength, "{} points", pts.len());
    assert!(pts.last().unwrap().z < -0.06);
}

#[test]
fn beyond_climb_after_no_step_climbs_even_where_the_outer_surface_slopes_up() {
    // Flow down and to +x; the outer surface a plane facing down and +x (the underside of a
    // hair mass) 4 mm from the root: the strand meets it at once and its projection onto the
    // plane slides it up along it. With `max_climb` 0 no step beyond `climb_after` rises (the
    // strand leaves the surface level and ends outside); with the rule off it climbs.
    let root = Vec3::new(-0.08, 0.0, -0.2);
    let n = Vec3::new(1.0, 0.0, -1.0).normalize();
    let mut f = flow(|_| Vec3::new(1.0, 0.0, -0.3).normalize());
    for i in 0..f.grid.len() {
        f.sd_outer[i] = (f.grid.centre(i) - root - Vec3::X * 0.004).dot(n);
    }
    let rises = |params: &GrowParams| {
        let (pts, _) = grow_one(&f, None, root, Vec3::new(1.0, 0.0, -0.3), params);
        let mut arc = 0.0f32;
        let mut rise = f32::MIN;
        for w in pts.windows(2) {
            if arc >= params.climb_after {
                rise = rise.max(w[1].z - w[0].z);
            }
            arc += w[0].distance(w[1]);
        }
        (rise, pts.len())
    };
    let params = GrowParams { trace_radius: 0.0, max_length: 0.1, ..GrowParams::default() };
    let (rise, n_on) = rises(&params);
    assert!(rise <= 1e-6, "a step beyond climb_after rose {rise} m ({n_on} points)");
    let (rise, n_off) = rises(&GrowParams { max_climb: 1.0, ..params });
    assert!(
        rise > 0.0005,
        "with the rule off the strand should climb the surface; largest rise {rise} m ({n_off} points)"
    );
}

/// Flow straight down; an inward-facing wall of the raw mesh 2 cm behind (+y) the root, so that the
/// root reads 2 cm outside. Directed points along the line down from the root and along the
/// wall, with tangents from `tangent(i)`.
fn wrong_sign_scene(tangent: impl Fn(usize) -> Vec3) -> (FlowField, PointIndex, Roots) {
    let root = Vec3::new(0.0, 0.0, -0.05);
    let mut f = flow(|_| Vec3::NEG_Z);
    for i in 0..f.grid.len() {
        f.sd_outer[i] = root.y + 0.02 - f.grid.centre(i).y;
    }
    let (mut pos, mut dir) = (Vec::new(), Vec::new());
    for k in 0..300 {
        for (x, y) in [(-0.001, 0.0), (0.001, 0.0), (0.0, 0.001), (-0.001, 0.02), (0.001, 0.02), (0.0, 0.019)] {
            pos.push(Vec3::new(x, y, root.z - 0.001 * k as f32));
            dir.push(tangent(pos.len()));
        }
    }
    let roots = Roots { positions: vec![root], normals: vec![Vec3::Z], growth: vec![Vec3::NEG_Z] };
    (f, PointIndex::new(pos, dir), roots)
}

#[test]
fn a_root_read_outside_the_raw_mesh_starts_free_whatever_the_points() {
    let params = GrowParams { trace_radius: 0.0, ..GrowParams::default() };
    let first = |g: &StrandSet| (g.strand(0)[1] - g.strand(0)[0]).normalize();
    // Without a free start the first step jumps onto the wall: back (+y), not down.
    let (f, points, roots) = wrong_sign_scene(|_| Vec3::NEG_Z);
    let off = GrowParams { root_gap: 0.0, ..params };
    let (g, stats) = grow_guides(&f, Some(&points), &roots, &off, &crate::progress::NoProgress).unwrap();
    assert!(first(&g).y > 0.9, "first step {:?}", first(&g));
    assert_eq!(stats.free_starts, 0);
    // With it the guide goes straight down for `root_gap`, whether the points agree (straight
    // hair) or their tangents go all round (wavy hair's points are incoherent).
    let incoherent = |i: usize| {
        let a = i as f32 * 2.4;
        Vec3::new(a.cos(), a.sin(), 0.3 * (1.7 * a).sin()).normalize()
    };
    for (f, points, roots) in [wrong_sign_scene(|_| Vec3::NEG_Z), wrong_sign_scene(incoherent)] {
        let (g, stats) = grow_guides(&f, Some(&points), &roots, &params, &crate::progress::NoProgress).unwrap();
        assert_eq!(stats.free_starts, 1);
        let s = g.strand(0);
        let n = (params.root_gap / params.step) as usize;
        assert!(s.len() > n);
        for p in &s[..n] {
            assert!(p.y.abs() < 1e-4 && p.x.abs() < 1e-4, "left the line at {p:?}");
        }
        assert!((s[n].z - (roots.positions[0].z - params.root_gap)).abs() < 1e-3);
    }
}

#[test]
fn the_exit_rule_waits_for_exit_after() {
    // Flow straight up (+z) through an outer surface at z = 0 (sd_outer = z): growth ends at the
    // surface, unless the exit rule is held off, in which case the strand slides (and, with a
    // purely normal flow, has nowhere to go but stays on the surface).
    let mut f = flow(|_| Vec3::Z);
    for i in 0..f.grid.len() {
        f.sd_outer[i] = f.grid.centre(i).z;
    }
    let params = GrowParams { exit_cos: 0.99, ..GrowParams::default() };
    let root = Vec3::new(0.0, 0.0, -0.05);
    let (pts, stop) = grow_one(&f, None, root, Vec3::Z, &params);
    assert_eq!(stop, Stop::Outside);
    let top = pts.iter().map(|p| p.z).fold(f32::MIN, f32::max);
    assert!(top.abs() < 0.004, "stopped at z = {top}");
}

#[test]
fn the_points_exit_rule_ends_where_the_seen_hair_stands_out_of_the_surface() {
    // An outer surface at z = 0 (sd_outer = z); the flow rises through it at 60° from the
    // horizontal. Where the directed points at the surface stand out of it too (spikes), growth
    // ends there; where they lie along it (hair combed flat), the strand slides along the surface
    // as before, and so it does with the rule off.
    let up = Vec3::new(0.5, 0.0, 0.75f32.sqrt());
    let mut f = flow(|_| up);
    for i in 0..f.grid.len() {
        f.sd_outer[i] = f.grid.centre(i).z;
    }
    let at_surface = |t: Vec3| {
        let pts: Vec<Vec3> =
            (0..400).map(|k| Vec3::new(-0.02 + 0.0005 * (k % 200) as f32, 0.0005 * (k / 200) as f32, 0.0)).collect();
        PointIndex::new(pts, vec![t; 400])
    };
    let (spikes, flat) = (at_surface(up), at_surface(Vec3::X));
    let rule = GrowParams { exit_points_cos: 0.5, max_length: 0.1, ..GrowParams::default() };
    let root = Vec3::new(-0.03, 0.0, -0.02);
    let reach = |pts: &[Vec3]| pts.iter().map(|p| p.x).fold(f32::MIN, f32::max);
    let (a, stop) = grow_one(&f, Some(&spikes), root, up, &rule);
    assert_eq!(stop, Stop::Outside);
    assert!(reach(&a) < 0.0, "ended at x = {} beyond the spikes' patch", reach(&a));
    let (b, _) = grow_one(&f, Some(&flat), root, up, &rule);
    let (c, _) = grow_one(&f, Some(&spikes), root, up, &GrowParams { exit_points_cos: 1.0, ..rule });
    assert!(reach(&b) > 0.03 && reach(&c) > 0.03, "slid to x = {} and {}", reach(&b), reach(&c));
}

#[test]
fn tracing_follows_the_points_where_the_field_is_smooth() {
    // The field points straight down; directed points lie along a helix of 6 mm radius that
    // hangs from the root. Without tracing a strand goes straight down; with it, it keeps to
    // the helix.
    let f = flow(|_| Vec3::NEG_Z);
    let helix = |t: f32| Vec3::new(0.006 * t.cos(), 0.006 * t.sin(), -0.004 * t);
    let (mut pts, mut tans) = (Vec::new(), Vec::new());
    for k in 0..3000 {
        let t = k as f32 * 0.01;
        pts.push(helix(t));
        tans.push((helix(t + 0.001) - helix(t)).normalize());
    }
    let index = PointIndex::new(pts.clone(), tans.clone());
    let off_helix = |strand: &[Vec3]| -> f32 {
        let near: Vec<f32> =
            strand.iter().map(|p| index.nearest(*p, 1).first().map(|n| n.1).unwrap_or(f32::MAX)).collect();
        near.iter().sum::<f32>() / near.len() as f32
    };
    let params = GrowParams { max_length: 0.15, grow_budget: 1.0, ..GrowParams::default() };
    let (with, _) = grow_one(&f, Some(&index), helix(0.0), tans[0], &params);
    let (without, _) = grow_one(&f, None, helix(0.0), tans[0], &params);
    let (a, b) = (off_helix(&with), off_helix(&without));
    assert!(a < 0.001, "traced strand {a} m from the helix on average");
    assert!(b > 0.003, "untraced strand {b} m from the helix on average");
}

#[test]
fn where_points_trump_a_strand_follows_them_out_through_the_outer_surface() {
    // The field points straight down; the outer surface is the plane x = 5 mm; directed points
    // fill the plane y = 0, all pointing 45° outward and down. By default the strand blends
    // the field with them and slides along the surface; where the points trump, it follows
    // them out through it (up to 1 cm). Points whose signs run against the strand never trump.
    let mut f = flow(|_| Vec3::NEG_Z);
    for i in 0..f.grid.len() {
        f.sd_outer[i] = f.grid.centre(i).x - 0.005;
    }
    let d = Vec3::new(1.0, 0.0, -1.0).normalize();
    let plane: Vec<Vec3> =
        (0..1600).map(|k| Vec3::new(-0.01 + (k % 40) as f32 * 0.001, 0.0, -((k / 40) as f32) * 0.001)).collect();
    let along = PointIndex::new(plane.clone(), vec![d; plane.len()]);
    let against = PointIndex::new(plane, vec![-d; 1600]);
    let base = GrowParams { max_length: 0.03, max_climb: 1.0, ..GrowParams::default() };
    let trump = GrowParams { trace_trumps: 0.5, ..base };
    let tip_x = |index: &PointIndex, p: &GrowParams| grow_one(&f, Some(index), Vec3::ZERO, d, p).0.last().unwrap().x;
    let (x_base, x_trump, x_against) = (tip_x(&along, &base), tip_x(&along, &trump), tip_x(&against, &trump));
    assert!(x_base < 0.0065, "default: tip {x_base} m out, should slide along x = 5 mm");
    assert!(x_trump > 0.012, "trumped: tip {x_trump} m out, should follow the points out of the surface");
    assert!(x_against < 0.0065, "points against the strand: tip {x_against} m out");
}

#[test]
fn straight_guides_are_smoothed_and_curly_ones_kept() {
    // A guide straight down with a 0.5 mm zig-zag, among points all along it. Where their
    // tangents agree (straight hair) the zig-zag is tracing noise and goes; where they spread
    // by 30° (curls crossing) the guide is kept as it is.
    let guide: Vec<Vec3> = (0..100).map(|k| Vec3::new(0.0005 * (k % 2) as f32, 0.0, -0.002 * k as f32)).collect();
    let guides = StrandSet::new(guide.clone(), vec![100]).unwrap();
    let pts: Vec<Vec3> = (0..2000)
        .map(|i| {
            Vec3::new(0.001 * ((i % 5) as f32 - 2.0) * 0.5, 0.0005 * ((i / 5 % 3) as f32 - 1.0), -0.0001 * i as f32)
        })
        .collect();
    let params = GrowParams::default();
    // The largest sideways step away from the ends (3σ = 6 segments): 0.5 mm before smoothing.
    let zigzag = |s: &[Vec3]| s[8..s.len() - 8].windows(2).map(|w| (w[1].x - w[0].x).abs()).fold(0.0f32, f32::max);

    let straight = PointIndex::new(pts.clone(), vec![Vec3::NEG_Z; pts.len()]);
    let (smoothed, stats) = smooth_guides(&guides, Some(&straight), None, &params);
    assert_eq!((stats.full, stats.partly, stats.none), (1, 0, 0));
    assert!(stats.median_angle_deg < 1.0, "{stats:?}");
    let s = smoothed.strand(0);
    assert_eq!(s[0], guide[0], "the root moved");
    assert_eq!(s.len(), guide.len());
    assert!(zigzag(&guide) > 0.00049);
    assert!(zigzag(s) < 0.00005, "zig-zag {} m left of 0.0005", zigzag(s));

    let spread = |i: usize| {
        let a = if i.is_multiple_of(2) { 30f32 } else { -30f32 }.to_radians();
        let t = Vec3::new(a.sin(), 0.0, -a.cos());
        if i % 4 < 2 {
            t
        } else {
            Vec3::new(t.y, t.x, t.z)
        }
    };
    let curly = PointIndex::new(pts.clone(), (0..pts.len()).map(spread).collect());
    let (kept, stats) = smooth_guides(&guides, Some(&curly), None, &params);
    assert_eq!((stats.full, stats.partly, stats.none), (0, 0, 1));
    assert!((stats.median_angle_deg - 30.0).abs() < 3.0, "{stats:?}");
    assert_eq!(kept.strand(0), guide.as_slice());
}

#[test]
fn a_child_between_guides_that_part_follows_its_nearest_guide() {
    // Two guides 10 cm long whose roots are 1 cm apart: one leaves along +x, the other along -x
    // (a parting between them). A child rooted 0.4 mm nearer the first one.
    let guide = |x0: f32, dir: f32| (0..51).map(move |j| Vec3::new(x0 + dir * 0.002 * j as f32, 0.0, 0.0));
    let guides = StrandSet::new(guide(0.0, 1.0).chain(guide(0.01, -1.0)).collect(), vec![51, 51]).unwrap();
    let root = Vec3::new(0.0046, 0.001, 0.0);
    let roots = Roots { positions: vec![root], normals: vec![Vec3::Z], growth: vec![Vec3::X] };
    let child = |parting_reach: f32| {
        let params =
            GrowParams { blend: BlendParams { parting_reach, ..BlendParams::default() }, ..GrowParams::default() };
        let c = interpolate_children(&guides, &roots, None, &params, &crate::progress::NoProgress).unwrap();
        c.strand(0).to_vec()
    };
    let reach = |s: &[Vec3]| (s[s.len() - 1] - s[0]).length();

    // Blending both (weights 0.58 and 0.42), the segment vectors cancel but for 0.15 of a step.
    let blended = child(0.0);
    assert!(reach(&blended) < 0.03, "reach {} m", reach(&blended));
    // With the parting rule the child takes the nearer guide's shape: 10 cm along +x, 2 mm steps.
    let parted = child(0.5);
    assert_eq!(parted.len(), 51);
    assert!((parted[50] - (root + Vec3::X * 0.1)).length() < 1e-5, "tip {:?}", parted[50]);
    for w in parted.windows(2) {
        assert!(((w[1] - w[0]).length() - 0.002).abs() < 1e-6);
    }
    // Guides that leave 90° apart blend to a reach of 0.72 with these weights: kept at 0.5,
    // the nearest alone at 0.8.
    let side: Vec<Vec3> = guide(0.0, 1.0).chain((0..51).map(|j| Vec3::new(0.01, 0.002 * j as f32, 0.0))).collect();
    let guides = StrandSet::new(side, vec![51, 51]).unwrap();
    let blend = |reach: f32| {
        GuideBlend::new(&guides, &BlendParams { k: 2, min_guide_fraction: 0.0, parting_reach: reach }).weights(root, 2)
    };
    assert_eq!(blend(0.5).len(), 2);
    assert_eq!(blend(0.8), vec![(0, 1.0)]);
}
