//! Element tests: one material point driven through a path of mixed strain and stress
//! control, with the solver's own constitutive kernels.
//!
//! The point carries a deformation gradient `F` (3×3, from the start of the test) and the
//! model's history. Each of the nine components of the path is controlled either
//! kinematically (the value of `F_ij`) or statically (the Cauchy stress `σ_ij`, tension
//! positive, Pa). A stage moves every target from its value at the start of the stage to its
//! end value over a number of increments: stresses and shear components of `F` linearly, the
//! diagonal stretches geometrically (their logarithmic strains linearly, so that an isochoric
//! stage stays isochoric within it). In each increment the `F_ij` of the
//! statically controlled components are the unknowns of a small Newton solve,
//!
//! `r_k(F) = σ_k(F) − σ_k* = 0`, `σ(F) = τ(ΔF, Fⁿ, historyⁿ) / det F`, `ΔF = F Fⁿ⁻¹`,
//!
//! with the Jacobian `∂σ_k/∂F_l` from one dual-number evaluation of the model per unknown (the
//! consistent tangent, exact also at the repeated principal stresses of a triaxial test), and a
//! backtracking line search. The increment is then committed: `Fⁿ ← F`, `historyⁿ ← history`.
//!
//! Drained triaxial compression, for instance, prescribes `F_zz` (axial, decreasing), holds
//! `σ_xx = σ_yy = −σ_c` and the shear components of `F` at zero; undrained (isochoric) triaxial
//! prescribes `F_xx = F_yy = F_zz^(−½)`; an oedometer prescribes `F_xx = F_yy = 1`.

use loam_core::constitutive::{Material, MaterialState};
use loam_core::tensor::{det, inverse};
use nalgebra::Matrix3;
use num_dual::Dual64;
use thiserror::Error;

/// What one component of the path prescribes at the end of a stage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Target {
    /// The deformation-gradient component `F_ij` (from the start of the test).
    Stretch(f64),
    /// The Cauchy stress component `σ_ij` (Pa, tension positive).
    Stress(f64),
}

/// One stage of a path: the nine targets at its end (row `i`, column `j`; a stress target
/// off the diagonal controls the symmetric pair `σ_ij = σ_ji` through `F_ij`), reached in
/// `increments` equal increments.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage {
    /// The targets at the end of the stage.
    pub targets: [[Target; 3]; 3],
    /// Number of increments (at least 1).
    pub increments: usize,
}

/// The state of the material point after an increment.
#[derive(Clone, Debug, PartialEq)]
pub struct PointState {
    /// Deformation gradient from the start of the test.
    pub f: Matrix3<f64>,
    /// Cauchy stress (Pa, tension positive).
    pub stress: Matrix3<f64>,
    /// The model's history.
    pub history: MaterialState<f64>,
}

/// Why an element test stopped.
#[derive(Debug, Error, PartialEq)]
pub enum ElementError {
    /// The stress targets could not be met in an increment.
    #[error(
        "stage {stage}, increment {increment}: the stress targets were not met after \
         {iterations} Newton iterations (residual {residual:.3e} Pa); the material cannot carry \
         the prescribed stress (beyond its strength?) or the increment is too large"
    )]
    NotConverged {
        /// Stage (from 0).
        stage: usize,
        /// Increment within the stage (from 1).
        increment: usize,
        /// Iterations taken.
        iterations: usize,
        /// Largest stress residual left (Pa).
        residual: f64,
    },
    /// The deformation gradient became singular or inverted.
    #[error("stage {stage}, increment {increment}: det F ≤ 0 (the point was inverted)")]
    Inverted {
        /// Stage (from 0).
        stage: usize,
        /// Increment within the stage (from 1).
        increment: usize,
    },
}

/// The Cauchy stress and new history of a trial `F` from the committed state.
fn response<T: loam_core::Scalar>(
    material: &Material<T>,
    f: &Matrix3<T>,
    f_n_inv: &Matrix3<T>,
    history: &MaterialState<T>,
) -> Option<(Matrix3<T>, MaterialState<T>)> {
    let j = det::<T, 3>(f);
    if j.re() <= 0.0 {
        return None;
    }
    let delta_f = f * f_n_inv;
    let (tau, state) = material.kirchhoff_update(&delta_f, f, history);
    Some((tau / j, state))
}

/// The value of a kinematically controlled `F_ij` a fraction `s` of the way through a stage
/// from `from` to `to`: geometric, `from^(1−s) to^s`, for a diagonal stretch whose ends are
/// both positive (the logarithmic strain `ln F_ii` moves linearly, so a path whose ends
/// keep `F_xx F_yy F_zz = 1`, an undrained triaxial stage, is isochoric at every increment),
/// linear otherwise (shear components, which may change sign).
fn stretch_between(from: f64, to: f64, s: f64, diagonal: bool) -> f64 {
    if diagonal && from > 0.0 && to > 0.0 {
        from * (to / from).powf(s)
    } else {
        from + s * (to - from)
    }
}

/// Newton iterations allowed per increment.
const MAX_ITERATIONS: usize = 60;

/// Runs the path from `start` (`F`, stress and history at the start of the test; the stress
/// must be the one the history stands for) and returns the state after every increment, the
/// start first.
pub fn run(
    material: &Material<f64>,
    start: PointState,
    stages: &[Stage],
) -> Result<Vec<PointState>, ElementError> {
    let dual = material.lift::<Dual64>();
    let mut states = vec![start];
    for (stage_index, stage) in stages.iter().enumerate() {
        let first = states.last().expect("start").clone();
        let unknowns: Vec<(usize, usize)> = (0..9)
            .map(|k| (k / 3, k % 3))
            .filter(|&(i, j)| matches!(stage.targets[i][j], Target::Stress(_)))
            .collect();
        let increments = stage.increments.max(1);
        for increment in 1..=increments {
            let s = increment as f64 / increments as f64;
            let prev = states.last().expect("start").clone();
            let f_n_inv = inverse::<f64, 3>(&prev.f).ok_or(ElementError::Inverted {
                stage: stage_index,
                increment,
            })?;
            // Kinematic targets interpolated; unknown components start from the last state.
            let mut f = prev.f;
            let mut goal = Vec::with_capacity(unknowns.len());
            for i in 0..3 {
                for j in 0..3 {
                    match stage.targets[i][j] {
                        Target::Stretch(x) => {
                            f[(i, j)] = stretch_between(first.f[(i, j)], x, s, i == j)
                        }
                        Target::Stress(x) => {
                            goal.push(first.stress[(i, j)] + s * (x - first.stress[(i, j)]))
                        }
                    }
                }
            }
            let residual =
                |f: &Matrix3<f64>| -> Option<(Vec<f64>, Matrix3<f64>, MaterialState<f64>)> {
                    let (stress, history) = response(material, f, &f_n_inv, &prev.history)?;
                    let r = unknowns
                        .iter()
                        .zip(&goal)
                        .map(|(&(i, j), g)| stress[(i, j)] - g)
                        .collect();
                    Some((r, stress, history))
                };
            let norm = |r: &[f64]| r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let (mut r, mut stress, mut history) = residual(&f).ok_or(ElementError::Inverted {
                stage: stage_index,
                increment,
            })?;
            let scale = goal
                .iter()
                .chain(prev.stress.iter())
                .fold(1.0f64, |m, x| m.max(x.abs()));
            // Round-off of the stress update is ~1e-15 of its scale; 1e-10 leaves room for
            // the conditioning of the mixed control.
            let tolerance = 1e-10 * scale;
            let mut iterations = 0;
            while norm(&r) > tolerance {
                if iterations == MAX_ITERATIONS {
                    return Err(ElementError::NotConverged {
                        stage: stage_index,
                        increment,
                        iterations,
                        residual: norm(&r),
                    });
                }
                iterations += 1;
                let n = unknowns.len();
                let mut jac = nalgebra::DMatrix::<f64>::zeros(n, n);
                let fd = f.map(Dual64::from_re);
                let f_n_inv_d = f_n_inv.map(Dual64::from_re);
                let hist_d = prev.history.lift::<Dual64>();
                for (col, &(a, b)) in unknowns.iter().enumerate() {
                    let mut seeded = fd;
                    seeded[(a, b)].eps = 1.0;
                    let (sd, _) = response(&dual, &seeded, &f_n_inv_d, &hist_d).ok_or(
                        ElementError::Inverted {
                            stage: stage_index,
                            increment,
                        },
                    )?;
                    for (row, &(i, j)) in unknowns.iter().enumerate() {
                        jac[(row, col)] = sd[(i, j)].eps;
                    }
                }
                let rhs = nalgebra::DVector::from_column_slice(&r);
                // The minimum-norm solution: on an edge of Mohr–Coulomb (and at other
                // non-smooth points) the stress does not fix how the plastic strain splits
                // between the components of the edge, so the Jacobian is singular there; the
                // pseudo-inverse keeps the split symmetric.
                let svd = jac.svd(true, true);
                let cut = 1e-10 * svd.singular_values.max();
                let Ok(step) = svd.solve(&rhs, cut) else {
                    return Err(ElementError::NotConverged {
                        stage: stage_index,
                        increment,
                        iterations,
                        residual: norm(&r),
                    });
                };
                // Backtracking: halve the step until the residual falls (or 20 halvings).
                let mut alpha = 1.0;
                let current = norm(&r);
                loop {
                    let mut trial = f;
                    for (k, &(a, b)) in unknowns.iter().enumerate() {
                        trial[(a, b)] -= alpha * step[k];
                    }
                    if let Some((rt, st, ht)) = residual(&trial)
                        && (norm(&rt) < current || alpha < 1e-6)
                    {
                        (f, r, stress, history) = (trial, rt, st, ht);
                        break;
                    }
                    alpha *= 0.5;
                    if alpha < 1e-6 {
                        return Err(ElementError::NotConverged {
                            stage: stage_index,
                            increment,
                            iterations,
                            residual: current,
                        });
                    }
                }
            }
            states.push(PointState { f, stress, history });
        }
    }
    Ok(states)
}

/// Soil-mechanics measures of a point state, compression positive: the mean effective stress
/// `p′ = −tr σ/3`, the deviator stress `q = σ′_a − σ′_r = σ_r − σ_a` with the axial direction
/// `z` and the radial stress `σ_r = ½(σ_xx + σ_yy)` (positive in triaxial compression,
/// negative in extension), the axial strain `ε_a = 1 − F_zz` and the volumetric strain
/// `ε_v = 1 − det F` (both as the change over the original length or volume).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoilMeasures {
    /// Mean effective stress `p′` (Pa, compression positive).
    pub p: f64,
    /// Deviator stress `q = σ′_a − σ′_r` (Pa).
    pub q: f64,
    /// Axial strain `ε_a = 1 − F_zz` (compression positive).
    pub axial_strain: f64,
    /// Volumetric strain `ε_v = 1 − det F` (compression positive).
    pub volumetric_strain: f64,
    /// `√(3 J₂)` of the stress (Pa, non-negative).
    pub von_mises: f64,
}

impl PointState {
    /// The soil-mechanics measures of the state ([`SoilMeasures`]).
    pub fn measures(&self) -> SoilMeasures {
        let s = &self.stress;
        let p = -s.trace() / 3.0;
        let dev = s + Matrix3::identity() * p;
        SoilMeasures {
            p,
            q: 0.5 * (s[(0, 0)] + s[(1, 1)]) - s[(2, 2)],
            axial_strain: 1.0 - self.f[(2, 2)],
            volumetric_strain: 1.0 - det::<f64, 3>(&self.f),
            von_mises: (1.5 * dev.norm_squared()).sqrt(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use loam_core::constitutive::{Cone, DruckerPrager, Elasticity, Lame, Model, MohrCoulomb};

    fn triaxial(confining: f64, axial: f64, increments: usize) -> Stage {
        use Target::{Stress, Stretch};
        Stage {
            targets: [
                [Stress(-confining), Stretch(0.0), Stretch(0.0)],
                [Stretch(0.0), Stress(-confining), Stretch(0.0)],
                [Stretch(0.0), Stretch(0.0), Stretch(1.0 - axial)],
            ],
            increments,
        }
    }

    fn start(material: &Material<f64>, p0: f64) -> PointState {
        let stress = Matrix3::identity() * -p0;
        PointState {
            f: Matrix3::identity(),
            stress,
            history: material
                .prestressed_state(&stress)
                .expect("model with history"),
        }
    }

    /// Drained triaxial compression of cohesionless Drucker–Prager (compression cone) reaches
    /// `q_f = 3 M p₀ / (3 − M)`, `M = 6 sin φ/(3 − sin φ)`, and holds the confining stress.
    /// The yield condition is on the Kirchhoff stress, which with `c = 0` is the Cauchy
    /// condition scaled by `J` (a cone through the origin), so the plateau is exact: 1e-9.
    #[test]
    fn drained_triaxial_reaches_the_drucker_prager_peak() {
        let phi: f64 = 35f64.to_radians();
        let material = Material {
            density: 2000.0,
            model: Model::DruckerPrager(DruckerPrager {
                lame: Lame::from_young_poisson(25e6, 0.3),
                friction_angle: phi,
                dilation_angle: 5f64.to_radians(),
                cohesion: 0.0,
                tension_cutoff: None,
                cone: Cone::Compression,
                elasticity: Elasticity::Hencky,
            }),
        };
        let p0 = 150e3;
        let states = run(&material, start(&material, p0), &[triaxial(p0, 0.1, 100)]).unwrap();
        let m = 6.0 * phi.sin() / (3.0 - phi.sin());
        let q_f = 3.0 * m * p0 / (3.0 - m);
        let last = states.last().unwrap();
        let q = last.measures().q;
        assert!((q - q_f).abs() < 1e-9 * q_f, "q = {q}, closed form {q_f}");
        assert!((last.stress[(0, 0)] + p0).abs() < 1e-9 * p0);
        // Dilatant flow (ψ > 0): the sample expands at the end.
        let dv = last.measures().volumetric_strain
            - states[states.len() - 2].measures().volumetric_strain;
        assert!(dv < 0.0, "ε_v increment {dv}");
    }

    /// Mohr–Coulomb drained triaxial compression and extension with `c = 0` end at
    /// `σ′₁/σ′₃ = (1 + sin φ)/(1 − sin φ)` (1e-9, the plateau of a perfectly plastic model).
    #[test]
    fn drained_triaxial_reaches_the_mohr_coulomb_ratio() {
        let phi: f64 = 30f64.to_radians();
        let material = Material {
            density: 2000.0,
            model: Model::MohrCoulomb(MohrCoulomb {
                lame: Lame::from_young_poisson(25e6, 0.3),
                friction_angle: phi,
                dilation_angle: 0.0,
                cohesion: 0.0,
            }),
        };
        let ratio = (1.0 + phi.sin()) / (1.0 - phi.sin());
        let p0 = 100e3;
        for axial in [0.05, -0.05] {
            let states = run(&material, start(&material, p0), &[triaxial(p0, axial, 50)]).unwrap();
            let s = states.last().unwrap().stress;
            let (major, minor) = if axial > 0.0 {
                (s[(2, 2)], s[(0, 0)])
            } else {
                (s[(0, 0)], s[(2, 2)])
            };
            let r = major / minor;
            assert!(
                (r - ratio).abs() < 1e-9 * ratio,
                "axial {axial}: ratio {r} vs {ratio}"
            );
        }
    }

    /// A stress target beyond the strength is reported, not looped on.
    #[test]
    fn an_impossible_stress_target_is_reported() {
        use Target::{Stress, Stretch};
        let material = Material {
            density: 2000.0,
            model: Model::MohrCoulomb(MohrCoulomb {
                lame: Lame::from_young_poisson(25e6, 0.3),
                friction_angle: 30f64.to_radians(),
                dilation_angle: 0.0,
                cohesion: 0.0,
            }),
        };
        // Axial stress raised to 5 × the confining: beyond the ratio 3 of φ = 30°.
        let stage = Stage {
            targets: [
                [Stress(-100e3), Stretch(0.0), Stretch(0.0)],
                [Stretch(0.0), Stress(-100e3), Stretch(0.0)],
                [Stretch(0.0), Stretch(0.0), Stress(-500e3)],
            ],
            increments: 20,
        };
        let err = run(&material, start(&material, 100e3), &[stage]).unwrap_err();
        assert!(matches!(err, ElementError::NotConverged { .. }), "{err}");
    }

    /// An undrained (isochoric) triaxial stage of many increments keeps `det F = 1` at every
    /// increment, not only at its end, and its axial stretch falls monotonically to the
    /// target. The stretches are products of `exp` of linear log strains: round-off 1e-14.
    #[test]
    fn an_undrained_stage_is_isochoric_at_every_increment() {
        use Target::Stretch;
        let material = Material {
            density: 2000.0,
            model: Model::MohrCoulomb(MohrCoulomb {
                lame: Lame::from_young_poisson(25e6, 0.3),
                friction_angle: 30f64.to_radians(),
                dilation_angle: 0.0,
                cohesion: 20e3,
            }),
        };
        let fz = 0.9f64;
        let lateral = fz.powf(-0.5);
        let stage = Stage {
            targets: [
                [Stretch(lateral), Stretch(0.0), Stretch(0.0)],
                [Stretch(0.0), Stretch(lateral), Stretch(0.0)],
                [Stretch(0.0), Stretch(0.0), Stretch(fz)],
            ],
            increments: 10,
        };
        let states = run(&material, start(&material, 100e3), &[stage]).unwrap();
        assert_eq!(states.len(), 11);
        for pair in states.windows(2) {
            assert!(pair[1].f[(2, 2)] < pair[0].f[(2, 2)]);
        }
        for s in &states {
            let j = s.f.determinant();
            assert!((j - 1.0).abs() < 1e-14, "det F = {j}");
        }
        assert!((states[10].f[(2, 2)] - fz).abs() < 1e-15);
    }
}
