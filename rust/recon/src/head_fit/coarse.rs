//! The coarse search: initial poses of the template on the raw mesh, each refined briefly by
//! trimmed ICP, the best kept.
//!
//! - Rotations: a super-Fibonacci spiral of SO(3) (Alexa, "Super-Fibonacci Spirals: Fast,
//!   Low-Discrepancy Sampling of SO(3)", CVPR 2022): deterministic and near uniform, so that every
//!   head orientation, face and back, top and bottom, has a start within the ICP's reach. With
//!   cameras, their mean up vector gives the head's up and a ring of rotations about it comes first.
//! - Scale and centre: the raw surface's radius of gyration against the template's, and its centre
//!   (or, with cameras, the point nearest to all optical axes). When extra surfaces (shoulders,
//!   clothes, a backdrop) make these wrong, [`blob_centres`] finds where the surface is densest at
//!   a head's size, for a ladder of smaller scales.

use glam::{DMat3, DQuat, DVec3};
use hairrecon_core::Camera;

/// `n` rotations spread near uniformly over SO(3) (super-Fibonacci spiral).
pub fn rotation_grid(n: usize) -> Vec<DMat3> {
    const PHI: f64 = std::f64::consts::SQRT_2;
    const PSI: f64 = 1.533_751_168_755_204_3;
    (0..n)
        .map(|i| {
            let s = i as f64 + 0.5;
            let r = (s / n as f64).sqrt();
            let big_r = (1.0 - s / n as f64).sqrt();
            let alpha = std::f64::consts::TAU * s / PHI;
            let beta = std::f64::consts::TAU * s / PSI;
            let q = DQuat::from_xyzw(r * alpha.sin(), r * alpha.cos(), big_r * beta.sin(), big_r * beta.cos());
            DMat3::from_quat(q.normalize())
        })
        .collect()
}

/// Rotations (template → raw) that take the template's up (+Z) to within `tilt` of `up` (raw
/// frame): `yaws` turns about up, each at tilts 0 and ±`tilt` about two horizontal axes.
pub fn up_ring(up: DVec3, yaws: usize, tilt: f64) -> Vec<DMat3> {
    let align = DMat3::from_quat(DQuat::from_rotation_arc(DVec3::Z, up.normalize()));
    let tilts = [
        DMat3::IDENTITY,
        DMat3::from_rotation_x(tilt),
        DMat3::from_rotation_x(-tilt),
        DMat3::from_rotation_y(tilt),
        DMat3::from_rotation_y(-tilt),
    ];
    let mut out = Vec::with_capacity(yaws * tilts.len());
    for tl in tilts {
        for k in 0..yaws {
            let yaw = DMat3::from_rotation_z(std::f64::consts::TAU * k as f64 / yaws as f64);
            out.push(align * tl * yaw);
        }
    }
    out
}

/// What the cameras tell: the mean up vector (OpenCV: image y points down) and the point nearest
/// to all optical axes, in the cameras' world frame. `None` without two non-parallel axes.
pub fn camera_prior(cameras: &[Camera]) -> Option<(DVec3, DVec3)> {
    if cameras.len() < 2 {
        return None;
    }
    let mut up = DVec3::ZERO;
    let mut a = DMat3::ZERO;
    let mut b = DVec3::ZERO;
    for cam in cameras {
        let rt = cam.r().transpose().as_dmat3();
        up += rt * DVec3::NEG_Y;
        let d = (rt * DVec3::Z).normalize();
        let c = cam.center().as_dvec3();
        let m = DMat3::IDENTITY - DMat3::from_cols(d * d.x, d * d.y, d * d.z);
        a += m;
        b += m * c;
    }
    if a.determinant().abs() < 1e-9 * cameras.len().pow(3) as f64 || up.length() < 1e-9 {
        return None;
    }
    Some((up.normalize(), a.inverse() * b))
}

/// Where a surface is densest at the scale of a ball of radius `radius`: mean shift of the
/// `points` (area-weighted surface samples) with a flat kernel, from every `stride`-th point,
/// modes merged within `radius / 2`, ordered by how many points their ball holds, at most `max`.
pub fn blob_centres(points: &[DVec3], radius: f64, seeds: usize, max: usize) -> Vec<DVec3> {
    let r2 = radius * radius;
    let step = (points.len() / seeds.max(1)).max(1);
    let mut modes: Vec<(DVec3, usize)> = Vec::new();
    for start in points.iter().step_by(step) {
        let mut c = *start;
        let mut count = 0;
        for _ in 0..30 {
            let (mut sum, mut n) = (DVec3::ZERO, 0usize);
            for &p in points {
                if (p - c).length_squared() <= r2 {
                    sum += p;
                    n += 1;
                }
            }
            if n == 0 {
                break;
            }
            let next = sum / n as f64;
            count = n;
            let moved = (next - c).length();
            c = next;
            if moved < 1e-3 * radius {
                break;
            }
        }
        match modes.iter_mut().find(|(m, _)| (*m - c).length() < 0.5 * radius) {
            Some(m) => {
                if count > m.1 {
                    *m = (c, count);
                }
            }
            None => modes.push((c, count)),
        }
    }
    modes.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.x.total_cmp(&b.0.x)));
    modes.into_iter().take(max).map(|(c, _)| c).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_is_the_ball_s_height_in_the_photos() {
        use glam::Vec3;
        // Three cameras 1.2 m from a ball of 9 cm at (0.1, 0.2, 1.5), one behind a fourth that looks away.
        let c = Vec3::new(0.1, 0.2, 1.5);
        let mut cams: Vec<Camera> = (0..3)
            .map(|i| {
                let a = 2.0 * i as f32;
                let eye = c + 1.2 * Vec3::new(a.cos(), a.sin(), 0.1).normalize();
                Camera::look_at(eye, c, Vec3::Z, 0.5 + 0.1 * i as f32, 300, 400).unwrap()
            })
            .collect();
        cams.push(Camera::look_at(c + Vec3::X, c + 2.0 * Vec3::X, Vec3::Z, 0.5, 300, 400).unwrap());
        // In a frame scaled by 7 and moved: the fraction is the same.
        let s =
            crate::head_fit::Similarity { scale: 7.0, rotation: DMat3::from_rotation_z(0.4), translation: DVec3::ONE };
        let f = Framing::new(&cams, &s).unwrap().fraction(s.apply(c.as_dvec3()), 7.0 * 0.09).unwrap();
        // The ball's top and bottom as each camera sees them (the median camera of the three).
        let mut seen: Vec<f64> = cams[..3]
            .iter()
            .map(|cam| {
                let y = |dz: f32| f64::from(cam.project(c + Vec3::new(0.0, 0.0, dz)).unwrap().pixel.y);
                (y(-0.09) - y(0.09)) / 400.0
            })
            .collect();
        seen.sort_by(f64::total_cmp);
        assert!((f / seen[1] - 1.0).abs() < 0.01, "{f} against {seen:?}");
        assert!(f > 0.05 && f < 1.0, "{f}");
    }

    #[test]
    fn the_rotation_grid_covers_so3() {
        let grid = rotation_grid(240);
        // Every one of many probe rotations is near a grid rotation (the coarse ICP reaches about 30°).
        let probes = rotation_grid(997);
        let worst = probes
            .iter()
            .map(|p| {
                grid.iter()
                    .map(|g| {
                        let c = ((g.transpose() * *p).to_cols_array().iter().step_by(4).sum::<f64>() - 1.0) / 2.0;
                        c.clamp(-1.0, 1.0).acos().to_degrees()
                    })
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max);
        println!("worst gap {worst:.1}°");
        assert!(worst < 35.0, "worst gap {worst:.1}°");
    }
}

/// How the views frame a head: from each camera (in the normalised frame of the fit), how large a
/// ball looks in its image. A photogrammetry capture of a head frames it, so a pose whose head
/// would be a speck in every photo (or overflow them all) is not the head, however well it fits
/// some clutter.
#[derive(Debug, Clone)]
pub struct Framing {
    /// Per camera: its centre, its optical axis (unit) and fy / image height.
    cams: Vec<(DVec3, DVec3, f64)>,
}

impl Framing {
    /// The cameras' framing; `to_normalised` maps their frame (the raw mesh's) to the fit's.
    pub fn new(cameras: &[Camera], to_normalised: &crate::head_fit::Similarity) -> Option<Self> {
        let cams: Vec<(DVec3, DVec3, f64)> = cameras
            .iter()
            .map(|c| {
                let axis = to_normalised.rotation * (c.r().transpose().as_dmat3() * DVec3::Z).normalize();
                let fy = f64::from(c.k_rows()[1][1]);
                (to_normalised.apply(c.center().as_dvec3()), axis, fy / f64::from(c.height().max(1)))
            })
            .collect();
        (!cams.is_empty()).then_some(Self { cams })
    }

    /// The median, over the cameras in front of which it lies, of the apparent diameter of a ball
    /// of `radius` at `centre`, as a fraction of the image height; `None` when no camera has it in
    /// front.
    pub fn fraction(&self, centre: DVec3, radius: f64) -> Option<f64> {
        let mut f: Vec<f64> = self
            .cams
            .iter()
            .filter_map(|&(c, axis, fy_h)| {
                let z = (centre - c).dot(axis);
                (z > 0.0).then(|| 2.0 * radius * fy_h / z)
            })
            .collect();
        if f.is_empty() {
            return None;
        }
        f.sort_by(f64::total_cmp);
        Some(f[f.len() / 2])
    }
}
