//! Implicit runs: load steps with a per-step Newton table.

use super::probes::Probes;
use super::{Options, Stop, Target, interrupt};
use crate::Outcome;
use loam_core::Particles;
use loam_core::tensor::det;
use loam_implicit::{ImplicitConfig, ImplicitSolver, StepReport};
use loam_scene::output::{LoadStepSummary, WaterTable};
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
    let coupled = built.pore_fluid.is_some();
    let unit = built.time_unit();
    let water = built.water_table();
    let probes = Probes::new(built.probes.clone(), water, coupled);
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
    rec.summary.probes = probes.histories(&particles);
    // Frames and the summary use simulated time in dynamics and in a coupled run (there in
    // the consolidation's unit), the load factor otherwise.
    let time_scale = plan
        .newmark_dt
        .map_or(1.0, |dt| dt * plan.load_steps as f64);
    let clock = |solver: &ImplicitSolver<D>| match coupled {
        true => solver.time() / unit.seconds(),
        false => solver.load_factor() * time_scale,
    };
    rec.summary.end_time = match &built.pore_fluid {
        Some(fluid) => fluid.schedule.time.last().copied().unwrap_or(0.0) / unit.seconds(),
        None => time_scale,
    };
    if coupled {
        rec.summary.time_unit = Some(unit.name().to_owned());
    }
    let mut consolidation = Consolidation::new(water);
    if !quiet {
        let coupled_columns = if coupled {
            format!(" {:>11} {:>6}", format!("t ({})", unit.name()), "U")
        } else {
            String::new()
        };
        println!(
            "{:>5} {:>9}{coupled_columns} {:>8} {:>5} {:>5} {:>11} {:>7} {:>8}  residual history ‖R‖/ref",
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
            let degree =
                coupled.then(|| consolidation.observe(&particles, report.step <= plan.load_steps));
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
                load_factor: solver.applied_load(),
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
                constraint_displacements: rigid_displacements(solver.config(), &report),
                time: coupled.then(|| clock(&solver)),
                degree_of_consolidation: degree.map(|d| d.0),
                max_excess_pore_pressure: degree.map(|d| d.1),
            });
            probes.sample(&mut rec.summary, &particles);
            if !quiet {
                let history: Vec<String> = last
                    .map(|s| {
                        s.residuals
                            .iter()
                            .map(|r| format!("{:.1e}", r / s.reference))
                            .collect()
                    })
                    .unwrap_or_default();
                let coupled_columns = match degree {
                    Some((u, _)) => format!(" {:>11.4e} {:>6.4}", clock(&solver), u),
                    None => String::new(),
                };
                println!(
                    "{:>5} {:>9.4}{coupled_columns} {:>8} {:>5} {:>5} {:>11.3e} {:>7} {:>8.3}  {}",
                    report.step,
                    solver.applied_load(),
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
                && let Err(e) = rec.frame(report.step, clock(&solver), &particles)
            {
                stop = Some(e);
            }
        }
    });
    let wall = start.elapsed().as_secs_f64();
    if let Err(e) = probes.write(rec.dir(), &rec.summary) {
        stop.get_or_insert(Stop::Failed(e));
    }
    let iterations: u64 = rec.summary.load_steps.iter().map(|s| s.iterations).sum();
    let reached = match (coupled, plan.newmark_dt) {
        (true, _) => format!("t = {:.4e} {}", clock(&solver), unit.name()),
        (false, Some(_)) => format!("t = {:.4} s", clock(&solver)),
        (false, None) => format!("load factor {:.4}", solver.load_factor()),
    };
    let done = format!(
        "{} steps to {reached} in {wall:.2} s, {iterations} Newton iterations ({} particles)",
        solver.steps(),
        particles.len()
    );
    rec.finish(solver.steps(), clock(&solver), wall, stop, &done)
}

/// The degree of consolidation of a coupled run, `U = 1 − ∫ p_e dV / ∫ p_e,0 dV` with
/// `p_e,0` the excess pore pressure at the end of the loading.
struct Consolidation {
    water: Option<WaterTable>,
    /// `∫ p_e dV` at the end of the loading.
    initial: Option<f64>,
}

impl Consolidation {
    fn new(water: Option<WaterTable>) -> Self {
        Self {
            water,
            initial: None,
        }
    }

    /// `(U, max p_e)` of the particles after a step; `loading`: the step is one of the loading
    /// steps, whose `∫ p_e dV` the later ones compare with (`U = 0` during the loading).
    fn observe<const D: usize>(&mut self, p: &Particles<f64, D>, loading: bool) -> (f64, f64) {
        let excess = |i: usize| {
            p.pore_pressure[i] - self.water.map_or(0.0, |w| w.hydrostatic(p.x[i][D - 1]))
        };
        let integral: f64 = (0..p.len())
            .map(|i| excess(i) * p.volume0[i] * det(&p.f[i]))
            .sum();
        let largest = (0..p.len()).map(excess).fold(f64::NEG_INFINITY, f64::max);
        if loading {
            self.initial = Some(integral);
        }
        let u = match self.initial {
            Some(i0) if i0 != 0.0 && !loading => 1.0 - integral / i0,
            _ => 0.0,
        };
        (u, largest)
    }
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

/// Per constraint, the total displacement of each force-controlled component (`None` for
/// the others); empty when no constraint is force-controlled.
fn rigid_displacements<const D: usize>(
    config: &ImplicitConfig<D>,
    report: &StepReport<D>,
) -> Vec<Vec<Option<f64>>> {
    if config
        .constraints
        .iter()
        .all(|k| k.force.iter().all(Option::is_none))
    {
        return Vec::new();
    }
    config
        .constraints
        .iter()
        .zip(&report.constraint_displacements)
        .map(|(k, u)| (0..D).map(|a| k.force[a].map(|_| u[a])).collect())
        .collect()
}
