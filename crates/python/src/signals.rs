//! Work that runs on a thread of its own while the calling thread, with the GIL released,
//! wakes every few milliseconds to check the interpreter's signals: on Ctrl-C it asks the
//! work to stop at its next safe point ([`interrupt::request`]) and waits for it to finish
//! (a run writes its summary, an inversion its history and checkpoint). loam's own signal
//! handler is never installed in the interpreter.

use loam_driver::run::interrupt;
use pyo3::prelude::*;
use std::time::Duration;

/// How long the calling thread sleeps between two checks for a signal.
const POLL: Duration = Duration::from_millis(20);

/// `work()` on a scoped thread, with the interpreter's signals checked while it runs:
/// its result (`Err` if it panicked) and the `KeyboardInterrupt` to raise, if a signal came.
pub fn watched<T: Send>(
    py: Python<'_>,
    work: impl FnOnce() -> T + Send,
) -> (std::thread::Result<T>, Option<PyErr>) {
    interrupt::clear();
    let out = std::thread::scope(|s| {
        let running = s.spawn(work);
        let mut signal = None;
        while !running.is_finished() {
            py.detach(|| std::thread::sleep(POLL));
            if signal.is_none()
                && let Err(e) = py.check_signals()
            {
                interrupt::request();
                signal = Some(e);
            }
        }
        (running.join(), signal)
    });
    interrupt::clear();
    out
}
