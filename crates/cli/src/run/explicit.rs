//! Explicit runs: step to each frame, with a progress display.
//!
//! With a fixed step the frames are tied to steps ([`Built::frame_steps`]): the run makes
//! `round(end_time / dt)` steps, none of them shortened. With an adaptive step the frames are
//! at their times ([`Built::frame_times`]), the step before each shortened to end on it.

use super::progress::Progress;
use super::{Options, Stop, Target, interrupt};
use crate::Outcome;
use crate::preflight;
use loam_core::Particles;
use loam_explicit::Solver;
use loam_scene::output::RunSummary;
use loam_scene::{Built, ExplicitPlan};
use std::time::Instant;

/// Where a frame is written: after a step (fixed step) or at a time (adaptive step).
#[derive(Clone, Copy)]
enum FrameAt {
    Step(usize),
    Time(f64),
}

/// When the run started and the simulated time it ends at, for the progress display.
#[derive(Clone, Copy)]
struct Clock {
    start: Instant,
    end: f64,
}

/// Steps until the frame point `at` is reached, recording the step sizes in `summary`; stops
/// on an error or a signal (checked before every step).
fn step_to<const D: usize>(
    solver: &mut Solver<f64, D>,
    particles: &mut Particles<f64, D>,
    at: FrameAt,
    summary: &mut RunSummary,
    progress: &mut Progress,
    clock: Clock,
) -> Result<(), Stop> {
    loop {
        if interrupt::requested() {
            return Err(Stop::Interrupted);
        }
        let cap = match at {
            FrameAt::Step(s) => (solver.steps() < s).then_some(f64::INFINITY),
            FrameAt::Time(t) => solver.next_step_cap(t),
        };
        let Some(cap) = cap else { return Ok(()) };
        let info = solver
            .step(particles, cap)
            .map_err(|e| Stop::Failed(e.to_string()))?;
        summary.dt_min = summary.dt_min.min(info.dt);
        summary.dt_max = summary.dt_max.max(info.dt);
        let wall = clock.start.elapsed().as_secs_f64();
        progress.update(info.step, info.time, clock.end, wall);
    }
}

/// Runs an explicit scene.
pub fn run<const D: usize>(
    built: Built<D>,
    plan: ExplicitPlan,
    target: Target,
    options: &Options,
) -> Outcome {
    let frames: Vec<FrameAt> = match plan.fixed_steps() {
        Some(_) => built.frame_steps().into_iter().map(FrameAt::Step).collect(),
        None => built.frame_times().into_iter().map(FrameAt::Time).collect(),
    };
    let mut solver = match Solver::new(
        built.explicit_config().expect("an explicit plan"),
        &built.particles,
    ) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    let warnings = match preflight::explicit(&built, &plan, &solver, &built.particles) {
        Ok(w) => w,
        Err(msg) => {
            eprintln!("error: {}: {msg}", target.scene.display());
            return Outcome::BadInput;
        }
    };
    for w in &warnings {
        eprintln!("warning: {}: {w}", target.scene.display());
    }
    let mut rec = match target.recorder(&built) {
        Ok(r) => r,
        Err(outcome) => return outcome,
    };
    rec.summary.warnings.extend(warnings);
    rec.summary.end_time = plan.end_time;
    let mut particles = built.particles;
    let mut progress = Progress::new(options.quiet, options.progress_every);
    let start = Instant::now();
    let mut stop = None;
    for (k, &at) in frames.iter().enumerate() {
        if k > 0 {
            let clock = Clock {
                start,
                end: plan.end_time,
            };
            let stepped = step_to(
                &mut solver,
                &mut particles,
                at,
                &mut rec.summary,
                &mut progress,
                clock,
            );
            if let Err(e) = stepped {
                stop = Some(e);
                break;
            }
        }
        if let Err(e) = rec.frame(solver.steps(), solver.time(), &particles) {
            stop = Some(e);
            break;
        }
    }
    progress.finish();
    let wall = start.elapsed().as_secs_f64();
    let steps = solver.steps();
    let done = format!(
        "{steps} steps to t = {:.4} s in {wall:.2} s ({:.3e} particle-steps/s, {} particles)",
        solver.time(),
        steps as f64 * particles.len() as f64 / wall.max(1e-9),
        particles.len()
    );
    rec.finish(steps, solver.time(), wall, stop, &done)
}
