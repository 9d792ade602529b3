//! The fit's metric on synthetic captures, whose true scalp is known: how far the fitted scalp's
//! surface lies from the true one.

use hairrecon_core::{Bvh, TriMesh};

use super::template::sample_surface;

/// Symmetric surface distances between two meshes, in their units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceError {
    pub mean: f64,
    pub p95: f64,
    pub max: f64,
}

/// Distances from `n` area-weighted samples of each surface to the other (seeded), pooled.
/// `None` when either mesh has no area.
pub fn surface_error(a: &TriMesh, b: &TriMesh, n: usize) -> Option<SurfaceError> {
    let one_way = |from: &TriMesh, to: &TriMesh| -> Option<Vec<f64>> {
        let pts = sample_surface(from, |_| true, n, 0x5ca1_e77e);
        if pts.is_empty() {
            return None;
        }
        let bvh = Bvh::new(to.clone());
        pts.iter()
            .map(|p| bvh.closest_point(p.as_vec3(), f32::INFINITY).map(|c| (c.point.as_dvec3() - *p).length()))
            .collect()
    };
    let mut d = one_way(a, b)?;
    d.extend(one_way(b, a)?);
    d.sort_by(f64::total_cmp);
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let p95 = d[((d.len() as f64 * 0.95) as usize).min(d.len() - 1)];
    Some(SurfaceError { mean, p95, max: d[d.len() - 1] })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use hairrecon_core::mesh::unit_cube;

    #[test]
    fn a_shifted_cube_is_as_far_as_its_shift() {
        let a = unit_cube();
        let mut b = unit_cube();
        let e = surface_error(&a, &b, 2000).unwrap();
        assert!(e.max < 1e-6, "{e:?}");
        for v in &mut b.vertices {
            *v += Vec3::new(0.0, 0.0, 0.1);
        }
        let e = surface_error(&a, &b, 4000).unwrap();
        // Top and bottom faces (1/3 of the area) are 0.1 apart; the sides' points lie on the other
        // cube's sides except the 0.1 strips beyond its top or bottom.
        assert!(e.max > 0.099 && e.max < 0.1001, "{e:?}");
        assert!(e.mean > 0.02 && e.mean < 0.05, "{e:?}");
    }
}
