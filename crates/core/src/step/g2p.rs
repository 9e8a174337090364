//! Stage 3: grid to particle.
//!
//! Per particle, from the updated grid velocity `v_i` (and `v_iⁿ` for FLIP): the new velocity
//! and affine matrix by the transfer ([`Transfer::particle_velocity`]: PIC, FLIP, APIC, TPIC,
//! MLS-MPM), the position `x ← x + Δt Σ w_ip v_i`, and the velocity gradient
//! `L_p = Σ v_i ⊗ ∇w_ip` (MLS-MPM: `L_p = C_p`).

use crate::grid::Grid;
use crate::scalar::Scalar;
use crate::shape::Shape;
use crate::stencil::{Layout, Stencil};
use crate::tensor::{Tensor, Vector};
use crate::transfer::{Gathered, Transfer, g2p};

/// The G2P stage of one step: grid, shape, transfer and `Δt`, formed once per step.
#[derive(Clone, Copy, Debug)]
pub struct G2p<'a, T: Scalar, const D: usize> {
    grid: &'a Grid<D>,
    layout: Layout<D>,
    shape: Shape,
    transfer: Transfer,
    dt: T,
}

impl<'a, T: Scalar, const D: usize> G2p<'a, T, D> {
    /// The stage for a step of size `dt`, reading grid arrays laid out as the whole `grid`.
    pub fn new(grid: &'a Grid<D>, shape: Shape, transfer: Transfer, dt: f64) -> Self {
        Self {
            grid,
            layout: Layout::grid(grid),
            shape,
            transfer,
            dt: T::cst(dt),
        }
    }

    /// The transfer's sums at a particle with stencil `st` (the gradient when `gradient`).
    #[inline(always)]
    fn gather(
        &self,
        st: &Stencil<T, D>,
        gradient: bool,
        vel: &[Vector<T, D>],
        old: &[Vector<T, D>],
    ) -> Gathered<T, D> {
        let (grid, shape, transfer) = (self.grid, self.shape, self.transfer);
        g2p(st, &self.layout, grid, shape, transfer, gradient, vel, old)
    }

    /// USL: the particle's new velocity `v`, affine matrix `c` and position `x` from the
    /// updated grid velocity `vel` (`old`: the start-of-step grid velocity, read by FLIP
    /// only); returns its velocity gradient `L_p`.
    #[inline(always)]
    pub fn particle(
        &self,
        st: &Stencil<T, D>,
        vel: &[Vector<T, D>],
        old: &[Vector<T, D>],
        x: &mut Vector<T, D>,
        v: &mut Vector<T, D>,
        c: &mut Tensor<T, D>,
    ) -> Tensor<T, D> {
        // MLS takes L = C and needs no gradient sums (a constant flag per call, so each
        // inlines to only its own sums).
        let (g, l) = if self.transfer.is_mls() {
            let g = self.gather(st, false, vel, old);
            (g, g.affine)
        } else {
            let g = self.gather(st, true, vel, old);
            (g, g.grad_v)
        };
        (*v, *c) = self.transfer.particle_velocity(v, &g);
        *x += g.v * self.dt;
        l
    }

    /// MUSL's first half: the new position, velocity and affine matrix of a particle at
    /// `x` with velocity `v`, without the velocity gradient.
    #[inline(always)]
    pub fn motion(
        &self,
        st: &Stencil<T, D>,
        vel: &[Vector<T, D>],
        old: &[Vector<T, D>],
        x: &Vector<T, D>,
        v: &Vector<T, D>,
    ) -> (Vector<T, D>, Vector<T, D>, Tensor<T, D>) {
        let g = self.gather(st, false, vel, old);
        let (v, c) = self.transfer.particle_velocity(v, &g);
        (x + g.v * self.dt, v, c)
    }

    /// MUSL's velocity gradient from the re-projected grid velocity `vel`:
    /// `L_p = Σ v_i ⊗ ∇w_ip`, or MLS-MPM's `C_p` of that field.
    #[inline(always)]
    pub fn velocity_gradient(&self, st: &Stencil<T, D>, vel: &[Vector<T, D>]) -> Tensor<T, D> {
        let (l, grid, shape) = (&self.layout, self.grid, self.shape);
        // Two calls with constant transfers, so each inlines to only its own sums.
        if self.transfer.is_mls() {
            g2p(st, l, grid, shape, Transfer::Mls, false, vel, &[]).affine
        } else {
            g2p(st, l, grid, shape, Transfer::Pic, true, vel, &[]).grad_v
        }
    }
}
