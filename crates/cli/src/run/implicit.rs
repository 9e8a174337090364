//! Implicit runs: load steps with a per-step Newton table.

use super::{Options, Stop, Target, interrupt};
use crate::Outcome;
use loam_implicit::ImplicitSolver;
use loam_scene::output::LoadStepSummary;
use loam_scene::{Built, ImplicitPlan};
use std::time::Instant;

/// Runs an implicit scene, printing one line per load step (unless `quiet`).
pub fn run<const D: usize>(
    built: Built<D>,
    plan: ImplicitPlan,
    target: Target,
    options: &Options,
) -> Outcome {
    let quiet = options.quiet;
    let frame_steps = built.frame_steps();
    let config = built
        .implicit_config()
        .expect("an implicit plan has an implicit configuration");
    if plan.balance_initial_stress && !quiet {
        report_balance(&config, &built.particles);
    }
    let mut solver = match ImplicitSolver::new(config, &built.particles) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    let mut rec = match target.recorder(&built) {
        Ok(r) => r,
        Err(outcome) => return outcome,
    };
    let mut particles = built.particles;
    // Frames and the summary use simulated time in dynamics, the load factor otherwise.
    let time_scale = plan
        .newmark_dt
        .map_or(1.0, |dt| dt * plan.load_steps as f64);
    rec.summary.end_time = time_scale;
    if !quiet {
        println!(
            "{:>5} {:>9} {:>8} {:>5} {:>5} {:>11} {:>7} {:>8}  residual history ‖R‖/ref",
            "step", "load", "unknowns", "its", "cuts", "‖R‖/ref", "lin.its", "time(s)"
        );
    }
    let start = Instant::now();
    let mut stop = None;
    if frame_steps.first() == Some(&0)
        && let Err(e) = rec.frame(0, 0.0, &particles)
    {
        stop = Some(e);
    }
    // The load steps run on the rayon pool with its other workers awake, as the explicit
    // steps do (`loam_explicit::pool::hold`): faer's parallel kernels start from inside the
    // pool, and no loop of a Newton iteration waits for a worker to wake.
    loam_explicit::pool::hold(|| {
        while stop.is_none() && !solver.finished() {
            if interrupt::requested() {
                stop = Some(Stop::Interrupted);
                break;
            }
            let t = Instant::now();
            let report = match solver.step(&mut particles) {
                Ok(r) => r,
                Err(e) => {
                    stop = Some(Stop::Failed(e.to_string()));
                    break;
                }
            };
            let wall = t.elapsed().as_secs_f64();
            let last = report.solves.last();
            let rel = last.map_or(0.0, |s| {
                s.residuals.last().copied().unwrap_or(0.0) / s.reference
            });
            let lin: usize = report
                .solves
                .iter()
                .flat_map(|s| s.linear_iterations.iter())
                .sum();
            rec.summary.load_steps.push(LoadStepSummary {
                step: report.step as u64,
                load_factor: report.load_factor,
                iterations: report.iterations() as u64,
                cuts: report.cuts as u64,
                residual: rel,
                linear_iterations: lin as u64,
                wall_time_s: wall,
                constraint_forces: report
                    .constraint_forces
                    .iter()
                    .map(|f| f.iter().copied().collect())
                    .collect(),
            });
            if !quiet {
                let history: Vec<String> = last
                    .map(|s| {
                        s.residuals
                            .iter()
                            .map(|r| format!("{:.1e}", r / s.reference))
                            .collect()
                    })
                    .unwrap_or_default();
                println!(
                    "{:>5} {:>9.4} {:>8} {:>5} {:>5} {:>11.3e} {:>7} {:>8.3}  {}",
                    report.step,
                    report.load_factor,
                    report.unknowns,
                    report.iterations(),
                    report.cuts,
                    rel,
                    lin,
                    wall,
                    history.join(" ")
                );
            }
            if frame_steps.contains(&report.step)
                && let Err(e) = rec.frame(report.step, report.load_factor * time_scale, &particles)
            {
                stop = Some(e);
            }
        }
    });
    let wall = start.elapsed().as_secs_f64();
    let iterations: u64 = rec.summary.load_steps.iter().map(|s| s.iterations).sum();
    let reached = match plan.newmark_dt {
        Some(_) => format!("t = {:.4} s", solver.load_factor() * time_scale),
        None => format!("load factor {:.4}", solver.load_factor()),
    };
    let done = format!(
        "{} steps to {reached} in {wall:.2} s, {iterations} Newton iterations ({} particles)",
        solver.steps(),
        particles.len()
    );
    rec.finish(
        solver.steps(),
        solver.load_factor() * time_scale,
        wall,
        stop,
        &done,
    )
}

/// Says how large the balance of the initial stress is (`solver.balance_initial_stress`):
/// `|Σ_p f_p|` and `max_p |f_p|` against the total and the particle's weight, or why it could
/// not be computed.
fn report_balance<const D: usize>(
    config: &loam_implicit::ImplicitConfig<D>,
    particles: &loam_core::Particles<f64, D>,
) {
    if config.balance.is_empty() {
        if let Err(e) = loam_implicit::balance_initial_stress(config, particles) {
            eprintln!("warning: the initial stress is not balanced: {e}");
        }
        return;
    }
    let g = config.gravity.norm();
    let weight: f64 = particles.mass.iter().sum::<f64>() * g;
    let total = config
        .balance
        .iter()
        .sum::<loam_core::tensor::Vector<f64, D>>();
    let largest = (config.balance.iter().zip(&particles.mass))
        .map(|(f, m)| f.norm() / (m * g))
        .fold(0.0, f64::max);
    println!(
        "initial stress balanced on the grid: net balancing force {:.2} % of the weight; \
         the largest on one particle {:.2} times its weight",
        100.0 * total.norm() / weight,
        largest
    );
}
