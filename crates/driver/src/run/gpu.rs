//! Explicit runs on the GPU (`solver.device = "gpu"` or `--device gpu`): the steps run on the
//! device in f32 ([`loam_gpu::GpuSolver`]) and the particles come back only at the frames
//! and the checkpoints, widened to f64 for the same frame, summary and checkpoint files as a
//! CPU run. A run continued from a checkpoint uploads the saved particles (f32 values
//! widened, so narrowed back exactly) and sets the device's clock; with the gather P2G it
//! has the same bits as the run that never stopped.

use super::Stop;
use super::checkpoint::Checkpointer;
use super::explicit::FrameAt;
use crate::Outcome;
use loam_core::Particles;
use loam_explicit::Config;
use loam_gpu::{CHECK_EVERY, Gpu, GpuError, GpuSolver};
use loam_scene::output::RunSummary;

/// How P2G adds into the grid on the GPU, where not the adapter's choice (native f32 atomics
/// where it has them, else the gather): `--p2g` of `loam run` and `loam bench`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum P2g {
    /// A scatter that adds with a compare-exchange loop on the float bits, on any adapter
    /// (`loam_gpu::Atomics::CompareExchange`).
    CompareExchange,
    /// A gather from the particles binned by stencil, on any adapter: the same bits on every
    /// run (`loam_gpu::Atomics::Gather`).
    Gather,
}

/// Opens the first GPU adapter with P2G as `p2g` asks (`None`: the adapter's choice).
pub fn device(p2g: Option<P2g>) -> Result<Gpu, GpuError> {
    let gpu = Gpu::new(p2g == Some(P2g::CompareExchange))?;
    Ok(match p2g {
        Some(P2g::Gather) => gpu.with_gather(),
        _ => gpu,
    })
}

/// Opens the first GPU adapter and uploads the run: no adapter is a failure of the run (exit
/// 1, with how to get a software adapter), a scene whose buffers are larger than the adapter
/// binds invalid input (exit 2, naming the scene field that sizes them); both are reported
/// here.
pub fn open<const D: usize>(
    config: &Config<f64, D>,
    particles: &Particles<f64, D>,
    p2g: Option<P2g>,
) -> Result<GpuSolver<D>, Outcome> {
    let config = config.lift();
    let gpu = device(p2g).map_err(|e| {
        eprintln!("error: {e}");
        Outcome::Failed
    })?;
    GpuSolver::new(&gpu, &config, &particles.lift()).map_err(|e| {
        eprintln!("error: {e}");
        match e {
            GpuError::Unsupported { .. } | GpuError::Config(_) => Outcome::BadInput,
            _ => Outcome::Failed,
        }
    })
}

/// Steps to the frame point `at` (a step, with a fixed step; a time, with an adaptive one),
/// in runs of at most [`CHECK_EVERY`] steps (each ends with the stability flags read back),
/// looking for a signal and reporting progress between runs; then reads the particles back
/// into `particles`. `report(step, time)` draws the progress. With `checkpoints`, a run also
/// ends at each step where a state is saved, and the particles are read back and saved there
/// (`loam run --checkpoint-every`, as on the CPU).
pub fn step_to<const D: usize>(
    solver: &mut GpuSolver<D>,
    particles: &mut Particles<f64, D>,
    at: FrameAt,
    summary: &mut RunSummary,
    mut checkpoints: Option<&mut Checkpointer>,
    mut report: impl FnMut(usize, f64),
) -> Result<(), Stop> {
    loop {
        let done = match at {
            FrameAt::Step(target) => solver.steps() >= target,
            FrameAt::Time(t) => solver.next_step_cap(t).is_none(),
        };
        if done {
            break;
        }
        if super::interrupt::requested() {
            return Err(Stop::Interrupted);
        }
        let run = checkpoints.as_deref().map_or(CHECK_EVERY, |c| {
            c.steps_to_next(solver.steps()).min(CHECK_EVERY)
        });
        let stepped = match at {
            FrameAt::Step(target) => solver.advance((target - solver.steps()).min(run)),
            FrameAt::Time(t) => solver.advance_toward(t, run).map(|_| ()),
        };
        stepped
            .map_err(|e| Stop::Failed(format!("{e} (t = {:.6e} s, on the GPU)", solver.time())))?;
        let (lo, hi) = solver.dt_range();
        summary.dt_min = summary.dt_min.min(lo);
        summary.dt_max = summary.dt_max.max(hi);
        if let Some(c) = checkpoints.as_deref_mut()
            && c.due(solver.steps())
        {
            solver
                .read_particles(particles)
                .map_err(|e| Stop::Failed(e.to_string()))?;
            c.after_step(solver.steps(), solver.time(), particles)
                .map_err(Stop::Failed)?;
        }
        report(solver.steps(), solver.time());
    }
    solver
        .read_particles(particles)
        .map_err(|e| Stop::Failed(e.to_string()))
}
