//! A capture in another frame than the canonical one (metres, Z up, the face toward −Y): the
//! similarity to the canonical frame that head fitting found (`to_canonical` in capture.json), and
//! the capture as the reconstruction sees it in that frame.
//!
//! [`Capture::in_canonical_frame`] moves the cameras at once and records the similarity as the
//! capture's [`Capture::file_frame`]: the meshes and strands its files hold are mapped when they
//! are read ([`Capture::read_mesh`], [`Capture::read_strands`]), and results go back to the files'
//! frame with [`Capture::to_file_frame`]. The files themselves never change.

use std::path::Path;

use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};

use crate::capture::{Capture, CaptureError, Frame, Units, View};
use crate::similarity::{transform_camera, transform_mesh, transform_strands, Similarity};
use crate::{FormatError, StrandSet, TriMesh};

/// capture.json's `to_canonical`: `x ↦ scale · rotation · x + translation` takes the capture's
/// coordinates to the canonical frame in metres. `rotation` by rows.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FrameSpec {
    pub scale: f64,
    pub rotation: [[f64; 3]; 3],
    pub translation: [f64; 3],
}

impl FrameSpec {
    /// The similarity, if the numbers make one: a finite positive scale, a proper rotation
    /// (orthonormal within 1e-6, determinant +1), a finite translation.
    pub fn similarity(&self) -> Option<Similarity> {
        let rotation = DMat3::from_cols_array_2d(&self.rotation).transpose();
        let translation = DVec3::from_array(self.translation);
        let orthonormal =
            (rotation.transpose() * rotation - DMat3::IDENTITY).to_cols_array().iter().all(|x| x.abs() < 1e-6);
        let ok = self.scale.is_finite()
            && self.scale > 0.0
            && orthonormal
            && rotation.determinant() > 0.0
            && translation.is_finite();
        ok.then_some(Similarity { scale: self.scale, rotation, translation })
    }

    /// The spec of a similarity.
    pub fn of(s: &Similarity) -> Self {
        Self {
            scale: s.scale,
            rotation: s.rotation.transpose().to_cols_array_2d(),
            translation: s.translation.to_array(),
        }
    }

    /// Checks the spec: a similarity, and only on an imported capture. `json` names the file.
    pub(crate) fn validate(&self, frame: Option<&str>, json: &Path) -> Result<(), CaptureError> {
        let spec_err = |msg: &str| CaptureError::Spec { path: json.into(), msg: msg.into() };
        if self.similarity().is_none() {
            return Err(spec_err(
                "\"to_canonical\" must hold a positive scale, a rotation (3 × 3, by rows, orthonormal, determinant +1) \
                 and a translation; run `hairrecon fit-head --write` to make it",
            ));
        }
        if Frame::parse(frame) != Some(Frame::Imported) {
            return Err(spec_err("\"to_canonical\" belongs to a capture whose \"frame\" is \"imported\""));
        }
        Ok(())
    }
}

impl Capture {
    /// The capture as the reconstruction works on it: itself when canonical; when imported with a
    /// `to_canonical` similarity, the same capture in the canonical frame (cameras moved, files
    /// mapped when read); `None` otherwise (an imported capture that no head fit has placed yet).
    pub fn in_canonical_frame(&self) -> Result<Option<Capture>, CaptureError> {
        if self.is_canonical() {
            return Ok(Some(self.clone()));
        }
        let Some(s) = self.to_canonical else { return Ok(None) };
        let mut views = Vec::with_capacity(self.views.len());
        for v in &self.views {
            let camera = transform_camera(&v.camera, &s).map_err(|source| CaptureError::Camera {
                view: v.name.clone(),
                path: self.dir.join("capture.json"),
                source,
            })?;
            views.push(View { camera, ..v.clone() });
        }
        Ok(Some(Capture {
            units: Units::Metres,
            frame: Frame::Canonical,
            views,
            to_canonical: None,
            file_frame: Some(s),
            ..self.clone()
        }))
    }

    /// Reads a mesh the capture names, in the capture's frame.
    pub fn read_mesh(&self, path: &Path) -> Result<TriMesh, FormatError> {
        let mesh = crate::formats::read_mesh(path)?;
        Ok(match &self.file_frame {
            Some(s) => transform_mesh(&mesh, s),
            None => mesh,
        })
    }

    /// Reads strands the capture names (its ground truth), in the capture's frame.
    pub fn read_strands(&self, path: &Path) -> Result<StrandSet, FormatError> {
        let strands = crate::formats::read_strands(path)?;
        match &self.file_frame {
            Some(s) => transform_strands(&strands, s).map_err(|e| FormatError::from(e).in_file(path)),
            None => Ok(strands),
        }
    }

    /// Strands in the capture's frame, mapped to the frame of its files (the user's): unchanged
    /// unless [`Capture::in_canonical_frame`] moved the capture.
    pub fn to_file_frame(&self, strands: &StrandSet) -> Result<StrandSet, crate::StrandError> {
        match &self.file_frame {
            Some(s) => transform_strands(strands, &s.inverse()),
            None => Ok(strands.clone()),
        }
    }

    /// Strands in the frame of the capture's files, mapped to the capture's frame: the inverse of
    /// [`Capture::to_file_frame`].
    pub fn from_file_frame(&self, strands: &StrandSet) -> Result<StrandSet, crate::StrandError> {
        match &self.file_frame {
            Some(s) => transform_strands(strands, s),
            None => Ok(strands.clone()),
        }
    }
}
