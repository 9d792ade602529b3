//! The bundled head fixture: Cem Yuksel's woman head brought once into the project's frame.
//!
//! In: `woman_head.ply` (sha256 [`SOURCE_SHA256`]; arbitrary units, Y down toward the neck cut, face
//! along +X). Out: `head.ply` in **metres, Z up, face toward −Y** (Blender's front view), with its
//! normals and UVs, plus the scalp mesh and mask of [`crate::scalp_region`].
//!
//! The map is `new = SOURCE_TO_METRES · R · (old − c)`, where `R (x, y, z) = (z, −x, −y)` is a proper
//! rotation (det +1) and `c` is the centre of the source's bounding box, so the fixture's bounding
//! box is centred on the origin. [`SOURCE_TO_METRES`] = 0.056 makes the skull 0.152 m wide above the
//! ears (2.71 source units), within the 0.15–0.16 m of a real head.

use std::path::{Path, PathBuf};

use glam::{Affine3A, Mat3, Vec3};
use hairrecon_core::formats::{read_mesh, write_mesh};
use hairrecon_core::TriMesh;
use sha2::{Digest, Sha256};

use crate::error::SynthError;
use crate::scalp_region::{scalp_submesh, uv_mask};

/// sha256 of the source head, `woman_head.ply`.
pub const SOURCE_SHA256: &str = "1738db1f84ee4060172048c5aaea75676bba9cd9ecb77e2385824793a44fa50e";
/// Metres per source unit.
pub const SOURCE_TO_METRES: f32 = 0.056;
/// Size of the UV-space scalp mask, pixels per side.
pub const MASK_SIZE: u32 = 1024;

/// The rotation from the source frame to the project's frame: `(x, y, z) → (z, −x, −y)`.
pub fn source_rotation() -> Mat3 {
    // Columns are the images of the source axes: x → −Y, y → −Z, z → +X.
    Mat3::from_cols(Vec3::NEG_Y, Vec3::NEG_Z, Vec3::X)
}

/// The affine map from the source head to metres, Z up, face toward −Y, centred on the bounding box.
pub fn normalising_transform(source: &TriMesh) -> Affine3A {
    let (lo, hi) = source.bbox();
    let c = 0.5 * (lo + hi);
    let m = source_rotation() * SOURCE_TO_METRES;
    Affine3A::from_mat3_translation(m, -(m * c))
}

/// The source head in the project's frame (normals rotated, UVs kept).
pub fn normalise_head(source: &TriMesh) -> TriMesh {
    source.transformed(normalising_transform(source))
}

/// Lower-case hex sha256 of `bytes`.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// What [`prepare_fixtures`] wrote.
#[derive(Debug, Clone)]
pub struct FixtureSummary {
    pub head: PathBuf,
    pub scalp: PathBuf,
    pub mask: PathBuf,
    pub head_vertices: usize,
    pub head_triangles: usize,
    pub scalp_vertices: usize,
    pub scalp_triangles: usize,
    /// Scalp area, m².
    pub scalp_area: f32,
    /// Bounding box of the normalised head, metres.
    pub bbox: (Vec3, Vec3),
}

/// Checks the source's sha256, then writes `head.ply`, `scalp.ply` and `scalp_mask.png` into
/// `out_dir` (created if needed).
pub fn prepare_fixtures(source: &Path, out_dir: &Path) -> Result<FixtureSummary, SynthError> {
    let bytes = std::fs::read(source).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => SynthError::MissingFile {
            what: "the source head",
            path: source.to_path_buf(),
            hint: "give the path of woman_head.ply (see /work/shared/data/README.md)",
        },
        _ => SynthError::Io { path: source.to_path_buf(), source: e },
    })?;
    let got = sha256_hex(&bytes);
    if got != SOURCE_SHA256 {
        return Err(SynthError::Checksum { path: source.to_path_buf(), expected: SOURCE_SHA256, got });
    }
    let head = normalise_head(&read_mesh(source)?);
    let scalp = scalp_submesh(&head)?;
    std::fs::create_dir_all(out_dir).map_err(|e| SynthError::Io { path: out_dir.to_path_buf(), source: e })?;
    let (head_path, scalp_path, mask_path) =
        (out_dir.join("head.ply"), out_dir.join("scalp.ply"), out_dir.join("scalp_mask.png"));
    write_mesh(&head_path, &head)?;
    write_mesh(&scalp_path, &scalp)?;
    uv_mask(&scalp, MASK_SIZE)
        .save(&mask_path)
        .map_err(|e| SynthError::Image { path: mask_path.clone(), source: e })?;
    let scalp_area = (0..scalp.triangles.len()).map(|i| scalp.face_area(i)).sum();
    Ok(FixtureSummary {
        head_vertices: head.vertices.len(),
        head_triangles: head.triangles.len(),
        scalp_vertices: scalp.vertices.len(),
        scalp_triangles: scalp.triangles.len(),
        scalp_area,
        bbox: head.bbox(),
        head: head_path,
        scalp: scalp_path,
        mask: mask_path,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_is_proper_and_maps_the_source_axes() {
        let r = source_rotation();
        assert!((r.determinant() - 1.0).abs() < 1e-6);
        // Source face direction +X becomes −Y, source down (+Y, toward the neck) becomes −Z, source
        // ear axis Z becomes X.
        assert_eq!(r * Vec3::X, Vec3::NEG_Y);
        assert_eq!(r * Vec3::Y, Vec3::NEG_Z);
        assert_eq!(r * Vec3::Z, Vec3::X);
        assert_eq!(sha256_hex(b"abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    }

    #[test]
    fn normalised_box_is_centred_and_scaled() {
        let m = TriMesh::new(
            vec![Vec3::new(1.0, -3.0, -2.0), Vec3::new(3.0, 3.0, 2.0), Vec3::new(1.0, 3.0, 0.0)],
            vec![[0, 1, 2]],
            None,
            None,
        )
        .unwrap();
        let (lo, hi) = normalise_head(&m).bbox();
        assert!((lo + hi).length() < 1e-6);
        // Source extents (2, 6, 4) become (4, 2, 6) × 0.056.
        assert!(((hi - lo) - Vec3::new(4.0, 2.0, 6.0) * SOURCE_TO_METRES).length() < 1e-6);
    }
}
