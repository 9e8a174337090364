//! Newton's method with backtracking line search for one load step.

use crate::linear::{LinearError, LinearSolver, LinearSolverKind};
use crate::system::{Inverted, Materials, StepSystem};

/// How the tangent is assembled (in a scene file: `tangent = "local"` or `"colour"`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TangentMethod {
    /// Per-particle forward-mode AD of the stress w.r.t. `ΔF`, chained with the shape-function
    /// gradients (fast; tested against the colour-seeded one).
    #[default]
    Local,
    /// Block-colour seeding over the `b^D` node colours (the reference); `color` is
    /// accepted.
    #[serde(alias = "color")]
    Colour,
}

/// Convergence and robustness settings of the Newton iteration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonSettings {
    /// Converged when `‖R‖ ≤ residual_tol · max(‖R(Δu₀)‖, ‖f_ext‖)`.
    pub residual_tol: f64,
    /// …or when the Newton correction `‖δ‖_∞ ≤ increment_tol · h` (with `‖R‖` already below
    /// `√residual_tol` of the reference).
    pub increment_tol: f64,
    /// Iteration limit per attempt.
    pub max_iterations: usize,
    /// Safeguard the Newton step: halve it (up to 10 times) while the trial state inverts a
    /// particle, is not finite, or (after the first correction of a step) does not decrease
    /// the residual; the first correction may grow it by up to 10⁴.
    pub line_search: bool,
    /// How often a failed step may be cut in half before the run stops.
    pub max_cuts: usize,
    /// Tangent assembly.
    pub tangent: TangentMethod,
    /// Linear solver for the Newton corrections.
    pub linear: LinearSolverKind,
}

impl Default for NewtonSettings {
    fn default() -> Self {
        Self {
            residual_tol: 1e-8,
            increment_tol: 1e-10,
            max_iterations: 25,
            line_search: true,
            max_cuts: 6,
            tangent: TangentMethod::Local,
            linear: LinearSolverKind::Lu,
        }
    }
}

/// What one Newton solve did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NewtonReport {
    /// Residual norm before each iteration and at the end (`iterations + 1` values).
    pub residuals: Vec<f64>,
    /// Line-search step length of each iteration.
    pub step_lengths: Vec<f64>,
    /// Linear-solver iterations per Newton iteration (1 for direct solvers).
    pub linear_iterations: Vec<usize>,
    /// The reference the residual tolerance is relative to.
    pub reference: f64,
    /// Whether it converged.
    pub converged: bool,
    /// Why it stopped, when it did not converge.
    pub failure: Option<String>,
    /// Seconds spent assembling tangents, factorising/solving, and evaluating residuals.
    pub time_tangent: f64,
    /// Seconds in the linear solver.
    pub time_linear: f64,
    /// Seconds evaluating residuals.
    pub time_residual: f64,
}

impl NewtonReport {
    /// Newton iterations taken.
    pub fn iterations(&self) -> usize {
        self.step_lengths.len()
    }
}

/// Residuals the non-monotone line search compares with.
const MEMORY: usize = 4;

/// Largest growth of ‖R‖ a Newton step may cause before it is shortened.
const GROWTH_LIMIT: f64 = 1e4;

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Solves `R(x) = 0` from `x = 0`; returns the solution (or the last iterate) and the report.
pub fn solve<const D: usize>(
    system: &StepSystem<D>,
    materials: &Materials,
    settings: &NewtonSettings,
    linear: &mut LinearSolver,
    h: f64,
) -> (Vec<f64>, NewtonReport) {
    let n = system.len();
    let mut x = vec![0.0; n];
    let mut report = NewtonReport::default();
    let clock = std::time::Instant::now;
    let t = clock();
    let mut r = match system.residual(&x, materials) {
        Ok(r) => r,
        Err(Inverted { particle }) => {
            report.failure = Some(format!(
                "the prescribed increment inverts particle {particle}"
            ));
            return (x, report);
        }
    };
    report.time_residual += t.elapsed().as_secs_f64();
    let mut rn = norm(&r);
    report.reference = rn.max(norm(&system.f_ext)).max(f64::MIN_POSITIVE);
    report.residuals.push(rn);
    if n == 0 || rn <= settings.residual_tol * report.reference {
        report.converged = true;
        return (x, report);
    }
    let mut dx = vec![0.0; n];
    for iteration in 0..settings.max_iterations {
        let t = clock();
        let k = match settings.tangent {
            TangentMethod::Local => system.tangent_local(&x, materials),
            TangentMethod::Colour => system.tangent_colour(&x, materials),
        };
        report.time_tangent += t.elapsed().as_secs_f64();
        let Ok(k) = k else {
            report.failure = Some("tangent at an inverted state".into());
            return (x, report);
        };
        let neg_r: Vec<f64> = r.iter().map(|v| -v).collect();
        let t = clock();
        let stats = linear.solve(&k, &neg_r, &mut dx);
        report.time_linear += t.elapsed().as_secs_f64();
        match stats {
            Ok(s) => report.linear_iterations.push(s.iterations),
            Err(e) => {
                report.failure = Some(linear_failure(&e));
                return (x, report);
            }
        }
        // Safeguarded step. The first correction of a step may grow ‖R‖ by up to
        // `GROWTH_LIMIT`: the predictor of bending-dominated problems raises the residual
        // ~10²× through membrane forces and then converges quadratically, which a monotone
        // test would reject. Later corrections must decrease ‖R‖ below the largest of the
        // last few residuals (α halved up to 10 times), which keeps plastic steps from
        // wandering off without rejecting an occasional rise; a trial that inverts a
        // particle or is not finite is always shortened. A step that still does not converge
        // is cut by the load stepping.
        let mut alpha = 1.0;
        let mut accepted = None;
        let tries = if settings.line_search { 10 } else { 1 };
        for _ in 0..tries {
            let trial: Vec<f64> = x.iter().zip(&dx).map(|(xi, di)| xi + alpha * di).collect();
            let t = clock();
            let rt = system.residual(&trial, materials);
            report.time_residual += t.elapsed().as_secs_f64();
            if let Ok(rt) = rt {
                let rtn = norm(&rt);
                // Non-monotone Armijo test (Grippo–Lampariello–Lucidi): against the largest
                // of the last `MEMORY` residuals, so an occasional rise is accepted but a
                // sustained divergence is not.
                let recent = report
                    .residuals
                    .iter()
                    .rev()
                    .take(MEMORY)
                    .fold(0.0f64, |m, &r| m.max(r));
                let bound = if iteration == 0 || !settings.line_search {
                    GROWTH_LIMIT * rn
                } else {
                    (1.0 - 1e-4 * alpha) * recent
                };
                if rtn.is_finite() && rtn <= bound {
                    accepted = Some((trial, rt, rtn));
                    break;
                }
            }
            alpha *= 0.5;
        }
        let Some((trial, rt, rtn)) = accepted else {
            report.failure = Some(format!(
                "no admissible step along the Newton direction (inverted particles or no decrease of the residual; ‖R‖ = {rn:.3e})"
            ));
            return (x, report);
        };
        x = trial;
        r = rt;
        rn = rtn;
        report.step_lengths.push(alpha);
        report.residuals.push(rn);
        let step = alpha * dx.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let small_residual = rn <= settings.residual_tol * report.reference;
        let small_step = step <= settings.increment_tol * h
            && rn <= settings.residual_tol.sqrt() * report.reference;
        if small_residual || small_step {
            report.converged = true;
            return (x, report);
        }
        if !rn.is_finite() {
            break;
        }
    }
    report.failure = Some(format!(
        "no convergence in {} iterations (‖R‖/ref = {:.3e})",
        settings.max_iterations,
        rn / report.reference
    ));
    (x, report)
}

fn linear_failure(e: &LinearError) -> String {
    format!("linear solver: {e}")
}
