//! The reverse pass over the accepted sub-steps of an implicit run (quasi-static or Newmark).
//!
//! A sub-step maps the particle state `s` to `s' = Φ(s, Δu, θ)` where `Δu` solves
//! `R(Δu; s, θ) = 0`; a reaction `r(s, Δu, θ)` may be observed after it. With `s̄'` the
//! adjoint of the end state and `r̄ = ∂L/∂r`, the implicit function theorem gives
//!
//! ```text
//! Jᵀ λ = (∂Φ/∂Δu)ᵀ s̄' + (∂r/∂Δu)ᵀ r̄                       (J = ∂R/∂Δu, the step's tangent)
//! s̄   = (∂Φ/∂s)ᵀ s̄' + (∂r/∂s)ᵀ r̄ − (∂R/∂s)ᵀ λ
//! θ̄  += (∂Φ/∂θ)ᵀ s̄' + (∂r/∂θ)ᵀ r̄ − (∂R/∂θ)ᵀ λ
//! ```
//!
//! Every term is a sum over particles of derivatives of one scalar per particle,
//! `ψₚ = Σ_i (a_i·f_int,i + c_i·f_ext,i) + s̄'ₚ·s'ₚ` ([`super::pullback`]), with `a = r̄ − λ`
//! and `c = λ` on the nodes (through the unknown map, mirror signs included). The right-hand
//! side is `∂ψₚ/∂Δu` with `λ = 0`; the state's adjoint `∂ψₚ/∂sₚ` and each parameter's share
//! `∂ψₚ/∂θ` follow from the same linearisation of the particle's step, whose `∂S/∂ΔF` also
//! gives the tangent `J`.
//!
//! A Newmark sub-step also maps the velocities, through the mass solve of its grid velocity
//! increment `Δv`: that solve is reversed first (`B μ = Δv̄`), `(2/Δt) M μ` joins the
//! right-hand side, `J` includes `(4/Δt²) M`, the external force's weight is `c = 2λ` (it enters
//! the residual once directly and once through the start force `rₙ`), the start force's
//! `f_int(0)` is a second linearisation per particle (at the increments with the unknowns at
//! zero) weighted by `−λ`, and the mass and momentum terms add to `ψₚ`
//! ([`super::inertia`]).

use super::inertia::{InertiaWeights, gather};
use super::kernel::{state_len, velocity_index};
use super::observe::ImplicitObservations;
use super::params::ImplicitParam;
use super::pullback::{Cotangent, LaneMaterials, Linearisation};
use super::record::{Replay, SubStep, Trajectory};
use super::seeds::StepSeeds;
use crate::error::AdjointError;
use crate::params::MaterialField;
use loam_core::tensor::Vector;
use loam_core::{Material, Particles};
use loam_implicit::linear::{LinearSolver, LinearSolverKind};
use loam_implicit::system::StepSystem;
use loam_implicit::{ImplicitConfig, ImplicitError, ImplicitSolver, NodeDof};
use num_dual::Dual64;
use rayon::prelude::*;

/// The reverse pass of `run` (a forward run of `config` from `initial`): `dL/dθ` for every
/// parameter in `params`, for the loss of `observations`.
///
/// # Errors
/// A sub-step whose system cannot be rebuilt or whose adjoint system cannot be solved.
pub fn reverse<const D: usize>(
    config: &ImplicitConfig<D>,
    initial: &Particles<f64, D>,
    run: &Trajectory<D>,
    observations: &ImplicitObservations,
    params: &[ImplicitParam],
) -> Result<Vec<f64>, AdjointError> {
    let weights = observations.residual_weights(run);
    reverse_from(config, initial, run, observations, &weights, params, 0)
}

/// The vector–Jacobian product `ȳᵀ ∂m/∂θ` of the model values `m_k` of `observations` in
/// `run` ([`ImplicitObservations::model`]) with the cotangent `cotangent` (`ȳ_k`, one per
/// observation): the reverse pass of [`reverse`] seeded with `ȳ` instead of `∂L/∂m`.
///
/// # Errors
/// As [`reverse`].
pub fn pull_back<const D: usize>(
    config: &ImplicitConfig<D>,
    initial: &Particles<f64, D>,
    run: &Trajectory<D>,
    observations: &ImplicitObservations,
    cotangent: &[f64],
    params: &[ImplicitParam],
) -> Result<Vec<f64>, AdjointError> {
    reverse_from(config, initial, run, observations, cotangent, params, 0)
}

/// The "last step only" approximation of [`reverse`]: the reverse pass of the last accepted
/// sub-step alone, its start state held fixed (the history of the load path ignored, and
/// observations of earlier steps with it). This is what differentiating only the last load
/// step's residual gives; it is exact only when nothing before the last sub-step depends on
/// the parameters.
///
/// # Errors
/// As [`reverse`].
pub fn reverse_last_substep<const D: usize>(
    config: &ImplicitConfig<D>,
    initial: &Particles<f64, D>,
    run: &Trajectory<D>,
    observations: &ImplicitObservations,
    params: &[ImplicitParam],
) -> Result<Vec<f64>, AdjointError> {
    let last = run.substeps.len().saturating_sub(1);
    let weights = observations.residual_weights(run);
    reverse_from(config, initial, run, observations, &weights, params, last)
}

/// The reverse pass over the sub-steps `first..` of `run`, seeded with `weights`, the
/// cotangent `∂L/∂m_k` of each observation's model value.
fn reverse_from<const D: usize>(
    config: &ImplicitConfig<D>,
    initial: &Particles<f64, D>,
    run: &Trajectory<D>,
    observations: &ImplicitObservations,
    weights: &[f64],
    params: &[ImplicitParam],
    first: usize,
) -> Result<Vec<f64>, AdjointError> {
    if config.pore_fluid.is_some() {
        return super::coupled::reverse(config, initial, run, observations, weights, params, first);
    }
    let solver = ImplicitSolver::new(config.clone(), initial)?;
    let n = initial.len();
    let nodes = config.grid.num_nodes();
    let lanes = LaneMaterials::new(&config.materials);
    // Per parameter and material, the material with that parameter seeded (if it is one of
    // its constants).
    let seeded: Vec<Vec<Option<Material<Dual64>>>> = params
        .iter()
        .map(|q| {
            (config.materials.iter().enumerate())
                .map(|(k, m)| q.seeded_material(k, m))
                .collect()
        })
        .collect();
    // Per parameter, the derivative of each particle's balancing force (a K0's; empty for
    // the others).
    let balance_rates: Vec<Vec<Vector<f64, D>>> = (params.iter())
        .map(|q| q.balance_tangent(config, initial))
        .collect::<Result<_, _>>()?;
    let zeros = vec![Vector::<f64, D>::zeros(); nodes];
    let mut linear = LinearSolver::new(config.newton.linear);
    let mut mass_solver = LinearSolver::new(LinearSolverKind::Cholesky);
    let vi = velocity_index(D);
    let no_end = vec![0.0; state_len(D)];
    let mut sbar = vec![vec![0.0; state_len(D)]; n];
    let mut grad = vec![0.0; params.len()];
    for (i, sub) in run.substeps.iter().enumerate().skip(first).rev() {
        let seeds = SubStep::ends_step(&run.substeps, i)
            .then(|| StepSeeds::new(config, observations, weights, sub.step));
        for &(p, k, w) in seeds.iter().flat_map(|s| &s.states) {
            sbar[p][k] += w;
        }
        let replay = Replay::new(&solver, initial, sub)?;
        let system = &replay.system;
        system.prepare(&mut linear);
        let inverted = |particle| {
            AdjointError::Implicit(ImplicitError::InvalidState {
                step: sub.step,
                particle,
            })
        };
        let a_r = (seeds.as_ref())
            .and_then(|s| s.reaction_weights.as_deref())
            .unwrap_or(&zeros);
        let material = |p: usize| initial.material[p] as usize;
        let linearised: Vec<Option<Linearisation<D>>> = (0..n)
            .into_par_iter()
            .map(|p| {
                let (setting, state, loads) = (replay.setting(p), replay.state(p), replay.loads(p));
                let du = |f: usize, a: usize| replay.du(f, a);
                Linearisation::new(&setting, &lanes, material(p), &state, &loads, du)
            })
            .collect();
        let linearised: Vec<Linearisation<D>> = (linearised.into_iter().enumerate())
            .map(|(p, l)| l.ok_or_else(|| inverted(p)))
            .collect::<Result<_, _>>()?;
        // A Newmark sub-step: the start force's linearisation, the grid motion and the
        // reverse of its mass solve, `B μ = Δv̄`.
        let dynamic = match &system.inertia {
            Some(inertia) => {
                let start: Vec<Option<Linearisation<D>>> = (0..n)
                    .into_par_iter()
                    .map(|p| {
                        let (setting, state) = (replay.setting(p), replay.state(p));
                        let du = |f: usize, a: usize| replay.du_start(f, a);
                        Linearisation::new(
                            &setting,
                            &lanes,
                            material(p),
                            &state,
                            &replay.loads(p),
                            du,
                        )
                    })
                    .collect();
                let start: Vec<Linearisation<D>> = (start.into_iter().enumerate())
                    .map(|(p, l)| l.ok_or_else(|| inverted(p)))
                    .collect::<Result<_, _>>()?;
                let singular = |source| AdjointError::Linear {
                    step: sub.step,
                    what: "mass",
                    source,
                };
                let motion = inertia
                    .grid_motion(&sub.solution, &mut mass_solver)
                    .map_err(singular)?;
                let stencils: Vec<Vec<(usize, f64)>> =
                    linearised.iter().map(Linearisation::weights).collect();
                let v_end = |p: usize| Vector::<f64, D>::from_fn(|a, _| sbar[p][vi + a]);
                let dv_bar = gather(
                    &system.dofs,
                    (stencils.iter().enumerate()).map(|(p, s)| (s.as_slice(), v_end(p))),
                );
                let mut mu = vec![0.0; system.len()];
                if dv_bar.iter().any(|v| *v != 0.0) {
                    mass_solver
                        .solve(&inertia.regularised_mass(), &dv_bar, &mut mu)
                        .map_err(singular)?;
                }
                Some((inertia, start, motion.velocity_increment, mu))
            }
            None => None,
        };
        // Right-hand side: ∂ψ/∂Δu with λ = 0.
        let by_increments: Vec<Vec<(usize, Vector<f64, D>)>> = (linearised.par_iter())
            .zip(&sbar)
            .map(|(lin, end)| {
                lin.increments(&Cotangent {
                    internal: a_r,
                    external: &zeros,
                    end,
                    inertia: None,
                })
            })
            .collect();
        let mut rhs = vec![0.0; system.len()];
        if let Some((inertia, _, _, mu)) = &dynamic {
            inertia.mass.mul_vec(mu, &mut rhs);
            rhs.iter_mut().for_each(|r| *r *= 2.0 / inertia.dt);
        }
        for (flat, g) in by_increments.iter().flatten() {
            for a in 0..D {
                if let NodeDof::Free { dof, sign } = system.dofs.get(*flat, a) {
                    rhs[dof] += sign * g[a];
                }
            }
        }
        let mut lambda = vec![0.0; system.len()];
        if rhs.iter().any(|v| *v != 0.0) {
            let k = system
                .tangent_from(|p| Some(linearised[p].tangent()))
                .map_err(|e| inverted(e.particle))?;
            let failed = |source| AdjointError::Linear {
                step: sub.step,
                what: "adjoint",
                source,
            };
            let product = |v: &[f64], out: &mut [f64]| k.mul_vec_transpose(v, out);
            if !(sub.solve_adjoint_near(&k.pattern, product, &rhs, &mut lambda)).map_err(failed)? {
                linear
                    .solve_transpose(&k, &rhs, &mut lambda)
                    .map_err(failed)?;
            }
        }
        // Nodal weights of ψ: a = r̄ − λ on the internal force, c = λ (Newmark: 2λ) on the
        // external one, −λ on the start force's f_int(0).
        let c = if dynamic.is_some() { 2.0 } else { 1.0 };
        let mut internal = a_r.to_vec();
        let mut external = zeros.clone();
        let mut start_internal = zeros.clone();
        for node in 0..nodes {
            for a in 0..D {
                if let NodeDof::Free { dof, sign } = system.dofs.get(node, a) {
                    internal[node][a] -= sign * lambda[dof];
                    external[node][a] += c * sign * lambda[dof];
                    start_internal[node][a] -= sign * lambda[dof];
                }
            }
        }
        let weights = (dynamic.as_ref()).map(|(inertia, _, dv, mu)| {
            InertiaWeights::new(&system.dofs, inertia, &sub.solution, dv, &lambda, mu)
        });
        let start_cot = Cotangent {
            internal: &start_internal,
            external: &zeros,
            end: &no_end,
            inertia: None,
        };
        let rates = replay.prescribed_rates(params)?;
        let per_particle: Vec<Option<(Vec<f64>, Vec<f64>)>> = (0..n)
            .into_par_iter()
            .map(|p| {
                let lin = &linearised[p];
                let cot = Cotangent {
                    internal: &internal,
                    external: &external,
                    end: &sbar[p],
                    inertia: weights.as_ref(),
                };
                let start = dynamic.as_ref().map(|d| &d.1[p]);
                let mut shares = vec![0.0; params.len()];
                for (j, q) in params.iter().enumerate() {
                    shares[j] = match *q {
                        // Through the masses, below.
                        ImplicitParam::Material(_, MaterialField::Density) => continue,
                        ImplicitParam::Material(..) => match &seeded[j][material(p)] {
                            Some(m) => {
                                lin.material_share(m, &cot)?
                                    + match start {
                                        Some(s) => s.material_share(m, &start_cot)?,
                                        None => 0.0,
                                    }
                            }
                            None => continue,
                        },
                        ImplicitParam::Gravity(a) => lin.gravity_share(&cot)[a] * initial.mass[p],
                        ImplicitParam::PointLoad(k, a) if config.point_loads[k].particle == p => {
                            lin.load_share(&cot)[a]
                        }
                        // The solid alone has no pore fluid (a coupled run takes its own pass);
                        // a constraint's force acts on its shared unknown, below.
                        ImplicitParam::PointLoad(..)
                        | ImplicitParam::Conductivity(_)
                        | ImplicitParam::ConstraintForce(..) => continue,
                        // Through the initial history, below, and the balancing forces.
                        ImplicitParam::K0(_) => match balance_rates[j].get(p) {
                            Some(rate) => lin.balance_share(&cot).dot(rate),
                            None => continue,
                        },
                        ImplicitParam::Displacement(..) => {
                            let rate = rates[j].as_ref().expect("rates of displacements");
                            let through = |l: &Linearisation<D>, cot: &Cotangent<'_, D>| {
                                (l.increments(cot).iter())
                                    .map(|(f, g)| rate[*f].dot(g))
                                    .sum::<f64>()
                            };
                            through(lin, &cot) + start.map_or(0.0, |s| through(s, &start_cot))
                        }
                    };
                }
                let mut state = lin.state_adjoint(&cot);
                if let Some(s) = start {
                    let from_start = s.state_adjoint(&start_cot);
                    state.iter_mut().zip(&from_start).for_each(|(a, b)| *a += b);
                }
                Some((state, shares))
            })
            .collect();
        for (p, r) in per_particle.into_iter().enumerate() {
            let (s, shares) = r.ok_or_else(|| inverted(p))?;
            sbar[p] = s;
            grad.iter_mut().zip(&shares).for_each(|(g, s)| *g += s);
        }
        add_controlled_shares(system, &lambda, params, &mut grad);
    }
    // The parameters the initial state depends on (the density through the masses, a
    // prestressed body's constants and K0 through its history): s̄₀ · ds₀/dθ.
    for (g, q) in grad.iter_mut().zip(params) {
        for (p, t) in q.initial_tangent(config, initial) {
            *g += t.iter().zip(&sbar[p]).map(|(a, b)| a * b).sum::<f64>();
        }
    }
    Ok(grad)
}

/// The shares of the constraints' forces in `params`: a force-controlled component puts
/// `f_ext = ℓ F` (load factor `ℓ`) on its shared unknown ([`loam_implicit::system::Controlled`]),
/// which enters `−R` with the weight `c = 1` (Newmark: 2, [`StepSystem::controlled_rate`]);
/// its weight in `ψ` is `c λ` there, so `dψ/dF = c ℓ λ_dof`.
pub(super) fn add_controlled_shares<const D: usize>(
    system: &StepSystem<D>,
    lambda: &[f64],
    params: &[ImplicitParam],
    grad: &mut [f64],
) {
    for (g, q) in grad.iter_mut().zip(params) {
        if let ImplicitParam::ConstraintForce(k, a) = *q {
            for c in (system.controlled.iter()).filter(|c| c.constraint == k && c.component == a) {
                *g += lambda[c.dof] * system.controlled_rate(c);
            }
        }
    }
}
