//! The forward-mode dual derivative of an implicit run: the oracle of the reverse pass.
//!
//! The implicit solver runs in `f64` (faer's sparse factorisations are real), so the run is
//! not re-executed with a dual scalar. What such a run would compute is this: with every
//! particle's state a `Dual64` carrying `ṡ = ds/dθ`, Newton's iteration
//! `Δu ← Δu − J⁻¹ R(Δu)` in duals converges, in its derivative part, to the solution of
//! `J Δu̇ = −Ṙ` with `Ṙ` the derivative part of the residual at the converged `Δu` and `Δu̇`
//! held at zero on the unknowns (the implicit function theorem). This pass evaluates exactly
//! that, sub-step by sub-step in the forward order: one `Dual64` evaluation of every
//! particle's kernel for `Ṙ`, one solve with `J`, one evaluation for the end state
//! `ṡ' = Φ̇`. It shares the kernel with the reverse pass but none of its transposition.
//!
//! A Newmark sub-step (`super::inertia`) adds to `Ṙ` the derivative parts of
//! `f_int(0) − f_ext + (4/Δt²) M Δu − (4/Δt) pₙ` with `Δu` held, and its velocities take
//! `v̇' = v̇ + Σ_i (Ṅ_i Δv_i + N_i Δv̇_i)` with `B Δv̇ = (2/Δt)(Ṁ Δu + M Δu̇) − 2ṗₙ − Ḃ Δv`
//! (`Ḃ = Ṁ + ε diag Ṁ`).

use super::inertia::rates;
use super::kernel::{ParticleStep, particle_step, state_len, velocity_index};
use super::observe::{ImplicitObservations, Quantity};
use super::params::ImplicitParam;
use super::record::{Replay, SubStep, Trajectory};
use super::seeds::StepSeeds;
use crate::error::AdjointError;
use loam_core::tensor::Vector;
use loam_core::{Material, Particles};
use loam_implicit::linear::{LinearSolver, LinearSolverKind};
use loam_implicit::system::{MASS_REGULARISATION, StepSystem};
use loam_implicit::{ImplicitConfig, ImplicitError, ImplicitSolver, NodeDof};
use num_dual::Dual64;
use rayon::prelude::*;

/// `dL/dθ = Σ_k (∂L/∂m_k) dm_k/dθ` of the loss of `observations` over `run` (a forward run
/// of `config` from `initial`) by forward-mode duals ([`model_tangents`]).
///
/// # Errors
/// As [`super::adjoint::reverse`].
pub fn dual_derivative<const D: usize>(
    config: &ImplicitConfig<D>,
    initial: &Particles<f64, D>,
    run: &Trajectory<D>,
    observations: &ImplicitObservations,
    param: ImplicitParam,
) -> Result<f64, AdjointError> {
    let tangents = model_tangents(config, initial, run, observations, param)?;
    let weights = observations.residual_weights(run);
    Ok(weights.iter().zip(&tangents).map(|(w, t)| w * t).sum())
}

/// `dm_k/dθ` of every observed model quantity `m_k` of `observations` over `run` (a forward
/// run of `config` from `initial`) by forward-mode duals: the columns of the Jacobian a
/// Gauss–Newton analysis needs.
///
/// # Errors
/// As [`super::adjoint::reverse`].
pub fn model_tangents<const D: usize>(
    config: &ImplicitConfig<D>,
    initial: &Particles<f64, D>,
    run: &Trajectory<D>,
    observations: &ImplicitObservations,
    param: ImplicitParam,
) -> Result<Vec<f64>, AdjointError> {
    if config.pore_fluid.is_some() {
        return super::coupled::model_tangents(config, initial, run, observations, param);
    }
    let solver = ImplicitSolver::new(config.clone(), initial)?;
    let n = initial.len();
    let materials: Vec<Material<Dual64>> = (config.materials.iter().enumerate())
        .map(|(k, m)| param.seeded_material(k, m).unwrap_or_else(|| m.lift()))
        .collect();
    // ṡ at the start: the masses m_p = ρ₀ V⁰_p move with a density, a prestressed body's
    // history with its constants.
    let mut sdot = vec![vec![0.0; state_len(D)]; n];
    for (p, t) in param.initial_tangent(config, initial) {
        sdot[p] = t;
    }
    // A K0 moves the balancing forces too.
    let balance_rate = param.balance_tangent(config, initial)?;
    let mut linear = LinearSolver::new(config.newton.linear);
    let mut mass_solver = LinearSolver::new(LinearSolverKind::Cholesky);
    let vi = velocity_index(D);
    let mut tangents = vec![0.0; observations.items.len()];
    for (i, sub) in run.substeps.iter().enumerate() {
        let replay = Replay::new(&solver, initial, sub)?;
        let system = &replay.system;
        system.prepare(&mut linear);
        let inverted = |particle| {
            AdjointError::Implicit(ImplicitError::InvalidState {
                step: sub.step,
                particle,
            })
        };
        let rate = match param {
            ImplicitParam::Displacement(k, a) => Some(replay.prescribed_rate(k, a)?),
            _ => None,
        };
        // Every particle's step with the unknowns' derivative parts `free` (per unknown), at
        // the converged increments or (`start`) with the unknowns at zero.
        let evaluate =
            |free: &[f64], start: bool| -> Result<Vec<ParticleStep<Dual64, D>>, AdjointError> {
                let steps: Vec<Option<ParticleStep<Dual64, D>>> = (0..n)
                    .into_par_iter()
                    .map(|p| {
                        let loads = param.seeded_loads(config, &replay.loads(p), p, &balance_rate);
                        let du = |f: usize, a: usize| {
                            let eps = match system.dofs.get(f, a) {
                                NodeDof::Free { dof, sign } => sign * free[dof],
                                _ => rate.as_ref().map_or(0.0, |r| r[f][a]),
                            };
                            let re = if start {
                                replay.du_start(f, a)
                            } else {
                                replay.du(f, a)
                            };
                            Dual64::new(re, eps)
                        };
                        particle_step(
                            &replay.setting(p),
                            &materials[initial.material[p] as usize],
                            &replay.state(p).dual(&sdot[p]),
                            &loads,
                            du,
                        )
                    })
                    .collect();
                (steps.into_iter().enumerate())
                    .map(|(p, s)| s.ok_or_else(|| inverted(p)))
                    .collect()
            };
        // Ṙ with the unknowns held, then J Δu̇ = −Ṙ.
        let held = evaluate(&vec![0.0; system.len()], false)?;
        let mut r_dot = vec![0.0; system.len()];
        let mut subtract = |steps: &[ParticleStep<Dual64, D>]| {
            for s in steps {
                for node in &s.nodes {
                    for a in 0..D {
                        if let NodeDof::Free { dof, sign } = system.dofs.get(node.flat, a) {
                            r_dot[dof] -= sign * (node.internal[a].eps - node.external[a].eps);
                        }
                    }
                }
            }
        };
        subtract(&held);
        // A Newmark step: the start force, the mass and the momentum, with Δu held.
        let stencils: Vec<Vec<(usize, Dual64)>> = (held.iter())
            .map(|s| s.nodes.iter().map(|n| (n.flat, n.weight)).collect())
            .collect();
        let dynamic = match &system.inertia {
            Some(inertia) => {
                subtract(&evaluate(&vec![0.0; system.len()], true)?);
                let motion = inertia
                    .grid_motion(&sub.solution, &mut mass_solver)
                    .map_err(|source| AdjointError::Linear {
                        step: sub.step,
                        what: "mass",
                        source,
                    })?;
                let dv = motion.velocity_increment;
                let particles = (stencils.iter().zip(&held))
                    .map(|(nodes, s)| (nodes.clone(), s.end.mass, &s.end.v));
                let r = rates(&system.dofs, particles, &[&sub.solution, &dv]);
                let dt = inertia.dt;
                for (d, rd) in r_dot.iter_mut().enumerate() {
                    *rd -= 4.0 / (dt * dt) * r.mass_times[0][d] - 4.0 / dt * r.momentum[d];
                }
                Some((inertia, r, dv))
            }
            None => None,
        };
        add_controlled_rate(system, param, &mut r_dot);
        let u_dot = solve_tangent(&solver, &replay, &mut linear, &r_dot)?;
        let moved = evaluate(&u_dot, false)?;
        for (p, s) in moved.iter().enumerate() {
            sdot[p] = s.end.tangent();
        }
        // The Newmark velocity update: B Δv̇ = (2/Δt)(Ṁ Δu + M Δu̇) − 2ṗₙ − Ḃ Δv.
        if let Some((inertia, r, dv)) = dynamic {
            let mut m_u_dot = vec![0.0; system.len()];
            inertia.mass.mul_vec(&u_dot, &mut m_u_dot);
            let rhs: Vec<f64> = (0..system.len())
                .map(|d| {
                    2.0 / inertia.dt * (r.mass_times[0][d] + m_u_dot[d])
                        - 2.0 * r.momentum[d]
                        - r.mass_times[1][d]
                        - MASS_REGULARISATION * r.diagonal[d] * dv[d]
                })
                .collect();
            let mut dv_dot = vec![0.0; system.len()];
            mass_solver
                .solve(&inertia.regularised_mass(), &rhs, &mut dv_dot)
                .map_err(|source| AdjointError::Linear {
                    step: sub.step,
                    what: "mass",
                    source,
                })?;
            for (p, nodes) in stencils.iter().enumerate() {
                for &(flat, w) in nodes {
                    for a in 0..D {
                        let (v, v_dot) = (
                            system.dofs.field(flat, a, &dv),
                            system.dofs.field(flat, a, &dv_dot),
                        );
                        sdot[p][vi + a] += w.eps * v + w.re * v_dot;
                    }
                }
            }
        }
        if SubStep::ends_step(&run.substeps, i) {
            let observed =
                (observations.items.iter().zip(&mut tangents)).filter(|(o, _)| o.step == sub.step);
            for (o, t) in observed {
                *t = match o.quantity {
                    Quantity::Displacement {
                        particle,
                        component,
                    } => sdot[particle][component],
                    Quantity::Velocity {
                        particle,
                        component,
                    } => sdot[particle][vi + component],
                    Quantity::Reaction {
                        constraint,
                        component,
                    } => {
                        let mut unit = vec![Vector::<f64, D>::zeros(); config.constraints.len()];
                        unit[constraint][component] = 1.0;
                        reaction_derivative(&moved, &StepSeeds::node_weights(config, &unit))
                    }
                    // Observed in coupled runs only (validated), which take the coupled pass.
                    Quantity::PorePressure { .. } => 0.0,
                };
            }
        }
    }
    Ok(tangents)
}

/// Adds `−∂R/∂F` of a constraint's force to `r_dot` (`ṙ = −Ṙ`): the force `F` of a
/// force-controlled component acts on its shared unknown as `ℓ F` at load factor `ℓ`
/// ([`loam_implicit::system::Controlled`]), twice in a Newmark step
/// ([`StepSystem::controlled_rate`]).
pub(super) fn add_controlled_rate<const D: usize>(
    system: &StepSystem<D>,
    param: ImplicitParam,
    r_dot: &mut [f64],
) {
    if let ImplicitParam::ConstraintForce(k, a) = param {
        for c in (system.controlled.iter()).filter(|c| c.constraint == k && c.component == a) {
            r_dot[c.dof] += system.controlled_rate(c);
        }
    }
}

/// `Δu̇` from `J Δu̇ = ṙ` (`ṙ = −Ṙ`) with the sub-step's tangent at its converged unknowns.
///
/// # Errors
/// A particle that inverts at the solution, or a tangent that cannot be solved.
pub(super) fn solve_tangent<const D: usize>(
    solver: &ImplicitSolver<D>,
    replay: &Replay<'_, D>,
    linear: &mut LinearSolver,
    r_dot: &[f64],
) -> Result<Vec<f64>, AdjointError> {
    let (system, sub) = (&replay.system, replay.sub);
    let mut u_dot = vec![0.0; system.len()];
    if !system.is_empty() {
        let k = system
            .tangent_local(&sub.solution, solver.materials())
            .map_err(|e| {
                AdjointError::Implicit(ImplicitError::InvalidState {
                    step: sub.step,
                    particle: e.particle,
                })
            })?;
        linear
            .solve(&k, r_dot, &mut u_dot)
            .map_err(|source| AdjointError::Linear {
                step: sub.step,
                what: "tangent",
                source,
            })?;
    }
    Ok(u_dot)
}

/// `Σ_i r̄_i · ḟ_int,i`: the derivative of the observed reactions' share of the loss.
fn reaction_derivative<const D: usize>(
    steps: &[ParticleStep<Dual64, D>],
    weights: &[Vector<f64, D>],
) -> f64 {
    let mut total = 0.0;
    for s in steps {
        for node in &s.nodes {
            for a in 0..D {
                total += weights[node.flat][a] * node.internal[a].eps;
            }
        }
    }
    total
}
