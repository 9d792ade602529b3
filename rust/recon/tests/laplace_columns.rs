//! The hair volume of a layer thicker than `scalp_dist + max_point_dist`: a spherical head, its top
//! as the scalp, and hair seen 3.5 cm above it (`LaplaceParams::column_angle_deg` and
//! `LaplaceParams::scalp_lift`).

use crate::common;

use glam::Vec3;
use hairrecon_core::Bvh;
use hairrecon_recon::laplace::{solve_flow, FlowField, LaplaceParams};
use hairrecon_recon::points3d::OrientedPoints;
use hairrecon_recon::progress::NoProgress;
use hairrecon_recon::roots::Scalp;

const R: f32 = 0.09;
const SEEN: f32 = 0.035;

fn flow(column_angle_deg: f32, scalp_lift: f32) -> FlowField {
    let head = common::sphere(R, std::f32::consts::PI, 48, 96);
    let scalp = Scalp::new(common::sphere(R, 60f32.to_radians(), 24, 96)).unwrap();
    let raw = common::sphere(R + SEEN + 0.003, std::f32::consts::PI, 64, 128);
    // Directed points 3.5 cm above the scalp over its top 50°, about 3 mm apart, pointing away
    // from the crown.
    let mut points = OrientedPoints::default();
    let r = R + SEEN;
    let rings = (50f32.to_radians() * r / 0.003) as usize;
    for i in 1..=rings {
        let th = 50f32.to_radians() * i as f32 / rings as f32;
        let n = ((2.0 * std::f32::consts::PI * r * th.sin()) / 0.003).max(1.0) as usize;
        for j in 0..n {
            let ph = 2.0 * std::f32::consts::PI * j as f32 / n as f32;
            let u = Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
            points.positions.push(u * r);
            points.directions.push(Vec3::new(th.cos() * ph.cos(), th.cos() * ph.sin(), -th.sin()));
            points.confidence.push(1.0);
        }
    }
    let params = LaplaceParams { column_angle_deg, scalp_lift, ..LaplaceParams::default() };
    solve_flow(&Bvh::new(raw), &Bvh::new(head), &scalp, &points, &params, &NoProgress).unwrap().0
}

fn label(f: &FlowField, p: Vec3) -> u8 {
    f.label[f.grid.voxel_of(p).unwrap()]
}

#[test]
fn a_thick_layer_is_hair_from_the_scalp_up_to_the_seen_hair_with_columns() {
    let (off, on) = (flow(0.0, 0.0), flow(30.0, 0.0));
    // Halfway up over the crown and over a point 30° from it: 1.75 cm from the scalp and from the
    // points, farther than `scalp_dist` (1.2 cm) and `max_point_dist` (1.5 cm).
    for th in [0f32, 30f32.to_radians()] {
        let u = Vec3::new(th.sin(), 0.0, th.cos());
        let mid = u * (R + 0.5 * SEEN);
        assert_eq!(label(&off, mid), 0, "polar {th}: without columns the middle of the layer is a hole");
        assert!(label(&on, mid) > 0, "polar {th}: a column fills it");
        assert!(on.field[on.grid.voxel_of(mid).unwrap()].length() > 0.5, "the field reaches it");
    }
    // Beside the scalp (polar 100°, under no seen hair) the layer stays empty either way, and the
    // head's inside is never hair.
    let side = Vec3::new(100f32.to_radians().sin(), 0.0, 100f32.to_radians().cos()) * (R + 0.5 * SEEN);
    assert_eq!((label(&off, side), label(&on, side)), (0, 0));
    assert_eq!(label(&on, Vec3::new(0.0, 0.0, 0.5 * R)), 0);
    // Near the scalp and near the points both are hair, and columns add only to the hole.
    let added = (0..on.label.len()).filter(|&i| on.label[i] > 0 && off.label[i] == 0).count();
    let removed = (0..on.label.len()).filter(|&i| on.label[i] == 0 && off.label[i] > 0).count();
    assert_eq!(removed, 0);
    assert!(added > 1000, "{added} voxels added");
}

/// The mean rise (the field along the sphere's radius) of the scalp's constrained voxels between
/// the polar angles `lo` and `hi` (degrees).
fn scalp_rise(f: &FlowField, lo: f32, hi: f32) -> f32 {
    let (mut sum, mut n) = (0.0, 0);
    for i in 0..f.label.len() {
        let c = f.grid.centre(i);
        let polar = (c.z / c.length()).acos().to_degrees();
        if f.label[i] == 2 && c.length() < R + f.grid.voxel && (lo..hi).contains(&polar) {
            sum += f.field[i].dot(c.normalize());
            n += 1;
        }
    }
    assert!(n > 20, "{n} scalp voxels");
    sum / n as f32
}

#[test]
fn where_the_hair_stands_off_the_scalp_the_roots_take_off_along_the_normal() {
    // The raw mesh lies 3.8 cm above the scalp: beyond twice a lift of 1 cm, so the scalp's
    // condition is its normal; a lift of 3 cm turns it 0.8 / 3 = 27% of the way; off, it is S,
    // which leans away from the normal away from the crown.
    let (s, part, normal) = (flow(30.0, 0.0), flow(30.0, 0.03), flow(30.0, 0.01));
    let (rs, rp, rn) = (scalp_rise(&s, 30.0, 55.0), scalp_rise(&part, 30.0, 55.0), scalp_rise(&normal, 30.0, 55.0));
    assert!(rn > 0.99, "{rn}");
    assert!(rs < 0.9, "S off the crown leans: {rs}");
    assert!(rs < rp && rp < rn, "{rs} {rp} {rn}");
}
