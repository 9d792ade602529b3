//! What a run reports: `OUT/report.json`, one typed record per stage (wall time, the process's
//! peak memory at its end, the stage's own statistics) and, when the capture has ground truth,
//! the scores that [`crate::eval`] gave each stage's output.
//!
//! A run resumed with `--from STAGE` keeps the records of the stages before STAGE from the report
//! it finds in the folder, so the report always describes every stage of the result.
//!
//! The report is also the run's record of itself: it is written when the run starts (status
//! `running`), again after each stage, and last with the run's outcome (`complete`, `failed` or
//! `cancelled`); each stage's record lists the files it wrote, which is what the next run in the
//! folder clears ([`crate::runner`]).

use std::path::Path;

use hairrecon_core::metric::MetricReport;
use serde::{Deserialize, Serialize};

use crate::config::{Stage, GIT_COMMIT, VERSION};
use crate::eval::{AxisScore, DirectionScore, PointsScore};
use crate::orient2d::OrientationError;

/// One stage of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageRecord {
    pub stage: Stage,
    /// Wall time of the stage, seconds.
    pub seconds: f64,
    /// CPU time of the process during the stage, user and system, over all threads, seconds
    /// (`cpu_seconds / seconds` is how many cores the stage kept busy; `None` off Linux).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cpu_seconds: Option<f64>,
    /// The process's peak resident memory at the end of the stage, MiB (a running maximum: the
    /// first stage whose value jumps is the one that needed the memory; `None` off Linux).
    pub peak_rss_mb: Option<f64>,
    /// The stage's own statistics (its typed stats struct, serialized).
    #[serde(default, skip_serializing_if = "serde_json::Value::is_null")]
    pub stats: serde_json::Value,
    /// The files the stage wrote, relative to the output folder.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub files: Vec<String>,
}

/// Where a run stands.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RunStatus {
    /// Started, not ended: still running, or killed outright (its stages' files are complete,
    /// the result is not).
    Running,
    /// Every stage of the plan finished (a report without a status is one of these).
    #[default]
    Complete,
    /// A stage failed; `message` says why.
    Failed,
    /// The user cancelled the run (Blender, Python, or SIGINT/SIGTERM in the CLI).
    Cancelled,
}

/// Scores against the capture's ground truth (all `None` without it).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Scores {
    /// The 2D orientation maps against `gt/orientation`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orient2d: Option<OrientationError>,
    /// The oriented 3D points: precision and coverage at 2 mm/20°.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orient3d: Option<PointsScore>,
    /// The directed points: agreement with the ground truth's direction.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub direction: Option<DirectionScore>,
    /// With curls: the ringlet axes against the ground truth's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub axes: Option<AxisScore>,
    /// The strand metric of the guides and children before DR.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub init_guides: Option<MetricReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub init_strands: Option<MetricReport>,
    /// The same after DR.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dr_guides: Option<MetricReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dr_strands: Option<MetricReport>,
}

/// `OUT/report.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    pub hairrecon_version: String,
    pub git_commit: String,
    /// The capture folder.
    pub capture: String,
    /// Where the run stands; `message` says why it failed or stopped.
    #[serde(default)]
    pub status: RunStatus,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub message: Option<String>,
    /// The stages of the result, in order.
    pub stages: Vec<StageRecord>,
    pub scores: Scores,
    /// Warnings a user should read (e.g. the visual hull's trim was skipped).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

impl Report {
    pub fn new(capture: &Path) -> Self {
        Self {
            hairrecon_version: VERSION.into(),
            git_commit: GIT_COMMIT.into(),
            capture: capture.display().to_string(),
            status: RunStatus::Running,
            message: None,
            stages: Vec::new(),
            scores: Scores::default(),
            warnings: Vec::new(),
        }
    }

    /// The report of an earlier run in `out_dir` cut to the stages before `from` (their scores
    /// kept), or a new one when there is none.
    pub fn resumed(capture: &Path, out_dir: &Path, from: Stage) -> Self {
        let mut r = Self::new(capture);
        if let Some(old) = Self::load(out_dir) {
            r.stages = old.stages.into_iter().filter(|s| s.stage < from).collect();
            let s = old.scores;
            let keep = |st: Stage| st < from;
            r.scores = Scores {
                orient2d: s.orient2d.filter(|_| keep(Stage::Orient2d)),
                orient3d: s.orient3d.filter(|_| keep(Stage::Orient3d)),
                direction: s.direction.filter(|_| keep(Stage::Direction)),
                axes: s.axes.filter(|_| keep(Stage::Init)),
                init_guides: s.init_guides.filter(|_| keep(Stage::Init)),
                init_strands: s.init_strands.filter(|_| keep(Stage::Init)),
                dr_guides: None,
                dr_strands: None,
            };
        }
        r
    }

    /// The report in `out_dir`, when there is one that reads.
    pub fn load(out_dir: &Path) -> Option<Self> {
        std::fs::read(out_dir.join("report.json")).ok().and_then(|b| serde_json::from_slice(&b).ok())
    }

    /// Records a finished stage with its statistics (`&()` for none) and the files it wrote.
    pub fn record(
        &mut self,
        stage: Stage,
        seconds: f64,
        cpu_seconds: Option<f64>,
        stats: &impl Serialize,
        files: Vec<String>,
    ) {
        let stats = serde_json::to_value(stats).unwrap_or(serde_json::Value::Null);
        self.stages.retain(|s| s.stage != stage);
        let peak_rss_mb = peak_rss_bytes().map(|b| (b as f64 / (1 << 20) as f64).round());
        self.stages.push(StageRecord { stage, seconds, cpu_seconds, peak_rss_mb, stats, files });
    }

    /// Every file of the run, relative to the output folder: the stages' and the run's own
    /// (`config.json`, `report.json`).
    pub fn files(&self) -> impl Iterator<Item = &str> {
        ["config.json", "report.json"]
            .into_iter()
            .chain(self.stages.iter().flat_map(|s| s.files.iter().map(|f| f.as_str())))
    }

    /// (stage name, seconds) in order.
    pub fn stage_times(&self) -> Vec<(String, f64)> {
        self.stages.iter().map(|s| (s.stage.to_string(), s.seconds)).collect()
    }

    /// Writes `report.json` atomically.
    pub fn save(&self, path: &Path) -> Result<(), crate::error::ReconError> {
        crate::stages::write_json(path, self)
    }
}

/// Wall and CPU time since a stage started.
#[derive(Debug, Clone, Copy)]
pub struct StageClock {
    wall: std::time::Instant,
    cpu: Option<f64>,
}

impl StageClock {
    pub fn start() -> Self {
        Self { wall: std::time::Instant::now(), cpu: process_cpu_seconds() }
    }

    /// (wall seconds, CPU seconds) since [`StageClock::start`].
    pub fn elapsed(&self) -> (f64, Option<f64>) {
        let cpu = self.cpu.zip(process_cpu_seconds()).map(|(a, b)| ((b - a) * 100.0).round() / 100.0);
        (self.wall.elapsed().as_secs_f64(), cpu)
    }
}

/// The process's CPU time so far, user and system over all threads, in seconds (Linux
/// `/proc/self/stat`, whose clock ticks are 1/100 s on every Linux; `None` elsewhere).
pub fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name (field 2) may hold spaces; the fields after it start past its ')'.
    let rest = &stat[stat.rfind(')')? + 2..];
    let mut fields = rest.split_whitespace();
    let utime: u64 = fields.nth(11)?.parse().ok()?;
    let stime: u64 = fields.next()?.parse().ok()?;
    Some((utime + stime) as f64 / 100.0)
}

/// The process's peak resident memory so far in bytes (Linux `VmHWM`; `None` elsewhere), never
/// less than an earlier call returned. The kernel reports `VmHWM` as the larger of a recorded
/// high-water mark and the current resident size, whose per-CPU counters lag, so two readings can
/// fall by a megabyte (a run's report once read 105 then 104 MiB for consecutive stages).
pub fn peak_rss_bytes() -> Option<u64> {
    static MAX_SEEN: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    let bytes = kb * 1024;
    let earlier = MAX_SEEN.fetch_max(bytes, std::sync::atomic::Ordering::Relaxed);
    Some(bytes.max(earlier))
}
