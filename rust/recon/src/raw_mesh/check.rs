//! How well a raw mesh fits the hair that the photographs see (issue 3's acceptance criterion).
//!
//! In: a mesh, ground-truth strand points, and the depth maps of the photographs (for synthetic
//! captures the Cycles depth of what each pixel's first sample hit, at the true strand radius:
//! `gt/depth`). Out: a [`SeenHairCheck`] over the points that are **seen** in at least
//! `min_views` views, a point being seen in a view when it projects into the image, in front of
//! the camera, and its depth is within `depth_tolerance` of the depth map's value at the nearest
//! pixel (i.e. neither the head nor other hair hides it in that photograph).
//!
//! The figures: the share of seen points within `within` of the mesh, the median and 90th
//! percentile of the unsigned distance, and the signed distance, positive where the mesh surface
//! lies in front of the point (the point is inside the mesh) and negative where the point sticks
//! out of it. A raw mesh that bounds the hair volume from outside has most of its error positive.

use glam::Vec3;
use hairrecon_core::mesh::Bvh;
use hairrecon_core::TriMesh;
use rayon::prelude::*;

use super::tsdf::DepthView;

/// Settings of [`check_seen_hair`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckOptions {
    /// A point is seen in a view when |depth map − point depth| < this (metres, default 1 mm).
    pub depth_tolerance: f32,
    /// Points seen in fewer views are left out (default 2).
    pub min_views: usize,
    /// The distance the criterion counts within (metres, default 3 mm).
    pub within: f32,
}

impl Default for CheckOptions {
    fn default() -> Self {
        Self { depth_tolerance: 1e-3, min_views: 2, within: 3e-3 }
    }
}

/// The figures of [`check_seen_hair`]. Distances in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct SeenHairCheck {
    pub options: CheckOptions,
    /// Points tested.
    pub points: usize,
    /// Points seen in at least `min_views` views.
    pub seen: usize,
    /// Share of the seen points within `options.within` of the mesh.
    pub within: f32,
    /// Median and 90th percentile of the unsigned distance.
    pub median: f32,
    pub p90: f32,
    /// Signed distance, positive where the mesh lies in front of the point: median, 10th and 90th
    /// percentiles.
    pub signed_median: f32,
    pub signed_p10: f32,
    pub signed_p90: f32,
    /// Share of the seen points that lie more than `within` inside the mesh (the surface is in
    /// front of them), and more than `within` outside it.
    pub beyond_inside: f32,
    pub beyond_outside: f32,
}

impl std::fmt::Display for SeenHairCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mm = |x: f32| x * 1e3;
        write!(
            f,
            "{} of {} points seen in >= {} views (depth within {:.2} mm); {:.2}% within {:.1} mm of the mesh; \
             distance median {:.2} mm, p90 {:.2} mm; signed (+ = mesh in front of the point) median {:+.2} mm, \
             p10 {:+.2} mm, p90 {:+.2} mm; {:.2}% more than {:.1} mm inside, {:.2}% more than {:.1} mm outside",
            self.seen,
            self.points,
            self.options.min_views,
            mm(self.options.depth_tolerance),
            100.0 * self.within,
            mm(self.options.within),
            mm(self.median),
            mm(self.p90),
            mm(self.signed_median),
            mm(self.signed_p10),
            mm(self.signed_p90),
            100.0 * self.beyond_inside,
            mm(self.options.within),
            100.0 * self.beyond_outside,
            mm(self.options.within),
        )
    }
}

/// How many of `views` see each point (see the module doc).
pub fn seen_counts(points: &[Vec3], views: &[DepthView], depth_tolerance: f32) -> Vec<u32> {
    points
        .par_iter()
        .map(|&p| {
            let mut n = 0u32;
            for v in views {
                let pc = v.camera.to_camera(p);
                if pc.z <= 1e-6 {
                    continue;
                }
                if let Some(d) = v.sample(v.camera.camera_to_pixel(pc)) {
                    if d > 0.0 && (d - pc.z).abs() < depth_tolerance {
                        n += 1;
                    }
                }
            }
            n
        })
        .collect()
}

/// Signed distances of `points` to `mesh`: positive inside (the mesh surface in front of the
/// point), negative outside.
pub fn depth_below_surface(mesh: &TriMesh, points: &[Vec3]) -> Vec<f32> {
    let bvh = Bvh::new(mesh.clone());
    points.par_iter().map(|&p| bvh.signed_distance(p, f32::INFINITY).map_or(f32::INFINITY, |d| -d)).collect()
}

fn quantile(sorted: &[f32], q: f32) -> f32 {
    if sorted.is_empty() {
        return f32::NAN;
    }
    let i = ((sorted.len() - 1) as f32 * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// Measures `mesh` against the `points` seen in at least `opts.min_views` of `views` (see the
/// module doc). Returns the figures and, per seen point, (its index, its signed distance).
pub fn check_seen_hair(
    mesh: &TriMesh,
    points: &[Vec3],
    views: &[DepthView],
    opts: &CheckOptions,
) -> (SeenHairCheck, Vec<(usize, f32)>) {
    let counts = seen_counts(points, views, opts.depth_tolerance);
    let idx: Vec<usize> = (0..points.len()).filter(|&i| counts[i] as usize >= opts.min_views).collect();
    let sel: Vec<Vec3> = idx.iter().map(|&i| points[i]).collect();
    let signed = depth_below_surface(mesh, &sel);
    let mut s = signed.clone();
    s.sort_by(f32::total_cmp);
    let mut u: Vec<f32> = signed.iter().map(|d| d.abs()).collect();
    u.sort_by(f32::total_cmp);
    let n = signed.len().max(1) as f32;
    let share = |f: &dyn Fn(f32) -> bool| signed.iter().filter(|&&d| f(d)).count() as f32 / n;
    let report = SeenHairCheck {
        options: *opts,
        points: points.len(),
        seen: idx.len(),
        within: share(&|d| d.abs() < opts.within),
        median: quantile(&u, 0.5),
        p90: quantile(&u, 0.9),
        signed_median: quantile(&s, 0.5),
        signed_p10: quantile(&s, 0.1),
        signed_p90: quantile(&s, 0.9),
        beyond_inside: share(&|d| d >= opts.within),
        beyond_outside: share(&|d| d <= -opts.within),
    };
    (report, idx.into_iter().zip(signed).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use hairrecon_core::Camera;

    /// A unit cube seen by one camera on +Z: points on its top face are seen, points under it are
    /// not; a point 1 cm inside the mesh has signed distance +1 cm.
    #[test]
    fn points_on_and_under_a_seen_face() {
        let mesh = hairrecon_core::mesh::unit_cube();
        let (lo, hi) = mesh.bbox();
        let top = hi.z;
        let centre = 0.5 * (lo + hi);
        let eye = Vec3::new(centre.x, centre.y, top + 3.0);
        let mut views = Vec::new();
        for _ in 0..2 {
            let cam = Camera::look_at(eye, centre, Vec3::Y, 0.5, 64, 64).unwrap();
            // Depth of the plane z = top for every pixel: it faces the camera, planar depth 3.
            views.push(DepthView { camera: cam, depth: vec![3.0; 64 * 64] });
        }
        let pts = vec![Vec3::new(centre.x, centre.y, top), Vec3::new(centre.x, centre.y, top - 0.01)];
        let opts = CheckOptions::default();
        let counts = seen_counts(&pts, &views, opts.depth_tolerance);
        assert_eq!(counts, vec![2, 0]);
        let d = depth_below_surface(&mesh, &pts);
        assert!(d[0].abs() < 1e-5 && (d[1] - 0.01).abs() < 1e-5, "{d:?}");
        let (r, per) = check_seen_hair(&mesh, &pts, &views, &opts);
        assert_eq!((r.seen, per.len()), (1, 1));
        assert_eq!(r.within, 1.0);
    }
}
