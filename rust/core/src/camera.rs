//! Pinhole cameras in the OpenCV convention.
//!
//! `x_img = K (R X + t)`: camera x right, y down, z forward; pixel centres at integer coordinates
//! (`docs/method.md`, Conventions). World units are metres. A [`Camera`] is validated at
//! construction: finite values, K invertible with positive focal lengths and zero bottom row, R a
//! proper rotation, a positive image size.

use glam::{Mat3, Vec2, Vec3};
use thiserror::Error;

/// Why a camera could not be built.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CameraError {
    #[error("camera has a non-finite value in {0}; every entry of K, R and t must be a finite number")]
    NotFinite(&'static str),
    #[error(
        "K is not a pinhole intrinsic matrix ({0}); expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0"
    )]
    BadIntrinsics(&'static str),
    #[error(
        "R is not a rotation matrix (|R^T R - I| = {orth:.2e}, det = {det:.4}); give an orthonormal R with det +1"
    )]
    NotRotation { orth: f32, det: f32 },
    #[error("image size {width}x{height} is invalid; width and height must be positive")]
    BadSize { width: u32, height: u32 },
}

/// An OpenCV pinhole camera: intrinsics K, world-to-camera rotation R and translation t, image size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    k: Mat3,
    k_inv: Mat3,
    r: Mat3,
    t: Vec3,
    width: u32,
    height: u32,
}

/// Projection of a world point: pixel position, depth along the optical axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projected {
    pub pixel: Vec2,
    pub depth: f32,
}

impl Camera {
    /// Builds a camera from row-major K (3×3), R (3×3), t (3) and the image size in pixels.
    pub fn new(k: [[f32; 3]; 3], r: [[f32; 3]; 3], t: [f32; 3], width: u32, height: u32) -> Result<Self, CameraError> {
        if k.iter().flatten().any(|v| !v.is_finite()) {
            return Err(CameraError::NotFinite("K"));
        }
        if r.iter().flatten().any(|v| !v.is_finite()) {
            return Err(CameraError::NotFinite("R"));
        }
        if t.iter().any(|v| !v.is_finite()) {
            return Err(CameraError::NotFinite("t"));
        }
        if width == 0 || height == 0 {
            return Err(CameraError::BadSize { width, height });
        }
        if k[1][0] != 0.0 || k[2][0] != 0.0 || k[2][1] != 0.0 || (k[2][2] - 1.0).abs() > 1e-6 {
            return Err(CameraError::BadIntrinsics("the bottom row must be [0, 0, 1] and K[1][0] must be 0"));
        }
        if k[0][0] <= 0.0 || k[1][1] <= 0.0 {
            return Err(CameraError::BadIntrinsics("focal lengths fx and fy must be positive"));
        }
        // A field of view between about 0.06° and 178° across the image's larger side; beyond,
        // projections overflow f32 or every ray is parallel (a unit mix-up, not a lens).
        let size = width.max(height) as f32;
        if !(k[0][0] <= 1e3 * size && k[1][1] <= 1e3 * size && k[0][0] >= 0.01 * size && k[1][1] >= 0.01 * size) {
            return Err(CameraError::BadIntrinsics(
                "fx and fy must lie between 0.01 and 1000 times the image's larger side (in pixels)",
            ));
        }
        if k[0][1].abs() > 1e3 * size || k[0][2].abs() > 1e3 * size || k[1][2].abs() > 1e3 * size {
            return Err(CameraError::BadIntrinsics("skew, cx and cy must lie within 1000 image sizes"));
        }
        // glam matrices are column-major: transpose the row-major input.
        let km = Mat3::from_cols_array_2d(&k).transpose();
        let rm = Mat3::from_cols_array_2d(&r).transpose();
        let rtr = rm.transpose() * rm;
        let orth = (rtr - Mat3::IDENTITY).to_cols_array().iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let det = rm.determinant();
        if orth > 1e-4 || (det - 1.0).abs() > 1e-4 {
            return Err(CameraError::NotRotation { orth, det });
        }
        Ok(Self { k: km, k_inv: km.inverse(), r: rm, t: Vec3::from(t), width, height })
    }

    /// A camera at `eye` looking at `target`, with `up` giving the image's up direction, a vertical
    /// field of view `fov_y` (radians) and the image size; principal point at the image centre.
    pub fn look_at(
        eye: Vec3,
        target: Vec3,
        up: Vec3,
        fov_y: f32,
        width: u32,
        height: u32,
    ) -> Result<Self, CameraError> {
        let z = (target - eye).normalize();
        let x = z.cross(up).normalize(); // camera x (right) = forward × up
        let y = z.cross(x); // camera y (down)
        let r = [x.to_array(), y.to_array(), z.to_array()];
        let t = -(Mat3::from_cols(x, y, z).transpose() * eye);
        let f = 0.5 * height as f32 / (0.5 * fov_y).tan();
        let k = [[f, 0.0, (width as f32 - 1.0) * 0.5], [0.0, f, (height as f32 - 1.0) * 0.5], [0.0, 0.0, 1.0]];
        Self::new(k, r, t.to_array(), width, height)
    }

    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }
    /// K, column-major glam matrix.
    pub fn k(&self) -> Mat3 {
        self.k
    }
    /// R, column-major glam matrix (world to camera).
    pub fn r(&self) -> Mat3 {
        self.r
    }
    pub fn t(&self) -> Vec3 {
        self.t
    }
    /// K as row-major arrays.
    pub fn k_rows(&self) -> [[f32; 3]; 3] {
        self.k.transpose().to_cols_array_2d()
    }
    /// R as row-major arrays.
    pub fn r_rows(&self) -> [[f32; 3]; 3] {
        self.r.transpose().to_cols_array_2d()
    }

    /// Camera centre in world coordinates, `-Rᵀ t`.
    pub fn center(&self) -> Vec3 {
        -(self.r.transpose() * self.t)
    }

    /// Transforms a world point into camera coordinates.
    #[inline]
    pub fn to_camera(&self, p: Vec3) -> Vec3 {
        self.r * p + self.t
    }

    /// Projects a point given in camera coordinates to pixels. The caller ensures `pc.z > 0`.
    #[inline]
    pub fn camera_to_pixel(&self, pc: Vec3) -> Vec2 {
        let q = self.k * pc;
        Vec2::new(q.x / q.z, q.y / q.z)
    }

    /// Projects a world point. `None` when the point is not in front of the camera.
    #[inline]
    pub fn project(&self, p: Vec3) -> Option<Projected> {
        let pc = self.to_camera(p);
        if pc.z <= 1e-9 {
            return None;
        }
        Some(Projected { pixel: self.camera_to_pixel(pc), depth: pc.z })
    }

    /// Back-projects a pixel at a depth (along the optical axis) to a world point.
    pub fn back_project(&self, pixel: Vec2, depth: f32) -> Vec3 {
        let ray = self.k_inv * Vec3::new(pixel.x, pixel.y, 1.0);
        let pc = ray * (depth / ray.z);
        self.r.transpose() * (pc - self.t)
    }

    /// Unit direction in world coordinates of the ray through a pixel.
    pub fn ray_direction(&self, pixel: Vec2) -> Vec3 {
        (self.r.transpose() * (self.k_inv * Vec3::new(pixel.x, pixel.y, 1.0))).normalize()
    }

    /// Jacobian of the projection at a world point: rows are ∂u/∂X and ∂v/∂X (each a world vector).
    /// `None` when the point is not in front of the camera.
    #[inline]
    pub fn project_jacobian(&self, p: Vec3) -> Option<[Vec3; 2]> {
        let pc = self.to_camera(p);
        if pc.z <= 1e-9 {
            return None;
        }
        Some(self.camera_jacobian(pc))
    }

    /// Jacobian of pixel coordinates with respect to the world point, given camera coordinates `pc`.
    #[inline]
    pub fn camera_jacobian(&self, pc: Vec3) -> [Vec3; 2] {
        // q = K pc, u = q.x/q.z, v = q.y/q.z. With K's bottom row [0,0,1], q.z = pc.z.
        let q = self.k * pc;
        let iz = 1.0 / q.z;
        let k0 = self.k.row(0);
        let k1 = self.k.row(1);
        let k2 = self.k.row(2);
        // d(u)/d(pc) = (k0 - u k2) / q.z ; then chain through R: d/dX = Rᵀ (d/dpc).
        let du_dpc = (k0 - k2 * (q.x * iz)) * iz;
        let dv_dpc = (k1 - k2 * (q.y * iz)) * iz;
        let rt = self.r.transpose();
        [rt * du_dpc, rt * dv_dpc]
    }

    /// Whether a pixel position lies inside the image (pixel centres at integers, edges at ±0.5).
    pub fn contains(&self, pixel: Vec2) -> bool {
        pixel.x >= -0.5 && pixel.y >= -0.5 && pixel.x < self.width as f32 - 0.5 && pixel.y < self.height as f32 - 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Camera {
        Camera::look_at(Vec3::new(0.3, -0.9, 0.4), Vec3::new(0.0, 0.0, 0.1), Vec3::Z, 0.5, 341, 512).unwrap()
    }

    #[test]
    fn look_at_projects_target_to_centre_and_up_is_up() {
        let c = cam();
        let p = c.project(Vec3::new(0.0, 0.0, 0.1)).unwrap();
        assert!((p.pixel - Vec2::new(170.0, 255.5)).length() < 1e-3, "{:?}", p);
        // A point above the target appears higher in the image (smaller v).
        let q = c.project(Vec3::new(0.0, 0.0, 0.2)).unwrap();
        assert!(q.pixel.y < p.pixel.y);
        assert!((c.center() - Vec3::new(0.3, -0.9, 0.4)).length() < 1e-5);
    }

    #[test]
    fn back_projection_inverts_projection() {
        let c = cam();
        let x = Vec3::new(0.05, -0.02, 0.15);
        let p = c.project(x).unwrap();
        assert!((c.back_project(p.pixel, p.depth) - x).length() < 1e-5);
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let c = cam();
        let x = Vec3::new(0.05, -0.02, 0.15);
        let j = c.project_jacobian(x).unwrap();
        let h = 1e-4;
        for axis in 0..3 {
            let mut e = Vec3::ZERO;
            e[axis] = h;
            let d = (c.project(x + e).unwrap().pixel - c.project(x - e).unwrap().pixel) / (2.0 * h);
            assert!((d.x - j[0][axis]).abs() < 1e-2 * j[0].length().max(1.0), "axis {axis}: {d:?} vs {j:?}");
            assert!((d.y - j[1][axis]).abs() < 1e-2 * j[1].length().max(1.0), "axis {axis}: {d:?} vs {j:?}");
        }
    }

    #[test]
    fn rejects_bad_cameras() {
        let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let k = [[100.0, 0.0, 50.0], [0.0, 100.0, 50.0], [0.0, 0.0, 1.0]];
        assert!(Camera::new(k, id, [0.0; 3], 100, 100).is_ok());
        let mut r = id;
        r[0][0] = 2.0;
        assert!(matches!(Camera::new(k, r, [0.0; 3], 100, 100), Err(CameraError::NotRotation { .. })));
        let mut kz = k;
        kz[0][0] = 0.0;
        assert!(matches!(Camera::new(kz, id, [0.0; 3], 100, 100), Err(CameraError::BadIntrinsics(_))));
        assert!(matches!(Camera::new(k, id, [f32::NAN, 0.0, 0.0], 100, 100), Err(CameraError::NotFinite("t"))));
        assert!(matches!(Camera::new(k, id, [0.0; 3], 0, 100), Err(CameraError::BadSize { .. })));
        // Focal lengths no lens has (a unit mix-up): rays would overflow or all be parallel.
        for f in [1e30, 1.01e5, 0.99] {
            let mut kf = k;
            kf[0][0] = f;
            assert!(matches!(Camera::new(kf, id, [0.0; 3], 100, 100), Err(CameraError::BadIntrinsics(_))), "{f}");
        }
        let mut kc = k;
        kc[0][2] = 2e5;
        assert!(matches!(Camera::new(kc, id, [0.0; 3], 100, 100), Err(CameraError::BadIntrinsics(_))));
    }
}
