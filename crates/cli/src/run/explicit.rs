//! Explicit runs: step to each frame time with a progress bar.

use super::Recorder;
use crate::Outcome;
use indicatif::{ProgressBar, ProgressStyle};
use loam_explicit::Solver;
use loam_scene::{Built, ExplicitPlan};
use std::time::{Duration, Instant};

/// Runs an explicit scene.
pub fn run<const D: usize>(
    built: Built<D>,
    plan: ExplicitPlan,
    mut rec: Recorder<D>,
    quiet: bool,
) -> Outcome {
    let frame_times = built.frame_times();
    let config = built
        .explicit_config()
        .expect("an explicit plan has an explicit configuration");
    let mut particles = built.particles;
    let mut solver = match Solver::new(config, &particles) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    rec.summary.end_time = plan.end_time;
    let bar = progress_bar(quiet);
    let start = Instant::now();
    let mut last_draw = Instant::now();
    let mut failure = None;
    for (k, &t) in frame_times.iter().enumerate() {
        if k > 0 {
            let summary = &mut rec.summary;
            let result = solver.advance_to(&mut particles, t, |info, _| {
                summary.dt_min = summary.dt_min.min(info.dt);
                summary.dt_max = summary.dt_max.max(info.dt);
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
        }
        if let Err(e) = rec.frame(solver.steps(), solver.time(), &particles) {
            failure = Some(e);
            break;
        }
    }
    bar.finish_and_clear();
    let wall = start.elapsed().as_secs_f64();
    let steps = solver.steps();
    let done = format!(
        "{steps} steps to t = {:.4} s in {wall:.2} s ({:.3e} particle-steps/s, {} particles)",
        solver.time(),
        steps as f64 * particles.len() as f64 / wall.max(1e-9),
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
