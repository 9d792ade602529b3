//! `hairrecon fit-head`: the similarity that takes a capture's raw mesh to the canonical frame
//! (metres, Z up, the face toward −Y), by registering the head template to it
//! (`hairrecon_recon::head_fit`). Prints it as JSON on stdout. With `--write`, the template's head
//! and scalp mapped into the capture's frame become the capture's `head_mesh` and `scalp_mesh`
//! (`fitted_head.ply`, `fitted_scalp.ply`) where it has none, and the JSON is kept as
//! `head_fit.json`. A capture that has a scalp already (a synthetic one) gets, instead, the fitted
//! scalp's distance to it: the stage's metric.
//!
//! The template: `--template`, else the repository's `blend_fixtures/head.ply`, found from where
//! this program was built (`CARGO_MANIFEST_DIR/../../blend_fixtures`; a binary moved away from its
//! source tree needs `--template`). Its scalp (the triangles the fit ignores, since hair hides them)
//! is `--scalp`, else `scalp.ply` beside the template when it exists.

use std::path::{Path, PathBuf};
use std::time::Instant;

use hairrecon_core::capture::CaptureSpec;
use hairrecon_core::TriMesh;
use hairrecon_recon::head_fit::compare::surface_error;
use hairrecon_recon::head_fit::{fit_similarity, transform_mesh, FitOptions, HeadTemplate};
use serde_json::json;

use crate::CmdResult;

#[derive(Debug, clap::Args)]
pub struct FitHeadArgs {
    /// Capture folder (or its capture.json): its raw mesh and its cameras are used.
    pub capture: PathBuf,
    /// Head template in the canonical frame (.ply or .obj). Default: the repository's
    /// blend_fixtures/head.ply.
    #[arg(long)]
    pub template: Option<PathBuf>,
    /// The template's scalp, left out of the fit. Default: scalp.ply beside the template, if any.
    #[arg(long)]
    pub scalp: Option<PathBuf>,
    /// Ignore the cameras (fit from the mesh alone).
    #[arg(long)]
    pub no_cameras: bool,
    /// Write the fitted head and scalp into the capture where it has none, and head_fit.json.
    #[arg(long)]
    pub write: bool,
    /// Template points used by the fit.
    #[arg(long, default_value_t = 2000)]
    pub samples: usize,
    /// Fail when more than this fraction of the template's skin lies outside the raw mesh.
    #[arg(long, default_value_t = FitOptions::default().max_exposed_fraction)]
    pub max_exposed: f64,
}

/// The repository's head template, from where this program was built.
pub fn default_template() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../blend_fixtures/head.ply")
}

pub fn run(args: FitHeadArgs) -> CmdResult {
    let t0 = Instant::now();
    let json_path = if args.capture.is_dir() { args.capture.join("capture.json") } else { args.capture.clone() };
    let text = std::fs::read_to_string(&json_path).map_err(|e| format!("cannot read {}: {e}", json_path.display()))?;
    let spec = CaptureSpec::from_json(serde_json::from_str(&text)?, &json_path)?;
    let cameras = spec.validate(&json_path)?;
    let dir = json_path.parent().map(Path::to_path_buf).unwrap_or_default();
    let raw_path = dir.join(&spec.raw_mesh);
    let raw = hairrecon_core::read_mesh(&raw_path)?;

    let template_path = args.template.clone().unwrap_or_else(default_template);
    let head = hairrecon_core::read_mesh(&template_path).map_err(|e| {
        format!("cannot read the head template {}: {e}; give one with --template", template_path.display())
    })?;
    let scalp_path = args.scalp.clone().or_else(|| {
        let p = template_path.with_file_name("scalp.ply");
        p.is_file().then_some(p)
    });
    let scalp = scalp_path.as_ref().map(hairrecon_core::read_mesh).transpose()?;
    let template = HeadTemplate::new(&head, scalp.as_ref(), args.samples, 7)
        .ok_or_else(|| format!("the head template {} has no area outside its scalp", template_path.display()))?;

    let opts = FitOptions { max_exposed_fraction: args.max_exposed, ..FitOptions::default() };
    let cams = (!args.no_cameras).then_some(cameras.as_slice());
    let fit = fit_similarity(&template, &raw, cams, &opts)?;
    let s = fit.to_canonical;
    let to_capture = s.inverse();
    let (fitted_head, fitted_scalp) =
        (transform_mesh(&head, &to_capture), scalp.as_ref().map(|m| transform_mesh(m, &to_capture)));
    // The metric, where the capture knows its scalp: canonical millimetres.
    let scalp_error = match (&spec.scalp_mesh, &fitted_scalp) {
        (Some(given), Some(fitted)) => {
            let given = hairrecon_core::read_mesh(dir.join(given))?;
            surface_error(fitted, &given, 20_000).map(|e| {
                let mm = s.scale * 1e3;
                json!({"mean_mm": e.mean * mm, "p95_mm": e.p95 * mm, "max_mm": e.max * mm})
            })
        }
        _ => None,
    };
    let (axis, degrees) = s.axis_angle_degrees();
    let rows = |m: glam::DMat3| {
        let t = m.transpose();
        [t.x_axis.to_array(), t.y_axis.to_array(), t.z_axis.to_array()]
    };
    let out = json!({
        "raw_mesh": raw_path,
        "template": template_path,
        "scalp": scalp_path,
        "units": spec.units,
        "frame": spec.frame.as_deref().unwrap_or("canonical"),
        "to_canonical": {
            "scale": s.scale,
            "rotation_axis": axis.to_array(),
            "rotation_degrees": degrees,
            "rotation_matrix": rows(s.rotation),
            "translation": s.translation.to_array(),
        },
        "residual_mm": fit.residual_mm,
        "on_mesh_fraction": fit.score.on_surface,
        "covered_fraction": fit.score.inside,
        "exposed_fraction": fit.score.outside,
        "cost": fit.score.cost,
        "runner_up_cost": fit.runner_up_cost,
        "cameras_given": cams.map_or(0, <[_]>::len),
        "scalp_error_against_the_captures_scalp": scalp_error,
        "seconds": t0.elapsed().as_secs_f64(),
    });
    let text = serde_json::to_string_pretty(&out)?;
    if args.write {
        write_into_capture(&json_path, spec, &fitted_head, fitted_scalp.as_ref(), &text)?;
    }
    println!("{text}");
    Ok(())
}

/// Writes the fitted meshes where the capture has none (never replacing the user's), then
/// head_fit.json, then capture.json (atomically, last: a failure before it leaves the capture as
/// it was, apart from unreferenced files).
fn write_into_capture(
    json_path: &Path,
    mut spec: CaptureSpec,
    head: &TriMesh,
    scalp: Option<&TriMesh>,
    report: &str,
) -> CmdResult {
    let dir = json_path.parent().map(Path::to_path_buf).unwrap_or_default();
    if spec.head_mesh.is_none() {
        hairrecon_core::formats::write_mesh(dir.join("fitted_head.ply"), head)?;
        spec.head_mesh = Some("fitted_head.ply".into());
    }
    if let (None, Some(scalp)) = (&spec.scalp_mesh, scalp) {
        hairrecon_core::formats::write_mesh(dir.join("fitted_scalp.ply"), scalp)?;
        spec.scalp_mesh = Some("fitted_scalp.ply".into());
    }
    std::fs::write(dir.join("head_fit.json"), format!("{report}\n"))
        .map_err(|e| format!("cannot write {}: {e}", dir.join("head_fit.json").display()))?;
    spec.write(json_path)?;
    Ok(())
}
