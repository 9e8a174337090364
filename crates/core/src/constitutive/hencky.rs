//! Hencky (logarithmic-strain) hyperelasticity.

use super::{Hyperelastic, Lame};
use crate::scalar::Scalar;
use crate::spectral::{Log, symmetric_fn};
use nalgebra::Matrix3;

/// `ψ = μ ε:ε + ½λ (tr ε)²` on the Hencky strain `ε = ½ ln(F Fᵀ)`, giving the Kirchhoff stress
/// `τ = 2μ ε + λ tr(ε) I` (isotropy makes `τ` coaxial with `ε`).
///
/// The logarithm goes through [`symmetric_fn`], so tangents and parameter derivatives are
/// finite and exact at `F = I` and at repeated principal stretches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hencky<T> {
    /// Lamé parameters.
    pub lame: Lame<T>,
}

impl<T: Scalar> Hencky<T> {
    /// Hencky strain `ε = ½ ln(F Fᵀ)`.
    pub fn strain(f: &Matrix3<T>) -> Matrix3<T> {
        symmetric_fn(&(f * f.transpose()), &Log) * T::cst(0.5)
    }
}

impl<T: Scalar> Hyperelastic<T> for Hencky<T> {
    fn energy_density(&self, f: &Matrix3<T>) -> T {
        self.lame.energy(&Self::strain(f))
    }

    fn kirchhoff_stress(&self, f: &Matrix3<T>) -> Matrix3<T> {
        self.lame.stress(&Self::strain(f))
    }

    fn lame(&self) -> Lame<T> {
        self.lame
    }
}
