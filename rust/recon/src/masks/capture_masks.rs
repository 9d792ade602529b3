//! Masks written where they are used: into the capture (`masks/<view>.png` for the views without
//! a mask, `hair_region.ply`, `masks.json`, and the masks named in capture.json), or into a folder
//! of their own for a look or a score.

use std::path::{Path, PathBuf};

use hairrecon_core::capture::{CaptureError, CaptureSpec};
use hairrecon_core::formats::{read_mesh, write_mesh_with_quality};
use hairrecon_core::image_io::write_png16_gray;
use hairrecon_core::FormatError;
use thiserror::Error;

use serde_json::json;

use super::quality::MaskScore;
use super::{MaskOptions, MaskSet};

/// The masks' folder, inside a capture or an output folder.
pub const MASKS_DIR: &str = "masks";
/// The raw mesh with each vertex's hair probability as its `quality`.
pub const HAIR_REGION: &str = "hair_region.ply";
/// The masks' report (what `hairrecon masks` prints).
pub const MASKS_JSON: &str = "masks.json";

/// Why masks could not be written.
#[derive(Debug, Error)]
pub enum WriteMasksError {
    #[error(transparent)]
    Capture(#[from] CaptureError),
    #[error(transparent)]
    Format(#[from] FormatError),
    #[error("cannot create {path}: {source}")]
    Dir { path: PathBuf, source: std::io::Error },
}

/// Writes the masks of every view into `out/masks/<view>.png` (16-bit), the hair region into
/// `out/hair_region.ply` (the raw mesh as its file has it, `raw_file`, with the probability as
/// vertex quality) and `report` into `out/masks.json`. Returns the files written.
pub fn write_folder(
    out: &Path,
    names: &[String],
    set: &MaskSet,
    raw_file: &Path,
    report: &str,
) -> Result<Vec<PathBuf>, WriteMasksError> {
    let dir = out.join(MASKS_DIR);
    std::fs::create_dir_all(&dir).map_err(|source| WriteMasksError::Dir { path: dir.clone(), source })?;
    let mut written = Vec::new();
    for (name, alpha) in names.iter().zip(&set.alphas) {
        let path = dir.join(format!("{name}.png"));
        write_png16_gray(&path, alpha)?;
        written.push(path);
    }
    written.push(write_region(out, set, raw_file)?);
    let path = out.join(MASKS_JSON);
    write_text(&path, report)?;
    written.push(path);
    Ok(written)
}

/// Writes the masks into the capture `json_path`: `masks/<view>.png` for every view that has no
/// mask in `spec` (a user's own masks are kept), `hair_region.ply`, `masks.json`, and
/// capture.json naming the new masks. Returns the files written.
pub fn write_into_capture(
    json_path: &Path,
    spec: &CaptureSpec,
    set: &MaskSet,
    report: &str,
) -> Result<Vec<PathBuf>, WriteMasksError> {
    let dir = json_path.parent().map(Path::to_path_buf).unwrap_or_default();
    let masks = dir.join(MASKS_DIR);
    std::fs::create_dir_all(&masks).map_err(|source| WriteMasksError::Dir { path: masks.clone(), source })?;
    let mut spec = spec.clone();
    let mut written = Vec::new();
    for (view, alpha) in spec.views.iter_mut().zip(&set.alphas) {
        if view.mask.is_some() {
            continue;
        }
        let rel = PathBuf::from(MASKS_DIR).join(format!("{}.png", view.name));
        write_png16_gray(dir.join(&rel), alpha)?;
        written.push(dir.join(&rel));
        view.mask = Some(rel);
    }
    written.push(write_region(&dir, set, &dir.join(&spec.raw_mesh))?);
    let path = dir.join(MASKS_JSON);
    write_text(&path, report)?;
    written.push(path);
    written.push(spec.write(json_path)?);
    Ok(written)
}

fn write_region(dir: &Path, set: &MaskSet, raw_file: &Path) -> Result<PathBuf, WriteMasksError> {
    // The file's own vertices (its frame and units), in the same order as the canonical copy's.
    let raw = read_mesh(raw_file)?;
    let path = dir.join(HAIR_REGION);
    write_mesh_with_quality(&path, &raw, &set.region)?;
    Ok(path)
}

fn write_text(path: &Path, text: &str) -> Result<(), WriteMasksError> {
    hairrecon_core::formats::atomic_write(path, |w| {
        use std::io::Write;
        Ok(writeln!(w, "{text}")?)
    })?;
    Ok(())
}

/// The report of a masks run (what `hairrecon masks` prints and `masks.json` keeps): the views,
/// the region's summary, the masks' mean coverage, the options, the time, and the scores when
/// there are.
pub fn report(
    set: &MaskSet,
    names: &[String],
    scores: Option<&[(String, MaskScore)]>,
    opts: &MaskOptions,
    seconds: f64,
) -> serde_json::Value {
    let coverage: Vec<f64> =
        set.alphas.iter().map(|a| a.data.iter().map(|&x| x as f64).sum::<f64>() / a.data.len().max(1) as f64).collect();
    let mut r = json!({
        "views": names.len(),
        "region": set.summary,
        "mean_coverage": coverage.iter().sum::<f64>() / coverage.len().max(1) as f64,
        "options": opts,
        "seconds": round1(seconds),
        "phase_seconds": {
            "rays": round1(set.seconds.rays),
            "region": round1(set.seconds.region),
            "silhouettes": round1(set.seconds.silhouettes),
            "matting": round1(set.seconds.matting),
        },
    });
    if let Some(scores) = scores {
        let n = scores.len().max(1) as f64;
        let mean = |f: fn(&MaskScore) -> f32| scores.iter().map(|(_, s)| f(s) as f64).sum::<f64>() / n;
        r["score"] = json!({
            "mean_iou": mean(|s| s.iou),
            "min_iou": scores.iter().map(|(_, s)| s.iou).fold(1.0f32, f32::min),
            "mean_alpha_error": mean(|s| s.alpha_error),
            "mean_off_hair": mean(|s| s.off_hair),
            "max_off_hair": scores.iter().map(|(_, s)| s.off_hair).fold(0.0f32, f32::max),
            "per_view": scores.iter().map(|(v, s)| json!({"view": v, "iou": s.iou, "alpha_error": s.alpha_error,
                "off_hair": s.off_hair, "area": s.area, "gt_area": s.gt_area})).collect::<Vec<_>>(),
        });
    }
    r
}

fn round1(x: f64) -> f64 {
    (x * 10.0).round() / 10.0
}
