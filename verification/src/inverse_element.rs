//! `inverse-triaxial-mcc`: the constants of Modified Cam-Clay fitted to laboratory curves by
//! an inversion of element tests ([`loam_inverse::element`]).
//!
//! The tests are those of `examples/inverse/triaxial_mcc.toml`: a drained and an undrained
//! triaxial compression of normally consolidated clay (λ = 0.2, κ = 0.04, M = 1, e₀ = 1,
//! ν = 0.3), each isotropically consolidated to p′₀ = 200 kPa and sheared to 20 % axial
//! strain. Synthetic observations from the truth: after every 5th increment, `q` and `ε_v` of
//! the drained test and `q` and `p′` of the undrained one (σ = 1 kPa, 10⁻³). λ and κ need
//! both tests: the undrained path fixes the ratio `(λ − κ)/λ` (its `p′_f/p′₀`) and M, the
//! drained volume change the slopes themselves. Levenberg–Marquardt with the Jacobian of the
//! residuals by forward-mode duals through the element driver recovers λ, κ, M from 1.25 λ,
//! 1.25 κ and 0.75 M, each kept within half and twice its truth: **within 1 % each** (the
//! minimum is the truth, so the tolerance bounds how far the optimiser stops short of it).
//! Information: iterations, runs, wall time, and the Gauss–Newton condition number and
//! correlations at the truth ([`loam_inverse::implicit::Identifiability`]).
//!
//! Reduced size: 25 increments per test (5 observed points each); full size: the example's
//! 100 (20 each).

use crate::inversion::{Stop, levenberg_marquardt};
use crate::{CaseReport, Metric, Size, VerifyError, write_csv, write_text};
use loam_inverse::element::{ElementProblem, LabTest, Measure};
use loam_inverse::{AdjointError, MaterialField, Transform, Variable};
use loam_scene::SceneFormat;
use loam_scene::element::ElementTest;
use std::path::Path;

const CASE: &str = "inverse-triaxial-mcc";

/// The example's drained test.
const DRAINED: &str = include_str!("../../examples/element/triaxial_mcc_drained.toml");
/// The example's undrained test.
const UNDRAINED: &str = include_str!("../../examples/element/triaxial_mcc.toml");

/// The first guesses, as factors of the truth: λ and κ 25 % high, M 25 % low.
const FACTORS: [f64; 3] = [1.25, 1.25, 0.75];

fn failed(source: AdjointError) -> VerifyError {
    VerifyError::Adjoint {
        case: CASE.into(),
        source,
    }
}

/// The element test of `text` with `increments` increments in each stage.
fn test(text: &str, increments: usize) -> LabTest {
    let t = ElementTest::from_str_in(text, SceneFormat::Toml)
        .unwrap_or_else(|e| panic!("the example's element test: {e}"));
    let mut stages = t.stages();
    stages.iter_mut().for_each(|s| s.increments = increments);
    LabTest {
        material: t.material(),
        stress: t.initial_stress(),
        stages,
        void_ratio: t.initial.void_ratio,
        observed: Vec::new(),
    }
}

/// Runs `inverse-triaxial-mcc`.
pub fn run(size: Size, dir: &Path) -> Result<CaseReport, VerifyError> {
    use MaterialField::{CriticalStateSlope, Kappa, Lambda};
    let increments = match size {
        Size::Full => 100,
        Size::Reduced => 25,
    };
    let every = 5;
    let mut problem = ElementProblem {
        tests: vec![test(DRAINED, increments), test(UNDRAINED, increments)],
        params: vec![Lambda, Kappa, CriticalStateSlope],
    };
    let truth = problem.values().map_err(failed)?;
    let fitted = [
        vec![
            (Measure::DeviatorStress, 1e3),
            (Measure::VolumetricStrain, 1e-3),
        ],
        vec![(Measure::DeviatorStress, 1e3), (Measure::MeanStress, 1e3)],
    ];
    problem.observe(&truth, every, &fitted).map_err(failed)?;
    let start: Vec<f64> = truth.iter().zip(FACTORS).map(|(t, f)| t * f).collect();
    let variables: Vec<Variable> = (truth.iter().zip(&start))
        .map(|(&t, &s)| Variable {
            transform: Transform::Identity,
            scale: s,
            bounds: Some((0.5 * t, 2.0 * t)),
        })
        .collect();
    let r = levenberg_marquardt(
        CASE,
        |theta| problem.trial_gauss_newton(theta),
        &variables,
        &start,
        Stop {
            max_iterations: 40,
            loss: 1e-20,
        },
    )?;
    let errors: Vec<f64> = (r.theta.iter().zip(&truth))
        .map(|(f, t)| (f / t - 1.0).abs())
        .collect();
    let g = problem.identifiability(&truth).map_err(failed)?;
    let corr = |i: usize, j: usize| g.correlation.as_ref().map_or(f64::NAN, |c| c[(i, j)]);
    let metrics = vec![
        Metric::at_most(CASE, "|λ/λ* − 1|", errors[0], 1e-2),
        Metric::at_most(CASE, "|κ/κ* − 1|", errors[1], 1e-2),
        Metric::at_most(CASE, "|M/M* − 1|", errors[2], 1e-2),
        Metric::info(CASE, "iterations", r.iterations as f64),
        Metric::info(CASE, "runs of the loss", r.evaluations as f64),
        Metric::info(CASE, "wall (s)", r.wall),
        Metric::info(CASE, "cond JᵀJ (λ, κ, M)", g.condition),
        Metric::info(CASE, "corr(λ, κ)", corr(0, 1)),
    ];
    let md = format!(
        "Modified Cam-Clay from a drained (q, ε_v) and an undrained (q, p′) triaxial test, {} \
         increments each, observed every {every}th ({} residuals)\n\n\
         | | λ | κ | M |\n|---|---|---|---|\n\
         | truth | {} | {} | {} |\n| first guess | {} | {} | {} |\n\
         | recovered | {:.8} | {:.8} | {:.8} |\n| relative error | {:.3e} | {:.3e} | {:.3e} |\n\n\
         Levenberg–Marquardt: {} iterations, {} runs of the loss, {:.2} s; L {:.3e} → {:.3e}\n\
         Gauss–Newton at the truth: eigenvalues {:?}; condition {:.4e}; corr(λ, κ) {:.6}, \
         corr(λ, M) {:.6}, corr(κ, M) {:.6}\n",
        increments,
        problem.observations(),
        truth[0],
        truth[1],
        truth[2],
        start[0],
        start[1],
        start[2],
        r.theta[0],
        r.theta[1],
        r.theta[2],
        errors[0],
        errors[1],
        errors[2],
        r.iterations,
        r.evaluations,
        r.wall,
        r.first_loss,
        r.loss,
        g.eigenvalues,
        g.condition,
        corr(0, 1),
        corr(0, 2),
        corr(1, 2),
    );
    let file = dir.join("inverse_triaxial_mcc.md");
    write_text(&file, &md)?;
    let csv = dir.join("inverse_triaxial_mcc_history.csv");
    write_csv(
        &csv,
        &[
            "iteration",
            "loss",
            "lambda",
            "kappa",
            "critical_state_slope",
        ],
        &r.rows(),
    )?;
    Ok(CaseReport {
        metrics,
        files: vec![file, csv],
    })
}
