//! The Newmark terms of a sub-step (`loam_implicit::system::Inertia`) in the reverse and the
//! tangent pass.
//!
//! On the unknowns of a Newmark step of size `Δt`, with the consistent mass
//! `M_dd' = Σₚ mₚ w_pd w_pd'` (per component; `w_pd = Σ_{i→d} s_i N_i(xₚ)` the weight of unknown
//! `d` at particle `p` through the unknown map, mirror signs `s_i` included), the momentum
//! `pₙ = Σₚ mₚ w_p vₚ` and the start force `rₙ = f_ext − f_int(0)`, the step computes
//!
//! ```text
//! R(Δu)   = f_int(Δu) + f_int(0) − 2 f_ext + (4/Δt²) M Δu − (4/Δt) pₙ = 0
//! B Δv    = (2/Δt) M Δu − 2 pₙ              (B = M + ε diag M)
//! vₚ'     = vₚ + ⟨Δv⟩ₚ                      (⟨y⟩ₚ = Σ_i N_i(xₚ) y_i through the unknown map)
//! ```
//!
//! and the acceleration `M aₙ₊₁ = (2/Δt) M Δv − rₙ`, which no later step reads. With `v̄'` the
//! adjoint of the end velocities, the reverse of the mass solve is `B μ = Δv̄ = Σₚ w_p v̄'ₚ`
//! (B is symmetric), the adjoint system gains `(2/Δt) M μ` on its right-hand side, and with
//! `λ` its solution the scalar whose derivatives by the particle's state and the parameters
//! are the step's adjoint gains, besides `−λ·f_int(0)` and the weight `2λ` on `f_ext`,
//!
//! ```text
//! ψₚ,dyn = mₚ (⟨α⟩·⟨Δu⟩ − ⟨μ⟩·⟨Δv⟩ + ⟨β⟩·vₚ − Σ_d ε μ_d Δv_d w_pd²) + v̄'ₚ·(vₚ + ⟨Δv⟩ₚ)
//! α = (2/Δt) μ − (4/Δt²) λ,     β = (4/Δt) λ − 2 μ
//! ```
//!
//! (`Δu` here on the unknowns only: `M` couples no prescribed component), so that
//!
//! ```text
//! N̄_i = mₚ Σ_c (α_i ⟨Δu⟩ + ⟨α⟩ Δu_i − μ_i ⟨Δv⟩ − ⟨μ⟩ Δv_i + β_i vₚ − 2 ε μ_d Δv_d w_pd s_i)_c + v̄'ₚ·Δv_i
//! v̄ₚ  = v̄'ₚ + mₚ ⟨β⟩ₚ,     m̄ₚ += ⟨α⟩·⟨Δu⟩ − ⟨μ⟩·⟨Δv⟩ + ⟨β⟩·vₚ − Σ_d ε μ_d Δv_d w_pd²
//! ```
//!
//! and `N̄_i` goes through the stencil's Jacobian into `x̄ₚ` and `F̄ₚ` (`super::pullback`). The
//! tangent pass takes the derivative parts of the same particle sums with dual weights,
//! masses and velocities ([`rates`]).

use loam_core::Scalar;
use loam_core::tensor::Vector;
use loam_implicit::NodeDof;
use loam_implicit::dofs::DofMap;
use loam_implicit::system::{Inertia, MASS_REGULARISATION};
use num_dual::Dual64;

/// `⟨y⟩ₚ = Σ_i N_i y_i` of a field `y` on the unknowns, for the stencil `nodes` (flat index,
/// weight `N_i`).
pub fn interpolate<T: Scalar, const D: usize>(
    nodes: &[(usize, T)],
    dofs: &DofMap<D>,
    y: &[f64],
) -> Vector<T, D> {
    let mut out = Vector::<T, D>::zeros();
    for &(flat, w) in nodes {
        for c in 0..D {
            out[c] += w * T::cst(dofs.field(flat, c, y));
        }
    }
    out
}

/// The weights `w_pd = Σ_{i→d} s_i N_i` of the distinct unknowns `d` a stencil reaches.
fn dof_weights<T: Scalar, const D: usize>(
    nodes: &[(usize, T)],
    dofs: &DofMap<D>,
) -> Vec<(usize, T)> {
    let mut out: Vec<(usize, T)> = Vec::with_capacity(nodes.len() * D);
    for &(flat, w) in nodes {
        for c in 0..D {
            if let NodeDof::Free { dof, sign } = dofs.get(flat, c) {
                match out.iter_mut().find(|(d, _)| *d == dof) {
                    Some((_, s)) => *s += w * T::cst(sign),
                    None => out.push((dof, w * T::cst(sign))),
                }
            }
        }
    }
    out
}

/// The weights of a Newmark sub-step's grid terms in the reverse pass (module docs), on the
/// unknowns.
#[derive(Debug)]
pub struct InertiaWeights<'a, const D: usize> {
    dofs: &'a DofMap<D>,
    du: &'a [f64],
    dv: &'a [f64],
    alpha: Vec<f64>,
    mu: &'a [f64],
    beta: Vec<f64>,
    /// `ε μ_d Δv_d`.
    diagonal: Vec<f64>,
}

/// A particle's share of `ψₚ,dyn` differentiated (module docs).
#[derive(Clone, Debug)]
pub struct InertiaPull<const D: usize> {
    /// `N̄_i` per stencil node, in the order given.
    pub weights: Vec<f64>,
    /// `v̄ₚ` (the end velocity's adjoint included).
    pub velocity: Vector<f64, D>,
    /// The share of `m̄ₚ`.
    pub mass: f64,
}

impl<'a, const D: usize> InertiaWeights<'a, D> {
    /// The weights of the step of `inertia` on the unknowns of `dofs`, with the converged
    /// `Δu` and `Δv`, the adjoint system's solution `λ` and the mass solve's `μ`.
    pub fn new(
        dofs: &'a DofMap<D>,
        inertia: &Inertia,
        du: &'a [f64],
        dv: &'a [f64],
        lambda: &[f64],
        mu: &'a [f64],
    ) -> Self {
        let dt = inertia.dt;
        Self {
            dofs,
            du,
            dv,
            alpha: (mu.iter().zip(lambda))
                .map(|(m, l)| 2.0 / dt * m - 4.0 / (dt * dt) * l)
                .collect(),
            mu,
            beta: (mu.iter().zip(lambda))
                .map(|(m, l)| 4.0 / dt * l - 2.0 * m)
                .collect(),
            diagonal: (mu.iter().zip(dv))
                .map(|(m, v)| MASS_REGULARISATION * m * v)
                .collect(),
        }
    }

    /// `∂ψₚ,dyn` by the stencil weights, the velocity and the mass of a particle with stencil
    /// `nodes`, mass `mass`, velocity `v` and end-velocity adjoint `v_end`.
    pub fn pull(
        &self,
        nodes: &[(usize, f64)],
        mass: f64,
        v: &Vector<f64, D>,
        v_end: &Vector<f64, D>,
    ) -> InertiaPull<D> {
        let at = |y: &[f64]| interpolate(nodes, self.dofs, y);
        let (alpha, du, mu, dv, beta) = (
            at(&self.alpha),
            at(self.du),
            at(self.mu),
            at(self.dv),
            at(&self.beta),
        );
        let w = dof_weights(nodes, self.dofs);
        let diagonal: f64 = w.iter().map(|&(d, wd)| self.diagonal[d] * wd * wd).sum();
        let weights = (nodes.iter())
            .map(|&(flat, _)| {
                let field =
                    |y: &[f64]| Vector::<f64, D>::from_fn(|c, _| self.dofs.field(flat, c, y));
                let mut dyn_part = field(&self.alpha).dot(&du) + alpha.dot(&field(self.du))
                    - field(self.mu).dot(&dv)
                    - mu.dot(&field(self.dv))
                    + field(&self.beta).dot(v);
                for c in 0..D {
                    if let NodeDof::Free { dof, sign } = self.dofs.get(flat, c) {
                        let wd = w.iter().find(|(d, _)| *d == dof).map_or(0.0, |x| x.1);
                        dyn_part -= 2.0 * self.diagonal[dof] * wd * sign;
                    }
                }
                mass * dyn_part + v_end.dot(&field(self.dv))
            })
            .collect();
        InertiaPull {
            weights,
            velocity: v_end + beta * mass,
            mass: alpha.dot(&du) - mu.dot(&dv) + beta.dot(v) - diagonal,
        }
    }
}

/// `Δv̄ = Σₚ w_p v̄'ₚ`: the end velocities' adjoint gathered onto the unknowns, from every
/// particle's stencil (flat index, weight) and `v̄'ₚ`.
pub fn gather<'a, const D: usize>(
    dofs: &DofMap<D>,
    particles: impl Iterator<Item = (&'a [(usize, f64)], Vector<f64, D>)>,
) -> Vec<f64> {
    let mut out = vec![0.0; dofs.len()];
    for (nodes, v_end) in particles {
        for &(flat, w) in nodes {
            for c in 0..D {
                if let NodeDof::Free { dof, sign } = dofs.get(flat, c) {
                    out[dof] += sign * w * v_end[c];
                }
            }
        }
    }
    out
}

/// The derivative parts of a Newmark step's particle sums, on the unknowns.
#[derive(Clone, Debug)]
pub struct InertiaRates {
    /// `Ṁ y` for each field `y` given to [`rates`], in order.
    pub mass_times: Vec<Vec<f64>>,
    /// `ṗₙ`.
    pub momentum: Vec<f64>,
    /// `diag Ṁ`.
    pub diagonal: Vec<f64>,
}

/// The derivative parts of `M y` (every `y` of `fields`), of `pₙ` and of `diag M`, from every
/// particle's stencil, mass and velocity in `Dual64` (the tangent pass).
pub fn rates<'a, const D: usize>(
    dofs: &DofMap<D>,
    particles: impl Iterator<Item = (Vec<(usize, Dual64)>, Dual64, &'a Vector<Dual64, D>)>,
    fields: &[&[f64]],
) -> InertiaRates {
    let n = dofs.len();
    let mut out = InertiaRates {
        mass_times: vec![vec![0.0; n]; fields.len()],
        momentum: vec![0.0; n],
        diagonal: vec![0.0; n],
    };
    for (nodes, mass, v) in particles {
        let at: Vec<Vector<Dual64, D>> = fields
            .iter()
            .map(|y| interpolate(&nodes, dofs, y))
            .collect();
        for &(flat, w) in &nodes {
            for c in 0..D {
                if let NodeDof::Free { dof, sign } = dofs.get(flat, c) {
                    let share = mass * w * sign;
                    for (m, y) in out.mass_times.iter_mut().zip(&at) {
                        m[dof] += (share * y[c]).eps;
                    }
                    out.momentum[dof] += (share * v[c]).eps;
                }
            }
        }
        for (dof, wd) in dof_weights(&nodes, dofs) {
            out.diagonal[dof] += (mass * wd * wd).eps;
        }
    }
    out
}
