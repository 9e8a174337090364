//! Helpers shared by the integration tests that drive the explicit solver in process.

use loam_explicit::Config;
use loam_scene::{Built, SolverPlan};

/// The solver configuration of a built explicit scene, as `loam run` makes it.
pub fn config<const D: usize>(built: &Built<D>) -> Config<f64, D> {
    let SolverPlan::Explicit(plan) = built.plan else {
        panic!("an explicit scene");
    };
    Config {
        grid: built.grid.clone(),
        shape: built.shape,
        transfer: plan.transfer,
        scheme: plan.scheme,
        boundary: built.boundary,
        contact: built.contact.clone(),
        gravity: built.gravity,
        materials: built.materials.clone(),
        time_step: plan.time_step,
    }
}
