//! SIGINT, SIGTERM and SIGHUP (the `ctrlc` crate, whose handler runs on a thread of its own, not
//! in signal context, so it may print and remove files).
//!
//! A command that can stop at a safe point (`reconstruct`, through [`Interrupt::listen`]) is asked to:
//! its stages check the flag, the current write finishes (every output goes through a temporary
//! file and a rename), and the command ends with [`Interrupt::exit`]. Any other command, or a
//! second signal, removes the temporary files of the writes under way and exits at once. Either
//! way the exit code is 130 (128 + SIGINT), which shells read as an interrupt.

use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};

/// The exit code of an interrupted command.
pub const EXIT_CODE: i32 = 130;

/// Whether a command listens for the flag; how many signals came.
static COOPERATIVE: AtomicBool = AtomicBool::new(false);
static SIGNALS: AtomicU8 = AtomicU8::new(0);

/// Installs the handler (once, at the start of `main`).
pub fn install() {
    let handler = || {
        let n = SIGNALS.fetch_add(1, Ordering::SeqCst);
        if n == 0 && COOPERATIVE.load(Ordering::SeqCst) {
            eprintln!("\nhairrecon: interrupted; stopping after the current write (interrupt again to stop at once)");
            return;
        }
        let removed = hairrecon_core::formats::remove_temporaries();
        eprintln!("\nhairrecon: interrupted; stopped at once ({removed} unfinished file(s) removed)");
        std::process::exit(EXIT_CODE);
    };
    if let Err(e) = ctrlc::set_handler(handler) {
        eprintln!("hairrecon: warning: cannot handle SIGINT/SIGTERM ({e}); an interrupt may leave temporary files");
    }
}

/// The interrupt as seen by a command that stops at safe points.
#[derive(Debug)]
pub struct Interrupt;

impl Interrupt {
    /// From now on, the first signal only sets the flag.
    pub fn listen() -> Self {
        COOPERATIVE.store(true, Ordering::SeqCst);
        Self
    }

    /// Whether a signal came.
    pub fn requested(&self) -> bool {
        SIGNALS.load(Ordering::SeqCst) > 0
    }

    /// Ends the process after a signal, with `message` on stderr.
    pub fn exit(&self, message: &str) -> ! {
        eprintln!("hairrecon: interrupted: {message}");
        std::process::exit(EXIT_CODE)
    }
}
