//! Stage 1: particle to grid.
//!
//! Per particle `p` and node `i` of its stencil (weight `w_ip`, gradient `∇w_ip`):
//! `m_i += w_ip m_p`, `(m v)_i += w_ip (m_p v_p + m_p C_p (x_i − x_p))`,
//! `f_i −= V_p σ_p ∇w_ip` with `V_p = det(F_p) V_p⁰` (see [`crate::transfer`]); MLS-MPM folds
//! `Δt f_i` into the momentum ([`mls_affine_momentum`]) and leaves `f_i` zero.

use crate::grid::Grid;
use crate::particles::Particles;
use crate::scalar::Scalar;
use crate::shape::Shape;
use crate::stencil::{Frame, Layout, Stencil, particle_half_width};
use crate::tensor::{Tensor, Vector, det, from3};
use crate::transfer::{Transfer, mls_affine_momentum, p2g, p2g_momentum};

/// What P2G adds up at a node: mass `m_i`, momentum `(m v)_i` and internal force `f_i`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeSums<T: Scalar, const D: usize> {
    /// Mass `m_i = Σ_p w_ip m_p`.
    pub m: T,
    /// Momentum `(m v)_i`.
    pub p: Vector<T, D>,
    /// Internal force `f_i` (zero for MLS-MPM, whose force is in `p`).
    pub f: Vector<T, D>,
}

impl<T: Scalar, const D: usize> NodeSums<T, D> {
    /// All zero.
    #[inline]
    pub fn zero() -> Self {
        Self {
            m: T::zero(),
            p: Vector::zeros(),
            f: Vector::zeros(),
        }
    }
}

/// The P2G stage of one step: what it needs besides the particles (the grid frame, the shape
/// function, the transfer's force form and `Δt`), formed once per step.
#[derive(Clone, Copy, Debug)]
pub struct P2g<T: Scalar, const D: usize> {
    shape: Shape,
    frame: Frame<T, D>,
    h: f64,
    affine: bool,
    /// MLS-MPM's `1/κ` (`D_p = κ h² I`), `None` for the gradient force.
    mls: Option<f64>,
    dt: T,
}

impl<T: Scalar, const D: usize> P2g<T, D> {
    /// The stage for a step of size `dt` on `grid`.
    ///
    /// # Panics
    /// If `transfer` is MLS-MPM and `shape` is not a B-spline (`loam-explicit`'s
    /// `Config::validate` refuses that combination first).
    pub fn new(grid: &Grid<D>, shape: Shape, transfer: Transfer, dt: f64) -> Self {
        Self {
            shape,
            frame: Frame::new(grid),
            h: grid.h,
            affine: transfer.is_affine(),
            mls: transfer.is_mls().then(|| {
                shape
                    .apic_inverse_inertia()
                    .expect("MLS-MPM needs a B-spline shape function")
            }),
            dt: T::cst(dt),
        }
    }

    /// Particle `i`'s stencil of the step (into `stencil`, from `x_p`, `F_p` and its
    /// half-width) and its mass, momentum and internal force added to `nodes`, an array of the
    /// given `layout`.
    #[inline(always)]
    pub fn particle(
        &self,
        p: &Particles<T, D>,
        i: usize,
        stencil: &mut Stencil<T, D>,
        layout: &Layout<D>,
        nodes: &mut [NodeSums<T, D>],
    ) {
        let hw = particle_half_width(self.shape, self.h, &p.half_width0[i], &p.f[i]);
        stencil.set_in(self.shape, &self.frame, &p.x[i], &hw);
        let volume = p.volume0[i] * det(&p.f[i]);
        let sv = from3::<T, D>(&p.stress[i]) * volume;
        let m = p.mass[i];
        if let Some(inverse_inertia) = self.mls {
            // Internal force and affine momentum in one term; `f` stays zero.
            let a = mls_affine_momentum(m, &p.c[i], &sv, self.dt, inverse_inertia, self.h);
            p2g_momentum(
                stencil,
                layout,
                &p.v[i],
                &a,
                m,
                nodes,
                #[inline(always)]
                |e, m, mom| {
                    e.m += m;
                    e.p += mom;
                },
            );
        } else {
            p2g(
                stencil,
                layout,
                &p.v[i],
                self.affine.then_some(&p.c[i]),
                m,
                &sv,
                nodes,
                #[inline(always)]
                |e, m, mom, f| {
                    e.m += m;
                    e.p += mom;
                    e.f += f;
                },
            );
        }
    }
}

/// MUSL's second P2G for one particle: the momentum of its updated velocity `v` (and affine
/// matrix `c` when `affine`) at its start-of-step stencil, `(m v)_i += w_ip m_p (v + C (x_i −
/// x_p))`, added to `nodes[..].p`.
#[inline(always)]
pub fn momentum_to_grid<T: Scalar, const D: usize>(
    stencil: &Stencil<T, D>,
    layout: &Layout<D>,
    mass: T,
    v: &Vector<T, D>,
    c: &Tensor<T, D>,
    affine: bool,
    nodes: &mut [NodeSums<T, D>],
) {
    let mc = if affine { c * mass } else { Tensor::zeros() };
    p2g_momentum(
        stencil,
        layout,
        v,
        &mc,
        mass,
        nodes,
        #[inline(always)]
        |e, _, mom| e.p += mom,
    );
}
