//! Element tests: one material point driven through a path of mixed strain and stress
//! control, with the solvers' own constitutive kernels.
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
//! prescribes `F_xx = F_yy = F_zz^(−½)`; an oedometer prescribes `F_xx = F_yy = 1`
//! ([`Loading`] builds these targets from the state at the start of a stage).
//!
//! **Sensitivities.** [`run_carrying`] runs the same path with the material, the start state
//! and the targets in a dual scalar `T` (derivatives with respect to material constants, say).
//! Newton iterates on the real parts only, as [`run`] does. At the converged increment the
//! residual `r(F_u, θ) = σ_u(F_u; F_p(θ), Fⁿ(θ), historyⁿ(θ), θ) − σ*(θ)` (the prescribed
//! components `F_p` and the targets `σ*` carry derivatives from the state at the start of the
//! stage) vanishes for every `θ`, so `∂F_u/∂θ = −J⁻¹ ∂r/∂θ` (the implicit-function theorem,
//! `J = ∂σ_u/∂F_u`). One Newton step on the derivative parts alone gives it:
//!
//! `Ḟ_u ← Ḟ_u − J⁺ ṙ`,
//!
//! with `ṙ` the derivative part of `r` evaluated in `T` at the converged real `F_u` (linear in
//! `Ḟ_u`, so it vanishes after the step) and `J⁺` the pseudo-inverse Newton steps with (where
//! `J` is singular, at a Mohr–Coulomb edge, the derivative of the minimum-norm split). The
//! response is then evaluated once more in `T` for the dual stress and history of the
//! increment. The real parts are those of [`run`]; nothing differentiates the iteration.

use loam_core::Scalar;
use loam_core::constitutive::{Material, MaterialState};
use loam_core::tensor::{det, inverse};
use nalgebra::{DMatrix, DVector, Matrix3};
use num_dual::Dual64;
use thiserror::Error;

/// What one component of the path prescribes at the end of a stage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Target<T = f64> {
    /// The deformation-gradient component `F_ij` (from the start of the test).
    Stretch(T),
    /// The Cauchy stress component `σ_ij` (Pa, tension positive).
    Stress(T),
}

/// One stage of a path: the nine targets at its end (row `i`, column `j`; a stress target
/// off the diagonal controls the symmetric pair `σ_ij = σ_ji` through `F_ij`), reached in
/// `increments` equal increments.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage<T = f64> {
    /// The targets at the end of the stage.
    pub targets: [[Target<T>; 3]; 3],
    /// Number of increments (at least 1).
    pub increments: usize,
}

/// A laboratory loading, stated as a soil-mechanics test states it (compression positive,
/// axial direction `z`); [`Loading::stage`] turns it into the targets of a [`Stage`] from the
/// state at the start of the stage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Loading {
    /// Drained triaxial: `ε_a = 1 − F_zz` changes by `axial_strain`, the radial stresses
    /// `σ_xx`, `σ_yy` are held at their values at the start of the stage.
    DrainedTriaxial {
        /// Change of `ε_a` over the stage (negative: extension or unloading).
        axial_strain: f64,
    },
    /// Undrained (isochoric) triaxial: `F_zz` as for [`Loading::DrainedTriaxial`], and
    /// `F_xx`, `F_yy` scaled by `√(F_zz,start/F_zz)` so that the volume is kept.
    UndrainedTriaxial {
        /// Change of `ε_a` over the stage.
        axial_strain: f64,
    },
    /// Oedometer: `F_zz` as above, the lateral components of `F` held.
    Oedometer {
        /// Change of `ε_a` over the stage.
        axial_strain: f64,
    },
    /// Isotropic: the three normal stresses moved to `−p`.
    Isotropic {
        /// The mean effective stress at the end of the stage (Pa, compression positive).
        p: f64,
    },
    /// Simple shear in the `x`–`z` plane: `F_xz` grows by `shear_strain`; `F_zz` is held
    /// unless `vertical_stress` is given, which then holds `σ_zz = −vertical_stress`.
    SimpleShear {
        /// Change of `γ = F_xz` over the stage.
        shear_strain: f64,
        /// The vertical effective stress held (Pa, compression positive).
        vertical_stress: Option<f64>,
    },
}

impl Loading {
    /// The stage of `increments` increments that applies this loading from the state at its
    /// start (`f`, `stress`): every component not named above keeps its `F_ij` (so the shear
    /// components of a triaxial test stay at zero). With dual `f` and `stress` the held
    /// values carry their derivatives.
    pub fn stage<T: Scalar>(
        &self,
        f: &Matrix3<T>,
        stress: &Matrix3<T>,
        increments: usize,
    ) -> Stage<T> {
        use Target::{Stress, Stretch};
        let mut targets = [[Stretch(T::zero()); 3]; 3];
        for (i, row) in targets.iter_mut().enumerate() {
            for (j, t) in row.iter_mut().enumerate() {
                *t = Stretch(f[(i, j)]);
            }
        }
        match *self {
            Self::DrainedTriaxial { axial_strain } => {
                targets[0][0] = Stress(stress[(0, 0)]);
                targets[1][1] = Stress(stress[(1, 1)]);
                targets[2][2] = Stretch(f[(2, 2)] - T::cst(axial_strain));
            }
            Self::UndrainedTriaxial { axial_strain } => {
                let fz = f[(2, 2)] - T::cst(axial_strain);
                let lateral = (f[(2, 2)] / fz).sqrt();
                targets[0][0] = Stretch(f[(0, 0)] * lateral);
                targets[1][1] = Stretch(f[(1, 1)] * lateral);
                targets[2][2] = Stretch(fz);
            }
            Self::Oedometer { axial_strain } => {
                targets[2][2] = Stretch(f[(2, 2)] - T::cst(axial_strain));
            }
            Self::Isotropic { p } => {
                for (a, row) in targets.iter_mut().enumerate() {
                    row[a] = Stress(T::cst(-p));
                }
            }
            Self::SimpleShear {
                shear_strain,
                vertical_stress,
            } => {
                targets[0][2] = Stretch(f[(0, 2)] + T::cst(shear_strain));
                if let Some(sv) = vertical_stress {
                    targets[2][2] = Stress(T::cst(-sv));
                }
            }
        }
        Stage {
            targets,
            increments,
        }
    }
}

/// One stage of a laboratory test: its loading and number of increments.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LabStage {
    /// What the stage does.
    pub loading: Loading,
    /// Equal increments of the stage (at least 1).
    pub increments: usize,
}

/// The state of the material point after an increment.
#[derive(Clone, Debug, PartialEq)]
pub struct PointState<T = f64> {
    /// Deformation gradient from the start of the test.
    pub f: Matrix3<T>,
    /// Cauchy stress (Pa, tension positive).
    pub stress: Matrix3<T>,
    /// The model's history.
    pub history: MaterialState<T>,
}

/// Why an element test stopped.
#[derive(Clone, Debug, Error, PartialEq)]
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

impl ElementError {
    /// The stage (from 0) that could not be completed.
    pub fn stage(&self) -> usize {
        match *self {
            Self::NotConverged { stage, .. } | Self::Inverted { stage, .. } => stage,
        }
    }
}

/// The Cauchy stress and new history of a trial `F` from the committed state.
fn response<T: Scalar>(
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
/// linear otherwise (shear components, which may change sign); with dual ends the value
/// carries their derivatives.
fn stretch_between<T: Scalar>(from: T, to: T, s: f64, diagonal: bool) -> T {
    if diagonal && from.re() > 0.0 && to.re() > 0.0 {
        from * (to / from).powf(T::cst(s))
    } else {
        from + (to - from) * T::cst(s)
    }
}

/// Newton iterations allowed per increment.
const MAX_ITERATIONS: usize = 60;

/// The relative cut of the singular values in the pseudo-inverse of the Jacobian (round-off
/// of a tangent assembled from dual evaluations is ~1e-15 of its largest entry).
const SINGULAR_CUT: f64 = 1e-10;

/// Runs the path from `start` (`F`, stress and history at the start of the test; the stress
/// must be the one the history stands for) and returns the state after every increment, the
/// start first.
pub fn run(
    material: &Material<f64>,
    start: PointState,
    stages: &[Stage],
) -> Result<Vec<PointState>, ElementError> {
    run_carrying(material, material, start, stages)
}

/// [`run`] in the scalar `T`: `material` is the material in `T` (dual parameters), `real` its
/// real parts, and `start` and the stages' targets may carry derivatives too. Newton runs on
/// the real parts, so the real parts of the states are [`run`]'s; each increment's derivative
/// parts come from one implicit-function step (module docs), exactly.
pub fn run_carrying<T: Scalar>(
    real: &Material<f64>,
    material: &Material<T>,
    start: PointState<T>,
    stages: &[Stage<T>],
) -> Result<Vec<PointState<T>>, ElementError> {
    let mut states = vec![start];
    for (index, stage) in stages.iter().enumerate() {
        run_stage(real, material, &mut states, stage, index)?;
    }
    Ok(states)
}

/// The states of a laboratory test ([`run_test`]): every state after the start, with the
/// stage it belongs to, and why the test stopped early, if it did.
#[derive(Clone, Debug)]
pub struct TestPath<T = f64> {
    /// The start, then the state after every increment.
    pub states: Vec<PointState<T>>,
    /// The stage (from 0) of each state (the start counts to stage 0).
    pub stage_of: Vec<usize>,
    /// The stage that could not be completed and why; the states up to it are kept.
    pub failure: Option<ElementError>,
}

/// Runs the stages of a laboratory test one after the other from `start`, each built by
/// [`Loading::stage`] from the state where the last one ended, in the scalar `T` as
/// [`run_carrying`] (`real` the real parts of `material`). A stage that fails ends the test;
/// its error names the stage by its index in `stages`.
pub fn run_test<T: Scalar>(
    real: &Material<f64>,
    material: &Material<T>,
    start: PointState<T>,
    stages: &[LabStage],
) -> TestPath<T> {
    let mut states = vec![start];
    let mut stage_of = vec![0];
    for (index, s) in stages.iter().enumerate() {
        let last = states.last().expect("the start");
        let stage = s.loading.stage(&last.f, &last.stress, s.increments);
        let result = run_stage(real, material, &mut states, &stage, index);
        stage_of.resize(states.len(), index);
        if let Err(e) = result {
            return TestPath {
                states,
                stage_of,
                failure: Some(e),
            };
        }
    }
    TestPath {
        states,
        stage_of,
        failure: None,
    }
}

/// The Jacobian `∂σ_u/∂F_u` of the stress components of `unknowns` with respect to the same
/// components of `F`, at the real `f`, by one `Dual64` evaluation per unknown; `None` when a
/// seeded `F` is inverted.
fn jacobian(
    dual: &Material<Dual64>,
    f: &Matrix3<f64>,
    f_n_inv: &Matrix3<f64>,
    history: &MaterialState<f64>,
    unknowns: &[(usize, usize)],
) -> Option<DMatrix<f64>> {
    let n = unknowns.len();
    let mut jac = DMatrix::<f64>::zeros(n, n);
    let fd = f.map(Dual64::from_re);
    let f_n_inv_d = f_n_inv.map(Dual64::from_re);
    let hist_d = history.lift::<Dual64>();
    for (col, &(a, b)) in unknowns.iter().enumerate() {
        let mut seeded = fd;
        seeded[(a, b)].eps = 1.0;
        let (sd, _) = response(dual, &seeded, &f_n_inv_d, &hist_d)?;
        for (row, &(i, j)) in unknowns.iter().enumerate() {
            jac[(row, col)] = sd[(i, j)].eps;
        }
    }
    Some(jac)
}

/// Runs one stage (number `index`, for the errors) from the last of `states`, pushing the
/// state after every increment.
fn run_stage<T: Scalar>(
    real: &Material<f64>,
    material: &Material<T>,
    states: &mut Vec<PointState<T>>,
    stage: &Stage<T>,
    index: usize,
) -> Result<(), ElementError> {
    let dual = real.lift::<Dual64>();
    let first = states.last().expect("start").clone();
    let unknowns: Vec<(usize, usize)> = (0..9)
        .map(|k| (k / 3, k % 3))
        .filter(|&(i, j)| matches!(stage.targets[i][j], Target::Stress(_)))
        .collect();
    let increments = stage.increments.max(1);
    for increment in 1..=increments {
        let inverted = ElementError::Inverted {
            stage: index,
            increment,
        };
        let s = increment as f64 / increments as f64;
        let prev = states.last().expect("start").clone();
        let f_n_inv = inverse::<T, 3>(&prev.f).ok_or(inverted.clone())?;
        let f_n_inv_re = f_n_inv.map(|x| x.re());
        let history_re = prev.history.map(|x| x.re());
        // Kinematic targets interpolated; unknown components start from the last state.
        let mut f = prev.f;
        let mut goal = Vec::with_capacity(unknowns.len());
        for i in 0..3 {
            for j in 0..3 {
                let start = first.f[(i, j)];
                match stage.targets[i][j] {
                    Target::Stretch(x) => f[(i, j)] = stretch_between(start, x, s, i == j),
                    Target::Stress(x) => {
                        let start = first.stress[(i, j)];
                        goal.push(start + (x - start) * T::cst(s));
                    }
                }
            }
        }
        // The residual in `T` at `f`, with the unknowns' derivative parts as they are.
        let residual = |f: &Matrix3<T>| -> Option<(Vec<T>, Matrix3<T>, MaterialState<T>)> {
            let (stress, history) = response(material, f, &f_n_inv, &prev.history)?;
            let r = unknowns
                .iter()
                .zip(&goal)
                .map(|(&(i, j), g)| stress[(i, j)] - *g)
                .collect();
            Some((r, stress, history))
        };
        let norm = |r: &[T]| r.iter().fold(0.0f64, |m, x| m.max(x.re().abs()));
        let (mut r, mut stress, mut history) = residual(&f).ok_or(inverted.clone())?;
        let scale = goal
            .iter()
            .map(|x| x.re())
            .chain(prev.stress.iter().map(|x| x.re()))
            .fold(1.0f64, |m, x| m.max(x.abs()));
        // Round-off of the stress update is ~1e-15 of its scale; 1e-10 leaves room for
        // the conditioning of the mixed control.
        let tolerance = 1e-10 * scale;
        let mut iterations = 0;
        let not_converged = |iterations, residual| ElementError::NotConverged {
            stage: index,
            increment,
            iterations,
            residual,
        };
        while norm(&r) > tolerance {
            if iterations == MAX_ITERATIONS {
                return Err(not_converged(iterations, norm(&r)));
            }
            iterations += 1;
            let f_re = f.map(|x| x.re());
            let jac = jacobian(&dual, &f_re, &f_n_inv_re, &history_re, &unknowns)
                .ok_or(inverted.clone())?;
            let rhs = DVector::from_iterator(r.len(), r.iter().map(|x| x.re()));
            // The minimum-norm solution: on an edge of Mohr–Coulomb (and at other
            // non-smooth points) the stress does not fix how the plastic strain splits
            // between the components of the edge, so the Jacobian is singular there; the
            // pseudo-inverse keeps the split symmetric.
            let svd = jac.svd(true, true);
            let cut = SINGULAR_CUT * svd.singular_values.max();
            let Ok(step) = svd.solve(&rhs, cut) else {
                return Err(not_converged(iterations, norm(&r)));
            };
            // Backtracking: halve the step until the residual falls (or 20 halvings).
            let mut alpha = 1.0;
            let current = norm(&r);
            loop {
                let mut trial = f;
                for (k, &(a, b)) in unknowns.iter().enumerate() {
                    trial[(a, b)] -= T::cst(alpha * step[k]);
                }
                if let Some((rt, st, ht)) = residual(&trial)
                    && (norm(&rt) < current || alpha < 1e-6)
                {
                    (f, r, stress, history) = (trial, rt, st, ht);
                    break;
                }
                alpha *= 0.5;
                if alpha < 1e-6 {
                    return Err(not_converged(iterations, current));
                }
            }
        }
        // The derivative parts of the unknowns: one Newton step on them alone,
        // Ḟ_u ← Ḟ_u − J⁺ ṙ (module docs). Nothing to do where the residual carries none
        // (always in `f64`).
        let dr: Vec<T> = r.iter().map(|x| *x - T::cst(x.re())).collect();
        if dr.iter().any(|x| !x.is_constant()) {
            let f_re = f.map(|x| x.re());
            let jac = jacobian(&dual, &f_re, &f_n_inv_re, &history_re, &unknowns)
                .ok_or(inverted.clone())?;
            let svd = jac.svd(true, true);
            let cut = SINGULAR_CUT * svd.singular_values.max();
            let pinv = svd
                .pseudo_inverse(cut)
                .map_err(|_| not_converged(iterations, norm(&r)))?;
            for (k, &(a, b)) in unknowns.iter().enumerate() {
                let df = (0..unknowns.len())
                    .fold(T::zero(), |acc, l| acc + dr[l] * T::cst(pinv[(k, l)]));
                f[(a, b)] -= df;
            }
            (_, stress, history) = residual(&f).ok_or(inverted.clone())?;
        }
        states.push(PointState { f, stress, history });
    }
    Ok(())
}

impl<T: Scalar> PointState<T> {
    /// The state at `F = I` that carries the Cauchy stress `stress` (Pa, tension positive; at
    /// `F = I` it is the Kirchhoff stress): the model's prestressed history
    /// ([`Material::prestressed_state`]), or the stress-free history for the models that
    /// carry no stress at `F = I` (for which `stress` must be zero). With dual parameters
    /// the history carries their derivatives.
    pub fn at_rest(material: &Material<T>, stress: &Matrix3<f64>) -> Self {
        let stress = stress.map(T::cst);
        PointState {
            f: Matrix3::identity(),
            history: material.prestressed_state(&stress).unwrap_or_default(),
            stress,
        }
    }

    /// The real parts of the state.
    pub fn real(&self) -> PointState<f64> {
        PointState {
            f: self.f.map(|x| x.re()),
            stress: self.stress.map(|x| x.re()),
            history: self.history.map(|x| x.re()),
        }
    }

    /// The soil-mechanics measures of the state ([`SoilMeasures`]), in `T`.
    pub fn measures(&self) -> SoilMeasures<T> {
        let s = &self.stress;
        let p = -s.trace() / T::cst(3.0);
        let dev = s + Matrix3::identity() * p;
        SoilMeasures {
            p,
            q: (s[(0, 0)] + s[(1, 1)]) * T::cst(0.5) - s[(2, 2)],
            axial_strain: T::one() - self.f[(2, 2)],
            volumetric_strain: T::one() - det::<T, 3>(&self.f),
            von_mises: (1.5 * dev.map(|x| x.re()).norm_squared()).sqrt(),
        }
    }
}

/// Soil-mechanics measures of a point state, compression positive: the mean effective stress
/// `p′ = −tr σ/3`, the deviator stress `q = σ′_a − σ′_r = σ_r − σ_a` with the axial direction
/// `z` and the radial stress `σ_r = ½(σ_xx + σ_yy)` (positive in triaxial compression,
/// negative in extension), the axial strain `ε_a = 1 − F_zz` and the volumetric strain
/// `ε_v = 1 − det F` (both as the change over the original length or volume).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoilMeasures<T = f64> {
    /// Mean effective stress `p′` (Pa, compression positive).
    pub p: T,
    /// Deviator stress `q = σ′_a − σ′_r` (Pa).
    pub q: T,
    /// Axial strain `ε_a = 1 − F_zz` (compression positive).
    pub axial_strain: T,
    /// Volumetric strain `ε_v = 1 − det F` (compression positive).
    pub volumetric_strain: T,
    /// `√(3 J₂)` of the stress (Pa, non-negative), of the real parts (its derivative is
    /// infinite at an isotropic state).
    pub von_mises: f64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use loam_core::constitutive::{
        Cone, DruckerPrager, Elasticity, Lame, Model, ModifiedCamClay, MohrCoulomb,
        Preconsolidation, Shear,
    };

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
        PointState::at_rest(material, &(Matrix3::identity() * -p0))
    }

    /// Normally consolidated Modified Cam-Clay, `theta` = (λ, κ, M), e₀ = 1, ν = 0.3.
    fn clay(theta: [f64; 3]) -> Material<f64> {
        Material {
            density: 1800.0,
            model: Model::ModifiedCamClay(ModifiedCamClay {
                lambda: theta[0],
                kappa: theta[1],
                critical_state_slope: theta[2],
                void_ratio: 1.0,
                shear: Shear::Poisson(0.3),
                preconsolidation: Preconsolidation::Ratio(1.0),
            }),
        }
    }

    /// Mohr–Coulomb, `theta` = (φ, c), `E` = 20 MPa, `ν` = 0.3, `ψ = 0`.
    fn sand(theta: [f64; 2]) -> Material<f64> {
        Material {
            density: 1900.0,
            model: Model::MohrCoulomb(MohrCoulomb {
                lame: Lame::from_young_poisson(20e6, 0.3),
                friction_angle: theta[0],
                dilation_angle: 0.0,
                cohesion: theta[1],
                tension_cutoff: None,
            }),
        }
    }

    /// `m` lifted to `Dual64` with a unit derivative on its `k`-th parameter (in the order of
    /// [`clay`]'s and [`sand`]'s `theta`).
    fn seeded(m: &Material<f64>, k: usize) -> Material<Dual64> {
        let mut dual = m.lift::<Dual64>();
        match (&mut dual.model, k) {
            (Model::ModifiedCamClay(c), 0) => c.lambda.eps = 1.0,
            (Model::ModifiedCamClay(c), 1) => c.kappa.eps = 1.0,
            (Model::ModifiedCamClay(c), 2) => c.critical_state_slope.eps = 1.0,
            (Model::MohrCoulomb(c), 0) => c.friction_angle.eps = 1.0,
            (Model::MohrCoulomb(c), 1) => c.cohesion.eps = 1.0,
            _ => unreachable!("no parameter {k}"),
        }
        dual
    }

    /// `q` at the end of the `stages` from the isotropic `p0`, with its derivative with
    /// respect to parameter `k` of `m`.
    fn end_q(m: &Material<f64>, k: usize, p0: f64, stages: &[LabStage]) -> Dual64 {
        let dual = seeded(m, k);
        let start = PointState::at_rest(&dual, &(Matrix3::identity() * -p0));
        let path = run_test(m, &dual, start, stages);
        assert_eq!(path.failure, None);
        path.states.last().unwrap().measures().q
    }

    /// The central difference of `end_q` along parameter `k` of `theta` with the relative
    /// step `h`.
    fn central<const N: usize>(
        material: impl Fn([f64; N]) -> Material<f64>,
        theta: [f64; N],
        k: usize,
        h: f64,
        p0: f64,
        stages: &[LabStage],
    ) -> f64 {
        let at = |d: f64| {
            let mut t = theta;
            t[k] += d;
            end_q(&material(t), k, p0, stages).re
        };
        let d = h * theta[k];
        (at(d) - at(-d)) / (2.0 * d)
    }

    /// The derivatives of a whole path carried by [`run_test`] agree with central differences
    /// of real runs: `q` at the end of an undrained test of normally consolidated Modified
    /// Cam-Clay (isotropic compression from 100 to 200 kPa, then 20 % axial strain) with
    /// respect to λ, κ and M, and at the end of a drained Mohr–Coulomb test (K0 = 1 from
    /// 100 kPa, 5 % axial strain, yielding on the compression edge, where the tangent is
    /// singular) with respect to φ and c. The differences use `h = 10⁻⁵ θ`: their truncation
    /// error is `O(h²)` ≈ 1e-10 relative, and the real runs converge each increment to the
    /// round-off of the stress (quadratic convergence below the 1e-10 tolerance), which the
    /// difference divides by `2h`: 1e-10 relative at most; 1e-6 bounds both with room. The
    /// perturbed runs stay on the branches of the reference (no increment changes between
    /// elastic and plastic within ±h).
    #[test]
    fn the_derivatives_of_a_path_agree_with_central_differences() {
        let undrained = [
            LabStage {
                loading: Loading::Isotropic { p: 200e3 },
                increments: 10,
            },
            LabStage {
                loading: Loading::UndrainedTriaxial { axial_strain: 0.2 },
                increments: 40,
            },
        ];
        let theta = [0.2, 0.04, 1.0];
        for k in 0..3 {
            let dual = end_q(&clay(theta), k, 100e3, &undrained).eps;
            let fd = central(clay, theta, k, 1e-5, 100e3, &undrained);
            assert!(
                (dual - fd).abs() <= 1e-6 * fd.abs(),
                "MCC parameter {k}: dual {dual:e}, central difference {fd:e}"
            );
        }
        let drained = [LabStage {
            loading: Loading::DrainedTriaxial { axial_strain: 0.05 },
            increments: 50,
        }];
        let theta = [30f64.to_radians(), 10e3];
        for k in 0..2 {
            let dual = end_q(&sand(theta), k, 100e3, &drained).eps;
            let fd = central(sand, theta, k, 1e-5, 100e3, &drained);
            assert!(
                (dual - fd).abs() <= 1e-6 * fd.abs(),
                "MC parameter {k}: dual {dual:e}, central difference {fd:e}"
            );
        }
    }

    /// Cohesionless Mohr–Coulomb reaches `q_f = σ_r (N_φ − 1)`, `N_φ = (1 + sin φ)/(1 − sin φ)`,
    /// exactly (the plateau of a cone through the origin in Kirchhoff stress is one in Cauchy
    /// stress too), so the derivative carried through 50 increments of drained compression is
    /// `dq_f/dφ = σ_r dN_φ/dφ = σ_r 2 cos φ/(1 − sin φ)²`: to 1e-9, the plateau's accuracy.
    #[test]
    fn the_derivative_of_the_mohr_coulomb_plateau_is_the_closed_form() {
        let phi = 30f64.to_radians();
        let drained = [LabStage {
            loading: Loading::DrainedTriaxial { axial_strain: 0.05 },
            increments: 50,
        }];
        let p0 = 100e3;
        let dq = end_q(&sand([phi, 0.0]), 0, p0, &drained).eps;
        let exact = p0 * 2.0 * phi.cos() / (1.0 - phi.sin()).powi(2);
        assert!(
            (dq - exact).abs() < 1e-9 * exact,
            "dq/dφ = {dq:e}, closed form {exact:e}"
        );
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
                tension_cutoff: None,
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
                tension_cutoff: None,
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
                tension_cutoff: None,
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
