//! Small-strain linear elasticity.

use super::{Hyperelastic, Lame};
use crate::scalar::Scalar;
use crate::tensor::product;
use nalgebra::Matrix3;

/// Linear elasticity on the small-strain tensor `ε = ½(F + Fᵀ) − I`:
/// `ψ = μ ε:ε + ½λ (tr ε)²`, `σ = λ tr(ε) I + 2μ ε`.
///
/// It is exact only for infinitesimal rotations (not objective); use [`super::Hencky`] or
/// [`super::NeoHookean`] for large deformation. Its `P = ∂ψ/∂F` equals the returned stress
/// (the small-strain theory does not distinguish stress measures), so the Kirchhoff stress
/// returned is `σ Fᵀ` to keep `P = τ F⁻ᵀ = σ` consistent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearElastic<T> {
    /// Lamé parameters.
    pub lame: Lame<T>,
}

impl<T: Scalar> LinearElastic<T> {
    /// The small-strain stress `σ = λ tr(ε) I + 2μ ε`.
    pub fn small_strain_stress(&self, f: &Matrix3<T>) -> Matrix3<T> {
        let eps = (f + f.transpose()) * T::cst(0.5) - Matrix3::identity();
        Matrix3::identity() * (self.lame.lambda * eps.trace()) + eps * (self.lame.mu * T::cst(2.0))
    }
}

impl<T: Scalar> Hyperelastic<T> for LinearElastic<T> {
    fn energy_density(&self, f: &Matrix3<T>) -> T {
        let eps = (f + f.transpose()) * T::cst(0.5) - Matrix3::identity();
        let tr = eps.trace();
        self.lame.mu * eps.component_mul(&eps).sum() + self.lame.lambda * tr * tr * T::cst(0.5)
    }

    fn kirchhoff_stress(&self, f: &Matrix3<T>) -> Matrix3<T> {
        product(&self.small_strain_stress(f), &f.transpose())
    }

    fn cauchy_stress(&self, f: &Matrix3<T>) -> Matrix3<T> {
        self.small_strain_stress(f)
    }

    fn first_piola(&self, f: &Matrix3<T>) -> Matrix3<T> {
        self.small_strain_stress(f)
    }

    fn lame(&self) -> Lame<T> {
        self.lame
    }
}
