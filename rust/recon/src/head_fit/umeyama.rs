//! The closed-form similarity between two point sets in correspondence: Umeyama, "Least-squares
//! estimation of transformation parameters between two point patterns", PAMI 1991.
//!
//! Given pairs (pᵢ, qᵢ) it finds the scale c, rotation R and translation t that minimise
//! Σ |qᵢ − (c R pᵢ + t)|²: the SVD of the cross-covariance Σ = U D Vᵀ gives R = U S Vᵀ with
//! S = diag(1, 1, det(U) det(V)) (the reflection fix: a mirror image is never returned),
//! c = tr(D S) / σₚ², t = μ_q − c R μ_p. In f64, through nalgebra's SVD.

use glam::{DMat3, DVec3};
use nalgebra::Matrix3;

use super::Similarity;

/// The least-squares similarity mapping `src[i]` onto `dst[i]` (`with_scale = false`: a rigid
/// motion, scale 1). `None` when fewer than three pairs are given or the source points are all at one
/// place.
pub fn umeyama(src: &[DVec3], dst: &[DVec3], with_scale: bool) -> Option<Similarity> {
    let n = src.len().min(dst.len());
    if n < 3 {
        return None;
    }
    let inv_n = 1.0 / n as f64;
    let mu_p = src[..n].iter().copied().sum::<DVec3>() * inv_n;
    let mu_q = dst[..n].iter().copied().sum::<DVec3>() * inv_n;
    let mut cov = Matrix3::<f64>::zeros();
    let mut var_p = 0.0;
    for (p, q) in src[..n].iter().zip(&dst[..n]) {
        let a = *p - mu_p;
        let b = *q - mu_q;
        var_p += a.length_squared();
        for r in 0..3 {
            for c in 0..3 {
                cov[(r, c)] += b[r] * a[c];
            }
        }
    }
    var_p *= inv_n;
    cov *= inv_n;
    if (var_p.is_nan() || var_p <= 0.0) || !cov.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = cov.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let d = if u.determinant() * v_t.determinant() < 0.0 { -1.0 } else { 1.0 };
    let s = Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 1.0, d));
    let r = u * s * v_t;
    let scale = if with_scale {
        (svd.singular_values[0] + svd.singular_values[1] + d * svd.singular_values[2]) / var_p
    } else {
        1.0
    };
    if scale.is_nan() || scale <= 0.0 {
        return None;
    }
    let rotation = DMat3::from_cols(
        DVec3::new(r[(0, 0)], r[(1, 0)], r[(2, 0)]),
        DVec3::new(r[(0, 1)], r[(1, 1)], r[(2, 1)]),
        DVec3::new(r[(0, 2)], r[(1, 2)], r[(2, 2)]),
    );
    let translation = mu_q - scale * (rotation * mu_p);
    Some(Similarity { scale, rotation, translation })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    #[test]
    fn recovers_a_similarity_exactly_and_never_a_reflection() {
        let truth = Similarity {
            scale: 3.7,
            rotation: DMat3::from_quat(DQuat::from_axis_angle(DVec3::new(1.0, -2.0, 0.5).normalize(), 2.1)),
            translation: DVec3::new(-4.0, 0.3, 12.0),
        };
        let src: Vec<DVec3> = (0..20)
            .map(|i| {
                let f = i as f64;
                DVec3::new((f * 1.3).sin(), (f * 0.7).cos() * 2.0, (f * 0.11).sin() - 0.5)
            })
            .collect();
        let dst: Vec<DVec3> = src.iter().map(|&p| truth.apply(p)).collect();
        let est = umeyama(&src, &dst, true).unwrap();
        assert!((est.scale - truth.scale).abs() < 1e-9);
        assert!((est.rotation - truth.rotation).abs_diff_eq(DMat3::ZERO, 1e-9));
        assert!(est.translation.abs_diff_eq(truth.translation, 1e-9));
        // A mirrored target: the best proper rotation, det +1.
        let mirrored: Vec<DVec3> = dst.iter().map(|q| DVec3::new(-q.x, q.y, q.z)).collect();
        let m = umeyama(&src, &mirrored, true).unwrap();
        assert!((m.rotation.determinant() - 1.0).abs() < 1e-9);
        assert!(umeyama(&src[..2], &dst[..2], true).is_none());
    }
}
