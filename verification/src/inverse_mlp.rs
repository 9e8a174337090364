//! `inverse-mlp`: recovering the initial velocity field of a water column, given by a
//! multilayer perceptron, from tracked particles (JAX-MPM's Study 2, on a smaller scene).
//!
//! The scene (`verification/scenes/inverse_mlp.toml`): a water column `L0 = 0.3` m wide and
//! `H = 0.15` m high (1,152 particles at full size, MLS-MPM, USL, 400 steps of 2.5e-4 s) whose
//! truth initial velocity is `v_x = 1.5 (y/H)(2 − y/H) + 0.3 sin(2πx/L0)`, `v_y = 0`. A truth
//! run gives the positions of tracked particles every 20th step; an MLP of the initial
//! position (2 → 30 → 30 → 30 → 1, tanh, 1,981 weights, Glorot start from seed 0) gives `v_x`
//! and L-BFGS recovers its weights.
//!
//! | size | cell | particles | steps (Δt) | tracked | iterations |
//! |---|---|---|---|---|---|
//! | full (`loam verify`) | 0.0125 m | 1,152 | 400 (2.5e-4 s) | 100, 500, 1,000 | 100 |
//! | reduced (tests) | 0.025 m | 288 | 200 (5e-4 s) | 100 | 40 |
//!
//! Metric: the relative L2 error of the recovered field over the column's particles,
//! `‖v(w) − v*‖ / ‖v*‖`. Full size: below the reference's **6.4 %** with 500 tracked
//! particles and **3.7 %** with 1,000; the 100 case is reported (the reference: 45.1 %).
//! Reduced size: below **15 %** with 100 of the 288 particles after 40 iterations, from
//! about 98 % at the Glorot start: a third of the reference's 45.1 % with 100 tracked
//! particles (a coarser scene whose 100 particles are a third of the column; 12.8 % when
//! this was written, so a regression of the gradient or the optimiser shows). The scene is not the reference's (fewer particles, a
//! shorter run), so the figures compare the method, not the study.

use crate::inverse_v0::fixed_steps;
use crate::inversion::{Stop, lbfgs};
use crate::{CaseReport, Metric, Size, VerifyError, scenes, write_csv, write_text};
use loam_core::Particles;
use loam_inverse::{
    Checkpoints, Control, Observations, Problem, Transform, Variable, VelocityField, choose,
};
use std::collections::BTreeSet;
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::Path;

const CASE: &str = "inverse-mlp";
/// Column height `H` and width `L0` (m).
const H: f64 = 0.15;
const L0: f64 = 0.3;
/// Steps between observations.
const EVERY: usize = 20;

/// The truth field `v_x(x, y)`.
fn truth(x: f64, y: f64) -> f64 {
    1.5 * (y / H) * (2.0 - y / H) + 0.3 * (2.0 * PI * x / L0).sin()
}

/// `‖v − v*‖ / ‖v*‖` over all particles.
fn relative_error(v: &Particles<f64, 2>, truth: &Particles<f64, 2>) -> f64 {
    let (mut diff, mut norm) = (0.0, 0.0);
    for (a, b) in v.v.iter().zip(&truth.v) {
        diff += (a - b).norm_squared();
        norm += b.norm_squared();
    }
    (diff / norm).sqrt()
}

/// Runs the case.
pub fn run(size: Size, dir: &Path) -> Result<CaseReport, VerifyError> {
    let mut scene = scenes::scene("inverse_mlp");
    let (sets, goals, iterations): (&[usize], &[Option<f64>], usize) = match size {
        Size::Full => (&[100, 500, 1000], &[None, Some(0.064), Some(0.037)], 100),
        Size::Reduced => {
            scene.grid.cell_size = 0.025;
            scene.solver.time_step = Some(loam_core::TimeStep::Fixed { dt: 5e-4 });
            (&[100], &[Some(0.15)], 40)
        }
    };
    let built = scenes::build::<2>(&scene);
    let config = built.explicit_config().expect("an explicit scene");
    let (steps, dt) = fixed_steps(&built.plan);
    let rest = built.particles;
    let mut truth_state = rest.clone();
    for (v, x) in truth_state.v.iter_mut().zip(&rest.x) {
        v[0] = truth(x[0], x[1]);
        v[1] = 0.0;
    }
    let failed = |source| VerifyError::Adjoint {
        case: CASE.into(),
        source,
    };
    let observed: BTreeSet<usize> = (EVERY..=steps).step_by(EVERY).collect();
    let field = VelocityField::new(&rest, Some(0), vec![1.0, 0.0], &[30, 30, 30], 0)
        .expect("the column's particles");
    let identity = Variable {
        transform: Transform::Identity,
        scale: 1.0,
        bounds: None,
    };
    let mut metrics = Vec::new();
    let mut files = Vec::new();
    let mut md = format!(
        "{} particles, {steps} steps of {dt:e} s, tracked particles observed every {EVERY}th \
         step; MLP 2 → 30 → 30 → 30 → 1 (tanh, {} weights), L-BFGS from the Glorot start \
         (seed 0)\n\n| tracked | error at start | error at end | iterations | gradients | \
         L(start) | L(end) | wall (s) |\n|---|---|---|---|---|---|---|---|\n",
        rest.len(),
        field.mlp.len()
    );
    for (&tracked, &goal) in sets.iter().zip(goals) {
        let ids = choose(rest.len(), tracked, 1);
        let objective = Observations::record(
            &config,
            &truth_state,
            steps,
            &observed,
            &ids,
            Observations::with_monitors(Vec::new()),
        )
        .map_err(failed)?;
        let problem = Problem {
            config: config.clone(),
            initial: rest.clone(),
            steps,
            controls: vec![Control::VelocityField(field.clone())],
            objective,
            checkpoints: Checkpoints::Least,
        };
        let theta0 = problem.values().map_err(failed)?;
        let error_at = |theta: &[f64]| -> Result<f64, VerifyError> {
            let (_, p) = problem.setup(theta).map_err(failed)?;
            Ok(relative_error(&p, &truth_state))
        };
        let start = error_at(&theta0)?;
        let variables = vec![identity; theta0.len()];
        let r = lbfgs(
            CASE,
            |t| problem.gradient(t),
            &variables,
            &theta0,
            Stop {
                max_iterations: iterations,
                loss: 0.0,
            },
        )?;
        let end = error_at(&r.theta)?;
        let name = format!("relative L2 error, {tracked} tracked");
        metrics.push(match goal {
            Some(g) => Metric::at_most(CASE, &name, end, g),
            None => Metric::info(CASE, &name, end),
        });
        metrics.push(Metric::info(
            CASE,
            &format!("wall (s), {tracked} tracked"),
            r.wall,
        ));
        writeln!(
            md,
            "| {tracked} | {:.1} % | {:.2} % | {} | {} | {:.3e} | {:.3e} | {:.1} |",
            100.0 * start,
            100.0 * end,
            r.iterations,
            r.evaluations,
            r.first_loss,
            r.loss,
            r.wall
        )
        .expect("writing to a String");
        let csv = dir.join(format!("inverse_mlp_{tracked}_history.csv"));
        let rows: Vec<Vec<f64>> = (r.history.iter().enumerate())
            .map(|(i, (loss, _))| vec![i as f64, *loss])
            .collect();
        write_csv(&csv, &["iteration", "loss"], &rows)?;
        files.push(csv);
    }
    let table = dir.join("inverse_mlp.md");
    write_text(&table, &md)?;
    files.insert(0, table);
    Ok(CaseReport { metrics, files })
}
