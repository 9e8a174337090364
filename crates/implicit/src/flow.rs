//! The pore fluid of a coupled (u–p) step: saturated soil as a mixture of a skeleton and
//! water, with the excess pore pressure as one more unknown per node.
//!
//! **Sign convention.** The pore pressure `p` is positive in compression (a water pressure);
//! the skeleton's stress `σ′` (the effective stress, what the constitutive model returns) is
//! tension-positive like every stress in loam, and the total stress is `σ = σ′ − α p I`. The
//! pore pressure is the hydrostatic pressure of a water table plus an excess,
//! `p = p_h(x) + p_e`, with `p_h = γ_w (z_w − z)` below the water table at height `z_w` (the
//! last axis is up) and zero above it or without one. The unknowns are the nodal excess
//! pressures; the water at rest under a flat water table carries its own weight, so the
//! Darcy flux is driven by the excess alone, `q = −κ ∇p_e` with the mobility `κ = k/γ_w`
//! (`k` the hydraulic conductivity).
//!
//! **Equations** (updated Lagrangian from the start of the step, backward Euler over `Δt`). Per
//! particle, with `ΔF` and `ΔJ = det ΔF` from the displacement increments, `Jⁿ = det Fⁿ`,
//! `Vⁿ = Jⁿ V⁰`, `p̂ = Σ_i N_i p_i` and `∇ⁿp̂ = Σ_i ∇ⁿN_i p_i` at the start-of-step position:
//!
//! ```text
//! mixture:  f_i = Σ_p V⁰ (τ′ − α Jⁿ ΔJ p I) ΔF⁻ᵀ ∇ⁿN_i                        (= f_ext,i)
//! fluid:    g_i = Σ_p Vⁿ [α (ΔJ − 1) + S (p − pⁿ)] N_i
//!                 + Σ_p Δt Vⁿ ΔJ κ ∇ⁿN_i · (ΔFᵀΔF)⁻¹ ∇ⁿp_e                     (= 0)
//! ```
//!
//! The mixture balance is the solid path's with the total stress. The fluid balance is the
//! volume of water the skeleton's change of volume `α ΔV` and the water's compression
//! `S Δp V` (storage `S = 1/M`, zero for incompressible constituents) expel, against the
//! water that flows out, `Δt ∫ ∇N_i · κ ∇p_e dv` in the end-of-step configuration
//! (`∇N = ΔF⁻ᵀ ∇ⁿN`, `dv = ΔJ dvⁿ`); faces without a drained condition are impermeable
//! (the natural condition), unless water is fed through them ([`Inflow`]) or they drain
//! as free surfaces that move with the soil ([`SurfaceDrain`]). The mobility is constant, or follows the porosity of the
//! end-of-step volume `J = Jⁿ ΔJ` by Kozeny–Carman ([`Permeability`]). The fluid rows are scaled by `G_ref/h` and the pressure unknowns
//! by its inverse ([`Flow::scale`]), so that the two blocks of the residual are forces and
//! the two blocks of the unknowns lengths, and Newton's tolerances hold for both.
//!
//! **Time integration.** Backward Euler by default; the variable-step BDF2 of
//! [`TimeIntegration::Bdf2`] (second order) subtracts `c₁` times each particle's fluid-content
//! change over the previous step from its volume term and weights the flows by `c₂`: the
//! kernel reads `c₁ ΔΞⁿ_p` from [`FlowFrozen::carried`] and `c₂ Δt` as the step's `Δt`
//! ([`Flow::dt`]). The stabilisation below is a rate term too (a pseudo-storage of the
//! pressure's fluctuation), so it is integrated alike: its increments `Δp_p` less
//! `c₁ Δp_pⁿ` ([`FlowFrozen::carried_increment`]). (Left as a backward-Euler increment, it
//! would keep the scheme first order wherever it acts, and weight it by `1/c₂`.)
//!
//! **Stabilisation.** Equal-order interpolation of `u` and `p` does not satisfy the inf–sup
//! condition: near the undrained limit (`Δt κ → 0`, `S → 0`) the pressure oscillates from
//! node to node. The polynomial pressure projection (Bochev–Dohrmann; White & Borja for
//! u–p) adds to the fluid rows
//!
//! ```text
//! Σ_patches Σ_p (Vⁿ_p / G_p) (Δp_p − Π Δp) N_i,    Π Δp = Σ_p w_p Δp_p / Σ_p w_p,  w_p = Vⁿ_p / G_p,
//! ```
//!
//! the pressure increment minus its projection onto constants over a patch, scaled by the
//! skeleton's shear modulus `G_p`: it vanishes on pressures that are constant over each patch
//! and penalises the rest, a term of the order of the discretisation error of a smooth
//! pressure. A patch is the set of particles in one grid cell. (Grouping the particles that
//! share a stencil instead would keep the term inside the solid's sparsity pattern, but with
//! quadratic B-splines the nodal checkerboard `(−1)^i` is constant over each such group, so
//! the projection would not see the very mode it must remove; the cell patches vary it and
//! need the pressure pattern one node wider, `StepSystem::new`.)

use crate::dofs::NodeDof;
use crate::kernel::stress_update;
use crate::linear::SparseMatrix;
use crate::system::{CHUNK, Inverted, Materials, Placed, StepSystem};
use loam_core::tensor::{Tensor, Vector, det, inverse, product};
use loam_core::{Material, Scalar};
use nalgebra::Matrix3;
use num_dual::DualSVec64;
use rayon::prelude::*;

/// The hydraulic properties of a porous material, in scalar type `T` (`f64` in the solver; a
/// dual number where a gradient by them is taken).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hydraulic<T = f64> {
    /// Mobility `κ = k/γ_w` (m²/(Pa·s)): the hydraulic conductivity `k` (m/s) over the unit
    /// weight of water `γ_w` (N/m³).
    pub mobility: T,
    /// Biot coefficient `α` (1 for incompressible grains).
    pub biot: T,
    /// Storage `S = 1/M = n/K_w + (α − n)/K_s` (1/Pa); zero for incompressible water and
    /// grains.
    pub storage: T,
    /// How the mobility follows the volume change.
    pub permeability: Permeability,
}

impl Hydraulic<f64> {
    /// The properties as constants of scalar type `T`.
    pub fn lift<T: Scalar>(&self) -> Hydraulic<T> {
        Hydraulic {
            mobility: T::cst(self.mobility),
            biot: T::cst(self.biot),
            storage: T::cst(self.storage),
            permeability: self.permeability,
        }
    }
}

/// How a material's mobility follows its volume change at large strain.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Permeability {
    /// `κ` constant.
    #[default]
    Constant,
    /// Kozeny–Carman: `κ(J) = κ₀ [n³/(1 − n)²] / [n₀³/(1 − n₀)²]` with the porosity
    /// `n = 1 − (1 − n₀)/J` of incompressible grains, `n₀` the porosity at `F = I` (where
    /// `κ = κ₀`) and `J = det F`.
    KozenyCarman {
        /// `n₀`, in (0, 1).
        porosity: f64,
    },
}

impl Permeability {
    /// `κ(J)/κ₀` (enum docs); `None` where the grains alone would fill more than the volume
    /// (`J ≤ 1 − n₀`, no porosity left).
    pub fn factor<T: Scalar>(&self, j: T) -> Option<T> {
        match *self {
            Self::Constant => Some(T::one()),
            Self::KozenyCarman { porosity: n0 } => {
                let solid = T::cst(1.0 - n0) / j;
                let n = T::one() - solid;
                if n.re() <= 0.0 {
                    return None;
                }
                let reference = n0.powi(3) / ((1.0 - n0) * (1.0 - n0));
                Some(n * n * n / (solid * solid * T::cst(reference)))
            }
        }
    }
}

/// The pore fluid of one particle, frozen over a step, in scalar type `T` (as [`Hydraulic`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlowFrozen<T = f64> {
    /// Excess pore pressure at the start of the step, `p_eⁿ` (Pa).
    pub excess: T,
    /// Hydrostatic pressure at the start-of-step position, `p_h(xⁿ)` (Pa).
    pub hydrostatic: T,
    /// Stabilisation weight `w_p = Vⁿ_p / G_p` (m³/Pa; m²/Pa in 2D).
    pub weight: T,
    /// Leakage `κ A_p / ℓ_p` of a particle on a drained free surface (m³/(Pa·s); m²/(Pa·s)
    /// in 2D), zero elsewhere ([`SurfaceDrain`]).
    pub leakage: T,
    /// The share `c₁ ΔΞⁿ_p` of the particle's fluid-content change over the previous step
    /// that a BDF2 step carries (m³; m² in 2D; [`TimeIntegration::Bdf2`]), zero under
    /// backward Euler.
    pub carried: T,
    /// The share `c₁ Δp_eⁿ_p` of the particle's excess-pressure increment over the previous
    /// step that a BDF2 step carries into the stabilisation (Pa), zero under backward Euler.
    pub carried_increment: T,
}

impl FlowFrozen<f64> {
    /// The frozen data as constants of scalar type `T`.
    pub fn lift<T: Scalar>(&self) -> FlowFrozen<T> {
        FlowFrozen {
            excess: T::cst(self.excess),
            hydrostatic: T::cst(self.hydrostatic),
            weight: T::cst(self.weight),
            leakage: T::cst(self.leakage),
            carried: T::cst(self.carried),
            carried_increment: T::cst(self.carried_increment),
        }
    }
}

/// The pore fluid of a coupled step (module docs).
#[derive(Clone, Debug)]
pub struct Flow {
    /// The weight of the step's flows (s): the time step `Δt` under backward Euler,
    /// `c₂ Δt` under BDF2 ([`TimeIntegration`]); zero for an undrained step.
    pub dt: f64,
    /// `c₁` of a BDF2 step ([`TimeIntegration::weights`]): the share of the previous step's
    /// fluid-content change and pressure increment it carries; zero under backward Euler.
    pub carry: f64,
    /// `G_ref/h` (Pa/m): the pore pressure is `scale` times its unknown, and the fluid rows
    /// are scaled by it.
    pub scale: f64,
    /// Per material.
    pub hydraulic: Vec<Hydraulic>,
    /// Per particle.
    pub particles: Vec<FlowFrozen>,
    /// The stabilisation's patches (the particles of one grid cell each); empty when the
    /// stabilisation is off.
    pub patches: Vec<Vec<usize>>,
    /// The stabilisation's tangent, a constant of the step: assembled by the first tangent
    /// that needs it.
    pub stabilisation: std::sync::OnceLock<SparseMatrix>,
}

/// What the coupled kernel gives for one particle: the coefficients of its nodal forces and
/// fluid volumes, `f_i = momentum ∇ⁿN_i`, `g_i = volume N_i + flux · ∇ⁿN_i` (both scaled as
/// the rows are), and its end-of-step stress and history.
#[derive(Clone, Debug)]
pub struct Coupled<T: Scalar, const D: usize> {
    /// `V⁰ (τ′ − α J p I) ΔF⁻ᵀ`.
    pub momentum: Tensor<T, D>,
    /// `scale · (ΔΞ − c₁ ΔΞⁿ)` plus the leakage of a drained free surface, with the
    /// fluid-content change `ΔΞ` ([`Coupled::content`]).
    pub volume: T,
    /// The particle's fluid-content change over the step, `ΔΞ = Vⁿ [α (ΔJ − 1) + S Δp]`
    /// (m³; m² in 2D): the volume of water it expels.
    pub content: T,
    /// `scale · Δt Vⁿ ΔJ κ (ΔFᵀΔF)⁻¹ ∇ⁿp_e`.
    pub flux: Vector<T, D>,
    /// Effective Kirchhoff stress `τ′`.
    pub tau: Matrix3<T>,
    /// History at the end of the step.
    pub state: loam_core::MaterialState<T>,
    /// Excess pore pressure `p_e` (Pa).
    pub excess: T,
}

/// The start-of-step state of a particle that the coupled kernel reads, in scalar type `T`
/// (the solver's frozen `f64` values lifted, or duals where the adjoint differentiates by
/// them).
#[derive(Clone, Copy, Debug)]
pub struct CoupledStart<'a, T: Scalar, const D: usize> {
    /// Deformation gradient `Fⁿ`.
    pub f_n: &'a Tensor<T, D>,
    /// Constitutive history.
    pub history: &'a loam_core::MaterialState<T>,
    /// Reference volume `V⁰`.
    pub volume0: f64,
    /// The pore fluid's frozen data.
    pub fluid: &'a FlowFrozen<T>,
}

/// The coupled kernel of one particle (module docs) for the trial `ΔF`, the interpolated
/// pressure unknown `p̂` and its gradient `∇ⁿp̂`; `None` if `ΔF` inverts the particle.
#[allow(clippy::too_many_arguments)]
pub fn coupled_update<T: Scalar, const D: usize>(
    material: &Material<T>,
    start: &CoupledStart<'_, T, D>,
    hydraulic: &Hydraulic<T>,
    dt: f64,
    scale: f64,
    delta_f: &Tensor<T, D>,
    p_hat: T,
    grad_p_hat: &Vector<T, D>,
) -> Option<Coupled<T, D>> {
    let fluid = start.fluid;
    let (s, tau, state) = stress_update(
        material,
        start.f_n,
        start.history,
        T::cst(start.volume0),
        delta_f,
    )?;
    let dj = det(delta_f);
    let jn = det(start.f_n);
    let vn = jn * T::cst(start.volume0);
    let excess = p_hat * T::cst(scale);
    let p = excess + fluid.hydrostatic;
    let dfinv = inverse(delta_f)?;
    let alpha = hydraulic.biot;
    let momentum = s - dfinv.transpose() * (alpha * p * dj * vn);
    let content = (alpha * (dj - T::one()) + hydraulic.storage * (excess - fluid.excess)) * vn;
    let volume =
        (content - fluid.carried) * T::cst(scale) + excess * fluid.leakage * T::cst(scale * dt);
    let mobility = hydraulic.permeability.factor(dj * jn)? * hydraulic.mobility;
    let flux = product(&dfinv, &product(&dfinv.transpose(), grad_p_hat))
        * (dj * mobility * vn * T::cst(scale * scale * dt));
    Some(Coupled {
        momentum,
        volume,
        content,
        flux,
        tau,
        state,
        excess,
    })
}

/// Lanes of the coupled per-particle tangent: `D²` entries of `ΔF`, `p̂` and `D` entries of
/// `∇ⁿp̂` (7 in 2D, 13 in 3D).
pub const fn coupled_lanes(d: usize) -> usize {
    d * d + 1 + d
}

/// The derivative of the coupled kernel's outputs (`momentum` row-major, `volume`, `flux`)
/// with respect to its inputs (`ΔF` row-major, `p̂`, `∇ⁿp̂`), `L × L` row-major
/// (`L` = [`coupled_lanes`]).
pub type CoupledTangent<const L: usize> = [[f64; L]; L];

impl<const D: usize> StepSystem<D> {
    /// Adds the water the inflows bring over the step, `Δt Σ Q N_i(xⁿ)`, to the external side
    /// of the fluid rows (scaled as the rows are); nothing without a pore fluid.
    pub(crate) fn add_inflow(&mut self, inflow: &[Inflow]) {
        let Some(flow) = &self.flow else { return };
        let weight = flow.dt * flow.scale;
        for q in inflow {
            self.frozen[q.particle].stencil.for_each(|node| {
                if let NodeDof::Free { dof, sign } = self.dofs.get(node.flat, D) {
                    self.f_ext[dof] += sign * node.weight * weight * q.rate;
                }
            });
        }
    }

    /// The pore fluid of this step, if it is coupled.
    fn fluid(&self) -> &Flow {
        self.flow.as_ref().expect("a coupled step")
    }

    /// `ΔF`, `p̂` and `∇ⁿp̂` of particle `p` for the unknowns `x` (real).
    fn coupled_inputs(&self, p: usize, x: &[f64]) -> (Tensor<f64, D>, f64, Vector<f64, D>) {
        let mut p_hat = 0.0;
        let mut grad = Vector::<f64, D>::zeros();
        self.frozen[p].stencil.for_each(|n| {
            let v = self.dofs.value(n.flat, D, x);
            p_hat += n.weight * v;
            grad += n.gradient * v;
        });
        (self.delta_f_real(p, x), p_hat, grad)
    }

    /// The coupled kernel of particle `p` at the real unknowns `x`.
    pub(crate) fn coupled_real(
        &self,
        p: usize,
        x: &[f64],
        materials: &Materials,
    ) -> Option<Coupled<f64, D>> {
        let (g, p_hat, grad) = self.coupled_inputs(p, x);
        self.kernel(p, &materials.real, &g, p_hat, &grad)
    }

    /// [`coupled_update`] of particle `p` with its material from `mats` (lifted to the scalar
    /// type of the inputs), its fluid data and the step's `Δt` and scale.
    fn kernel<T: Scalar>(
        &self,
        p: usize,
        mats: &[Material<T>],
        delta_f: &Tensor<T, D>,
        p_hat: T,
        grad_p_hat: &Vector<T, D>,
    ) -> Option<Coupled<T, D>> {
        let flow = self.fluid();
        let fr = &self.frozen[p];
        coupled_update(
            &mats[fr.material],
            &CoupledStart {
                f_n: &fr.f_n.map(T::cst),
                history: &fr.state.lift(),
                volume0: fr.volume0,
                fluid: &flow.particles[p].lift(),
            },
            &flow.hydraulic[fr.material].lift(),
            flow.dt,
            flow.scale,
            delta_f,
            p_hat,
            grad_p_hat,
        )
    }

    /// Scatters one particle's coupled forces into `f` on the unknowns.
    fn scatter_coupled(&self, p: usize, c: &Coupled<f64, D>, f: &mut [f64]) {
        self.frozen[p].stencil.for_each(|node| {
            let fi = c.momentum * node.gradient;
            for a in 0..D {
                if let NodeDof::Free { dof, sign } = self.dofs.get(node.flat, a) {
                    f[dof] += sign * fi[a];
                }
            }
            if let NodeDof::Free { dof, sign } = self.dofs.get(node.flat, D) {
                f[dof] += sign * (c.volume * node.weight + c.flux.dot(&node.gradient));
            }
        });
    }

    /// The coupled internal force (mixture and fluid rows, stabilisation included) on the
    /// unknowns.
    pub(crate) fn coupled_force(
        &self,
        x: &[f64],
        materials: &Materials,
    ) -> Result<Vec<f64>, Inverted> {
        let mut f = vec![0.0; self.len()];
        self.chunked(
            |p| self.coupled_real(p, x, materials),
            |p, c| self.scatter_coupled(p, &c, &mut f),
        )?;
        self.add_stabilisation(x, &mut f);
        Ok(f)
    }

    /// The mixture's nodal force on every grid node (reactions at prescribed nodes).
    pub(crate) fn coupled_nodal_force(
        &self,
        x: &[f64],
        materials: &Materials,
    ) -> Result<Vec<Vector<f64, D>>, Inverted> {
        let mut f = vec![Vector::<f64, D>::zeros(); self.grid().num_nodes()];
        for (p, fr) in self.frozen.iter().enumerate() {
            let c = self
                .coupled_real(p, x, materials)
                .ok_or(Inverted { particle: p })?;
            fr.stencil
                .for_each(|node| f[node.flat] += c.momentum * node.gradient);
        }
        Ok(f)
    }

    /// `Δp_p = scale p̂_p − p_eⁿ_p` of every particle of a patch, less the share of the
    /// previous step's a BDF2 step carries ([`FlowFrozen::carried_increment`]).
    fn pressure_increments(&self, patch: &[usize], x: &[f64]) -> Vec<f64> {
        let flow = self.fluid();
        patch
            .iter()
            .map(|&p| {
                let mut p_hat = 0.0;
                self.frozen[p]
                    .stencil
                    .for_each(|n| p_hat += n.weight * self.dofs.value(n.flat, D, x));
                flow.scale * p_hat - flow.particles[p].excess - flow.particles[p].carried_increment
            })
            .collect()
    }

    /// Adds the stabilisation `scale Σ_p w_p (Δp_p − Π Δp) N_i` to the fluid rows of `f`.
    fn add_stabilisation(&self, x: &[f64], f: &mut [f64]) {
        let flow = self.fluid();
        for patch in &flow.patches {
            let dp = self.pressure_increments(patch, x);
            let w: Vec<f64> = patch.iter().map(|&p| flow.particles[p].weight).collect();
            let total: f64 = w.iter().sum();
            let mean = w.iter().zip(&dp).map(|(w, d)| w * d).sum::<f64>() / total;
            for ((&p, w), d) in patch.iter().zip(&w).zip(&dp) {
                let r = flow.scale * w * (d - mean);
                self.frozen[p].stencil.for_each(|n| {
                    if let NodeDof::Free { dof, sign } = self.dofs.get(n.flat, D) {
                        f[dof] += sign * r * n.weight;
                    }
                });
            }
        }
    }

    /// The stabilisation's tangent, `scale² (Σ_p w_p N_ip N_jp − a_i a_j / Σ_p w_p)` with
    /// `a_i = Σ_p w_p N_ip` per patch (over the union of its particles' stencils), added to
    /// `k`.
    fn add_stabilisation_tangent(&self, k: &mut SparseMatrix) {
        let m = self.stabilisation_tangent();
        k.values
            .iter_mut()
            .zip(&m.values)
            .for_each(|(k, m)| *k += m);
    }

    /// The stabilisation's tangent, assembled by the first call of the step.
    fn stabilisation_tangent(&self) -> &SparseMatrix {
        self.fluid().stabilisation.get_or_init(|| {
            let mut m = SparseMatrix::zeros(self.pattern.clone());
            self.assemble_stabilisation(&mut m);
            m
        })
    }

    /// The pressure mass matrix of the step, `M_ij = Σ_p w_p N_i(x_p) N_j(x_p)` over the free
    /// pressure unknowns, with the stabilisation's weights `w_p = Vⁿ_p / G_p` (the skeleton's
    /// compliance, so that a stiffer material weighs less, as in the undrained Schur
    /// complement `≈ Σ_p Vⁿ_p/(K_p + 4G_p/3) N_i N_j`): what the block preconditioner's Schur
    /// approximation takes its shape from ([`crate::linear::BlockSplit::with_pressure_mass`]).
    /// Zero on the displacement rows.
    ///
    /// # Panics
    /// On a step without pore fluid.
    pub fn pressure_mass(&self) -> SparseMatrix {
        let flow = self.fluid();
        let mut m = SparseMatrix::zeros(self.pattern.clone());
        let mut local: Vec<(Placed, f64)> = Vec::new();
        for (frozen, particle) in self.frozen.iter().zip(&flow.particles) {
            local.clear();
            frozen.stencil.for_each(|n| {
                if let NodeDof::Free { dof, sign } = self.dofs.get(n.flat, D) {
                    local.push((self.place(dof, sign), n.weight));
                }
            });
            for (row, n_row) in &local {
                for (col, n_col) in &local {
                    m.values[self.slot_placed(row, col)] +=
                        row.sign * col.sign * particle.weight * n_row * n_col;
                }
            }
        }
        m
    }

    /// Assembles the stabilisation's tangent into `k` (see
    /// [`StepSystem::add_stabilisation_tangent`]): per patch, a dense block over the nodes
    /// of its particles' stencils, added to `k` once.
    fn assemble_stabilisation(&self, k: &mut SparseMatrix) {
        let flow = self.fluid();
        let s2 = flow.scale * flow.scale;
        let mut nodes: Vec<usize> = Vec::new();
        let mut a: Vec<f64> = Vec::new();
        let mut local: Vec<(usize, f64)> = Vec::new();
        let mut dense: Vec<f64> = Vec::new();
        for patch in &flow.patches {
            nodes.clear();
            a.clear();
            for &p in patch {
                self.frozen[p].stencil.for_each(|n| {
                    if !nodes.contains(&n.flat) {
                        nodes.push(n.flat);
                        a.push(0.0);
                    }
                });
            }
            let m = nodes.len();
            dense.clear();
            dense.resize(m * m, 0.0);
            let mut total = 0.0;
            for &p in patch {
                let w = flow.particles[p].weight;
                total += w;
                local.clear();
                self.frozen[p].stencil.for_each(|n| {
                    let i = nodes.iter().position(|&f| f == n.flat).expect("collected");
                    a[i] += w * n.weight;
                    local.push((i, n.weight));
                });
                let c = s2 * w;
                for &(i, wi) in &local {
                    for &(j, wj) in &local {
                        dense[i * m + j] += c * wi * wj;
                    }
                }
            }
            let c = -s2 / total;
            for (i, ai) in a.iter().enumerate() {
                for (j, aj) in a.iter().enumerate() {
                    dense[i * m + j] += c * ai * aj;
                }
            }
            let placed: Vec<Option<Placed>> = nodes
                .iter()
                .map(|&f| match self.dofs.get(f, D) {
                    NodeDof::Free { dof, sign } => Some(self.place(dof, sign)),
                    _ => None,
                })
                .collect();
            for (row, block) in placed.iter().zip(dense.chunks_exact(m)) {
                let Some(row) = row else { continue };
                for (col, v) in placed.iter().zip(block) {
                    if let Some(col) = col {
                        k.values[self.slot_placed(row, col)] += row.sign * col.sign * v;
                    }
                }
            }
        }
    }

    /// The coupled tangent by per-particle forward-mode AD: the kernel's `L × L` derivative
    /// ([`coupled_lanes`]) in one pass with every input seeded, chained with the shape
    /// functions (`∂ΔF_cd/∂u_jc = ∂_d N_j`, `∂p̂/∂p_j = N_j`, `∂(∇ⁿp̂)_d/∂p_j = ∂_d N_j`, and
    /// the same weights on the rows), plus the stabilisation.
    pub(crate) fn coupled_tangent_local(
        &self,
        x: &[f64],
        materials: &Materials,
    ) -> Result<SparseMatrix, Inverted> {
        match D {
            2 => self.coupled_tangent_from::<7>(|p| self.coupled_local(p, x, &materials.dual7)),
            3 => self.coupled_tangent_from::<13>(|p| self.coupled_local(p, x, &materials.dual13)),
            _ => unreachable!("D is 2 or 3"),
        }
    }

    /// The coupled tangent from every particle's kernel derivative `A_p` ([`CoupledTangent`],
    /// given by `local(p)`; `None`: particle `p` is inverted), chained with the shape
    /// functions, `K_{(i,r),(j,c)} = Σ_p Σ_{o,z} B_i(r)_o A_p,oz B_j(c)_z`, plus the
    /// stabilisation.
    pub fn coupled_tangent_from<const L: usize>(
        &self,
        local: impl Fn(usize) -> Option<CoupledTangent<L>> + Sync,
    ) -> Result<SparseMatrix, Inverted> {
        debug_assert_eq!(L, coupled_lanes(D));
        let mut k = SparseMatrix::zeros(self.pattern.clone());
        self.assemble_coupled_local::<L>(local, &mut k)?;
        self.add_stabilisation_tangent(&mut k);
        Ok(k)
    }

    /// The coupled tangent `K` that [`StepSystem::coupled_tangent_from`] assembles from the
    /// kernel derivatives `local` (one per particle), as the operator `v ↦ Kᵀ v`
    /// ([`CoupledTransposed`]), without assembling it.
    ///
    /// # Panics
    /// On a step without pore fluid, or `local` of the wrong length.
    pub fn coupled_tangent_transposed<const L: usize>(
        &self,
        local: Vec<CoupledTangent<L>>,
    ) -> CoupledTransposed<D, L> {
        debug_assert_eq!(L, coupled_lanes(D));
        assert_eq!(
            local.len(),
            self.frozen.len(),
            "one kernel derivative per particle"
        );
        let mut offsets = Vec::with_capacity(local.len() + 1);
        offsets.push(0);
        let mut nodes = Vec::new();
        for frozen in &self.frozen {
            frozen.stencil.for_each(|n| {
                let unknowns =
                    std::array::from_fn(|c| match (c <= D).then(|| self.dofs.get(n.flat, c)) {
                        Some(NodeDof::Free { dof, sign }) => (dof, sign),
                        _ => (0, 0.0),
                    });
                nodes.push((n.weight, n.gradient, unknowns));
            });
            offsets.push(nodes.len());
        }
        let m = self.stabilisation_tangent();
        let (col_ptr, row_idx) = (m.pattern.col_ptr(), m.pattern.row_idx());
        let mut stabilisation = Vec::new();
        for j in 0..m.pattern.n() {
            for k in col_ptr[j]..col_ptr[j + 1] {
                if m.values[k] != 0.0 {
                    stabilisation.push((row_idx[k], j, m.values[k]));
                }
            }
        }
        CoupledTransposed {
            local,
            offsets,
            nodes,
            stabilisation,
        }
    }

    /// Adds every particle's part of the coupled tangent to `k`. The kernel's derivatives are
    /// taken in parallel chunks of [`CHUNK`] particles; within a chunk, the particles whose
    /// stencils cover the same nodes (the same unknowns) are summed into one dense block,
    /// in particle order, which is then added to `k` once: the sparse look-ups are made per
    /// group of particles rather than per particle, and the order of every sum is fixed.
    fn assemble_coupled_local<const L: usize>(
        &self,
        kernel: impl Fn(usize) -> Option<CoupledTangent<L>> + Sync,
        k: &mut SparseMatrix,
    ) -> Result<(), Inverted> {
        let n = self.frozen.len();
        let fields = D + 1;
        let mut local: Vec<Option<CoupledTangent<L>>> = Vec::new();
        let mut order: Vec<usize> = Vec::new();
        // The group's free node components: their index in the dense block, and placed.
        let mut placed: Vec<(usize, Placed)> = Vec::new();
        let mut shapes: Vec<(f64, Vector<f64, D>)> = Vec::new();
        let mut dense: Vec<f64> = Vec::new();
        let base = |p: usize| self.frozen[p].stencil.base;
        for start in (0..n).step_by(CHUNK) {
            let end = (start + CHUNK).min(n);
            (start..end)
                .into_par_iter()
                .map(&kernel)
                .collect_into_vec(&mut local);
            if let Some(i) = local.iter().position(Option::is_none) {
                return Err(Inverted {
                    particle: start + i,
                });
            }
            order.clear();
            order.extend(start..end);
            order.sort_by_key(|&p| base(p));
            for group in order.chunk_by(|&a, &b| base(a) == base(b)) {
                // The unknowns of the group's nodes, placed once; the dense block holds every
                // node component of the stencil, free or not.
                placed.clear();
                let mut nodes = 0;
                self.frozen[group[0]].stencil.for_each(|node| {
                    for c in 0..fields {
                        if let NodeDof::Free { dof, sign } = self.dofs.get(node.flat, c) {
                            placed.push((nodes * fields + c, self.place(dof, sign)));
                        }
                    }
                    nodes += 1;
                });
                let m = nodes * fields;
                dense.clear();
                dense.resize(m * m, 0.0);
                for &p in group {
                    let a = local[p - start].as_ref().expect("checked above");
                    shapes.clear();
                    self.frozen[p]
                        .stencil
                        .for_each(|n| shapes.push((n.weight, n.gradient)));
                    add_local_block::<D, L>(a, &shapes, &mut dense);
                }
                for (j, col) in &placed {
                    let block = &dense[j * m..(j + 1) * m];
                    for (i, row) in &placed {
                        k.values[self.slot_placed(row, col)] += row.sign * col.sign * block[*i];
                    }
                }
            }
        }
        Ok(())
    }

    /// The kernel's derivative for particle `p` with all `L` inputs seeded.
    fn coupled_local<const L: usize>(
        &self,
        p: usize,
        x: &[f64],
        mats: &[Material<DualSVec64<L>>],
    ) -> Option<CoupledTangent<L>> {
        debug_assert_eq!(L, coupled_lanes(D));
        let (g, p_hat, grad) = self.coupled_inputs(p, x);
        let seed = |v: f64, lane: usize| {
            let mut e = nalgebra::SVector::<f64, L>::zeros();
            e[lane] = 1.0;
            DualSVec64::<L>::new(v, num_dual::Derivative::some(e))
        };
        let gd = Tensor::<DualSVec64<L>, D>::from_fn(|i, j| seed(g[(i, j)], i * D + j));
        let pd = seed(p_hat, D * D);
        let gradd = Vector::<DualSVec64<L>, D>::from_fn(|d, _| seed(grad[d], D * D + 1 + d));
        let c = self.kernel(p, mats, &gd, pd, &gradd)?;
        let lanes = |v: &DualSVec64<L>| -> [f64; L] {
            std::array::from_fn(|l| v.eps.0.as_ref().map_or(0.0, |e| e[l]))
        };
        Some(std::array::from_fn(|o| {
            if o < D * D {
                lanes(&c.momentum[(o / D, o % D)])
            } else if o == D * D {
                lanes(&c.volume)
            } else {
                lanes(&c.flux[o - D * D - 1])
            }
        }))
    }

    /// The coupled tangent by block-colour seeding (the reference, as
    /// [`StepSystem::tangent_colour`] for the solid): per node colour, the `D + 1` unknowns of
    /// every owner node of that colour are seeded in a `D + 1`-lane dual, every particle is
    /// evaluated once, and the dual parts of its rows go to the columns of the one seeded node
    /// in its stencil; plus the stabilisation.
    pub(crate) fn coupled_tangent_colour(
        &self,
        x: &[f64],
        materials: &Materials,
    ) -> Result<SparseMatrix, Inverted> {
        let mut k = SparseMatrix::zeros(self.pattern.clone());
        match D {
            2 => self.coupled_colour_lanes::<3>(x, &materials.dual3, &mut k)?,
            3 => self.coupled_colour_lanes::<4>(x, &materials.dual4, &mut k)?,
            _ => unreachable!("D is 2 or 3"),
        }
        self.add_stabilisation_tangent(&mut k);
        Ok(k)
    }

    fn coupled_colour_lanes<const L: usize>(
        &self,
        x: &[f64],
        mats: &[Material<DualSVec64<L>>],
        k: &mut SparseMatrix,
    ) -> Result<(), Inverted> {
        for colour in 0..self.colours() {
            self.chunked(
                |p| {
                    let fr = &self.frozen[p];
                    // Per component, the seeded unknown in the stencil (its column).
                    let mut seeded = [None; 4];
                    let mut value = |flat: usize, c: usize| {
                        let v = self.dofs.value(flat, c, x);
                        match self.dofs.get(flat, c) {
                            NodeDof::Free { dof, sign } if self.colour(dof) == colour => {
                                seeded[c] = Some(dof);
                                let mut e = nalgebra::SVector::<f64, L>::zeros();
                                e[c] = sign;
                                DualSVec64::<L>::new(v, num_dual::Derivative::some(e))
                            }
                            _ => DualSVec64::<L>::from_re(v),
                        }
                    };
                    let mut g = Tensor::<DualSVec64<L>, D>::identity();
                    let mut p_hat = DualSVec64::<L>::from_re(0.0);
                    let mut grad = Vector::<DualSVec64<L>, D>::zeros();
                    fr.stencil.for_each(|n| {
                        for a in 0..D {
                            let u = value(n.flat, a);
                            for b in 0..D {
                                g[(a, b)] += u * n.gradient[b];
                            }
                        }
                        let pv = value(n.flat, D);
                        p_hat += pv * n.weight;
                        grad += n.gradient.map(DualSVec64::<L>::from_re) * pv;
                    });
                    let c = self.kernel(p, mats, &g, p_hat, &grad)?;
                    Some((seeded, c))
                },
                |p, (seeded, c)| {
                    if seeded.iter().all(Option::is_none) {
                        return;
                    }
                    self.frozen[p].stencil.for_each(|node| {
                        let gi = node.gradient.map(DualSVec64::<L>::from_re);
                        let fi = c.momentum * gi;
                        let gi_fluid = c.volume * node.weight + c.flux.dot(&gi);
                        for r in 0..=D {
                            let NodeDof::Free { dof: row, sign: sr } = self.dofs.get(node.flat, r)
                            else {
                                continue;
                            };
                            let v = if r < D { &fi[r] } else { &gi_fluid };
                            let Some(eps) = v.eps.0.as_ref() else {
                                continue;
                            };
                            for (col_c, col) in seeded.iter().enumerate().take(D + 1) {
                                if let Some(col) = *col {
                                    k.values[self.slot(row, col)] += sr * eps[col_c];
                                }
                            }
                        }
                    });
                },
            )?;
        }
        Ok(())
    }
}

/// A stencil node of [`CoupledTransposed`]: `N`, `∇N`, and per component `c ≤ D` its free
/// unknown and sign (unknown 0 with sign zero where the component is not free: its products
/// add nothing, and there are no branches).
type TransposedNode<const D: usize> = (f64, Vector<f64, D>, [(usize, f64); 4]);

/// The coupled tangent `K` of a step as the operator `v ↦ Kᵀ v`
/// ([`StepSystem::coupled_tangent_transposed`]): per particle `Kₚᵀ v = Bᵀ Aₚᵀ B v` on its
/// stencil's unknowns (`B` the shape-function weights of [`add_local_block`]: `∂_e N_j` on
/// `ΔF_ce`, `N_j` on `p̂`, `∂_e N_j` on `∇p̂_e`), plus the stabilisation's `Sᵀ v`. About
/// `L² + 4 (D + 1) D · 3^D` products per particle, against the `((D + 1) 3^D)²` entries of its
/// dense block in an assembly, with the shape functions and the unknowns' places looked up
/// once. Particles and entries are summed in order, so the product does not depend on the
/// threads.
#[derive(Clone, Debug)]
pub struct CoupledTransposed<const D: usize, const L: usize> {
    /// Per particle, the kernel's derivative `A`.
    local: Vec<CoupledTangent<L>>,
    /// Particle `p`'s stencil nodes are `nodes[offsets[p]..offsets[p + 1]]`.
    offsets: Vec<usize>,
    /// The stencil nodes of every particle.
    nodes: Vec<TransposedNode<D>>,
    /// The stabilisation's nonzero entries `(row, column, value)`, column by column.
    stabilisation: Vec<(usize, usize, f64)>,
}

impl<const D: usize, const L: usize> CoupledTransposed<D, L> {
    /// The derivative `A` of particle `p`'s kernel.
    pub fn local(&self, p: usize) -> &CoupledTangent<L> {
        &self.local[p]
    }

    /// `y = Kᵀ v`.
    ///
    /// # Panics
    /// If `v` or `y` is shorter than the step's unknowns.
    pub fn apply(&self, v: &[f64], y: &mut [f64]) {
        y.fill(0.0);
        for &(i, j, s) in &self.stabilisation {
            y[j] += s * v[i];
        }
        for (a, window) in self.local.iter().zip(self.offsets.windows(2)) {
            let nodes = &self.nodes[window[0]..window[1]];
            // t = B v, the stencil sums of v.
            let mut t = [0.0; L];
            for (weight, gradient, unknowns) in nodes {
                for (c, &(dof, sign)) in unknowns.iter().enumerate().take(D) {
                    let u = sign * v[dof];
                    for e in 0..D {
                        t[c * D + e] += u * gradient[e];
                    }
                }
                let u = unknowns[D].1 * v[unknowns[D].0];
                t[D * D] += u * weight;
                for e in 0..D {
                    t[D * D + 1 + e] += u * gradient[e];
                }
            }
            // w = Aᵀ t.
            let mut w = [0.0; L];
            for (ao, to) in a.iter().zip(&t) {
                for (wz, az) in w.iter_mut().zip(ao) {
                    *wz += az * to;
                }
            }
            // y += Bᵀ w on the free node components.
            for (weight, gradient, unknowns) in nodes {
                for (c, &(dof, sign)) in unknowns.iter().enumerate().take(D) {
                    let mut s = 0.0;
                    for e in 0..D {
                        s += w[c * D + e] * gradient[e];
                    }
                    y[dof] += sign * s;
                }
                let (dof, sign) = unknowns[D];
                let mut s = w[D * D] * weight;
                for e in 0..D {
                    s += w[D * D + 1 + e] * gradient[e];
                }
                y[dof] += sign * s;
            }
        }
    }
}

/// Adds one particle's `K_{(i,r),(j,c)} = Σ_{o,z} B_i(r)_o A_{oz} B_j(c)_z` (the kernel's
/// derivative `A`, `L × L` row-major, between the shape-function weights `B` of the row and
/// column node components) to the dense block `dense`, column-major over every node component
/// `(i, r)` of the stencil (index `i (D + 1) + r`; `shapes` holds `(N_i, ∇N_i)` per node). The
/// weights of a node component over the kernel's inputs are also those over its outputs:
/// `∂_d N` on `ΔF_cd` for a displacement component `c`, `N` on `p̂` and `∂_d N` on `∇p̂_d` for
/// the pressure (inputs in the order `ΔF` row by row, `p̂`, `∇p̂`: `L = D² + 1 + D`).
///
/// Per column node `j` it forms `C_j = A B_jᵀ` (`L × (D + 1)`), then per row node `i` the
/// block `B_i C_j`, in loops of fixed length: the sums are those of the sparse weights, in
/// the same order, without index tables.
fn add_local_block<const D: usize, const L: usize>(
    a: &CoupledTangent<L>,
    shapes: &[(f64, Vector<f64, D>)],
    dense: &mut [f64],
) {
    debug_assert_eq!(L, coupled_lanes(D));
    let fields = D + 1;
    let m = shapes.len() * fields;
    // c[o][c]: output o of A times the weights of component c of node j.
    let mut c = [[0.0; 4]; L];
    for (j, (wj, gj)) in shapes.iter().enumerate() {
        for (co, ao) in c.iter_mut().zip(a) {
            for (comp, cv) in co.iter_mut().enumerate().take(D) {
                let mut v = 0.0;
                for e in 0..D {
                    v += ao[comp * D + e] * gj[e];
                }
                *cv = v;
            }
            let mut v = 0.0 + ao[D * D] * wj;
            for e in 0..D {
                v += ao[D * D + 1 + e] * gj[e];
            }
            co[D] = v;
        }
        for comp in 0..fields {
            let column = &mut dense[(j * fields + comp) * m..(j * fields + comp + 1) * m];
            for ((wi, gi), rows) in shapes.iter().zip(column.chunks_exact_mut(fields)) {
                for (r, kv) in rows.iter_mut().enumerate().take(D) {
                    let mut s = 0.0;
                    for d in 0..D {
                        s += gi[d] * c[r * D + d][comp];
                    }
                    *kv += s;
                }
                let mut s = 0.0 + wi * c[D * D][comp];
                for d in 0..D {
                    s += gi[d] * c[D * D + 1 + d][comp];
                }
                rows[D] += s;
            }
        }
    }
}

/// The pore fluid of a coupled run.
#[derive(Clone, Debug, PartialEq)]
pub struct PoreFluid<const D: usize> {
    /// Per material of the run's table.
    pub hydraulic: Vec<Hydraulic>,
    /// Unit weight of water `γ_w` (N/m³).
    pub unit_weight: f64,
    /// Height of the water table on the last axis (m); `None`: no hydrostatic pressure.
    pub water_table: Option<f64>,
    /// The grid faces that drain.
    pub drained: crate::dofs::Drained<D>,
    /// Whether the pressure projection stabilisation is on (module docs).
    pub stabilisation: bool,
    /// Time (s) and load factor at the end of each load step.
    pub schedule: Schedule,
    /// Prescribed flows of water into the soil, constant in time.
    pub inflow: Vec<Inflow>,
    /// The particles of drained free surfaces.
    pub drains: Vec<SurfaceDrain>,
    /// The time discretisation of the fluid balance.
    pub time_integration: TimeIntegration,
}

/// The time discretisation of the fluid balance `dΞ/dt + ∇·q = 0` (`Ξ` the fluid content,
/// `q` the Darcy flux) over a step from `tⁿ` to `tⁿ⁺¹ = tⁿ + Δt`, the mixture balance being
/// quasi-static at `tⁿ⁺¹`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TimeIntegration {
    /// Backward Euler, first order: `ΔΞ + Δt ∇·qⁿ⁺¹ = 0`. Its lag on a decaying mode
    /// `exp(−λt)` grows as `λ²Δt t/2`.
    #[default]
    BackwardEuler,
    /// The two-step backward differentiation formula with variable steps, second order and
    /// L-stable: with `ω = Δt/Δtⁿ⁻¹` the ratio to the previous step,
    ///
    /// ```text
    /// ΔΞ − c₁ ΔΞⁿ + c₂ Δt ∇·qⁿ⁺¹ = 0,   c₁ = ω²/(1 + 2ω),  c₂ = (1 + ω)/(1 + 2ω)
    /// ```
    ///
    /// (`ΔΞⁿ` the previous step's change, carried per particle: [`FlowFrozen::carried`]),
    /// `ω = 1` giving `ΔΞ − ΔΞⁿ/3 + (2/3) Δt ∇·q = 0`. A step takes backward Euler instead
    /// when there is no previous step with time (the first, or the one after the undrained
    /// loading: the load's jump is not a smooth change to extrapolate) or when it is more
    /// than [`TimeIntegration::MAX_RATIO`] times the previous one.
    Bdf2,
}

impl TimeIntegration {
    /// The largest step ratio `ω` a BDF2 step takes: the formula is zero-stable for
    /// `ω < 1 + √2`, and 2 keeps a margin.
    pub const MAX_RATIO: f64 = 2.0;

    /// `(c₁, c₂)` of a step of `dt` after one of `previous` (zero when there was none with
    /// time): `(0, 1)`, backward Euler, unless BDF2 applies (variant docs). The ratio is
    /// compared with [`TimeIntegration::MAX_RATIO`] to a relative `1e-9`: steps that double
    /// (`growth = 2`) are differences of the schedule's times and come out a few ulp either
    /// side of 2.
    pub fn weights(self, dt: f64, previous: f64) -> (f64, f64) {
        let omega = dt / previous;
        match self {
            Self::Bdf2 if previous > 0.0 && dt > 0.0 && omega <= Self::MAX_RATIO * (1.0 + 1e-9) => {
                (
                    omega * omega / (1.0 + 2.0 * omega),
                    (1.0 + omega) / (1.0 + 2.0 * omega),
                )
            }
            _ => (0.0, 1.0),
        }
    }
}

/// A particle of a drained free surface, which moves with the soil (unlike a drained grid
/// face). The excess pressure falls to zero across the distance `ℓ_p` from the particle to
/// the surface, so the water leaves through the particle's share `A_p` of the surface at the
/// rate `κ A_p p_e / ℓ_p`: over a step it adds `Δt κ (A_p/ℓ_p) p̂_e N_i(xⁿ)` to the fluid
/// balance of node `i` (a Robin condition that tends to `p_e = 0` on the surface as `ℓ_p`
/// shrinks with the cell size). The undrained steps at `t = 0` (`Δt = 0`) lose no water.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceDrain {
    /// Particle id.
    pub particle: usize,
    /// `A_p / ℓ_p` (m; dimensionless in 2D, per metre of depth): the particle's share of the
    /// surface over its distance to it.
    pub conductance: f64,
}

/// A prescribed flow of water into the soil through a free surface, carried by one particle
/// of the surface: over a step it brings `Δt Q N_i(xⁿ)` to the fluid balance of node `i`
/// (the natural boundary term `Δt ∫_Γ q̄ N_i dΓ` with the surface lumped on its particles).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inflow {
    /// Particle id.
    pub particle: usize,
    /// Volume rate `Q = q̄ A_p` into the soil (m³/s; m²/s per metre of depth in 2D); negative
    /// for an outflow.
    pub rate: f64,
}

impl<const D: usize> PoreFluid<D> {
    /// The hydrostatic pressure `p_h = γ_w (z_w − z)` below the water table, zero above it
    /// or without one (Pa).
    pub fn hydrostatic(&self, x: &Vector<f64, D>) -> f64 {
        self.water_table
            .map_or(0.0, |z| self.unit_weight * (z - x[D - 1]).max(0.0))
    }
}

/// Time and load factor along a coupled run: `time[k]` and `load[k]` at the end of load step
/// `k` (`time[0] = 0`, `load[0] = 0` at the start), linear in between.
#[derive(Clone, Debug, PartialEq)]
pub struct Schedule {
    /// Time at the end of each step (s), non-decreasing from 0.
    pub time: Vec<f64>,
    /// Load factor at the end of each step.
    pub load: Vec<f64>,
}

impl Schedule {
    /// The first `loading` steps (at least one) ramp the load from 0 to 1 in zero time
    /// (undrained loading), then the load is held over time steps `dt₀, dt₀ r, dt₀ r², …`
    /// until `end` (the last step shortened to end there).
    pub fn geometric(loading: usize, first: f64, growth: f64, end: f64) -> Self {
        let loading = loading.max(1);
        let mut time = vec![0.0; loading + 1];
        let mut load: Vec<f64> = (0..=loading).map(|k| k as f64 / loading as f64).collect();
        let mut dt = first;
        let mut t = 0.0;
        while t < end * (1.0 - 1e-12) {
            t = (t + dt).min(end);
            time.push(t);
            load.push(1.0);
            dt *= growth;
        }
        Self { time, load }
    }

    /// Splits the step that spans time `t` so that a step ends at `t` (for output at given
    /// times); the load factor there is interpolated. No-op when a step already ends within
    /// `1e-9 t` of it or `t` is outside the schedule.
    pub fn land_on(&mut self, t: f64) {
        let tol = 1e-9 * t.abs();
        if self.time.iter().any(|&s| (s - t).abs() <= tol) {
            return;
        }
        if let Some(k) = self.time.iter().position(|&s| s > t)
            && k > 0
        {
            let w = (t - self.time[k - 1]) / (self.time[k] - self.time[k - 1]);
            let load = self.load[k - 1] + w * (self.load[k] - self.load[k - 1]);
            self.time.insert(k, t);
            self.load.insert(k, load);
        }
    }

    /// Number of load steps.
    pub fn steps(&self) -> usize {
        self.time.len() - 1
    }

    /// `(time, load factor)` at run progress `s ∈ [0, 1]` (`s · steps` load steps done).
    pub fn at(&self, s: f64) -> (f64, f64) {
        let n = self.steps();
        let x = (s * n as f64).clamp(0.0, n as f64);
        let k = (x.floor() as usize).min(n.saturating_sub(1));
        let w = x - k as f64;
        let lerp = |v: &[f64]| v[k] + w * (v[k + 1] - v[k]);
        (lerp(&self.time), lerp(&self.load))
    }
}
