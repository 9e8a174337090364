//! Weakly compressible Newtonian fluid (e.g. water in a dam-break).
//!
//! The pressure comes from the volume ratio `J = det F` alone (the density ratio is
//! `ρ/ρ₀ = 1/J`) through the Tait equation of state, normalised so that `K` is the bulk
//! modulus in the reference state:
//!
//! ```text
//! p(J) = (K/γ) ((1/J)^γ − 1),        dp/d(ρ/ρ₀) = K at J = 1,  dp/dJ = −K at J = 1.
//! ```
//!
//! `γ = 1` is the same formula, `p = K (1/J − 1)`; `γ = 7` is the usual choice for water.
//! (Some codes write `p = K((1/J)^γ − 1)`, whose reference bulk modulus is `γK`; here the
//! parameter *is* the bulk modulus, so the sound speed is `c = √(K/ρ₀)` whatever `γ`.)
//!
//! The Cauchy stress adds Newtonian viscosity on the deviatoric rate of deformation:
//!
//! ```text
//! σ = −p I + 2η (D − ⅓ tr(D) I),     D = ½ (L + Lᵀ),
//! ```
//!
//! with `L` the velocity gradient of the step ([`Kinematics::velocity_gradient`], 3×3 with a
//! zero out-of-plane row and column in plane strain, so `σ_zz` of a 2D run carries
//! `−p − ⅔η tr D`). There is no bulk viscosity and no history: only `det F` of the
//! deformation gradient enters, so shear accumulated in `F` has no effect.
//!
//! The stored compression energy per unit reference volume is `ψ(J) = −∫₁ᴶ p(J') dJ'`:
//!
//! ```text
//! ψ(J) = (K/γ) [ (J − 1) + (J^{1−γ} − 1)/(γ − 1) ]   (γ ≠ 1),
//! ψ(J) = K [ (J − 1) − ln J ]                        (γ = 1, the limit of the above),
//! ```
//!
//! convex with `ψ(1) = ψ'(1) = 0`, `ψ'(J) = −p(J)` and `ψ''(J) = K J^{−γ−1}`. Both cases are
//! evaluated by one formula, `(J^{1−γ} − 1)/(γ − 1) = −ln J · expm1(a)/a` with
//! `a = (1 − γ) ln J`, which is exact at `γ = 1` and free of cancellation near it.

use super::{Constitutive, Kinematics, MaterialState};
use crate::scalar::Scalar;
use crate::tensor::det;
use nalgebra::Matrix3;

/// Largest whole Tait exponent `γ` for which [`Fluid::pressure`] takes `J^{−γ}` as an integer
/// power (far above any exponent in use, so the repeated multiplications stay accurate).
const MAX_INTEGER_GAMMA: u32 = 64;

/// Weakly compressible Newtonian fluid: Tait pressure on `J = det F` plus deviatoric
/// viscous stress on the rate of deformation. See the module docs for the equations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fluid<T> {
    /// Bulk modulus `K` (Pa) at the reference density, positive: `dp/d(ρ/ρ₀) = K` at `J = 1`.
    pub bulk_modulus: T,
    /// Tait exponent `γ ≥ 1` (7 for water; 1 gives `p = K(1/J − 1)`).
    pub gamma: T,
    /// Dynamic (shear) viscosity `η ≥ 0` (Pa·s).
    pub viscosity: T,
}

impl<T: Scalar> Fluid<T> {
    /// From the reference sound speed `c` (m/s) and density `ρ₀` (kg/m³): `K = ρ₀ c²`.
    ///
    /// In a weakly compressible model `c` is a numerical parameter, usually about ten times
    /// the largest flow speed (density variations of about 1 %), far below the physical one.
    pub fn from_sound_speed(sound_speed: T, density: T, gamma: T, viscosity: T) -> Self {
        Self {
            bulk_modulus: density * sound_speed * sound_speed,
            gamma,
            viscosity,
        }
    }

    /// Pressure `p(J) = (K/γ)(J^{−γ} − 1)` (positive in compression, `J < 1`).
    ///
    /// `J^{−γ}` is `1/J^γ` by repeated multiplication when `γ` is a whole number without a
    /// derivative part (γ = 7 for water, 1): cheaper than `exp(−γ ln J)`, as accurate, and
    /// with the same derivative with respect to `J`. Any other `γ`, or one carrying a
    /// derivative (a sensitivity with respect to `γ`), takes `exp(−γ ln J)`.
    #[inline]
    pub fn pressure(&self, j: T) -> T {
        // A whole γ round-trips through an integer (NaN and negative γ do not: they saturate).
        let (g, n) = (self.gamma.re(), self.gamma.re() as u32);
        let power = if n as f64 == g && n <= MAX_INTEGER_GAMMA && self.gamma.is_constant() {
            T::one() / whole_power(j, n)
        } else {
            (-self.gamma * j.ln()).exp()
        };
        (self.bulk_modulus / self.gamma) * (power - T::one())
    }

    /// Stored compression energy per unit reference volume `ψ(J) = −∫₁ᴶ p dJ'` (see the
    /// module docs for the closed form); `ψ'(J) = −p(J)`.
    pub fn energy_of_volume_ratio(&self, j: T) -> T {
        let ln_j = j.ln();
        let a = (T::one() - self.gamma) * ln_j;
        // (J^{1−γ} − 1)/(γ − 1) = −ln J · (eᵃ − 1)/a, → −ln J as a → 0 (γ = 1 or J = 1).
        let ratio = if a.re() == 0.0 {
            T::one() + a * T::cst(0.5)
        } else {
            a.exp_m1() / a
        };
        (self.bulk_modulus / self.gamma) * ((j - T::one()) - ln_j * ratio)
    }

    /// Stored compression energy per unit reference volume as a function of `F`,
    /// `ψ(det F)`.
    pub fn energy_density(&self, f: &Matrix3<T>) -> T {
        self.energy_of_volume_ratio(det::<T, 3>(f))
    }

    /// The pressure part of the Kirchhoff stress, `τ = −J p(J) I = ∂ψ/∂F Fᵀ`, `J = det F`.
    ///
    /// This is what an implicit (quasi-static or Newmark) solver sees of the fluid: the
    /// viscous stress needs a rate of deformation, which the implicit path's
    /// `(ΔF, F, state)` interface does not carry, so there the fluid is inviscid
    /// (a purely volumetric hyperelastic material with zero shear stiffness).
    pub fn kirchhoff_stress(&self, f: &Matrix3<T>) -> Matrix3<T> {
        let j = det::<T, 3>(f);
        Matrix3::identity() * (-j * self.pressure(j))
    }

    /// Viscous Cauchy stress `2η (D − ⅓ tr(D) I)`, `D = sym(L)`.
    pub fn viscous_stress(&self, velocity_gradient: &Matrix3<T>) -> Matrix3<T> {
        let d = (velocity_gradient + velocity_gradient.transpose()) * T::cst(0.5);
        let dev = d - Matrix3::identity() * (d.trace() / T::cst(3.0));
        dev * (self.viscosity * T::cst(2.0))
    }
}

/// `x^n` by binary powering, in a fixed order of multiplications (the same bits wherever it
/// is inlined, unlike `powi`, whose order the compiler may choose; exact derivatives for duals).
#[inline]
fn whole_power<T: Scalar>(x: T, n: u32) -> T {
    let (mut acc, mut base, mut n) = (T::one(), x, n);
    loop {
        if n & 1 == 1 {
            acc *= base;
        }
        n >>= 1;
        if n == 0 {
            return acc;
        }
        base *= base;
    }
}

impl Fluid<f64> {
    /// The same parameters as constants of another scalar type (zero derivative parts).
    pub fn lift<T: Scalar>(&self) -> Fluid<T> {
        Fluid {
            bulk_modulus: T::cst(self.bulk_modulus),
            gamma: T::cst(self.gamma),
            viscosity: T::cst(self.viscosity),
        }
    }
}

impl<T: Scalar> Constitutive<T> for Fluid<T> {
    /// `σ = −p(det F) I + 2η dev sym(L)`; no history, `state` untouched. An inviscid fluid
    /// (`η = 0` exactly, derivative part included) skips the viscous term.
    #[inline]
    fn update(&self, kin: &Kinematics<'_, T>, _state: &mut MaterialState<T>) -> Matrix3<T> {
        let pressure = Matrix3::from_diagonal_element(-self.pressure(det::<T, 3>(kin.f)));
        if self.viscosity.re() == 0.0 && self.viscosity.is_constant() {
            pressure
        } else {
            self.viscous_stress(kin.velocity_gradient) + pressure
        }
    }

    /// `K`: the sound speed `c = √(K/ρ₀)` sets the time-step bound. The viscous (diffusive)
    /// limit, of order `Δt ≲ ρ₀ h²/η`, is not part of it; it only binds for very viscous
    /// fluids on fine grids.
    fn p_wave_modulus(&self) -> f64 {
        self.bulk_modulus.re()
    }
}
