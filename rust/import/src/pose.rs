//! Small 3D helpers shared by the calibration readers and writers: 3x3 matrices as row-major
//! arrays, unit quaternions (Hamilton convention, `w` first, as COLMAP stores them), the nearest
//! rotation to an almost-orthonormal matrix, and similarity transforms `X ↦ s R X + t`.
//!
//! A pose is stored world-to-camera (`X_cam = R X + t`); tools that store camera-to-world give the
//! camera's rotation `Rᵀ` and centre `C = -Rᵀ t`.

use nalgebra::{Matrix3, Quaternion, Rotation3, UnitQuaternion};

/// A row-major 3x3 matrix.
pub type Mat3 = [[f64; 3]; 3];

/// The identity matrix.
pub const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// How far `RᵀR` may be from the identity (largest entry) for a matrix read from a file to be taken
/// as a rotation printed with few digits; it is then replaced by the nearest rotation.
pub const ORTHONORMAL_TOLERANCE: f64 = 1e-4;

pub fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    m
}

pub fn transpose(a: &Mat3) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = a[j][i];
        }
    }
    m
}

pub fn mul_vec(a: &Mat3, v: &[f64; 3]) -> [f64; 3] {
    [
        a[0][0] * v[0] + a[0][1] * v[1] + a[0][2] * v[2],
        a[1][0] * v[0] + a[1][1] * v[1] + a[1][2] * v[2],
        a[2][0] * v[0] + a[2][1] * v[1] + a[2][2] * v[2],
    ]
}

/// The camera centre `C = -Rᵀ t` of a world-to-camera pose.
pub fn centre(r: &Mat3, t: &[f64; 3]) -> [f64; 3] {
    let c = mul_vec(&transpose(r), t);
    [-c[0], -c[1], -c[2]]
}

/// The translation `t = -R C` of a world-to-camera pose with rotation `r` and centre `c`.
pub fn translation(r: &Mat3, c: &[f64; 3]) -> [f64; 3] {
    let t = mul_vec(r, c);
    [-t[0], -t[1], -t[2]]
}

/// The rotation of a Hamilton quaternion `(w, x, y, z)`, normalized first.
///
/// Fails (with the reason) when a component is not finite or the norm is zero.
pub fn rotation_from_quaternion(q: [f64; 4]) -> Result<Mat3, String> {
    if q.iter().any(|v| !v.is_finite()) {
        return Err(format!("the quaternion {q:?} is not finite (NaN pose)"));
    }
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if n == 0.0 || !n.is_finite() {
        return Err(format!("the quaternion {q:?} has zero norm (NaN pose)"));
    }
    let uq = UnitQuaternion::from_quaternion(Quaternion::new(q[0] / n, q[1] / n, q[2] / n, q[3] / n));
    Ok(from_na(uq.to_rotation_matrix().matrix()))
}

/// The unit quaternion `(w, x, y, z)` of a rotation, with `w ≥ 0`.
pub fn quaternion_from_rotation(r: &Mat3) -> [f64; 4] {
    let rot = Rotation3::from_matrix_unchecked(to_na(r));
    let q = UnitQuaternion::from_rotation_matrix(&rot);
    let (w, x, y, z) = (q.w, q.i, q.j, q.k);
    if w < 0.0 {
        [-w, -x, -y, -z]
    } else {
        [w, x, y, z]
    }
}

/// The rotation nearest to `m` (by SVD) when `m` is a rotation up to [`ORTHONORMAL_TOLERANCE`];
/// otherwise the reason it is not one.
pub fn nearest_rotation(m: &Mat3) -> Result<Mat3, String> {
    if m.iter().flatten().any(|v| !v.is_finite()) {
        return Err(format!("the rotation {m:?} is not finite (NaN pose)"));
    }
    let a = to_na(m);
    let gram = a.transpose() * a - Matrix3::identity();
    let dev = gram.iter().fold(0.0f64, |acc, v| acc.max(v.abs()));
    if dev > ORTHONORMAL_TOLERANCE {
        return Err(format!(
            "the rotation part {m:?} is not orthonormal (RᵀR differs from the identity by {dev:e}); \
             the matrix holds a scale or shear"
        ));
    }
    if a.determinant() <= 0.0 {
        return Err(format!("the rotation part {m:?} is a reflection (determinant ≤ 0), not a rotation"));
    }
    if dev == 0.0 {
        return Ok(*m);
    }
    let svd = a.svd(true, true);
    let (u, v_t) = (svd.u.expect("u requested"), svd.v_t.expect("v_t requested"));
    Ok(from_na(&(u * v_t)))
}

/// A similarity transform `X ↦ scale · rotation · X + translation`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Similarity {
    pub rotation: Mat3,
    pub translation: [f64; 3],
    pub scale: f64,
}

impl Similarity {
    pub const IDENTITY: Similarity = Similarity { rotation: IDENTITY, translation: [0.0; 3], scale: 1.0 };

    pub fn apply(&self, x: &[f64; 3]) -> [f64; 3] {
        let r = mul_vec(&self.rotation, x);
        [
            self.scale * r[0] + self.translation[0],
            self.scale * r[1] + self.translation[1],
            self.scale * r[2] + self.translation[2],
        ]
    }

    /// `self ∘ other`: applies `other` first.
    pub fn compose(&self, other: &Similarity) -> Similarity {
        Similarity {
            rotation: mul(&self.rotation, &other.rotation),
            translation: self.apply(&other.translation),
            scale: self.scale * other.scale,
        }
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Similarity {
        let rt = transpose(&self.rotation);
        let t = mul_vec(&rt, &self.translation);
        let s = 1.0 / self.scale;
        Similarity { rotation: rt, translation: [-s * t[0], -s * t[1], -s * t[2]], scale: s }
    }
}

fn to_na(m: &Mat3) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| m[i][j])
}

fn from_na(m: &Matrix3<f64>) -> Mat3 {
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = m[(i, j)];
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternion_round_trip() {
        let r = rotation_from_quaternion([0.3, -0.5, 0.7, 0.2]).unwrap();
        let q = quaternion_from_rotation(&r);
        let r2 = rotation_from_quaternion(q).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                assert!((r[i][j] - r2[i][j]).abs() < 1e-15);
            }
        }
        // Hamilton convention: a quarter turn about z maps x to y.
        let s = 0.5f64.sqrt();
        let rz = rotation_from_quaternion([s, 0.0, 0.0, s]).unwrap();
        let y = mul_vec(&rz, &[1.0, 0.0, 0.0]);
        assert!((y[1] - 1.0).abs() < 1e-15 && y[0].abs() < 1e-15);
    }

    #[test]
    fn bad_quaternions() {
        assert!(rotation_from_quaternion([f64::NAN, 0.0, 0.0, 1.0]).unwrap_err().contains("NaN pose"));
        assert!(rotation_from_quaternion([0.0; 4]).unwrap_err().contains("zero norm"));
    }

    #[test]
    fn nearest_rotation_fixes_rounding_and_rejects_scale() {
        let r = rotation_from_quaternion([0.9, 0.1, -0.3, 0.2]).unwrap();
        let rounded = r.map(|row| row.map(|v| (v * 1e6).round() / 1e6));
        let fixed = nearest_rotation(&rounded).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                assert!((fixed[i][j] - r[i][j]).abs() < 1e-5);
            }
        }
        let scaled = r.map(|row| row.map(|v| 2.0 * v));
        assert!(nearest_rotation(&scaled).unwrap_err().contains("not orthonormal"));
        let mut reflected = r;
        reflected[2] = reflected[2].map(|v| -v);
        assert!(nearest_rotation(&reflected).unwrap_err().contains("reflection"));
    }

    #[test]
    fn similarity_inverse_and_compose() {
        let a = Similarity {
            rotation: rotation_from_quaternion([0.2, 0.4, -0.1, 0.8]).unwrap(),
            translation: [1.0, -2.0, 3.0],
            scale: 2.5,
        };
        let x = [0.3, 0.7, -1.1];
        let back = a.inverse().apply(&a.apply(&x));
        let id = a.compose(&a.inverse()).apply(&x);
        for k in 0..3 {
            assert!((back[k] - x[k]).abs() < 1e-14 && (id[k] - x[k]).abs() < 1e-14);
        }
    }
}
