//! SIGINT and SIGTERM during `hairrecon reconstruct`, through the real binary on the small
//! synthetic capture of `rust/recon/tests/common`: whenever the signal comes, the run stops at its
//! next safe point with exit code 130 (or, when the signal comes too late, completes); the output
//! folder then holds exactly what its `report.json` lists (the stages that finished, complete, for
//! `--from`), a result only when the run completed, and no temporary file.

#[path = "../../recon/tests/common/mod.rs"]
mod common;

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Instant;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_hairrecon")
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hairrecon-interrupt-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn start(cap: &Path, out: &Path) -> Child {
    Command::new(bin())
        .arg("reconstruct")
        .arg(cap)
        .args(["--out", out.to_str().unwrap(), "--guides", "60", "--children", "400"])
        // A short DR: the signals should land in every stage, not mostly in DR's steps.
        .args(["--dr-iters-guides", "6", "--dr-iters-children", "3"])
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap()
}

fn signal(pid: u32, signal: &str) {
    assert!(Command::new("kill").args([signal, &pid.to_string()]).status().unwrap().success());
}

/// Reads `out/report.json` and checks that the folder holds exactly the files it lists (with
/// `config.json` and itself), none other and no temporary; returns the report.
fn folder_is_what_its_report_lists(out: &Path, context: &str) -> serde_json::Value {
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let mut listed: Vec<String> = ["config.json", "report.json"].map(String::from).to_vec();
    let stages = report["stages"].as_array().unwrap();
    listed.extend(
        stages.iter().flat_map(|s| s["files"].as_array().unwrap().iter().map(|f| f.as_str().unwrap().to_string())),
    );
    listed.sort();
    let mut found: Vec<String> = Vec::new();
    for sub in ["", "orient2d", "masks"] {
        if let Ok(rd) = std::fs::read_dir(out.join(sub)) {
            for e in rd.flatten().filter(|e| e.path().is_file()) {
                found.push(Path::new(sub).join(e.file_name()).to_string_lossy().into_owned());
            }
        }
    }
    found.sort();
    assert_eq!(found, listed, "{context}: the folder holds files its report does not list");
    report
}

/// SIGTERM while orient2d runs, then SIGINT while orient3d runs in the same folder: each run stops
/// at its next safe point with a message and exit code 130; the folder holds what its report lists
/// (the stages that finished, complete), no result and no temporary file.
#[test]
fn an_interrupted_run_leaves_its_finished_stages_and_no_temporary() {
    let dir = tmp("interrupt");
    let cap = common::write_capture(&dir.join("capture"), 600, 128, 3);
    let out = dir.join("out");
    for (sig, stage, finished) in [("-TERM", "orient2d", 0), ("-INT", "orient3d", 1)] {
        let mut child = start(&cap, &out);
        // Not a terminal: one line per stage change on stderr.
        let mut err = BufReader::new(child.stderr.take().unwrap());
        let mut text = String::new();
        while !text.lines().any(|l| l.contains(&format!("] {stage} "))) {
            assert!(err.read_line(&mut text).unwrap() > 0, "{stage} never started:\n{text}");
        }
        signal(child.id(), sig);
        err.read_to_string(&mut text).unwrap();
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(130), "{sig} at {stage}:\n{text}");
        assert!(text.contains("interrupted") && text.contains("no result was written"), "{text}");
        let report = folder_is_what_its_report_lists(&out, &format!("{sig} at {stage}"));
        assert_eq!(report["status"], "cancelled", "{report}");
        assert_eq!(report["stages"].as_array().unwrap().len(), finished, "{sig} at {stage}: {report}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The stage a progress line names (`[  1.2 s] stage  40% message`).
fn stage_of(line: &str) -> Option<&str> {
    line.split("] ").nth(1)?.split(' ').next()
}

/// Twelve signals at seeded random moments of a run, SIGINT and SIGTERM in turn, into the folder of a
/// complete earlier run: each signal follows the run's k-th change of stage (k seeded, over every
/// change of a whole run up to DR's start) by a seeded delay of up to 0.25 s, so that it lands in the
/// run however fast the machine is at the time. Each run either stops (exit 130, report `cancelled`, no
/// `strands.hair`) or, signalled after its last write, completes (exit 0, the result whole); the folder
/// always holds exactly what its report lists and no temporary file.
#[test]
fn runs_interrupted_at_random_moments_leave_what_their_report_lists() {
    let dir = tmp("random");
    let cap = common::write_capture(&dir.join("capture"), 600, 128, 3);
    let out = dir.join("out");
    let t0 = Instant::now();
    let whole = start(&cap, &out).wait_with_output().unwrap();
    assert!(whole.status.success(), "{}", String::from_utf8_lossy(&whole.stderr));
    let full = t0.elapsed();
    let complete = std::fs::read(out.join("strands.hair")).unwrap();
    // The changes of stage of a whole run: a line whose stage is not the last line's.
    let changes = |text: &str| {
        let mut last = String::new();
        let mut n = 0;
        for stage in text.lines().filter_map(stage_of) {
            if stage != last {
                n += 1;
                last = stage.to_string();
            }
        }
        n
    };
    let total = changes(&String::from_utf8_lossy(&whole.stderr));
    assert!(total >= 5, "a whole run should go through several stages:\n{}", String::from_utf8_lossy(&whole.stderr));
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut stages_reached = std::collections::BTreeSet::new();
    let mut stopped = 0;
    for trial in 0..12 {
        // Not after the last two changes: DR's scoring and its closing line come after the run's
        // last safe point.
        let k = 1 + ((next() * (total - 2) as f64) as usize).min(total - 3);
        let delay = std::time::Duration::from_secs_f64(0.25 * next());
        let sig = if trial % 2 == 0 { "-INT" } else { "-TERM" };
        let mut child = start(&cap, &out);
        let pid = child.id();
        let err = child.stderr.take().unwrap();
        // Reads the run's log; at the k-th change of stage, waits `delay` and signals. The child is
        // reaped only after its log ends, so its pid stays its own until then.
        let reader = std::thread::spawn(move || {
            let mut text = String::new();
            let (mut last, mut seen) = (String::new(), 0);
            for line in BufReader::new(err).lines() {
                let line = line.unwrap();
                if let Some(stage) = stage_of(&line) {
                    if stage != last {
                        seen += 1;
                        last = stage.to_string();
                        if seen == k {
                            std::thread::sleep(delay);
                            signal(pid, sig);
                        }
                    }
                }
                text.push_str(&line);
                text.push('\n');
            }
            text
        });
        let text = reader.join().unwrap();
        let status = child.wait().unwrap();
        let context = format!("trial {trial}: {sig} {delay:?} after change of stage {k} of {total}");
        if let Some(stage) = text.lines().rev().find_map(stage_of) {
            stages_reached.insert(stage.to_string());
        }
        let report = folder_is_what_its_report_lists(&out, &context);
        match status.code() {
            Some(0) => {
                assert_eq!(report["status"], "complete", "{context}: {report}");
                assert_eq!(std::fs::read(out.join("strands.hair")).unwrap(), complete, "{context}");
            }
            Some(130) => {
                stopped += 1;
                assert!(text.contains("interrupted"), "{context}:\n{text}");
                match report["status"].as_str().unwrap() {
                    "cancelled" => {
                        assert!(!out.join("strands.hair").exists(), "{context}: a cancelled run left a result")
                    }
                    // Stopped while the capture was checked, before the folder was touched: the
                    // earlier run's result stands, whole.
                    "complete" => assert_eq!(std::fs::read(out.join("strands.hair")).unwrap(), complete, "{context}"),
                    other => panic!("{context}: status {other}: {report}"),
                }
            }
            other => panic!("{context}: exit {other:?}\n{text}"),
        }
    }
    eprintln!("12 signals over {total} changes of stage of a {full:?} run: {stopped} stopped it; last stages seen: {stages_reached:?}");
    // Only a delay that outlasts the last stages can find the run complete.
    assert!(stopped >= 8, "most signals should land during the run: {stopped} of 12 stopped it");
    assert!(stages_reached.len() >= 4, "signals should land in several stages: {stages_reached:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
