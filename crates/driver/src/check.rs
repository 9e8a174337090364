//! `loam check`: parse and validate a scene, estimate its size before building it, build it,
//! and make the checks a run makes before its first step.

use crate::Outcome;
use crate::preflight::{self, MemoryLimit, StepLimit};
use loam_explicit::Solver;
use loam_scene::{Built, Scene, SolverPlan};
use std::path::Path;

/// Validates `path`, printing a summary with the estimates and any warnings, or the
/// problems (a run of more steps than `max_steps` among them).
pub fn check(path: &Path, memory_limit: Option<MemoryLimit>, max_steps: StepLimit) -> Outcome {
    let scene = match Scene::read_path(path) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    let size = match preflight::size(&scene, memory_limit)
        .and_then(|size| preflight::implicit_steps(&scene, max_steps).map(|()| size))
    {
        Ok(s) => s,
        Err(msg) => {
            eprintln!("error: {}: {msg}", path.display());
            return Outcome::BadInput;
        }
    };
    if let Err(e) = scene.validate() {
        eprintln!("error: {e}");
        return Outcome::BadInput;
    }
    let checked = match scene.dim() {
        2 => check_dim::<2>(&scene, max_steps),
        _ => check_dim::<3>(&scene, max_steps),
    };
    let (particles, steps, warnings) = match checked {
        Ok(c) => c,
        // The scene's own errors name the file already.
        Err(Refused::Scene(e)) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
        Err(Refused::Solver(msg)) => {
            eprintln!("error: {}: {msg}", path.display());
            return Outcome::BadInput;
        }
    };
    let consolidation = preflight::consolidation_steps(&scene);
    let extent = match (scene.solver.end_time, scene.solver.load_steps) {
        (Some(t), _) => format!("end time {t} s"),
        (None, Some(n)) if consolidation > 0.0 => {
            let k = scene.solver.consolidation.expect("a consolidation");
            format!(
                "{n} undrained load step(s), then {consolidation} consolidation steps to {} {}",
                k.end_time,
                k.time_unit.name()
            )
        }
        (None, Some(n)) => format!("{n} load steps"),
        (None, None) => String::new(),
    };
    println!(
        "{}: valid {}D {} scene, {} material(s), {} bod(y/ies), {particles} particles, {extent}",
        path.display(),
        scene.dim(),
        scene.solver.kind.name(),
        scene.materials.len(),
        scene.bodies.len(),
    );
    let steps = steps.map_or_else(String::new, |s| format!("; about {s:.3e} steps"));
    println!("  estimated before building: {}{steps}", size.describe());
    for w in warnings {
        eprintln!("warning: {}: {w}", path.display());
    }
    Outcome::Ok
}

/// Builds the scene and makes the solver's checks: the particle count, the estimated steps
/// (explicit) and the warnings, or the problem.
/// Why [`check_dim`] refused a scene.
enum Refused {
    /// The scene does not build (its error names the file).
    Scene(loam_scene::SceneError),
    /// The solver's checks failed.
    Solver(String),
}

impl From<String> for Refused {
    fn from(msg: String) -> Self {
        Self::Solver(msg)
    }
}

fn check_dim<const D: usize>(
    scene: &Scene,
    max_steps: StepLimit,
) -> Result<(usize, Option<f64>, Vec<String>), Refused> {
    let built: Built<D> = scene.build().map_err(Refused::Scene)?;
    let n = built.particles.len();
    match built.plan {
        SolverPlan::Explicit(plan) => {
            let config = built.explicit_config().expect("an explicit plan");
            let solver = Solver::new(config, &built.particles).map_err(|e| e.to_string())?;
            let warnings =
                preflight::explicit(&built, &plan, &solver, &built.particles, max_steps)?;
            let steps = preflight::explicit_steps(&plan, &solver, &built.particles);
            Ok((n, Some(steps), warnings))
        }
        SolverPlan::Implicit(_) => Ok((n, None, Vec::new())),
    }
}
