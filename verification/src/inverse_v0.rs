//! `inverse-v0`: recovering the initial velocity of a dam break from observations of its
//! flow (JAX-MPM's Study 1, on a coarser grid).
//!
//! The scene (`verification/scenes/inverse_v0.toml`): a water column 0.5 m × 0.3 m in a
//! 2.0 m × 0.4 m tank starting with a uniform horizontal velocity v₀ = 2.0 m/s (MLS-MPM, USL,
//! 5,000 steps of 6e-5 s at full size). A truth run at v₀ = 2.0 m/s gives synthetic
//! observations over the last 100 frames (every 10th step); L-BFGS recovers v₀ from the first
//! guess 0.5 m/s, with the gradient by the discrete adjoint, from
//!
//! - (a) the positions of all particles,
//! - (b) the positions of 100 tracked particles (20 at reduced size), chosen by
//!   [`loam_inverse::choose`],
//! - (c) the mean velocity in four Eulerian monitors along the flow's path, boxes over the
//!   tank's depth whose edges are smoothed over one cell ([`MonitorBox`]): with sharp edges a
//!   particle entering or leaving a box is a jump of the loss that the gradient does not see,
//!   and near the truth the line search met such jumps and stalled.
//!
//! Metric: each recovered v₀ within **0.5 %** of the truth. With synthetic observations from
//! the same discrete model the minimum is the truth itself, so the inversion stops when the
//! loss has fallen by 12 orders of magnitude (v₀ then agrees to about 1e-6). Iterations and
//! wall time are reported.

use crate::inversion::{Recovered, Stop, lbfgs};
use crate::{CaseReport, Metric, Size, VerifyError, scenes, write_csv, write_text};
use loam_core::Particles;
use loam_core::tensor::Vector;
use loam_explicit::Config;
use loam_inverse::{Checkpoints, Control, MonitorBox, Observations, Problem, Variable, choose};
use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::Path;

const CASE: &str = "inverse-v0";
/// The truth (m/s).
pub const TRUTH: f64 = 2.0;
/// The first guess (m/s).
pub const FIRST_GUESS: f64 = 0.5;
/// Observed frames, the last of the run.
const FRAMES: usize = 100;
/// Steps between frames.
const EVERY: usize = 10;

/// The step count and `Δt` of a scene with a fixed step.
///
/// # Panics
/// When the scene is implicit or has an adaptive step: the cases' scenes are explicit with a
/// fixed step, which the adjoint needs.
pub(crate) fn fixed_steps(plan: &loam_scene::SolverPlan) -> (usize, f64) {
    match plan {
        loam_scene::SolverPlan::Explicit(p) => match (p.fixed_steps(), p.time_step) {
            (Some(n), loam_core::TimeStep::Fixed { dt }) => (n, dt),
            _ => panic!("the scene has no fixed time step"),
        },
        loam_scene::SolverPlan::Implicit(_) => panic!("the scene is not explicit"),
    }
}

/// The case's scene at `size`: solver inputs, step count, `Δt` and the tracked particles' count.
fn setup(size: Size) -> (Config<f64, 2>, Particles<f64, 2>, usize, f64, usize) {
    let mut scene = scenes::scene("inverse_v0");
    let tracked = match size {
        Size::Full => 100,
        Size::Reduced => {
            // 0.05 m cells, Δt scaled with h (the same CFL number).
            scene.grid.cell_size = 0.05;
            scene.solver.time_step = Some(loam_core::TimeStep::Fixed { dt: 1.5e-4 });
            20
        }
    };
    let built = scenes::build::<2>(&scene);
    let config = built.explicit_config().expect("an explicit scene");
    let (steps, dt) = fixed_steps(&built.plan);
    (config, built.particles, steps, dt, tracked)
}

/// Runs the case. The monitor boxes' edges are smoothed over one cell
/// ([`MonitorBox`]), so the monitor loss has no jumps as particles cross them.
pub fn run(size: Size, dir: &Path) -> Result<CaseReport, VerifyError> {
    let full = setup(size);
    let boxes: Vec<MonitorBox<2>> = [0.4, 0.7, 1.0, 1.3]
        .into_iter()
        .map(|x| MonitorBox {
            lo: Vector::from([x, 0.0]),
            hi: Vector::from([x + 0.3, 0.4]),
            edge: full.0.grid.h,
        })
        .collect();
    let all: Vec<usize> = (0..full.1.len()).collect();
    let some = choose(full.1.len(), full.4, 1);
    let variants: [(&str, &[usize], Vec<MonitorBox<2>>); 3] = [
        ("all particles", &all, Vec::new()),
        ("tracked particles", &some, Vec::new()),
        ("velocity monitors", &[], boxes),
    ];
    let variable = Variable {
        transform: loam_inverse::Transform::Identity,
        scale: 1.0,
        bounds: None,
    };
    let stop = Stop {
        max_iterations: 30,
        loss: 1e-12,
    };
    let mut metrics = Vec::new();
    let mut files = Vec::new();
    let mut md = format!(
        "observed: the last {FRAMES} frames, every {EVERY}th step\n\n\
         | observations | particles | steps | recovered v₀ (m/s) | rel. error | iterations | gradients | L(first guess) | L(end) | wall (s) |\n|---|---|---|---|---|---|---|---|---|---|\n"
    );
    let (config, particles, steps) = (&full.0, &full.1, full.2);
    for (name, ids, boxes) in variants {
        let observed: BTreeSet<usize> = (0..FRAMES).map(|i| steps - i * EVERY).collect();
        let objective = Observations::record(
            config,
            particles,
            steps,
            &observed,
            ids,
            Observations::with_monitors(boxes.clone()),
        )
        .map_err(|source| VerifyError::Adjoint {
            case: CASE.into(),
            source,
        })?;
        let problem = Problem {
            config: config.clone(),
            initial: particles.clone(),
            steps,
            controls: vec![Control::InitialVelocity {
                material: None,
                direction: vec![1.0, 0.0],
            }],
            objective,
            checkpoints: Checkpoints::Least,
        };
        let r: Recovered = lbfgs(
            CASE,
            |t| problem.gradient(t),
            &[variable],
            &[FIRST_GUESS],
            stop,
        )?;
        let error = (r.theta[0] - TRUTH).abs() / TRUTH;
        metrics.push(Metric::at_most(
            CASE,
            &format!("{name}: |v₀ − 2| / 2"),
            error,
            5e-3,
        ));
        metrics.push(Metric::info(
            CASE,
            &format!("{name}: iterations"),
            r.iterations as f64,
        ));
        metrics.push(Metric::info(CASE, &format!("{name}: wall (s)"), r.wall));
        let csv = dir.join(format!("inverse_v0_{}.csv", name.replace(' ', "_")));
        write_csv(&csv, &["iteration", "loss", "v0"], &r.rows())?;
        files.push(csv);
        writeln!(
            md,
            "| {name} | {} | {steps} | {:.10} | {error:.1e} | {} | {} | {:.4e} | {:.4e} | {:.1} |",
            particles.len(),
            r.theta[0],
            r.iterations,
            r.evaluations,
            r.first_loss,
            r.loss,
            r.wall
        )
        .expect("writing to a String");
    }
    let table = dir.join("inverse_v0.md");
    write_text(&table, &md)?;
    files.insert(0, table);
    Ok(CaseReport { metrics, files })
}
