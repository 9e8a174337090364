//! Compressible Neo-Hookean hyperelasticity.

use super::{Hyperelastic, Lame};
use crate::scalar::Scalar;
use crate::tensor::det;
use nalgebra::Matrix3;

/// `ψ = ½μ (tr(FᵀF) − 3) − μ ln J + ½λ (ln J)²`, giving the Kirchhoff stress
/// `τ = μ (F Fᵀ − I) + λ ln J · I`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeoHookean<T> {
    /// Lamé parameters (the small-strain limit).
    pub lame: Lame<T>,
}

impl<T: Scalar> Hyperelastic<T> for NeoHookean<T> {
    fn energy_density(&self, f: &Matrix3<T>) -> T {
        let ln_j = det::<T, 3>(f).ln();
        let half = T::cst(0.5);
        half * self.lame.mu * (f.component_mul(f).sum() - T::cst(3.0)) - self.lame.mu * ln_j
            + half * self.lame.lambda * ln_j * ln_j
    }

    fn kirchhoff_stress(&self, f: &Matrix3<T>) -> Matrix3<T> {
        let ln_j = det::<T, 3>(f).ln();
        (f * f.transpose() - Matrix3::identity()) * self.lame.mu
            + Matrix3::identity() * (self.lame.lambda * ln_j)
    }

    fn lame(&self) -> Lame<T> {
        self.lame
    }
}
