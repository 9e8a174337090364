//! The axial bar of [`crate::axial_bar`] run by the implicit solver with Newmark dynamics
//! (β = ¼, γ = ½, consistent mass) at time steps above the explicit stability limit.
//!
//! The trapezoidal rule is unconditionally stable and conserves the energy of a linear system;
//! its period error is O((ωΔt)²), so the error must fall with Δt at a fixed grid.

use crate::axial_bar::{
    DENSITY, Setup, YOUNG, duration, first_mode_velocity, max_relative_error, write_history,
};
use crate::{CaseReport, Metric, Size, VerifyError, scenes};
use loam_implicit::{ImplicitError, ImplicitSolver};
use loam_scene::Scene;
use std::path::Path;

/// The scene of the bar with `cells` cells and `Δt = courant · h/c` over 2.5 periods:
/// `verification/scenes/axial_bar_newmark.toml` discretised as the explicit bar
/// ([`Setup::discretise`]), with that Newmark step and step count.
pub fn scene(cells: usize, courant: f64) -> Scene {
    let setup = Setup::new(cells);
    let mut scene = scenes::scene("axial_bar_newmark");
    setup.discretise(&mut scene);
    let dt = courant * setup.h() / (YOUNG / DENSITY).sqrt();
    scene.solver.newmark_dt = Some(dt);
    scene.solver.load_steps = Some((duration() / dt).round() as usize);
    scene
}

/// Centre-of-mass velocity history of the bar with `cells` cells and `Δt = courant · h/c`.
pub fn history(cells: usize, courant: f64) -> Result<(Vec<(f64, f64)>, usize), ImplicitError> {
    let mut built = scenes::build::<2>(&scene(cells, courant));
    first_mode_velocity(&mut built.particles);
    let config = built
        .implicit_config()
        .expect("the Newmark bar is an implicit scene");
    let dt = config.dynamics.expect("the Newmark bar runs dynamics");
    let mut particles = built.particles;
    let mut solver = ImplicitSolver::new(config, &particles)?;
    let mut out = vec![(0.0, particles.centre_of_mass_velocity()[0])];
    let mut iterations = 0;
    while !solver.finished() {
        iterations += solver.step(&mut particles)?.iterations();
        out.push((
            solver.steps() as f64 * dt,
            particles.centre_of_mass_velocity()[0],
        ));
    }
    Ok((out, iterations))
}

/// Runs the case.
pub fn run(_size: Size, out: &Path) -> Result<CaseReport, VerifyError> {
    const CASE: &str = "axial-bar-newmark";
    let err = |source| VerifyError::Implicit {
        case: CASE.into(),
        source,
    };
    // 80 cells at both sizes: the run takes well under a second.
    let cells = 80;
    // Δt = 2 h/c is 10× the explicit run's step and twice its stability limit.
    let (hist, _) = history(cells, 2.0).map_err(err)?;
    let (coarse, _) = history(cells, 4.0).map_err(err)?;
    let e = max_relative_error(&hist);
    let e_coarse = max_relative_error(&coarse);
    let (csv, png) = write_history(
        out,
        "axial_bar_newmark",
        &format!("Axial bar, implicit Newmark, {cells} cells, dt = 2 h/c"),
        &hist,
    )?;
    Ok(CaseReport {
        metrics: vec![
            // The explicit case's goal, 1 %, at twice the explicit stability limit.
            Metric::at_most(CASE, "max_rel_error_vcm_dt_2h_over_c", e, 0.01),
            // Halving Δt from 4 h/c to 2 h/c: the O(Δt²) period error must fall by at least 2×.
            Metric::at_least(CASE, "error_ratio_dt_halved", e_coarse / e, 2.0),
        ],
        files: vec![csv, png],
    })
}
