//! File formats: meshes (PLY, OBJ) and hair strands (`.hair`, `.data`, PLY polylines, OBJ lines).
//!
//! - [`read_mesh`] / [`write_mesh`]: triangle meshes as PLY ([`ply`], binary or ASCII in, binary
//!   little-endian out) or Wavefront OBJ ([`obj`]), chosen by the file extension.
//! - [`read_strands`] / [`write_strands`]: strand sets as Cem Yuksel's `.hair` ([`hair`]),
//!   USC-HairSalon `.data` ([`usc`]), PLY polylines ([`ply_strands`]) or OBJ lines ([`obj_lines`]).
//!
//! Every reader also has a byte-level form (`read_*_bytes`) that works on memory and returns errors
//! without a file name; the path-level functions add the file name. Readers never panic and never
//! allocate on the word of an untrusted count: a count is checked against the bytes left in the file
//! before anything is reserved for it. Every writer goes through [`atomic_write`], so an error leaves
//! no half-written file behind.

pub mod bytes;
pub mod hair;
pub mod obj;
pub mod obj_lines;
pub mod ply;
pub mod ply_strands;
pub mod usc;

use std::fmt;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use thiserror::Error;

use crate::mesh::{MeshError, TriMesh};
use crate::strands::{StrandError, StrandSet};

pub use hair::{
    read_hair, read_hair_bytes, read_hair_bytes_with, write_hair, write_hair_bytes, write_hair_strands_bytes, HairFile,
};
pub use obj::{read_obj_bytes, write_obj_bytes};
pub use obj_lines::{read_obj_lines_bytes, write_obj_lines_bytes};
pub use ply::{read_ply_mesh_bytes, write_ply_mesh_bytes};
pub use ply_strands::{read_ply_strands_bytes, write_ply_strands_bytes};
pub use usc::{read_usc, read_usc_bytes, write_usc_bytes, UscReadOptions};

/// Options of the strand readers.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StrandReadOptions {
    /// Drop strands of fewer than two points instead of failing (USC-HairSalon `.data` files and
    /// some `.hair` files have them). The readers that take options report how many were dropped.
    pub skip_short_strands: bool,
}

/// Extensions that [`read_mesh`] and [`write_mesh`] accept.
pub const MESH_EXTENSIONS: &str = ".ply, .obj";
/// Extensions that [`read_strands`] and [`write_strands`] accept.
pub const STRAND_EXTENSIONS: &str = ".hair (Cem Yuksel), .data (USC-HairSalon), .ply (polylines), .obj (lines)";

/// A reading or writing error, with the file it concerns when there is one.
#[derive(Debug, Error)]
pub struct FormatError {
    /// The file read or written; `None` for the byte-level functions.
    pub path: Option<PathBuf>,
    /// What went wrong.
    pub kind: FormatErrorKind,
}

impl fmt::Display for FormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.path {
            Some(p) => write!(f, "{}: {}", p.display(), self.kind),
            None => write!(f, "{}", self.kind),
        }
    }
}

impl FormatError {
    /// Attaches a file name (keeping one that is already there).
    pub fn in_file(mut self, path: &Path) -> Self {
        if self.path.is_none() {
            self.path = Some(path.to_path_buf());
        }
        self
    }
}

impl From<FormatErrorKind> for FormatError {
    fn from(kind: FormatErrorKind) -> Self {
        Self { path: None, kind }
    }
}

impl From<io::Error> for FormatError {
    fn from(e: io::Error) -> Self {
        FormatErrorKind::Io(e).into()
    }
}

impl From<MeshError> for FormatError {
    fn from(e: MeshError) -> Self {
        FormatErrorKind::Mesh(e).into()
    }
}

impl From<StrandError> for FormatError {
    fn from(e: StrandError) -> Self {
        FormatErrorKind::Strands(e).into()
    }
}

/// What went wrong while reading or writing a file.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum FormatErrorKind {
    #[error("input/output error: {0}")]
    Io(#[source] io::Error),
    #[error("unsupported file extension {ext:?}; supported: {supported}")]
    UnknownExtension { ext: String, supported: &'static str },
    #[error("not a {format} file: expected {expected:?} at the start but found {found:?}")]
    BadMagic { format: &'static str, expected: &'static str, found: String },
    #[error(
        "the file ends after {len} bytes while reading {what} (which needs {needed} bytes from offset \
         {offset}); the file is truncated or a count in its header is wrong"
    )]
    Truncated { what: String, offset: u64, needed: u64, len: u64 },
    #[error(
        "{count} {what} cannot fit in the {available} bytes left in the file (at least {min_size} bytes \
         each); the header's count is wrong or the file is truncated"
    )]
    CountTooLarge { what: &'static str, count: u64, available: u64, min_size: u64 },
    #[error("{count} bytes follow the last {what}; the counts in the file disagree with its size")]
    TrailingBytes { what: &'static str, count: u64 },
    #[error("bad header: {0}")]
    Header(String),
    #[error("line {line}: {msg}")]
    Syntax { line: u64, msg: String },
    #[error("{what} {index} is not finite ({value}); remove NaN or infinite values from the file")]
    NotFinite { what: &'static str, index: u64, value: f64 },
    #[error(
        "strand {strand} has {count} point(s); every strand needs at least 2 (root and tip); \
         drop such strands first{hint}"
    )]
    ShortStrand { strand: u64, count: u64, hint: &'static str },
    #[error("{what}: {expected} expected but {found} found; the file is inconsistent")]
    CountMismatch { what: &'static str, expected: u64, found: u64 },
    #[error("{what} {index} refers to item {value} but there are only {count}; the file is corrupt")]
    IndexOutOfRange { what: &'static str, index: u64, value: i64, count: u64 },
    #[error("{0}")]
    Invalid(String),
    #[error("invalid mesh: {0}")]
    Mesh(#[from] MeshError),
    #[error("invalid strands: {0}")]
    Strands(#[from] StrandError),
    #[error("image: {0}")]
    Image(String),
}

/// Result type of this module.
pub type Result<T, E = FormatError> = std::result::Result<T, E>;

/// The lower-case extension of `path` without the dot, or an empty string.
fn extension(path: &Path) -> String {
    path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).unwrap_or_default()
}

/// Reads a whole file, naming it in the error.
pub fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| FormatError::from(e).in_file(path))
}

/// Reads a triangle mesh from a `.ply` or `.obj` file. Polygons are fan-triangulated.
pub fn read_mesh(path: impl AsRef<Path>) -> Result<TriMesh> {
    let path = path.as_ref();
    let reader: fn(&[u8]) -> Result<TriMesh> = match extension(path).as_str() {
        "ply" => ply::read_ply_mesh_bytes,
        "obj" => obj::read_obj_bytes,
        ext => return Err(unknown_extension(path, ext, MESH_EXTENSIONS)),
    };
    let bytes = read_file(path)?;
    reader(&bytes).map_err(|e| e.in_file(path))
}

/// Writes a triangle mesh: binary little-endian PLY for `.ply`, Wavefront OBJ for `.obj`.
/// The file is written atomically.
pub fn write_mesh(path: impl AsRef<Path>, mesh: &TriMesh) -> Result<()> {
    let path = path.as_ref();
    match extension(path).as_str() {
        "ply" => atomic_write(path, |w| ply::write_ply_mesh(w, mesh)),
        "obj" => atomic_write(path, |w| obj::write_obj(w, mesh)),
        ext => Err(unknown_extension(path, ext, MESH_EXTENSIONS)),
    }
}

/// Writes a triangle mesh as binary PLY with a per-vertex `quality` (see
/// [`ply::write_ply_mesh_with_quality`]); atomically. Only `.ply` holds it.
pub fn write_mesh_with_quality(path: impl AsRef<Path>, mesh: &TriMesh, quality: &[f32]) -> Result<()> {
    let path = path.as_ref();
    match extension(path).as_str() {
        "ply" => atomic_write(path, |w| ply::write_ply_mesh_with_quality(w, mesh, Some(quality))),
        ext => Err(unknown_extension(path, ext, "ply")),
    }
}

/// Reads strands from `.hair`, `.data`, `.ply` (polylines) or `.obj` (lines). A strand of fewer
/// than two points is an error; see [`read_strands_with`] to skip such strands.
pub fn read_strands(path: impl AsRef<Path>) -> Result<StrandSet> {
    read_strands_with(path, StrandReadOptions::default()).map(|(s, _)| s)
}

/// Reads strands like [`read_strands`] with options; returns the strands and the number of strands
/// skipped. Only `.hair` and `.data` files can hold one-point strands; `.ply` and `.obj` strand files
/// always reject them.
pub fn read_strands_with(path: impl AsRef<Path>, options: StrandReadOptions) -> Result<(StrandSet, usize)> {
    let path = path.as_ref();
    type Reader = fn(&[u8], StrandReadOptions) -> Result<(StrandSet, usize)>;
    let reader: Reader = match extension(path).as_str() {
        "hair" => |b, o| hair::read_hair_bytes_with(b, o).map(|(h, k)| (h.strands, k)),
        "data" => usc::read_usc_bytes,
        "ply" => |b, _| ply_strands::read_ply_strands_bytes(b).map(|s| (s, 0)),
        "obj" => |b, _| obj_lines::read_obj_lines_bytes(b).map(|s| (s, 0)),
        ext => return Err(unknown_extension(path, ext, STRAND_EXTENSIONS)),
    };
    let bytes = read_file(path)?;
    reader(&bytes, options).map_err(|e| e.in_file(path))
}

/// Writes strands as `.hair`, `.data`, `.ply` (binary polylines) or `.obj` (lines), atomically.
pub fn write_strands(path: impl AsRef<Path>, strands: &StrandSet) -> Result<()> {
    let path = path.as_ref();
    let writer: fn(&StrandSet) -> Result<Vec<u8>> = match extension(path).as_str() {
        "hair" => hair::write_hair_strands_bytes,
        "data" => |s| Ok(usc::write_usc_bytes(s)),
        "ply" => |s| Ok(ply_strands::write_ply_strands_bytes(s)),
        "obj" => |s| Ok(obj_lines::write_obj_lines_bytes(s)),
        ext => return Err(unknown_extension(path, ext, STRAND_EXTENSIONS)),
    };
    let bytes = writer(strands).map_err(|e| e.in_file(path))?;
    atomic_write(path, |w| Ok(w.write_all(&bytes)?))
}

fn unknown_extension(path: &Path, ext: &str, supported: &'static str) -> FormatError {
    FormatError::from(FormatErrorKind::UnknownExtension { ext: format!(".{ext}"), supported }).in_file(path)
}

/// Writes a file atomically: `write` fills a temporary file in the same folder, which is then
/// flushed and renamed over `path`. If `write` or any step fails, the temporary file is removed and
/// `path` is left as it was (absent, or its old content). The error names `path`.
///
/// The temporary file is named `.NAME.tmp-PID-N` (see [`is_temporary`]) and listed while it exists,
/// so that a process stopped by a signal can remove it ([`remove_temporaries`]).
pub fn atomic_write<F>(path: impl AsRef<Path>, write: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<File>) -> Result<()>,
{
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let path = path.as_ref();
    let name = path.file_name().ok_or_else(|| {
        FormatError::from(FormatErrorKind::Invalid("the output path has no file name".into())).in_file(path)
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let tmp = dir.join(format!(".{}.tmp-{}-{}", name.to_string_lossy(), std::process::id(), n));
    live_temporaries(|t| t.push(tmp.clone()));
    let result = (|| -> Result<()> {
        let file = File::create(&tmp)?;
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        std::fs::rename(&tmp, path)?;
        Ok(())
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    live_temporaries(|t| t.retain(|p| *p != tmp));
    result.map_err(|e| e.in_file(path))
}

/// Runs `f` on the list of the temporary files [`atomic_write`] is filling now.
fn live_temporaries(f: impl FnOnce(&mut Vec<PathBuf>)) {
    static LIVE: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    let mut live = LIVE.lock().unwrap_or_else(|e| e.into_inner());
    f(&mut live);
}

/// Removes the temporary files that [`atomic_write`] calls are filling now, and returns how many:
/// for a process about to exit on a signal (their writes never finish, and no `path` is touched).
pub fn remove_temporaries() -> usize {
    let mut n = 0;
    live_temporaries(|t| {
        for p in t.drain(..) {
            n += usize::from(std::fs::remove_file(&p).is_ok());
        }
    });
    n
}

/// Whether a file name is that of an [`atomic_write`] temporary (`.NAME.tmp-PID-N`): what a
/// process killed outright (SIGKILL, power loss) leaves behind.
pub fn is_temporary(file_name: &str) -> bool {
    let Some(rest) = file_name.strip_prefix('.') else { return false };
    let Some((_, tail)) = rest.rsplit_once(".tmp-") else { return false };
    let mut parts = tail.split('-');
    let digits = |p: Option<&str>| p.is_some_and(|p| !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit()));
    digits(parts.next()) && digits(parts.next()) && parts.next().is_none()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_write_leaves_nothing_on_error() {
        let dir = std::env::temp_dir().join(format!("hairrecon-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("out.bin");
        std::fs::write(&path, b"old").unwrap();
        let err = atomic_write(&path, |w| {
            w.write_all(b"half")?;
            Err(FormatErrorKind::Invalid("stop".into()).into())
        })
        .unwrap_err();
        assert_eq!(err.path.as_deref(), Some(path.as_path()));
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "the temporary file was not removed");
        atomic_write(&path, |w| Ok(w.write_all(b"new")?)).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn temporary_names_are_recognized() {
        assert!(is_temporary(".strands.hair.tmp-4242-0") && is_temporary(".a.tmp-1-23"));
        for name in ["strands.hair", ".hidden", ".a.tmp-", ".a.tmp-1", ".a.tmp-x-1", "a.tmp-1-2", ".a.tmp-1-2-3"] {
            assert!(!is_temporary(name), "{name}");
        }
    }

    #[test]
    fn unknown_extensions_list_the_supported_ones() {
        let e = read_strands("x.abc").unwrap_err();
        assert!(matches!(e.kind, FormatErrorKind::UnknownExtension { .. }));
        assert!(e.to_string().contains(".hair") && e.to_string().contains("x.abc"), "{e}");
        let e = read_mesh("x").unwrap_err();
        assert!(e.to_string().contains(".ply, .obj"), "{e}");
    }
}
