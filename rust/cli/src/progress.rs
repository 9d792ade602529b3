//! Progress bars shared by the long subcommands (indicatif; hidden when stderr is not a terminal).

use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use hairrecon_recon::progress::Progress;
use indicatif::{ProgressBar, ProgressStyle};

use crate::interrupt::Interrupt;

/// A progress bar for `len` steps of a named stage.
pub fn bar(len: u64, stage: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{prefix:>12} [{bar:30}] {pos}/{len} {msg} ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb.set_prefix(stage.to_string());
    pb
}

/// One indicatif bar per stage, replaced when the stage changes. When stderr is not a terminal
/// (a log file, a pipe), the bars are hidden and a plain line goes to stderr when the stage changes
/// and then at most every [`LOG_EVERY`].
pub struct Bars {
    pub interrupt: Interrupt,
    current: Mutex<Option<(String, ProgressBar)>>,
    log: Option<Mutex<(String, Instant)>>,
    start: Instant,
}

const LOG_EVERY: Duration = Duration::from_secs(10);

impl std::fmt::Debug for Bars {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Bars")
    }
}

const STEPS: u64 = 1000;

impl Progress for Bars {
    fn update(&self, stage: &str, fraction: f32, message: &str) {
        if let Some(log) = &self.log {
            let Ok(mut last) = log.lock() else { return };
            if last.0 != stage || last.1.elapsed() >= LOG_EVERY {
                let t = self.start.elapsed().as_secs_f64();
                eprintln!("[{t:7.1} s] {stage} {:3.0}% {message}", 100.0 * fraction.clamp(0.0, 1.0));
                *last = (stage.to_string(), Instant::now());
            }
            return;
        }
        let Ok(mut cur) = self.current.lock() else { return };
        if cur.as_ref().is_none_or(|(s, _)| s != stage) {
            if let Some((_, pb)) = cur.take() {
                pb.set_position(STEPS);
                pb.finish();
            }
            *cur = Some((stage.to_string(), bar(STEPS, stage)));
        }
        if let Some((_, pb)) = cur.as_ref() {
            pb.set_position((fraction.clamp(0.0, 1.0) * STEPS as f32) as u64);
            pb.set_message(message.to_string());
        }
    }
    fn cancelled(&self) -> bool {
        self.interrupt.requested()
    }
}

impl Bars {
    /// Bars on a terminal, else log lines on stderr; cancelled by SIGINT/SIGTERM.
    pub fn new() -> Self {
        let log = (!std::io::stderr().is_terminal()).then(|| Mutex::new((String::new(), Instant::now())));
        Self { interrupt: Interrupt::listen(), current: Mutex::new(None), log, start: Instant::now() }
    }

    /// Ends the current bar.
    pub fn finish(&self) {
        if let Ok(mut cur) = self.current.lock() {
            if let Some((_, pb)) = cur.take() {
                pb.set_position(STEPS);
                pb.finish();
            }
        }
    }
}
