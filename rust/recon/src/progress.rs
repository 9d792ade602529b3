//! Progress reporting and cancellation for long stages.
//!
//! A stage calls [`Progress::update`] now and then, and [`Progress::cancelled`] at safe points; when
//! cancelled it stops and returns [`Cancelled`] (wrapped in its own error type) without writing
//! partial output. The CLI shows a progress bar, the Python module an atomic value that Blender
//! polls; neither calls back into Python from worker threads.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Mutex;

/// The operation was cancelled by the user.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("cancelled by the user")]
pub struct Cancelled;

/// Receives progress from a running stage. Must be cheap and thread-safe.
pub trait Progress: Sync {
    /// `stage` names the current stage; `fraction` in [0, 1] is its progress; `message` is
    /// free text such as the current loss.
    fn update(&self, stage: &str, fraction: f32, message: &str);
    /// Whether the user asked to stop.
    fn cancelled(&self) -> bool {
        false
    }
    /// `Err(Cancelled)` when the user asked to stop: `progress.check()?` at safe points.
    fn check(&self) -> Result<(), Cancelled> {
        if self.cancelled() {
            Err(Cancelled)
        } else {
            Ok(())
        }
    }
}

/// Progress that goes nowhere and is never cancelled.
#[derive(Debug, Default, Clone, Copy)]
pub struct NoProgress;

impl Progress for NoProgress {
    fn update(&self, _stage: &str, _fraction: f32, _message: &str) {}
}

/// Progress held in shared state: polled from another thread (the Blender add-on's timer), and
/// cancelled by setting a flag.
#[derive(Debug, Default)]
pub struct SharedProgress {
    fraction_bits: AtomicU32,
    cancel: AtomicBool,
    text: Mutex<String>,
}

impl SharedProgress {
    pub fn new() -> Self {
        Self::default()
    }
    /// Asks the running work to stop at its next safe point.
    pub fn request_cancel(&self) {
        self.cancel.store(true, Ordering::SeqCst);
    }
    /// The latest (fraction, "stage: message") pair.
    pub fn snapshot(&self) -> (f32, String) {
        let f = f32::from_bits(self.fraction_bits.load(Ordering::Relaxed));
        let text = self.text.lock().map(|t| t.clone()).unwrap_or_default();
        (f, text)
    }
}

impl Progress for SharedProgress {
    fn update(&self, stage: &str, fraction: f32, message: &str) {
        self.fraction_bits.store(fraction.clamp(0.0, 1.0).to_bits(), Ordering::Relaxed);
        if let Ok(mut t) = self.text.lock() {
            t.clear();
            t.push_str(stage);
            if !message.is_empty() {
                t.push_str(": ");
                t.push_str(message);
            }
        }
    }
    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::SeqCst)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_progress_reports_and_cancels() {
        let p = SharedProgress::new();
        p.update("orient2d", 0.25, "view 4/16");
        assert_eq!(p.snapshot(), (0.25, "orient2d: view 4/16".to_string()));
        assert_eq!(p.check(), Ok(()));
        p.request_cancel();
        assert_eq!(p.check(), Err(Cancelled));
    }
}
