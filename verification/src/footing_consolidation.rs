//! A rigid square footing on a saturated elastic block in 3D (`footing-consolidation-3d`): the
//! coupled (u–p) implicit solver's immediate and long-term settlements and the consolidation
//! between them.
//!
//! A quarter of the block by symmetry (`verification/scenes/footing_consolidation_3d.toml`):
//! slip walls on the planes of symmetry and the far sides, a fixed base, the top surface free
//! and drained; a smooth rigid footing of width `B` on it, force-controlled (the top nodes
//! under it share one vertical unknown), loaded by `P` in one undrained step at `t = 0` and
//! held while the block drains through its surface.
//!
//! On an elastic half-space the settlement of a rigid footing under `P` is
//! `s = P (1 − ν) / (β G B)`, with `β = 2.27` for a square (Gazetas 1991, "Formulas and charts
//! for impedances of surface and embedded foundations", J. Geotech. Eng. 117(9), Table 1:
//! static vertical stiffness `K_z = 2 G L (0.73 + 1.54 χ^0.75)/(1 − ν)` with `χ = 1`,
//! `L = B/2`). The undrained response of a soil with incompressible constituents is that of
//! an elastic solid with the same `G` and `ν_u = 0.5`, so the immediate settlement is
//! `(1 − ν_u)/(1 − ν)` of the long-term one whatever the footing's shape.
//!
//! Metrics:
//! - the immediate settlement over the long-term one against the half-space's
//!   `(1 − ν_u)/(1 − ν)` = 0.625: within 5 % (the block is finite, 6 footing half-widths wide
//!   and deep, and the footing two cells wide; the ratio's error was 3.0 % there and 10.8 %
//!   with the footing one cell wide, the reduced size, whose tolerance is 12 %);
//! - the long-term settlement (the last step, `c_v t/H² ≈ 5`) against a drained run of the
//!   same block (no pore fluid; the load in 20 steps, so that both follow the geometry):
//!   within 1 % (a fully drained coupled run is the drained solid);
//! - the immediate step keeps the volume below the top two layers of cells: `|Σ V₀ (J − 1)|`
//!   over those particles, over the volume the footing displaces (`s B²/4` in the quarter), at
//!   most 1 % (0.49 % at the reduced size). The top layers are left out: the drained surface's
//!   nodes hold `p = 0` in a step without time, so the cells under them drain at once, and the
//!   stabilisation's projection over cells reaches one cell further (a boundary layer like
//!   `mandel`'s drained side, whose volume halves with the cell size: 47 % of the displaced
//!   volume with cells of 0.5 m, 23 % with 0.25 m, reported for the whole block);
//! - the consolidation curve between them: the settlement never decreases from one step to
//!   the next (by more than 1e-9 of the long-term settlement).
//!
//! The settlements against the half-space's `P (1 − ν)/(β G B)` are reported (information:
//! the finite block is stiffer).
//!
//! Reduced size (the test suite): cells of 0.5 m, the steps growing by 1.5.

use crate::{CaseReport, Metric, Series, Size, VerifyError, scenes, write_csv, write_plot};
use loam_core::Particles;
use loam_implicit::{ImplicitSolver, StepReport};
use loam_scene::Scene;
use std::path::Path;

const CASE: &str = "footing-consolidation-3d";
/// Gazetas' `β` of a rigid square footing on a half-space (module documentation).
const GAZETAS_SQUARE: f64 = 2.27;
/// Poisson's ratio of the undrained soil with incompressible constituents.
const UNDRAINED_POISSON: f64 = 0.5;
/// Load steps of the drained reference run.
const DRAINED_LOAD_STEPS: usize = 20;

/// The footing and the soil of the scene.
struct Footing {
    /// Full width `B` (m): twice the quarter's.
    width: f64,
    /// Full load `P` (N): four times the quarter's.
    load: f64,
    /// Shear modulus `G` (Pa).
    shear_modulus: f64,
    /// Drained Poisson's ratio `ν`.
    poisson: f64,
    /// Consolidation coefficient `c_v = (k/γ_w) E(1 − ν)/((1 + ν)(1 − 2ν))` (m²/s).
    cv: f64,
    /// Depth of the block `H` (m).
    depth: f64,
}

impl Footing {
    fn of(scene: &Scene) -> Self {
        let m = &scene.materials[0];
        let (e, nu) = (
            m.youngs_modulus.unwrap_or(0.0),
            m.poisson_ratio.unwrap_or(0.0),
        );
        let c = &scene.constraints[0];
        let unit_weight = scene.pore_fluid.as_ref().map_or(9810.0, |f| f.unit_weight);
        let mobility = m.hydraulic_conductivity.unwrap_or(0.0) / unit_weight;
        Self {
            width: 2.0 * (c.hi[0] - c.lo[0]),
            load: -4.0 * c.force.get(2).copied().flatten().unwrap_or(0.0),
            shear_modulus: e / (2.0 * (1.0 + nu)),
            poisson: nu,
            cv: mobility * e * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            depth: scene.grid.hi[2] - scene.grid.lo[2],
        }
    }

    /// The half-space's settlement with Poisson's ratio `nu` (m).
    fn half_space(&self, nu: f64) -> f64 {
        self.load * (1.0 - nu) / (GAZETAS_SQUARE * self.shear_modulus * self.width)
    }

    /// `T = c_v t / H²`.
    fn time_factor(&self, t: f64) -> f64 {
        self.cv * t / (self.depth * self.depth)
    }
}

/// The footing's settlement in a step's report (m, downwards positive).
fn settlement(report: &StepReport<3>) -> f64 {
    -report.constraint_displacements[0][2]
}

/// `Σ V₀ (J − 1)` over the particles below `depth` (m³).
fn volume_change(particles: &Particles<f64, 3>, depth: f64) -> f64 {
    (0..particles.len())
        .filter(|&p| particles.x[p][2] < depth)
        .map(|p| particles.volume0[p] * (particles.f[p].determinant() - 1.0))
        .sum()
}

/// What a coupled run gives.
struct Consolidation {
    /// `(t, settlement)` after every step.
    curve: Vec<(f64, f64)>,
    /// The volume change of the first (undrained) step: of the soil below the depth asked
    /// for, and of all of it (m³).
    undrained_volume_change: [f64; 2],
}

/// A coupled run, with the undrained step's volume change below `depth`.
fn consolidate(scene: &Scene, depth: f64) -> Result<Consolidation, VerifyError> {
    let built = scenes::build::<3>(scene);
    let config = built.implicit_config().expect("an implicit scene");
    let mut particles = built.particles;
    let fail = |source| VerifyError::Implicit {
        case: CASE.into(),
        source,
    };
    let mut solver = ImplicitSolver::new(config, &particles).map_err(fail)?;
    let mut curve = Vec::new();
    let mut undrained_volume_change = None;
    while !solver.finished() {
        let report = solver.step(&mut particles).map_err(fail)?;
        undrained_volume_change.get_or_insert_with(|| {
            [
                volume_change(&particles, depth),
                volume_change(&particles, f64::INFINITY),
            ]
        });
        curve.push((solver.time(), settlement(&report)));
    }
    Ok(Consolidation {
        curve,
        undrained_volume_change: undrained_volume_change.unwrap_or_default(),
    })
}

/// The settlement of the same block without pore fluid, the load in
/// [`DRAINED_LOAD_STEPS`] steps.
fn drained(scene: &Scene) -> Result<f64, VerifyError> {
    let mut scene = scene.clone();
    scene.pore_fluid = None;
    scene.solver.consolidation = None;
    scene.solver.load_steps = Some(DRAINED_LOAD_STEPS);
    for m in &mut scene.materials {
        m.hydraulic_conductivity = None;
    }
    let built = scenes::build::<3>(&scene);
    let config = built.implicit_config().expect("an implicit scene");
    let mut particles = built.particles;
    let fail = |source| VerifyError::Implicit {
        case: CASE.into(),
        source,
    };
    let mut solver = ImplicitSolver::new(config, &particles).map_err(fail)?;
    let mut last = 0.0;
    while !solver.finished() {
        last = settlement(&solver.step(&mut particles).map_err(fail)?);
    }
    Ok(last)
}

/// Runs the case.
pub fn run(size: Size, out: &Path) -> Result<CaseReport, VerifyError> {
    let mut scene = scenes::scene("footing_consolidation_3d");
    let mut ratio_tolerance = 0.05;
    if size == Size::Reduced {
        scene.grid.cell_size = 0.5;
        if let Some(steps) = scene.solver.consolidation.as_mut() {
            steps.growth = 1.5;
        }
        // The footing one cell wide (module documentation).
        ratio_tolerance = 0.12;
    }
    let footing = Footing::of(&scene);
    let Consolidation {
        curve,
        undrained_volume_change: [volume_below, volume],
    } = consolidate(&scene, footing.depth - 2.0 * scene.grid.cell_size)?;
    let s_drained = drained(&scene)?;
    let immediate = curve.first().map_or(0.0, |&(_, s)| s);
    let long_term = curve.last().map_or(0.0, |&(_, s)| s);
    let expected_ratio = (1.0 - UNDRAINED_POISSON) / (1.0 - footing.poisson);
    let largest_decrease = curve
        .windows(2)
        .map(|w| w[0].1 - w[1].1)
        .fold(0.0f64, f64::max);
    let quarter_area = footing.width * footing.width / 4.0;
    let metrics = vec![
        Metric::info(CASE, "steps", curve.len() as f64),
        Metric::info(CASE, "immediate_settlement_mm", 1e3 * immediate),
        Metric::info(CASE, "long_term_settlement_mm", 1e3 * long_term),
        Metric::at_most(
            CASE,
            "immediate_over_long_term_rel_error",
            (immediate / long_term / expected_ratio - 1.0).abs(),
            ratio_tolerance,
        ),
        Metric::at_most(
            CASE,
            "long_term_vs_drained_rel_error",
            (long_term / s_drained - 1.0).abs(),
            0.01,
        ),
        Metric::at_most(
            CASE,
            "undrained_volume_change_below_top_cells",
            volume_below.abs() / (immediate * quarter_area),
            0.01,
        ),
        Metric::info(
            CASE,
            "undrained_volume_change",
            volume.abs() / (immediate * quarter_area),
        ),
        Metric::at_most(
            CASE,
            "settlement_largest_decrease",
            largest_decrease / long_term,
            1e-9,
        ),
        Metric::info(
            CASE,
            "immediate_over_half_space",
            immediate / footing.half_space(UNDRAINED_POISSON),
        ),
        Metric::info(
            CASE,
            "long_term_over_half_space",
            long_term / footing.half_space(footing.poisson),
        ),
    ];
    let csv = out.join("footing_consolidation_3d.csv");
    let rows: Vec<Vec<f64>> = curve
        .iter()
        .map(|&(t, s)| {
            vec![
                t,
                footing.time_factor(t),
                s,
                (s - immediate) / (s_drained - immediate),
            ]
        })
        .collect();
    write_csv(
        &csv,
        &["t_s", "T", "settlement_m", "degree_of_consolidation"],
        &rows,
    )?;
    let png = out.join("footing_consolidation_3d.png");
    // Times on a log axis; the undrained step (t = 0) at the first step's time.
    let first = curve.get(1).map_or(1.0, |&(t, _)| t);
    let log_t = |t: f64| footing.time_factor(t.max(first)).log10();
    let (t0, t1) = (log_t(first), log_t(curve.last().map_or(first, |&(t, _)| t)));
    let level = |name: &str, s: f64| Series {
        name: name.into(),
        points: vec![(t0, 1e3 * s), (t1, 1e3 * s)],
        markers: false,
    };
    write_plot(
        &png,
        "Rigid square footing on a saturated elastic block: settlement",
        "log₁₀ T (T = c_v t / H²)",
        "settlement (mm)",
        &[
            Series {
                name: "loam, coupled u–p".into(),
                points: curve.iter().map(|&(t, s)| (log_t(t), 1e3 * s)).collect(),
                markers: true,
            },
            level("drained run", s_drained),
            level(
                "(1 − ν_u)/(1 − ν) × drained run",
                expected_ratio * s_drained,
            ),
        ],
    )?;
    Ok(CaseReport {
        metrics,
        files: vec![csv, png],
    })
}
