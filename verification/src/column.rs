//! A soil column compacting under its own weight (quasi-static, large deformation).
//!
//! A column of height H = 50 m rests on a fixed base between frictionless (slip) walls, so it
//! deforms in uniaxial strain. Gravity g = 10 m/s² is ramped over 40 load steps; E = 10 kPa,
//! ν = 0, ρ₀ = 80 kg/m³, Hencky elasticity. The bottom is compressed to about 30 % of its height.
//! Whatever the material, equilibrium and mass conservation give the exact vertical Cauchy
//! stress at a particle that started at height Y₀: `σ_yy = −ρ₀ g (H − Y₀)`. The error norm is
//! `Σ_p |σ_yy − σ_exact| V⁰_p / Σ_p ρ₀ g H V⁰_p`.

use crate::{CaseReport, Metric, Series, Size, VerifyError, write_csv, write_plot, write_text};
use loam_core::tensor::Vector;
use loam_core::{Boundary, Grid, Material, ModelKind, Particles, Shape, Wall, WallKind};
use loam_implicit::{ImplicitConfig, ImplicitSolver, NewtonSettings};
use std::path::Path;

/// Column height (m).
pub const HEIGHT: f64 = 50.0;
/// Young's modulus (Pa).
pub const YOUNG: f64 = 10.0e3;
/// Reference density (kg/m³).
pub const DENSITY: f64 = 80.0;
/// Gravity (m/s²).
pub const GRAVITY: f64 = 10.0;

/// A particle's reference height `Y₀` and its final `σ_yy`, `σ_xx` (Pa).
pub type Sample = (f64, f64, f64);

/// Discretisation of the column.
#[derive(Clone, Copy, Debug)]
pub struct Setup {
    /// Cells over the height.
    pub cells: usize,
    /// Particles per cell per axis.
    pub ppc: usize,
    /// Load steps.
    pub steps: usize,
    /// Shape functions.
    pub shape: Shape,
}

impl Setup {
    /// cpGIMP, 2×2 particles per cell, 40 load steps.
    ///
    /// cpGIMP because the bottom particles are compressed to ~30 % of their height: their
    /// domains shrink with F, so the quadrature follows the material. With point-integrated
    /// quadratic B-splines the stress picks up ±1 % particle-to-particle noise from the cell
    /// crossings over the 40 steps (error 5.2e-3 at 32 cells, not converging), cpGIMP reaches
    /// 1.0e-3 (see docs/verification.md).
    pub fn new(cells: usize) -> Self {
        Self {
            cells,
            ppc: 2,
            steps: 40,
            shape: Shape::Cpgimp,
        }
    }

    /// Configuration and particles: one cell wide, the grid one cell taller than the column.
    pub fn build(&self, material: Material<f64>) -> (ImplicitConfig<2>, Particles<f64, 2>) {
        let h = HEIGHT / self.cells as f64;
        let grid = Grid::new([0.0, 0.0], [1, self.cells + 1], h, self.shape.ghost_cells());
        let mut boundary = Boundary::all(Wall::new(WallKind::Slip));
        boundary.walls[1][0] = Wall::new(WallKind::Fixed);
        boundary.walls[1][1] = Wall::new(WallKind::Free);
        let config = ImplicitConfig {
            grid,
            shape: self.shape,
            boundary,
            materials: vec![material],
            gravity: Vector::<f64, 2>::new(0.0, -GRAVITY),
            constraints: Vec::new(),
            point_loads: Vec::new(),
            load_steps: self.steps,
            newton: NewtonSettings::default(),
            dynamics: None,
            min_node_support: ImplicitConfig::<2>::DEFAULT_MIN_NODE_SUPPORT,
        };
        let mut particles = Particles::default();
        let dp = h / self.ppc as f64;
        let hw = Vector::<f64, 2>::repeat(dp / 2.0);
        for j in 0..self.cells * self.ppc {
            for i in 0..self.ppc {
                let x = Vector::<f64, 2>::new((i as f64 + 0.5) * dp, (j as f64 + 0.5) * dp);
                particles.push(x, Vector::zeros(), DENSITY, hw, 0);
            }
        }
        (config, particles)
    }

    /// Runs all load steps; returns `(Y₀, σ_yy, σ_xx)` per particle and the Newton iterations.
    pub fn run(
        &self,
        material: Material<f64>,
    ) -> Result<(Vec<Sample>, usize), loam_implicit::ImplicitError> {
        let (config, mut particles) = self.build(material);
        let y0: Vec<f64> = particles.x.iter().map(|x| x[1]).collect();
        let mut solver = ImplicitSolver::new(config, &particles)?;
        let mut iterations = 0;
        while !solver.finished() {
            iterations += solver.step(&mut particles)?.iterations();
        }
        let samples = y0
            .into_iter()
            .zip(&particles.stress)
            .map(|(y, st)| (y, st[(1, 1)], st[(0, 0)]))
            .collect();
        Ok((samples, iterations))
    }
}

/// The exact vertical stress at reference height `y0`.
pub fn exact_stress(y0: f64) -> f64 {
    -DENSITY * GRAVITY * (HEIGHT - y0)
}

/// `Σ |σ − σ_exact| / Σ ρ₀ g H` over particles of equal volume, for pairs (computed, exact).
pub fn error_norm(pairs: impl ExactSizeIterator<Item = (f64, f64)>) -> f64 {
    let n = pairs.len() as f64;
    let num: f64 = pairs.map(|(s, e)| (s - e).abs()).sum();
    num / (n * DENSITY * GRAVITY * HEIGHT)
}

/// Yield stress of the J2 column, `σ_y = √3 κ` with the shear strength κ = 5 kPa.
pub fn j2_yield_stress() -> f64 {
    3f64.sqrt() * 5.0e3
}

/// Closed form of the perfectly plastic J2 column (ν = 0): the lateral Cauchy stress at a
/// particle whose vertical stress is `s = −ρ₀ g (H − Y₀)`.
///
/// Uniaxial strain with both lateral directions constrained (slip walls and plane strain)
/// keeps `τ_xx = τ_zz`. Elastic (`λ = 0` for ν = 0): `τ_xx = 0`, `τ_yy = E ln J`. The von Mises
/// surface `‖dev τ‖ = √(2/3) σ_y` is `|τ_yy − τ_xx| = σ_y`; once yielded under compression
/// `τ_xx = τ_yy + σ_y`, and the plastic flow is isochoric, so `tr τ = E ln J` gives
/// `τ_yy = (E ln J − 2σ_y)/3`. `J` follows from `τ_yy / J = s` (bisection on (0, 1]).
pub fn j2_lateral_stress(s: f64) -> f64 {
    let sy = j2_yield_stress();
    let solve = |f: &dyn Fn(f64) -> f64| {
        // f(J) = τ_yy(J)/J − s is increasing in J on (0, 1] for these laws.
        let (mut lo, mut hi) = (1e-6, 1.0);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if f(mid) > 0.0 { hi = mid } else { lo = mid }
        }
        0.5 * (lo + hi)
    };
    let je = solve(&|j: f64| YOUNG * j.ln() / j - s);
    if (YOUNG * je.ln()).abs() <= sy {
        return 0.0;
    }
    let jp = solve(&|j: f64| (YOUNG * j.ln() - 2.0 * sy) / (3.0 * j) - s);
    s + sy / jp
}

/// Runs the case: error at 64 cells and the refinement study.
pub fn run(size: Size, out: &Path) -> Result<CaseReport, VerifyError> {
    const CASE: &str = "column-compaction";
    let err = |source| VerifyError::Implicit {
        case: CASE.into(),
        source,
    };
    let hencky = Material::elastic(ModelKind::Hencky, YOUNG, 0.0, DENSITY);
    let levels: &[usize] = match size {
        Size::Reduced => &[8, 16, 32],
        Size::Full => &[8, 16, 32, 64, 128],
    };
    let main_cells = match size {
        Size::Reduced => 32,
        Size::Full => 64,
    };
    let mut table = String::from(
        "| cells | h (m) | error | observed order | Newton iterations |\n|---|---|---|---|---|\n",
    );
    let mut prev: Option<f64> = None;
    let mut main = None;
    let mut last_rate = f64::NAN;
    for &n in levels {
        let s = Setup::new(n);
        let (stress, its) = s.run(hencky.clone()).map_err(err)?;
        let e = error_norm(stress.iter().map(|&(y0, syy, _)| (syy, exact_stress(y0))));
        let rate = prev.map(|p| (p / e).log2());
        if let Some(r) = rate {
            last_rate = r;
        }
        table.push_str(&format!(
            "| {n} | {:.4} | {e:.3e} | {} | {its} |\n",
            HEIGHT / n as f64,
            rate.map_or("–".to_string(), |r| format!("{r:.2}"))
        ));
        prev = Some(e);
        if n == main_cells {
            main = Some((e, stress));
        }
    }
    let (main_err, stress) = main.expect("the main level is in the refinement list");
    // The same column, perfectly plastic J2 (κ = 5 kPa): σ_yy is still fixed by equilibrium,
    // σ_xx follows the closed form of `j2_lateral_stress`.
    let j2 = Material::j2(YOUNG, 0.0, j2_yield_stress(), 0.0, DENSITY);
    let (plastic, _) = Setup::new(main_cells).run(j2).map_err(err)?;
    let j2_yy = error_norm(plastic.iter().map(|&(y0, syy, _)| (syy, exact_stress(y0))));
    let j2_xx = error_norm(
        plastic
            .iter()
            .map(|&(y0, _, sxx)| (sxx, j2_lateral_stress(exact_stress(y0)))),
    );
    table.push_str(&format!(
        "\nJ2 (κ = 5 kPa, perfectly plastic) at {main_cells} cells: σ_yy error {j2_yy:.3e}, σ_xx error {j2_xx:.3e}\n"
    ));
    let csv = out.join("column_compaction.csv");
    let rows: Vec<Vec<f64>> = stress
        .iter()
        .zip(&plastic)
        .map(|(&(y0, s, _), &(_, syy, sxx))| {
            let e = exact_stress(y0);
            vec![y0, s, e, syy, sxx, j2_lateral_stress(e)]
        })
        .collect();
    write_csv(
        &csv,
        &[
            "y0",
            "sigma_yy_hencky",
            "sigma_yy_exact",
            "sigma_yy_j2",
            "sigma_xx_j2",
            "sigma_xx_j2_exact",
        ],
        &rows,
    )?;
    let png = out.join("column_compaction.png");
    write_plot(
        &png,
        &format!("Column under self-weight, {main_cells} cells (Hencky, cpGIMP)"),
        "reference height Y0 (m)",
        "sigma_yy (Pa)",
        &[
            Series {
                name: "exact".into(),
                points: vec![(0.0, exact_stress(0.0)), (HEIGHT, 0.0)],
                markers: false,
            },
            Series {
                name: "loam".into(),
                points: stress.iter().step_by(2).map(|&(y, s, _)| (y, s)).collect(),
                markers: true,
            },
            Series {
                name: "J2 sigma_xx exact".into(),
                points: (0..=100)
                    .map(|k| {
                        let y = HEIGHT * k as f64 / 100.0;
                        (y, j2_lateral_stress(exact_stress(y)))
                    })
                    .collect(),
                markers: false,
            },
            Series {
                name: "J2 sigma_xx loam".into(),
                points: plastic
                    .iter()
                    .step_by(2)
                    .map(|&(y, _, sxx)| (y, sxx))
                    .collect(),
                markers: true,
            },
        ],
    )?;
    let md = out.join("column_compaction.md");
    write_text(&md, &table)?;
    Ok(CaseReport {
        metrics: vec![
            // Goal: 4e-4 at 64 cells. The reduced run (32 cells) measures 1.05e-3; with the
            // observed order ≈ 1.3–1.8 the goal scales to ≈ 1.0–1.4e-3 there, so 1.5e-3.
            Metric::at_most(
                CASE,
                "stress_error_norm",
                main_err,
                match size {
                    Size::Full => 4e-4,
                    Size::Reduced => 1.5e-3,
                },
            ),
            Metric::at_least(CASE, "observed_order", last_rate, 1.0),
            // J2 (no goal in the benchmark definition): measured σ_yy 3.3e-3 / 1.35e-3 and
            // σ_xx 9.4e-4 / 3.9e-4 at 32 / 64 cells (order ≈ 1.3); the bounds leave ~25 % margin
            // so that a regression in the return mapping or the tangent shows up.
            Metric::at_most(
                CASE,
                "j2_sigma_yy_error_norm",
                j2_yy,
                match size {
                    Size::Full => 1.7e-3,
                    Size::Reduced => 4.1e-3,
                },
            ),
            Metric::at_most(
                CASE,
                "j2_sigma_xx_error_norm",
                j2_xx,
                match size {
                    Size::Full => 5e-4,
                    Size::Reduced => 1.2e-3,
                },
            ),
        ],
        files: vec![csv, png, md],
    })
}
