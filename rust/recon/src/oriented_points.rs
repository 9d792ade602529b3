//! Oriented 3D points: the data that flows from the line MVS ([`crate::points3d`]) through the
//! direction stage ([`crate::direction`]) to the flow and the curls: positions, unit directions and a
//! confidence, saved as a binary PLY (the direction as the normal) and reloaded exactly.

use std::io::{BufRead, Read, Write};
use std::path::Path;

use glam::Vec3;
use thiserror::Error;

/// Why points could not be saved or loaded.
#[derive(Debug, Error)]
pub enum PointsError {
    #[error("cannot write {path}: {source}")]
    Write { path: std::path::PathBuf, source: std::io::Error },
    #[error("cannot read {path}: {source}")]
    Read { path: std::path::PathBuf, source: std::io::Error },
    #[error("{path} is not a points PLY written by hairrecon: {msg}")]
    Format { path: std::path::PathBuf, msg: String },
}

/// Oriented (undirected or directed) 3D points.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OrientedPoints {
    pub positions: Vec<Vec3>,
    /// Unit directions.
    pub directions: Vec<Vec3>,
    /// In [0, 1].
    pub confidence: Vec<f32>,
}

impl OrientedPoints {
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Writes a binary little-endian PLY: x y z nx ny nz (direction) confidence.
    pub fn save_ply(&self, path: &Path) -> Result<(), PointsError> {
        let header = format!(
            "ply\nformat binary_little_endian 1.0\ncomment hairrecon oriented points\nelement vertex {}\n\
             property float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\n\
             property float nz\nproperty float confidence\nend_header\n",
            self.len()
        );
        let mut buf = Vec::with_capacity(self.len() * 28);
        for i in 0..self.len() {
            let (p, d) = (self.positions[i], self.directions[i]);
            for v in [p.x, p.y, p.z, d.x, d.y, d.z, self.confidence[i]] {
                buf.extend_from_slice(&v.to_le_bytes());
            }
        }
        write_atomically(path, &[header.as_bytes(), &buf])
    }

    /// Reads a PLY written by [`OrientedPoints::save_ply`].
    pub fn load_ply(path: &Path) -> Result<Self, PointsError> {
        let f = std::fs::File::open(path).map_err(|source| PointsError::Read { path: path.into(), source })?;
        let mut r = std::io::BufReader::new(f);
        let ferr = |msg: &str| PointsError::Format { path: path.into(), msg: msg.into() };
        let mut n = None;
        let mut props = 0;
        loop {
            let mut line = String::new();
            if r.read_line(&mut line).map_err(|source| PointsError::Read { path: path.into(), source })? == 0 {
                return Err(ferr("no end_header"));
            }
            let line = line.trim();
            if let Some(rest) = line.strip_prefix("element vertex ") {
                n = rest.trim().parse::<usize>().ok();
            } else if line.starts_with("property float") {
                props += 1;
            } else if line.starts_with("format") && !line.contains("binary_little_endian") {
                return Err(ferr("not binary little endian"));
            } else if line == "end_header" {
                break;
            }
        }
        let n = n.ok_or_else(|| ferr("no vertex count"))?;
        if props != 7 {
            return Err(ferr("expected 7 float properties (x y z nx ny nz confidence)"));
        }
        let mut bytes = vec![0u8; n * 28];
        r.read_exact(&mut bytes).map_err(|source| PointsError::Read { path: path.into(), source })?;
        let mut out = OrientedPoints::default();
        for c in bytes.chunks_exact(28) {
            let v: Vec<f32> = c.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
            out.positions.push(Vec3::new(v[0], v[1], v[2]));
            out.directions.push(Vec3::new(v[3], v[4], v[5]));
            out.confidence.push(v[6]);
        }
        Ok(out)
    }
}

/// Writes `parts` one after the other into `path` through a temporary file and a rename, so that
/// an error or an interrupt never leaves a half-written file.
pub(crate) fn write_atomically(path: &Path, parts: &[&[u8]]) -> Result<(), PointsError> {
    hairrecon_core::formats::atomic_write(path, |w| parts.iter().try_for_each(|b| Ok(w.write_all(b)?)))
        .map_err(|e| PointsError::Write { path: path.into(), source: std::io::Error::other(e.kind.to_string()) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ply_round_trip() {
        let pts = OrientedPoints {
            positions: vec![Vec3::new(0.1, 0.2, 0.3), Vec3::new(-1.0, 0.0, 2.0)],
            directions: vec![Vec3::X, Vec3::new(0.0, 0.6, 0.8)],
            confidence: vec![0.5, 1.0],
        };
        let p = std::env::temp_dir().join(format!("hairrecon-points-{}.ply", std::process::id()));
        pts.save_ply(&p).unwrap();
        assert_eq!(OrientedPoints::load_ply(&p).unwrap(), pts);
        let _ = std::fs::remove_file(&p);
    }
}
