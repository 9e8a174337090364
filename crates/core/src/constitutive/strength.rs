//! Strength reduction: a material with its shear strength divided by a factor `F`, the
//! parameter change behind the factor of safety of a slope by strength reduction
//! (Zienkiewicz, Humpheson & Lewis 1975; Griffiths & Lane 1999, *Géotechnique* 49(3)).
//!
//! - [`MohrCoulomb`] and [`DruckerPrager`]: `c_F = c / F` and `tan φ_F = tan φ / F`, so the
//!   strength on any plane, `τ_f = c + σ′_n tan φ` (compression positive), becomes `τ_f / F`.
//!   The dilation angle follows the same rule, `tan ψ_F = tan ψ / F`: associated flow stays
//!   associated, `ψ = 0` stays `0`, and `ψ_F ≤ φ_F` whenever `ψ ≤ φ`. The apex of the yield
//!   surface, `c cot φ`, is unchanged by the reduction, so a Drucker–Prager tension cutoff
//!   (at or below the apex) is kept as it is.
//! - [`J2`]: the undrained strength `c_u = σ_y / √3` and the hardening modulus are divided by
//!   `F` (`σ_y + H ε̄ᵖ` becomes `(σ_y + H ε̄ᵖ) / F`).
//! - The elastic models and the fluid have no strength to reduce.
//! - [`ModifiedCamClay`](super::ModifiedCamClay) has no strength in this sense either: its
//!   shear strength is not a material constant `c + σ′_n tan φ` but follows from the state
//!   (`q_f = M p′` at critical state, reached at a `p′` set by the preconsolidation pressure
//!   and the drainage), so there is no `c` or `φ` to divide. Reductions of `M` alone have
//!   been used, but no rule is established that gives the factor of safety of the classical
//!   definition, so the reduction is not defined for it.
//!
//! The elastic constants are unchanged: the factor of safety is a property of the strength
//! alone, and the elastic state only sets how the loads are carried before failure.

use super::{DruckerPrager, J2, Material, Model, MohrCoulomb};
use crate::scalar::Scalar;

/// `atan(tan θ / F)`: an angle whose tangent is divided by `F`.
fn reduced_angle<T: Scalar>(angle: T, factor: T) -> T {
    (angle.tan() / factor).atan()
}

impl<T: Scalar> Material<T> {
    /// The material with its shear strength divided by `factor` (`F > 0`; see the module docs
    /// for each model's rule): `τ_f = c + σ′_n tan φ` becomes `τ_f / F` for Mohr–Coulomb and
    /// Drucker–Prager, `σ_y + H ε̄ᵖ` becomes `(σ_y + H ε̄ᵖ) / F` for J2. `None` for a model
    /// without a strength to reduce: the elastic models, the fluid and Modified Cam-Clay
    /// (whose strength comes from its state, not from a `c` and a `φ`). `F = 1` gives the
    /// material back.
    pub fn strength_reduced(&self, factor: T) -> Option<Self> {
        let model = match &self.model {
            Model::MohrCoulomb(m) => Model::MohrCoulomb(MohrCoulomb {
                friction_angle: reduced_angle(m.friction_angle, factor),
                dilation_angle: reduced_angle(m.dilation_angle, factor),
                cohesion: m.cohesion / factor,
                ..*m
            }),
            Model::DruckerPrager(m) => Model::DruckerPrager(DruckerPrager {
                friction_angle: reduced_angle(m.friction_angle, factor),
                dilation_angle: reduced_angle(m.dilation_angle, factor),
                cohesion: m.cohesion / factor,
                ..*m
            }),
            Model::J2(m) => Model::J2(J2 {
                yield_stress: m.yield_stress / factor,
                hardening: m.hardening / factor,
                ..*m
            }),
            Model::LinearElastic(_)
            | Model::NeoHookean(_)
            | Model::Hencky(_)
            | Model::Fluid(_)
            | Model::ModifiedCamClay(_) => return None,
        };
        Some(Self {
            density: self.density,
            model,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ModelKind;
    use crate::constitutive::{
        Lame, MaterialState, ModifiedCamClay, Preconsolidation, Region, Shear,
    };
    use nalgebra::Matrix3;

    fn mohr_coulomb(phi_deg: f64, psi_deg: f64, cohesion: f64) -> Material<f64> {
        Material {
            density: 2000.0,
            model: Model::MohrCoulomb(MohrCoulomb {
                lame: Lame::from_young_poisson(1.0e8, 0.3),
                friction_angle: phi_deg.to_radians(),
                dilation_angle: psi_deg.to_radians(),
                cohesion,
                tension_cutoff: None,
            }),
        }
    }

    /// A returned stress of the reduced Mohr–Coulomb material lies on the reduced envelope:
    /// its Mohr circle (centre `s`, radius `t`, compression-positive) touches the line
    /// `τ = (c + σ tan φ) / F`, i.e. the distance `(c + s tan φ)/F · cos φ_F` from the centre
    /// to the line equals `t`, for trial states loaded far beyond yield (main plane and both
    /// edges), and the original material is not yet at failure there.
    #[test]
    fn a_reduced_mohr_coulomb_material_fails_on_the_divided_envelope() {
        let (phi, c) = (20f64.to_radians(), 10e3);
        let original = mohr_coulomb(20.0, 0.0, c);
        for factor in [1.0, 1.4, 2.5] {
            let reduced = original.strength_reduced(factor).expect("has a strength");
            let Model::MohrCoulomb(m) = reduced.model else {
                panic!("the model changed")
            };
            let Model::MohrCoulomb(m0) = original.model else {
                panic!("not Mohr–Coulomb")
            };
            // Start at rest at 100 kPa isotropic compression, then compress one axis and
            // stretch or compress the others (main plane, compression and extension edges).
            let k = m.lame.lambda + 2.0 / 3.0 * m.lame.mu;
            let state = MaterialState {
                plastic_strain: 0.0,
                tensor: Matrix3::identity() * (-2.0 * 100e3 / (3.0 * k)).exp(),
                hardening: 0.0,
            };
            let mut regions = Vec::new();
            for df in [
                Matrix3::from_diagonal(&nalgebra::vector![1.002, 0.999, 0.996]),
                Matrix3::from_diagonal(&nalgebra::vector![1.002, 1.002, 0.996]),
                Matrix3::from_diagonal(&nalgebra::vector![1.004, 0.998, 0.998]),
            ] {
                let (tau, _, region) = m.return_map(&df, &state);
                regions.push(region);
                let (mut l, _) = crate::spectral::symmetric_eigen(&tau);
                l.sort_by(f64::total_cmp);
                // Compression positive: σ₁ = −l[0] (major), σ₃ = −l[2] (minor).
                let (s1, s3) = (-l[0], -l[2]);
                let (centre, radius) = ((s1 + s3) / 2.0, (s1 - s3) / 2.0);
                let distance = |phi: f64, c: f64| (c + centre * phi.tan()) * phi.cos();
                let reduced_distance = distance(m.friction_angle, m.cohesion);
                // Round-off of the closed-form return and the eigenvalues: 1e-9 of the stress.
                assert!(
                    (reduced_distance - radius).abs() <= 1e-9 * s1.abs(),
                    "F = {factor}, {region:?}: circle radius {radius} vs distance to the \
                     reduced envelope {reduced_distance}"
                );
                // The reduced envelope is the original one divided by F, at every σ.
                for sigma in [0.0, 50e3, 300e3] {
                    let reduced_tau = m.cohesion + sigma * m.friction_angle.tan();
                    let tau_f = c + sigma * phi.tan();
                    assert!((reduced_tau * factor - tau_f).abs() <= 1e-9 * tau_f);
                }
                if factor > 1.0 {
                    assert!(distance(m0.friction_angle, m0.cohesion) > radius);
                }
            }
            assert_eq!(regions, [Region::Shear, Region::Edge, Region::Edge]);
            assert_eq!(m.dilation_angle, 0.0, "ψ = 0 stays 0");
        }
    }

    #[test]
    fn every_strength_is_divided_and_associated_flow_stays_associated() {
        let f = 1.7;
        let mc = mohr_coulomb(30.0, 30.0, 10e3)
            .strength_reduced(f)
            .expect("MC");
        let Model::MohrCoulomb(m) = mc.model else {
            panic!("MC")
        };
        assert!((m.friction_angle.tan() - 30f64.to_radians().tan() / f).abs() < 1e-15);
        assert_eq!(m.dilation_angle, m.friction_angle);
        assert!((m.cohesion - 10e3 / f).abs() < 1e-9);
        assert_eq!(mc.density, 2000.0);

        let dp = Material::drucker_prager(1e7, 0.3, 0.6, 0.2, 5e3, Some(1e3), 1800.0);
        let Model::DruckerPrager(d0) = dp.model else {
            panic!("DP")
        };
        let Some(Material {
            model: Model::DruckerPrager(d),
            ..
        }) = dp.strength_reduced(f)
        else {
            panic!("DP keeps its model")
        };
        assert!((d.friction_angle.tan() - 0.6f64.tan() / f).abs() < 1e-15);
        assert!((d.dilation_angle.tan() - 0.2f64.tan() / f).abs() < 1e-15);
        assert!((d.cohesion - 5e3 / f).abs() < 1e-9);
        // The apex c cot φ does not move, so the cutoff below it is kept.
        assert!((d.apex() - d0.apex()).abs() < 1e-9 * d0.apex());
        assert_eq!(d.tension_cutoff, Some(1e3));
        assert_eq!(
            (d.lame, d.cone, d.elasticity),
            (d0.lame, d0.cone, d0.elasticity)
        );

        let j2 = Material::j2(1e7, 0.3, 3e4, 1e5, 1.0);
        let Some(Material {
            model: Model::J2(j),
            ..
        }) = j2.strength_reduced(f)
        else {
            panic!("J2 keeps its model")
        };
        assert!((j.yield_stress - 3e4 / f).abs() < 1e-9 && (j.hardening - 1e5 / f).abs() < 1e-9);

        for kind in [
            ModelKind::LinearElastic,
            ModelKind::NeoHookean,
            ModelKind::Hencky,
        ] {
            assert_eq!(
                Material::elastic(kind, 1e7, 0.3, 1.0).strength_reduced(f),
                None
            );
        }
        assert_eq!(
            Material::fluid(2e6, 7.0, 0.0, 1000.0).strength_reduced(f),
            None
        );
        // Modified Cam-Clay: its strength comes from its state, not from a c and a φ.
        let clay = Material {
            density: 1800.0,
            model: Model::ModifiedCamClay(ModifiedCamClay {
                lambda: 0.2,
                kappa: 0.04,
                critical_state_slope: 1.0,
                void_ratio: 1.0,
                shear: Shear::Poisson(0.3),
                preconsolidation: Preconsolidation::Ratio(1.0),
            }),
        };
        assert_eq!(clay.strength_reduced(f), None);
        // F = 1 gives the material back.
        let same = mohr_coulomb(25.0, 5.0, 3e3);
        let back = same.strength_reduced(1.0).expect("MC");
        let (Model::MohrCoulomb(a), Model::MohrCoulomb(b)) = (&same.model, &back.model) else {
            panic!("MC")
        };
        assert!((a.friction_angle - b.friction_angle).abs() < 1e-15);
        assert!((a.dilation_angle - b.dilation_angle).abs() < 1e-15);
        assert_eq!(a.cohesion, b.cohesion);
    }
}
