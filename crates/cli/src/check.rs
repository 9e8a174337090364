//! `loam check`: parse, validate and build a scene without running it.

use crate::Outcome;
use loam_scene::{Scene, SceneError};
use std::path::Path;

/// Loads and builds the scene; returns the particle count.
fn particle_count(scene: &Scene) -> Result<usize, SceneError> {
    Ok(match scene.dim() {
        2 => scene.build::<2>()?.particles.len(),
        _ => scene.build::<3>()?.particles.len(),
    })
}

/// Validates `path`, printing a one-line summary or the problems.
pub fn check(path: &Path) -> Outcome {
    let result = Scene::from_path(path).and_then(|s| particle_count(&s).map(|n| (s, n)));
    match result {
        Ok((scene, n)) => {
            let extent = match (scene.solver.end_time, scene.solver.load_steps) {
                (Some(t), _) => format!("end time {t} s"),
                (None, Some(n)) => format!("{n} load steps"),
                (None, None) => String::new(),
            };
            println!(
                "{}: valid {}D {} scene, {} material(s), {} bod(y/ies), {n} particles, {extent}",
                path.display(),
                scene.dim(),
                scene.solver.kind.name(),
                scene.materials.len(),
                scene.bodies.len(),
            );
            Outcome::Ok
        }
        Err(e) => {
            eprintln!("error: {e}");
            Outcome::BadInput
        }
    }
}
