//! The coupled (u–p) step of a saturated soil in both passes of the implicit adjoint.
//!
//! A coupled sub-step maps each particle's state `sₚ = (xₚ, Fₚ, hₚ, vₚ, mₚ)` and excess pore
//! pressure `p_eₚ` to their end values, through the nodal unknowns `(Δu_i, p̂_i)` that solve
//! `R = 0` ([`loam_implicit::flow`]): per particle ([`particle_step`], generic over the
//! scalar, the solver's own kernel [`coupled_update`] inside)
//!
//! ```text
//! mixture rows  f_i = V⁰ (τ′ − α Jⁿ ΔJ p I) ΔF⁻ᵀ ∇N_i − q N_i          p = s p̂ + p_h(xₚ)
//! fluid rows    g_i = volume N_i + flux · ∇N_i − Δt s Q N_i             (s the row scale)
//! end state     xₚ' = xₚ + Σ N_i Δu_i,  Fₚ' = ΔF Fₚ,  hₚ',  p_eₚ' = s p̂
//! ```
//!
//! plus the pressure stabilisation, which couples the particles of one grid cell (a patch
//! `P`): `Σ_{p∈P} s wₚ (Δpₚ − m) N_i(xₚ)` with `wₚ = Vₚⁿ/Gₚ`, `Δpₚ = p_eₚ' − p_eₚ` and
//! `m = Σ w Δp / Σ w`. Everything but the stabilisation's mean is one particle's; the
//! stabilisation's share of `ψ = Σ_i b_i · (stabilisation)_i` is
//! `Σ_p s wₚ (Δpₚ − m)(Bₚ − B̄)` with `Bₚ = Σ_i b_i N_i(xₚ)` and `B̄ = Σ w B / Σ w` (because
//! `Σ_p wₚ (Δpₚ − m) = 0`), and its gradient by one particle's inputs is that of its own
//! term with `m` and `B̄` held: `∂/∂Δpₚ = s wₚ (Bₚ − B̄)`, `∂/∂Bₚ = s wₚ (Δpₚ − m)`,
//! `∂/∂wₚ = s (Δpₚ − m)(Bₚ − B̄)`, exactly the sums' partials. So the whole step is a sum of
//! per-particle terms once each patch's `(m, B̄)` is known.
//!
//! Both passes evaluate the one kernel:
//!
//! - the reverse pass ([`reverse`]) weights a particle's outputs into the scalar
//!   `ψₚ = Σ_i [a_i·f_i + b_i g_i] + s̄'ₚ·sₚ' + p̄'ₚ p_eₚ' + (stabilisation)`, with `a = r̄ − λ_u`
//!   (`r̄` the observed reactions) and `b = −λ_p` from `Jᵀλ = ∂ψ/∂(Δu, p̂)|_{λ=0}`, and takes
//!   its gradient by the particle's inputs with multi-lane duals. The unknowns enter a
//!   particle only through the stencil sums `(ΔF, p̂, ∇ⁿp̂, Δx)` ([`StencilSums`]), so the
//!   duals seed those (and the state components the step reads, and the excess), and the
//!   gradient by the unknowns follows by the chain rule through the shape functions. Two
//!   evaluations per particle and sub-step:
//!   1. *pass 1*, with `λ = 0`: the kernel alone ([`coupled_update`]) with the sums
//!      `(ΔF, p̂, ∇ⁿp̂)` seeded ([`coupled_lanes`]: 7 in 2D, 13 in 3D) gives the derivative of
//!      its rows, which `J` is assembled from, and of the end excess and history
//!      ([`SumsJacobian`]); the right-hand side `∂ψ/∂(Δu, p̂)|_{λ=0}` is that derivative
//!      contracted with the weights `ψ` puts on them ([`Local::sums_partial`]);
//!   2. *the final pass*, with `λ`: the sums' partials are again pass 1's derivative
//!      contracted, now with `λ`'s weights; the state's follow from the step split where it
//!      is linear ([`Local::partials`]): the kernel's start (`Fⁿ`, history, excess, the
//!      vertical position through the hydrostatic pressure below a water table) by
//!      multi-lane duals with the stencil held (5 lanes for a 2D particle without history
//!      above the water table, 6 below it, at most [`LANES`] a time), the stencil
//!      `(xₚ, Fₚ) ↦ (N_i, ∇N_i)` by one more (the rows and sums are linear in it, so its
//!      weights are closed form), the end position `x' = x + Δx` and the mass in closed
//!      form. Each parameter's share is one `Dual64` evaluation of the kernel with the
//!      parameter seeded, plus the loads' share in closed form;
//! - the forward-mode pass ([`model_tangents`], the oracle) evaluates the same kernel with
//!   `Dual64` states and parameters, solves `J u̇ = −Ṙ` and carries `ṡ'`, `ṗ_e'` forward.
//!
//! A BDF2 step also reads the previous step's fluid-content change `ΔΞⁿₚ` and excess-pressure
//! increment `Δp_eⁿₚ` (`c₁ ΔΞⁿ` enters the fluid rows, `c₁ Δp_eⁿ` the stabilisation's
//! increment, [`loam_implicit::flow::TimeIntegration::Bdf2`]), and hands on its own `ΔΞₚ` and
//! `Δpₚ`: they are two more inputs of the particle ([`FluidInputs`]) and two more outputs,
//! weighted in `ψₚ` by their adjoints `ΔΞ̄ₚ`, `Δp̄ₚ` from the next sub-step's reverse (zero
//! after the last, and through a backward-Euler step, which reads them with `c₁ = 0`). The
//! recorded sub-step keeps what it read ([`super::record::SubStep::fluid_history`]).
//!
//! The row scale `s = G_ref/h` is held in both: the physical solution does not depend on it
//! (it scales the pressure unknowns and the fluid rows alike), so it carries no derivative.

use super::kernel::{Loads, ParticleState, Setting, carries_history, mass_index, state_len};
use super::observe::{ImplicitObservations, Quantity};
use super::params::ImplicitParam;
use super::pullback::{Node, pull_geometry, stencil_jacobian};
use super::record::{Replay, SubStep, Trajectory};
use super::seeds::StepSeeds;
use crate::error::AdjointError;
use crate::params::MaterialField;
use loam_core::tensor::{Tensor, Vector, det};
use loam_core::{Material, Particles, Scalar, Stencil};
use loam_implicit::flow::{
    CoupledStart, CoupledTangent, FlowFrozen, Hydraulic, PoreFluid, coupled_lanes, coupled_update,
};
use loam_implicit::kernel::delta_f;
use loam_implicit::system::StepSystem;
use loam_implicit::{ImplicitConfig, ImplicitError, ImplicitSolver, NodeDof};
use nalgebra::SVector;
use num_dual::{Derivative, Dual64, DualSVec64};
use rayon::prelude::*;

/// Inputs differentiated per evaluation of the final pass's gradient.
pub const LANES: usize = 16;

/// The final pass's lanes for a particle with at most this many differentiated inputs (the
/// state of a 2D particle without history: `Fⁿ`, the excess and below a water table the
/// vertical position, 5 or 6): a dual's cost grows with its lanes, not with those seeded.
const NARROW_LANES: usize = 6;

/// What one particle sees of the pore fluid in a sub-step, besides its state.
#[derive(Clone, Copy, Debug)]
pub struct FluidSetting<'a, const D: usize> {
    /// The run's pore fluid (water table, unit weight of water).
    pub fluid: &'a PoreFluid<D>,
    /// Time step `Δt` (s).
    pub dt: f64,
    /// Row scale `s = G_ref/h`.
    pub scale: f64,
    /// `A_p/ℓ_p` of a particle on a drained free surface (zero elsewhere).
    pub conductance: f64,
    /// Volume rate `Q` of water fed through the particle (zero elsewhere).
    pub inflow: f64,
    /// `c₁` of a BDF2 step, the share of the previous step's fluid-content change and
    /// pressure increment it carries; zero under backward Euler.
    pub carry: f64,
}

/// A particle's pore-fluid inputs to a coupled sub-step: its start excess pore pressure and
/// what a BDF2 step reads of the previous step, `ΔΞⁿ` and `Δp_eⁿ`, which `frozen` weights
/// by `c₁` into [`FlowFrozen`] (a backward-Euler step has `c₁ = 0`).
#[derive(Clone, Copy, Debug)]
pub struct FluidInputs<T> {
    /// Excess pore pressure `p_e` at the start (Pa).
    pub excess: T,
    /// The previous step's fluid-content change `ΔΞⁿ` (m³; m² in 2D).
    pub content: T,
    /// The previous step's excess-pressure increment `Δp_eⁿ` (Pa).
    pub increment: T,
}

impl<const D: usize> FluidSetting<'_, D> {
    /// The hydrostatic pressure `p_h(x) = γ_w (z_w − x_D)` below the water table, zero above
    /// it or without one.
    fn hydrostatic<T: Scalar>(&self, x: &Vector<T, D>) -> T {
        match self.fluid.water_table {
            Some(z) if z > x[D - 1].re() => (T::cst(z) - x[D - 1]) * T::cst(self.fluid.unit_weight),
            _ => T::zero(),
        }
    }

    /// `∂p_h/∂x_D` at `x`.
    fn hydrostatic_slope(&self, x: &Vector<f64, D>) -> f64 {
        match self.fluid.water_table {
            Some(z) if z > x[D - 1] => -self.fluid.unit_weight,
            _ => 0.0,
        }
    }
}

/// One stencil node's share of a coupled particle step.
#[derive(Clone, Copy, Debug)]
pub struct CoupledNode<T, const D: usize> {
    /// Flat grid index.
    pub flat: usize,
    /// `N_i(xₚ)`.
    pub weight: T,
    /// Mixture row: internal force `V⁰ (τ′ − α J p I) ΔF⁻ᵀ ∇N_i`.
    pub internal: Vector<T, D>,
    /// Mixture row: external force `q N_i`.
    pub external: Vector<T, D>,
    /// Fluid row: `volume N_i + flux · ∇N_i` (scaled).
    pub fluid: T,
    /// Fluid row, external side: the inflow `Δt s Q N_i`.
    pub inflow: T,
}

/// A particle's part of a coupled sub-step (module docs).
#[derive(Clone, Debug)]
pub struct CoupledParticle<T, const D: usize> {
    /// Per stencil node.
    pub nodes: Vec<CoupledNode<T, D>>,
    /// End state.
    pub end: ParticleState<T, D>,
    /// End excess pore pressure `p_e' = s p̂` (Pa).
    pub excess: T,
    /// `Δp = p_e' − p_e`, which the next step carries under BDF2.
    pub increment: T,
    /// The fluid-content change `ΔΞ` ([`loam_implicit::flow::Coupled::content`]), which the
    /// next step carries under BDF2.
    pub content: T,
    /// The stabilisation's increment `Δp − c₁ Δp_eⁿ` (`Δp` under backward Euler).
    pub stabilised: T,
    /// Stabilisation weight `w = Vⁿ/G`.
    pub stabilisation: T,
}

/// The sums over a particle's stencil through which the nodal unknowns `u(flat, c)` enter
/// its step, each linear in them:
///
/// ```text
/// ΔF = I + Σ_i Δu_i ⊗ ∇N_i,   p̂ = Σ_i N_i p̂_i,   ∇ⁿp̂ = Σ_i p̂_i ∇N_i,   Δx = Σ_i N_i Δu_i
/// ```
#[derive(Clone, Copy, Debug)]
pub struct StencilSums<T: Scalar, const D: usize> {
    /// `ΔF`.
    pub delta_f: Tensor<T, D>,
    /// `p̂`.
    pub p_hat: T,
    /// `∇ⁿp̂`.
    pub grad_p_hat: Vector<T, D>,
    /// `Δx`.
    pub dx: Vector<T, D>,
}

impl<T: Scalar + From<f64>, const D: usize> StencilSums<T, D> {
    /// The sums over `stencil` for the unknowns `u(flat, c)` (`c < D`: displacement
    /// increments; `c = D`: the pressure unknown).
    pub fn of(stencil: &Stencil<T, D>, u: impl Fn(usize, usize) -> T) -> Self {
        let mut sums = Self {
            delta_f: delta_f::<T, T, D>(stencil, &u),
            p_hat: T::zero(),
            grad_p_hat: Vector::<T, D>::zeros(),
            dx: Vector::<T, D>::zeros(),
        };
        stencil.for_each(|n| {
            let p = u(n.flat, D);
            sums.p_hat += n.weight * p;
            sums.grad_p_hat += n.gradient * p;
            for a in 0..D {
                sums.dx[a] += n.weight * u(n.flat, a);
            }
        });
        sums
    }
}

/// The particle's part of a coupled sub-step with the stencil sums that `sums` gives for its
/// stencil ([`StencilSums::of`] for the nodal unknowns); `None` where the particle inverts.
#[allow(clippy::too_many_arguments)]
pub fn particle_step<T: Scalar + From<f64>, const D: usize>(
    setting: &Setting<'_, D>,
    fluid: &FluidSetting<'_, D>,
    material: &Material<T>,
    hydraulic: &Hydraulic<T>,
    state: &ParticleState<T, D>,
    inputs: &FluidInputs<T>,
    loads: &Loads<T, D>,
    sums: impl FnOnce(&Stencil<T, D>) -> StencilSums<T, D>,
) -> Option<CoupledParticle<T, D>> {
    let stencil = setting.stencil(state);
    let StencilSums {
        delta_f: g,
        p_hat,
        grad_p_hat: grad,
        dx,
    } = sums(&stencil);
    let frozen = frozen(setting, fluid, material, hydraulic, state, inputs);
    let c = coupled_update(
        material,
        &CoupledStart {
            f_n: &state.f,
            history: &state.history,
            volume0: setting.volume0,
            fluid: &frozen,
        },
        hydraulic,
        fluid.dt,
        fluid.scale,
        &g,
        p_hat,
        &grad,
    )?;
    let q = loads.gravity * (state.mass * T::cst(setting.gravity_factor))
        + loads.point * T::cst(setting.load_factor)
        + loads.balance;
    let inflow = T::cst(fluid.dt * fluid.scale * fluid.inflow);
    let mut nodes = Vec::with_capacity(stencil.len());
    stencil.for_each(|n| {
        nodes.push(CoupledNode {
            flat: n.flat,
            weight: n.weight,
            internal: c.momentum * n.gradient,
            external: q * n.weight,
            fluid: c.volume * n.weight + c.flux.dot(&n.gradient),
            inflow: inflow * n.weight,
        });
    });
    Some(CoupledParticle {
        nodes,
        end: ParticleState {
            x: state.x + dx,
            f: g * state.f,
            history: c.state,
            v: state.v,
            mass: state.mass,
        },
        excess: c.excess,
        increment: c.excess - inputs.excess,
        content: c.content,
        stabilised: c.excess - inputs.excess - frozen.carried_increment,
        stabilisation: frozen.weight,
    })
}

/// What the kernel holds of a particle's start state: its excess and hydrostatic pore
/// pressure, the stabilisation weight `wₚ = Vⁿ/G`, the drained surface's leakage and the
/// shares `c₁ ΔΞⁿ`, `c₁ Δp_eⁿ` a BDF2 step carries.
fn frozen<T: Scalar + From<f64>, const D: usize>(
    setting: &Setting<'_, D>,
    fluid: &FluidSetting<'_, D>,
    material: &Material<T>,
    hydraulic: &Hydraulic<T>,
    state: &ParticleState<T, D>,
    inputs: &FluidInputs<T>,
) -> FlowFrozen<T> {
    let carry = T::cst(fluid.carry);
    let shear = material.shear_modulus_in(&state.history);
    FlowFrozen {
        excess: inputs.excess,
        hydrostatic: fluid.hydrostatic(&state.x),
        weight: det(&state.f) * T::cst(setting.volume0)
            / if shear.re() > 0.0 {
                shear
            } else {
                T::cst(f64::MIN_POSITIVE)
            },
        leakage: hydraulic.mobility * T::cst(fluid.conductance),
        carried: carry * inputs.content,
        carried_increment: carry * inputs.increment,
    }
}

/// The weights of a particle's outputs in `ψₚ` (module docs).
#[derive(Clone, Copy, Debug)]
pub struct CoupledCotangent<'a, const D: usize> {
    /// `a_i` on the mixture rows' internal force, per grid node.
    pub internal: &'a [Vector<f64, D>],
    /// `c_i` on the mixture rows' external force, per grid node.
    pub external: &'a [Vector<f64, D>],
    /// `b_i` on the fluid rows (and `−b_i` on their inflow), per grid node.
    pub fluid: &'a [f64],
    /// `s̄'` of the end state ([`ParticleState::components`] order).
    pub end: &'a [f64],
    /// `p̄'` of the end excess pressure.
    pub excess: f64,
    /// The weight of the fluid-content change `ΔΞ` (what the next BDF2 step makes of it).
    pub content: f64,
    /// The weight of the increment `Δp = p_e' − p_e` (likewise).
    pub increment: f64,
    /// The particle's patch: `(m, B̄)` (module docs).
    pub patch: (f64, f64),
    /// Row scale `s`.
    pub scale: f64,
}

/// Everything fixed about one particle in one coupled sub-step.
struct Local<'a, const D: usize> {
    setting: Setting<'a, D>,
    fluid: FluidSetting<'a, D>,
    state: ParticleState<f64, D>,
    /// The pore-fluid inputs ([`FluidInputs`]).
    fluid_inputs: FluidInputs<f64>,
    loads: Loads<f64, D>,
    material: usize,
    /// Whether the material reads and updates its history ([`carries_history`]).
    carries: bool,
    /// The stencil's nodes (flat indices) in the kernel's order.
    flats: Vec<usize>,
    /// `(N_i, ∇N_i)` of the stencil's nodes at the start state, in the same order.
    shape: Vec<(f64, Vector<f64, D>)>,
}

impl<const D: usize> Local<'_, D> {
    /// Inputs: the state's components, the pore-fluid inputs (excess, `ΔΞⁿ`, `Δp_eⁿ`), then
    /// `D + 1` unknowns per stencil node.
    fn inputs(&self, system: &StepSystem<D>, x: &[f64]) -> Vec<f64> {
        let mut z = self.state.components();
        let f = &self.fluid_inputs;
        z.extend([f.excess, f.content, f.increment]);
        for &f in &self.flats {
            z.extend((0..=D).map(|c| system.dofs.value(f, c, x)));
        }
        z
    }

    /// Index of the first unknown among the inputs, and of the first stencil sum among the
    /// differentiated inputs (`ΔF` row by row, `p̂`, `∇ⁿp̂`: [`coupled_lanes`] of them).
    const UNKNOWNS: usize = state_len(D) + 3;

    /// The pore-fluid inputs of input vector `z`.
    fn fluid_of<T: Scalar>(z: &[T]) -> FluidInputs<T> {
        let k = state_len(D);
        FluidInputs {
            excess: z[k],
            content: z[k + 1],
            increment: z[k + 2],
        }
    }

    /// The unknowns of input vector `z` as `u(flat, c)`.
    fn unknowns<'s, T: Scalar>(&'s self, z: &'s [T]) -> impl Fn(usize, usize) -> T + 's {
        // A stencil visits its nodes in the order of `flats`, each for several components,
        // so the node asked for is nearly always the last one found or the next.
        let last = std::cell::Cell::new(0);
        move |flat: usize, c: usize| {
            let k = (last.get()..self.flats.len().min(last.get() + 2))
                .find(|&k| self.flats[k] == flat)
                .or_else(|| self.flats.iter().position(|&f| f == flat));
            match k {
                Some(k) => {
                    last.set(k);
                    z[Self::UNKNOWNS + k * (D + 1) + c]
                }
                None => T::zero(),
            }
        }
    }

    /// The state of input vector `z`.
    fn state_of<T: Scalar>(z: &[T]) -> ParticleState<T, D> {
        let h0 = D + D * D;
        let hl = loam_core::constitutive::HISTORY_LEN;
        ParticleState {
            x: Vector::<T, D>::from_fn(|a, _| z[a]),
            f: Tensor::<T, D>::from_fn(|r, c| z[D + r * D + c]),
            history: loam_core::MaterialState::from_components(|k| z[h0 + k]),
            v: Vector::<T, D>::from_fn(|a, _| z[h0 + hl + a]),
            mass: z[h0 + hl + D],
        }
    }

    /// The step with the inputs `z` in scalar `T` and the material and hydraulic properties
    /// given.
    fn step<T: Scalar + From<f64>>(
        &self,
        z: &[T],
        material: &Material<T>,
        hydraulic: &Hydraulic<T>,
        loads: &Loads<T, D>,
    ) -> Option<CoupledParticle<T, D>> {
        let u = self.unknowns(z);
        particle_step(
            &self.setting,
            &self.fluid,
            material,
            hydraulic,
            &Self::state_of(z),
            &Self::fluid_of(z),
            loads,
            |stencil| StencilSums::of(stencil, u),
        )
    }

    /// The differentiated inputs of the final pass: the state's components that the step
    /// reads (not the velocity, nor the mass, which enters through the load alone
    /// ([`Local::partials`]), nor the history of a material that carries none, nor in 2D
    /// the history tensor's out-of-plane entries `(a, 2)`, `(2, a)` with `a < 2`), and the
    /// excess. The kernel reads the position only through the hydrostatic pressure
    /// `p_h(x_D)`, so of the position only `x_D` below the water table is differentiated
    /// (its other partials are the end position's weights, [`Local::partials`]). The
    /// previous step's `ΔΞⁿ` and `Δp_eⁿ` are not among them ([`Local::carried_partials`]),
    /// nor are the stencil sums: their partials follow from pass 1's derivative
    /// ([`Local::sums_partial`]).
    ///
    /// A plane-strain history tensor (the elastic left Cauchy–Green tensor of every model
    /// that carries one) keeps those entries zero, and their end values do not move with any
    /// in-plane input (they are odd under the reflection `z → −z`, the inputs even), so their
    /// adjoints never reach the gradient: the initial states' tangents are zero there too.
    fn lanes(&self) -> Vec<usize> {
        let h0 = D + D * D;
        let hl = loam_core::constitutive::HISTORY_LEN;
        let in_plane = |k: usize| -> bool {
            let (r, c) = ((k - 1) / 3, (k - 1) % 3);
            D == 3 || k == 0 || k == hl - 1 || (r < D && c < D) || (r == 2 && c == 2)
        };
        let below = self.fluid.hydrostatic_slope(&self.state.x) != 0.0;
        (D - 1..D)
            .filter(|_| below)
            .chain(D..h0)
            .chain(
                (0..hl)
                    .filter(|&k| self.carries && in_plane(k))
                    .map(|k| h0 + k),
            )
            .chain([state_len(D)])
            .collect()
    }

    /// `∂ψₚ/∂(ΔF, p̂, ∇ⁿp̂)` with the particle's state held, from pass 1's derivative of its
    /// step by the stencil sums ([`SumsJacobian`]). `ψ` reads the sums through the kernel's
    /// rows, weighted per row by the stencil's cotangents
    ///
    /// ```text
    /// ∂ψ/∂momentum_kd = Σ_i a_ik ∂_d N_i,   ∂ψ/∂volume = Σ_i b_i N_i = Bₚ,   ∂ψ/∂flux_d = Σ_i b_i ∂_d N_i,
    /// ```
    ///
    /// through the end deformation gradient `F' = ΔF Fⁿ` (`∂ψ/∂ΔF_rc = Σ_k F̄'_rk Fⁿ_ck`), the
    /// end excess (weight `p̄' + Δp̄ + s wₚ (Bₚ − B̄)`, the stabilisation's share and the next
    /// step's `Δp̄` through `Δpₚ = p_e' − p_e`), the fluid-content change (weight `ΔΞ̄`) and the
    /// end history (weights `s̄'` of its components). `w` is the particle's stabilisation
    /// weight `wₚ`.
    fn sums_partial(&self, jac: &SumsJacobian, cot: &CoupledCotangent<'_, D>, w: f64) -> Vec<f64> {
        let lanes = coupled_lanes(D);
        let mut weights = vec![0.0; lanes];
        let mut b_p = 0.0;
        for (&f, (n, g)) in self.flats.iter().zip(&self.shape) {
            let (a, b) = (cot.internal[f], cot.fluid[f]);
            for k in 0..D {
                for d in 0..D {
                    weights[k * D + d] += a[k] * g[d];
                }
                weights[D * D + 1 + k] += b * g[k];
            }
            b_p += b * n;
        }
        weights[D * D] = b_p;
        let mut out = vec![0.0; lanes];
        for (o, w) in weights.iter().enumerate() {
            for (x, j) in out.iter_mut().zip(&jac.rows[o * lanes..(o + 1) * lanes]) {
                *x += w * j;
            }
        }
        let excess = cot.excess + cot.increment + cot.scale * w * (b_p - cot.patch.1);
        for (x, j) in out.iter_mut().zip(&jac.excess) {
            *x += excess * j;
        }
        if cot.content != 0.0 {
            for (x, j) in out.iter_mut().zip(&jac.content) {
                *x += cot.content * j;
            }
        }
        let h0 = D + D * D;
        for (h, row) in jac.history.chunks(lanes).enumerate() {
            let weight = cot.end[h0 + h];
            if weight != 0.0 {
                for (x, j) in out.iter_mut().zip(row) {
                    *x += weight * j;
                }
            }
        }
        let f = &self.state.f;
        for r in 0..D {
            for c in 0..D {
                out[r * D + c] += (0..D)
                    .map(|k| cot.end[D + r * D + k] * f[(c, k)])
                    .sum::<f64>();
            }
        }
        out
    }

    /// `∂ψₚ/∂(ΔΞⁿ, Δp_eⁿ)`, the partials by what a BDF2 step reads of the previous one, in
    /// closed form: they enter the step only as `c₁ ΔΞⁿ` subtracted from the fluid content in
    /// the volume row (`ψ` reads the row as `s Bₚ · volume`) and `c₁ Δp_eⁿ` subtracted from
    /// the stabilisation's increment, and no output depends on them, so
    ///
    /// ```text
    /// ∂ψ/∂ΔΞⁿ = −c₁ s Bₚ,   ∂ψ/∂Δp_eⁿ = −c₁ s wₚ (Bₚ − B̄)
    /// ```
    ///
    /// (`Bₚ = Σ_i b_i N_i`). Two more lanes in [`Local::partials`] would give the same at
    /// twice the cost of the final pass of a 2D particle without history; the forward-mode
    /// oracle [`model_tangents`] differentiates them by duals.
    fn carried_partials(&self, cot: &CoupledCotangent<'_, D>, w: f64) -> (f64, f64) {
        if self.fluid.carry == 0.0 {
            return (0.0, 0.0);
        }
        let b_p: f64 = (self.flats.iter().zip(&self.shape))
            .map(|(&f, (n, _))| cot.fluid[f] * n)
            .sum();
        let c = self.fluid.carry * cot.scale;
        (-c * b_p, -c * w * (b_p - cot.patch.1))
    }

    /// Pass 1's evaluation: the kernel alone ([`coupled_update`]) at the inputs `z`, its
    /// `L` = [`coupled_lanes`] stencil sums `(ΔF, p̂, ∇ⁿp̂)` seeded and the state held. Returns
    /// the kernel's derivative `A` (what the tangent `J` is assembled from), the derivative
    /// of the rows, the end excess, the fluid-content change and the end history by the
    /// sums, and `(Δpₚ, wₚ)` (`Δpₚ` the stabilisation's, [`CoupledParticle::stabilised`]);
    /// `None` where the particle inverts.
    fn linearise<const L: usize>(
        &self,
        z: &[f64],
        mats: &[Material<DualSVec64<L>>],
        hydraulic: &Hydraulic<DualSVec64<L>>,
    ) -> Option<(CoupledTangent<L>, SumsJacobian, (f64, f64))> {
        let lift = |v: f64| DualSVec64::<L>::from_re(v);
        let seeded = |v: f64, l: usize| {
            let mut e = SVector::<f64, L>::zeros();
            e[l] = 1.0;
            DualSVec64::new(v, Derivative::some(e))
        };
        let lifted: Vec<DualSVec64<L>> = z[..Self::UNKNOWNS].iter().copied().map(lift).collect();
        let state = Self::state_of(&lifted);
        let real = StencilSums::of(&self.setting.stencil(&Self::state_of(z)), self.unknowns(z));
        let delta_f =
            Tensor::<DualSVec64<L>, D>::from_fn(|r, c| seeded(real.delta_f[(r, c)], r * D + c));
        let p_hat = seeded(real.p_hat, D * D);
        let grad =
            Vector::<DualSVec64<L>, D>::from_fn(|r, _| seeded(real.grad_p_hat[r], D * D + 1 + r));
        let material = &mats[self.material];
        let inputs = Self::fluid_of(&lifted);
        let frozen = frozen(
            &self.setting,
            &self.fluid,
            material,
            hydraulic,
            &state,
            &inputs,
        );
        let start = CoupledStart {
            f_n: &state.f,
            history: &state.history,
            volume0: self.setting.volume0,
            fluid: &frozen,
        };
        let (dt, scale) = (self.fluid.dt, self.fluid.scale);
        let c = coupled_update(
            material, &start, hydraulic, dt, scale, &delta_f, p_hat, &grad,
        )?;
        let lanes = |v: &DualSVec64<L>| -> [f64; L] {
            std::array::from_fn(|k| v.eps.0.as_ref().map_or(0.0, |e| e[k]))
        };
        let momentum = c.momentum.transpose();
        let rows: Vec<&DualSVec64<L>> = (momentum.iter())
            .chain(std::iter::once(&c.volume))
            .chain(c.flux.iter())
            .collect();
        let a: CoupledTangent<L> = std::array::from_fn(|o| lanes(rows[o]));
        let history = if self.carries {
            (c.state.components().iter()).flat_map(lanes).collect()
        } else {
            Vec::new()
        };
        let jacobian = SumsJacobian {
            rows: a.iter().flatten().copied().collect(),
            excess: lanes(&c.excess).to_vec(),
            content: lanes(&c.content).to_vec(),
            history,
        };
        let stabilised = c.excess.re - inputs.excess.re - frozen.carried_increment.re;
        Some((a, jacobian, (stabilised, frozen.weight.re)))
    }

    /// The particle's stencil at its start state with its derivative by `(x, F)`
    /// ([`stencil_jacobian`]), the stencil sums at the unknowns of `z`, and the weights `ψₚ`
    /// puts on the kernel's rows.
    fn pulled(&self, z: &[f64], cot: &CoupledCotangent<'_, D>) -> Pulled<D> {
        let u = self.unknowns(z);
        let state = Self::state_of(z);
        let (nodes, geometry) = match D {
            2 => stencil_jacobian::<6, D>(&self.setting, &state, &u),
            3 => stencil_jacobian::<12, D>(&self.setting, &state, &u),
            _ => unreachable!("D is 2 or 3"),
        };
        let pressures: Vec<f64> = nodes.iter().map(|n| u(n.flat, D)).collect();
        let mut out = Pulled {
            delta_f: Tensor::<f64, D>::identity(),
            p_hat: 0.0,
            grad: Vector::<f64, D>::zeros(),
            m_bar: Tensor::<f64, D>::zeros(),
            b_p: 0.0,
            flux_bar: Vector::<f64, D>::zeros(),
            external: Vector::<f64, D>::zeros(),
            nodes: Vec::new(),
            geometry,
            pressures: Vec::new(),
        };
        for (n, &p) in nodes.iter().zip(&pressures) {
            out.delta_f += n.du * n.gradient.transpose();
            out.p_hat += n.weight * p;
            out.grad += n.gradient * p;
            out.m_bar += cot.internal[n.flat] * n.gradient.transpose();
            out.b_p += cot.fluid[n.flat] * n.weight;
            out.flux_bar += n.gradient * cot.fluid[n.flat];
            out.external += cot.external[n.flat] * n.weight;
        }
        out.nodes = nodes;
        out.pressures = pressures;
        out
    }

    /// The part of `ψₚ` that the kernel's start moves with the stencil held (`pulled`): the
    /// start state and excess of `z` through [`frozen`] and [`coupled_update`], the outputs
    /// weighted as `ψₚ` weighs them through the rows (`M̄ = Σ_i a_i ⊗ ∇N_i` on the momentum,
    /// `Bₚ = Σ_i b_i N_i` on the volume, `Σ_i b_i ∇N_i` on the flux), the end state (but
    /// the velocity and mass, which pass through), the end excess, the increment, the
    /// fluid-content change and the stabilisation's term. Also returns the real parts of
    /// `(M, volume, flux, wₚ (Δpₚ − m))`.
    fn kernel_psi<T: Scalar + From<f64>>(
        &self,
        pulled: &Pulled<D>,
        cot: &CoupledCotangent<'_, D>,
        z: &[T],
        material: &Material<T>,
        hydraulic: &Hydraulic<T>,
    ) -> Option<(T, KernelReal<D>)> {
        let start = Self::state_of(z);
        let inputs = Self::fluid_of(z);
        let frozen = frozen(
            &self.setting,
            &self.fluid,
            material,
            hydraulic,
            &start,
            &inputs,
        );
        let g = pulled.delta_f.map(T::cst);
        let c = coupled_update(
            material,
            &CoupledStart {
                f_n: &start.f,
                history: &start.history,
                volume0: self.setting.volume0,
                fluid: &frozen,
            },
            hydraulic,
            self.fluid.dt,
            self.fluid.scale,
            &g,
            T::cst(pulled.p_hat),
            &pulled.grad.map(T::cst),
        )?;
        let (m, b_bar) = cot.patch;
        let stabilised = c.excess - inputs.excess - frozen.carried_increment;
        let mut psi = c.volume * T::cst(pulled.b_p) + c.excess * T::cst(cot.excess + cot.increment)
            - inputs.excess * T::cst(cot.increment)
            + c.content * T::cst(cot.content)
            + frozen.weight * (stabilised - T::cst(m)) * T::cst(cot.scale * (pulled.b_p - b_bar));
        for r in 0..D {
            psi += c.flux[r] * T::cst(pulled.flux_bar[r]) + start.x[r] * T::cst(cot.end[r]);
            for k in 0..D {
                psi += c.momentum[(r, k)] * T::cst(pulled.m_bar[(r, k)]);
                let end_f = (0..D).fold(T::zero(), |e, j| e + g[(r, j)] * start.f[(j, k)]);
                psi += end_f * T::cst(cot.end[D + r * D + k]);
            }
        }
        if self.carries {
            let h0 = D + D * D;
            let weights = &cot.end[h0..h0 + loam_core::constitutive::HISTORY_LEN];
            for (v, &w) in c.state.components().iter().zip(weights) {
                if w != 0.0 {
                    psi += *v * T::cst(w);
                }
            }
        }
        let real = (
            c.momentum.map(|v| v.re()),
            c.volume.re(),
            c.flux.map(|v| v.re()),
            frozen.weight.re() * (stabilised.re() - m),
        );
        Some((psi, real))
    }

    /// The partials of `ψₚ` by the inputs `lanes` (state components and excess, by index)
    /// with the unknowns held, from `sums_bar = ∂ψₚ/∂(ΔF, p̂, ∇ⁿp̂)` ([`Local::sums_partial`])
    /// and the step split where it is linear:
    ///
    /// - [`Local::kernel_psi`] by `L`-lane duals, `L` lanes at a time;
    /// - the stencil `(xₚ, Fₚ) ↦ (N_i, ∇N_i)`, differentiated in `pulled`, weighted by
    ///
    /// ```text
    /// N̄_i  = c_i·q + b_i (volume − Δt s Q) + x̄'·Δu_i + p̂̄ p̂_i + s wₚ (Δpₚ − m) b_i
    /// ∇N̄_i = Mᵀ a_i + b_i flux + ΔF̄ᵀ Δu_i + ∇ⁿp̂̄ p̂_i
    /// ```
    ///
    ///   (the rows and the sums are linear in `(N_i, ∇N_i)`);
    /// - the position where it is not among the lanes (above the water table, and `x_a`,
    ///   `a < D`, everywhere), which the kernel does not read: `x̄ = x̄'`, the end position's
    ///   weight (`x' = x + Δx`);
    /// - the mass, which enters through `q` alone: `m̄ = m̄' + λ_g Σ_i N_i c_i·g`.
    ///
    /// Returns the partials (the state's components, the excess, then zeros for the
    /// [`coupled_lanes`] sums); the entries of the other inputs not differentiated are
    /// zero.
    #[allow(clippy::too_many_arguments)]
    fn partials<const L: usize>(
        &self,
        pulled: &Pulled<D>,
        z: &[f64],
        lanes: &[usize],
        mats: &[Material<DualSVec64<L>>],
        hydraulic: &Hydraulic<DualSVec64<L>>,
        cot: &CoupledCotangent<'_, D>,
        sums_bar: &[f64],
    ) -> Option<Vec<f64>> {
        let sums = Self::UNKNOWNS;
        let mut dz = vec![0.0; sums + coupled_lanes(D)];
        let mut real = None;
        for chunk in lanes.chunks(L) {
            let seed = |k: usize| -> Option<DualSVec64<L>> {
                let l = chunk.iter().position(|&j| j == k)?;
                let mut e = SVector::<f64, L>::zeros();
                e[l] = 1.0;
                Some(DualSVec64::new(0.0, Derivative::some(e)))
            };
            let seeded: Vec<DualSVec64<L>> = (z[..sums].iter().enumerate())
                .map(|(k, &v)| match seed(k) {
                    Some(e) => DualSVec64::from_re(v) + e,
                    None => DualSVec64::from_re(v),
                })
                .collect();
            let (psi, r) =
                self.kernel_psi(pulled, cot, &seeded, &mats[self.material], hydraulic)?;
            if let Some(e) = psi.eps.0.as_ref() {
                for (l, &k) in chunk.iter().enumerate() {
                    dz[k] = e[l];
                }
            }
            real.get_or_insert(r);
        }
        let (momentum, volume, flux, stabilisation) = real?;
        for a in (0..D).filter(|a| !lanes.contains(a)) {
            dz[a] = cot.end[a];
        }
        let mass = z[mass_index(D)];
        let q = self.loads.gravity * (mass * self.setting.gravity_factor)
            + self.loads.point * self.setting.load_factor
            + self.loads.balance;
        let scale = cot.scale;
        let inflow = self.fluid.dt * scale * self.fluid.inflow;
        let x_end = Vector::<f64, D>::from_fn(|a, _| cot.end[a]);
        let df_bar = Tensor::<f64, D>::from_fn(|r, c| sums_bar[r * D + c]);
        let p_bar = sums_bar[D * D];
        let grad_bar = Vector::<f64, D>::from_fn(|a, _| sums_bar[D * D + 1 + a]);
        let h0 = D + D * D;
        pull_geometry(&pulled.nodes, &pulled.geometry, &mut dz[..h0], |i, n| {
            let (a, b, p) = (cot.internal[n.flat], cot.fluid[n.flat], pulled.pressures[i]);
            let n_bar = cot.external[n.flat].dot(&q)
                + b * (volume - inflow + scale * stabilisation)
                + x_end.dot(&n.du)
                + p_bar * p;
            let g_bar =
                momentum.transpose() * a + flux * b + df_bar.transpose() * n.du + grad_bar * p;
            (n_bar, g_bar)
        });
        let mi = mass_index(D);
        dz[mi] =
            cot.end[mi] + self.setting.gravity_factor * pulled.external.dot(&self.loads.gravity);
        Some(dz)
    }

    /// `∂ψₚ/∂θ` for a parameter `θ` seeded in `seeded`: [`Local::kernel_psi`] with the
    /// material and hydraulic properties seeded, plus `Σ_i N_i c_i·∂q/∂θ` through the loads.
    fn share(
        &self,
        pulled: &Pulled<D>,
        z: &[f64],
        seeded: &SeededProperties,
        loads: &Loads<Dual64, D>,
        cot: &CoupledCotangent<'_, D>,
    ) -> Option<f64> {
        let held: Vec<Dual64> = z.iter().map(|&v| Dual64::from_re(v)).collect();
        let (psi, _) = self.kernel_psi(pulled, cot, &held, &seeded.material, &seeded.hydraulic)?;
        let mass = z[mass_index(D)] * self.setting.gravity_factor;
        let q_dot = (0..D).map(|a| {
            loads.gravity[a].eps * mass
                + loads.point[a].eps * self.setting.load_factor
                + loads.balance[a].eps
        });
        Some(
            psi.eps
                + q_dot
                    .zip(pulled.external.iter())
                    .map(|(q, c)| q * c)
                    .sum::<f64>(),
        )
    }

    /// `∂ψₚ/∂z` (inputs order) from the partials `dz` ([`Local::partials`]) by the chain rule
    /// through the stencil sums: `∂ψ/∂Δu_ic = Σ_d ∂ψ/∂ΔF_cd ∂_d N_i + x̄'_c N_i` (the end
    /// position `x' = x + Δx` is read by `ψ` alone), `∂ψ/∂p̂_i = ∂ψ/∂p̂ N_i + ∂ψ/∂∇ⁿp̂ · ∇N_i`,
    /// and the inputs that pass through unchanged (velocity; history of a material that
    /// carries none) take their end weights.
    fn chain(&self, dz: &[f64], inputs: usize, cot: &CoupledCotangent<'_, D>) -> Vec<f64> {
        let sums = Self::UNKNOWNS;
        let mut out = vec![0.0; inputs];
        out[..sums].copy_from_slice(&dz[..sums]);
        let h0 = D + D * D;
        let hl = loam_core::constitutive::HISTORY_LEN;
        let through = (h0..h0 + hl).filter(|_| !self.carries);
        for k in through.chain(h0 + hl..h0 + hl + D) {
            out[k] = cot.end[k];
        }
        let d = &dz[sums..];
        for (k, (w, g)) in self.shape.iter().enumerate() {
            let o = &mut out[sums + k * (D + 1)..sums + (k + 1) * (D + 1)];
            for c in 0..D {
                o[c] = (0..D).map(|e| d[c * D + e] * g[e]).sum::<f64>() + cot.end[c] * w;
            }
            o[D] = d[D * D] * w + (0..D).map(|e| d[D * D + 1 + e] * g[e]).sum::<f64>();
        }
        out
    }
}

/// The derivative of a particle's step by its stencil sums `(ΔF, p̂, ∇ⁿp̂)` with its state
/// held, from pass 1 ([`Held::adjoint`]); each row has [`coupled_lanes`] entries: the
/// kernel's rows ([`CoupledTangent`] order), the end excess, the fluid-content change, and
/// the end history's components where the material carries one (none otherwise: its history
/// passes through).
struct SumsJacobian {
    rows: Vec<f64>,
    excess: Vec<f64>,
    content: Vec<f64>,
    history: Vec<f64>,
}

/// A particle's stencil and sums in the final pass ([`Local::pulled`]).
struct Pulled<const D: usize> {
    /// The stencil's nodes with their increments `Δu_i`.
    nodes: Vec<Node<D>>,
    /// The stencil's derivative by `(x, F)` ([`stencil_jacobian`]).
    geometry: Vec<f64>,
    /// `p̂_i` per node.
    pressures: Vec<f64>,
    /// `ΔF`.
    delta_f: Tensor<f64, D>,
    /// `p̂`.
    p_hat: f64,
    /// `∇ⁿp̂`.
    grad: Vector<f64, D>,
    /// `M̄ = Σ_i a_i ⊗ ∇N_i`.
    m_bar: Tensor<f64, D>,
    /// `Bₚ = Σ_i b_i N_i`.
    b_p: f64,
    /// `Σ_i b_i ∇N_i`.
    flux_bar: Vector<f64, D>,
    /// `Σ_i N_i c_i`.
    external: Vector<f64, D>,
}

/// The real parts [`Local::kernel_psi`] returns: `(M, volume, flux, wₚ (Δpₚ − m))`.
type KernelReal<const D: usize> = (Tensor<f64, D>, f64, Vector<f64, D>, f64);

/// The per-particle settings of a coupled sub-step.
fn locals<'a, const D: usize>(
    replay: &'a Replay<'a, D>,
    fluid: &'a PoreFluid<D>,
    initial: &'a Particles<f64, D>,
    materials: &[Material<f64>],
) -> Vec<Local<'a, D>> {
    let system = &replay.system;
    let flow = system.flow.as_ref().expect("a coupled step");
    let mut conductance = vec![0.0; initial.len()];
    for d in &fluid.drains {
        conductance[d.particle] += d.conductance;
    }
    let mut inflow = vec![0.0; initial.len()];
    for q in &fluid.inflow {
        inflow[q.particle] += q.rate;
    }
    let history = replay.sub.fluid_history.as_ref();
    (0..initial.len())
        .map(|p| {
            let setting = replay.setting(p);
            let state = replay.state(p);
            let stencil = setting.stencil(&state);
            let mut flats = Vec::with_capacity(stencil.len());
            let mut shape = Vec::with_capacity(stencil.len());
            stencil.for_each(|n| {
                flats.push(n.flat);
                shape.push((n.weight, n.gradient));
            });
            let material = initial.material[p] as usize;
            Local {
                setting,
                fluid: FluidSetting {
                    fluid,
                    dt: flow.dt,
                    scale: flow.scale,
                    conductance: conductance[p],
                    inflow: inflow[p],
                    carry: flow.carry,
                },
                state,
                fluid_inputs: FluidInputs {
                    excess: flow.particles[p].excess,
                    content: history.map_or(0.0, |h| h.content[p]),
                    increment: history.map_or(0.0, |h| h.increment[p]),
                },
                loads: replay.loads(p),
                material,
                carries: carries_history(&materials[material]),
                flats,
                shape,
            }
        })
        .collect()
}

/// Per particle, `(m, B̄)` of its patch for the fluid weights `b` (module docs), from each
/// particle's `(Δpₚ, wₚ)`; with the stabilisation off, `(Δpₚ, Bₚ)` (its term and its
/// gradient vanish).
fn patch_constants<const D: usize>(
    system: &StepSystem<D>,
    local: &[Local<'_, D>],
    increments: &[(f64, f64)],
    b: &[f64],
) -> Vec<(f64, f64)> {
    let flow = system.flow.as_ref().expect("a coupled step");
    let b_of = |l: &Local<'_, D>| -> f64 {
        (l.flats.iter().zip(&l.shape))
            .map(|(&f, (w, _))| w * b[f])
            .sum()
    };
    let mut out: Vec<(f64, f64)> = (local.iter().zip(increments))
        .map(|(l, &(dp, _))| (dp, b_of(l)))
        .collect();
    for patch in &flow.patches {
        let (mut w, mut wp, mut wb) = (0.0, 0.0, 0.0);
        for &p in patch {
            let (dp, wt) = increments[p];
            w += wt;
            wp += wt * dp;
            wb += wt * out[p].1;
        }
        for &p in patch {
            out[p] = (wp / w, wb / w);
        }
    }
    out
}

/// A parameter's lifts of one material's constitutive and hydraulic properties as `Dual64`,
/// seeded where it acts on them; the same for every particle of the material, so built once
/// per run.
struct SeededProperties {
    material: Material<Dual64>,
    hydraulic: Hydraulic<Dual64>,
}

impl SeededProperties {
    fn new<const D: usize>(
        param: ImplicitParam,
        config: &ImplicitConfig<D>,
        fluid: &PoreFluid<D>,
        k: usize,
    ) -> Self {
        Self {
            material: param
                .seeded_material(k, &config.materials[k])
                .unwrap_or_else(|| config.materials[k].lift()),
            hydraulic: param.seeded_hydraulic(fluid, k),
        }
    }

    /// Per material of `config`.
    fn per_material<const D: usize>(
        param: ImplicitParam,
        config: &ImplicitConfig<D>,
        fluid: &PoreFluid<D>,
    ) -> Vec<Self> {
        (0..config.materials.len())
            .map(|k| Self::new(param, config, fluid, k))
            .collect()
    }
}

/// Particle `particle` inverted in sub-step `step`.
fn inverted(step: usize, particle: usize) -> AdjointError {
    AdjointError::Implicit(ImplicitError::InvalidState { step, particle })
}

/// A sub-step's `ψ` with `λ = 0`: the weights of the reactions and of the end states, and
/// what they are evaluated at.
struct Held<'a, const D: usize> {
    system: &'a StepSystem<D>,
    local: &'a [Local<'a, D>],
    /// Per particle, [`Local::inputs`] at the converged solution.
    inputs: &'a [Vec<f64>],
    /// `r̄` on the mixture rows' internal force, per grid node.
    reactions: &'a [Vector<f64, D>],
    /// `s̄'` per particle.
    end: &'a [Vec<f64>],
    /// `p̄'` per particle.
    excess: &'a [f64],
    /// `ΔΞ̄` and `Δp̄` per particle (what the next BDF2 step makes of them).
    carried: &'a [(f64, f64)],
    /// The sub-step (its load step for errors, its kept factors for the adjoint solve).
    sub: &'a SubStep<D>,
}

/// A sub-step's adjoint `λ` with each particle's `(Δpₚ, wₚ)` and the derivative of its step
/// by its stencil sums ([`Held::adjoint`]).
type Adjoint = (Vec<f64>, Vec<(f64, f64)>, Vec<SumsJacobian>);

impl<const D: usize> Held<'_, D> {
    /// The sub-step's adjoint `λ` from `Jᵀλ = ∂ψ/∂(Δu, p̂)|_{λ=0}`, and each particle's
    /// `(Δpₚ, wₚ)`. One evaluation per particle with its `L` = [`coupled_lanes`] stencil
    /// sums seeded gives both the right-hand side ([`Local::gradient`]) and the kernel's
    /// derivative `A = ∂(rows)/∂(ΔF, p̂, ∇ⁿp̂)` that the tangent `J` is assembled from
    /// ([`StepSystem::coupled_tangent_from`]).
    ///
    /// # Errors
    /// An inverted particle, or an adjoint system that cannot be solved.
    fn adjoint<const L: usize>(
        &self,
        mats: &[Material<DualSVec64<L>>],
        fluid: &PoreFluid<D>,
        linear: &mut loam_implicit::linear::LinearSolver,
    ) -> Result<Adjoint, AdjointError> {
        let system = self.system;
        let nodes = system.grid().num_nodes();
        let (no_forces, no_fluid) = (vec![Vector::<f64, D>::zeros(); nodes], vec![0.0; nodes]);
        let hydraulic: Vec<Hydraulic<DualSVec64<L>>> =
            fluid.hydraulic.iter().map(Hydraulic::lift).collect();
        type Linear<const L: usize> = (Vec<f64>, CoupledTangent<L>, (f64, f64), SumsJacobian);
        let linearised: Vec<Option<Linear<L>>> = (0..self.local.len())
            .into_par_iter()
            .map(|p| {
                let l = &self.local[p];
                let cot = CoupledCotangent {
                    internal: self.reactions,
                    external: &no_forces,
                    fluid: &no_fluid,
                    end: &self.end[p],
                    excess: self.excess[p],
                    content: self.carried[p].0,
                    increment: self.carried[p].1,
                    patch: (0.0, 0.0),
                    scale: l.fluid.scale,
                };
                let z = &self.inputs[p];
                let (a, jacobian, w) = l.linearise(z, mats, &hydraulic[l.material])?;
                let mut dz = vec![0.0; Local::<D>::UNKNOWNS + coupled_lanes(D)];
                dz[Local::<D>::UNKNOWNS..].copy_from_slice(&l.sums_partial(&jacobian, &cot, w.1));
                Some((l.chain(&dz, z.len(), &cot), a, w, jacobian))
            })
            .collect();
        let linearised: Vec<Linear<L>> = (linearised.into_iter().enumerate())
            .map(|(p, s)| s.ok_or_else(|| inverted(self.sub.step, p)))
            .collect::<Result<_, _>>()?;
        let mut rhs = vec![0.0; system.len()];
        for (l, (g, ..)) in self.local.iter().zip(&linearised) {
            scatter(system, &l.flats, g, &mut rhs);
        }
        let mut lambda = vec![0.0; system.len()];
        if rhs.iter().any(|v| *v != 0.0) {
            let failed = |source| AdjointError::Linear {
                step: self.sub.step,
                what: "adjoint",
                source,
            };
            let tangent =
                system.coupled_tangent_transposed(linearised.iter().map(|l| l.1).collect());
            let product = |v: &[f64], out: &mut [f64]| tangent.apply(v, out);
            let near = (self.sub)
                .solve_adjoint_near(&system.pattern, product, &rhs, &mut lambda)
                .map_err(failed)?;
            if !near {
                let k = system
                    .coupled_tangent_from::<L>(|p| Some(*tangent.local(p)))
                    .map_err(|e| inverted(self.sub.step, e.particle))?;
                linear
                    .solve_transpose(&k, &rhs, &mut lambda)
                    .map_err(failed)?;
            }
        }
        let (increments, jacobians) = linearised.into_iter().map(|l| (l.2, l.3)).unzip();
        Ok((lambda, increments, jacobians))
    }
}

/// The reverse pass of a coupled run over its sub-steps `first..`, seeded with `weights`
/// (the cotangent of each observation's model value; [`super::adjoint`] for the equations,
/// module docs for the coupled step).
///
/// # Errors
/// A sub-step whose system cannot be rebuilt or whose adjoint system cannot be solved.
pub fn reverse<const D: usize>(
    config: &ImplicitConfig<D>,
    initial: &Particles<f64, D>,
    run: &Trajectory<D>,
    observations: &ImplicitObservations,
    weights: &[f64],
    params: &[ImplicitParam],
    first: usize,
) -> Result<Vec<f64>, AdjointError> {
    let fluid = config.pore_fluid.as_ref().expect("a coupled run");
    let solver = ImplicitSolver::new(config.clone(), initial)?;
    let n = initial.len();
    let nodes = config.grid.num_nodes();
    let mats: Vec<Material<DualSVec64<LANES>>> =
        config.materials.iter().map(|m| m.lift()).collect();
    let narrow: Vec<Material<DualSVec64<NARROW_LANES>>> =
        config.materials.iter().map(|m| m.lift()).collect();
    let balance_rates: Vec<Vec<Vector<f64, D>>> = (params.iter())
        .map(|q| q.balance_tangent(config, initial))
        .collect::<Result<_, _>>()?;
    let seeded: Vec<Vec<SeededProperties>> = (params.iter())
        .map(|&q| SeededProperties::per_material(q, config, fluid))
        .collect();
    let zeros = vec![Vector::<f64, D>::zeros(); nodes];
    let mut linear = loam_implicit::linear::LinearSolver::new(config.newton.linear);
    let mut sbar = vec![vec![0.0; state_len(D)]; n];
    let mut ebar = vec![0.0; n];
    // `(ΔΞ̄, Δp̄)` of the sub-step's outputs that the next one carries under BDF2.
    let mut carried = vec![(0.0, 0.0); n];
    let mut grad = vec![0.0; params.len()];
    for (i, sub) in run.substeps.iter().enumerate().skip(first).rev() {
        let seeds = SubStep::ends_step(&run.substeps, i)
            .then(|| StepSeeds::new(config, observations, weights, sub.step));
        let replay = Replay::new(&solver, initial, sub)?;
        let system = &replay.system;
        let local = locals(&replay, fluid, initial, &config.materials);
        for &(p, k, w) in seeds.iter().flat_map(|s| &s.states) {
            sbar[p][k] += w;
        }
        // A pore pressure p_h(x') + p_e' after the step.
        for &(p, w) in seeds.iter().flat_map(|s| &s.pressures) {
            let end = &run.positions[sub.step][p];
            ebar[p] += w;
            sbar[p][D - 1] += w * local[p].fluid.hydrostatic_slope(end);
        }
        system.prepare(&mut linear);
        let inverted = |particle| inverted(sub.step, particle);
        let a_r = (seeds.as_ref())
            .and_then(|s| s.reaction_weights.as_deref())
            .unwrap_or(&zeros);
        let inputs: Vec<Vec<f64>> = (local.par_iter())
            .map(|l| l.inputs(system, &sub.solution))
            .collect();
        let hydraulic: Vec<Hydraulic<DualSVec64<LANES>>> =
            fluid.hydraulic.iter().map(Hydraulic::lift).collect();
        let narrow_hydraulic: Vec<Hydraulic<DualSVec64<NARROW_LANES>>> =
            fluid.hydraulic.iter().map(Hydraulic::lift).collect();
        let held = Held {
            system,
            local: &local,
            inputs: &inputs,
            reactions: a_r,
            end: &sbar,
            excess: &ebar,
            carried: &carried,
            sub,
        };
        let (lambda, increments, jacobians) = match D {
            2 => held.adjoint::<7>(&solver.materials().dual7, fluid, &mut linear)?,
            3 => held.adjoint::<13>(&solver.materials().dual13, fluid, &mut linear)?,
            _ => unreachable!("D is 2 or 3"),
        };
        // Nodal weights: a = r̄ − λ_u, c = λ_u, b = −λ_p.
        let mut internal = a_r.to_vec();
        let mut external = zeros.clone();
        let mut fluid_w = vec![0.0; nodes];
        for node in 0..nodes {
            for c in 0..=D {
                if let NodeDof::Free { dof, sign } = system.dofs.get(node, c) {
                    if c < D {
                        internal[node][c] -= sign * lambda[dof];
                        external[node][c] += sign * lambda[dof];
                    } else {
                        fluid_w[node] -= sign * lambda[dof];
                    }
                }
            }
        }
        let patches = patch_constants(system, &local, &increments, &fluid_w);
        let rates = replay.prescribed_rates(params)?;
        let per_particle: Vec<Option<(Vec<f64>, Vec<f64>)>> = (0..n)
            .into_par_iter()
            .map(|p| {
                let l = &local[p];
                let z = &inputs[p];
                let cot = CoupledCotangent {
                    internal: &internal,
                    external: &external,
                    fluid: &fluid_w,
                    end: &sbar[p],
                    excess: ebar[p],
                    content: carried[p].0,
                    increment: carried[p].1,
                    patch: patches[p],
                    scale: l.fluid.scale,
                };
                let lanes = l.lanes();
                let sums = l.sums_partial(&jacobians[p], &cot, increments[p].1);
                let pulled = l.pulled(z, &cot);
                let mut dz = if lanes.len() <= NARROW_LANES {
                    let h = &narrow_hydraulic[l.material];
                    l.partials(&pulled, z, &lanes, &narrow, h, &cot, &sums)?
                } else {
                    let h = &hydraulic[l.material];
                    l.partials(&pulled, z, &lanes, &mats, h, &cot, &sums)?
                };
                dz[Local::<D>::UNKNOWNS..].copy_from_slice(&sums);
                let k = state_len(D);
                (dz[k + 1], dz[k + 2]) = l.carried_partials(&cot, increments[p].1);
                let g = l.chain(&dz, z.len(), &cot);
                let mut shares = vec![0.0; params.len()];
                for (j, q) in params.iter().enumerate() {
                    shares[j] = match *q {
                        // Through the masses (the initial state's tangent).
                        ImplicitParam::Material(_, MaterialField::Density) => continue,
                        // On the constraint's shared unknown, below.
                        ImplicitParam::ConstraintForce(..) => continue,
                        ImplicitParam::Displacement(..) => {
                            let rate = rates[j].as_ref().expect("rates of displacements");
                            (l.flats.iter().enumerate())
                                .map(|(k, &f)| {
                                    (0..D)
                                        .map(|a| {
                                            rate[f][a] * g[Local::<D>::UNKNOWNS + k * (D + 1) + a]
                                        })
                                        .sum::<f64>()
                                })
                                .sum()
                        }
                        _ => {
                            let loads = q.seeded_loads(config, &l.loads, p, &balance_rates[j]);
                            l.share(&pulled, z, &seeded[j][l.material], &loads, &cot)?
                        }
                    };
                }
                Some((g, shares))
            })
            .collect();
        for (p, r) in per_particle.into_iter().enumerate() {
            let (g, shares) = r.ok_or_else(|| inverted(p))?;
            sbar[p].copy_from_slice(&g[..state_len(D)]);
            ebar[p] = g[state_len(D)];
            carried[p] = (g[state_len(D) + 1], g[state_len(D) + 2]);
            grad.iter_mut().zip(&shares).for_each(|(g, s)| *g += s);
        }
        super::adjoint::add_controlled_shares(system, &lambda, params, &mut grad);
    }
    for (g, q) in grad.iter_mut().zip(params) {
        for (p, t) in q.initial_tangent(config, initial) {
            *g += t.iter().zip(&sbar[p]).map(|(a, b)| a * b).sum::<f64>();
        }
    }
    Ok(grad)
}

/// Adds a particle's gradient by its stencil unknowns (`g`, inputs order) to `out` on the
/// free unknowns.
fn scatter<const D: usize>(system: &StepSystem<D>, flats: &[usize], g: &[f64], out: &mut [f64]) {
    for (k, &f) in flats.iter().enumerate() {
        for c in 0..=D {
            if let NodeDof::Free { dof, sign } = system.dofs.get(f, c) {
                out[dof] += sign * g[Local::<D>::UNKNOWNS + k * (D + 1) + c];
            }
        }
    }
}

/// `dm_k/dθ` of every observed quantity of a coupled run by forward-mode duals (module
/// docs; [`super::tangent::model_tangents`] for a run of the solid alone).
///
/// # Errors
/// As [`reverse`].
pub fn model_tangents<const D: usize>(
    config: &ImplicitConfig<D>,
    initial: &Particles<f64, D>,
    run: &Trajectory<D>,
    observations: &ImplicitObservations,
    param: ImplicitParam,
) -> Result<Vec<f64>, AdjointError> {
    let fluid = config.pore_fluid.as_ref().expect("a coupled run");
    let solver = ImplicitSolver::new(config.clone(), initial)?;
    let n = initial.len();
    let mut sdot = vec![vec![0.0; state_len(D)]; n];
    for (p, t) in param.initial_tangent(config, initial) {
        sdot[p] = t;
    }
    let mut edot = vec![0.0; n];
    // The derivatives of each particle's `(ΔΞ, Δp)` over the last sub-step.
    let mut carried_dot = vec![(0.0, 0.0); n];
    let balance_rate = param.balance_tangent(config, initial)?;
    let seeded = SeededProperties::per_material(param, config, fluid);
    let mut linear = loam_implicit::linear::LinearSolver::new(config.newton.linear);
    let mut tangents = vec![0.0; observations.items.len()];
    for (i, sub) in run.substeps.iter().enumerate() {
        let replay = Replay::new(&solver, initial, sub)?;
        let system = &replay.system;
        let flow = system.flow.as_ref().expect("a coupled step");
        let local = locals(&replay, fluid, initial, &config.materials);
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
        // Every particle's step with the free unknowns' derivative parts `free`.
        let evaluate = |free: &[f64]| -> Result<Vec<CoupledParticle<Dual64, D>>, AdjointError> {
            let steps: Vec<Option<CoupledParticle<Dual64, D>>> = (0..n)
                .into_par_iter()
                .map(|p| {
                    let l = &local[p];
                    let loads = param.seeded_loads(config, &l.loads, p, &balance_rate);
                    let mut z: Vec<Dual64> = (l.state.components().iter().zip(&sdot[p]))
                        .map(|(&v, &t)| Dual64::new(v, t))
                        .collect();
                    let f = &l.fluid_inputs;
                    z.push(Dual64::new(f.excess, edot[p]));
                    z.push(Dual64::new(f.content, carried_dot[p].0));
                    z.push(Dual64::new(f.increment, carried_dot[p].1));
                    for &f in &l.flats {
                        for c in 0..=D {
                            let eps = match system.dofs.get(f, c) {
                                NodeDof::Free { dof, sign } => sign * free[dof],
                                _ if c < D => rate.as_ref().map_or(0.0, |r| r[f][c]),
                                _ => 0.0,
                            };
                            z.push(Dual64::new(system.dofs.value(f, c, &sub.solution), eps));
                        }
                    }
                    let s = &seeded[l.material];
                    l.step(&z, &s.material, &s.hydraulic, &loads)
                })
                .collect();
            (steps.into_iter().enumerate())
                .map(|(p, s)| s.ok_or_else(|| inverted(p)))
                .collect()
        };
        // Ṙ with the unknowns held, the stabilisation's included, then J u̇ = −Ṙ.
        let held = evaluate(&vec![0.0; system.len()])?;
        let mut r_dot = vec![0.0; system.len()];
        let mut add = |flat: usize, c: usize, v: f64| {
            if let NodeDof::Free { dof, sign } = system.dofs.get(flat, c) {
                r_dot[dof] -= sign * v;
            }
        };
        for s in &held {
            for node in &s.nodes {
                for a in 0..D {
                    add(node.flat, a, (node.internal[a] - node.external[a]).eps);
                }
                add(node.flat, D, (node.fluid - node.inflow).eps);
            }
        }
        for patch in &flow.patches {
            let (mut w, mut wp) = (Dual64::from_re(0.0), Dual64::from_re(0.0));
            for &p in patch {
                w += held[p].stabilisation;
                wp += held[p].stabilisation * held[p].stabilised;
            }
            let mean = wp / w;
            for &p in patch {
                let r = held[p].stabilisation
                    * (held[p].stabilised - mean)
                    * Dual64::from_re(flow.scale);
                for node in &held[p].nodes {
                    add(node.flat, D, (r * node.weight).eps);
                }
            }
        }
        super::tangent::add_controlled_rate(system, param, &mut r_dot);
        let u_dot = super::tangent::solve_tangent(&solver, &replay, &mut linear, &r_dot)?;
        let moved = evaluate(&u_dot)?;
        for (p, s) in moved.iter().enumerate() {
            sdot[p] = s.end.tangent();
            edot[p] = s.excess.eps;
            carried_dot[p] = (s.content.eps, s.increment.eps);
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
                    Quantity::Velocity { .. } => 0.0,
                    Quantity::PorePressure { particle } => {
                        let end = &run.positions[sub.step][particle];
                        edot[particle]
                            + local[particle].fluid.hydrostatic_slope(end) * sdot[particle][D - 1]
                    }
                    Quantity::Reaction {
                        constraint,
                        component,
                    } => {
                        let mut unit = vec![Vector::<f64, D>::zeros(); config.constraints.len()];
                        unit[constraint][component] = 1.0;
                        let w = StepSeeds::node_weights(config, &unit);
                        (moved.iter().flat_map(|s| &s.nodes))
                            .map(|node| {
                                (0..D)
                                    .map(|a| w[node.flat][a] * node.internal[a].eps)
                                    .sum::<f64>()
                            })
                            .sum()
                    }
                };
            }
        }
    }
    Ok(tangents)
}
