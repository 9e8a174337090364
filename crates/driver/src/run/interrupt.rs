//! Ctrl-C (SIGINT), SIGTERM and SIGHUP end a run cleanly: the handler only raises a flag,
//! which the run loops read between steps; they stop there, drop the frame in progress and
//! write the summary with the status `interrupted`. A second signal ends the process at once
//! (exit 130): every file is written through a temporary name and a rename, so even then no
//! file is left half-written.

use std::sync::atomic::{AtomicBool, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// The exit code of an interrupted run (128 + SIGINT, the shells' convention).
pub const EXIT_CODE: u8 = 130;

/// Installs the handler (once per process).
pub fn install() -> Result<(), String> {
    ctrlc::set_handler(|| {
        if REQUESTED.swap(true, Ordering::SeqCst) {
            std::process::exit(i32::from(EXIT_CODE));
        }
    })
    .map_err(|e| format!("cannot install the signal handler: {e}"))
}

/// Whether a signal asked the run to stop.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed)
}
