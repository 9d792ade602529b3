//! `hairrecon.import_colmap`, `import_metashape`, `import_nerf`: a photogrammetry tool's
//! calibration, its photos and the raw mesh, written as a capture folder (`hairrecon_import`, the
//! same as `hairrecon import colmap|metashape|nerf`).
//!
//! ```python
//! result = hairrecon.import_colmap("sparse/0", "images/", "mesh.ply", "capture/", height=512,
//!                                  progress=lambda done, total: print(done, "/", total))
//! result["capture"]    # path of capture/capture.json ("frame": "imported": the tool's frame and units)
//! result["warnings"]   # what the reader skipped or could not be sure of, one sentence each
//! ```
//!
//! The import runs on a Rust thread while the calling thread waits with the GIL released. The
//! `progress` callback is always called on the calling thread (never from a Rust worker: bpy is not
//! thread-safe), once after each photo, with `(views done, views in all)` (done = 1, 2, ..., all);
//! it returns `False` to cancel
//! (`hairrecon.Cancelled`), and an exception it raises cancels the import and is raised again. A
//! photo's worker waits for the callback's answer about it, so a cancel always writes nothing: the
//! capture folder appears whole or not at all. Ctrl-C (a pending signal) cancels the same way.

use std::path::{Path, PathBuf};
use std::sync::{Condvar, Mutex, MutexGuard};
use std::time::Duration;

use hairrecon_import::photo::Prefer;
use hairrecon_import::{import_capture, Imported, Source, WriteOptions};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict};

use crate::error::{import_err, input_err, to_py};

/// How often the waiting thread looks for a pending signal (Ctrl-C).
const SIGNAL_POLL: Duration = Duration::from_millis(100);

/// What the import thread and the calling thread share: progress reports waiting for the
/// callback's answer, the cancel flag and whether the import has ended.
#[derive(Default)]
struct Shared {
    state: Mutex<State>,
    changed: Condvar,
}

#[derive(Default)]
struct State {
    /// Progress calls made so far (each waits until `answered` reaches its number).
    reported: u64,
    /// Progress calls the callback has answered, in order: the k-th answer is "k views done".
    answered: u64,
    /// The views in all.
    total: usize,
    cancel: bool,
    finished: bool,
}

/// What the calling thread wakes up for.
enum Event {
    Progress { done: usize, total: usize, upto: u64 },
    Tick,
    Finished,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        // a panic while holding the lock cannot leave the counters inconsistent: take them anyway
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The import's progress function (called by the writer's worker threads): reports and waits
    /// for the callback's answer; `false` cancels.
    fn report(&self, total: usize) -> bool {
        let mut s = self.lock();
        s.reported += 1;
        let mine = s.reported;
        s.total = total;
        self.changed.notify_all();
        while s.answered < mine && !s.cancel {
            s = self.changed.wait(s).unwrap_or_else(|p| p.into_inner());
        }
        !s.cancel
    }

    /// Waits (up to [`SIGNAL_POLL`]) for an unanswered report or the end of the import; reports are
    /// answered one at a time, so the callback sees 1, 2, ..., total views done.
    fn next_event(&self) -> Event {
        let mut s = self.lock();
        if s.answered == s.reported && !s.finished {
            s = self.changed.wait_timeout(s, SIGNAL_POLL).unwrap_or_else(|p| p.into_inner()).0;
        }
        if s.finished {
            Event::Finished
        } else if s.answered < s.reported {
            Event::Progress { done: s.answered as usize + 1, total: s.total, upto: s.answered + 1 }
        } else {
            Event::Tick
        }
    }

    /// Answers the reports up to `upto` (and releases all of them when cancelling).
    fn answer(&self, upto: u64, cancel: bool) {
        let mut s = self.lock();
        s.answered = s.answered.max(upto);
        s.cancel |= cancel;
        self.changed.notify_all();
    }

    fn finish(&self) {
        self.lock().finished = true;
        self.changed.notify_all();
    }
}

/// Runs the import on a Rust thread, calling `progress` on this thread (module docs).
fn run(
    py: Python<'_>,
    source: Source,
    opts: WriteOptions,
    out: &Path,
    progress: Option<PyObject>,
) -> PyResult<Imported> {
    if opts.height == 0 {
        return Err(input_err("height must be at least 1 pixel"));
    }
    let shared = Shared::default();
    let mut raised: Option<PyErr> = None;
    let result = std::thread::scope(|scope| {
        let worker = scope.spawn(|| {
            // the writer's own count of views done arrives out of order from its threads: count here
            let report = |_done: usize, total: usize| shared.report(total);
            let r =
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| import_capture(&source, &opts, out, &report)));
            shared.finish();
            r
        });
        let mut asking = progress.is_some();
        loop {
            match py.allow_threads(|| shared.next_event()) {
                Event::Finished => break,
                Event::Progress { done, total, upto } => {
                    let mut cancel = false;
                    if let (true, Some(cb)) = (asking, &progress) {
                        match cb.call1(py, (done, total)) {
                            // only False cancels: None (no return) and any other value go on
                            Ok(v) => cancel = v.bind(py).downcast::<PyBool>().is_ok_and(|b| !b.is_true()),
                            Err(e) => {
                                cancel = true;
                                raised = Some(e);
                            }
                        }
                        asking = !cancel;
                    }
                    shared.answer(upto, cancel);
                }
                Event::Tick => {
                    if raised.is_none() {
                        if let Err(e) = py.check_signals() {
                            raised = Some(e);
                            asking = false;
                            shared.answer(0, true);
                        }
                    }
                }
            }
        }
        worker.join()
    });
    let result = match result {
        Ok(Ok(r)) => r,
        // a panic in the importer (not in the writer's workers: rayon passes theirs on) or a
        // worker that died otherwise
        Ok(Err(_)) | Err(_) => return Err(to_py("internal error in the hairrecon importer (please report it)")),
    };
    if let Some(e) = raised {
        return Err(e);
    }
    result.map_err(|e| import_err(&e))
}

/// The options shared by the three importers.
fn write_options(images: PathBuf, mesh: PathBuf, height: u32, exif_orientation: bool) -> WriteOptions {
    WriteOptions { images, mesh, height, prefer: if exif_orientation { Prefer::Exif } else { Prefer::Stored } }
}

/// The folder a calibration file's photo names are relative to by default: the file's folder.
fn folder_of(file: &Path) -> PathBuf {
    match file.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

fn imported_to_py(py: Python<'_>, out: Imported) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("capture", out.capture_json)?;
    d.set_item("warnings", out.warnings)?;
    Ok(d)
}

/// Imports a COLMAP sparse model (the folder holding `cameras`, `images` and `points3D` as .txt
/// or .bin, e.g. `sparse/0`), the photos in `images` and the raw mesh `mesh` (PLY or OBJ) as a
/// capture folder `out` (which must not exist or be empty). The photos become undistorted pinhole
/// working copies `height` pixels high; the capture keeps COLMAP's frame and units
/// (`"frame": "imported"`). `exif_orientation=True` takes a photo's EXIF-rotated pixels when both
/// orientations match the camera's size (default: the stored pixels, as COLMAP reads them).
/// `progress(done, total)` is called after each photo on this thread; returning False cancels.
///
/// Returns `{"capture": path of capture.json, "warnings": [str, ...]}`. Raises `Cancelled` (nothing
/// written), `InputError` (a path that names no calibration, an existing non-empty `out`, a bad
/// height), `FormatError` (a calibration, photo or mesh that cannot be read), `CaptureError` (a
/// photo that does not match its camera, two views of one name); the message names the file.
#[pyfunction]
#[pyo3(signature = (sparse, images, mesh, out, height=512, exif_orientation=false, progress=None))]
fn import_colmap<'py>(
    py: Python<'py>,
    sparse: PathBuf,
    images: PathBuf,
    mesh: PathBuf,
    out: PathBuf,
    height: u32,
    exif_orientation: bool,
    progress: Option<PyObject>,
) -> PyResult<Bound<'py, PyDict>> {
    let opts = write_options(images, mesh, height, exif_orientation);
    let done = run(py, Source::Colmap(sparse), opts, &out, progress)?;
    imported_to_py(py, done)
}

/// Imports an Agisoft Metashape cameras XML (File > Export > Export Cameras, Agisoft XML) with its
/// photos and the raw mesh as a capture folder `out`, like `import_colmap`. `images` is the folder
/// the photos' labels are relative to (default: the XML's folder).
#[pyfunction]
#[pyo3(signature = (xml, mesh, out, images=None, height=512, exif_orientation=false, progress=None))]
fn import_metashape<'py>(
    py: Python<'py>,
    xml: PathBuf,
    mesh: PathBuf,
    out: PathBuf,
    images: Option<PathBuf>,
    height: u32,
    exif_orientation: bool,
    progress: Option<PyObject>,
) -> PyResult<Bound<'py, PyDict>> {
    let images = images.unwrap_or_else(|| folder_of(&xml));
    let opts = write_options(images, mesh, height, exif_orientation);
    let done = run(py, Source::Metashape(xml), opts, &out, progress)?;
    imported_to_py(py, done)
}

/// Imports an instant-ngp or nerfstudio `transforms.json` with its photos and the raw mesh as a
/// capture folder `out`, like `import_colmap`. `images` is the folder the frames' `file_path`s are
/// relative to (default: the transforms.json's folder).
#[pyfunction]
#[pyo3(signature = (transforms, mesh, out, images=None, height=512, exif_orientation=false, progress=None))]
fn import_nerf<'py>(
    py: Python<'py>,
    transforms: PathBuf,
    mesh: PathBuf,
    out: PathBuf,
    images: Option<PathBuf>,
    height: u32,
    exif_orientation: bool,
    progress: Option<PyObject>,
) -> PyResult<Bound<'py, PyDict>> {
    let images = images.unwrap_or_else(|| folder_of(&transforms));
    let opts = write_options(images, mesh, height, exif_orientation);
    let done = run(py, Source::Nerf(transforms), opts, &out, progress)?;
    imported_to_py(py, done)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(import_colmap, m)?)?;
    m.add_function(wrap_pyfunction!(import_metashape, m)?)?;
    m.add_function(wrap_pyfunction!(import_nerf, m)?)?;
    Ok(())
}
