//! Running a series of steps on the rayon pool with its other threads kept awake.
//!
//! A step is a chain of parallel phases (P2G, the grid, G2P) with short serial parts between
//! them (sorting the particles into blocks, the ghost folds, choosing `Δt`). When a rayon
//! worker finds no work it yields a few dozen times and then sleeps on a futex, and the next
//! phase must wake it; a series of steps called from outside the pool also hands each step to
//! it and waits to be woken. On a virtual machine a wake-up costs tens of microseconds, which
//! a step of a few hundred microseconds pays several times. rayon has no setting for how long
//! its workers spin, so [`hold`] keeps them busy itself for the length of a run: every other
//! worker runs a loop that takes the pool's pending jobs as they appear
//! ([`rayon::yield_now`]) until the run ends, as an OpenMP runtime's active wait does between
//! parallel regions. On a 2-core virtual machine (`docs/performance.md`) the friction
//! dam-break (6,000 particles) runs in 27 % less wall time, and scenes of 37,500 to 110,000
//! particles in 2–12 % less.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Idle polls of a kept worker before it pauses between them (a few milliseconds): a run
/// whose serial part is long (writing a frame) does not keep a core busy.
const POLLS_BEFORE_PAUSE: u32 = 2_000;

/// Spin-loop hints between two polls of an idle kept worker, so that its polls do not crowd
/// the cache lines of the busy workers' queues.
const SPINS_PER_POLL: u32 = 64;

/// The pause of a kept worker that has found nothing for [`POLLS_BEFORE_PAUSE`] polls.
const PAUSE: Duration = Duration::from_micros(200);

/// The longest a kept worker's job runs before it hands itself back to the pool (see
/// [`keep_awake`]).
const SLICE: Duration = Duration::from_millis(2);

/// Runs `f` (a series of steps) on a thread of the current rayon pool while the pool's other
/// threads wait for work awake instead of asleep, and returns its result. Called from a
/// thread of a pool (whose caller holds it), it runs `f` as it is.
///
/// The results do not depend on it: the parallel phases give the same bits at any thread
/// count and in any schedule.
pub fn hold<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    hold_until(Arc::new(AtomicBool::new(false)), f)
}

/// [`hold`], releasing the kept workers by setting `done` (which the kept workers share until
/// they leave).
fn hold_until<R: Send>(done: Arc<AtomicBool>, f: impl FnOnce() -> R + Send) -> R {
    let flag = Arc::clone(&done);
    let _end = EndOnDrop(done);
    if rayon::current_thread_index().is_some() {
        return f();
    }
    rayon::scope(|_| {
        if rayon::current_num_threads() < 2 {
            return f();
        }
        let caller = rayon::current_thread_index();
        rayon::spawn_broadcast(move |ctx| {
            if Some(ctx.index()) != caller {
                keep_awake(Arc::clone(&flag), 0);
            }
        });
        f()
    })
}

/// Sets the flag when dropped, so the kept workers are released when the run returns or
/// unwinds.
struct EndOnDrop(Arc<AtomicBool>);

impl Drop for EndOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

/// Takes the pool's pending jobs until `done`, pausing briefly after a long idle stretch
/// (`idle` polls found nothing so far).
///
/// The loop is a job of the pool, so a worker can also start it *inside* another job: a job
/// it stole waits for its other half, and the wait takes the next pending job, which may be
/// this loop (of this run, or of another run held at the same time from another thread). A
/// loop that ran until its run ends would then bury the stolen job under it, and a run
/// waiting for that job would never end: two runs held at once from two threads did wait on
/// each other for ever that way. So each job of the loop runs for at most [`SLICE`], then
/// queues its continuation on this worker (`rayon::spawn` from a worker pushes onto its own
/// deque, which it takes from first) and returns, and the job under it goes on.
fn keep_awake(done: Arc<AtomicBool>, mut idle: u32) {
    let start = Instant::now();
    while !done.load(Ordering::Acquire) {
        if start.elapsed() >= SLICE {
            rayon::spawn(move || keep_awake(done, idle));
            return;
        }
        match rayon::yield_now() {
            Some(rayon::Yield::Executed) => idle = 0,
            _ if idle < POLLS_BEFORE_PAUSE => {
                idle += 1;
                for _ in 0..SPINS_PER_POLL {
                    std::hint::spin_loop();
                }
            }
            _ => std::thread::sleep(PAUSE),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    /// Waits until no kept worker holds `done` any more (each holds the broadcast's clone
    /// until it leaves), failing after `limit`.
    fn released(done: &Arc<AtomicBool>, limit: Duration) -> bool {
        let start = Instant::now();
        while Arc::strong_count(done) > 1 {
            if start.elapsed() > limit {
                return false;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        true
    }

    #[test]
    fn a_held_run_gives_the_result_of_the_plain_one_and_releases_the_workers() {
        let sum = |n: u64| (0..n).into_par_iter().map(|i| i * i).sum::<u64>();
        let done = Arc::new(AtomicBool::new(false));
        let held = hold_until(Arc::clone(&done), || (1..200).map(sum).collect::<Vec<_>>());
        let plain: Vec<_> = (1..200).map(sum).collect();
        assert_eq!(held, plain);
        assert!(done.load(Ordering::Acquire));
        // A kept worker polls the flag between jobs and pauses at most `PAUSE`; a second is
        // several thousand times that.
        assert!(released(&done, Duration::from_secs(1)));
    }

    /// Runs held at once from two threads outside the pool (as concurrent tests hold them),
    /// with plain parallel loops from a third thread besides: many short runs of a few
    /// parallel phases each (nested joins), so that runs start and end while the other
    /// thread's kept workers are busy. Every run finishes with the sums of the plain loops.
    #[test]
    fn runs_held_at_once_from_several_threads_all_finish() {
        let phase = |seed: u64| {
            (0..4_000u32)
                .into_par_iter()
                .with_min_len(64)
                .map(|i| (u64::from(i) ^ seed).wrapping_mul(2_654_435_761) % 1_000)
                .sum::<u64>()
        };
        let work = move |seed: u64, held: bool| {
            (0..2_000u64)
                .map(|r| {
                    let run = || (0..4).map(|k| phase(seed + r + k)).sum::<u64>();
                    if held { hold(run) } else { run() }
                })
                .sum::<u64>()
        };
        let expected: Vec<u64> = (0..3).map(|seed| work(seed, false)).collect();
        let (tx, rx) = std::sync::mpsc::channel();
        for seed in 0..3u64 {
            let tx = tx.clone();
            std::thread::spawn(move || {
                tx.send((seed, work(seed, seed != 2)))
                    .expect("the test waits");
            });
        }
        let mut got = [None; 3];
        for _ in 0..3 {
            // The runs take a second or two; a minute means they wait on each other for ever.
            let (seed, sum) = rx
                .recv_timeout(Duration::from_secs(60))
                .expect("every run finishes (no deadlock between held runs)");
            got[seed as usize] = Some(sum);
        }
        assert_eq!(got.map(|g| g.expect("a result")).to_vec(), expected);
    }

    #[test]
    fn a_run_that_panics_releases_the_workers() {
        let done = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&done);
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            hold_until(flag, || panic!("a step failed"))
        }));
        assert!(outcome.is_err());
        assert!(done.load(Ordering::Acquire));
        assert!(released(&done, Duration::from_secs(1)));
    }
}
