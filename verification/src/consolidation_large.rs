//! Large-strain one-dimensional consolidation (`consolidation-large`): the coupled (u–p)
//! implicit solver against Gibson's finite-strain theory (solved by finite volumes in
//! `gibson.rs`), in GeoWarp's large-consolidation setting.
//!
//! A weightless column `H = 10 m`, 0.1 m wide, of Neo-Hookean soil (E = 36 kPa, ν = 0.2, so
//! the constrained modulus is `M = E(1−ν)/((1+ν)(1−2ν))` = 40 kPa), mobility
//! `κ = k/γ_w = 1e-6 m²/(Pa·s)`, between slip walls on a fixed, impermeable base, is loaded on
//! its top by `q = 10 kPa` in one undrained step at `t = 0` and consolidates, draining through
//! its top: `q/M = 0.25`, and the column shortens by `H(1 − λ_∞)` = 2.08 m (21 %). Time is
//! given as the small-strain time factor `T_v = κ M t/H²` (T_v = 1 at 2,500 s). The top
//! settles 2 m away from the grid's face, so it drains as a free surface that follows the soil
//! (`[[pore_fluid.drained_surface]]`); a drained grid face would stop draining once the soil
//! leaves it. The reference's coordinate is the distance from the drained top.
//!
//! Cells of 0.1 m as GeoWarp's, but 6 × 6 particles per cell instead of 2 × 2. The particles
//! are the quadrature of the grid's equations, and once the column has shortened they leave
//! the settlement high by an error that falls as `1/n²` with `n × n` particles per cell and
//! not with the cell size: with steps small enough to leave the time error out, at most
//! 2.9 % with 2 × 2 (4.2 % on cells of 0.025 m), 1.0 % with 4 × 4, 0.53 % with 6 × 6 and
//! 0.28 % with 8 × 8 (`docs/verification.md`).
//!
//! At `T_v` = 0.1, 0.2, 0.5, 1 and 2 (steps of 0.1 s growing by 3 % to `T_v = 2`):
//! - the settlement of the top row of particles against the reference's settlement of the
//!   same material points: within 1 %;
//! - the largest `|p − p_ref|/q` over the particles, the reference at each particle's initial
//!   height: at most 1e-2, the bar of the settlement (5.7e-3 measured: from `T_v = 0.5` on
//!   backward Euler's lag in time, as in `terzaghi`, which halves with half the steps'
//!   growth; at `T_v = 0.1`, the steep pressure near the drained top);
//! - Terzaghi's small-strain settlement of the same points against the reference, as
//!   information at each time (within 1 % up to `T_v = 0.2`, where the stiffening
//!   `dσ′/dλ > M` of the compressed soil makes up for its smaller final settlement; 13 % at
//!   `T_v = 1`, 20 % at `T_v = 2`), and its largest difference at least 5 %, five times the bar
//!   of the settlement: a small-strain solver could not pass the case.
//!
//! At full size, the largest settlement error over the times with 2 × 2 (GeoWarp's) and
//! 4 × 4 particles per cell is reported as information.
//!
//! Reduced size (the test suite): cells of 0.2 m and steps growing by 4 %.

use crate::gibson::{Gibson, Profile, Resolution};
use crate::terzaghi::{Column, Consolidation, coarsen_column, consolidate};
use crate::{CaseReport, Metric, Series, Size, VerifyError, scenes, write_csv, write_plot};
use loam_scene::Scene;
use std::path::Path;

const CASE: &str = "consolidation-large";
/// Output times (`T_v`).
const TIMES: [f64; 5] = [0.1, 0.2, 0.5, 1.0, 2.0];

/// The reference's settlement of the top row of particles, at height `top` on the fixed
/// base: the compression of the soil below it, which lies between `H − top` and `H` from the
/// drained top (the reference's coordinate).
fn top_settlement(exact: &Profile, height: f64, top: f64) -> f64 {
    exact.settlement(height) - exact.settlement(height - top)
}

/// The relative error of the top row's settlement at each output time against `exact`.
fn settlement_errors(run: &Consolidation, exact: &[&Profile], height: f64) -> Vec<f64> {
    run.snapshots
        .iter()
        .zip(exact)
        .map(|(snapshot, exact)| snapshot.settlement / top_settlement(exact, height, run.top) - 1.0)
        .collect()
}

/// The scene with `n × n` particles per cell.
fn with_particles(scene: &Scene, n: u32) -> Scene {
    let mut scene = scene.clone();
    scene.bodies[0].particles_per_cell = n;
    scene
}

/// Runs the case.
pub fn run(size: Size, out: &Path) -> Result<CaseReport, VerifyError> {
    let mut scene = scenes::scene("consolidation_large");
    if size == Size::Reduced {
        coarsen_column(&mut scene, 0.2);
        if let Some(steps) = scene.solver.consolidation.as_mut() {
            steps.growth = 1.04;
        }
    }
    let column = Column::of(&scene);
    let gibson = Gibson {
        height: column.height,
        load: column.load,
        mobility: column.mobility,
        shear_modulus: column.shear_modulus,
        lame: column.lame,
    };
    let times = TIMES.map(|tv| gibson.time(tv));
    let run = consolidate(CASE, &scene, &times)?;
    // The reference at every step of the run, the output times among them.
    let step_times: Vec<f64> = run.history.iter().map(|&(t, _)| t).collect();
    let reference = gibson.solve(&step_times, Resolution::CONVERGED);
    let exact: Vec<&Profile> = times
        .iter()
        .map(|&t| {
            let k = step_times
                .iter()
                .position(|&s| (s - t).abs() <= 1e-9 * t)
                .expect("the run lands on the output times");
            &reference[k]
        })
        .collect();
    let tv_of = |t: f64| t * gibson.cv() / (gibson.height * gibson.height);
    // Terzaghi's settlement of the top row, `H − top` below the drained top.
    let small = |tv: f64| column.settlement(gibson.height - run.top, tv);
    let errors = settlement_errors(&run, &exact, gibson.height);
    let mut metrics = Vec::new();
    let mut difference = 0.0f64;
    for (((snapshot, exact), error), tv) in run.snapshots.iter().zip(&exact).zip(&errors).zip(TIMES)
    {
        metrics.push(Metric::at_most(
            CASE,
            &format!("settlement_rel_error_tv{tv}"),
            error.abs(),
            1e-2,
        ));
        let p_error = snapshot
            .pressures
            .iter()
            .map(|&(y, p)| (p - exact.pressure(gibson.height - y)).abs() / gibson.load)
            .fold(0.0f64, f64::max);
        metrics.push(Metric::at_most(
            CASE,
            &format!("p_error_tv{tv}"),
            p_error,
            1e-2,
        ));
        let small_strain = small(tv) / top_settlement(exact, gibson.height, run.top) - 1.0;
        difference = difference.max(small_strain.abs());
        metrics.push(Metric::info(
            CASE,
            &format!("small_strain_settlement_difference_tv{tv}"),
            small_strain,
        ));
    }
    metrics.push(Metric::at_least(
        CASE,
        "small_strain_settlement_difference_max",
        difference,
        5e-2,
    ));
    if size == Size::Full {
        for n in [2, 4] {
            let coarse = consolidate(CASE, &with_particles(&scene, n), &times)?;
            let worst = settlement_errors(&coarse, &exact, gibson.height)
                .iter()
                .fold(0.0f64, |m, e| m.max(e.abs()));
            metrics.push(Metric::info(
                CASE,
                &format!("settlement_rel_error_max_{n}x{n}_particles"),
                worst,
            ));
        }
    }
    let rows: Vec<Vec<f64>> = run
        .history
        .iter()
        .zip(&reference)
        .map(|(&(t, s), exact)| {
            let tv = tv_of(t);
            vec![
                t,
                tv,
                s,
                top_settlement(exact, gibson.height, run.top),
                small(tv),
            ]
        })
        .collect();
    let csv = out.join("consolidation_large.csv");
    write_csv(
        &csv,
        &[
            "t",
            "T_v",
            "settlement_loam",
            "settlement_gibson",
            "settlement_terzaghi",
        ],
        &rows,
    )?;
    let png = out.join("consolidation_large.png");
    let curve = |name: &str, column: usize, markers: bool| Series {
        name: name.into(),
        points: rows.iter().map(|r| (r[1], r[column])).collect(),
        markers,
    };
    write_plot(
        &png,
        "Large-strain consolidation (q/M = 0.25): settlement of the top",
        "T_v = c_v t / H² (small-strain c_v)",
        "settlement (m)",
        &[
            curve("loam", 2, true),
            curve("Gibson, finite strain (finite volumes)", 3, false),
            curve("Terzaghi, small strain", 4, false),
        ],
    )?;
    Ok(CaseReport {
        metrics,
        files: vec![csv, png],
    })
}
