//! The gradient of a loss over an explicit run, by the discrete adjoint with checkpoints.
//!
//! The run of `T` steps is cut into segments of `K` steps, aligned on its end (the first
//! segment holds the remainder). The forward pass runs the solver, keeps the state at the
//! start of every segment but the last (the checkpoints) and every step's `Δt` (an adaptive
//! step is held fixed in the reverse pass: the gradient is that of the run with the step sizes
//! the forward pass took), and traces the last segment: its start-of-step states and each
//! step's grid ([`StepTrace`]). The reverse pass goes through the segments last
//! to first: it runs each earlier segment again from its checkpoint, tracing it the same way,
//! and maps the adjoint back through the traced steps ([`ReverseStep`]), adding each state's
//! loss term on the way. Memory is `⌈T/K⌉ − 1` checkpoints plus `K` traced steps,
//! `O(N (T/K + K))` for `N` particles, smallest near `K ≈ √T` ([`Footprint`], which also
//! chooses `K` from a memory budget); the work is the forward run, the
//! recomputation of all segments but the last, and the reverse steps (`K ≥ T`: one traced
//! forward run, nothing recomputed). The recomputed segment must end on the bits of the next
//! segment's start (the explicit step is deterministic at any thread count): a difference is
//! reported, not ignored.

use crate::adjoint_state::ParticleAdjoint;
use crate::checkpoints::{Checkpoints, Footprint};
use crate::error::AdjointError;
use crate::objective::Objective;
use crate::params::{Acts, MaterialField, Param};
use crate::step::ReverseStep;
use loam_core::Particles;
use loam_explicit::{Config, Solver, StepTrace};
use std::time::Instant;

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
    /// The memory model's bytes at that `K` ([`Footprint::bytes`]).
    pub memory: u64,
    /// Where the wall time went.
    pub phases: Phases,
}

/// Wall time of a gradient's three parts, in seconds: the gradient costs
/// `forward + recomputed + reverse`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Phases {
    /// The forward pass: the run with its checkpoints, the loss, the last segment traced.
    pub forward: f64,
    /// The recomputation of every segment but the last from its checkpoint, traced.
    pub recomputed: f64,
    /// The reverse steps, with the loss terms' adjoints.
    pub reverse: f64,
}

/// `L` and `dL/dθ` for a run of `steps` steps of `config` from `initial`, with respect to
/// `params`, by the discrete adjoint with segments of `K` steps chosen by `checkpoints`.
///
/// # Errors
/// A parameter the configuration does not have, a configuration the adjoint does not cover,
/// a memory budget below the least the run needs, a forward run that stops, or a
/// recomputation that does not reproduce the forward pass.
pub fn gradient<const D: usize>(
    config: &Config<f64, D>,
    initial: &Particles<f64, D>,
    steps: usize,
    params: &[Param],
    objective: &impl Objective<D>,
    checkpoints: Checkpoints,
) -> Result<Gradient<D>, AdjointError> {
    // On a pool thread with the other workers awake (`loam_explicit::pool::hold`): the
    // forward, recomputed and reverse steps start their parallel phases from inside the pool.
    loam_explicit::pool::hold(|| {
        let footprint = Footprint::new(config, initial, steps);
        let k = footprint.segment(checkpoints)?;
        let mut reverse = ReverseStep::new(config, params)?;
        // Segment starts, first to last: 0, then T − jK for j = ⌈T/K⌉ − 1, …, 1.
        let count = steps.div_ceil(k).max(1);
        let starts: Vec<usize> = std::iter::once(0)
            .chain((1..count).map(|j| steps - (count - j) * k))
            .collect();
        let last = starts[count - 1];
        // Forward: the checkpoints, the step sizes, the loss, and the last segment traced.
        let mut solver = Solver::new(config.clone(), initial)?;
        let mut p = initial.clone();
        let mut checkpoints = Vec::with_capacity(count - 1);
        let mut states: Vec<Particles<f64, D>> = Vec::with_capacity(steps - last);
        let mut traces: Vec<StepTrace<f64, D>> = Vec::with_capacity(steps - last);
        let mut times = Vec::with_capacity(steps + 1);
        let mut dts = Vec::with_capacity(steps);
        let clock = Instant::now();
        let mut phases = Phases::default();
        let mut loss = objective.term(0, &p, None);
        times.push(0.0);
        for s in 0..steps {
            let info = if s < last {
                if starts[checkpoints.len()] == s {
                    checkpoints.push(p.clone());
                }
                solver.step(&mut p, f64::INFINITY)?
            } else {
                states.push(p.clone());
                traces.push(StepTrace::default());
                let trace = traces.last_mut().expect("just pushed");
                solver.step_traced(&mut p, f64::INFINITY, trace)?
            };
            dts.push(info.dt);
            times.push(info.time);
            loss += objective.term(s + 1, &p, None);
        }
        phases.forward = clock.elapsed().as_secs_f64();
        // Reverse, segment by segment, the last one from the forward pass's trace.
        let mut adjoint = ParticleAdjoint::zeros(p.len());
        let mut grad = vec![0.0; params.len()];
        objective.term(steps, &p, Some(&mut adjoint));
        let (mut next, mut end) = (Particles::default(), Particles::default());
        for (j, &s0) in starts.iter().enumerate().rev() {
            let s1 = starts.get(j + 1).copied().unwrap_or(steps);
            let clock = Instant::now();
            if s1 < steps {
                // `next` holds the state at `s1`, where the segment must end. Each step goes from
                // one kept state into the next one's buffer (the last into `end`), uncopied.
                states[0] = checkpoints.pop().expect("a checkpoint per earlier segment");
                let mut solver = Solver::new(config.clone(), &states[0])?;
                solver.set_clock(times[s0], s0);
                for s in s0..s1 {
                    let (done, rest) = states.split_at_mut(s + 1 - s0);
                    let out = match rest.first_mut() {
                        Some(q) if s + 1 < s1 => q,
                        _ => &mut end,
                    };
                    let trace = &mut traces[s - s0];
                    let info = solver.step_traced_from(&done[s - s0], out, f64::INFINITY, trace)?;
                    if info.dt.to_bits() != dts[s].to_bits() {
                        return Err(AdjointError::Replay {
                            step: s + 1,
                            what: format!("time step {} instead of {}", info.dt, dts[s]),
                        });
                    }
                }
                if next != end {
                    return Err(AdjointError::Replay {
                        step: s1,
                        what: "the particle state differs from the checkpoint".into(),
                    });
                }
            }
            let replayed = clock.elapsed().as_secs_f64();
            phases.recomputed += replayed;
            for s in (s0..s1).rev() {
                let start = &states[s - s0];
                // The state after the step: the next traced start, or the segment's end.
                let after = match states.get(s + 1 - s0) {
                    Some(q) if s + 1 < s1 => q,
                    _ if s1 == steps => &p,
                    _ => &next,
                };
                let trace = &traces[s - s0];
                reverse.reverse(start, after, trace, times[s], &mut adjoint, &mut grad);
                objective.term(s, start, Some(&mut adjoint));
            }
            if s0 < s1 {
                std::mem::swap(&mut next, &mut states[0]);
            }
            phases.reverse += clock.elapsed().as_secs_f64() - replayed;
        }
        // Parameters that act through the initial state: the density, through m_p = ρ₀ V⁰_p;
        // the OCR and p_c₀, through a prestressed body's history.
        for (k, param) in params.iter().enumerate() {
            if let (Acts::Initial, Param::Material(m, MaterialField::Density)) =
                (param.acts(), param)
            {
                grad[k] += (0..initial.len())
                    .filter(|&i| initial.material[i] as usize == *m)
                    .map(|i| adjoint.mass[i] * initial.volume0[i])
                    .sum::<f64>();
            }
            for (i, h) in param.initial_histories(config, initial)? {
                let (bar, dh) = (adjoint.history[i].components(), h.components());
                grad[k] += bar.iter().zip(&dh).map(|(b, d)| b * d.eps).sum::<f64>();
            }
        }
        Ok(Gradient {
            loss,
            params: grad,
            initial: adjoint,
            steps,
            segment: k,
            memory: footprint.bytes(k),
            phases,
        })
    })
}
