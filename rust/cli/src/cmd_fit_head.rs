//! `hairrecon fit-head`: the similarity that takes a capture's raw mesh to the canonical frame
//! (metres, Z up, the face toward −Y), by registering the head template to it
//! (`hairrecon_recon::head_fit`). Prints it as JSON on stdout. With `--write`, the template's head
//! and scalp mapped into the capture's frame become the capture's `head_mesh` and `scalp_mesh`
//! (`fitted_head.ply`, `fitted_scalp.ply`) where it has none, and the JSON is kept as
//! `head_fit.json`. A capture that has a scalp already (a synthetic one) gets, instead, the fitted
//! scalp's distance to it: the stage's metric.
//!
//! The template: `--template` with its scalp (`--scalp`, else `scalp.ply` beside it), else the
//! bundled head and scalp (`blend_fixtures/`, built into the library). The scalp's triangles are
//! the ones the fit ignores, since hair hides them.

use std::path::PathBuf;
use std::time::Instant;

use hairrecon_recon::head_fit::capture_fit::{fit_capture, write_into_capture, Template};
use hairrecon_recon::head_fit::FitOptions;

use crate::CmdResult;

#[derive(Debug, clap::Args)]
pub struct FitHeadArgs {
    /// Capture folder (or its capture.json): its raw mesh and its cameras are used.
    pub capture: PathBuf,
    /// Head template in the canonical frame (.ply or .obj). Default: the bundled head (the
    /// repository's blend_fixtures/head.ply, built in).
    #[arg(long)]
    pub template: Option<PathBuf>,
    /// The template's scalp, left out of the fit. Default: scalp.ply beside --template.
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
    /// The true frame (a wild synthetic project's gt/frame.json: {"scale", "rotation" by rows,
    /// "translation"}, as capture.json's to_canonical): prints the fit's error against it, and the
    /// true frame's own score.
    #[arg(long, value_name = "FRAME_JSON")]
    pub gt_frame: Option<PathBuf>,
    /// Fail when more than this fraction of the template's skin lies outside the raw mesh.
    #[arg(long, default_value_t = FitOptions::default().max_exposed_fraction)]
    pub max_exposed: f64,
    /// Keep the template's own shape (the similarity alone): no fit of the subject's head shape.
    #[arg(long)]
    pub no_shape: bool,
    /// Landmarks placed on the raw mesh, in the capture's frame: a JSON object of names
    /// (nose_tip, chin, eye_outer_left, eye_outer_right, ear_left, ear_right; left and right the
    /// subject's own) to [x, y, z], three or more. The fit starts from the pose they give instead
    /// of searching. Default: the capture's landmarks.json, when it has one.
    #[arg(long, value_name = "JSON")]
    pub landmarks: Option<PathBuf>,
}

pub fn run(args: FitHeadArgs) -> CmdResult {
    let t0 = Instant::now();
    let json_path = if args.capture.is_dir() { args.capture.join("capture.json") } else { args.capture.clone() };
    let (template, template_path, scalp_path) = match &args.template {
        Some(head) => {
            let scalp = args.scalp.clone().unwrap_or_else(|| head.with_file_name("scalp.ply"));
            let t = Template::from_files(head, &scalp).map_err(|e| {
                format!("cannot read the head template {} with its scalp {}: {e}", head.display(), scalp.display())
            })?;
            (t, Some(head.clone()), Some(scalp))
        }
        None => (Template::bundled(), None, None),
    };
    let defaults = FitOptions::default();
    let opts = FitOptions {
        max_exposed_fraction: args.max_exposed,
        deform: defaults.deform.clone().filter(|_| !args.no_shape),
        ..defaults
    };
    let fitted = fit_capture(&json_path, &template, &opts, !args.no_cameras, args.landmarks.as_deref())?;
    if let Some(w) = fitted.fit.close_call() {
        eprintln!("warning: {w}");
    }
    let out =
        fitted.report(template_path.as_deref(), scalp_path.as_deref(), !args.no_cameras, t0.elapsed().as_secs_f64());
    let mut out = out;
    if let Some(path) = &args.gt_frame {
        out["against_the_true_frame"] = frame_error(path, &fitted, &template, &json_path, &opts)?;
    }
    let text = serde_json::to_string_pretty(&out)?;
    if args.write {
        write_into_capture(&json_path, &fitted, &text)?;
    }
    println!("{text}");
    Ok(())
}

/// The fit against a known frame: the rotation between them, the ratio of the scales, and the
/// true frame's score (cost and fractions, as the fit's own).
fn frame_error(
    path: &std::path::Path,
    fitted: &hairrecon_recon::head_fit::capture_fit::CaptureFit,
    template: &Template,
    json_path: &std::path::Path,
    opts: &FitOptions,
) -> Result<serde_json::Value, Box<dyn std::error::Error + Send + Sync>> {
    use hairrecon_core::capture::FrameSpec;
    use hairrecon_recon::head_fit::{score_frame, HeadTemplate};
    let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let spec: FrameSpec = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let truth = spec.similarity().ok_or_else(|| format!("{}: not a similarity", path.display()))?;
    let found = fitted.fit.to_canonical;
    let dir = json_path.parent().unwrap_or(std::path::Path::new("."));
    let raw = hairrecon_core::formats::read_mesh(dir.join(&fitted.spec.raw_mesh))?;
    let points = HeadTemplate::new(&template.head, Some(&template.scalp), 2000, 7).ok_or("the template has no skin")?;
    let s = score_frame(&points, &raw, &truth, opts);
    // The fitted scalp against the template's scalp placed by the true frame, canonical mm.
    let placed = hairrecon_recon::head_fit::transform_mesh(&template.scalp, &truth.inverse());
    let e = hairrecon_recon::head_fit::compare::surface_error(&fitted.scalp, &placed, 20_000);
    let mm = |x: f64| x * truth.scale * 1e3;
    Ok(serde_json::json!({
        "scalp_error_mm": e.map(|e| serde_json::json!({"mean": mm(e.mean), "p95": mm(e.p95), "max": mm(e.max)})),
        "rotation_error_degrees": found.rotation_angle_to(&truth),
        "scale_ratio": truth.scale / found.scale,
        "true_frame_cost": s.cost,
        "true_frame_on_mesh_fraction": s.on_surface,
        "true_frame_exposed_fraction": s.outside,
    }))
}
