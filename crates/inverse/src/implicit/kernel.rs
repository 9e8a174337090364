//! One particle's part of a converged implicit (sub-)step, generic over the scalar, and its
//! local vector–Jacobian products by forward-mode duals.
//!
//! For particle `p` with start-of-step state `sₚ = (xₚ, Fₚ, historyₚ, mₚ)` and the nodal
//! increments `Δu_i` on its stencil, the step computes
//!
//! ```text
//! ΔF      = I + Σ_i Δu_i ⊗ ∇N_i(xₚ)
//! f_int,i = V⁰ τ(ΔF, Fₚ, historyₚ) ΔF⁻ᵀ ∇N_i(xₚ)            (internal force on node i)
//! f_ext,i = (mₚ g + f_load) λ N_i(xₚ)                       (external force, load factor λ)
//! xₚ'     = xₚ + Σ_i N_i(xₚ) Δu_i,   Fₚ' = ΔF Fₚ,   historyₚ' from the return mapping
//! ```
//!
//! which is everything the step's residual `R = Σₚ (f_int − f_ext)`, its reactions and the
//! next step read of the particle. Each particle depends only on its own state and on the
//! increments of its own stencil, so the adjoint of the step is a sum of per-particle
//! vector–Jacobian products of the scalar
//!
//! ```text
//! ψₚ = Σ_i (a_i · f_int,i + c_i · f_ext,i) + x̄'·xₚ' + F̄' : Fₚ' + h̄'·historyₚ'
//! ```
//!
//! for nodal weights `a`, `c` and the adjoint `(x̄', F̄', h̄')` of the particle's end state
//! ([`Cotangent`]). `∂ψₚ/∂sₚ` takes one `Dual64` evaluation per component of `sₚ`
//! (`D + D² + 11`); `∂ψₚ/∂Δu_i` goes through `ΔF`: with a perturbation `E` added to `ΔF`,
//! `∂ψₚ/∂Δu_{i,a} = Σ_b ∂ψₚ/∂E_ab ∂_b N_i + x̄'_a N_i` (`D²` evaluations).

use loam_core::constitutive::{MaterialState, Model};
use loam_core::stencil::particle_half_width;
use loam_core::tensor::{Tensor, Vector};
use loam_core::{Grid, Material, Scalar, Shape, Stencil};
use loam_implicit::kernel::{delta_f, stress_update};
use num_dual::Dual64;

/// The state a particle carries from one (sub-)step to the next, in scalar type `T`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParticleState<T, const D: usize> {
    /// Position `xₚ`.
    pub x: Vector<T, D>,
    /// Deformation gradient `Fₚ`.
    pub f: Tensor<T, D>,
    /// Constitutive history (J2: equivalent plastic strain and elastic left Cauchy–Green
    /// tensor `bₑ`).
    pub history: MaterialState<T>,
    /// Mass `mₚ` (a constant of the run; its adjoint carries the density's gradient).
    pub mass: T,
}

/// Number of scalar components of a [`ParticleState`]: `D + D² + 10 + 1`.
pub const fn state_len(d: usize) -> usize {
    d + d * d + 11
}

impl<const D: usize> ParticleState<f64, D> {
    /// All components ([`state_len`] in all): x, F row by row, plastic strain, `bₑ` row by
    /// row, mass.
    pub fn components(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(state_len(D));
        out.extend(self.x.iter());
        out.extend(self.f.transpose().iter());
        out.push(self.history.plastic_strain);
        out.extend(self.history.tensor.transpose().iter());
        out.push(self.mass);
        out
    }

    /// The state lifted to `Dual64` with derivative parts `tangent` (same order).
    pub fn dual(&self, tangent: &[f64]) -> ParticleState<Dual64, D> {
        let v = self.components();
        let d = |k: usize| Dual64::new(v[k], tangent[k]);
        let (f0, h0) = (D, D + D * D);
        ParticleState {
            x: Vector::<Dual64, D>::from_fn(|a, _| d(a)),
            f: Tensor::<Dual64, D>::from_fn(|r, c| d(f0 + r * D + c)),
            history: MaterialState {
                plastic_strain: d(h0),
                tensor: nalgebra::Matrix3::<Dual64>::from_fn(|r, c| d(h0 + 1 + r * 3 + c)),
            },
            mass: d(h0 + 10),
        }
    }
}

impl<const D: usize> ParticleState<Dual64, D> {
    /// The derivative parts in the order of [`ParticleState::components`].
    pub fn tangent(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(state_len(D));
        out.extend(self.x.iter().map(|v| v.eps));
        out.extend(self.f.transpose().iter().map(|v| v.eps));
        out.push(self.history.plastic_strain.eps);
        out.extend(self.history.tensor.transpose().iter().map(|v| v.eps));
        out.push(self.mass.eps);
        out
    }
}

/// What is fixed for a particle in one (sub-)step.
#[derive(Clone, Copy, Debug)]
pub struct Setting<'a, const D: usize> {
    /// The grid.
    pub grid: &'a Grid<D>,
    /// Shape functions.
    pub shape: Shape,
    /// Reference half-width (GIMP).
    pub half_width0: Vector<f64, D>,
    /// Reference volume `V⁰`.
    pub volume0: f64,
    /// Load factor `λ` at the end of the (sub-)step.
    pub load_factor: f64,
}

/// One stencil node's share of a particle's step.
#[derive(Clone, Copy, Debug)]
pub struct NodeShare<T, const D: usize> {
    /// Flat grid index.
    pub flat: usize,
    /// `N_i(xₚ)`.
    pub weight: T,
    /// `f_int,i`.
    pub internal: Vector<T, D>,
    /// `f_ext,i`.
    pub external: Vector<T, D>,
}

/// A particle's part of a (sub-)step: its nodal forces and its end state.
#[derive(Clone, Debug)]
pub struct ParticleStep<T, const D: usize> {
    /// Per stencil node.
    pub nodes: Vec<NodeShare<T, D>>,
    /// End state (the mass unchanged).
    pub end: ParticleState<T, D>,
}

/// The loads acting on a particle, in scalar type `T`.
#[derive(Clone, Copy, Debug)]
pub struct Loads<T, const D: usize> {
    /// Gravity `g`.
    pub gravity: Vector<T, D>,
    /// Total point load on the particle at load factor 1.
    pub point: Vector<T, D>,
}

/// The particle's part of the step (module docs) for the nodal increments `du(flat, a)` and a
/// perturbation `perturbation` added to `ΔF` (zero in value; seeded for `∂/∂ΔF`). `None`
/// when `det ΔF ≤ 0`.
pub fn particle_step<T: Scalar + From<f64>, const D: usize>(
    setting: &Setting<'_, D>,
    material: &Material<T>,
    state: &ParticleState<T, D>,
    loads: &Loads<T, D>,
    du: impl Fn(usize, usize) -> T,
    perturbation: &Tensor<T, D>,
) -> Option<ParticleStep<T, D>> {
    let grid = setting.grid;
    let hw = particle_half_width(
        setting.shape,
        grid.h,
        &setting.half_width0.map(T::cst),
        &state.f,
    );
    let stencil = Stencil::new(setting.shape, grid, &state.x, &hw);
    let g = delta_f::<T, T, D>(&stencil, &du) + perturbation;
    let (s, _, history) = stress_update(
        material,
        &state.f,
        &state.history,
        T::cst(setting.volume0),
        &g,
    )?;
    let lambda = T::cst(setting.load_factor);
    let q = loads.gravity * (state.mass * lambda) + loads.point * lambda;
    let mut x = state.x;
    let mut nodes = Vec::with_capacity(stencil.len());
    stencil.for_each(|n| {
        for a in 0..D {
            x[a] += n.weight * du(n.flat, a);
        }
        nodes.push(NodeShare {
            flat: n.flat,
            weight: n.weight,
            internal: s * n.gradient,
            external: q * n.weight,
        });
    });
    Some(ParticleStep {
        nodes,
        end: ParticleState {
            x,
            f: g * state.f,
            history,
            mass: state.mass,
        },
    })
}

/// The weights of [`particle_step`]'s outputs in `ψₚ` (module docs).
#[derive(Clone, Copy, Debug)]
pub struct Cotangent<'a, const D: usize> {
    /// `a_i` per grid node (flat index).
    pub internal: &'a [Vector<f64, D>],
    /// `c_i` per grid node.
    pub external: &'a [Vector<f64, D>],
    /// `(x̄', F̄', h̄', m̄')` of the end state, in the order of [`ParticleState::components`].
    pub end: &'a [f64],
}

impl<const D: usize> Cotangent<'_, D> {
    /// `ψₚ` of a particle's step.
    pub fn contract<T: Scalar>(&self, step: &ParticleStep<T, D>) -> T {
        let mut psi = T::zero();
        for n in &step.nodes {
            for a in 0..D {
                psi += n.internal[a] * T::cst(self.internal[n.flat][a])
                    + n.external[a] * T::cst(self.external[n.flat][a]);
            }
        }
        let e = &step.end;
        let mut k = 0;
        let mut add = |v: T| {
            psi += v * T::cst(self.end[k]);
            k += 1;
        };
        e.x.iter().for_each(|&v| add(v));
        e.f.transpose().iter().for_each(|&v| add(v));
        add(e.history.plastic_strain);
        e.history.tensor.transpose().iter().for_each(|&v| add(v));
        add(e.mass);
        psi
    }
}

/// The derivative part of `ψₚ` for a particle's step evaluated with `Dual64` inputs (one
/// seeded direction): `(∂ψₚ/∂inputs)·(seed)`; `None` at an inverted state.
pub fn psi_derivative<const D: usize>(
    setting: &Setting<'_, D>,
    material: &Material<Dual64>,
    state: &ParticleState<Dual64, D>,
    loads: &Loads<Dual64, D>,
    du: impl Fn(usize, usize) -> Dual64,
    perturbation: &Tensor<Dual64, D>,
    cotangent: &Cotangent<'_, D>,
) -> Option<f64> {
    let step = particle_step(setting, material, state, loads, du, perturbation)?;
    Some(cotangent.contract(&step).eps)
}

/// `∂ψₚ/∂ΔF` (the derivative with respect to a perturbation of `ΔF`) at the real state, by
/// `D²` `Dual64` evaluations; `None` at an inverted state.
pub fn psi_by_delta_f<const D: usize>(
    setting: &Setting<'_, D>,
    material: &Material<Dual64>,
    state: &ParticleState<f64, D>,
    loads: &Loads<f64, D>,
    du: impl Fn(usize, usize) -> f64,
    cotangent: &Cotangent<'_, D>,
) -> Option<Tensor<f64, D>> {
    let state = state.dual(&vec![0.0; state_len(D)]);
    let loads = lift_loads(loads);
    let du = |n: usize, c: usize| Dual64::from_re(du(n, c));
    let mut out = Tensor::<f64, D>::zeros();
    for a in 0..D {
        for b in 0..D {
            let e = Tensor::<Dual64, D>::from_fn(|r, c| {
                Dual64::new(0.0, if (r, c) == (a, b) { 1.0 } else { 0.0 })
            });
            out[(a, b)] = psi_derivative(setting, material, &state, &loads, du, &e, cotangent)?;
        }
    }
    Some(out)
}

/// Whether a model reads and updates its history (J2, Drucker–Prager). The others return it
/// unchanged and their stress does not depend on it, so its adjoint passes through a step as
/// it is (`h̄ = h̄'`) without an evaluation.
pub fn carries_history<T>(material: &Material<T>) -> bool {
    matches!(material.model, Model::J2(_) | Model::DruckerPrager(_))
}

/// `∂ψₚ/∂sₚ` in the order of [`ParticleState::components`], by one `Dual64` evaluation per
/// component (the history's `∂ψₚ/∂h = h̄'` taken directly for a model without one);
/// `None` at an inverted state.
pub fn psi_by_state<const D: usize>(
    setting: &Setting<'_, D>,
    material: &Material<Dual64>,
    state: &ParticleState<f64, D>,
    loads: &Loads<f64, D>,
    du: impl Fn(usize, usize) -> f64,
    cotangent: &Cotangent<'_, D>,
) -> Option<Vec<f64>> {
    let loads = lift_loads(loads);
    let du = |n: usize, c: usize| Dual64::from_re(du(n, c));
    let zero = Tensor::<Dual64, D>::zeros();
    let history = D + D * D..D + D * D + 10;
    let passes = !carries_history(material);
    let mut seed = vec![0.0; state_len(D)];
    (0..state_len(D))
        .map(|k| {
            if passes && history.contains(&k) {
                return Some(cotangent.end[k]);
            }
            seed[k] = 1.0;
            let s = state.dual(&seed);
            seed[k] = 0.0;
            psi_derivative(setting, material, &s, &loads, du, &zero, cotangent)
        })
        .collect()
}

/// The loads as `Dual64` constants.
pub fn lift_loads<const D: usize>(loads: &Loads<f64, D>) -> Loads<Dual64, D> {
    Loads {
        gravity: loads.gravity.map(Dual64::from_re),
        point: loads.point.map(Dual64::from_re),
    }
}
