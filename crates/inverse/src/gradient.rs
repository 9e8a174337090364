//! The gradient of a loss over an explicit run, by the discrete adjoint with checkpoints.
//!
//! The forward pass runs the solver and keeps the state every `K` steps (the checkpoints)
//! and every step's `Δt` (an adaptive step is held fixed in the reverse pass: the gradient is
//! that of the run with the step sizes the forward pass took). The reverse pass goes through
//! the segments last to first: it runs the segment again from its checkpoint, keeping its `K`
//! start-of-step states, and maps the adjoint back through them step by step
//! ([`ReverseStep`]), adding each state's loss term on the way. Memory is
//! `O(N (T/K + K))` for `N` particles and `T` steps, smallest at `K ≈ √T`; the work is two
//! forward runs plus the reverse steps. The recomputed segment must end on the bits of the
//! next checkpoint (the explicit step is deterministic at any thread count): a difference is
//! reported, not ignored.

use crate::adjoint_state::ParticleAdjoint;
use crate::error::AdjointError;
use crate::objective::Objective;
use crate::params::{Acts, MaterialField, Param};
use crate::step::ReverseStep;
use loam_core::Particles;
use loam_explicit::{Config, Solver};

/// The gradient of a loss over a run.
#[derive(Clone, Debug)]
pub struct Gradient<const D: usize> {
    /// The loss `L`.
    pub loss: f64,
    /// `dL/dθ_k`, in the order of the parameters asked for.
    pub params: Vec<f64>,
    /// `∂L/∂(initial state)`: what initial-state parameters (an initial velocity, a field)
    /// chain through.
    pub initial: ParticleAdjoint<D>,
    /// Steps run.
    pub steps: usize,
    /// Steps per segment `K` between checkpoints.
    pub segment: usize,
}

/// How many steps a segment between checkpoints holds: `⌈√T⌉` unless given.
pub fn segment_length(steps: usize, given: Option<usize>) -> usize {
    given
        .unwrap_or_else(|| (steps as f64).sqrt().ceil() as usize)
        .max(1)
}

/// `L` and `dL/dθ` for a run of `steps` steps of `config` from `initial`, with respect to
/// `params`, by the discrete adjoint with a checkpoint every `segment` steps (`⌈√T⌉` when
/// `None`).
///
/// # Errors
/// A parameter the configuration does not have, a configuration the adjoint does not cover,
/// a forward run that stops, or a recomputation that does not reproduce the forward pass.
pub fn gradient<const D: usize>(
    config: &Config<f64, D>,
    initial: &Particles<f64, D>,
    steps: usize,
    params: &[Param],
    objective: &impl Objective<D>,
    segment: Option<usize>,
) -> Result<Gradient<D>, AdjointError> {
    let k = segment_length(steps, segment);
    let mut reverse = ReverseStep::new(config, params)?;
    // Forward: the checkpoints, the step sizes and the loss.
    let mut solver = Solver::new(config.clone(), initial)?;
    let mut p = initial.clone();
    let mut checkpoints = Vec::new();
    let mut times = Vec::with_capacity(steps + 1);
    let mut dts = Vec::with_capacity(steps);
    let mut loss = objective.term(0, &p, None);
    times.push(0.0);
    for s in 0..steps {
        if s % k == 0 {
            checkpoints.push((s, p.clone()));
        }
        let info = solver.step(&mut p, f64::INFINITY)?;
        dts.push(info.dt);
        times.push(info.time);
        loss += objective.term(s + 1, &p, None);
    }
    // Reverse, segment by segment.
    let mut adjoint = ParticleAdjoint::zeros(p.len());
    let mut grad = vec![0.0; params.len()];
    objective.term(steps, &p, Some(&mut adjoint));
    let mut next: Option<Particles<f64, D>> = None;
    for (s0, state0) in checkpoints.into_iter().rev() {
        let s1 = (s0 + k).min(steps);
        let mut solver = Solver::new(config.clone(), &state0)?;
        solver.set_clock(times[s0], s0);
        let mut states = Vec::with_capacity(s1 - s0);
        let mut q = state0;
        for s in s0..s1 {
            states.push(q.clone());
            let info = solver.step(&mut q, f64::INFINITY)?;
            if info.dt.to_bits() != dts[s].to_bits() {
                return Err(AdjointError::Replay {
                    step: s + 1,
                    what: format!("time step {} instead of {}", info.dt, dts[s]),
                });
            }
        }
        if let Some(expected) = &next
            && *expected != q
        {
            return Err(AdjointError::Replay {
                step: s1,
                what: "the particle state differs from the checkpoint".into(),
            });
        }
        for s in (s0..s1).rev() {
            let start = &states[s - s0];
            reverse.reverse(start, times[s], dts[s], &mut adjoint, &mut grad);
            objective.term(s, start, Some(&mut adjoint));
        }
        next = states.into_iter().next();
    }
    // Parameters that act through the initial state: the density, through m_p = ρ₀ V⁰_p.
    for (k, param) in params.iter().enumerate() {
        if let (Acts::Initial, Param::Material(m, MaterialField::Density)) = (param.acts(), param) {
            grad[k] += (0..initial.len())
                .filter(|&i| initial.material[i] as usize == *m)
                .map(|i| adjoint.mass[i] * initial.volume0[i])
                .sum::<f64>();
        }
    }
    Ok(Gradient {
        loss,
        params: grad,
        initial: adjoint,
        steps,
        segment: k,
    })
}
