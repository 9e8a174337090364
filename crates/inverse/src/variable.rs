//! Reparameterisations: the variable `z` an optimiser moves and the physical value `θ(z)` it
//! stands for, with optional bounds.

use serde::{Deserialize, Serialize};

/// How the physical value follows from the optimiser's variable.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Transform {
    /// `θ = s z`.
    #[default]
    Identity,
    /// `θ = s softplus(z) = s ln(1 + eᶻ)`: `θ > 0` for every `z` (a friction coefficient
    /// `μ ≥ 0`); `dθ/dz = s / (1 + e⁻ᶻ)`.
    Softplus,
}

/// `softplus(z) = ln(1 + eᶻ)`, evaluated as `max(z, 0) + ln(1 + e^(−|z|))` so that it neither
/// overflows nor loses `z` for large `|z|`.
pub fn softplus(z: f64) -> f64 {
    z.max(0.0) + (-z.abs()).exp().ln_1p()
}

/// The inverse of [`softplus`] for `y > 0`: `z = y + ln(1 − e⁻ʸ)`.
pub fn softplus_inverse(y: f64) -> f64 {
    let y = y.max(f64::MIN_POSITIVE);
    y + (-(-y).exp_m1()).ln()
}

/// The logistic function `σ(z) = 1 / (1 + e⁻ᶻ)`, the derivative of [`softplus`].
fn logistic(z: f64) -> f64 {
    1.0 / (1.0 + (-z).exp())
}

/// One unknown as an optimiser sees it: `θ = s z` or `θ = s softplus(z)` ([`Transform`]),
/// kept in `[lo, hi]` by projection when bounds are given.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Variable {
    /// The reparameterisation.
    pub transform: Transform,
    /// The scale `s > 0` (the typical size of `θ`, so that every `z` is of order one).
    pub scale: f64,
    /// Bounds `[lo, hi]` on `θ`.
    pub bounds: Option<(f64, f64)>,
}

impl Variable {
    /// `θ(z)`.
    pub fn physical(&self, z: f64) -> f64 {
        self.scale
            * match self.transform {
                Transform::Identity => z,
                Transform::Softplus => softplus(z),
            }
    }

    /// `z(θ)`, the inverse of [`Variable::physical`] (a softplus variable needs `θ > 0`;
    /// smaller values map to the `z` of the smallest positive number).
    pub fn internal(&self, theta: f64) -> f64 {
        let y = theta / self.scale;
        match self.transform {
            Transform::Identity => y,
            Transform::Softplus => softplus_inverse(y),
        }
    }

    /// `dθ/dz` at `z`, by which `dL/dz = dL/dθ · dθ/dz`.
    pub fn slope(&self, z: f64) -> f64 {
        self.scale
            * match self.transform {
                Transform::Identity => 1.0,
                Transform::Softplus => logistic(z),
            }
    }

    /// `z` moved so that `θ(z)` lies within the bounds: `z(clamp(θ(z), lo, hi))`.
    pub fn project(&self, z: f64) -> f64 {
        match self.bounds {
            Some((lo, hi)) => {
                let theta = self.physical(z);
                if theta < lo || theta > hi {
                    self.internal(theta.clamp(lo, hi))
                } else {
                    z
                }
            }
            None => z,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn softplus_of_the_reference_start_and_its_inverse() {
        // JAX-MPM starts every friction coefficient from softplus(0.2) = ln(1 + e^0.2).
        assert!((softplus(0.2) - 0.798_138_869_381_592_2).abs() < 1e-15);
        for y in [1e-8, 0.01, 0.798, 3.0, 50.0] {
            let z = softplus_inverse(y);
            assert!((softplus(z) - y).abs() <= 1e-14 * y.max(1.0), "{y}");
        }
        // No overflow far out: softplus(z) = z to round-off for large z, e^z for very negative z.
        assert_eq!(softplus(800.0), 800.0);
        assert!((softplus(-40.0) - (-40.0f64).exp()).abs() < 1e-30);
    }

    #[test]
    fn slope_is_the_derivative_and_projection_respects_bounds() {
        let v = Variable {
            transform: Transform::Softplus,
            scale: 2.0,
            bounds: Some((0.1, 1.0)),
        };
        for z in [-3.0, -0.5, 0.2, 2.0] {
            // Central difference of a smooth function, h = 1e-5: error O(h²) ≈ 1e-10.
            let h = 1e-5;
            let fd = (v.physical(z + h) - v.physical(z - h)) / (2.0 * h);
            assert!((fd - v.slope(z)).abs() < 1e-9, "{z}");
        }
        assert!((v.physical(v.project(5.0)) - 1.0).abs() < 1e-14);
        assert!((v.physical(v.project(-20.0)) - 0.1).abs() < 1e-14);
        assert_eq!(v.project(-0.5), -0.5);
    }
}
