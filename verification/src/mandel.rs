//! Mandel's problem (`mandel`): the coupled (u–p) implicit solver with a force-controlled
//! rigid plate against the series solution (Cheng & Detournay 1988), in plane strain.
//!
//! A quarter of the specimen, `x ∈ [0, a]`, `y ∈ [0, b]`, between slip walls on the planes of
//! symmetry, drained at `x = a`, under a smooth rigid plate on `y = b` that carries the force
//! `F` (per metre run, on the half width) from `t = 0` on (`verification/scenes/mandel.toml`;
//! the series is [`crate::mandel_series`]). The pressure depends on `x` and `t` alone; the
//! undrained loading gives `p₀ = B(1 + ν_u)F/(3a)` everywhere, and the centre's pressure then
//! rises above it before it decays (the Mandel–Cryer effect).
//!
//! Metrics:
//! - the undrained loading alone (the `t = 0` step), over the inner half `x < a/2` (the
//!   drained side's `p = 0` reaches a few cells in through the stabilisation's projection
//!   over cells): the spread of `p/p₀` is at most 1e-3 with the pressure
//!   stabilisation and at least 0.1 without it (equal-order interpolation lets the pressure
//!   alternate from node to node: the stabilisation matters); their mean is within 2 % of
//!   `p₀` (the drained side's boundary layer, one cell wide in a step without time, carries
//!   less of the load: an `O(h/a)` error);
//! - at `T = c t / a²` = 0.01, 0.05, 0.1, 0.5 and 1: the RMS over the particles of
//!   `(p − p_exact(x))/p₀` at most 2 %, and the plate's settlement within 2 % of the series;
//! - the centre's peak: the largest pressure over time of the particles nearest `x = 0`
//!   within 2 % of the series' largest at their `x`, and above `p₀` (the effect itself).
//!
//! Reduced size (the test suite): cells of 0.1 m and steps growing from `ΔT = 5e-4`.

use crate::mandel_series::Mandel;
use crate::terzaghi::undrained_loading;
use crate::{CaseReport, Metric, Series, Size, VerifyError, scenes, write_csv, write_plot};
use loam_implicit::ImplicitSolver;
use loam_scene::Scene;
use std::path::Path;

const CASE: &str = "mandel";
/// Output times (T = c t / a²).
const TIMES: [f64; 5] = [0.01, 0.05, 0.1, 0.5, 1.0];

/// The series solution of the scene's specimen.
fn series(scene: &Scene) -> Mandel {
    let m = &scene.materials[0];
    let (e, nu) = (
        m.youngs_modulus.unwrap_or(0.0),
        m.poisson_ratio.unwrap_or(0.0),
    );
    let unit_weight = scene.pore_fluid.as_ref().map_or(9810.0, |f| f.unit_weight);
    let force = scene.constraints[0]
        .force
        .get(1)
        .copied()
        .flatten()
        .unwrap_or(0.0);
    Mandel {
        bulk_modulus: e / (3.0 * (1.0 - 2.0 * nu)),
        shear_modulus: e / (2.0 * (1.0 + nu)),
        biot_coefficient: m.biot_coefficient.unwrap_or(1.0),
        biot_modulus: f64::INFINITY,
        mobility: m.hydraulic_conductivity.unwrap_or(0.0) / unit_weight,
        half_width: scene.grid.hi[0] - scene.grid.lo[0],
        force: -force,
    }
}

/// A run's figures.
struct Run {
    /// Per output time: `(T, RMS (p − p_exact)/p₀, plate settlement / exact − 1)`.
    rows: Vec<(f64, f64, f64)>,
    /// Per output time, `(x, p/p₀)` of every particle.
    profiles: Vec<Vec<(f64, f64)>>,
    /// `(T, p/p₀)` of the centre particles after every step.
    centre: Vec<(f64, f64)>,
    /// The centre particles' initial `x`.
    centre_x: f64,
}

fn run_with(scene: &Scene, mandel: &Mandel) -> Result<Run, VerifyError> {
    let mut built = scenes::build::<2>(scene);
    let fluid = built.pore_fluid.as_mut().expect("a coupled scene");
    for tv in TIMES {
        fluid.schedule.land_on(mandel.time(tv));
    }
    let config = built.implicit_config().expect("an implicit scene");
    let mut particles = built.particles;
    let x0: Vec<f64> = particles.x.iter().map(|x| x[0]).collect();
    let centre_x = x0.iter().fold(f64::INFINITY, |m, &x| m.min(x));
    let centre: Vec<usize> = (0..x0.len()).filter(|&p| x0[p] == centre_x).collect();
    let p0 = mandel.initial_pressure();
    let fail = |source| VerifyError::Implicit {
        case: CASE.into(),
        source,
    };
    let mut solver = ImplicitSolver::new(config, &particles).map_err(fail)?;
    let height = scene.grid.hi[1] - scene.grid.lo[1];
    let mut run = Run {
        rows: Vec::new(),
        profiles: Vec::new(),
        centre: Vec::new(),
        centre_x,
    };
    while !solver.finished() {
        let report = solver.step(&mut particles).map_err(fail)?;
        let t = solver.time();
        if t > 0.0 {
            let mean = centre
                .iter()
                .map(|&p| particles.pore_pressure[p])
                .sum::<f64>()
                / centre.len() as f64;
            run.centre.push((mandel.time_factor(t), mean / p0));
        }
        let Some(&tv) = TIMES
            .iter()
            .find(|&&tv| (mandel.time(tv) - t).abs() <= 1e-9 * t)
        else {
            continue;
        };
        let profile: Vec<(f64, f64)> = (0..particles.len())
            .map(|p| (x0[p], particles.pore_pressure[p] / p0))
            .collect();
        let rms = (profile
            .iter()
            .map(|&(x, p)| (p - mandel.pressure(x, t) / p0).powi(2))
            .sum::<f64>()
            / profile.len() as f64)
            .sqrt();
        let plate = report.constraint_displacements[0][1];
        let exact = mandel.displacement_y(height, t);
        run.rows.push((tv, rms, plate / exact - 1.0));
        run.profiles.push(profile);
    }
    Ok(run)
}

/// The undrained loading alone, with the stabilisation on or off, over the inner half of the
/// specimen (`x < a/2`): the spread `(max p − min p)/p₀` (a checkerboard's
/// amplitude) and the mean's `|p̄/p₀ − 1|`.
fn undrained(scene: &Scene, p0: f64, stabilisation: bool) -> Result<(f64, f64), VerifyError> {
    let particles = undrained_loading(CASE, scene, stabilisation)?;
    let edge = 0.5 * (scene.grid.hi[0] - scene.grid.lo[0]);
    let inner: Vec<f64> = (0..particles.len())
        .filter(|&p| particles.x[p][0] < edge)
        .map(|p| particles.pore_pressure[p] / p0)
        .collect();
    let (lo, hi) = inner
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &p| {
            (l.min(p), h.max(p))
        });
    let mean = inner.iter().sum::<f64>() / inner.len() as f64;
    Ok((hi - lo, (mean - 1.0).abs()))
}

/// Runs the case.
pub fn run(size: Size, out: &Path) -> Result<CaseReport, VerifyError> {
    let mut scene = scenes::scene("mandel");
    if size == Size::Reduced {
        scene.grid.cell_size = 0.1;
        if let Some(steps) = scene.solver.consolidation.as_mut() {
            steps.time_step *= 4.0;
            steps.growth = 1.1;
        }
    }
    let mandel = series(&scene);
    let p0 = mandel.initial_pressure();
    // Undrained, the pressure is p₀ everywhere. Equal-order interpolation without the
    // stabilisation lets it alternate from node to node instead. The level is off by the
    // drained side's boundary layer, one cell wide in a step without time (p = 0 on the
    // side's nodes), which carries less of the load: an O(h/a) error.
    let (spread, level) = undrained(&scene, p0, true)?;
    let (spread_off, _) = undrained(&scene, p0, false)?;
    let mut metrics = vec![
        Metric::at_most(CASE, "undrained_p_spread_stabilised", spread, 1e-3),
        Metric::at_least(CASE, "undrained_p_spread_unstabilised", spread_off, 0.1),
        Metric::at_most(CASE, "undrained_p_mean_error", level, 0.02),
    ];
    let run = run_with(&scene, &mandel)?;
    metrics.push(Metric::info(CASE, "steps", run.centre.len() as f64));
    for &(tv, rms, plate) in &run.rows {
        metrics.push(Metric::at_most(
            CASE,
            &format!("p_rms_error_t{tv}"),
            rms,
            0.02,
        ));
        metrics.push(Metric::at_most(
            CASE,
            &format!("plate_settlement_rel_error_t{tv}"),
            plate.abs(),
            0.02,
        ));
    }
    // The centre's peak against the series' at the same x, found on a fine grid of times
    // (the peak is flat: a step of 1e-3 in T changes it by less than 1e-5).
    let peak = run.centre.iter().fold(0.0f64, |m, &(_, p)| m.max(p));
    let exact_peak = (1..=1000)
        .map(|k| mandel.pressure(run.centre_x, mandel.time(k as f64 * 1e-3)) / p0)
        .fold(0.0f64, f64::max);
    metrics.push(Metric::at_least(CASE, "centre_peak_over_p0", peak, 1.0));
    metrics.push(Metric::at_most(
        CASE,
        "centre_peak_rel_error",
        (peak / exact_peak - 1.0).abs(),
        0.02,
    ));
    let csv = out.join("mandel.csv");
    let rows: Vec<Vec<f64>> = run
        .centre
        .iter()
        .map(|&(tv, p)| vec![tv, p, mandel.pressure(run.centre_x, mandel.time(tv)) / p0])
        .collect();
    write_csv(&csv, &["T", "centre_p_over_p0", "series_p_over_p0"], &rows)?;
    let png = out.join("mandel.png");
    let mut curves = Vec::new();
    for (k, &tv) in TIMES.iter().enumerate() {
        let Some(profile) = run.profiles.get(k) else {
            continue;
        };
        curves.push(Series {
            name: format!("loam, T = {tv}"),
            points: profile.clone(),
            markers: true,
        });
        curves.push(Series {
            name: format!("Mandel, T = {tv}"),
            points: (0..=100)
                .map(|i| {
                    let x = mandel.half_width * i as f64 / 100.0;
                    (x, mandel.pressure(x, mandel.time(tv)) / p0)
                })
                .collect(),
            markers: false,
        });
    }
    write_plot(
        &png,
        "Mandel's problem: pore pressure across the specimen (drained at x = a)",
        "x (m)",
        "p / p₀",
        &curves,
    )?;
    Ok(CaseReport {
        metrics,
        files: vec![csv, png],
    })
}
