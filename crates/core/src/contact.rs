//! Frictional walls and rigid obstacles acting on nodal velocities (explicit path).
//!
//! [`Contact`] is applied to every node's updated velocity before the plain wall conditions of
//! [`crate::Boundary`]; it is empty (a no-op) unless a scene declares friction segments or
//! obstacles.

use crate::grid::Grid;
use crate::scalar::Scalar;
use crate::tensor::Vector;
use std::marker::PhantomData;

/// Coulomb friction segments on grid walls and rigid obstacles.
#[derive(Clone, Debug)]
pub struct Contact<T: Scalar, const D: usize> {
    _scalar: PhantomData<T>,
}

impl<T: Scalar, const D: usize> Default for Contact<T, D> {
    fn default() -> Self {
        Self {
            _scalar: PhantomData,
        }
    }
}

impl<T: Scalar, const D: usize> Contact<T, D> {
    /// Whether there is nothing to apply.
    pub fn is_empty(&self) -> bool {
        true
    }

    /// Applies contact to the velocity `v` of `node` at simulated time `time`. With
    /// `friction = false` only non-penetration is enforced (MUSL's second projection).
    #[inline]
    pub fn apply(
        &self,
        _grid: &Grid<D>,
        _node: [usize; D],
        _time: f64,
        _v: &mut Vector<T, D>,
        _friction: bool,
    ) {
    }

    /// The obstacle a particle at `x` (real parts) lies inside at `time`, if any.
    pub fn penetrated(&self, _x: &[f64; D], _time: f64) -> Option<usize> {
        None
    }
}
