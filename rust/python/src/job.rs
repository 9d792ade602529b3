//! `hairrecon.Reconstruction` (a background job Blender can poll and cancel) and
//! `hairrecon.reconstruct` (the same, synchronous, for batch runs and tests).
//!
//! The job runs `hairrecon_recon::reconstruct` on a plain Rust thread. Progress lives in
//! a `SharedProgress` (atomics + a mutex), so `progress()` and `cancel()` only touch that state and
//! never call back into Python from the worker (bpy is not thread-safe).

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use hairrecon_core::capture::Capture;
use hairrecon_recon::config::{ConfigFile, ReconstructConfig, Stage};
use hairrecon_recon::curl::CurlError;
use hairrecon_recon::progress::{Progress, SharedProgress};
use hairrecon_recon::{reconstruct as run_pipeline, Plan, ReconError, ReconstructOutput};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::error::{input_err, to_py, Class, HairreconError};

type Outcome = Result<ReconstructOutput, RunError>;

/// The keyword arguments shared by `Reconstruction(...)` and `reconstruct(...)`: each given one
/// overrides `config` (a config.json path; else the library's defaults).
#[derive(Debug, Clone, Default)]
struct Args<'a> {
    config: Option<PathBuf>,
    from_stage: Option<&'a str>,
    stop_after: Option<&'a str>,
    guides: Option<usize>,
    children: Option<usize>,
    seed: Option<u64>,
    global_opt: Option<bool>,
    strand_init: Option<bool>,
    dr: Option<bool>,
    dr_iters_guides: Option<usize>,
    dr_iters_children: Option<usize>,
    hull_trim: Option<bool>,
    parting: Option<bool>,
    curl: Option<&'a str>,
    overwrite: bool,
}

fn stage(name: &str, s: Option<&str>) -> PyResult<Option<Stage>> {
    s.map(|s| s.parse::<Stage>().map_err(|e| input_err(format!("{name}: {e}")))).transpose()
}

/// The configuration and plan of the arguments.
fn options(a: Args<'_>) -> PyResult<(ReconstructConfig, Plan)> {
    let mut c = match &a.config {
        Some(p) => ConfigFile::load(p).map_err(input_err)?.config,
        None => ReconstructConfig::default(),
    };
    if a.guides == Some(0) || a.children == Some(0) {
        return Err(input_err("guides and children must be at least 1"));
    }
    c.guides = a.guides.unwrap_or(c.guides);
    c.children = a.children.unwrap_or(c.children);
    if let Some(s) = a.seed {
        (c.seed, c.dr_options.seed) = (s, s);
    }
    c.global_opt = a.global_opt.unwrap_or(c.global_opt);
    c.strand_init = a.strand_init.unwrap_or(c.strand_init);
    c.dr = a.dr.unwrap_or(c.dr);
    c.dr_options.iterations_guides = a.dr_iters_guides.unwrap_or(c.dr_options.iterations_guides);
    c.dr_options.iterations_children = a.dr_iters_children.unwrap_or(c.dr_options.iterations_children);
    c.hull_trim = a.hull_trim.unwrap_or(c.hull_trim);
    c.parting.enabled = a.parting.unwrap_or(c.parting.enabled);
    if let Some(curl) = a.curl {
        c.curl = curl.parse().map_err(|e: CurlError| input_err(format!("curl: {e}")))?;
    }
    c.validate().map_err(input_err)?;
    let plan = Plan {
        from: stage("from_stage", a.from_stage)?.unwrap_or(Stage::FIRST),
        stop_after: stage("stop_after", a.stop_after)?,
        overwrite: a.overwrite,
    };
    Ok((c, plan))
}

/// Runs the whole pipeline; any error or panic becomes a classified message (cancellation apart).
fn run(
    capture_dir: &std::path::Path,
    out_dir: &std::path::Path,
    (cfg, plan): &(ReconstructConfig, Plan),
    progress: &dyn Progress,
) -> Result<ReconstructOutput, RunError> {
    let capture = Capture::load(capture_dir).map_err(|e| RunError::Failed(Class::Capture, e.to_string()))?;
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        run_pipeline(&capture, out_dir, cfg, *plan, progress)
    })) {
        Ok(Ok(out)) => Ok(out),
        Ok(Err(ReconError::Cancelled(_))) => Err(RunError::Cancelled),
        Ok(Err(e)) => Err(RunError::Failed(Class::of(&e), e.to_string())),
        Err(_) => {
            Err(RunError::Failed(Class::Other, "internal error in the hairrecon pipeline (please report it)".into()))
        }
    }
}

#[derive(Debug, Clone)]
enum RunError {
    Cancelled,
    Failed(Class, String),
}

fn output_to_py<'py>(py: Python<'py>, out: &ReconstructOutput) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("strands", out.strands.clone())?;
    d.set_item("guides", out.guides.clone())?;
    d.set_item("init_strands", out.init_strands.clone())?;
    d.set_item("init_guides", out.init_guides.clone())?;
    d.set_item("loss_csv", out.loss_csv.clone())?;
    d.set_item("stage_times", out.report.stage_times())?;
    d.set_item("report", crate::json_to_py(py, &serde_json::to_value(&out.report).map_err(to_py)?)?)?;
    Ok(d)
}

fn run_error_to_py(e: RunError) -> PyErr {
    match e {
        RunError::Cancelled => Class::Cancelled.raise(
            "reconstruction cancelled by the user; no result was written (the output folder keeps the stages \
                 that finished, listed in report.json, for from_stage)",
        ),
        RunError::Failed(class, m) => class.raise(m),
    }
}

/// A reconstruction running in the background. Every keyword left at None takes its value from
/// `config` (a run's `config.json`), else the library's default. `from_stage` / `stop_after` run
/// part of the pipeline (`hairrecon reconstruct --from / --stop-after`). `dr=False` keeps the initial strands (no
/// optimization by differentiable rendering); `dr_iters_guides` / `dr_iters_children` set the DR
/// steps (None: the library's defaults); `hull_trim=False` keeps the initial strands' ends that a
/// view sees where its mask has no hair (by default they are cut at the visual hull before DR);
/// `parting=False` does not look for partings (by default, where the views see the scalp's skin,
/// the hair beside it leaves it sideways); `curl` is `"auto"` (the images decide), `"off"`, `"RADIUS_MM,PERIOD_MM,HAND"` or `"fine:RADIUS_MM,PERIOD_MM,HAND"` (`--curl`).
/// The run owns `out_dir`: it clears what an earlier run left there for the stages it makes again,
/// and refuses a folder holding other files (`InputError`) unless `overwrite=True` (`--overwrite`).
/// A cancelled or failed run keeps the stages it finished (listed in `report.json`), no result.
///
/// ```python
/// job = hairrecon.Reconstruction("capture/", "out/", guides=2000, children=50000, dr=True)
/// job.start()
/// while not job.done():
///     fraction, text = job.progress()
/// result = job.result()   # dict, or raises hairrecon.Error (a subclass: CaptureError, ...) / Cancelled
/// ```
#[derive(Debug)]
#[pyclass(module = "hairrecon")]
pub struct Reconstruction {
    capture_dir: PathBuf,
    out_dir: PathBuf,
    opts: (ReconstructConfig, Plan),
    progress: Arc<SharedProgress>,
    handle: Mutex<Option<JoinHandle<Result<ReconstructOutput, RunError>>>>,
    outcome: Mutex<Option<Outcome>>,
    cancelled: std::sync::atomic::AtomicBool,
}

#[pymethods]
impl Reconstruction {
    #[new]
    #[pyo3(signature = (capture_dir, out_dir, config=None, from_stage=None, stop_after=None, guides=None, children=None, seed=None, global_opt=None, strand_init=None, dr=None, dr_iters_guides=None, dr_iters_children=None, hull_trim=None, parting=None, curl=None, overwrite=false))]
    fn new(
        capture_dir: PathBuf,
        out_dir: PathBuf,
        config: Option<PathBuf>,
        from_stage: Option<&str>,
        stop_after: Option<&str>,
        guides: Option<usize>,
        children: Option<usize>,
        seed: Option<u64>,
        global_opt: Option<bool>,
        strand_init: Option<bool>,
        dr: Option<bool>,
        dr_iters_guides: Option<usize>,
        dr_iters_children: Option<usize>,
        hull_trim: Option<bool>,
        parting: Option<bool>,
        curl: Option<&str>,
        overwrite: bool,
    ) -> PyResult<Self> {
        let args = Args {
            config,
            from_stage,
            stop_after,
            guides,
            children,
            seed,
            global_opt,
            strand_init,
            dr,
            dr_iters_guides,
            dr_iters_children,
            hull_trim,
            parting,
            curl,
            overwrite,
        };
        Ok(Self {
            capture_dir,
            out_dir,
            opts: options(args)?,
            progress: Arc::new(SharedProgress::new()),
            handle: Mutex::new(None),
            outcome: Mutex::new(None),
            cancelled: std::sync::atomic::AtomicBool::new(false),
        })
    }

    /// Starts the work on a background thread. Raises if it was already started.
    fn start(&self) -> PyResult<()> {
        let mut h = self.handle.lock().map_err(to_py)?;
        if h.is_some() || self.outcome.lock().map_err(to_py)?.is_some() {
            return Err(HairreconError::new_err("this reconstruction was already started"));
        }
        let (c, o, opts, p) =
            (self.capture_dir.clone(), self.out_dir.clone(), self.opts.clone(), self.progress.clone());
        let handle = std::thread::Builder::new()
            .name("hairrecon-reconstruct".into())
            .spawn(move || run(&c, &o, &opts, p.as_ref()))
            .map_err(to_py)?;
        *h = Some(handle);
        Ok(())
    }

    /// `(fraction, text)`: progress of the current stage in [0, 1] and a status line.
    fn progress(&self) -> (f32, String) {
        self.progress.snapshot()
    }

    /// Asks the work to stop at its next safe point (within about a second).
    fn cancel(&self) {
        self.cancelled.store(true, std::sync::atomic::Ordering::SeqCst);
        self.progress.request_cancel();
    }

    /// Whether the work has finished (successfully or not).
    fn done(&self) -> PyResult<bool> {
        let h = self.handle.lock().map_err(to_py)?;
        Ok(match h.as_ref() {
            Some(h) => h.is_finished(),
            None => self.outcome.lock().map_err(to_py)?.is_some(),
        })
    }

    /// Waits for the work (GIL released) and returns its result dict: `strands`, `guides` (the final
    /// strands: paths or None), `init_strands`, `init_guides` (before DR, when it ran), `loss_csv`,
    /// `stage_times` [(name, seconds)], `report` (dict: what `report.json` holds). Raises `Cancelled` or another `hairrecon.Error`.
    fn result<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let handle = self.handle.lock().map_err(to_py)?.take();
        if let Some(h) = handle {
            let r = py.allow_threads(|| h.join());
            let outcome = r.unwrap_or_else(|_| {
                Err(RunError::Failed(
                    Class::Other,
                    "internal error in the hairrecon worker thread (please report it)".into(),
                ))
            });
            *self.outcome.lock().map_err(to_py)? = Some(outcome);
        }
        match self.outcome.lock().map_err(to_py)?.as_ref() {
            None => Err(HairreconError::new_err("this reconstruction was not started; call start() first")),
            Some(Ok(out)) => output_to_py(py, out),
            Some(Err(e)) => Err(run_error_to_py(e.clone())),
        }
    }
}

/// Reconstructs hair strands from a capture folder into `out_dir` (synchronous; the GIL is released
/// while Rust works). Returns the same dict as `Reconstruction.result()`.
#[pyfunction]
#[pyo3(signature = (capture_dir, out_dir, config=None, from_stage=None, stop_after=None, guides=None, children=None, seed=None, global_opt=None, strand_init=None, dr=None, dr_iters_guides=None, dr_iters_children=None, hull_trim=None, parting=None, curl=None, overwrite=false))]
fn reconstruct<'py>(
    py: Python<'py>,
    capture_dir: PathBuf,
    out_dir: PathBuf,
    config: Option<PathBuf>,
    from_stage: Option<&str>,
    stop_after: Option<&str>,
    guides: Option<usize>,
    children: Option<usize>,
    seed: Option<u64>,
    global_opt: Option<bool>,
    strand_init: Option<bool>,
    dr: Option<bool>,
    dr_iters_guides: Option<usize>,
    dr_iters_children: Option<usize>,
    hull_trim: Option<bool>,
    parting: Option<bool>,
    curl: Option<&str>,
    overwrite: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let opts = options(Args {
        config,
        from_stage,
        stop_after,
        guides,
        children,
        seed,
        global_opt,
        strand_init,
        dr,
        dr_iters_guides,
        dr_iters_children,
        hull_trim,
        parting,
        curl,
        overwrite,
    })?;
    let progress = SharedProgress::new();
    let out = py.allow_threads(|| run(&capture_dir, &out_dir, &opts, &progress).map_err(run_error_to_py))?;
    output_to_py(py, &out)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Reconstruction>()?;
    m.add_function(wrap_pyfunction!(reconstruct, m)?)?;
    Ok(())
}
