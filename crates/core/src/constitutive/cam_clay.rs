//! Modified Cam-Clay at finite strain, in Hencky strain space (after Borja & Tamagnini,
//! *Comput. Methods Appl. Mech. Engrg.* 155, 1998: a multiplicative split `F = Fₑ Fₚ`, the
//! elastic logarithmic strain `εₑ = ½ ln bₑ`, and the return mapping in its invariants).
//!
//! **Sign convention.** Inside this module, as in soil mechanics, the mean effective stress
//! `p = −tr τ / 3` and the volumetric elastic strain `ε_v = −tr εₑ` are compression positive;
//! the Kirchhoff stress `τ` the model returns is tension positive, as everywhere in loam.
//! `q = √(3/2) ‖dev τ‖`, `ε_s = √(2/3) ‖dev εₑ‖`.
//!
//! **Elasticity** (pressure dependent, coaxial with `εₑ`):
//!
//! ```text
//! p = p_r exp(ε_v / κ̃),    dev τ = 2G dev εₑ,    G = G₀  or  G = 3(1 − 2ν) / (2(1 + ν)) · p / κ̃
//! ```
//!
//! with `κ̃ = κ / (1 + e₀)` from the swelling slope `κ` of the `e–ln p′` line and the initial void
//! ratio `e₀`, so that the unloading line is `ln v = const − κ̃ ln p′` (a straight line in
//! `ln v–ln p′`, Butterfield's form; `de/d ln p′ = −κ v / v₀` in `e–ln p′`). `p_r` =
//! [`REFERENCE_PRESSURE`] only fixes the origin of `ε_v`: the states a scene gives are stresses,
//! and `bₑ` is built from them. With a constant `G₀` the law is hyperelastic (the energy
//! `κ̃ p + (3/2) G₀ ε_s²`); with `G` from `ν` it is Cauchy-elastic (a function of `εₑ`, so the
//! return mapping is exact, but not derivable from an energy: a closed elastic cycle can do
//! work).
//!
//! **Yield surface and hardening** (associated flow):
//!
//! ```text
//! f = q² / M² + p (p − p_c) ≤ 0,    p_c = p_cⁿ exp(Δε_vᵖ / (λ̃ − κ̃)),    λ̃ = λ / (1 + e₀)
//! ```
//!
//! `Δε_vᵖ = Δγ ∂f/∂p = Δγ (2p − p_c)` (compression positive). On the critical state line
//! `q = M p` the plastic volume change vanishes (`p = p_c / 2`).
//!
//! **Return mapping.** The trial `bₑᵗʳ = ΔF bₑⁿ ΔFᵀ` gives `ε_vᵗʳ` and the trial deviator
//! `eᵗʳ = dev εᵗʳ`. The return keeps the deviatoric direction and solves, for the elastic
//! `ε_v` and `z = Δγ p_cⁿ` (both strains):
//!
//! ```text
//! R₁ = ε_v − ε_vᵗʳ + z (2p − p_c) / p_cⁿ = 0,     R₂ = (q² / M² + p (p − p_c)) / p_cⁿ² = 0,
//! q = r ε_sᵗʳ,   r = 3G / (1 + 6GΔγ / M²)   (from ε_s = ε_sᵗʳ − 2qΔγ/M², q = 3G ε_s)
//! ```
//!
//! by a 2 × 2 Newton iteration with a backtracking line search on the real parts. The
//! derivative parts (a dual `ΔF`, state or parameter) then follow from the implicit-function
//! theorem: one step `x ← x − (∂R/∂x)⁻¹ R(x, ·)` evaluated in `T` at the converged `x`, with the
//! exact real Jacobian, gives `ẋ = −(∂R/∂x)⁻¹ ∂R/∂(·)`. The principal stresses are
//! `τ_i = −p + (2r/3) e_iᵗʳ` (finite at `ε_sᵗʳ = 0`), the new elastic strains
//! `εₑ_i = −ε_v/3 + (r/3G) e_iᵗʳ`, and the stress and `bₑ = exp(2εₑ)` are assembled from the
//! principal values of `bₑᵗʳ` through [`super::trial_return`] (one
//! eigen-decomposition for the trial strain, the stress and the state), so the dual tangent
//! is exact also at repeated principal strains.

use super::trial_return::{PrincipalReturn, trial_return};
use super::{Constitutive, Kinematics, MaterialState, Region};
use crate::scalar::Scalar;
use crate::spectral::{Exp, Log, symmetric_fn};
use crate::tensor::det;
use nalgebra::{Matrix3, SVector};
use num_dual::{Derivative, DualSVec64};
use std::borrow::Borrow;

/// The pressure `p_r` (Pa) at zero elastic volumetric strain: the origin of `ε_v`, no
/// material constant (module docs).
pub const REFERENCE_PRESSURE: f64 = 1.0e3;

/// How the shear modulus of [`ModifiedCamClay`] is given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shear<T> {
    /// A constant shear modulus `G₀` (Pa): hyperelastic.
    Modulus(T),
    /// A constant Poisson's ratio `ν`: `G = 3(1 − 2ν)/(2(1 + ν)) · K` with the tangent bulk
    /// modulus `K = p/κ̃`.
    Poisson(T),
}

/// The preconsolidation pressure of a [`ModifiedCamClay`] material at the start of a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Preconsolidation<T> {
    /// `p_c₀` (Pa), the same for every point.
    Pressure(T),
    /// An overconsolidation ratio `R ≥ 1` on the size of the yield locus: `p_c₀ = R p_y` with
    /// `p_y = p′₀ + q₀²/(M² p′₀)` the `p_c` of the ellipse through the initial stress (`R = 1`:
    /// normally consolidated; for an isotropic state `p_c₀ = R p′₀`).
    Ratio(T),
}

/// Modified Cam-Clay in Hencky strain space (module docs). State ([`MaterialState`]): `tensor`
/// is `bₑ`, `plastic_strain` the equivalent plastic strain, `hardening` the preconsolidation
/// pressure `p_c` (Pa).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModifiedCamClay<T> {
    /// Slope `λ` of the normal compression line in `e–ln p′`.
    pub lambda: T,
    /// Slope `κ` of the unloading–reloading line in `e–ln p′` (`0 < κ < λ`).
    pub kappa: T,
    /// Slope `M` of the critical state line in `p′–q`.
    pub critical_state_slope: T,
    /// Initial void ratio `e₀` (sets `λ̃ = λ/(1 + e₀)`, `κ̃ = κ/(1 + e₀)`).
    pub void_ratio: T,
    /// The shear modulus or Poisson's ratio.
    pub shear: Shear<T>,
    /// The preconsolidation pressure at the start (read only when a point's state is built
    /// from its initial stress: [`ModifiedCamClay::initial_state`]).
    pub preconsolidation: Preconsolidation<T>,
}

/// The return of a [`ModifiedCamClay`] material (owned or borrowed) from the
/// preconsolidation pressure `p_cⁿ`, as a [`PrincipalReturn`].
struct AtPressure<M, T> {
    model: M,
    p_c: T,
}

impl<T: Scalar, M: Borrow<ModifiedCamClay<T>>> PrincipalReturn<T> for AtPressure<M, T> {
    type Lanes = AtPressure<ModifiedCamClay<DualSVec64<3>>, DualSVec64<3>>;

    fn principal_state(&self, eps: [T; 3]) -> ([T; 3], Option<[T; 3]>, Region) {
        self.model.borrow().principal_return(eps, self.p_c)
    }

    fn lanes(&self) -> Self::Lanes {
        AtPressure {
            model: self.model.borrow().real().lift(),
            p_c: DualSVec64::from_re(self.p_c.re()),
        }
    }
}

/// Newton iterations of the local return before it gives up (a backtracking line search
/// keeps each one descending; a load step converges in well under ten).
const MAX_LOCAL_ITERATIONS: usize = 60;

impl<T: Scalar> ModifiedCamClay<T> {
    /// The real parts of the parameters.
    pub fn real(&self) -> ModifiedCamClay<f64> {
        ModifiedCamClay {
            lambda: self.lambda.re(),
            kappa: self.kappa.re(),
            critical_state_slope: self.critical_state_slope.re(),
            void_ratio: self.void_ratio.re(),
            shear: match self.shear {
                Shear::Modulus(g) => Shear::Modulus(g.re()),
                Shear::Poisson(nu) => Shear::Poisson(nu.re()),
            },
            preconsolidation: match self.preconsolidation {
                Preconsolidation::Pressure(p) => Preconsolidation::Pressure(p.re()),
                Preconsolidation::Ratio(r) => Preconsolidation::Ratio(r.re()),
            },
        }
    }

    /// `κ̃ = κ / (1 + e₀)`, the slope of `ln v` against `ln p′` on unloading.
    pub fn kappa_log(&self) -> T {
        self.kappa / (T::one() + self.void_ratio)
    }

    /// `λ̃ = λ / (1 + e₀)`, the slope of `ln v` against `ln p′` on the normal compression line.
    pub fn lambda_log(&self) -> T {
        self.lambda / (T::one() + self.void_ratio)
    }

    /// The mean effective stress `p = p_r exp(ε_v / κ̃)` at elastic volumetric strain `ε_v`
    /// (compression positive).
    pub fn pressure(&self, eps_v: T) -> T {
        (eps_v / self.kappa_log()).exp() * T::cst(REFERENCE_PRESSURE)
    }

    /// The elastic volumetric strain `ε_v = κ̃ ln(p / p_r)` at mean effective stress `p > 0`.
    pub fn volumetric_strain(&self, p: T) -> T {
        (p / T::cst(REFERENCE_PRESSURE)).ln() * self.kappa_log()
    }

    /// The shear modulus at mean effective stress `p`.
    pub fn shear_modulus(&self, p: T) -> T {
        match self.shear {
            Shear::Modulus(g) => g,
            Shear::Poisson(nu) => {
                let one = T::one();
                T::cst(1.5) * (one - nu * T::cst(2.0)) / (one + nu) * p / self.kappa_log()
            }
        }
    }

    /// The yield function `f = q²/M² + p (p − p_c)` (negative inside the ellipse).
    pub fn yield_function(&self, p: T, q: T, p_c: T) -> T {
        let m = self.critical_state_slope;
        q * q / (m * m) + p * (p - p_c)
    }

    /// The residuals `(R₁, R₂)` of the return (module docs) at `ε_v`, `z = Δγ p_cⁿ`, from the
    /// trial `ε_vᵗʳ`, `(ε_sᵗʳ)²` and `p_cⁿ`.
    fn residual(&self, x: [T; 2], trial: (T, T), p_cn: T) -> [T; 2] {
        let (eps_v, z) = (x[0], x[1]);
        let (eps_v_trial, eps_s2_trial) = trial;
        let m2 = self.critical_state_slope * self.critical_state_slope;
        let p = self.pressure(eps_v);
        let g = self.shear_modulus(p);
        let dgamma = z / p_cn;
        let r = g * T::cst(3.0) / (T::one() + g * dgamma * T::cst(6.0) / m2);
        let p_c = p_cn * ((eps_v_trial - eps_v) / (self.lambda_log() - self.kappa_log())).exp();
        let r1 = eps_v - eps_v_trial + z * (p * T::cst(2.0) - p_c) / p_cn;
        let r2 = (r * r * eps_s2_trial / m2 + p * (p - p_c)) / (p_cn * p_cn);
        [r1, r2]
    }

    /// The return of trial principal strains `εᵗʳ` (any order) from the preconsolidation
    /// pressure `p_cⁿ` to principal Kirchhoff stresses in the same order, with, for a plastic
    /// step, the principal elastic strains `εₑ = −ε_v/3 + (τ + p)/(2G)`, and the region taken
    /// ([`Region::Shear`] for a plastic step).
    pub fn principal_return(&self, eps: [T; 3], p_cn: T) -> ([T; 3], Option<[T; 3]>, Region) {
        let third = T::cst(1.0 / 3.0);
        let eps_v_trial = -(eps[0] + eps[1] + eps[2]);
        let dev: [T; 3] = std::array::from_fn(|i| eps[i] + eps_v_trial * third);
        let eps_s2 = (dev[0] * dev[0] + dev[1] * dev[1] + dev[2] * dev[2]) * T::cst(2.0 / 3.0);
        let stresses =
            |p: T, r: T| -> [T; 3] { std::array::from_fn(|i| -p + r * dev[i] * T::cst(2.0 / 3.0)) };
        let p_trial = self.pressure(eps_v_trial);
        let r_trial = self.shear_modulus(p_trial) * T::cst(3.0);
        // f with q² = r² (ε_sᵗʳ)² (no square root: smooth at ε_sᵗʳ = 0).
        let m2 = self.critical_state_slope * self.critical_state_slope;
        let f_trial = r_trial * r_trial * eps_s2 / m2 + p_trial * (p_trial - p_cn);
        if f_trial.re() <= 0.0 {
            return (stresses(p_trial, r_trial), None, Region::Elastic);
        }
        let trial = (eps_v_trial, eps_s2);
        let x = self
            .real()
            .solve_return([eps_v_trial.re(), 0.0], trial_re(trial), p_cn.re());
        // Implicit-function step in T at the converged real root: x − J⁻¹ R(x; inputs in T).
        let j = self.real().residual_jacobian(x, trial_re(trial), p_cn.re());
        let r = self.residual([T::cst(x[0]), T::cst(x[1])], trial, p_cn);
        let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
        let eps_v = T::cst(x[0]) - (r[0] * T::cst(j[1][1]) - r[1] * T::cst(j[0][1])) / T::cst(det);
        let z = T::cst(x[1]) - (r[1] * T::cst(j[0][0]) - r[0] * T::cst(j[1][0])) / T::cst(det);
        let p = self.pressure(eps_v);
        let g = self.shear_modulus(p);
        let ratio = g * T::cst(3.0) / (T::one() + g * (z / p_cn) * T::cst(6.0) / m2);
        // dev εₑ = dev τ / (2G) = (r / 3G) eᵗʳ.
        let shear = ratio / (g * T::cst(3.0));
        let elastic = std::array::from_fn(|i| -eps_v * third + shear * dev[i]);
        (stresses(p, ratio), Some(elastic), Region::Shear)
    }

    /// One step of the return mapping from the relative deformation gradient `ΔF` and the
    /// state at the start of the step: the Kirchhoff stress, the new state and the region.
    /// Pure; with dual `ΔF` its derivative is the consistent tangent.
    pub fn return_map(
        &self,
        delta_f: &Matrix3<T>,
        state: &MaterialState<T>,
    ) -> (Matrix3<T>, MaterialState<T>, Region) {
        let at = AtPressure {
            model: self,
            p_c: state.hardening,
        };
        let (tau, b_e, tag) = trial_return(&at, delta_f, state);
        if tag.region == Region::Elastic {
            let elastic = MaterialState {
                tensor: b_e,
                ..*state
            };
            return (tau, elastic, tag.region);
        }
        let p_c =
            state.hardening * (tag.plastic_volume / (self.lambda_log() - self.kappa_log())).exp();
        let plastic = MaterialState {
            plastic_strain: state.plastic_strain + tag.plastic * T::cst(2.0 / 3.0).sqrt(),
            tensor: b_e,
            hardening: p_c,
        };
        (tau, plastic, tag.region)
    }

    /// The state of a point that carries the Kirchhoff stress `τ₀` with no plastic strain:
    /// `bₑ = exp(2εₑ(τ₀))` and `p_c` from [`ModifiedCamClay::preconsolidation`]: given, or
    /// `OCR (p′₀ + q₀²/(M² p′₀))`, OCR times the ellipse through `τ₀`; `None` unless the mean
    /// effective stress `p′₀ = −tr τ₀/3` is positive (the model has no stiffness at zero
    /// pressure). With dual constants (or a dual `τ₀`) the derivative parts are those of the
    /// state, which the adjoints of prestressed runs need. Whether `τ₀` lies inside the ellipse
    /// (a given `p_c₀` may be too small) is the caller's to check.
    pub fn initial_state(&self, tau0: &Matrix3<T>) -> Option<MaterialState<T>> {
        let p = -tau0.trace() / T::cst(3.0);
        if p.re().is_nan() || p.re() <= 0.0 {
            return None;
        }
        let dev = tau0 + Matrix3::identity() * p;
        let q2 = dev.component_mul(&dev).sum() * T::cst(1.5);
        let p_c = match self.preconsolidation {
            Preconsolidation::Pressure(p_c) => p_c,
            Preconsolidation::Ratio(r) => {
                r * (p + q2 / (self.critical_state_slope * self.critical_state_slope * p))
            }
        };
        Some(MaterialState {
            plastic_strain: T::zero(),
            tensor: symmetric_fn(&(self.elastic_strain(tau0) * T::cst(2.0)), &Exp),
            hardening: p_c,
        })
    }

    /// The elastic Hencky strain of a Kirchhoff stress `τ` with `p = −tr τ/3 > 0`:
    /// `εₑ = −ε_v/3 I + dev τ / (2G)`, `ε_v = κ̃ ln(p/p_r)`.
    pub fn elastic_strain(&self, tau: &Matrix3<T>) -> Matrix3<T> {
        let p = -tau.trace() / T::cst(3.0);
        let dev = tau + Matrix3::identity() * p;
        Matrix3::identity() * (-self.volumetric_strain(p) / T::cst(3.0))
            + dev / (self.shear_modulus(p) * T::cst(2.0))
    }

    /// The explicit stress update: `σ = τ / det F` with `τ` from
    /// [`ModifiedCamClay::return_map`] on `kin.delta_f`; commits the new state and returns the
    /// region taken.
    pub fn update_region(
        &self,
        kin: &Kinematics<'_, T>,
        state: &mut MaterialState<T>,
    ) -> (Matrix3<T>, Region) {
        let (tau, new_state, region) = self.return_map(kin.delta_f, state);
        *state = new_state;
        (tau / det::<T, 3>(kin.f), region)
    }

    /// Elastic stored energy per unit reference volume, `κ̃ p + (3/2) G ε_s²` with
    /// `εₑ = ½ ln bₑ` (the energy of the hyperelastic law for a constant `G₀`; with `G` from
    /// `ν` the same expression at the current `G`, an indicator only).
    pub fn stored_energy(&self, state: &MaterialState<T>) -> T {
        let eps = symmetric_fn(&state.tensor, &Log) * T::cst(0.5);
        let eps_v = -eps.trace();
        let dev = eps + Matrix3::identity() * (eps_v / T::cst(3.0));
        let p = self.pressure(eps_v);
        let eps_s2 = dev.component_mul(&dev).sum() * T::cst(2.0 / 3.0);
        self.kappa_log() * p + self.shear_modulus(p) * eps_s2 * T::cst(1.5)
    }
}

/// The real parts of the trial invariants.
fn trial_re<T: Scalar>(trial: (T, T)) -> (f64, f64) {
    (trial.0.re(), trial.1.re())
}

impl ModifiedCamClay<f64> {
    /// The elastic constrained modulus `K + 4G/3` at mean effective stress `p`, with the
    /// tangent bulk modulus `K = dp/dε_v = p/κ̃` and `G` at `p`.
    pub fn p_wave_modulus_at(&self, p: f64) -> f64 {
        p / self.kappa_log() + self.shear_modulus(p) * 4.0 / 3.0
    }

    /// The same parameters as constants of another scalar type (zero derivative parts).
    pub fn lift<T: Scalar>(&self) -> ModifiedCamClay<T> {
        ModifiedCamClay {
            lambda: T::cst(self.lambda),
            kappa: T::cst(self.kappa),
            critical_state_slope: T::cst(self.critical_state_slope),
            void_ratio: T::cst(self.void_ratio),
            shear: match self.shear {
                Shear::Modulus(g) => Shear::Modulus(T::cst(g)),
                Shear::Poisson(nu) => Shear::Poisson(T::cst(nu)),
            },
            preconsolidation: match self.preconsolidation {
                Preconsolidation::Pressure(p) => Preconsolidation::Pressure(T::cst(p)),
                Preconsolidation::Ratio(r) => Preconsolidation::Ratio(T::cst(r)),
            },
        }
    }

    /// `∂R/∂(ε_v, z)` at a real point, by one evaluation with two dual lanes.
    fn residual_jacobian(&self, x: [f64; 2], trial: (f64, f64), p_cn: f64) -> [[f64; 2]; 2] {
        let lanes: [DualSVec64<2>; 2] = std::array::from_fn(|k| {
            let mut e = SVector::<f64, 2>::zeros();
            e[k] = 1.0;
            DualSVec64::new(x[k], Derivative::some(e))
        });
        let model = self.lift::<DualSVec64<2>>();
        let trial = (DualSVec64::from_re(trial.0), DualSVec64::from_re(trial.1));
        let r = model.residual(lanes, trial, DualSVec64::from_re(p_cn));
        std::array::from_fn(|i| std::array::from_fn(|k| r[i].eps.0.as_ref().map_or(0.0, |e| e[k])))
    }

    /// The root `(ε_v, z)` of the return's residuals, by Newton's method with a backtracking
    /// line search on `‖R‖²`, from `x0`. Stops at `‖R‖ ≤ 1e-14` (both residuals are strains,
    /// so this is round-off of the unit), or when a step no longer reduces `‖R‖`.
    fn solve_return(&self, x0: [f64; 2], trial: (f64, f64), p_cn: f64) -> [f64; 2] {
        let norm = |r: [f64; 2]| r[0].hypot(r[1]);
        let mut x = x0;
        let mut r = self.residual(x, trial, p_cn);
        for _ in 0..MAX_LOCAL_ITERATIONS {
            if norm(r) <= 1e-14 {
                break;
            }
            let j = self.residual_jacobian(x, trial, p_cn);
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            let dx = [
                -(r[0] * j[1][1] - r[1] * j[0][1]) / det,
                -(r[1] * j[0][0] - r[0] * j[1][0]) / det,
            ];
            let mut step = 1.0;
            let mut accepted = false;
            for _ in 0..30 {
                let trial_x = [x[0] + step * dx[0], x[1] + step * dx[1]];
                let trial_r = self.residual(trial_x, trial, p_cn);
                if trial_r.iter().all(|v| v.is_finite()) && norm(trial_r) < norm(r) {
                    x = trial_x;
                    r = trial_r;
                    accepted = true;
                    break;
                }
                step *= 0.5;
            }
            if !accepted {
                break;
            }
        }
        x
    }
}

/// The elastic strain `εₑ = ½ ln bₑ` of a point in `state`, its volumetric part
/// `ε_v = −tr εₑ` (compression positive) and the mean effective stress `p = p_r exp(ε_v/κ̃)`.
fn elastic_point<T: Scalar>(
    model: &ModifiedCamClay<T>,
    state: &MaterialState<T>,
) -> (Matrix3<T>, T, T) {
    let eps = symmetric_fn(&state.tensor, &Log) * T::cst(0.5);
    let eps_v = -eps.trace();
    (eps, eps_v, model.pressure(eps_v))
}

impl<T: Scalar> ModifiedCamClay<T> {
    /// The elastic shear modulus `G(p)` of a point in `state`, at its mean effective stress
    /// `p = p_r exp(ε_v/κ̃)` (in the scalar type, so that its derivative by the constants and
    /// the history is available).
    pub fn shear_modulus_in(&self, state: &MaterialState<T>) -> T {
        let (_, _, p) = elastic_point(self, state);
        self.shear_modulus(p)
    }
}

impl<T: Scalar> Constitutive<T> for ModifiedCamClay<T> {
    /// `σ = τ / det F` with `τ` from [`ModifiedCamClay::return_map`]; commits the new state.
    fn update(&self, kin: &Kinematics<'_, T>, state: &mut MaterialState<T>) -> Matrix3<T> {
        self.update_region(kin, state).0
    }

    /// The constrained modulus `K + 4G/3` at the reference pressure scale of 1 MPa (the
    /// stiffness grows with `p`: the explicit solver takes each particle's own,
    /// [`Constitutive::p_wave_modulus_in`]).
    fn p_wave_modulus(&self) -> f64 {
        self.real().p_wave_modulus_at(1.0e6)
    }

    /// A bound on the elastic stiffness of the state, for the explicit time step:
    /// `K + 4G/3 + 2 |dG/dε_v| ‖dev εₑ‖` at the mean effective stress `p = p_r exp(ε_v/κ̃)`,
    /// `εₑ = ½ ln bₑ`, `ε_v = −tr εₑ` (compression positive). The law
    /// `τ = −p I + 2G(p) dev εₑ` has the tangent `K 1⊗1 + 2G I_dev − 2 (dG/dε_v) dev εₑ ⊗ 1`;
    /// the last term (with `G` from ν, `dG/dε_v = G/κ̃`) is zero at an isotropic state but grows
    /// with the elastic distortion, which a heavily overconsolidated point (`p_c ≫ p`) can
    /// carry.
    fn p_wave_modulus_in(&self, state: &MaterialState<T>) -> f64 {
        let real = self.real();
        let (eps, eps_v, p) = elastic_point(&real, &state.map(|x| x.re()));
        let distortion = (eps + Matrix3::identity() * (eps_v / 3.0)).norm();
        let coupling = match real.shear {
            Shear::Modulus(_) => 0.0,
            Shear::Poisson(_) => real.shear_modulus(p) / real.kappa_log(),
        };
        real.p_wave_modulus_at(p) + 2.0 * coupling * distortion
    }

    fn stiffness_depends_on_state(&self) -> bool {
        true
    }
}
