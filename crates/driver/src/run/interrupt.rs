//! Ctrl-C (SIGINT), SIGTERM and SIGHUP end a run cleanly: the handler only raises a flag,
//! which the run loops read between steps; they stop there, drop the frame in progress and
//! write the summary with the status `interrupted`. A second signal ends the process at once
//! (exit 130): every file is written through a temporary name and a rename, so even then no
//! file is left half-written.
//!
//! A front end whose host owns the signals (the Python package: the interpreter turns
//! SIGINT into `KeyboardInterrupt`) calls [`leave_signals_to_front_end`] once; [`install`]
//! then installs no handler, and the front end raises the flag itself with [`request`] when
//! it sees a signal, and lowers it with [`clear`] before the next run.

use std::sync::atomic::{AtomicBool, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Whether the front end receives the signals itself ([`leave_signals_to_front_end`]).
static FRONT_END: AtomicBool = AtomicBool::new(false);

/// The exit code of an interrupted run (128 + SIGINT, the shells' convention).
pub const EXIT_CODE: u8 = 130;

/// Installs the handler (once per process), unless the front end receives the signals
/// itself.
pub fn install() -> Result<(), String> {
    if FRONT_END.load(Ordering::SeqCst) {
        return Ok(());
    }
    ctrlc::set_handler(|| {
        if REQUESTED.swap(true, Ordering::SeqCst) {
            std::process::exit(i32::from(EXIT_CODE));
        }
    })
    .map_err(|e| format!("cannot install the signal handler: {e}"))
}

/// From now on the front end receives the signals and reports them with [`request`]: no
/// handler is installed by [`install`].
pub fn leave_signals_to_front_end() {
    FRONT_END.store(true, Ordering::SeqCst);
}

/// Asks the run in progress to stop after its current step, as a signal does.
pub fn request() {
    REQUESTED.store(true, Ordering::SeqCst);
}

/// Withdraws a request ([`request`]), so that the next run goes to its end.
pub fn clear() {
    REQUESTED.store(false, Ordering::SeqCst);
}

/// Whether a signal asked the run to stop.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed)
}
