//! Checks made before a run writes anything: that the capture's meshes and cameras are of a head
//! in metres and agree with each other, so that a unit mix-up or a wrong file stops at once with
//! its cause named, instead of giving strands of 2 mm or 150 m "successfully".
//!
//! The cameras must surround the head: at least half the views see the raw mesh's centre.
//! The bounds are wide: a head with its hair spans about 0.3 to 1 m; anything from 0.1 to 5 m
//! passes. A photogrammetry mesh of a head has thousands of triangles; at least 100 are needed.

use hairrecon_core::capture::Capture;
use hairrecon_core::mesh::TriMesh;

use crate::error::ReconError;

/// The fewest triangles a raw mesh may have.
pub const MIN_RAW_TRIANGLES: usize = 100;
/// The raw mesh's bounding-box diagonal must lie in this range, in metres.
pub const RAW_DIAGONAL_M: (f32, f32) = (0.1, 5.0);
/// The scalp's bounding-box diagonal must lie in this range, in metres.
pub const SCALP_DIAGONAL_M: (f32, f32) = (0.03, 1.0);

fn implausible(what: String, msg: String) -> ReconError {
    ReconError::Implausible { what, msg }
}

fn diagonal(m: &TriMesh) -> f32 {
    let (lo, hi) = m.bbox();
    (hi - lo).length()
}

/// Checks the raw mesh, the scalp (when the capture has one) and the cameras (module docs).
/// Reads the meshes without building their BVHs (the stages build the one they need).
pub fn check(cap: &Capture) -> Result<(), ReconError> {
    let raw = &cap.read_mesh(&cap.raw_mesh)?;
    let name = cap.raw_mesh.display().to_string();
    if raw.triangles.len() < MIN_RAW_TRIANGLES {
        return Err(implausible(
            format!("the raw mesh {name}"),
            format!(
                "it has {} triangles, fewer than {MIN_RAW_TRIANGLES}; a photogrammetry mesh of a head has thousands: \
                 give the tool's whole mesh",
                raw.triangles.len()
            ),
        ));
    }
    let d = diagonal(raw);
    if !(RAW_DIAGONAL_M.0..=RAW_DIAGONAL_M.1).contains(&d) {
        return Err(implausible(
            format!("the raw mesh {name}"),
            format!(
                "it spans {d:.4} m (its bounding box's diagonal) where a head with its hair spans about 0.3 to 1 m; \
                 is it in metres, as capture.json says?"
            ),
        ));
    }
    let (lo, hi) = raw.bbox();
    let centre = 0.5 * (lo + hi);
    if let Some(scalp_path) = &cap.scalp_mesh {
        let scalp = cap.read_mesh(scalp_path)?;
        let ds = diagonal(&scalp);
        let what = format!("the scalp mesh {}", scalp_path.display());
        if !(SCALP_DIAGONAL_M.0..=SCALP_DIAGONAL_M.1).contains(&ds) {
            return Err(implausible(
                what,
                format!("it spans {ds:.4} m where a scalp spans about 0.1 to 0.3 m; is it in metres?"),
            ));
        }
        let (slo, shi) = scalp.bbox();
        let margin = 0.25 * d;
        if slo.cmplt(lo - margin).any() || shi.cmpgt(hi + margin).any() {
            return Err(implausible(
                what,
                format!(
                    "it lies outside the raw mesh (scalp from {slo:?} to {shi:?}, raw mesh from {lo:?} to {hi:?}); \
                     the scalp must sit under the hair, in the same frame and units"
                ),
            ));
        }
    }
    let seeing = cap.views.iter().filter(|v| v.camera.project(centre).is_some_and(|p| v.camera.contains(p.pixel)));
    let seeing = seeing.count();
    if 2 * seeing < cap.views.len() {
        return Err(implausible(
            "the cameras".into(),
            format!(
                "only {seeing} of {} views see the raw mesh's centre {centre:?}, where views of a head all look at \
                 it; the cameras and the mesh are not in the same frame and units",
                cap.views.len()
            ),
        ));
    }
    Ok(())
}
