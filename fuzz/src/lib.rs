//! The fuzzing harnesses: each takes the fuzzer's bytes to one reader of hairrecon, through the same
//! entry point a user's file takes (a file on disk where the reader opens files itself). A harness
//! passes when the reader returns, with a value or an error; a panic, an abort, a hang or memory over
//! the budget given to libFuzzer (`scripts/fuzz.sh`) is a finding.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{self, StrandReadOptions};
use hairrecon_core::image_io;
use hairrecon_import::photo::load_photo;
use hairrecon_import::{read_colmap, read_metashape, read_nerf};

/// Where multi-file inputs (a COLMAP model) split into their files.
pub const FILE_SEPARATOR: &[u8] = b"\n%%%%\n";

thread_local! {
    static SCRATCH: PathBuf = {
        let base = if Path::new("/dev/shm").is_dir() { PathBuf::from("/dev/shm") } else { std::env::temp_dir() };
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        base.join(format!("hairrecon-fuzz-{}-{n}", std::process::id()))
    };
}

/// A folder of this thread for the files a harness writes (in memory where /dev/shm exists): the
/// replay test runs targets on several threads at once.
fn scratch() -> PathBuf {
    let dir = SCRATCH.with(|d| d.clone());
    std::fs::create_dir_all(&dir).expect("scratch folder");
    dir
}

/// Removes this thread's scratch folder (the replay test calls it when a target is done; libFuzzer's
/// process leaves it, as it leaves its own files, for the run's end).
pub fn remove_scratch() {
    let _ = std::fs::remove_dir_all(SCRATCH.with(|d| d.clone()));
}

fn put(name: &str, bytes: &[u8]) -> PathBuf {
    let path = scratch().join(name);
    std::fs::write(&path, bytes).expect("scratch write");
    path
}

/// `data` cut at each [`FILE_SEPARATOR`], at most `n` parts (missing parts are empty).
pub fn split(data: &[u8], n: usize) -> Vec<&[u8]> {
    let mut parts = Vec::with_capacity(n);
    let mut rest = data;
    while parts.len() + 1 < n {
        match rest.windows(FILE_SEPARATOR.len()).position(|w| w == FILE_SEPARATOR) {
            Some(i) => {
                parts.push(&rest[..i]);
                rest = &rest[i + FILE_SEPARATOR.len()..];
            }
            None => break,
        }
    }
    parts.push(rest);
    parts.resize(n, &[]);
    parts
}

/// Cem Yuksel's `.hair`, strict and lenient.
pub fn hair(data: &[u8]) {
    let _ = formats::read_hair_bytes(data);
    let _ = formats::hair::read_hair_bytes_with(data, StrandReadOptions { skip_short_strands: true });
}

/// USC-HairSalon `.data`, strict and lenient.
pub fn data(data: &[u8]) {
    let _ = formats::read_usc_bytes(data, StrandReadOptions { skip_short_strands: false });
    let _ = formats::read_usc_bytes(data, StrandReadOptions { skip_short_strands: true });
}

/// PLY, as a mesh and as polylines.
pub fn ply(data: &[u8]) {
    let _ = formats::read_ply_mesh_bytes(data);
    let _ = formats::read_ply_strands_bytes(data);
}

/// Wavefront OBJ, as a mesh and as lines.
pub fn obj(data: &[u8]) {
    let _ = formats::read_obj_bytes(data);
    let _ = formats::read_obj_lines_bytes(data);
}

/// Images the pipeline reads (PNG, EXR, JPEG, TIFF), through every reader.
pub fn image(data: &[u8]) {
    let _ = image_io::read_image_bytes(data);
    let _ = image_io::read_gray_f32_bytes(data);
    let _ = image_io::read_rgb_f32_bytes(data);
    let _ = image_io::read_exr_channels_bytes(data);
}

/// A capture folder's `capture.json` (the images it names are absent unless it names itself).
pub fn capture_json(data: &[u8]) {
    let path = put("capture.json", data);
    let _ = Capture::load(&path);
    let _ = Capture::load_allowing_outside_paths(&path);
}

fn colmap(data: &[u8], names: [&str; 3]) {
    let dir = scratch().join("colmap");
    std::fs::create_dir_all(&dir).expect("scratch folder");
    for (name, part) in names.iter().zip(split(data, 3)) {
        std::fs::write(dir.join(name), part).expect("scratch write");
    }
    let _ = read_colmap(&dir);
}

/// A COLMAP text model: `cameras.txt`, `images.txt`, `points3D.txt` cut at [`FILE_SEPARATOR`].
pub fn colmap_text(data: &[u8]) {
    colmap(data, ["cameras.txt", "images.txt", "points3D.txt"]);
}

/// A COLMAP binary model: `cameras.bin`, `images.bin`, `points3D.bin` cut at [`FILE_SEPARATOR`].
pub fn colmap_binary(data: &[u8]) {
    colmap(data, ["cameras.bin", "images.bin", "points3D.bin"]);
}

/// An Agisoft Metashape XML camera export.
pub fn metashape(data: &[u8]) {
    let _ = read_metashape(&put("cameras.xml", data));
}

/// A NeRF-style `transforms.json`.
pub fn nerf(data: &[u8]) {
    let _ = read_nerf(&put("transforms.json", data));
}

/// A photo (JPEG, PNG, TIFF with EXIF orientation), loaded and turned upright.
pub fn photo(data: &[u8]) {
    if let Ok(photo) = load_photo(put("photo", data)) {
        let _ = photo.oriented();
    }
}

/// A harness: the fuzzer's bytes to one reader.
pub type Harness = fn(&[u8]);

/// Every harness by its target's name (the names of `fuzz_targets/`, `fuzz/seeds/` and `fuzz/corpus/`).
pub const TARGETS: [(&str, Harness); 11] = [
    ("hair", hair),
    ("data", data),
    ("ply", ply),
    ("obj", obj),
    ("image", image),
    ("capture_json", capture_json),
    ("colmap_text", colmap_text),
    ("colmap_binary", colmap_binary),
    ("metashape", metashape),
    ("nerf", nerf),
    ("photo", photo),
];
