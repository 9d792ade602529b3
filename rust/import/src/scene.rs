//! The importers' common description of a calibrated capture, before any photo is read.
//!
//! Conventions (the same as `hairrecon_core::camera`): OpenCV axes (camera x right, y down,
//! z forward), `x_img = K (R X + t)` with `X` in the source's world frame and units, pixel centres
//! at integer coordinates (the first pixel's centre is (0, 0)). Readers convert each tool's own
//! conventions to these, exactly, in f64.

use std::path::PathBuf;

/// Pinhole intrinsics in pixels of the view's original photo, pixel centres at integers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// `K[0][1]`; zero for every COLMAP model.
    pub skew: f64,
}

impl Intrinsics {
    /// Row-major K.
    pub fn k(&self) -> [[f64; 3]; 3] {
        [[self.fx, self.skew, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]]
    }
}

/// Lens distortion of normalized camera coordinates `(x, y) = (X/Z, Y/Z)`, the OpenCV model
/// extended to an r⁸ term:
///
/// ```text
/// r² = x² + y²
/// radial = (1 + k1 r² + k2 r⁴ + k3 r⁶ + k4 r⁸) / (1 + d1 r² + d2 r⁴ + d3 r⁶)
/// x' = x radial + 2 p1 x y + p2 (r² + 2 x²)
/// y' = y radial + p1 (r² + 2 y²) + 2 p2 x y
/// ```
///
/// COLMAP's SIMPLE_RADIAL, RADIAL, OPENCV and FULL_OPENCV (its k4..k6 are `d1..d3` here), and
/// Metashape's k1..k4 with p1/p2 (which Metashape names in the opposite order) all map onto it.
/// All zeros is no distortion.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Distortion {
    /// Numerator coefficients k1..k4 (r², r⁴, r⁶, r⁸).
    pub k: [f64; 4],
    /// Denominator coefficients d1..d3 (r², r⁴, r⁶): OpenCV's rational k4..k6.
    pub d: [f64; 3],
    /// Tangential p1, p2 in OpenCV's order.
    pub p: [f64; 2],
}

impl Distortion {
    /// True when every coefficient is zero.
    pub fn is_none(&self) -> bool {
        self.k.iter().chain(&self.d).chain(&self.p).all(|&c| c == 0.0)
    }
}

/// The unit of the source's world frame (the capture format's own type).
pub use hairrecon_core::capture::Units;

/// One calibrated view as a tool exported it.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneView {
    /// The view's name: the photo's file name without its folder (unique in a scene).
    pub name: String,
    /// The photo's path as the source names it, relative to the images folder the user gives.
    pub image: PathBuf,
    /// Size of the photo the calibration refers to, in pixels.
    pub width: u32,
    pub height: u32,
    pub intrinsics: Intrinsics,
    pub distortion: Distortion,
    /// World-to-camera rotation, row-major, OpenCV axes.
    pub r: [[f64; 3]; 3],
    /// World-to-camera translation.
    pub t: [f64; 3],
}

/// A calibrated capture as read from a tool's files, in the tool's frame and units.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub views: Vec<SceneView>,
    /// Sparse 3D points when the source has them (COLMAP's points3D), in the same frame.
    pub points: Vec<[f64; 3]>,
    pub units: Units,
    /// What the reader skipped or could not be sure of (e.g. Metashape cameras that were not
    /// aligned), one sentence each, for the importer to show.
    pub warnings: Vec<String>,
}

impl SceneView {
    /// The pixel where the world point `x` appears in this view, with the lens distortion applied
    /// (pixel centres at integers); `None` when the point is not in front of the camera (`Z ≤ 0`).
    ///
    /// `X_cam = R x + t`, `(x, y) = (X/Z, Y/Z)` distorted as [`Distortion`] says, then
    /// `u = fx x' + skew y' + cx`, `v = fy y' + cy`.
    pub fn project(&self, x: [f64; 3]) -> Option<[f64; 2]> {
        let r = &self.r;
        let c = [0, 1, 2].map(|i| r[i][0] * x[0] + r[i][1] * x[1] + r[i][2] * x[2] + self.t[i]);
        if c[2] <= 0.0 {
            return None;
        }
        let (xd, yd) = self.distortion.distort(c[0] / c[2], c[1] / c[2]);
        let k = &self.intrinsics;
        Some([k.fx * xd + k.skew * yd + k.cx, k.fy * yd + k.cy])
    }
}

impl Scene {
    /// The same scene in the frame `X' = s Q X + o` of `frame`: points mapped, each camera changed so
    /// that it sees every point where it saw it (`R' = R Qᵀ`, `t' = s t − R Qᵀ o`).
    pub fn transformed(&self, frame: &crate::pose::Similarity) -> Scene {
        use crate::pose;
        let mut out = self.clone();
        for v in &mut out.views {
            // s X_cam = R Qᵀ X' − R Qᵀ o + s t
            let r = pose::mul(&v.r, &pose::transpose(&frame.rotation));
            let ro = pose::mul_vec(&r, &frame.translation);
            v.t = [0, 1, 2].map(|i| frame.scale * v.t[i] - ro[i]);
            v.r = r;
        }
        out.points = self.points.iter().map(|p| frame.apply(p)).collect();
        out
    }
}
