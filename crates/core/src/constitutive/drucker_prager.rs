//! Non-associated Drucker–Prager plasticity with a tension cutoff, hypoelastic with the
//! Jaumann stress rate (the explicit path's model for sand and other frictional soils).
//!
//! **Sign convention.** `σ` is the Cauchy stress, tension positive (compression negative), as
//! everywhere in loam. `I₁ = tr σ`, `p = I₁/3` the mean stress (positive in tension),
//! `s = σ − p I` the deviator, `J₂ = ½ s:s`, so `√J₂ = ‖s‖/√2`.
//!
//! **Elasticity (hypoelastic, Jaumann rate).** With `L` the velocity gradient of the step,
//! `D = sym L`, `W = skew L` and `C` the isotropic elasticity tensor (`C:ε = λ tr(ε) I + 2μ ε`),
//! the objective rate `σ̇ − Wσ + σW = C:D` is integrated over a step by rotating the stress at
//! the start of the step and adding the elastic increment (Hughes & Winget 1980, "Finite
//! rotation effects in numerical integration of rate constitutive equations arising in
//! large-deformation analysis", IJNME 15, 1862–1867):
//!
//! ```text
//! σᵗʳ = Q σₙ Qᵀ + Δt C:D,      Q = (I − ½ΔtW)⁻¹ (I + ½ΔtW),
//! ```
//!
//! `Q σₙ Qᵀ = σₙ + Δt (W σₙ − σₙ W) + O(Δt²)`, so this is the forward-Euler trial
//! `σₙ + Δt (W σₙ − σₙ W) + Δt C:D` up to second-order terms, but `Q` (the Cayley transform of
//! the skew `½ΔtW`) is exactly orthogonal, so a pure spin leaves the invariants of `σ` unchanged
//! to round-off however many steps are taken; the plain forward-Euler rotation would change
//! them by `O(Δt²|W|²)` per step. *Choice:* `σₙ` is rotated, and the increment `Δt C:D`, computed
//! from `D` of the current configuration, is added unrotated. Rotating the whole trial,
//! `Q (σₙ + Δt C:D) Qᵀ`, is the other common variant; both are incrementally objective and
//! differ by `O(Δt² |W| |D|)`. The return mapping acts on the rotated trial, after the rotation,
//! so yield is checked in the end-of-step orientation. In plane strain (`D = 2`) `L` has a zero
//! out-of-plane row and column, so `Q_zz = 1` and `σ_zz` evolves through `λ tr(D)` only.
//!
//! **Yield surface and plastic potential.**
//!
//! ```text
//! f(σ) = √J₂ + α I₁ − k,            α   = tan φ / √(9 + 12 tan²φ),  k = 3c / √(9 + 12 tan²φ),
//! g(σ) = √J₂ + α_ψ I₁,              α_ψ = tan ψ / √(9 + 12 tan²ψ),
//! ```
//!
//! with the friction angle `φ`, the dilation angle `0 ≤ ψ ≤ φ` (`ψ = φ` associated, `ψ = 0`
//! isochoric flow) and the cohesion `c ≥ 0`. These `α`, `k` are the *plane-strain match* of
//! the Mohr–Coulomb criterion of the same `(c, φ)`: under plane strain and associated flow the
//! collapse loads of the two models agree (de Souza Neto, Perić & Owen, *Computational Methods
//! for Plasticity*, Wiley 2008, §6.4.2; in their notation `η = 3α`, `ξ c = k`). The other
//! usual fits of the same `f`, not used here:
//!
//! ```text
//! outer cone (touches MC at the compression meridian):  α = 2 sin φ / (√3 (3 − sin φ)),  k = 6c cos φ / (√3 (3 − sin φ))
//! inner cone (touches MC at the extension meridian):    α = 2 sin φ / (√3 (3 + sin φ)),  k = 6c cos φ / (√3 (3 + sin φ))
//! ```
//!
//! The plane-strain match, `α = sin φ / √(3 (3 + sin²φ))`, `k = √3 c cos φ / √(3 + sin²φ)`
//! written with `sin φ`, lies inside both: it is the cone inscribed in the Mohr–Coulomb
//! pyramid, tangent to its faces (in the deviatoric plane its radius is the smallest MC
//! radius over the Lode angle; checked in the tests), so it never overestimates the MC
//! strength. The cone's apex is at `I₁ = k/α`, i.e. the mean stress
//! `p_apex = k/(3α) = c cot φ`.
//!
//! **Tension cutoff.** `p ≤ σ_t`, a plane normal to the hydrostatic axis. The default `σ_t` is
//! the apex, `σ_t = c cot φ` (which is `0` when `c = 0`): the cutoff then adds nothing to the
//! cone, whose apex already bounds the mean stress. A given `σ_t` above the apex is replaced by
//! the apex (it could never be reached); one below it cuts the cone. The cutoff flow is
//! associated, `Δεₚ ∝ ∂(p − σ_t)/∂σ = I/3` (purely volumetric).
//!
//! **Return mapping** (closed form; perfect plasticity, so no local iteration). The trial state
//! is split into its mean stress `pᵗʳ` and deviatoric radius `qᵗʳ = √J₂ᵗʳ`. A plastic
//! correction `Δσ = −C:Δεₚ` moves the state in the `(p, q)` plane along
//!
//! ```text
//! shear   (Δεₚ = Δγ ∂g/∂σ = Δγ (n/√2 + α_ψ I), n = s/‖s‖):  (Δp, Δq) = −Δγ (3K α_ψ, μ),
//! tension (Δεₚ = Δλ I/3):                                   (Δp, Δq) = −Δλ (K, 0),
//! ```
//!
//! with `K = λ + ⅔μ` the bulk modulus, leaving the deviatoric direction `n` unchanged. The
//! cone and the cutoff meet at the corner `C = (σ_t, q_c)`, `q_c = k − 3α σ_t ≥ 0` (`q_c = 0`
//! when the cutoff is at the apex). Outside the elastic domain `{f ≤ 0, p ≤ σ_t}` the
//! `(p, q ≥ 0)` half-plane splits into three regions, each the set of trial states that one
//! return reaches (Koiter's rule for the corner; own derivation, written for this code):
//!
//! 1. **shear**: `Δγ = f(σᵗʳ) / (μ + 9Kαα_ψ)` (from `f(σ) = fᵗʳ − Δγ (μ + 9Kαα_ψ) = 0`),
//!    valid when the returned point is on the cone at or above the corner,
//!    `q = qᵗʳ − μΔγ ≥ q_c` (which also gives `q ≥ 0` and `p ≤ σ_t`);
//! 2. **tension**: `pᵗʳ > σ_t` and `qᵗʳ ≤ q_c`: `p = σ_t`, `s = sᵗʳ`;
//! 3. **corner** (the apex when `q_c = 0`): the rest, i.e. trial states
//!    `C + a (3Kα_ψ, μ) + b (K, 0)` with `a, b ≥ 0`: `p = σ_t`, `s = sᵗʳ q_c / qᵗʳ`.
//!
//! The three cones of directions at `C` (spanned by the cone's edge and the shear direction, by
//! the two return directions, and by the cutoff's edge and the tension direction) tile the
//! outside of the elastic domain without overlap, so the split is exhaustive and the
//! result is continuous across region boundaries. Every return ends with `f ≤ 0` and
//! `p ≤ σ_t` (equality on the active surfaces up to round-off).
//!
//! **Plastic strain.** In every case the plastic strain increment is the part of `Δt D` that
//! did not go into the elastic stress, `Δεₚ = C⁻¹:(σᵗʳ − σ)`, and the equivalent plastic
//! strain accumulates `ε̄ᵖ ← ε̄ᵖ + √(2/3) ‖Δεₚ‖` (Frobenius norm; for isochoric shear flow
//! this is the usual `√(2/3) ‖Δeₚ‖`, and dilatant or cutoff flow counts its volumetric part
//! too). It is stored in [`MaterialState::plastic_strain`].
//!
//! **State and energy.** The stress itself is carried by the solver (`Kinematics::stress`);
//! [`MaterialState::tensor`] holds `I + 2εₑ` with `εₑ = C⁻¹:σ` the elastic strain of the
//! current stress (the small-strain counterpart of the elastic left Cauchy–Green tensor
//! `bₑ = exp(2εₑ)` that [`super::J2`] stores, so the default state, the identity, is stress
//! free). It gives the stored elastic energy per unit reference volume,
//! `ψ = J ½ σ:C⁻¹:σ = J (μ εₑ:εₑ + ½λ (tr εₑ)²)` (`J = det F`; the energy density is per
//! current volume), and lets [`DruckerPrager::kirchhoff_update`] rebuild `σₙ = C:εₑ` without
//! the stress array. (Stored next to the identity, `εₑ` keeps an absolute round-off of about
//! the machine epsilon: 1e-13 relative at the elastic strains of soils in `f64`, but only
//! ~1e-4 in `f32`. The explicit stress update does not use it.)
//!
//! **Derivatives.** Every branch is taken on real parts; the parameters (`E`, `ν`, `φ`, `ψ`,
//! `c`, `σ_t`) are `T`, so running with a dual `φ` gives `∂σ/∂φ` of the branch taken (exact:
//! the return is closed form).

use super::{Constitutive, Kinematics, Lame, MaterialState, Region, hencky_trial};
use crate::scalar::Scalar;
use crate::spectral::{Exp, Log, symmetric_fn};
use crate::tensor::det;
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

/// Non-associated Drucker–Prager elastoplasticity with a tension cutoff, hypoelastic with the
/// Jaumann rate: `f = √J₂ + α I₁ − k`, `g = √J₂ + α_ψ I₁`, `p = I₁/3 ≤ σ_t`, perfectly
/// plastic. See the module docs for the equations and the return mapping.
///
/// Angles are in radians. State ([`MaterialState`]): `plastic_strain` is the equivalent plastic
/// strain `ε̄ᵖ = Σ √(2/3) ‖Δεₚ‖`, `tensor` is `I + 2εₑ` with `εₑ = C⁻¹:σ`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DruckerPrager<T> {
    /// Lamé parameters of the (hypo)elastic law `σ̊ = λ tr(D) I + 2μ D`.
    pub lame: Lame<T>,
    /// Friction angle `φ` (radians), `0 < φ < π/2`.
    pub friction_angle: T,
    /// Dilation angle `ψ` (radians), `0 ≤ ψ ≤ φ`: `0` is isochoric plastic flow, `φ` the
    /// associated flow rule.
    pub dilation_angle: T,
    /// Cohesion `c ≥ 0` (Pa).
    pub cohesion: T,
    /// Tension cutoff `σ_t` (Pa) on the mean stress `p = I₁/3`; `None` puts it at the apex of
    /// the cone, `c cot φ` (`0` for a cohesionless material). A value above the apex acts as
    /// the apex.
    pub tension_cutoff: Option<T>,
    /// Which Mohr–Coulomb section the cone is matched to ([`Cone`]).
    pub cone: Cone,
    /// The elastic law and its integration ([`Elasticity`]).
    pub elasticity: Elasticity,
}

/// How the Drucker–Prager cone `√J₂ + α I₁ = k` is matched to the Mohr–Coulomb pyramid of the
/// same `(c, φ)` (de Souza Neto, Perić & Owen 2008, §6.4.2). With `s = sin θ`, `t = tan θ` for
/// an angle `θ` (`φ` for the yield surface, `ψ` for the plastic potential):
///
/// ```text
/// plane strain:  α = t / √(9 + 12t²),       k = 3c / √(9 + 12t²)
/// compression:   α = 2s / (√3 (3 − s)),     k = 6c cos φ / (√3 (3 − s))
/// extension:     α = 2s / (√3 (3 + s)),     k = 6c cos φ / (√3 (3 + s))
/// ```
///
/// Every match has its apex at `p = k/(3α) = c cot φ`. In triaxial compression the compression
/// cone is `q = M p′ + …` with `M = 6 sin φ/(3 − sin φ)` (compression positive `p′`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Cone {
    /// The plane-strain match: collapse loads of plane-strain problems with associated flow
    /// equal those of Mohr–Coulomb; the cone inscribed in the pyramid, tangent to its faces.
    #[default]
    PlaneStrain,
    /// The outer cone through the pyramid's compression meridian (triaxial compression,
    /// `σ₁ = σ₂ > σ₃` in tension-positive order).
    Compression,
    /// The inner cone through the pyramid's extension meridian.
    Extension,
}

impl Cone {
    /// `(α_θ, k_θ / c)` of the match for an angle `θ`: the cone coefficient and the factor of
    /// the cohesion in `k` (see [`Cone`] for the formulas).
    pub fn coefficients<T: Scalar>(self, angle: T) -> (T, T) {
        match self {
            Self::PlaneStrain => {
                let t = angle.tan();
                let root = (T::cst(9.0) + T::cst(12.0) * t * t).sqrt();
                (t / root, T::cst(3.0) / root)
            }
            Self::Compression | Self::Extension => {
                let s = angle.sin();
                let sign = if self == Self::Compression { -1.0 } else { 1.0 };
                let den = (T::cst(3.0) + s * T::cst(sign)) * T::cst(3f64.sqrt());
                (s * T::cst(2.0) / den, angle.cos() * T::cst(6.0) / den)
            }
        }
    }
}

/// The elastic law of a [`DruckerPrager`] material.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Elasticity {
    /// Hypoelastic, Jaumann rate, integrated over each explicit step (the GPU path's model;
    /// [`MaterialState::tensor`] holds `I + 2εₑ`). Not for implicit load steps.
    #[default]
    Jaumann,
    /// Hyperelastic in Hencky strain with a multiplicative split `F = Fₑ Fₚ`, as [`super::J2`]:
    /// the trial `bₑᵗʳ = ΔF bₑⁿ ΔFᵀ`, `τᵗʳ = C:½ ln bₑᵗʳ`, the same return on the Kirchhoff
    /// stress, `bₑ = exp(2 C⁻¹:τ)` ([`MaterialState::tensor`] holds `bₑ`). Exact for any
    /// step size, so the implicit solver uses it; objective without a rate.
    Hencky,
}

impl<T: Scalar> DruckerPrager<T> {
    /// Friction coefficient `α` of `f = √J₂ + α I₁ − k` (`tan φ / √(9 + 12 tan²φ)` for the
    /// plane-strain [`Cone`]).
    pub fn alpha(&self) -> T {
        self.cone.coefficients(self.friction_angle).0
    }

    /// Dilatancy coefficient `α_ψ` of `g = √J₂ + α_ψ I₁`, the cone's `α` of the angle `ψ`.
    pub fn alpha_psi(&self) -> T {
        self.cone.coefficients(self.dilation_angle).0
    }

    /// Cohesive strength `k` of `f = √J₂ + α I₁ − k` (the value of `√J₂` at yield when
    /// `I₁ = 0`; `3c / √(9 + 12 tan²φ)` for the plane-strain [`Cone`]).
    pub fn k(&self) -> T {
        self.cohesion * self.cone.coefficients(self.friction_angle).1
    }

    /// Mean stress at the apex of the cone, `p_apex = k/(3α) = c cot φ` (`0` when `c = 0`).
    pub fn apex(&self) -> T {
        self.cohesion / self.friction_angle.tan()
    }

    /// The tension cutoff in force, `min(σ_t, c cot φ)` (compared on real parts); the apex
    /// when none is given.
    pub fn tension_limit(&self) -> T {
        self.corner().0
    }

    /// The corner `(σ_t, q_c)` where the cutoff plane meets the cone, `q_c = k − 3α σ_t ≥ 0`
    /// the value of `√J₂` there: exactly `(c cot φ, 0)`, the apex, when the cutoff is at or
    /// above it.
    pub fn corner(&self) -> (T, T) {
        let (_, _, sigma_t, q_c) = self.surface();
        (sigma_t, q_c)
    }

    /// `(α, k, σ_t, q_c)` of the yield surface and the cutoff, with one `tan` and one `sqrt`
    /// (the return mapping needs all four every step).
    fn surface(&self) -> (T, T, T, T) {
        let (alpha, k_factor) = self.cone.coefficients(self.friction_angle);
        let k = self.cohesion * k_factor;
        let apex = self.cohesion / self.friction_angle.tan();
        match self.tension_cutoff {
            Some(t) if t.re() < apex.re() => {
                let q_c = k - alpha * t * T::cst(3.0);
                // q_c > 0 below the apex up to round-off; never let it go negative.
                (alpha, k, t, if q_c.re() > 0.0 { q_c } else { T::zero() })
            }
            _ => (alpha, k, apex, T::zero()),
        }
    }

    /// Bulk modulus `K = λ + ⅔μ`.
    pub fn bulk_modulus(&self) -> T {
        self.lame.lambda + self.lame.mu * T::cst(2.0 / 3.0)
    }

    /// The yield function `f(σ) = √J₂ + α I₁ − k` (negative inside the cone).
    ///
    /// With dual numbers its derivative is not defined where `s = 0` (the cone's axis).
    pub fn yield_function(&self, sigma: &Matrix3<T>) -> T {
        let (p, s) = split(sigma);
        s.norm() * T::cst(std::f64::consts::FRAC_1_SQRT_2) + self.alpha() * p * T::cst(3.0)
            - self.k()
    }

    /// The elastic strain of a stress, `C⁻¹:σ = s/(2μ) + p/(3K) I`.
    pub fn compliance(&self, sigma: &Matrix3<T>) -> Matrix3<T> {
        let (p, s) = split(sigma);
        s / (self.lame.mu * T::cst(2.0))
            + Matrix3::identity() * (p / (self.bulk_modulus() * T::cst(3.0)))
    }

    /// The stress a state stands for, `C:εₑ`: the Cauchy stress with `εₑ = ½ (tensor − I)`
    /// ([`Elasticity::Jaumann`]), the Kirchhoff stress with `εₑ = ½ ln bₑ`
    /// ([`Elasticity::Hencky`]).
    pub fn stress_of_state(&self, state: &MaterialState<T>) -> Matrix3<T> {
        self.lame.stress(&self.elastic_strain(state))
    }

    /// The elastic strain `εₑ` a state holds: `½ (tensor − I)` ([`Elasticity::Jaumann`]) or
    /// the Hencky strain `½ ln bₑ` ([`Elasticity::Hencky`]).
    pub fn elastic_strain(&self, state: &MaterialState<T>) -> Matrix3<T> {
        match self.elasticity {
            Elasticity::Jaumann => (state.tensor - Matrix3::identity()) * T::cst(0.5),
            Elasticity::Hencky => symmetric_fn(&state.tensor, &Log) * T::cst(0.5),
        }
    }

    /// The state that an elastic strain `εₑ` stands for (the inverse of
    /// [`DruckerPrager::elastic_strain`]): `I + 2εₑ` or `bₑ = exp(2εₑ)`.
    pub fn state_tensor(&self, eps_e: &Matrix3<T>) -> Matrix3<T> {
        match self.elasticity {
            Elasticity::Jaumann => Matrix3::identity() + eps_e * T::cst(2.0),
            Elasticity::Hencky => symmetric_fn(&(eps_e * T::cst(2.0)), &Exp),
        }
    }

    /// One step of the Hencky model ([`Elasticity::Hencky`]) from the relative deformation
    /// gradient `ΔF`: `bₑᵗʳ = ΔF bₑⁿ ΔFᵀ`, `τᵗʳ = C:½ ln bₑᵗʳ`, [`DruckerPrager::return_map`] on
    /// `τᵗʳ`, `bₑ = exp(2 C⁻¹:τ)`. Returns the Kirchhoff stress, the new state and the region.
    /// Pure; with dual `ΔF` its derivative is the consistent tangent.
    pub fn hencky_return(
        &self,
        delta_f: &Matrix3<T>,
        state: &MaterialState<T>,
    ) -> (Matrix3<T>, MaterialState<T>, Region) {
        let (b_trial, eps_trial) = hencky_trial(delta_f, &state.tensor);
        let tau_trial = self.lame.stress(&eps_trial);
        let (tau, mut new_state, region) = self.return_map(&tau_trial, state);
        new_state.tensor = if region == Region::Elastic {
            b_trial
        } else {
            self.state_tensor(&self.compliance(&tau))
        };
        (tau, new_state, region)
    }

    /// The elastic trial stress of a step, `σᵗʳ = Q σₙ Qᵀ + C:(Δt D)`, from the stress at the
    /// start of the step and the velocity-gradient increment `ΔL = Δt L` (3×3; `ΔF − I` for a
    /// relative deformation gradient `ΔF`).
    ///
    /// `Q = (I − A)⁻¹(I + A)`, `A = ½ Δt W` skew, is evaluated in the closed form
    /// `Q = I + 2 (A + A²) / (1 + |a|²)`, `|a|² = ½ ‖A‖²` (from `A³ = −|a|² A`), exactly
    /// orthogonal and free of a matrix inverse.
    pub fn trial_stress(&self, sigma_n: &Matrix3<T>, dl: &Matrix3<T>) -> Matrix3<T> {
        let half = T::cst(0.5);
        let a = (dl - dl.transpose()) * (half * half);
        let d = (dl + dl.transpose()) * half;
        let a2 = a * a;
        let q =
            Matrix3::identity() + (a + a2) * (T::cst(2.0) / (T::one() + a.norm_squared() * half));
        let rotated = q * sigma_n * q.transpose();
        // Symmetrised so that round-off asymmetry does not accumulate over many steps.
        (rotated + rotated.transpose()) * half + self.lame.stress(&d)
    }

    /// The closed-form return mapping of a trial stress (see the module docs): the stress, the
    /// new state (`ε̄ᵖ` increased by `√(2/3) ‖C⁻¹:(σᵗʳ − σ)‖`, `tensor = I + 2 C⁻¹:σ`) and the
    /// region taken. Branches are taken on real parts.
    pub fn return_map(
        &self,
        sigma_trial: &Matrix3<T>,
        state: &MaterialState<T>,
    ) -> (Matrix3<T>, MaterialState<T>, Region) {
        let three = T::cst(3.0);
        let id = Matrix3::identity();
        let (p_tr, s_tr) = split(sigma_trial);
        // √J₂ of the trial. (Its dual part is NaN when s = 0, but then no branch that uses it
        // is taken: such a trial is elastic, in the tension region or, with f > 0, beyond the
        // apex, where the shear return gives q < 0 ≤ q_c.)
        let q_tr = s_tr.norm() * T::cst(std::f64::consts::FRAC_1_SQRT_2);
        let (alpha, k, sigma_t, q_c) = self.surface();
        let f_shear = q_tr + alpha * p_tr * three - k;
        let f_tension = p_tr - sigma_t;
        if f_shear.re() <= 0.0 && f_tension.re() <= 0.0 {
            let state = MaterialState {
                plastic_strain: state.plastic_strain,
                tensor: id + self.compliance(sigma_trial) * T::cst(2.0),
                hardening: state.hardening,
            };
            return (*sigma_trial, state, Region::Elastic);
        }
        let mu = self.lame.mu;
        let bulk = self.bulk_modulus();
        let alpha_psi = self.alpha_psi();
        let mut result = None;
        if f_shear.re() > 0.0 {
            let dgamma = f_shear / (mu + bulk * alpha * alpha_psi * T::cst(9.0));
            let q = q_tr - mu * dgamma;
            if q.re() >= q_c.re() {
                let p = p_tr - bulk * alpha_psi * dgamma * three;
                result = Some((s_tr * (q / q_tr) + id * p, Region::Shear));
            }
        }
        let (sigma, region) = result.unwrap_or_else(|| {
            if q_tr.re() <= q_c.re() {
                (s_tr + id * sigma_t, Region::Tension)
            } else {
                (s_tr * (q_c / q_tr) + id * sigma_t, Region::Corner)
            }
        });
        let eps_e = self.compliance(&sigma);
        let deps_p = self.compliance(sigma_trial) - eps_e;
        let state = MaterialState {
            plastic_strain: state.plastic_strain + deps_p.norm() * T::cst(2.0 / 3.0).sqrt(),
            tensor: id + eps_e * T::cst(2.0),
            hardening: state.hardening,
        };
        (sigma, state, region)
    }

    /// One step from the stress `σₙ` with the velocity-gradient increment `ΔL = Δt L`:
    /// [`DruckerPrager::trial_stress`] then [`DruckerPrager::return_map`]. Pure.
    pub fn stress_update(
        &self,
        sigma_n: &Matrix3<T>,
        dl: &Matrix3<T>,
        state: &MaterialState<T>,
    ) -> (Matrix3<T>, MaterialState<T>, Region) {
        self.return_map(&self.trial_stress(sigma_n, dl), state)
    }

    /// Kirchhoff stress and new state of a step with the relative deformation gradient `ΔF`.
    /// Pure. [`Elasticity::Hencky`]: [`DruckerPrager::hencky_return`].
    /// [`Elasticity::Jaumann`]: `τ = J σ` (`J = det f`) from the stress the state stands for
    /// ([`DruckerPrager::stress_of_state`]) and `ΔL = ΔF − I`; the scene checks keep this one
    /// out of the implicit solvers: the Jaumann update is accurate only for the small
    /// increments of explicit steps, not for whole load steps.
    pub fn kirchhoff_update(
        &self,
        delta_f: &Matrix3<T>,
        f: &Matrix3<T>,
        state: &MaterialState<T>,
    ) -> (Matrix3<T>, MaterialState<T>) {
        match self.elasticity {
            Elasticity::Hencky => {
                let (tau, state, _) = self.hencky_return(delta_f, state);
                (tau, state)
            }
            Elasticity::Jaumann => {
                let sigma_n = self.stress_of_state(state);
                let dl = delta_f - Matrix3::identity();
                let (sigma, state, _) = self.stress_update(&sigma_n, &dl, state);
                (sigma * det::<T, 3>(f), state)
            }
        }
    }

    /// The explicit stress update, committing the new state and returning the region taken:
    /// [`DruckerPrager::stress_update`] from `kin.stress` with `ΔL = kin.dt · L`
    /// ([`Elasticity::Jaumann`]), or `σ = τ / det F` with `τ` from
    /// [`DruckerPrager::hencky_return`] on `kin.delta_f` ([`Elasticity::Hencky`]).
    pub fn update_region(
        &self,
        kin: &Kinematics<'_, T>,
        state: &mut MaterialState<T>,
    ) -> (Matrix3<T>, Region) {
        let (sigma, new_state, region) = match self.elasticity {
            Elasticity::Jaumann => {
                let dl = kin.velocity_gradient * kin.dt;
                self.stress_update(kin.stress, &dl, state)
            }
            Elasticity::Hencky => {
                let (tau, new_state, region) = self.hencky_return(kin.delta_f, state);
                (tau / det::<T, 3>(kin.f), new_state, region)
            }
        };
        *state = new_state;
        (sigma, region)
    }

    /// Stored elastic energy per unit reference volume, from the elastic strain the state
    /// holds ([`DruckerPrager::elastic_strain`]): `ψ = μ εₑ:εₑ + ½λ (tr εₑ)²` for
    /// [`Elasticity::Hencky`] (per reference volume, as [`super::J2`]), `J ψ` for
    /// [`Elasticity::Jaumann`] (`J = det f`; its energy density is per current volume).
    pub fn stored_energy(&self, f: &Matrix3<T>, state: &MaterialState<T>) -> T {
        let psi = self.lame.energy(&self.elastic_strain(state));
        match self.elasticity {
            Elasticity::Jaumann => psi * det::<T, 3>(f),
            Elasticity::Hencky => psi,
        }
    }
}

impl DruckerPrager<f64> {
    /// The same parameters as constants of another scalar type (zero derivative parts).
    pub fn lift<T: Scalar>(&self) -> DruckerPrager<T> {
        DruckerPrager {
            lame: self.lame.lift(),
            friction_angle: T::cst(self.friction_angle),
            dilation_angle: T::cst(self.dilation_angle),
            cohesion: T::cst(self.cohesion),
            tension_cutoff: self.tension_cutoff.map(T::cst),
            cone: self.cone,
            elasticity: self.elasticity,
        }
    }
}

/// Mean stress `p = tr(σ)/3` and deviator `s = σ − p I`.
fn split<T: Scalar>(sigma: &Matrix3<T>) -> (T, Matrix3<T>) {
    let p = sigma.trace() / T::cst(3.0);
    (p, sigma - Matrix3::identity() * p)
}

impl<T: Scalar> Constitutive<T> for DruckerPrager<T> {
    /// [`DruckerPrager::stress_update`] from `kin.stress` with `ΔL = kin.dt · L`; commits the
    /// new state.
    fn update(&self, kin: &Kinematics<'_, T>, state: &mut MaterialState<T>) -> Matrix3<T> {
        self.update_region(kin, state).0
    }

    /// `λ + 2μ`: the elastic constrained modulus bounds the wave speed (plastic flow only
    /// softens the material).
    fn p_wave_modulus(&self) -> f64 {
        self.lame.p_wave_modulus().re()
    }
}
