//! The step's local kernels as functions of flat input lists, for [`crate::lanes::vjp`]: each
//! unpacks its inputs, runs the `loam-core` stage functions exactly as
//! `loam_explicit::Solver::step` composes them, and packs its outputs.

use crate::lanes::{Packed, Unpack};
use loam_core::constitutive::{Elasticity, HISTORY_LEN, Material, Model};
use loam_core::step::{EndOfStep, NodeLaw, NodeState, momentum_update, particle_end};
use loam_core::tensor::{Tensor, Vector};
use loam_core::transfer::Gathered;
use loam_core::{Scalar, Transfer};

/// The inputs of a transfer's G2P: the gathered `G.v`, `G.dv` (D each), `G.grad_v`,
/// `G.affine` (D² each), then the start-of-step `x`, `v` (D each).
pub(super) struct Motion<const D: usize>;

impl<const D: usize> Motion<D> {
    pub const G_V: usize = 0;
    pub const G_DV: usize = D;
    pub const G_GRAD: usize = 2 * D;
    pub const G_AFF: usize = 2 * D + D * D;
    pub const X: usize = 2 * D + 2 * D * D;
    pub const V: usize = 3 * D + 2 * D * D;
    /// Where the inputs after the motion's begin.
    pub const END: usize = 4 * D + 2 * D * D;

    /// The motion's input lanes whose adjoint can be non-zero: `G.v` and `x` always, `G.dv`
    /// and `v` for FLIP, `G.affine` for the affine transfers, `G.grad_v` when `gradient`
    /// (USL takes `L` from it).
    pub fn lanes(transfer: Transfer, gradient: bool) -> Vec<usize> {
        let mut lanes: Vec<usize> = (Self::G_V..Self::G_V + D).collect();
        if transfer.needs_old_grid_velocity() {
            lanes.extend(Self::G_DV..Self::G_DV + D);
            lanes.extend(Self::V..Self::V + D);
        }
        if gradient {
            lanes.extend(Self::G_GRAD..Self::G_GRAD + D * D);
        }
        if transfer.is_affine() {
            lanes.extend(Self::G_AFF..Self::G_AFF + D * D);
        }
        lanes.extend(Self::X..Self::X + D);
        lanes
    }
}

/// The inputs of the particle end after the motion: `F` (D²), `σ` (9), the history
/// ([`HISTORY_LEN`]), from offset `start`.
pub(super) struct End;

impl End {
    /// Length of the block in `D` dimensions.
    pub const fn len(d: usize) -> usize {
        d * d + 9 + HISTORY_LEN
    }

    /// The input lanes of the block from `start` whose adjoint can be non-zero for `model`:
    /// `F` always, the stress for the rate model that integrates from it, the history for the
    /// plastic models.
    pub fn lanes<const D: usize>(start: usize, model: &Model<f64>) -> Vec<usize> {
        let mut lanes: Vec<usize> = (start..start + D * D).collect();
        let s = start + D * D;
        let (stress, history) = match model {
            Model::DruckerPrager(dp) => (dp.elasticity == Elasticity::Jaumann, true),
            Model::J2(_) | Model::MohrCoulomb(_) | Model::ModifiedCamClay(_) => (false, true),
            _ => (false, false),
        };
        if stress {
            lanes.extend(s..s + 9);
        }
        if history {
            lanes.extend(s + 9..s + 9 + HISTORY_LEN);
        }
        lanes
    }
}

/// Reads `G` (the gathered sums) from the inputs.
fn gathered<T: Scalar, const D: usize>(u: &mut Unpack<'_, T>) -> Gathered<T, D> {
    Gathered {
        v: u.vector::<D>(),
        dv: u.vector::<D>(),
        grad_v: u.tensor::<D>(),
        affine: u.tensor::<D>(),
    }
}

/// The particle end of [`particle_end`] on unpacked inputs (`F`, `σ`, history from `u`),
/// writing `x, v, F, σ, plastic strain, tensor` (and `C` after `v` when `c` is given).
#[allow(clippy::too_many_arguments)]
fn finish<T: Scalar, const D: usize>(
    end: &EndOfStep<'_, T, D>,
    material: &Material<T>,
    l: &Tensor<T, D>,
    dt: T,
    mut x: Vector<T, D>,
    mut v: Vector<T, D>,
    c: Option<&Tensor<T, D>>,
    u: &mut Unpack<'_, T>,
    out: &mut Packed<T>,
) {
    let mut f = u.tensor::<D>();
    let mut stress = u.matrix3();
    let mut state = u.history();
    particle_end(
        end,
        material,
        l,
        dt,
        &mut x,
        &mut v,
        &mut f,
        &mut stress,
        &mut state,
    );
    out.vector(&x);
    out.vector(&v);
    if let Some(c) = c {
        out.tensor(c);
    }
    out.tensor(&f);
    out.matrix3(&stress);
    out.history(&state);
}

/// USL: one particle's G2P and end of step: the new velocity and affine matrix by the
/// transfer, `x ← x + Δt G.v`, then [`particle_end`] with `L = G.grad_v` (MLS-MPM:
/// `G.affine`). Inputs [`Motion`] then [`End`]; outputs `x, v, C, F, σ, plastic strain,
/// tensor`.
pub(super) fn usl_particle<T: Scalar, const D: usize>(
    transfer: Transfer,
    dt: T,
    end: &EndOfStep<'_, T, D>,
    material: &Material<T>,
    input: &[T],
    out: &mut Packed<T>,
) {
    let mut u = Unpack::new(input);
    let g = gathered::<T, D>(&mut u);
    let (x, v) = (u.vector::<D>(), u.vector::<D>());
    let (v, c) = transfer.particle_velocity(&v, &g);
    let x = x + g.v * dt;
    let l = if transfer.is_mls() {
        g.affine
    } else {
        g.grad_v
    };
    finish(end, material, &l, dt, x, v, Some(&c), &mut u, out);
}

/// MUSL's G2P: `(x + Δt G.v, v', C')` by the transfer. Inputs [`Motion`]; outputs
/// `x, v, C`.
pub(super) fn musl_motion<T: Scalar, const D: usize>(
    transfer: Transfer,
    dt: T,
    input: &[T],
    out: &mut Packed<T>,
) {
    let mut u = Unpack::new(input);
    let g = gathered::<T, D>(&mut u);
    let (x, v) = (u.vector::<D>(), u.vector::<D>());
    let (v, c) = transfer.particle_velocity(&v, &g);
    out.vector(&(x + g.v * dt));
    out.vector(&v);
    out.tensor(&c);
}

/// The offset of the [`End`] block in [`musl_end`]'s inputs: after `L` (D²), `x`, `v` (D each).
pub(super) const fn musl_end_start(d: usize) -> usize {
    d * d + 2 * d
}

/// MUSL's particle end: [`particle_end`] with the velocity gradient `L` of the re-projected
/// grid velocity. Inputs `L` (D²), the moved `x`, `v` (D each), then [`End`]; outputs `x, v,
/// F, σ, plastic strain, tensor` (the affine matrix passes through unchanged).
pub(super) fn musl_end<T: Scalar, const D: usize>(
    dt: T,
    end: &EndOfStep<'_, T, D>,
    material: &Material<T>,
    input: &[T],
    out: &mut Packed<T>,
) {
    let mut u = Unpack::new(input);
    let l = u.tensor::<D>();
    let (x, v) = (u.vector::<D>(), u.vector::<D>());
    finish(end, material, &l, dt, x, v, None, &mut u, out);
}

/// One node's update: `(vⁿ_i, v̂_i)` from `(m_i, P_i, f_i)` by [`momentum_update`] and the
/// contact and wall law; inputs `[m, P, f]`, outputs `[vⁿ, v̂]`.
pub(super) fn node_update<T: Scalar, const D: usize>(
    law: &NodeLaw<'_, T, D>,
    gravity: &Vector<T, D>,
    dt: T,
    node: [usize; D],
    input: &[T],
    out: &mut Packed<T>,
) {
    let mut u = Unpack::new(input);
    let m = u.scalar();
    let p = u.vector::<D>();
    let f = u.vector::<D>();
    let (v_old, mut v) = momentum_update(m, &p, &f, gravity, dt);
    law.apply(node, &mut v);
    out.vector(&v_old);
    out.vector(&v);
}

/// MUSL's second projection at one node: `v = P₂/m` with the first projection's active set
/// enforced ([`NodeLaw::enforce`]); inputs `[m, P₂]`, outputs `[v]`.
pub(super) fn node_enforce<T: Scalar, const D: usize>(
    law: &NodeLaw<'_, T, D>,
    node: [usize; D],
    state: NodeState,
    input: &[T],
    out: &mut Packed<T>,
) {
    let mut u = Unpack::new(input);
    let m = u.scalar();
    let mut v = u.vector::<D>() / m;
    law.enforce(node, &mut v, state);
    out.vector(&v);
}
