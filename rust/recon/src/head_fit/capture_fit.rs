//! Head fitting on a capture folder: the template (the bundled head and scalp, or the user's),
//! the capture's raw mesh and cameras, the fit, the fitted head and scalp in the capture's frame,
//! and, when the capture has a scalp already (a synthetic one), the fitted scalp's distance to it.
//! What the command line, Python and Blender call.

use std::path::{Path, PathBuf};

use glam::DVec3;
use hairrecon_core::camera::Camera;
use hairrecon_core::capture::{CaptureError, CaptureSpec, FrameSpec};
use hairrecon_core::formats::{read_mesh, read_ply_mesh_bytes, write_mesh};
use hairrecon_core::{FormatError, TriMesh};
use thiserror::Error;

use super::compare::{surface_error, SurfaceError};
use super::landmarks::{self, LandmarkError, Landmarks, LANDMARKS_JSON};
use super::nonrigid::fit_deformation;
use super::surface::RawSurface;
use super::{fit_similarity_from, transform_mesh, FitError, FitOptions, FitResult, HeadTemplate};

/// The head the fit registers, in the canonical frame (metres, Z up, the face toward −Y), and its
/// scalp (the triangles the fit leaves out, since hair hides them; the roots' region after it).
#[derive(Debug, Clone)]
pub struct Template {
    pub head: TriMesh,
    pub scalp: TriMesh,
    /// Its landmarks (name, canonical point; [`landmarks::BUNDLED`] for the bundled head, none for
    /// a user's template).
    pub landmarks: Vec<(String, DVec3)>,
}

impl Template {
    /// The bundled head (Cem Yuksel's, as in `blend_fixtures/`), built into the library.
    pub fn bundled() -> Self {
        const HEAD: &[u8] = include_bytes!("../../../../blend_fixtures/head.ply");
        const SCALP: &[u8] = include_bytes!("../../../../blend_fixtures/scalp.ply");
        let read = |b: &[u8]| read_ply_mesh_bytes(b).expect("the bundled head template reads");
        Self { head: read(HEAD), scalp: read(SCALP), landmarks: landmarks::bundled() }
    }

    /// A head and its scalp from files (.ply or .obj).
    pub fn from_files(head: &Path, scalp: &Path) -> Result<Self, FormatError> {
        Ok(Self { head: read_mesh(head)?, scalp: read_mesh(scalp)?, landmarks: Vec::new() })
    }
}

/// Why a capture could not be fitted.
#[derive(Debug, Error)]
pub enum CaptureFitError {
    #[error(transparent)]
    Capture(#[from] CaptureError),
    #[error(transparent)]
    Format(#[from] FormatError),
    #[error("head fitting on {raw}: {source}")]
    Fit { raw: PathBuf, source: FitError },
    #[error("the head template has no area outside its scalp")]
    Template,
    #[error(transparent)]
    Landmarks(#[from] LandmarkError),
}

/// A fitted capture.
#[derive(Debug, Clone)]
pub struct CaptureFit {
    pub fit: FitResult,
    /// The template's head and scalp in the capture's frame.
    pub head: TriMesh,
    pub scalp: TriMesh,
    /// The fitted scalp's distance to the capture's own scalp, canonical metres (only when the
    /// capture has one: a synthetic capture, or a scalp made by hand).
    pub scalp_error: Option<SurfaceError>,
    /// The capture's spec as read.
    pub spec: CaptureSpec,
}

/// Fits `template` to the capture `json_path` (its capture.json): its raw mesh and, with
/// `use_cameras`, its cameras; from the `landmarks` file when given, else from the capture's own
/// [`LANDMARKS_JSON`] when it has one, else by the search.
pub fn fit_capture(
    json_path: &Path,
    template: &Template,
    opts: &FitOptions,
    use_cameras: bool,
    landmarks: Option<&Path>,
) -> Result<CaptureFit, CaptureFitError> {
    let text = std::fs::read_to_string(json_path)
        .map_err(|source| CaptureError::Io { path: json_path.to_path_buf(), source })?;
    let value =
        serde_json::from_str(&text).map_err(|source| CaptureError::Json { path: json_path.to_path_buf(), source })?;
    let spec = CaptureSpec::from_json(value, json_path)?;
    let cameras = spec.validate(json_path)?;
    let dir = json_path.parent().map(Path::to_path_buf).unwrap_or_default();
    let raw_path = dir.join(&spec.raw_mesh);
    let cams = use_cameras.then_some(cameras.as_slice());
    let landmarks = match landmarks {
        Some(p) => Some(Landmarks::read(p)?),
        None => capture_landmarks(&dir)?,
    };
    let (fit, head, scalp) = fit_files(&raw_path, cams, template, landmarks.as_ref(), opts)?;
    let scalp_error = match &spec.scalp_mesh {
        Some(given) => {
            let given = read_mesh(dir.join(given))?;
            surface_error(&scalp, &given, 20_000).map(|e| {
                let s = fit.to_canonical.scale;
                SurfaceError { mean: e.mean * s, p95: e.p95 * s, max: e.max * s }
            })
        }
        None => None,
    };
    Ok(CaptureFit { fit, head, scalp, scalp_error, spec })
}

/// The landmarks of the capture in `dir` ([`LANDMARKS_JSON`]), when it has them.
pub fn capture_landmarks(dir: &Path) -> Result<Option<Landmarks>, LandmarkError> {
    let path = dir.join(LANDMARKS_JSON);
    path.is_file().then(|| Landmarks::read(&path)).transpose()
}

/// Fits `template` to the raw mesh in `raw_path` (with `cameras` in the same frame, when given;
/// from `landmarks` in that frame, when given, instead of the search): the fit, and the template's
/// head and scalp mapped into the raw mesh's frame.
pub fn fit_files(
    raw_path: &Path,
    cameras: Option<&[Camera]>,
    template: &Template,
    landmarks: Option<&Landmarks>,
    opts: &FitOptions,
) -> Result<(FitResult, TriMesh, TriMesh), CaptureFitError> {
    let raw = read_mesh(raw_path)?;
    let points = HeadTemplate::new(&template.head, Some(&template.scalp), 2000, 7).ok_or(CaptureFitError::Template)?;
    let start = landmarks.map(|l| l.pose(&template.landmarks)).transpose()?;
    let mut fit = fit_similarity_from(&points, &raw, cameras, start.as_ref().map(|s| &s.0), opts)
        .map_err(|source| CaptureFitError::Fit { raw: raw_path.into(), source })?;
    if let Some(l) = landmarks {
        fit.landmarks_mm = Some(l.rms_mm(&template.landmarks, &fit.to_canonical));
        fit.each_landmark_mm = l.each_mm(&template.landmarks, &fit.to_canonical);
    }
    // The subject's shape, fitted in the canonical frame to the raw mesh placed there.
    let (head, scalp) = match &opts.deform {
        Some(d) => {
            let placed = RawSurface::new(transform_mesh(&raw, &fit.to_canonical), opts.normal_smoothing);
            let (field, report) = fit_deformation(&template.head, &template.scalp, &placed, d);
            fit.shape = Some(report);
            (field.mesh(&template.head), field.mesh(&template.scalp))
        }
        None => (template.head.clone(), template.scalp.clone()),
    };
    let to_capture = fit.to_canonical.inverse();
    Ok((fit, transform_mesh(&head, &to_capture), transform_mesh(&scalp, &to_capture)))
}

impl CaptureFit {
    /// The fit as the JSON report that `hairrecon fit-head` prints and [`write_into_capture`] keeps
    /// as head_fit.json: the similarity to the canonical frame, the fit's residual and fractions,
    /// and the scalp error when the capture has a scalp. `template` and `scalp` name the template's
    /// files (`None`: the bundled head); `seconds` is the run's time.
    pub fn report(
        &self,
        template: Option<&Path>,
        scalp: Option<&Path>,
        cameras_used: bool,
        seconds: f64,
    ) -> serde_json::Value {
        let spec = &self.spec;
        let mut r = serde_json::json!({
            "raw_mesh": spec.raw_mesh,
            "template": template.map_or_else(|| "bundled".to_string(), |p| p.display().to_string()),
            "scalp": scalp,
            "units": spec.units,
            "frame": spec.frame.as_deref().unwrap_or("canonical"),
        });
        if let (Some(r), serde_json::Value::Object(fit)) = (r.as_object_mut(), fit_json(&self.fit)) {
            r.extend(fit);
        }
        r["cameras_used"] = cameras_used.into();
        r["scalp_error_against_the_captures_scalp"] = serde_json::json!(self.scalp_error.map(|e| serde_json::json!({
            "mean_mm": e.mean * 1e3, "p95_mm": e.p95 * 1e3, "max_mm": e.max * 1e3
        })));
        r["seconds"] = seconds.into();
        r
    }
}

/// A fit as JSON: the similarity to the canonical frame, the residual, the fractions of the
/// template on, inside and outside the raw mesh, the cost and the runner-up's.
pub fn fit_json(fit: &FitResult) -> serde_json::Value {
    let s = fit.to_canonical;
    let (axis, degrees) = s.axis_angle_degrees();
    serde_json::json!({
        "to_canonical": {
            "scale": s.scale,
            "rotation_axis": axis.to_array(),
            "rotation_degrees": degrees,
            "rotation_matrix": matrix_rows(s.rotation),
            "translation": s.translation.to_array(),
        },
        "residual_mm": fit.residual_mm,
        "on_mesh_fraction": fit.score.on_surface,
        "covered_fraction": fit.score.inside,
        "exposed_fraction": fit.score.outside,
        "cost": fit.score.cost,
        "runner_up_cost": fit.runner_up_cost,
        "landmarks_rms_mm": fit.landmarks_mm,
        "landmarks_mm": fit.landmark_distances().map(|each| each.into_iter()
            .map(|(n, d)| (n.to_string(), serde_json::json!(d)))
            .collect::<serde_json::Map<_, _>>()),
        "warning": fit.close_call(),
        "shape": fit.shape.map(|r| serde_json::json!({
            "skin_rms_mm": r.skin_rms * 1e3,
            "skin_matched_fraction": r.skin_matched,
            "scalp_matched_fraction": r.scalp_matched,
            "scalp_on_surface_fraction": r.scalp_on_surface,
            "scalp_border_on_surface_fraction": r.border_on_surface,
            "bald": r.bald,
            "max_displacement_mm": r.max_displacement * 1e3,
        })),
    })
}

/// A matrix as its rows.
pub fn matrix_rows(m: glam::DMat3) -> [[f64; 3]; 3] {
    let t = m.transpose();
    [t.x_axis.to_array(), t.y_axis.to_array(), t.z_axis.to_array()]
}

/// The files [`write_into_capture`] writes, beside capture.json.
pub const FITTED_HEAD: &str = "fitted_head.ply";
pub const FITTED_SCALP: &str = "fitted_scalp.ply";
pub const HEAD_FIT_JSON: &str = "head_fit.json";

/// Writes the fitted head and scalp where the capture has none (never replacing the user's),
/// `report` as head_fit.json, then capture.json (atomically, last: a failure before it leaves the
/// capture as it was, apart from files it does not name). Returns the files written.
pub fn write_into_capture(
    json_path: &Path,
    fitted: &CaptureFit,
    report: &str,
) -> Result<Vec<PathBuf>, CaptureFitError> {
    let dir = json_path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut spec = fitted.spec.clone();
    let mut written = Vec::new();
    // An imported capture is placed in the canonical frame by the fit; a canonical one already is.
    if hairrecon_core::capture::Frame::parse(spec.frame.as_deref()) == Some(hairrecon_core::capture::Frame::Imported) {
        spec.to_canonical = Some(FrameSpec::of(&fitted.fit.to_canonical));
    }
    if spec.head_mesh.is_none() {
        write_mesh(dir.join(FITTED_HEAD), &fitted.head)?;
        spec.head_mesh = Some(FITTED_HEAD.into());
        written.push(dir.join(FITTED_HEAD));
    }
    if spec.scalp_mesh.is_none() {
        write_mesh(dir.join(FITTED_SCALP), &fitted.scalp)?;
        spec.scalp_mesh = Some(FITTED_SCALP.into());
        written.push(dir.join(FITTED_SCALP));
    }
    let report_path = dir.join(HEAD_FIT_JSON);
    hairrecon_core::formats::atomic_write(&report_path, |w| {
        use std::io::Write;
        Ok(writeln!(w, "{report}")?)
    })?;
    written.push(report_path);
    written.push(spec.write(json_path)?);
    Ok(written)
}
