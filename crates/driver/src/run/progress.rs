//! Progress of an explicit run: a bar when stderr is a terminal, otherwise a plain line on
//! stderr every few seconds (so the log of a long run shows where it is), or nothing with
//! `--quiet`.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// How progress is shown.
pub enum Progress {
    /// Nothing (`--quiet`).
    Hidden,
    /// An indicatif bar, redrawn at most every 0.1 s.
    Bar { bar: ProgressBar, last: Instant },
    /// A line `progress: ...` every `every`.
    Lines { every: Duration, last: Instant },
}

impl Progress {
    /// The display for this process: hidden when `quiet`, a bar when stderr is a terminal,
    /// else lines every `every_s` seconds.
    pub fn new(quiet: bool, every_s: f64) -> Self {
        if quiet {
            return Self::Hidden;
        }
        if std::io::stderr().is_terminal() {
            let bar = ProgressBar::new(1000);
            bar.set_style(
                ProgressStyle::with_template("{bar:40.cyan/blue} {percent:>3}% {msg}")
                    .expect("static template is valid"),
            );
            return Self::Bar {
                bar,
                last: Instant::now(),
            };
        }
        Self::Lines {
            every: Duration::from_secs_f64(every_s.max(0.0)),
            last: Instant::now(),
        }
    }

    /// Reports step `step` at simulated time `time` of `end`, `wall` seconds into the run,
    /// which started at step and time `from` (`(0, 0)` unless resumed): the rate and the time
    /// left count only this run's steps (drawn only when the last report is old enough).
    pub fn update(&mut self, step: usize, time: f64, end: f64, wall: f64, from: (usize, f64)) {
        let frac = (time / end).clamp(0.0, 1.0);
        let rate = step.saturating_sub(from.0) as f64 / wall.max(1e-9);
        let done = ((time - from.1) / (end - from.1)).clamp(0.0, 1.0);
        let eta = if done > 0.0 {
            wall * (1.0 - done) / done
        } else {
            f64::NAN
        };
        let msg =
            format!("t = {time:.4e} / {end:.4e} s, step {step}, {rate:.0} steps/s, ETA {eta:.0} s");
        match self {
            Self::Hidden => {}
            Self::Bar { bar, last } => {
                if last.elapsed() > Duration::from_millis(100) {
                    *last = Instant::now();
                    bar.set_position((frac * 1000.0) as u64);
                    bar.set_message(msg);
                }
            }
            Self::Lines { every, last } => {
                if last.elapsed() >= *every {
                    *last = Instant::now();
                    eprintln!("progress: {:3.0} %, {msg}", 100.0 * frac);
                }
            }
        }
    }

    /// Clears the bar.
    pub fn finish(self) {
        if let Self::Bar { bar, .. } = self {
            bar.finish_and_clear();
        }
    }
}
