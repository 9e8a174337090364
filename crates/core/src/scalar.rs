//! The scalar contract: one trait that every differentiable kernel is generic over.
//!
//! Kernels are written once as `fn k<T: Scalar, const D: usize>(..)` and run with `f32`/`f64`
//! for simulation and with first-order forward-mode dual numbers (num-dual's [`Dual64`],
//! [`DualSVec64`]) for tangents and sensitivities. Branches on state are taken on the real part
//! ([`Scalar::re`]); the derivative part follows the branch taken.

use nalgebra::RealField;
use num_dual::{Dual64, DualSVec64};
use std::fmt::Debug;

/// What a loam kernel needs of its number type.
///
/// Implemented for `f32`, `f64`, [`Dual64`] and [`DualSVec64<N>`]. The dual implementations are
/// *first-order*: [`Scalar::re`] drops the derivative part, and code that splits a value into
/// `re` and `self - re` (see [`crate::spectral`]) relies on products of two pure perturbations
/// vanishing, which holds exactly for first-order duals.
pub trait Scalar: RealField + Copy + Send + Sync + Debug + 'static {
    /// Converts an `f64` constant (the derivative part is zero).
    fn cst(x: f64) -> Self;
    /// The real (primal) part as `f64`; used for branching, indexing and reporting.
    fn re(&self) -> f64;
    /// `true` when the real part and every derivative lane are finite.
    fn is_finite_all(&self) -> bool;
    /// `true` when every derivative lane is zero (always for `f32` and `f64`): the value is the
    /// plain number [`Scalar::re`], so a kernel may take a shortcut that is exact for that
    /// number only (an integer power, a skipped zero term) without losing a derivative.
    fn is_constant(&self) -> bool;
}

impl Scalar for f64 {
    #[inline(always)]
    fn cst(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn re(&self) -> f64 {
        *self
    }
    #[inline(always)]
    fn is_finite_all(&self) -> bool {
        self.is_finite()
    }
    #[inline(always)]
    fn is_constant(&self) -> bool {
        true
    }
}

impl Scalar for f32 {
    #[inline(always)]
    fn cst(x: f64) -> Self {
        x as f32
    }
    #[inline(always)]
    fn re(&self) -> f64 {
        *self as f64
    }
    #[inline(always)]
    fn is_finite_all(&self) -> bool {
        self.is_finite()
    }
    #[inline(always)]
    fn is_constant(&self) -> bool {
        true
    }
}

impl Scalar for Dual64 {
    #[inline(always)]
    fn cst(x: f64) -> Self {
        Dual64::from_re(x)
    }
    #[inline(always)]
    fn re(&self) -> f64 {
        self.re
    }
    #[inline(always)]
    fn is_finite_all(&self) -> bool {
        self.re.is_finite() && self.eps.is_finite()
    }
    #[inline(always)]
    fn is_constant(&self) -> bool {
        self.eps == 0.0
    }
}

impl<const N: usize> Scalar for DualSVec64<N> {
    #[inline(always)]
    fn cst(x: f64) -> Self {
        DualSVec64::from_re(x)
    }
    #[inline(always)]
    fn re(&self) -> f64 {
        self.re
    }
    #[inline(always)]
    fn is_finite_all(&self) -> bool {
        self.re.is_finite()
            && self
                .eps
                .0
                .as_ref()
                .is_none_or(|e| e.iter().all(|x| x.is_finite()))
    }
    #[inline(always)]
    fn is_constant(&self) -> bool {
        self.eps
            .0
            .as_ref()
            .is_none_or(|e| e.iter().all(|&x| x == 0.0))
    }
}

/// Shorthand for [`Scalar::cst`], for readable constants inside generic kernels.
#[inline(always)]
pub fn c<T: Scalar>(x: f64) -> T {
    T::cst(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square_plus_sin<T: Scalar>(x: T) -> T {
        x * x + x.sin()
    }

    #[test]
    fn dual_gives_the_derivative_through_a_generic_kernel() {
        // d/dx (x² + sin x) = 2x + cos x, exact to rounding for a first-order dual.
        let x = Dual64::from_re(0.7).derivative();
        let y = square_plus_sin(x);
        assert!((y.re - (0.49 + 0.7f64.sin())).abs() < 1e-15);
        assert!((y.eps - (1.4 + 0.7f64.cos())).abs() < 1e-15);
        let xv: DualSVec64<2> = DualSVec64::from_re(0.7).derivative(1);
        let yv = square_plus_sin(xv);
        let e = yv.eps.0.unwrap();
        assert_eq!(e[0], 0.0);
        assert!((e[1] - (1.4 + 0.7f64.cos())).abs() < 1e-15);
    }

    #[test]
    fn finiteness_checks_every_lane() {
        assert!(!Dual64::new(1.0, f64::NAN).is_finite_all());
        assert!(Dual64::new(1.0, 2.0).is_finite_all());
        assert!(!f32::INFINITY.is_finite_all());
    }

    #[test]
    fn constants_have_no_derivative_lane() {
        assert!(7.0f64.is_constant() && 7.0f32.is_constant());
        assert!(Dual64::cst(7.0).is_constant());
        assert!(!Dual64::new(7.0, 1.0).is_constant());
        assert!(!Dual64::new(0.0, 1.0).is_constant());
        assert!(DualSVec64::<3>::cst(7.0).is_constant());
        assert!(!DualSVec64::<3>::from_re(7.0).derivative(2).is_constant());
    }
}
