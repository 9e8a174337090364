//! Mandel's problem: the analytical (series) solution in plane strain.
//!
//! A poroelastic specimen `|x| ≤ a`, `|y| ≤ b` lies between two rigid, frictionless,
//! impermeable plates at `y = ±b`; its lateral faces `x = ±a` are traction-free and drained
//! (`p = 0`). A compressive force is applied to the plates suddenly at `t = 0` and held. The
//! specimen first responds undrained, with a uniform pore pressure `p₀`; as the edges drain
//! they soften, the still-undrained core takes more of the load, and the pressure at the centre
//! first *rises* above `p₀` (the Mandel–Cryer effect) before it decays to zero.
//!
//! Conventions: the pore pressure `p` is positive in compression; stresses are tension-positive
//! (`σ_yy < 0` under the load); displacements are positive along `+x` and `+y` (`u_y < 0` on
//! the top plate). `F` (N per metre run) is the compressive force on the *half* plate
//! `0 ≤ x ≤ a`, the force a quarter-symmetry model carries: the full plate carries `2F` and the
//! mean vertical stress is `−F/a`. Time `t < 0` is before the load (everything zero); `t = 0` is
//! the undrained state just after it.
//!
//! The solution (Mandel 1953; Cheng & Detournay 1988; Abousleiman et al. 1996; Verruijt,
//! *Theory and problems of poroelasticity*, ch. Mandel's problem), with `ξ = x/a`,
//! `T = c t/a²`, the roots `α_k` of `tan α = ((1 − ν)/(ν_u − ν)) α`,
//! `D_k = α_k − sin α_k cos α_k` and `E_k = exp(−α_k² T)`:
//!
//! ```text
//! p    = 2 p₀ Σ (sin α_k / D_k) (cos α_k ξ − cos α_k) E_k
//! u_x  = (F/(G a)) [ (ν/2 − ν_u Σ (sin α_k cos α_k / D_k) E_k) x + a Σ (cos α_k / D_k) sin α_k ξ E_k ]
//! u_y  = (F/(G a)) [ −(1 − ν)/2 + (1 − ν_u) Σ (sin α_k cos α_k / D_k) E_k ] y
//! σ_yy = −(F/a) [ 1 + 2 ((ν_u − ν)/(1 − ν)) Σ (sin α_k / D_k) cos α_k ξ E_k − 2 Σ (sin α_k cos α_k / D_k) E_k ]
//! σ_xx = σ_xy = 0
//! ```
//!
//! Derivation in brief: with `σ_xx = 0`, a uniform `ε_yy = ε(t)` (rigid plates), `λ = K − 2G/3`
//! and `σ = 2G ε + λ tr(ε) I − α p I`, the fluid balance `∂(α ε_vol + p/M)/∂t = κ ∂²p/∂x²`
//! becomes `∂p/∂t = c ∂²p/∂x² − β ε'(t)`, and vertical equilibrium ties `ε(t)` to `∫ p dx`;
//! the separable solutions `(cos α ξ − cos α) exp(−α² T)` of that non-local diffusion
//! equation need `tan α = ((1 − ν)/(ν_u − ν)) α`.

use std::f64::consts::{FRAC_PI_2, PI};

/// Most terms any series sums (the root `α_10000 ≈ 31 400`; below `T ≈ 4e-8` the series is
/// truncated there rather than converged).
const MAX_TERMS: usize = 10_000;
/// A term is dropped, and the series stopped, once its decay `exp(−α_k² T)` is below this: the
/// coefficients are at most ~1/α_k < 1, so the neglected tail is below ~1e-15 of the sum.
const NEGLIGIBLE: f64 = 1e-16;

/// Mandel's problem: a material and a load (see the [module docs](self)).
///
/// Valid input: `K > 0`, `G > 0`, `0 < α ≤ 1`, `M > 0` (or `f64::INFINITY`), `κ > 0`, `a > 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mandel {
    /// Drained bulk modulus `K` of the skeleton (Pa).
    pub bulk_modulus: f64,
    /// Shear modulus `G` (Pa).
    pub shear_modulus: f64,
    /// Biot coefficient `α` (-).
    pub biot_coefficient: f64,
    /// Biot modulus `M` (Pa); `f64::INFINITY` for incompressible constituents.
    pub biot_modulus: f64,
    /// Mobility `κ = k/γ_w` (m²/(Pa·s)).
    pub mobility: f64,
    /// Half-width `a` of the specimen (m).
    pub half_width: f64,
    /// Compressive force `F` on the half plate `0 ≤ x ≤ a` (N/m); the full plate carries `2F`.
    pub force: f64,
}

impl Mandel {
    /// Undrained bulk modulus (Pa); `∞` when `M = ∞`.
    ///
    /// ```text
    /// K_u = K + α² M
    /// ```
    pub fn undrained_bulk_modulus(&self) -> f64 {
        let alpha = self.biot_coefficient;
        if alpha == 0.0 {
            return self.bulk_modulus;
        }
        self.bulk_modulus + alpha * alpha * self.biot_modulus
    }

    /// Skempton's coefficient `B` (-); `1/α` when `M = ∞`.
    ///
    /// ```text
    /// B = α M / (K + α² M) = α / (α² + K/M)
    /// ```
    pub fn skempton(&self) -> f64 {
        let alpha = self.biot_coefficient;
        alpha / (alpha * alpha + self.bulk_modulus / self.biot_modulus)
    }

    /// Drained Poisson's ratio `ν` (-).
    ///
    /// ```text
    /// ν = (3K − 2G) / (2 (3K + G))
    /// ```
    pub fn poisson(&self) -> f64 {
        let (k, g) = (self.bulk_modulus, self.shear_modulus);
        (3.0 * k - 2.0 * g) / (2.0 * (3.0 * k + g))
    }

    /// Undrained Poisson's ratio `ν_u` (-); `1/2` when `M = ∞`.
    ///
    /// ```text
    /// ν_u = (3K_u − 2G) / (2 (3K_u + G)) = (3 − 2 G/K_u) / (2 (3 + G/K_u))
    /// ```
    pub fn undrained_poisson(&self) -> f64 {
        let r = self.shear_modulus / self.undrained_bulk_modulus();
        (3.0 - 2.0 * r) / (2.0 * (3.0 + r))
    }

    /// Consolidation coefficient `c` of Mandel's problem (m²/s): the plane-strain (oedometric)
    /// one, `κ (λ + 2G) = κ (K + 4G/3)` for incompressible constituents (`α = 1`, `M = ∞`).
    ///
    /// ```text
    /// c = κ / (α²/(K + 4G/3) + 1/M)
    ///   = 2 κ B² G (1 − ν)(1 + ν_u)² / (9 (1 − ν_u)(ν_u − ν))
    /// ```
    pub fn consolidation_coefficient(&self) -> f64 {
        let alpha = self.biot_coefficient;
        let oedometric = self.bulk_modulus + 4.0 * self.shear_modulus / 3.0;
        self.mobility * oedometric / (alpha * alpha + oedometric / self.biot_modulus)
    }

    /// Time factor `T` (-) at time `t` (s).
    ///
    /// ```text
    /// T = c t / a²
    /// ```
    pub fn time_factor(&self, t: f64) -> f64 {
        self.consolidation_coefficient() * t / (self.half_width * self.half_width)
    }

    /// Time `t` (s) at time factor `T` (-), the inverse of [`Mandel::time_factor`].
    ///
    /// ```text
    /// t = T a² / c
    /// ```
    pub fn time(&self, tv: f64) -> f64 {
        tv * self.half_width * self.half_width / self.consolidation_coefficient()
    }

    /// Uniform undrained pore pressure `p₀` just after loading (Pa): `−B` times the mean of
    /// `σ_xx = 0`, `σ_yy = −F/a` and `σ_zz = ν_u σ_yy`.
    ///
    /// ```text
    /// p₀ = B (1 + ν_u) F / (3a)
    /// ```
    pub fn initial_pressure(&self) -> f64 {
        self.skempton() * (1.0 + self.undrained_poisson()) * self.force / (3.0 * self.half_width)
    }

    /// The first `n` positive roots `α_k` (k = 1 … n) of the characteristic equation; `α_k`
    /// lies in `((k − 1)π, (k − 1)π + π/2)`, computed to machine precision.
    ///
    /// ```text
    /// tan α = ((1 − ν)/(ν_u − ν)) α,   (1 − ν)/(ν_u − ν) = (3K + 4G)(3 + (3K + G)/(α²M)) / (9G)
    /// ```
    pub fn roots(&self, n: usize) -> Vec<f64> {
        let factor = self.root_factor();
        (0..n).map(|k| root(factor, k)).collect()
    }

    /// Pore pressure `p(x, t)` (Pa, positive in compression), for `|x| ≤ a`; the series above,
    /// and at `t = 0` the undrained `p₀` (0 on the drained faces `|x| = a`).
    ///
    /// ```text
    /// p = 2 p₀ Σ (sin α_k / D_k) (cos α_k ξ − cos α_k) E_k
    /// ```
    pub fn pressure(&self, x: f64, t: f64) -> f64 {
        let xi = x / self.half_width;
        let series = if t < 0.0 {
            0.0
        } else if t == 0.0 {
            if xi.abs() < 1.0 { 0.5 } else { 0.0 }
        } else {
            self.sum(t, |r, s, c| s * ((r * xi).cos() - c))
        };
        2.0 * self.initial_pressure() * series
    }

    /// Horizontal displacement `u_x(x, t)` (m, along `+x`), for `|x| ≤ a`; at `t = 0` the
    /// undrained `F ν_u x/(2 G a)`.
    ///
    /// ```text
    /// u_x = (F/(G a)) [ (ν/2 − ν_u Σ (sin α_k cos α_k / D_k) E_k) x + a Σ (cos α_k / D_k) sin α_k ξ E_k ]
    /// ```
    pub fn displacement_x(&self, x: f64, t: f64) -> f64 {
        let (a, scale) = (self.half_width, self.force / self.shear_modulus);
        if t < 0.0 {
            return 0.0;
        }
        if t == 0.0 {
            return scale * self.undrained_poisson() * x / (2.0 * a);
        }
        let xi = x / a;
        let uniform = self.sum(t, |_, s, c| s * c);
        let wave = self.sum(t, |r, _, c| c * (r * xi).sin());
        scale * ((self.poisson() / 2.0 - self.undrained_poisson() * uniform) * xi + wave)
    }

    /// Vertical displacement `u_y(y, t)` (m, along `+y`; negative on the top plate `y = b`
    /// under compression); at `t = 0` the undrained `−F (1 − ν_u) y/(2 G a)`, as `t → ∞` the
    /// drained `−F (1 − ν) y/(2 G a)`.
    ///
    /// ```text
    /// u_y = (F/(G a)) [ −(1 − ν)/2 + (1 − ν_u) Σ (sin α_k cos α_k / D_k) E_k ] y
    /// ```
    pub fn displacement_y(&self, y: f64, t: f64) -> f64 {
        let nu_u = self.undrained_poisson();
        let bracket = if t < 0.0 {
            0.0
        } else if t == 0.0 {
            -(1.0 - nu_u) / 2.0
        } else {
            -(1.0 - self.poisson()) / 2.0 + (1.0 - nu_u) * self.sum(t, |_, s, c| s * c)
        };
        self.force / (self.shear_modulus * self.half_width) * bracket * y
    }

    /// Vertical total stress `σ_yy(x, t)` (Pa, tension-positive), for `|x| ≤ a`; at `t = 0`
    /// the uniform `−F/a`.
    ///
    /// ```text
    /// σ_yy = −(F/a) [ 1 + 2 ((ν_u − ν)/(1 − ν)) Σ (sin α_k / D_k) cos α_k ξ E_k − 2 Σ (sin α_k cos α_k / D_k) E_k ]
    /// ```
    pub fn stress_yy(&self, x: f64, t: f64) -> f64 {
        let a = self.half_width;
        if t < 0.0 {
            return 0.0;
        }
        let bracket = if t == 0.0 {
            1.0
        } else {
            let xi = x / a;
            let inverse_factor = 1.0 / self.root_factor();
            1.0 + 2.0 * self.sum(t, |r, s, c| s * (inverse_factor * (r * xi).cos() - c))
        };
        -self.force / a * bracket
    }

    /// The Mandel–Cryer peak of the pressure at the centre: `(T*, p(0, T*)/p₀)`, the time factor
    /// at which `p(0, t)/p₀` is largest and that largest value (> 1), by golden-section search
    /// on `T ∈ [1e-4, 1]`.
    ///
    /// ```text
    /// T* = argmax_T p(0, T)/p₀,   p(0, T)/p₀ = 2 Σ (sin α_k / D_k) (1 − cos α_k) E_k
    /// ```
    pub fn centre_peak(&self) -> (f64, f64) {
        let ratio = |tv: f64| 2.0 * self.sum_at(tv, |_, s, c| s * (1.0 - c));
        let ratio_gold = (5f64.sqrt() - 1.0) / 2.0;
        let (mut lo, mut hi) = (1e-4, 1.0);
        let mut left = hi - ratio_gold * (hi - lo);
        let mut right = lo + ratio_gold * (hi - lo);
        let (mut f_left, mut f_right) = (ratio(left), ratio(right));
        while hi - lo > 1e-10 {
            if f_left > f_right {
                hi = right;
                (right, f_right) = (left, f_left);
                left = hi - ratio_gold * (hi - lo);
                f_left = ratio(left);
            } else {
                lo = left;
                (left, f_left) = (right, f_right);
                right = lo + ratio_gold * (hi - lo);
                f_right = ratio(right);
            }
        }
        let tv = (lo + hi) / 2.0;
        (tv, ratio(tv))
    }

    /// `(1 − ν)/(ν_u − ν)`, written without the difference `ν_u − ν` and finite for `M = ∞`.
    fn root_factor(&self) -> f64 {
        let (k, g, alpha) = (self.bulk_modulus, self.shear_modulus, self.biot_coefficient);
        (3.0 * k + 4.0 * g) * (3.0 + (3.0 * k + g) / (alpha * alpha * self.biot_modulus))
            / (9.0 * g)
    }

    /// `Σ_k term(α_k, sin α_k, cos α_k) E_k / D_k` at time `t > 0`.
    fn sum(&self, t: f64, term: impl Fn(f64, f64, f64) -> f64) -> f64 {
        self.sum_at(self.time_factor(t), term)
    }

    /// `Σ_k term(α_k, sin α_k, cos α_k) E_k / D_k` at time factor `T > 0`, until `E_k` is
    /// negligible (or [`MAX_TERMS`] terms).
    fn sum_at(&self, tv: f64, term: impl Fn(f64, f64, f64) -> f64) -> f64 {
        let factor = self.root_factor();
        let mut total = 0.0;
        for k in 0..MAX_TERMS {
            let r = root(factor, k);
            let decay = (-r * r * tv).exp();
            if decay < NEGLIGIBLE {
                break;
            }
            let (s, c) = r.sin_cos();
            total += term(r, s, c) * decay / (r - s * c);
        }
        total
    }
}

/// The root of `tan α = factor · α` in `(kπ, kπ + π/2)` (k = 0, 1, …; `factor > 1`).
///
/// On that interval the equation is `h(α) = α − kπ − atan(factor · α) = 0`, where `h` is convex
/// (`h'' > 0` for `α > 0`), positive at `kπ + π/2`, and increasing from the root to there.
/// Newton's method from `kπ + π/2` therefore decreases monotonically onto the root; it stops
/// when rounding ends the decrease.
fn root(factor: f64, k: usize) -> f64 {
    let shift = k as f64 * PI;
    let mut alpha = shift + FRAC_PI_2;
    for _ in 0..100 {
        let fa = factor * alpha;
        let h = alpha - shift - fa.atan();
        let slope = 1.0 - factor / (1.0 + fa * fa);
        let next = alpha - h / slope;
        // Stops when the decrease ends (a step ≤ 0 or below an ulp) or on a NaN.
        if next.is_nan() || next >= alpha {
            break;
        }
        alpha = next;
    }
    alpha
}

#[cfg(test)]
#[path = "mandel_series_tests.rs"]
mod tests;
