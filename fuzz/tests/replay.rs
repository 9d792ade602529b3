//! Every committed fuzzing input, seeds and corpus (with the inputs of past findings), through its
//! harness: a reader that panics on one of them again fails here, on every `cargo test`, without the
//! coverage-instrumented build that `scripts/fuzz.sh` needs to look for new ones.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use hairrecon_fuzz::{remove_scratch, TARGETS};

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).to_path_buf()
}

fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    out.sort();
    out
}

/// Replays one target's seeds and corpus; returns how many inputs it read.
fn replay(name: &str) -> usize {
    let (_, harness) = TARGETS.iter().find(|(n, _)| *n == name).unwrap();
    let mut count = 0;
    for kind in ["seeds", "corpus"] {
        for path in files(&fuzz_dir().join(kind).join(name)) {
            let bytes = std::fs::read(&path).unwrap();
            let start = Instant::now();
            let outcome = std::panic::catch_unwind(|| harness(&bytes));
            let took = start.elapsed();
            assert!(outcome.is_ok(), "{name}: the reader panicked on {}", path.display());
            // libFuzzer's run allows 10 s an input; a committed input is far under it
            assert!(took < Duration::from_secs(10), "{name}: {} took {took:?}", path.display());
            count += 1;
        }
    }
    remove_scratch();
    count
}

#[test]
fn every_seed_and_corpus_folder_has_a_harness_and_inputs() {
    for kind in ["seeds", "corpus"] {
        let mut names: Vec<String> = std::fs::read_dir(fuzz_dir().join(kind))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        let mut want: Vec<&str> = TARGETS.iter().map(|(n, _)| *n).collect();
        want.sort();
        assert_eq!(names, want, "fuzz/{kind}/ and the harnesses differ");
    }
    for (name, _) in TARGETS {
        assert!(!files(&fuzz_dir().join("seeds").join(name)).is_empty(), "no seed for {name}");
    }
}

#[test]
fn every_committed_input_replays_through_its_reader() {
    for (name, _) in TARGETS {
        let n = replay(name);
        assert!(n > 1, "{name} replayed {n} inputs");
    }
}
