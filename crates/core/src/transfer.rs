//! Particle ↔ grid transfers: PIC, FLIP (blend) and APIC, generic over the scalar type.
//!
//! P2G (per particle, per stencil node `i`, weight `w_ip`, gradient `∇w_ip`):
//! - mass `m_i += w_ip m_p`;
//! - momentum `(m v)_i += w_ip m_p (v_p + C_p (x_i − x_p))` (`C_p = 0` for PIC / FLIP);
//! - internal force `f_i −= V_p σ_p ∇w_ip`, `V_p = J_p V_p⁰`.
//!
//! G2P gathers `v̄ = Σ w_ip v_i`, `L_p = Σ v_i ⊗ ∇w_ip` and, for APIC,
//! `C_p = D_p⁻¹-scaled Σ w_ip v_i (x_i − x_p)ᵀ` (B-splines, `D_p = κ h² I`) or `C_p = L_p`
//! (hat and GIMP, whose `D_p` is position dependent and may be singular); TPIC always takes
//! `C_p = L_p`.

use crate::grid::Grid;
use crate::scalar::Scalar;
use crate::shape::Shape;
use crate::stencil::Stencil;
use crate::tensor::{Tensor, Vector};
use serde::{Deserialize, Serialize};

/// The particle-velocity update scheme.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Transfer {
    /// Particle-in-cell: `v_p = Σ w v_i` (dissipative, stable).
    Pic,
    /// FLIP/PIC blend: `v_p ← α (v_p + Σ w (v_i − v_iⁿ)) + (1 − α) Σ w v_i`.
    Flip {
        /// FLIP fraction `α ∈ [0, 1]` (0 = PIC, 1 = pure FLIP).
        alpha: f64,
    },
    /// Affine particle-in-cell (Jiang et al. 2015): PIC plus the affine matrix `C_p`,
    /// conserving linear and angular momentum.
    Apic,
    /// Taylor particle-in-cell (Nakamura et al. 2023): like APIC, but the particle carries the
    /// velocity gradient `C_p = L_p = Σ_i v_i ⊗ ∇w_ip` for every shape function, a first-order
    /// Taylor expansion of the grid velocity about the particle.
    Tpic,
}

impl Transfer {
    /// Whether P2G carries the affine term `C_p (x_i − x_p)`.
    pub fn is_affine(&self) -> bool {
        matches!(self, Transfer::Apic | Transfer::Tpic)
    }

    /// Whether G2P needs the grid velocity at the start of the step.
    pub fn needs_old_grid_velocity(&self) -> bool {
        matches!(self, Transfer::Flip { .. })
    }
}

/// The velocity a particle carries to a node: `v_p + C_p (x_i − x_p)` (APIC) or `v_p`.
#[inline(always)]
fn affine_velocity<T: Scalar, const D: usize>(
    v: &Vector<T, D>,
    affine: Option<&Tensor<T, D>>,
    offset: &Vector<T, D>,
) -> Vector<T, D> {
    match affine {
        Some(c) => v + c * offset,
        None => *v,
    }
}

/// Calls `sink(node, m_ip, p_ip, f_ip)` with one particle's mass, momentum and internal force
/// contributions to each node of its stencil (see the module docs for the formulas).
/// `stress_volume = V_p σ_p` (the in-plane block in 2D); `affine` is `C_p` or `None`.
#[inline]
pub fn p2g<T: Scalar, const D: usize>(
    stencil: &Stencil<T, D>,
    v: &Vector<T, D>,
    affine: Option<&Tensor<T, D>>,
    mass: T,
    stress_volume: &Tensor<T, D>,
    mut sink: impl FnMut([usize; D], T, Vector<T, D>, Vector<T, D>),
) {
    stencil.for_each(|n| {
        let mw = mass * n.weight;
        sink(
            n.index,
            mw,
            affine_velocity(v, affine, &n.offset) * mw,
            -(stress_volume * n.gradient),
        );
    });
}

/// Calls `sink(node, m_ip, p_ip)` for the momentum-only transfer of MUSL's second P2G.
#[inline]
pub fn p2g_momentum<T: Scalar, const D: usize>(
    stencil: &Stencil<T, D>,
    v: &Vector<T, D>,
    affine: Option<&Tensor<T, D>>,
    mass: T,
    mut sink: impl FnMut([usize; D], T, Vector<T, D>),
) {
    stencil.for_each(|n| {
        let mw = mass * n.weight;
        sink(n.index, mw, affine_velocity(v, affine, &n.offset) * mw);
    });
}

/// What G2P gathers from the grid for one particle.
#[derive(Clone, Copy, Debug)]
pub struct Gathered<T: Scalar, const D: usize> {
    /// `Σ w_ip v_i` with the updated grid velocity.
    pub v: Vector<T, D>,
    /// `Σ w_ip (v_i − v_iⁿ)` (FLIP increment; zero unless requested).
    pub dv: Vector<T, D>,
    /// Velocity gradient `L_p = Σ v_i ⊗ ∇w_ip`.
    pub grad_v: Tensor<T, D>,
    /// APIC affine matrix `C_p` (zero unless requested).
    pub affine: Tensor<T, D>,
}

/// Gathers the grid velocity field at a particle. `velocity(flat)` returns the updated nodal
/// velocity of the node with flat index `flat` and `old(flat)` its velocity at the start of
/// the step (FLIP only).
#[inline]
pub fn g2p<T: Scalar, const D: usize>(
    stencil: &Stencil<T, D>,
    grid: &Grid<D>,
    shape: Shape,
    transfer: Transfer,
    velocity: impl Fn(usize) -> Vector<T, D>,
    old: impl Fn(usize) -> Vector<T, D>,
) -> Gathered<T, D> {
    let mut out = Gathered {
        v: Vector::zeros(),
        dv: Vector::zeros(),
        grad_v: Tensor::zeros(),
        affine: Tensor::zeros(),
    };
    let flip = transfer.needs_old_grid_velocity();
    let apic_b = if transfer == Transfer::Apic {
        shape.apic_inverse_inertia()
    } else {
        None
    };
    stencil.for_each(|n| {
        let vi = velocity(n.flat);
        out.v += vi * n.weight;
        out.grad_v += vi * n.gradient.transpose();
        if flip {
            out.dv += (vi - old(n.flat)) * n.weight;
        }
        if apic_b.is_some() {
            out.affine += vi * n.offset.transpose() * n.weight;
        }
    });
    if transfer.is_affine() {
        out.affine = match apic_b {
            Some(k) => out.affine * T::cst(k / (grid.h * grid.h)),
            None => out.grad_v,
        };
    }
    out
}

impl Transfer {
    /// New particle velocity and affine matrix from the gathered grid field and the old
    /// particle velocity.
    #[inline]
    pub fn particle_velocity<T: Scalar, const D: usize>(
        &self,
        v_old: &Vector<T, D>,
        g: &Gathered<T, D>,
    ) -> (Vector<T, D>, Tensor<T, D>) {
        match *self {
            Transfer::Pic => (g.v, Tensor::zeros()),
            Transfer::Flip { alpha } => {
                let a = T::cst(alpha);
                ((v_old + g.dv) * a + g.v * (T::one() - a), Tensor::zeros())
            }
            Transfer::Apic | Transfer::Tpic => (g.v, g.affine),
        }
    }
}

#[cfg(test)]
mod tests;
