//! Stage 4: the particle end of the step.
//!
//! Per particle, after G2P: the projection of a shallow crossing of a unilateral wall
//! ([`EndOfStep::project`]), `F ← (I + Δt L) F` and the constitutive update
//! ([`update_stress`]), and the flag for the end-of-step checks ([`EndOfStep::flag`]).

use super::record::ParticleBranch;
use crate::boundary::{Boundary, WallKind};
use crate::constitutive::{Kinematics, Material, MaterialState, Region};
use crate::contact::Contact;
use crate::grid::Grid;
use crate::scalar::Scalar;
use crate::tensor::{Tensor, Vector, det, to3};
use nalgebra::Matrix3;

/// How far beyond a unilateral (separable) wall, in cells, a particle centre is still put
/// back onto the face by [`EndOfStep::project`]; a centre deeper than that has escaped.
///
/// A unilateral condition is nodal: it stops the face nodes from moving into the wall, but a
/// particle also interpolates interior nodes, so where a flowing layer thins below about half
/// a particle spacing (the front of a granular or fluid surge) a centre can drift a fraction
/// of a spacing past the face (measured: up to 0.16 spacings in the granular collapses of
/// `docs/verification.md`). Half a cell is a whole particle spacing at 2 particles per cell.
pub const PROJECTION_DEPTH: f64 = 0.5;

/// `F ← (I + Δt L) F`, then the constitutive update on the 3×3 embedding (`F_zz = 1` and a
/// zero out-of-plane velocity gradient in 2D); returns the branch the update took.
#[inline(always)]
pub fn update_stress<T: Scalar, const D: usize>(
    material: &Material<T>,
    l: &Tensor<T, D>,
    dt: T,
    f: &mut Tensor<T, D>,
    stress: &mut Matrix3<T>,
    state: &mut MaterialState<T>,
) -> Region {
    let delta_f = Tensor::<T, D>::identity() + l * dt;
    *f = delta_f * *f;
    let f3 = to3(f, T::one());
    let df3 = to3(&delta_f, T::one());
    let l3 = to3(l, T::zero());
    let kin = Kinematics {
        f: &f3,
        delta_f: &df3,
        velocity_gradient: &l3,
        dt,
        stress,
    };
    let (sigma, region) = material.update_region(&kin, state);
    *stress = sigma;
    region
}

/// Stage 4 for one particle whose G2P gave the velocity gradient `l`: the wall projection of
/// `x`, `v`, then [`update_stress`]. Returns whether the particle needs a closer look by the
/// checks ([`EndOfStep::flag`]) and the branches it took.
#[inline(always)]
pub fn particle_end<T: Scalar, const D: usize>(
    end: &EndOfStep<'_, T, D>,
    material: &Material<T>,
    l: &Tensor<T, D>,
    dt: T,
    x: &mut Vector<T, D>,
    v: &mut Vector<T, D>,
    f: &mut Tensor<T, D>,
    stress: &mut Matrix3<T>,
    state: &mut MaterialState<T>,
) -> (bool, ParticleBranch) {
    let projected = end.project(x, v);
    let region = update_stress(material, l, dt, f, stress, state);
    (
        end.flag(x, v, f, stress),
        ParticleBranch { projected, region },
    )
}

/// The walls and obstacles as the end of a step sees them: the projection of shallow wall
/// crossings and the per-particle part of the end-of-step checks. A solver flags a particle
/// with [`EndOfStep::flag`] inside its last particle pass and runs its full checks (which
/// build the error with every offending id) only when one is flagged.
#[derive(Clone, Copy, Debug)]
pub struct EndOfStep<'a, T: Scalar, const D: usize> {
    /// Per axis, the positions below / above which a particle has crossed a wall
    /// (±∞ for free faces).
    bounds: [(f64, f64); D],
    /// Per axis and side, whether the wall is unilateral (`separable`, and not free), so that
    /// [`EndOfStep::project`] puts shallow crossings back onto the face.
    unilateral: [[bool; 2]; D],
    /// [`PROJECTION_DEPTH`] in metres.
    depth: f64,
    contact: &'a Contact<T, D>,
    time: f64,
}

impl<'a, T: Scalar, const D: usize> EndOfStep<'a, T, D> {
    /// The end of a step that reaches simulated time `time`.
    pub fn new(
        grid: &Grid<D>,
        boundary: &Boundary<D>,
        contact: &'a Contact<T, D>,
        time: f64,
    ) -> Self {
        let (lo, hi) = (grid.lo, grid.hi());
        let walled = |a: usize, side: usize| boundary.walls[a][side].kind != WallKind::Free;
        Self {
            bounds: std::array::from_fn(|a| {
                (
                    if walled(a, 0) {
                        lo[a]
                    } else {
                        f64::NEG_INFINITY
                    },
                    if walled(a, 1) { hi[a] } else { f64::INFINITY },
                )
            }),
            unilateral: std::array::from_fn(|a| {
                std::array::from_fn(|side| walled(a, side) && boundary.walls[a][side].separable)
            }),
            depth: PROJECTION_DEPTH * grid.h,
            contact,
            time,
        }
    }

    /// Puts a particle centre that ended the step less than [`PROJECTION_DEPTH`] cells beyond
    /// a unilateral wall back onto the face, `x_a ← lo_a` (or `hi_a`), and removes its
    /// velocity component into the wall, `v_a ← max(v_a, 0)` (or `min`): the position
    /// counterpart of the nodal condition. A deeper centre is left where it is, for the
    /// containment check to report. Comparisons on real parts; a projected coordinate is a
    /// constant (its sensitivity is zero). Returns the faces projected onto, bit
    /// `2·axis + side`.
    #[inline(always)]
    pub fn project(&self, x: &mut Vector<T, D>, v: &mut Vector<T, D>) -> u8 {
        let mut projected = 0;
        for a in 0..D {
            let (lo, hi) = self.bounds[a];
            let xa = x[a].re();
            if self.unilateral[a][0] && xa < lo && xa >= lo - self.depth {
                x[a] = T::cst(lo);
                if v[a].re() < 0.0 {
                    v[a] = T::zero();
                }
                projected |= 1 << (2 * a);
            } else if self.unilateral[a][1] && xa > hi && xa <= hi + self.depth {
                x[a] = T::cst(hi);
                if v[a].re() > 0.0 {
                    v[a] = T::zero();
                }
                projected |= 1 << (2 * a + 1);
            }
        }
        projected
    }

    /// Whether the particle has a non-finite field, is inverted, has crossed a wall or lies
    /// in an obstacle.
    #[inline(always)]
    pub fn flag(
        &self,
        x: &Vector<T, D>,
        v: &Vector<T, D>,
        f: &Tensor<T, D>,
        stress: &Matrix3<T>,
    ) -> bool {
        // One finiteness test of a sum instead of one per entry: a NaN or an infinity in any
        // entry makes the sum non-finite; a finite sum that overflows only flags the particle
        // for the exact checks. Two partial sums and plain indexed loops keep it short.
        let (mut s0, mut s1) = (T::zero(), T::zero());
        for a in 0..D {
            s0 += x[a];
            s1 += v[a];
            for b in 0..D {
                s0 += f[(a, b)];
            }
        }
        for a in 0..3 {
            for b in 0..3 {
                s1 += stress[(a, b)];
            }
        }
        if !(s0 + s1).is_finite_all() || det(f).re() <= 0.0 {
            return true;
        }
        let mut xr = [0.0; D];
        let mut out = false;
        for a in 0..D {
            xr[a] = x[a].re();
            out |= xr[a] < self.bounds[a].0 || xr[a] > self.bounds[a].1;
        }
        out || (!self.contact.is_empty() && self.contact.penetrated(&xr, self.time).is_some())
    }
}
