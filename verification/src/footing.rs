//! Bearing capacity of a rigid strip footing on weightless Tresca soil (Prandtl).
//!
//! A smooth rigid footing of half-width b = 1 m is pushed into a weightless, perfectly plastic
//! J2 soil (plane strain, so von Mises with σ_y = √3 c_u is Tresca with undrained strength c_u).
//! The limit pressure is Prandtl's `q_u = (2 + π) c_u`. By symmetry half the problem is
//! modelled: x ∈ [0, 5b] (slip walls on both sides), y ∈ [0, 5b] (fixed base), free surface on
//! top. The footing prescribes the vertical displacement of the grid nodes under it (the
//! surface row and the row above it, which the surface particles' B-spline supports reach); the
//! pressure is the reaction of those nodes over b.

use crate::{CaseReport, Metric, Series, Size, VerifyError, scenes, write_csv, write_plot};
use loam_implicit::ImplicitSolver;
use loam_scene::Scene;
use std::f64::consts::PI;
use std::path::Path;

/// Footing half-width b (m).
pub const HALF_WIDTH: f64 = 1.0;
/// Undrained shear strength c_u (Pa).
pub const CU: f64 = 10.0e3;
/// Young's modulus (Pa): E / c_u = 1000.
pub const YOUNG: f64 = 10.0e6;

/// The footing with `n` cells per half-width pushed `settlement` into the soil in `steps`
/// load steps: `verification/scenes/footing_prandtl.toml` with that cell size (the grid two
/// cells taller than the soil) and the footing's node rows (the surface row and the one above
/// it) moved with it.
pub fn scene(n: usize, steps: usize, settlement: f64) -> Scene {
    let mut scene = scenes::scene("footing_prandtl");
    let h = HALF_WIDTH / n as f64;
    let depth = 5.0 * HALF_WIDTH;
    scene.grid.cell_size = h;
    scene.grid.hi = vec![depth, (5 * n + 2) as f64 * h];
    let footing = &mut scene.constraints[0];
    footing.lo = vec![0.0, depth];
    footing.hi = vec![HALF_WIDTH, depth + h];
    footing.displacement = vec![None, Some(-settlement)];
    scene.solver.load_steps = Some(steps);
    scene
}

/// Runs the footing with `n` cells per half-width; returns (settlement, pressure / c_u) per step.
pub fn load_curve(
    n: usize,
    steps: usize,
    settlement: f64,
) -> Result<Vec<(f64, f64)>, loam_implicit::ImplicitError> {
    let built = scenes::build::<2>(&scene(n, steps, settlement));
    let config = built
        .implicit_config()
        .expect("the footing is an implicit scene");
    let mut particles = built.particles;
    let mut solver = ImplicitSolver::new(config, &particles)?;
    let mut curve = vec![(0.0, 0.0)];
    while !solver.finished() {
        let r = solver.step(&mut particles)?;
        curve.push((
            r.load_factor * settlement,
            -r.constraint_forces[0][1] / HALF_WIDTH / CU,
        ));
    }
    Ok(curve)
}

/// Runs the case.
pub fn run(size: Size, out: &Path) -> Result<CaseReport, VerifyError> {
    const CASE: &str = "footing-prandtl";
    let n = match size {
        Size::Reduced => 4,
        Size::Full => 8,
    };
    let curve = load_curve(n, 40, 0.1 * HALF_WIDTH).map_err(|source| VerifyError::Implicit {
        case: CASE.into(),
        source,
    })?;
    let exact = 2.0 + PI;
    let limit = curve.last().map_or(0.0, |c| c.1);
    let csv = out.join("footing.csv");
    let rows: Vec<Vec<f64>> = curve.iter().map(|&(s, q)| vec![s, q, exact]).collect();
    write_csv(
        &csv,
        &["settlement_m", "pressure_over_cu", "prandtl"],
        &rows,
    )?;
    let png = out.join("footing.png");
    write_plot(
        &png,
        &format!("Strip footing on Tresca soil, h = b/{n}"),
        "settlement (m)",
        "q / c_u",
        &[
            Series {
                name: "Prandtl (2 + π)".into(),
                points: vec![(0.0, exact), (0.1 * HALF_WIDTH, exact)],
                markers: false,
            },
            Series {
                name: "loam".into(),
                points: curve.clone(),
                markers: true,
            },
        ],
    )?;
    Ok(CaseReport {
        metrics: vec![Metric::at_most(
            CASE,
            "limit_pressure_rel_error",
            (limit - exact).abs() / exact,
            match size {
                // Goal of the benchmark: within 5 % of (2 + π) c_u.
                Size::Full => 0.05,
                // h = b/4: the footing edge is only resolved to ±h/2 = ±12 % of b.
                Size::Reduced => 0.15,
            },
        )],
        files: vec![csv, png],
    })
}
