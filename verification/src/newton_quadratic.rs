//! Quadratic convergence of Newton's method with the exact AD tangent.
//!
//! The cantilever at reduced size (Hencky, symmetry root, h = 0.5 m, 10 load steps) is solved
//! with a residual tolerance far below what round-off allows, so every step iterates into the
//! asymptotic range. With an exact tangent `r_{k+1} ≤ C r_k²`: the ratio `r_{k+1}/r_k²` stays
//! bounded as `r_k → 0` (for a merely linear rate ρ it would grow like ρ/r_k). The ratios are
//! taken where `r_k ≤ 1e-3` (asymptotic) and `r_{k+1} ≥ 1e-10` (above the round-off floor of
//! the assembled forces, ~1e-12 relative), residuals relative to the step's reference.

use crate::cantilever::{Root, Setup};
use crate::{CaseReport, Metric, Series, Size, VerifyError, write_csv, write_plot};
use loam_core::Shape;
use loam_implicit::NewtonSettings;
use std::path::Path;

/// Runs the case.
pub fn run(_size: Size, out: &Path) -> Result<CaseReport, VerifyError> {
    const CASE: &str = "newton-quadratic";
    let setup = Setup {
        root: Root::Symmetry,
        cell: 0.5,
        ppc: 4,
        // Cheap at any size (0.3 s): the same run for the tests and `loam verify`.
        steps: 10,
        newton: NewtonSettings {
            residual_tol: 1e-15,
            ..NewtonSettings::default()
        },
        ..Setup::reference(Shape::QuadraticBspline)
    };
    let (_, reports) = setup.run().map_err(|source| VerifyError::Implicit {
        case: CASE.into(),
        source,
    })?;
    let mut worst: f64 = 0.0;
    let mut samples = 0;
    let mut rows = Vec::new();
    let mut series = Vec::new();
    for r in &reports {
        for solve in r.solves.iter().filter(|s| s.converged) {
            let rel: Vec<f64> = solve
                .residuals
                .iter()
                .map(|x| x / solve.reference)
                .collect();
            for (k, w) in rel.windows(2).enumerate() {
                rows.push(vec![r.step as f64, k as f64, w[0], w[1]]);
                if w[0] <= 1e-3 && w[1] >= 1e-10 {
                    worst = worst.max(w[1] / (w[0] * w[0]));
                    samples += 1;
                }
            }
            series.push(Series {
                name: format!("step {}", r.step),
                points: rel
                    .iter()
                    .enumerate()
                    .map(|(k, x)| (k as f64, x.log10()))
                    .collect(),
                markers: false,
            });
        }
    }
    let csv = out.join("newton_quadratic.csv");
    write_csv(&csv, &["load_step", "iteration", "r_k", "r_k+1"], &rows)?;
    let png = out.join("newton_quadratic.png");
    write_plot(
        &png,
        "Newton residual histories (cantilever, Hencky)",
        "iteration",
        "log10 ‖R‖/ref",
        &series,
    )?;
    Ok(CaseReport {
        metrics: vec![
            // Bounded r_{k+1}/r_k²: 1e3 would mean r_{k+1} ≤ 1e-3·r_k already at r_k = 1e-6, far
            // beyond any linear rate; the measured constant is O(10).
            Metric::at_most(CASE, "max_r_next_over_r_squared", worst, 1e3),
            // At least a few iterations in the asymptotic range, or the check is empty.
            Metric::at_least(CASE, "asymptotic_samples", samples as f64, 3.0),
        ],
        files: vec![csv, png],
    })
}
