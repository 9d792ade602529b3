//! The committed head fixtures are what `prepare_head` makes from the source head, and they are
//! in metres, Z up, face toward −Y, with the scalp where it belongs.

use glam::Vec3;
use hairrecon_core::formats::read_mesh;
use hairrecon_synth::fixtures_dir;
use hairrecon_synth::head::{prepare_fixtures, SOURCE_SHA256};
use hairrecon_synth::scalp_region::is_scalp;

const SOURCE: &str = "/work/shared/data/heads/woman_head.ply";

#[test]
fn committed_fixtures_are_reproducible() {
    if !std::path::Path::new(SOURCE).is_file() {
        eprintln!("skipped: {SOURCE} is not on this machine");
        return;
    }
    let out = std::env::temp_dir().join(format!("hairrecon-fixtures-{}", std::process::id()));
    let summary = prepare_fixtures(SOURCE.as_ref(), &out).unwrap();
    for name in ["head.ply", "scalp.ply", "scalp_mask.png"] {
        let made = std::fs::read(out.join(name)).unwrap();
        let committed = std::fs::read(fixtures_dir().join(name)).unwrap();
        assert!(made == committed, "{name} differs from the committed fixture: rerun prepare_head");
    }
    assert_eq!(summary.head_vertices, 43_732);
    assert_eq!(summary.head_triangles, 78_520);
    std::fs::remove_dir_all(&out).ok();
    // A wrong source is refused with the checksum in the message.
    let bad = std::env::temp_dir().join(format!("hairrecon-bad-{}.ply", std::process::id()));
    std::fs::write(&bad, b"ply\n").unwrap();
    let e = prepare_fixtures(&bad, &out).unwrap_err().to_string();
    assert!(e.contains(SOURCE_SHA256), "{e}");
    std::fs::remove_file(&bad).ok();
}

#[test]
fn head_is_in_metres_z_up_face_minus_y() {
    let head = read_mesh(fixtures_dir().join("head.ply")).unwrap();
    assert!(head.normals.is_some() && head.uvs.is_some(), "normals and UVs are kept");
    let (lo, hi) = head.bbox();
    assert!((lo + hi).length() < 1e-4, "bounding box centred on the origin: {lo} {hi}");
    // Skull width just above the ears (which end at z = 0.069 m): 0.15 m give or take.
    let skull = head.vertices.iter().filter(|p| p.z > 0.075 && p.z < 0.095).map(|p| p.x.abs()).fold(0.0f32, f32::max);
    assert!((0.07..0.08).contains(&skull), "skull half-width {skull}");
    // The face: the most forward point (nose tip) is at -Y, well below the top.
    let nose = head.vertices.iter().copied().min_by(|a, b| a.y.total_cmp(&b.y)).unwrap();
    assert!(nose.y < -0.09 && nose.z < 0.05 && nose.z > -0.05 && nose.x.abs() < 0.005, "nose {nose}");
    // The top of the head is +Z, centred in X.
    let top = head.vertices.iter().copied().max_by(|a, b| a.z.total_cmp(&b.z)).unwrap();
    assert!(top.z > 0.16 && top.x.abs() < 0.02, "top {top}");
    // Normals point outward: at the top, up.
    let n = head.normals.as_ref().unwrap();
    let i = head.vertices.iter().position(|&p| p == top).unwrap();
    assert!(n[i].dot(Vec3::Z) > 0.9, "normal at the top {}", n[i]);
}

#[test]
fn scalp_covers_top_sides_and_back_only() {
    let scalp = read_mesh(fixtures_dir().join("scalp.ply")).unwrap();
    assert!(scalp.vertices.iter().all(|&p| is_scalp(p)));
    let area: f32 = (0..scalp.triangles.len()).map(|i| scalp.face_area(i)).sum();
    // A real scalp is about 0.06 m².
    assert!((0.05..0.075).contains(&area), "scalp area {area}");
    let (lo, hi) = scalp.bbox();
    // Reaches the top, goes down to the nape at the back, not down to the chin.
    assert!(hi.z > 0.16 && lo.z > -0.05 && lo.z < 0.03, "{lo} {hi}");
    let uv = scalp.uvs.as_ref().unwrap();
    assert!(uv.iter().all(|t| t.x > -1e-6 && t.x < 1.0 + 1e-6 && t.y > -1e-6 && t.y < 1.0 + 1e-6));
}

#[test]
fn growth_field_and_roots_on_the_fixture_scalp() {
    use hairrecon_core::scalp::Scalp;
    let scalp = Scalp::new(read_mesh(fixtures_dir().join("scalp.ply")).unwrap()).unwrap();
    let w = scalp.field().whorl;
    // The whorl: near the top, behind the middle.
    println!("whorl {w}");
    assert!(w.z > 0.14 && w.y > 0.02 && w.x.abs() < 0.03, "whorl {w}");
    let n = 5000;
    let roots = scalp.sample_roots(n, 5).unwrap();
    let (mut sides, mut back, mut front) = (0, 0, 0);
    for r in &roots {
        let s = r.direction;
        assert!(s.dot(r.normal) >= 0.49, "S·n = {} at {}", s.dot(r.normal), r.position);
        assert!(r.normal.dot(r.position - Vec3::new(0.0, 0.0, 0.03)) > 0.0, "normal points in at {}", r.position);
        let p = r.position;
        if p.x.abs() > 0.06 && p.z < 0.08 {
            sides += 1;
            assert!(s.z < -0.3, "side S {s} at {p}");
        }
        if p.y > 0.07 && p.z < 0.08 {
            back += 1;
            assert!(s.z < -0.3, "back S {s} at {p}");
        }
        if p.y < -0.07 {
            front += 1;
            assert!(s.y < -0.2, "front S {s} at {p}");
        }
    }
    assert!(sides > 100 && back > 100 && front > 50, "{sides} {back} {front}");
    // Blue noise: the closest pair is a good share of the hexagonal spacing 2 r_max.
    let spacing = 2.0 * scalp.poisson_radius(n);
    let mut min = f32::INFINITY;
    let mut sum = 0.0;
    for (i, a) in roots.iter().enumerate() {
        let d = roots
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != i)
            .map(|(_, b)| a.position.distance(b.position))
            .fold(f32::INFINITY, f32::min);
        min = min.min(d);
        sum += d;
    }
    let mean = sum / n as f32;
    println!("spacing {spacing:.5} m: closest pair {:.3}, mean nearest {:.3} of it", min / spacing, mean / spacing);
    // Measured: 0.699 and 0.796 (seed 5).
    assert!(min > 0.6 * spacing && mean > 0.75 * spacing, "min {min} mean {mean} spacing {spacing}");
}
