//! Explicit runs: step to each frame, with a progress display.
//!
//! With a fixed step the frames are tied to steps ([`Built::frame_steps`]): the run makes
//! `round(end_time / dt)` steps, none of them shortened. With an adaptive step the frames are
//! at their times ([`Built::frame_times`]), the step before each shortened to end on it.
//!
//! A resumed run starts from the saved particles and clock and goes through the same loop,
//! from the first frame point after the frames it kept.
//!
//! On the GPU ([`super::gpu`]) the same checks run first, on the CPU solver's view of the
//! initial state, and the same loop writes the frames; the particles come back from the
//! device at each frame.

use super::checkpoint::Checkpointer;
use super::progress::Progress;
use super::{Options, Start, Stop, Target, gpu, interrupt};
use crate::Outcome;
use crate::preflight;
use loam_core::Particles;
use loam_explicit::Solver;
use loam_scene::output::RunSummary;
use loam_scene::{Built, Device, ExplicitPlan};
use std::time::Instant;

/// Where a frame is written: after a step (fixed step) or at a time (adaptive step).
#[derive(Clone, Copy)]
pub enum FrameAt {
    /// After this step.
    Step(usize),
    /// At this simulated time.
    Time(f64),
}

/// When the run started, the step and simulated time it started from (`(0, 0)` unless
/// resumed) and the simulated time it ends at, for the progress display.
#[derive(Clone, Copy)]
struct Clock {
    start: Instant,
    from: (usize, f64),
    end: f64,
}

/// Steps until the frame point `at` is reached, recording the step sizes in `summary` and
/// saving the state with `checkpoints`; stops on an error (a failed checkpoint included) or a
/// signal (checked before every step, after the test for the frame point).
///
/// The loop runs on a thread of the rayon pool with the other workers kept
/// awake ([`loam_explicit::pool::hold`]): each step starts its parallel phases from inside the
/// pool instead of handing itself over to it, and none of them waits for a worker to wake.
fn step_to<const D: usize>(
    solver: &mut Solver<f64, D>,
    particles: &mut Particles<f64, D>,
    at: FrameAt,
    summary: &mut RunSummary,
    mut checkpoints: Option<&mut Checkpointer>,
    progress: &mut Progress,
    clock: Clock,
) -> Result<(), Stop> {
    loam_explicit::pool::hold(|| {
        loop {
            let cap = match at {
                FrameAt::Step(s) => (solver.steps() < s).then_some(f64::INFINITY),
                FrameAt::Time(t) => solver.next_step_cap(t),
            };
            // A frame whose steps are all done is written before a signal is looked at, so the
            // frame at a checkpoint's step is never dropped while the checkpoint is kept.
            let Some(cap) = cap else { return Ok(()) };
            if interrupt::requested() {
                return Err(Stop::Interrupted);
            }
            let info = solver
                .step(particles, cap)
                .map_err(|e| Stop::Failed(e.to_string()))?;
            summary.dt_min = summary.dt_min.min(info.dt);
            summary.dt_max = summary.dt_max.max(info.dt);
            if let Some(c) = checkpoints.as_deref_mut() {
                c.after_step(info.step, info.time, particles)
                    .map_err(Stop::Failed)?;
            }
            let wall = clock.start.elapsed().as_secs_f64();
            progress.update(info.step, info.time, clock.end, wall, clock.from);
        }
    })
}

/// The solver that takes the steps: the CPU solver on the run's particles, or the GPU solver
/// with the particles on the device.
enum Engine<const D: usize> {
    Cpu(Box<Solver<f64, D>>),
    Gpu(Box<loam_gpu::GpuSolver<D>>),
}

impl<const D: usize> Engine<D> {
    fn steps(&self) -> usize {
        match self {
            Self::Cpu(s) => s.steps(),
            Self::Gpu(s) => s.steps(),
        }
    }

    fn time(&self) -> f64 {
        match self {
            Self::Cpu(s) => s.time(),
            Self::Gpu(s) => s.time(),
        }
    }

    /// Steps to the frame point `at`, leaving the state of the frame in `particles`.
    fn step_to(
        &mut self,
        particles: &mut Particles<f64, D>,
        at: FrameAt,
        summary: &mut RunSummary,
        checkpoints: Option<&mut Checkpointer>,
        progress: &mut Progress,
        clock: Clock,
    ) -> Result<(), Stop> {
        match (self, at) {
            (Self::Cpu(s), _) => step_to(s, particles, at, summary, checkpoints, progress, clock),
            (Self::Gpu(s), _) => {
                gpu::step_to(s, particles, at, summary, checkpoints, |step, time| {
                    let wall = clock.start.elapsed().as_secs_f64();
                    progress.update(step, time, clock.end, wall, clock.from);
                })
            }
        }
    }
}

/// Runs an explicit scene, from its initial state or from the checkpoint in `start`, saving
/// its state as `start` asks. The checks before the run are those of the initial state, so a
/// resumed run is refused or warned about exactly when the fresh run was.
pub fn run<const D: usize>(
    built: Built<D>,
    plan: ExplicitPlan,
    target: Target,
    options: &Options,
    start: Start,
) -> Outcome {
    let restart = match &start.resume {
        None => None,
        Some(r) => match r.particles::<D>(built.particles.len()) {
            Ok(p) => Some((p, r.header.time, r.header.step as usize)),
            Err(e) => {
                eprintln!("error: {e}");
                return Outcome::BadInput;
            }
        },
    };
    let config = built.explicit_config().expect("an explicit plan");
    let solver = Solver::new(
        config.clone(),
        restart.as_ref().map_or(&built.particles, |r| &r.0),
    );
    let solver = match solver {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    let checked = preflight::explicit(&built, &plan, &solver, &built.particles, options.max_steps);
    let warnings = match checked {
        Ok(w) => w,
        Err(msg) => {
            eprintln!("error: {}: {msg}", target.scene.display());
            return Outcome::BadInput;
        }
    };
    for w in &warnings {
        eprintln!("warning: {}: {w}", target.scene.display());
    }
    // After the checks, which bound the steps and so the frames.
    let frames: Vec<FrameAt> = match plan.fixed_steps() {
        Some(_) => built.frame_steps().into_iter().map(FrameAt::Step).collect(),
        None => built.frame_times().into_iter().map(FrameAt::Time).collect(),
    };
    let device = options.device.unwrap_or(plan.device);
    if device == Device::Cpu && options.p2g.is_some() {
        eprintln!(
            "error: {}: --p2g chooses the GPU's transfer; this run is on the CPU (add --device \
             gpu, or set solver.device = \"gpu\")",
            target.scene.display()
        );
        return Outcome::BadInput;
    }
    let mut engine = match device {
        Device::Cpu => Engine::Cpu(Box::new(solver)),
        Device::Gpu => {
            drop(solver);
            let from = restart.as_ref().map_or(&built.particles, |r| &r.0);
            let mut solver = match gpu::open(&config, from, options.p2g) {
                Ok(s) => s,
                Err(outcome) => return outcome,
            };
            if let Some((_, time, steps)) = &restart
                && let Err(e) = solver.set_clock(*time, *steps)
            {
                eprintln!("error: {e}");
                return Outcome::BadInput;
            }
            Engine::Gpu(Box::new(solver))
        }
    };
    let rec = match &start.resume {
        None => target.recorder(&built),
        Some(r) => target.resumed_recorder(&built, r),
    };
    let mut rec = match rec {
        Ok(r) => r,
        Err(outcome) => return outcome,
    };
    rec.summary.warnings.extend(warnings);
    rec.summary.end_time = plan.end_time;
    // The obstacles' forces: measured by the CPU solver, from the clock the run starts at.
    let obstacles: Vec<[f64; D]> = (config.contact.obstacles.iter())
        .map(|o| std::array::from_fn(|a| o.velocity[a]))
        .collect();
    if !obstacles.is_empty() && matches!(engine, Engine::Gpu(_)) {
        let note = "the obstacles' forces (obstacle_forces.csv) are measured by CPU runs only";
        eprintln!("note: {}: {note}", target.scene.display());
        rec.summary.warnings.push(note.to_string());
    }
    let mut checkpoints = match start.checkpoints {
        None => None,
        Some((text, every)) => {
            match Checkpointer::create(&target.dir, target.scene, &text, every) {
                Ok(c) => Some(c),
                Err(e) => {
                    eprintln!("error: {e}");
                    return Outcome::Failed;
                }
            }
        }
    };
    let (mut particles, from) = match restart {
        None => (built.particles, (0, 0.0)),
        Some((particles, time, steps)) => {
            // (The GPU solver's clock was set when it was opened.)
            if let Engine::Cpu(solver) = &mut engine {
                solver.set_clock(time, steps);
            }
            (particles, (steps, time))
        }
    };
    let mut progress = Progress::new(options.quiet, options.progress_every);
    let clock = Clock {
        start: Instant::now(),
        from,
        end: plan.end_time,
    };
    let mut stop = None;
    if let Engine::Cpu(solver) = &engine
        && !obstacles.is_empty()
    {
        rec.obstacle_forces(from.0, from.1, solver.obstacle_impulse(), &obstacles);
    }
    // A resumed run continues after the frames it kept.
    let first = rec.frames_written();
    for (k, &at) in frames.iter().enumerate().skip(first) {
        if k > 0 {
            let stepped = engine.step_to(
                &mut particles,
                at,
                &mut rec.summary,
                checkpoints.as_mut(),
                &mut progress,
                clock,
            );
            if let Err(e) = stepped {
                stop = Some(e);
                break;
            }
        }
        if let Engine::Cpu(solver) = &engine
            && !obstacles.is_empty()
        {
            let impulse = solver.obstacle_impulse();
            rec.obstacle_forces(engine.steps(), engine.time(), impulse, &obstacles);
        }
        if let Err(e) = rec.frame(engine.steps(), engine.time(), &particles) {
            stop = Some(e);
            break;
        }
    }
    progress.finish();
    // A run stopped between frames keeps the forces up to where it stopped.
    if let Engine::Cpu(solver) = &engine
        && stop.is_some()
        && !obstacles.is_empty()
    {
        rec.obstacle_forces(
            engine.steps(),
            engine.time(),
            solver.obstacle_impulse(),
            &obstacles,
        );
    }
    rec.summary.checkpoint = checkpoints.and_then(|c| c.last);
    let wall = clock.start.elapsed().as_secs_f64();
    let steps = engine.steps();
    rec.summary.device = match &engine {
        Engine::Cpu(_) => None,
        Engine::Gpu(s) => Some(s.device_name()),
    };
    let on = match &rec.summary.device {
        Some(device) => format!(", on {device}"),
        None => String::new(),
    };
    let resumed = match start.resume {
        Some(_) => format!("resumed at step {} (t = {:.4} s), ", from.0, from.1),
        None => String::new(),
    };
    let done = format!(
        "{resumed}{steps} steps to t = {:.4} s in {wall:.2} s ({:.3e} particle-steps/s, {} \
         particles{on})",
        engine.time(),
        (steps - from.0) as f64 * particles.len() as f64 / wall.max(1e-9),
        particles.len()
    );
    rec.finish(steps, engine.time(), wall, stop, &done)
}
