//! `obstacle-velocity-fd`: the derivative with respect to a moving obstacle's velocity against
//! central differences of the loss.
//!
//! Scene (`verification/scenes/obstacle_velocity.toml`): a rigid disk of radius 0.04 m moving
//! at (0.2, −0.8) m/s into water at rest (MLS-MPM, 400 particles, 120 steps at full size, 60
//! reduced), with USL and MUSL. The loss is the particles' squared displacements after the
//! run, `L = Σ_p ‖x_p − x_p(0)‖²`; the unknowns are the two components of the disk's velocity.
//!
//! A moving obstacle's surface at time `t` is its shape at `x − v_o t`, so its velocity acts
//! through the velocity the contact law pushes the material to and through the position of
//! the surface, whose normal at a node turns as the disk moves. The adjoint and the forward
//! -mode dual run differentiate the same discrete map and agree to round-off whether or not
//! they carry the second: the reference here is therefore a difference of the loss itself.
//!
//! Metrics per scheme and velocity component:
//!
//! - the convergence of the reference: central differences (Richardson-extrapolated, as
//!   `loam_inverse::check::difference_at`) at `δ = 10⁻⁴, 10⁻⁵, 10⁻⁶ |v_o,a|`, each from runs
//!   that keep every branch (contact, stick/slip) of the run at the point, must agree with
//!   each other to **1e-6** (relative spread): the loss is smooth over the steps and neither
//!   truncation nor round-off is visible in the digits compared;
//! - the relative difference between the dual derivative and the difference at
//!   `δ = 10⁻⁵ |v_o,a|`, **≤ 1e-6**: the reference's own convergence;
//! - the relative difference between the adjoint and the dual derivative, **≤ 1e-10** (the
//!   same exact derivative, summed in another order);
//! - as information, the ratio of the dual derivative to the difference (1 when right).

use crate::{CaseReport, Metric, Size, VerifyError, scenes, write_csv, write_text};
use loam_core::Scheme;
use loam_core::tensor::Vector;
use loam_inverse::{AdjointError, Checkpoints, Control, Param, Problem, TrackedPositions, check};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

const CASE: &str = "obstacle-velocity-fd";

/// The relative steps of the central differences, largest first.
const STEPS: [f64; 3] = [1e-4, 1e-5, 1e-6];

/// The step whose difference the dual derivative is compared with (the middle one).
const REFERENCE: usize = 1;

fn adjoint_error(e: AdjointError) -> VerifyError {
    VerifyError::Adjoint {
        case: CASE.into(),
        source: e,
    }
}

/// One velocity component with one scheme.
struct Row {
    label: String,
    loss: f64,
    adjoint: f64,
    dual: f64,
    /// The difference at each of [`STEPS`], `None` where a perturbed run switched a branch.
    differences: Vec<Option<f64>>,
}

impl Row {
    /// The largest relative difference between two of the differences (`NaN` when one is
    /// missing).
    fn spread(&self) -> f64 {
        let mut spread = 0.0f64;
        for (i, a) in self.differences.iter().enumerate() {
            for b in &self.differences[i + 1..] {
                match (a, b) {
                    (Some(a), Some(b)) => {
                        spread = spread.max((a - b).abs() / a.abs().max(b.abs()));
                    }
                    _ => return f64::NAN,
                }
            }
        }
        spread
    }

    /// The reference difference (`NaN` when missing).
    fn reference(&self) -> f64 {
        self.differences[REFERENCE].unwrap_or(f64::NAN)
    }
}

/// Runs the scene with `scheme` and checks both velocity components.
fn check_scheme(scheme: Scheme, size: Size) -> Result<Vec<Row>, VerifyError> {
    let mut scene = scenes::scene("obstacle_velocity");
    scene.solver.scheme = Some(scheme);
    let built = scenes::build::<2>(&scene);
    let config = built.explicit_config().expect("an explicit scene");
    let particles = built.particles;
    let steps = match size {
        Size::Reduced => 60,
        Size::Full => 120,
    };
    let ids: Vec<(usize, Vector<f64, 2>)> = particles.x.iter().copied().enumerate().collect();
    let objective = TrackedPositions {
        targets: BTreeMap::from([(steps, ids)]),
        weight: 1.0,
    };
    let params = [Param::ObstacleVelocity(0, 0), Param::ObstacleVelocity(0, 1)];
    let problem = Problem {
        config,
        initial: particles,
        steps,
        controls: params.iter().map(|&p| Control::Param(p)).collect(),
        objective,
        checkpoints: Checkpoints::Least,
    };
    let theta = problem.values().map_err(adjoint_error)?;
    let (loss, grad) = problem.gradient(&theta).map_err(adjoint_error)?;
    let (config, particles) = problem.setup(&theta).map_err(adjoint_error)?;
    let base = check::branches(&config, &particles, steps).map_err(adjoint_error)?;
    let scheme_name = match scheme {
        Scheme::Usl => "USL",
        Scheme::Musl => "MUSL",
    };
    let mut rows = Vec::new();
    for (k, param) in params.iter().enumerate() {
        let dual = problem.dual_derivative(&theta, k).map_err(adjoint_error)?;
        let mut differences = Vec::new();
        for step in STEPS {
            let d =
                check::difference_at(&problem, &theta, k, step, &base).map_err(adjoint_error)?;
            differences.push(d.map(|d| d.value));
        }
        rows.push(Row {
            label: format!("{scheme_name} {param}"),
            loss,
            adjoint: grad[k],
            dual,
            differences,
        });
    }
    Ok(rows)
}

/// Runs the case.
pub fn run(size: Size, dir: &Path) -> Result<CaseReport, VerifyError> {
    let mut rows = check_scheme(Scheme::Usl, size)?;
    rows.extend(check_scheme(Scheme::Musl, size)?);
    let mut metrics = Vec::new();
    let mut md = String::from(
        "| run | L | adjoint | dual | central diff. δ = 1e-4 | 1e-5 | 1e-6 | spread | dual / central diff. |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut csv_rows = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        let reference = r.reference();
        metrics.push(Metric::at_most(
            CASE,
            &format!(
                "{}: spread of the central differences over δ = 1e-4, 1e-5, 1e-6",
                r.label
            ),
            r.spread(),
            1e-6,
        ));
        metrics.push(Metric::at_most(
            CASE,
            &format!("{}: rel |dual − central diff.|", r.label),
            (r.dual - reference).abs() / reference.abs(),
            1e-6,
        ));
        metrics.push(Metric::at_most(
            CASE,
            &format!("{}: rel |adjoint − dual|", r.label),
            (r.adjoint - r.dual).abs() / r.dual.abs(),
            1e-10,
        ));
        metrics.push(Metric::info(
            CASE,
            &format!("{}: dual / central diff.", r.label),
            r.dual / reference,
        ));
        let shown: Vec<String> = (r.differences.iter())
            .map(|d| d.map_or("— (a branch switched)".into(), |d| format!("{d:.10e}")))
            .collect();
        writeln!(
            md,
            "| {} | {:.6e} | {:.10e} | {:.10e} | {} | {:.1e} | {:.8} |",
            r.label,
            r.loss,
            r.adjoint,
            r.dual,
            shown.join(" | "),
            r.spread(),
            r.dual / reference
        )
        .expect("writing to a String");
        let mut row = vec![i as f64, r.loss, r.adjoint, r.dual];
        row.extend(r.differences.iter().map(|d| d.unwrap_or(f64::NAN)));
        csv_rows.push(row);
    }
    let table = dir.join("obstacle_velocity_fd.md");
    write_text(&table, &md)?;
    let csv = dir.join("obstacle_velocity_fd.csv");
    write_csv(
        &csv,
        &[
            "run",
            "loss",
            "adjoint",
            "dual",
            "central_difference_1e-4",
            "central_difference_1e-5",
            "central_difference_1e-6",
        ],
        &csv_rows,
    )?;
    Ok(CaseReport {
        metrics,
        files: vec![table, csv],
    })
}
