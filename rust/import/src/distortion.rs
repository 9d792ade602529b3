//! Lens distortion math for [`Distortion`]: the forward map, its Jacobian, its inverse, and the
//! radius up to which the model is one-to-one.
//!
//! The model (see [`Distortion`]) maps undistorted normalized coordinates `(x, y) = (X/Z, Y/Z)` to
//! distorted ones `(x', y')`:
//!
//! ```text
//! r² = x² + y²
//! N(r²) = 1 + k1 r² + k2 r⁴ + k3 r⁶ + k4 r⁸        D(r²) = 1 + d1 r² + d2 r⁴ + d3 r⁶
//! x' = x N/D + 2 p1 x y + p2 (r² + 2 x²)
//! y' = y N/D + p1 (r² + 2 y²) + 2 p2 x y
//! ```
//!
//! With `ρ = N/D` and `ρ' = dρ/d(r²) = (N' D − N D') / D²`, the Jacobian is
//!
//! ```text
//! ∂x'/∂x = ρ + 2 x² ρ' + 2 p1 y + 6 p2 x      ∂x'/∂y = 2 x y ρ' + 2 p1 x + 2 p2 y
//! ∂y'/∂x = 2 x y ρ' + 2 p1 x + 2 p2 y         ∂y'/∂y = ρ + 2 y² ρ' + 6 p1 y + 2 p2 x
//! ```
//!
//! References: OpenCV, "Camera Calibration and 3D Reconstruction" (the `calib3d` module's
//! distortion model, <https://docs.opencv.org/4.x/d9/d0c/group__calib3d.html>); J. Heikkilä and
//! O. Silvén, "A Four-step Camera Calibration Procedure with Implicit Image Correction", CVPR 1997
//! (the radial plus tangential model and its iterative inversion).
//!
//! **Valid radius.** A polynomial model fitted to a lens is only meaningful where the radial map
//! `r ↦ r ρ(r²)` increases: beyond its first maximum (or where `D` reaches zero) the model folds
//! back, several undistorted rays land on the same distorted point, and the lens never saw those
//! rays anyway. [`Distortion::valid_radius`] finds that radius; [`Distortion::undistort`] refuses
//! solutions beyond it and the photo resampler marks such output pixels as not covered.

use crate::scene::Distortion;

/// Largest undistorted radius [`Distortion::valid_radius`] searches (about 87° off axis).
pub const MAX_SEARCH_RADIUS: f64 = 20.0;

/// Step of the valid-radius scan in normalized units.
const RADIUS_STEP: f64 = 1e-3;

/// Tolerance of [`Distortion::undistort`] on the distorted coordinates (relative to their size
/// when it exceeds 1).
pub const UNDISTORT_TOLERANCE: f64 = 1e-12;

/// Newton iterations before [`Distortion::undistort`] gives up.
const MAX_ITERATIONS: usize = 100;

impl Distortion {
    /// `(ρ, dρ/d(r²), D)` at `r2`: the radial factor, its derivative in `r²` and the denominator.
    #[inline]
    fn radial(&self, r2: f64) -> (f64, f64, f64) {
        let [k1, k2, k3, k4] = self.k;
        let [d1, d2, d3] = self.d;
        let n = 1.0 + r2 * (k1 + r2 * (k2 + r2 * (k3 + r2 * k4)));
        let dn = k1 + r2 * (2.0 * k2 + r2 * (3.0 * k3 + r2 * 4.0 * k4));
        let d = 1.0 + r2 * (d1 + r2 * (d2 + r2 * d3));
        let dd = d1 + r2 * (2.0 * d2 + r2 * 3.0 * d3);
        (n / d, (dn * d - n * dd) / (d * d), d)
    }

    /// The distorted normalized coordinates of the undistorted `(x, y)`.
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let (rho, _, _) = self.radial(r2);
        let [p1, p2] = self.p;
        (x * rho + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x), y * rho + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y)
    }

    /// [`Self::distort`] and its Jacobian `[[∂x'/∂x, ∂x'/∂y], [∂y'/∂x, ∂y'/∂y]]` (module docs).
    #[inline]
    pub fn distort_with_jacobian(&self, x: f64, y: f64) -> ((f64, f64), [[f64; 2]; 2]) {
        let r2 = x * x + y * y;
        let (rho, drho, _) = self.radial(r2);
        let [p1, p2] = self.p;
        let xd = x * rho + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * rho + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        let cross = 2.0 * x * y * drho + 2.0 * p1 * x + 2.0 * p2 * y;
        let jxx = rho + 2.0 * x * x * drho + 2.0 * p1 * y + 6.0 * p2 * x;
        let jyy = rho + 2.0 * y * y * drho + 6.0 * p1 * y + 2.0 * p2 * x;
        ((xd, yd), [[jxx, cross], [cross, jyy]])
    }

    /// The undistorted radius up to which the radial map `r ↦ r ρ(r²)` increases and `D > 0`
    /// (module docs), found by scanning in steps of 10⁻³ and refining by bisection;
    /// [`MAX_SEARCH_RADIUS`] when the model stays valid that far. Tangential terms are ignored (they
    /// are small where calibrations are meaningful; [`Self::undistort`] also checks the full
    /// Jacobian). Costs about 20,000 polynomial evaluations: compute it once per camera.
    pub fn valid_radius(&self) -> f64 {
        // d/dr (r ρ(r²)) = ρ + 2 r² ρ'
        let ok = |r: f64| {
            let r2 = r * r;
            let (rho, drho, d) = self.radial(r2);
            d > 0.0 && rho + 2.0 * r2 * drho > 0.0
        };
        if self.k == [0.0; 4] && self.d == [0.0; 3] {
            return MAX_SEARCH_RADIUS;
        }
        let steps = (MAX_SEARCH_RADIUS / RADIUS_STEP) as usize;
        for i in 1..=steps {
            let r = i as f64 * RADIUS_STEP;
            if !ok(r) {
                let (mut lo, mut hi) = (r - RADIUS_STEP, r);
                for _ in 0..50 {
                    let mid = 0.5 * (lo + hi);
                    if ok(mid) {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                return lo;
            }
        }
        MAX_SEARCH_RADIUS
    }

    /// The undistorted `(x, y)` whose distortion is `(xd, yd)`, by Newton's method with the
    /// analytic Jacobian (a step that does not reduce the residual is halved), to
    /// [`UNDISTORT_TOLERANCE`] on the distorted coordinates. `None` when it does not converge,
    /// or when the solution lies beyond [`Self::valid_radius`] or where the Jacobian is not
    /// orientation-preserving (a point the lens model cannot have produced).
    pub fn undistort(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        self.undistort_within(xd, yd, self.valid_radius())
    }

    /// [`Self::undistort`] with the valid radius given (from [`Self::valid_radius`]), for callers
    /// that invert many points of one camera.
    pub fn undistort_within(&self, xd: f64, yd: f64, valid_radius: f64) -> Option<(f64, f64)> {
        if !(xd.is_finite() && yd.is_finite()) {
            return None;
        }
        if self.is_none() {
            return Some((xd, yd));
        }
        let tol = UNDISTORT_TOLERANCE * xd.abs().max(yd.abs()).max(1.0);
        let residual = |x: f64, y: f64| {
            let (dx, dy) = self.distort(x, y);
            (dx - xd, dy - yd)
        };
        let (mut x, mut y) = (xd, yd);
        let (mut ex, mut ey) = residual(x, y);
        let mut converged = false;
        for _ in 0..MAX_ITERATIONS {
            if ex.abs().max(ey.abs()) <= tol {
                converged = true;
                break;
            }
            let (_, [[a, b], [c, d]]) = self.distort_with_jacobian(x, y);
            let det = a * d - b * c;
            if det.abs() < 1e-300 || !det.is_finite() {
                return None;
            }
            let sx = (d * ex - b * ey) / det;
            let sy = (a * ey - c * ex) / det;
            let norm = ex.hypot(ey);
            let mut t = 1.0;
            loop {
                let (nx, ny) = (x - t * sx, y - t * sy);
                let (nex, ney) = residual(nx, ny);
                if nex.hypot(ney) < norm || t < 1e-6 {
                    (x, y, ex, ey) = (nx, ny, nex, ney);
                    break;
                }
                t *= 0.5;
            }
            if !(x.is_finite() && y.is_finite()) {
                return None;
            }
        }
        if !converged && ex.abs().max(ey.abs()) > tol {
            return None;
        }
        let (_, [[a, b], [c, d]]) = self.distort_with_jacobian(x, y);
        if x.hypot(y) > valid_radius || a * d - b * c <= 0.0 {
            return None;
        }
        Some((x, y))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opencv() -> Distortion {
        Distortion { k: [-0.1, 0.02, 0.0, 0.0], d: [0.0; 3], p: [1e-3, 1e-3] }
    }

    fn full() -> Distortion {
        Distortion { k: [-0.12, 0.03, -0.004, 0.0005], d: [0.01, -0.002, 0.0003], p: [-7e-4, 4e-4] }
    }

    /// Normalized coordinates of a 4000x3000 photo with f = 3000 px, centre at the middle, on a
    /// 41x41 grid reaching the corners.
    fn image_grid() -> Vec<(f64, f64)> {
        let (w, h, f) = (4000.0, 3000.0, 3000.0);
        let mut pts = Vec::new();
        for j in 0..=40 {
            for i in 0..=40 {
                let u = i as f64 / 40.0 * (w - 1.0);
                let v = j as f64 / 40.0 * (h - 1.0);
                pts.push(((u - (w - 1.0) / 2.0) / f, (v - (h - 1.0) / 2.0) / f));
            }
        }
        pts
    }

    #[test]
    fn undistort_inverts_distort_over_the_image() {
        for dist in [opencv(), full()] {
            let mut worst = 0.0f64;
            for (x, y) in image_grid() {
                // both directions: undistort(distort(p)) = p and distort(undistort(q)) = q
                let (xd, yd) = dist.distort(x, y);
                let (ux, uy) = dist.undistort(xd, yd).expect("converges inside the image");
                worst = worst.max((ux - x).abs()).max((uy - y).abs());
                let (ux, uy) = dist.undistort(x, y).expect("converges inside the image");
                let (rx, ry) = dist.distort(ux, uy);
                worst = worst.max((rx - x).abs()).max((ry - y).abs());
            }
            assert!(worst < 1e-10, "round trip error {worst:e} for {dist:?}");
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let h = 1e-6;
        for dist in [opencv(), full()] {
            for (x, y) in image_grid().into_iter().step_by(7) {
                let (_, j) = dist.distort_with_jacobian(x, y);
                let (xp, yp) = dist.distort(x + h, y);
                let (xm, ym) = dist.distort(x - h, y);
                let col_x = [(xp - xm) / (2.0 * h), (yp - ym) / (2.0 * h)];
                let (xp, yp) = dist.distort(x, y + h);
                let (xm, ym) = dist.distort(x, y - h);
                let col_y = [(xp - xm) / (2.0 * h), (yp - ym) / (2.0 * h)];
                for (r, fd) in [[col_x[0], col_y[0]], [col_x[1], col_y[1]]].iter().enumerate() {
                    for c in 0..2 {
                        assert!((j[r][c] - fd[c]).abs() < 1e-7, "J[{r}][{c}] = {} vs {} at ({x}, {y})", j[r][c], fd[c]);
                    }
                }
            }
        }
    }

    #[test]
    fn distort_follows_the_formula_at_a_point() {
        // hand-computed: x = 0.3, y = -0.2, r² = 0.13
        let d = opencv();
        let (x, y) = (0.3, -0.2);
        let r2: f64 = 0.13;
        let rho = 1.0 - 0.1 * r2 + 0.02 * r2 * r2;
        let ex = x * rho + 2.0 * 1e-3 * x * y + 1e-3 * (r2 + 2.0 * x * x);
        let ey = y * rho + 1e-3 * (r2 + 2.0 * y * y) + 2.0 * 1e-3 * x * y;
        let (dx, dy) = d.distort(x, y);
        assert!((dx - ex).abs() < 1e-15 && (dy - ey).abs() < 1e-15);
        assert_eq!(Distortion::default().distort(x, y), (x, y));
    }

    #[test]
    fn valid_radius_finds_the_fold_and_undistort_refuses_beyond_it() {
        // r (1 - 0.2 r²) peaks at r = 1/sqrt(0.6)
        let d = Distortion { k: [-0.2, 0.0, 0.0, 0.0], ..Default::default() };
        let r_max = d.valid_radius();
        assert!((r_max - 1.0 / 0.6f64.sqrt()).abs() < 1e-9, "{r_max}");
        // the largest distorted radius the model reaches
        let peak = r_max * (1.0 - 0.2 * r_max * r_max);
        assert!(d.undistort(0.9 * peak, 0.0).is_some());
        assert!(d.undistort(1.1 * peak, 0.0).is_none(), "no undistorted point distorts beyond the fold");
        // the OpenCV example never folds
        assert_eq!(opencv().valid_radius(), MAX_SEARCH_RADIUS);
        // a denominator reaching zero bounds the model too: 1 - 0.5 r² = 0 at r = sqrt(2)
        let rational = Distortion { d: [-0.5, 0.0, 0.0], ..Default::default() };
        assert!(rational.valid_radius() < 2f64.sqrt());
    }

    #[test]
    fn undistort_of_no_distortion_is_identity_and_non_finite_is_none() {
        assert_eq!(Distortion::default().undistort(0.4, -1.2), Some((0.4, -1.2)));
        assert_eq!(opencv().undistort(f64::NAN, 0.0), None);
    }
}
