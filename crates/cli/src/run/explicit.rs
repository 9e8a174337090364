//! Explicit runs: step to each frame time with a progress bar.

use super::Recorder;
use super::checkpoint::Checkpointer;
use crate::Outcome;
use indicatif::{ProgressBar, ProgressStyle};
use loam_core::Particles;
use loam_explicit::{Config, Solver};
use loam_scene::{Built, ExplicitPlan};
use std::time::{Duration, Instant};

/// The saved state a resumed run starts from.
pub struct Restart<const D: usize> {
    /// The particles.
    pub particles: Particles<f64, D>,
    /// Simulated time.
    pub time: f64,
    /// Steps completed.
    pub steps: usize,
}

/// Runs an explicit scene, from its initial state or from `restart`, saving the state with
/// `checkpoints` if given.
pub fn run<const D: usize>(
    built: Built<D>,
    plan: ExplicitPlan,
    mut rec: Recorder<D>,
    quiet: bool,
    mut checkpoints: Option<Checkpointer>,
    restart: Option<Restart<D>>,
) -> Outcome {
    let frame_times = built.frame_times();
    let config = Config {
        grid: built.grid.clone(),
        shape: built.shape,
        transfer: plan.transfer,
        scheme: plan.scheme,
        boundary: built.boundary,
        contact: built.contact.clone(),
        gravity: built.gravity,
        materials: built.materials.clone(),
        time_step: plan.time_step,
    };
    let (mut particles, clock) = match restart {
        None => (built.particles, None),
        Some(r) => (r.particles, Some((r.time, r.steps))),
    };
    let mut solver = match Solver::new(config, &particles) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    if let Some((time, steps)) = clock {
        solver.set_clock(time, steps);
    }
    rec.summary.end_time = plan.end_time;
    let bar = progress_bar(quiet);
    let start = Instant::now();
    let mut last_draw = Instant::now();
    let mut failure = None;
    // A resumed run continues after the frames it kept.
    let first = rec.frames_written();
    for (k, &t) in frame_times.iter().enumerate().skip(first) {
        if k > 0 {
            let summary = &mut rec.summary;
            let result = solver.advance_to(&mut particles, t, |info, p| {
                summary.dt_min = summary.dt_min.min(info.dt);
                summary.dt_max = summary.dt_max.max(info.dt);
                if let Some(c) = checkpoints.as_mut() {
                    c.after_step(info.step, info.time, p);
                }
                if last_draw.elapsed() > Duration::from_millis(100) {
                    last_draw = Instant::now();
                    draw(
                        &bar,
                        info.step,
                        info.time,
                        plan.end_time,
                        start.elapsed().as_secs_f64(),
                    );
                }
            });
            if let Err(e) = result {
                failure = Some(e.to_string());
                break;
            }
            if let Some(e) = checkpoints.as_ref().and_then(Checkpointer::failure) {
                failure = Some(e.to_owned());
                break;
            }
        }
        if let Err(e) = rec.frame(solver.steps(), solver.time(), &particles) {
            failure = Some(e);
            break;
        }
    }
    bar.finish_and_clear();
    rec.summary.checkpoint = checkpoints.and_then(|c| c.last);
    let wall = start.elapsed().as_secs_f64();
    let steps = solver.steps();
    let (first_step, resumed) = match clock {
        Some((time, step)) => (step, format!("resumed at step {step} (t = {time:.4} s), ")),
        None => (0, String::new()),
    };
    let done = format!(
        "{resumed}{steps} steps to t = {:.4} s in {wall:.2} s ({:.3e} particle-steps/s, {} \
         particles)",
        solver.time(),
        (steps - first_step) as f64 * particles.len() as f64 / wall.max(1e-9),
        particles.len()
    );
    rec.finish(steps, solver.time(), wall, failure, &done)
}

fn progress_bar(quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(1000);
    bar.set_style(
        ProgressStyle::with_template("{bar:40.cyan/blue} {percent:>3}% {msg}")
            .expect("static template is valid"),
    );
    bar
}

fn draw(bar: &ProgressBar, step: usize, time: f64, end: f64, wall: f64) {
    let frac = (time / end).clamp(0.0, 1.0);
    bar.set_position((frac * 1000.0) as u64);
    let rate = step as f64 / wall.max(1e-9);
    let eta = if frac > 0.0 {
        wall * (1.0 - frac) / frac
    } else {
        f64::NAN
    };
    bar.set_message(format!(
        "t = {time:.4e} / {end:.4e} s, step {step}, {rate:.0} steps/s, ETA {eta:.0} s"
    ));
}
