//! One particle's part of a converged implicit (sub-)step, generic over the scalar.
//!
//! For particle `p` with start-of-step state `sₚ = (xₚ, Fₚ, historyₚ, vₚ, mₚ)` and the nodal
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
//! increments of its own stencil. A Newmark step also reads the particle's mass and velocity
//! through the grid's mass matrix and momentum, and adds the grid's velocity increment to
//! `vₚ` (`super::inertia`); here `vₚ` passes through unchanged. The forward-mode pass ([`super::tangent`]) evaluates
//! [`particle_step`] with `Dual64` inputs; the reverse pass takes the same derivatives by the
//! chain rule through the step's linearisation ([`super::pullback`]).

use loam_core::constitutive::{HISTORY_LEN, MaterialState, Model};
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
    /// Velocity `vₚ` (read and updated by Newmark steps only).
    pub v: Vector<T, D>,
    /// Mass `mₚ` (a constant of the run; its adjoint carries the density's gradient).
    pub mass: T,
}

/// Number of scalar components of a [`ParticleState`]: `D + D² + HISTORY_LEN + D + 1`.
pub const fn state_len(d: usize) -> usize {
    2 * d + d * d + HISTORY_LEN + 1
}

/// Index of the velocity's first component in [`ParticleState::components`].
pub const fn velocity_index(d: usize) -> usize {
    d + d * d + HISTORY_LEN
}

/// Index of the mass in [`ParticleState::components`] (the last one).
pub const fn mass_index(d: usize) -> usize {
    state_len(d) - 1
}

impl<const D: usize> ParticleState<f64, D> {
    /// All components ([`state_len`] in all): x, F row by row, the history
    /// ([`MaterialState::components`]), velocity, mass.
    pub fn components(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(state_len(D));
        out.extend(self.x.iter());
        out.extend(self.f.transpose().iter());
        out.extend(self.history.components());
        out.extend(self.v.iter());
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
            history: MaterialState::from_components(|k| d(h0 + k)),
            v: Vector::<Dual64, D>::from_fn(|a, _| d(h0 + HISTORY_LEN + a)),
            mass: d(h0 + HISTORY_LEN + D),
        }
    }
}

impl<const D: usize> ParticleState<Dual64, D> {
    /// The derivative parts in the order of [`ParticleState::components`].
    pub fn tangent(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(state_len(D));
        out.extend(self.x.iter().map(|v| v.eps));
        out.extend(self.f.transpose().iter().map(|v| v.eps));
        out.extend(self.history.components().iter().map(|v| v.eps));
        out.extend(self.v.iter().map(|v| v.eps));
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
    /// Load factor `λ` at the end of the (sub-)step (1 in a Newmark step: its loads act in
    /// full).
    pub load_factor: f64,
    /// The factor on gravity: `λ`, or 1 where gravity acts in full (a Newmark step, a
    /// prestressed scene: [`loam_implicit::ImplicitConfig::gravity_in_full`]).
    pub gravity_factor: f64,
}

impl<const D: usize> Setting<'_, D> {
    /// The stencil of a particle in `state`: at its position, with the cpGIMP half-width
    /// following its deformation gradient.
    pub fn stencil<T: Scalar>(&self, state: &ParticleState<T, D>) -> Stencil<T, D> {
        let hw = particle_half_width(
            self.shape,
            self.grid.h,
            &self.half_width0.map(T::cst),
            &state.f,
        );
        Stencil::new(self.shape, self.grid, &state.x, &hw)
    }
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
    /// End state (the mass unchanged, the velocity before the grid motion of a Newmark step).
    pub end: ParticleState<T, D>,
}

/// The loads acting on a particle, in scalar type `T`.
#[derive(Clone, Copy, Debug)]
pub struct Loads<T, const D: usize> {
    /// Gravity `g`.
    pub gravity: Vector<T, D>,
    /// Total point load on the particle at load factor 1.
    pub point: Vector<T, D>,
    /// The balance of the particle's initial stress, in full at every step
    /// ([`loam_implicit::ImplicitConfig::balance`]; data of the initial state).
    pub balance: Vector<T, D>,
}

/// The particle's part of the step (module docs) for the nodal increments `du(flat, a)`;
/// `None` when `det ΔF ≤ 0`.
pub fn particle_step<T: Scalar + From<f64>, const D: usize>(
    setting: &Setting<'_, D>,
    material: &Material<T>,
    state: &ParticleState<T, D>,
    loads: &Loads<T, D>,
    du: impl Fn(usize, usize) -> T,
) -> Option<ParticleStep<T, D>> {
    let stencil = setting.stencil(state);
    let g = delta_f::<T, T, D>(&stencil, &du);
    let (s, _, history) = stress_update(
        material,
        &state.f,
        &state.history,
        T::cst(setting.volume0),
        &g,
    )?;
    let lambda = T::cst(setting.load_factor);
    let q = loads.gravity * (state.mass * T::cst(setting.gravity_factor))
        + loads.point * lambda
        + loads.balance;
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
            v: state.v,
            mass: state.mass,
        },
    })
}

/// Whether a model reads and updates its history (J2, Drucker–Prager, Mohr–Coulomb, Modified
/// Cam-Clay). The others return it unchanged and their stress does not depend on it, so its
/// adjoint passes through a step as it is (`h̄ = h̄'`) without an evaluation. The match names
/// every model, so that a new one must be placed here.
pub fn carries_history<T>(material: &Material<T>) -> bool {
    match material.model {
        Model::J2(_)
        | Model::DruckerPrager(_)
        | Model::MohrCoulomb(_)
        | Model::ModifiedCamClay(_) => true,
        Model::LinearElastic(_) | Model::NeoHookean(_) | Model::Hencky(_) | Model::Fluid(_) => {
            false
        }
    }
}

/// The loads as `Dual64` constants.
pub fn lift_loads<const D: usize>(loads: &Loads<f64, D>) -> Loads<Dual64, D> {
    Loads {
        gravity: loads.gravity.map(Dual64::from_re),
        point: loads.point.map(Dual64::from_re),
        balance: loads.balance.map(Dual64::from_re),
    }
}
