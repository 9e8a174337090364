//! `loam bench tangent`: the cost of the consistent tangent of one material point, per model,
//! against Hencky's.
//!
//! The tangent the implicit solver assembles for a particle is `∂τ/∂ΔF` of the model's local
//! update, `τ(ΔF, F, state)`, from forward-mode duals: in 3D either nine passes of
//! [`Material::kirchhoff_update`] with one entry of `ΔF` seeded as a `Dual64`, or one pass
//! with all nine seeded in a `DualSVec64<9>`, as [`loam_implicit::system::tangent_in_one_pass`]
//! picks per model (`loam_implicit::StepSystem::tangent_local`). This bench times both for
//! one point, `evaluations` times, for each model at a state where its return mapping
//! runs: the point starts at rest under an isotropic effective stress of 200 kPa (the state
//! [`Material::prestressed_state`] gives) and is compressed by 3 % along `z` while its
//! sides stretch by 1 % and 0.8 %, far enough past yield for every plastic model (Hencky is
//! elastic, the reference). The figure is the time per point and its ratio to Hencky's.

use loam_core::constitutive::{
    Cone, DruckerPrager, Elasticity, Hencky, J2, Lame, Material, MaterialState, Model,
    ModifiedCamClay, MohrCoulomb, Preconsolidation, Shear,
};
use nalgebra::Matrix3;
use num_dual::{Derivative, Dual64, DualSVec64};
use std::time::Instant;

/// The isotropic effective stress the point starts from (Pa).
const P0: f64 = 200e3;

/// One model's figure.
pub struct TangentCost {
    /// `tangent/` and the model's scene name.
    pub name: &'static str,
    /// Wall time of all evaluations the way the solver takes them (s).
    pub wall: f64,
    /// Wall time of all evaluations the other way (s): one 9-lane pass where the solver
    /// takes nine passes, and the reverse.
    pub other: f64,
    /// Whether the solver takes this model's tangent in one 9-lane pass.
    pub one_pass: bool,
    /// Points whose tangent was evaluated.
    pub evaluations: usize,
    /// Whether the step was plastic (the return mapping ran).
    pub plastic: bool,
}

impl TangentCost {
    /// Microseconds per point.
    pub fn per_point_us(&self) -> f64 {
        1e6 * self.wall / self.evaluations as f64
    }

    /// Microseconds per point the other way ([`TangentCost::other`]).
    pub fn other_per_point_us(&self) -> f64 {
        1e6 * self.other / self.evaluations as f64
    }
}

/// The models timed, with E = 25 MPa, ν = 0.3 where they have them: Hencky, J2
/// (σ_y = 100 kPa), Drucker–Prager and Mohr–Coulomb (φ = 30°, ψ = 5°, c = 5 kPa) and
/// Modified Cam-Clay (λ = 0.2, κ = 0.04, M = 1, e₀ = 1, normally consolidated).
fn models() -> [(&'static str, Material<f64>); 5] {
    let lame = Lame::from_young_poisson(25e6, 0.3);
    let (phi, psi, c) = (30f64.to_radians(), 5f64.to_radians(), 5e3);
    let with = |model| Material {
        density: 2000.0,
        model,
    };
    [
        ("tangent/hencky", with(Model::Hencky(Hencky { lame }))),
        (
            "tangent/j2",
            with(Model::J2(J2 {
                lame,
                yield_stress: 100e3,
                hardening: 0.0,
            })),
        ),
        (
            "tangent/drucker_prager",
            with(Model::DruckerPrager(DruckerPrager {
                lame,
                friction_angle: phi,
                dilation_angle: psi,
                cohesion: c,
                tension_cutoff: None,
                cone: Cone::Compression,
                elasticity: Elasticity::Hencky,
            })),
        ),
        (
            "tangent/mohr_coulomb",
            with(Model::MohrCoulomb(MohrCoulomb {
                lame,
                friction_angle: phi,
                dilation_angle: psi,
                cohesion: c,
                tension_cutoff: None,
            })),
        ),
        (
            "tangent/modified_cam_clay",
            with(Model::ModifiedCamClay(ModifiedCamClay {
                lambda: 0.2,
                kappa: 0.04,
                critical_state_slope: 1.0,
                void_ratio: 1.0,
                shear: Shear::Poisson(0.3),
                preconsolidation: Preconsolidation::Ratio(1.0),
            })),
        ),
    ]
}

/// `∂τ/∂ΔF` by nine `Dual64` passes (entry `(c, d)` of `ΔF` seeded in pass `3c + d`), summed
/// into one number so that no pass can be optimised away.
fn tangent(
    material: &Material<Dual64>,
    delta_f: &Matrix3<f64>,
    f: &Matrix3<Dual64>,
    state: &MaterialState<Dual64>,
) -> f64 {
    let mut sum = 0.0;
    for c in 0..3 {
        for d in 0..3 {
            let seeded = Matrix3::from_fn(|i, j| {
                Dual64::new(delta_f[(i, j)], if (i, j) == (c, d) { 1.0 } else { 0.0 })
            });
            let (tau, _) = material.kirchhoff_update(&seeded, f, state);
            sum += tau.iter().map(|t| t.eps).sum::<f64>();
        }
    }
    sum
}

/// `∂τ/∂ΔF` in one pass with the nine entries of `ΔF` seeded in the lanes of a
/// `DualSVec64<9>` (lane `3c + d`), summed into one number as [`tangent`] does.
fn tangent_lanes(
    material: &Material<DualSVec64<9>>,
    delta_f: &Matrix3<f64>,
    f: &Matrix3<DualSVec64<9>>,
    state: &MaterialState<DualSVec64<9>>,
) -> f64 {
    let seeded = Matrix3::from_fn(|i, j| {
        let mut e = nalgebra::SVector::<f64, 9>::zeros();
        e[3 * i + j] = 1.0;
        DualSVec64::new(delta_f[(i, j)], Derivative::some(e))
    });
    let (tau, _) = material.kirchhoff_update(&seeded, f, state);
    tau.iter()
        .map(|t| t.eps.0.as_ref().map_or(0.0, |e| e.sum()))
        .sum()
}

/// Wall time of `evaluations` calls of `one` (s).
fn time(evaluations: usize, mut one: impl FnMut() -> f64) -> f64 {
    let start = Instant::now();
    let mut sink = 0.0;
    for _ in 0..evaluations {
        sink += one();
    }
    std::hint::black_box(sink);
    start.elapsed().as_secs_f64()
}

/// Times the tangent of every model over `evaluations` points, both ways.
pub fn measure(evaluations: usize) -> Vec<TangentCost> {
    let delta_f = Matrix3::from_diagonal(&nalgebra::vector![1.01, 1.008, 0.97]);
    let tau0 = Matrix3::identity() * -P0;
    models()
        .into_iter()
        .map(|(name, material)| {
            let state = material.prestressed_state(&tau0).unwrap_or_default();
            let (_, end) = material.kirchhoff_update(&delta_f, &delta_f, &state);
            let plastic = end.plastic_strain > state.plastic_strain;
            let dual = material.lift::<Dual64>();
            let (f, s1) = (delta_f.map(Dual64::from_re), state.lift::<Dual64>());
            let nine = time(evaluations, || {
                tangent(&dual, std::hint::black_box(&delta_f), &f, &s1)
            });
            let wide = material.lift::<DualSVec64<9>>();
            let (f, s9) = (delta_f.map(DualSVec64::from_re), state.lift());
            let lanes = time(evaluations, || {
                tangent_lanes(&wide, std::hint::black_box(&delta_f), &f, &s9)
            });
            let one_pass = loam_implicit::system::tangent_in_one_pass(&material);
            let (wall, other) = if one_pass {
                (lanes, nine)
            } else {
                (nine, lanes)
            };
            TangentCost {
                name,
                wall,
                other,
                one_pass,
                evaluations,
                plastic,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every plastic model is timed on a plastic step (else the figure would be an elastic
    /// update's), and Hencky, the reference, is elastic.
    #[test]
    fn every_plastic_model_is_timed_past_yield() {
        for cost in measure(1) {
            assert_eq!(cost.plastic, cost.name != "tangent/hencky", "{}", cost.name);
        }
    }

    /// The one-pass tangent is the nine-pass one: the 9-lane dual carries in lane `3c + d`
    /// what the single-lane pass `(c, d)` carries, for every model past yield (summed, to
    /// round-off of the sums, 1e-12 relative).
    #[test]
    fn one_pass_and_nine_passes_give_the_same_tangent() {
        let delta_f = Matrix3::from_diagonal(&nalgebra::vector![1.01, 1.008, 0.97]);
        for (name, material) in models() {
            let state = material
                .prestressed_state(&(Matrix3::identity() * -P0))
                .unwrap_or_default();
            let nine = tangent(
                &material.lift(),
                &delta_f,
                &delta_f.map(Dual64::from_re),
                &state.lift(),
            );
            let one = tangent_lanes(
                &material.lift(),
                &delta_f,
                &delta_f.map(DualSVec64::from_re),
                &state.lift(),
            );
            assert!(
                (one - nine).abs() <= 1e-12 * nine.abs(),
                "{name}: {one} vs {nine}"
            );
        }
    }
}
