//! A run owns its output folder: before it writes anything, [`claim`] clears what an earlier run
//! left there that this run makes again, so that no file of another run can pass for this one's.
//!
//! - A folder with a `report.json` or a `config.json`, or holding only names a run writes (stage
//!   files copied or linked in for `--from`), is a hairrecon run's: the files its report lists for the stages
//!   from `--from` on are removed (with the names [`crate::stages::OUTPUTS`] gives those stages, for
//!   reports that list none); the earlier stages' files stay, for the run to reload.
//!   Resuming (`--from`) a run of another capture is refused: it would mix two captures' stages.
//! - A missing or empty folder is fine.
//! - Any other folder (someone's documents, a capture) is refused, naming the files no run
//!   writes, unless `Plan::overwrite`; then only the names this run writes are cleared.
//!
//! While it runs, a run holds an advisory lock on the folder itself ([`lock`]; `flock` on the
//! directory, so nothing is written for it and a killed process lets go at once): a second run
//! into the same folder, from another process or another job of this one, is refused.
//!
//! The temporary files of an earlier run killed outright (`.NAME.tmp-PID-N`) are removed too,
//! unless their process still runs (on Linux, where that can be seen).

use std::path::{Component, Path};

use hairrecon_core::formats::is_temporary;

use crate::config::{ConfigFile, Plan, Stage};
use crate::error::ReconError;
use crate::report::Report;
use crate::stages::{remove, OUTPUTS};

/// The lock a run holds on its output folder while it runs (released when dropped).
#[derive(Debug)]
pub struct FolderLock {
    _dir: Option<std::fs::File>,
}

/// Creates `out_dir` if needed and locks it for this run; [`ReconError::Busy`] when another run
/// holds it. Where a folder cannot be opened as a file (Windows), runs are not locked.
pub fn lock(out_dir: &Path) -> Result<FolderLock, ReconError> {
    crate::stages::mkdir(out_dir)?;
    let Ok(dir) = std::fs::File::open(out_dir) else { return Ok(FolderLock { _dir: None }) };
    match dir.try_lock() {
        Ok(()) => Ok(FolderLock { _dir: Some(dir) }),
        Err(std::fs::TryLockError::WouldBlock) => Err(ReconError::Busy { path: out_dir.into() }),
        Err(std::fs::TryLockError::Error(source)) => Err(ReconError::OutDir { path: out_dir.into(), source }),
    }
}

/// Makes `out_dir` ready for a run of `plan` (see the module doc). Writes nothing; removes only
/// files of an earlier run.
pub fn claim(out_dir: &Path, plan: &Plan, capture_dir: &Path) -> Result<(), ReconError> {
    let io = |source| ReconError::OutDir { path: out_dir.into(), source };
    let entries = match std::fs::read_dir(out_dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        r => r.map_err(io)?,
    };
    let mut names = Vec::new();
    for e in entries {
        names.push(e.map_err(io)?.file_name().to_string_lossy().into_owned());
    }
    for dir in [out_dir.to_path_buf(), out_dir.join("orient2d"), out_dir.join("masks")] {
        remove_temporaries(&dir)?;
    }
    names.retain(|n| !is_temporary(n));
    let old = Report::load(out_dir);
    // A run killed before its first report (older versions wrote it last) left its config.json.
    let is_run = old.is_some() || ConfigFile::load(&out_dir.join("config.json")).is_ok();
    names.retain(|n| !written_by_a_run(n));
    if !is_run && !names.is_empty() && !plan.overwrite {
        names.sort();
        let mut found = names.iter().take(3).map(|n| format!("{n:?}")).collect::<Vec<_>>().join(", ");
        if names.len() > 3 {
            found.push_str(&format!(" and {} more", names.len() - 3));
        }
        return Err(ReconError::ForeignOutDir { path: out_dir.into(), found });
    }
    let from = plan.from;
    if let Some(old) = old.as_ref().filter(|_| from > Stage::FIRST) {
        // Compared as the same folder (a path given another way is fine); a capture since moved
        // or removed cannot be compared, and is let through.
        let (theirs, ours) = (std::fs::canonicalize(&old.capture), std::fs::canonicalize(capture_dir));
        if let (Ok(theirs), Ok(ours)) = (theirs, ours) {
            if theirs != ours {
                return Err(ReconError::OtherCapture { path: out_dir.into(), theirs, ours, from });
            }
        }
    }
    let listed = old.iter().flat_map(|r| r.stages.iter().filter(|s| s.stage >= from).flat_map(|s| &s.files));
    let known = OUTPUTS.iter().filter(|(s, _)| *s >= from).flat_map(|(_, files)| files.iter());
    for f in listed.map(String::as_str).chain(known.copied()) {
        // A report is a file anyone can edit: only plain names inside the folder are removed.
        if Path::new(f).components().all(|c| matches!(c, Component::Normal(_))) {
            remove(&out_dir.join(f))?;
        }
    }
    // The per-view files of views a report does not list (a report that lists no files).
    for (stage, dir) in [(Stage::Masks, "masks"), (Stage::Orient2d, "orient2d")] {
        if from <= stage {
            for name in list(&out_dir.join(dir))? {
                if name.ends_with(".exr") || name.ends_with(".png") {
                    remove(&out_dir.join(dir).join(name))?;
                }
            }
        }
    }
    Ok(())
}

/// Whether a run writes a file or folder of this name at the top of its output folder.
fn written_by_a_run(name: &str) -> bool {
    let staged = OUTPUTS.iter().flat_map(|(_, files)| files.iter()).filter_map(|f| f.split('/').next());
    ["config.json", "report.json"].into_iter().chain(staged).any(|f| f == name)
}

/// The file names in `dir` (none when it does not exist).
fn list(dir: &Path) -> Result<Vec<String>, ReconError> {
    match std::fs::read_dir(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Vec::new()),
        Err(source) => Err(ReconError::OutDir { path: dir.into(), source }),
        Ok(entries) => Ok(entries.flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect()),
    }
}

/// Removes the temporary files an earlier process left in `dir`.
fn remove_temporaries(dir: &Path) -> Result<(), ReconError> {
    list(dir)?.into_iter().filter(|n| is_temporary(n) && !writer_runs(n)).try_for_each(|n| remove(&dir.join(n)))
}

/// Whether the process that named the temporary file `name` still runs (a process id can be
/// reused: then the file stays, which is harmless).
fn writer_runs(name: &str) -> bool {
    let pid = name.rsplit_once(".tmp-").and_then(|(_, tail)| tail.split('-').next());
    pid.is_some_and(|pid| Path::new("/proc").join(pid).exists())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_is_locked_by_one_run_at_a_time() {
        let dir = std::env::temp_dir().join(format!("hairrecon-lock-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let first = lock(&dir).unwrap();
        assert!(dir.is_dir(), "the folder is made");
        match lock(&dir) {
            Err(e @ ReconError::Busy { .. }) => assert!(e.to_string().contains("another hairrecon run"), "{e}"),
            other => panic!("expected Busy, got {other:?}"),
        }
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "locking writes nothing");
        drop(first);
        let again = lock(&dir).unwrap();
        drop(again);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
