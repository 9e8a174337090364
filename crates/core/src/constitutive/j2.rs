//! J2 (von Mises) plasticity in Hencky strain space: Simo's multiplicative finite-strain
//! model with the logarithmic elastic strain and a closed-form radial return.
//!
//! With `F = Fₑ Fₚ`, the elastic left Cauchy–Green tensor `bₑ = Fₑ Fₑᵀ` and the elastic
//! Hencky strain `ε = ½ ln bₑ`, the stored energy is that of [`super::Hencky`],
//! `ψ = μ ε:ε + ½λ (tr ε)²`, so the Kirchhoff stress is `τ = 2μ ε + λ tr(ε) I`. One step with
//! the relative deformation gradient `ΔF`:
//!
//! 1. trial state (plastic flow frozen): `bₑᵗʳ = ΔF bₑⁿ ΔFᵀ`, `εᵗʳ = ½ ln bₑᵗʳ`,
//!    `τᵗʳ = 2μ εᵗʳ + λ tr(εᵗʳ) I`, `s = dev τᵗʳ`;
//! 2. yield function `f = ‖s‖ − √(2/3) (σ_y + H ε̄ᵖⁿ)`; if `f ≤ 0` the step is elastic:
//!    `τ = τᵗʳ`, `bₑ = bₑᵗʳ`;
//! 3. otherwise radial return along `n = s/‖s‖` (the exponential map of the associative flow
//!    rule, exact in log-strain space because `τ` and `ε` are coaxial):
//!    `Δγ = f / (2μ + ⅔H)`, `τ = τᵗʳ − 2μ Δγ n`, `ε = εᵗʳ − Δγ n`, `bₑ = exp(2ε)`,
//!    `ε̄ᵖ = ε̄ᵖⁿ + √(2/3) Δγ`.
//!
//! Linear hardening makes the return a closed form, so there is no local iteration. The
//! branch is taken on the real part of `f`; everything else is `T` arithmetic, and the
//! logarithm / exponential go through [`symmetric_fn`], so a dual-number evaluation gives the
//! exact consistent (algorithmic) tangent, also at repeated principal stretches.

use super::{Constitutive, Kinematics, Lame, MaterialState, Region, hencky_trial};
use crate::scalar::Scalar;
use crate::spectral::{Exp, Log, symmetric_fn};
use crate::tensor::det;
use nalgebra::Matrix3;

/// J2 (von Mises) elastoplasticity with linear isotropic hardening, in Hencky strain space.
///
/// The yield surface is `‖dev τ‖ = √(2/3) (σ_y + H ε̄ᵖ)`, i.e. von Mises stress
/// `√(3/2) ‖dev τ‖ = σ_y + H ε̄ᵖ`. State ([`MaterialState`]): `tensor` is the elastic left
/// Cauchy–Green tensor `bₑ` (identity in the stress-free reference state), `plastic_strain` the
/// equivalent plastic strain `ε̄ᵖ = ∫ √(2/3) ‖dₚ‖ dt`. See the module docs for the algorithm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct J2<T> {
    /// Lamé parameters of the Hencky elastic law.
    pub lame: Lame<T>,
    /// Initial uniaxial yield stress `σ_y` (Pa), `≥ 0`.
    pub yield_stress: T,
    /// Linear isotropic hardening modulus `H ≥ 0` (Pa): the yield stress grows to
    /// `σ_y + H ε̄ᵖ`; `H = 0` is perfect plasticity.
    pub hardening: T,
}

impl<T: Scalar> J2<T> {
    /// From the shear strength `κ` (the yield stress in pure shear): `σ_y = √3 κ`.
    ///
    /// In pure shear `τ₁₂ = κ`, `‖dev τ‖ = √2 κ = √(2/3) σ_y`, so the von Mises surface
    /// `‖dev τ‖ = √(2/3)(σ_y + H ε̄ᵖ)` is reached at `κ = σ_y/√3`. In plane strain, once the
    /// flow is fully plastic there is no out-of-plane plastic strain rate, so
    /// `s_zz = 0` (`τ_zz` is the mean of the in-plane normal stresses) and
    /// `‖dev τ‖ = √2 R` with `R` the radius of the in-plane Mohr circle: yield is `R = κ`, a
    /// Tresca material of undrained shear strength `c_u = κ = σ_y/√3` — the value to compare
    /// with Prandtl's bearing capacity `(2 + π) c_u`.
    pub fn from_shear_strength(lame: Lame<T>, kappa: T, hardening: T) -> Self {
        Self {
            lame,
            yield_stress: kappa * T::cst(3.0).sqrt(),
            hardening,
        }
    }

    /// The radius `√(2/3) (σ_y + H ε̄ᵖ)` of the yield surface in deviatoric Kirchhoff stress.
    fn yield_radius(&self, plastic_strain: T) -> T {
        (self.yield_stress + self.hardening * plastic_strain) * T::cst(2.0 / 3.0).sqrt()
    }

    /// One step of the return mapping, without side effects: the Kirchhoff stress `τ` at the
    /// end of the step and the new state (`bₑ`, `ε̄ᵖ`), from the relative deformation gradient
    /// `ΔF` and the state at the start of the step (see the module docs for the equations).
    ///
    /// Pure, so a Newton solver can call it at every iterate from the last converged state;
    /// with dual `ΔF` its derivative is the consistent tangent `∂τ/∂ΔF`.
    pub fn kirchhoff_update(
        &self,
        delta_f: &Matrix3<T>,
        state: &MaterialState<T>,
    ) -> (Matrix3<T>, MaterialState<T>) {
        let (tau, state, _) = self.return_map(delta_f, state);
        (tau, state)
    }

    /// [`J2::kirchhoff_update`] with the branch it took: [`Region::Elastic`] or
    /// [`Region::Shear`] (the radial return).
    pub fn return_map(
        &self,
        delta_f: &Matrix3<T>,
        state: &MaterialState<T>,
    ) -> (Matrix3<T>, MaterialState<T>, Region) {
        let (b_trial, eps_trial) = hencky_trial(delta_f, &state.tensor);
        let tau_trial = self.lame.stress(&eps_trial);
        let s = tau_trial - Matrix3::identity() * (tau_trial.trace() / T::cst(3.0));
        let s_norm = s.norm();
        let f = s_norm - self.yield_radius(state.plastic_strain);
        // With ‖s‖ = 0 the trial state is on the hydrostatic axis, inside the surface.
        if f.re() <= 0.0 || s_norm.re() == 0.0 {
            let elastic = MaterialState {
                plastic_strain: state.plastic_strain,
                tensor: b_trial,
                hardening: state.hardening,
            };
            return (tau_trial, elastic, Region::Elastic);
        }
        let two_mu = self.lame.mu * T::cst(2.0);
        let dgamma = f / (two_mu + self.hardening * T::cst(2.0 / 3.0));
        let n = s / s_norm;
        let tau = tau_trial - n * (two_mu * dgamma);
        let eps = eps_trial - n * dgamma;
        let plastic = MaterialState {
            plastic_strain: state.plastic_strain + dgamma * T::cst(2.0 / 3.0).sqrt(),
            tensor: symmetric_fn(&(eps * T::cst(2.0)), &Exp),
            hardening: state.hardening,
        };
        (tau, plastic, Region::Shear)
    }

    /// The explicit stress update: `σ = τ / det F` with `τ` from [`J2::return_map`] on
    /// `kin.delta_f`; commits the new state and returns the branch taken.
    pub fn update_region(
        &self,
        kin: &Kinematics<'_, T>,
        state: &mut MaterialState<T>,
    ) -> (Matrix3<T>, Region) {
        let (tau, new_state, region) = self.return_map(kin.delta_f, state);
        *state = new_state;
        (tau / det::<T, 3>(kin.f), region)
    }

    /// The elastic left Cauchy–Green tensor that a Kirchhoff stress stands for,
    /// `bₑ = exp(2 ε)` with `ε = C⁻¹:τ` the Hencky strain of [`Lame::strain`]: the state
    /// that [`J2::return_map`] leaves with the stress `τ`, rebuilt from it (the GPU path keeps
    /// the stress only).
    pub fn elastic_left_cauchy_green(&self, tau: &Matrix3<T>) -> Matrix3<T> {
        symmetric_fn(&(self.lame.strain(tau) * T::cst(2.0)), &Exp)
    }

    /// Elastic stored energy per unit reference volume of a state,
    /// `ψ = μ ε:ε + ½λ (tr ε)²` with `ε = ½ ln bₑ`.
    pub fn stored_energy(&self, state: &MaterialState<T>) -> T {
        self.lame
            .energy(&(symmetric_fn(&state.tensor, &Log) * T::cst(0.5)))
    }
}

impl<T: Scalar> Constitutive<T> for J2<T> {
    /// `σ = τ / det F` with `τ` from [`J2::kirchhoff_update`] on `kin.delta_f`; commits the new
    /// state.
    fn update(&self, kin: &Kinematics<'_, T>, state: &mut MaterialState<T>) -> Matrix3<T> {
        self.update_region(kin, state).0
    }

    /// `λ + 2μ`: the elastic constrained modulus bounds the wave speed.
    fn p_wave_modulus(&self) -> f64 {
        self.lame.p_wave_modulus().re()
    }
}
