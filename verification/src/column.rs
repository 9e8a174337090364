//! A soil column compacting under its own weight (quasi-static, large deformation).
//!
//! A column of height H = 50 m rests on a fixed base between frictionless (slip) walls, so it
//! deforms in uniaxial strain. Gravity g = 10 m/s² is ramped over 40 load steps; E = 10 kPa,
//! ν = 0, ρ₀ = 80 kg/m³, Hencky elasticity. The bottom is compressed to about 30 % of its height.
//! Whatever the material, equilibrium and mass conservation give the exact vertical Cauchy
//! stress at a particle that started at height Y₀: `σ_yy = −ρ₀ g (H − Y₀)`. The error norm is
//! `Σ_p |σ_yy − σ_exact| V⁰_p / Σ_p ρ₀ g H V⁰_p`.

use crate::{
    CaseReport, Metric, Series, Size, VerifyError, scenes, write_csv, write_plot, write_text,
};
use loam_core::{ModelKind, Particles, Shape};
use loam_implicit::{ImplicitConfig, ImplicitSolver};
use loam_scene::{BodyShape, Scene};
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

/// The column's material.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Soil {
    /// Hencky elasticity, the scene file's material.
    Elastic,
    /// The same moduli, perfectly plastic J2 with `σ_y =` [`j2_yield_stress`].
    Plastic,
}

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
    /// Cubic B-splines, 4×4 particles per cell, 40 load steps.
    ///
    /// The base is compressed to J ≈ 0.3, so over the 40 steps every particle crosses cells.
    /// The smoother the shape functions and the denser the quadrature, the smaller the stress
    /// noise those crossings leave (errors at 64 cells, see docs/verification.md): quadratic
    /// B-splines 5.4e-3 (2×2) / 1.6e-3 (4×4), cpGIMP 4.2e-4 (2×2; its domains follow the
    /// compression, but two particles in the compressed base cell see one linear field and
    /// carry one stress), cubic B-splines 8.7e-4 (2×2) / 1.8e-4 (4×4).
    pub fn new(cells: usize) -> Self {
        Self {
            cells,
            ppc: 4,
            steps: 40,
            shape: Shape::CubicBspline,
        }
    }

    /// The scene: `verification/scenes/column_compaction.toml` (one cell wide, the grid one
    /// cell taller than the column) with the cell size, particles per cell, load steps, shape
    /// functions and soil of this set-up.
    pub fn scene(&self, soil: Soil) -> Scene {
        let mut scene = scenes::scene("column_compaction");
        let h = HEIGHT / self.cells as f64;
        scene.grid.cell_size = h;
        scene.grid.hi = vec![h, (self.cells + 1) as f64 * h];
        scene.grid.shape_function = self.shape;
        let body = &mut scene.bodies[0];
        body.shape = BodyShape::Box {
            lo: vec![0.0, 0.0],
            hi: vec![h, HEIGHT],
        };
        body.particles_per_cell = self.ppc as u32;
        if soil == Soil::Plastic {
            let m = &mut scene.materials[0];
            m.model = ModelKind::J2;
            m.yield_stress = Some(j2_yield_stress());
            m.hardening = Some(0.0);
        }
        scene.solver.load_steps = Some(self.steps);
        scene
    }

    /// Configuration and particles of the [scene](Setup::scene).
    pub fn build(&self, soil: Soil) -> (ImplicitConfig<2>, Particles<f64, 2>) {
        let built = scenes::build::<2>(&self.scene(soil));
        let config = built
            .implicit_config()
            .expect("the column is an implicit scene");
        (config, built.particles)
    }

    /// Runs all load steps; returns `(Y₀, σ_yy, σ_xx)` per particle and the Newton iterations.
    pub fn run(&self, soil: Soil) -> Result<(Vec<Sample>, usize), loam_implicit::ImplicitError> {
        let (config, mut particles) = self.build(soil);
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

/// The least-squares slope of `log e` against `log h` over `(h, e)` pairs: the observed order
/// of convergence over a whole refinement study, `p` in `e ≈ C hᵖ`.
pub fn fitted_order(errors: &[(f64, f64)]) -> f64 {
    let n = errors.len() as f64;
    let (mx, my) = errors.iter().fold((0.0, 0.0), |(sx, sy), &(h, e)| {
        (sx + h.ln() / n, sy + e.ln() / n)
    });
    let (sxy, sxx) = errors.iter().fold((0.0, 0.0), |(sxy, sxx), &(h, e)| {
        let dx = h.ln() - mx;
        (sxy + dx * (e.ln() - my), sxx + dx * dx)
    });
    sxy / sxx
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
    let mut errors = Vec::new();
    for &n in levels {
        let s = Setup::new(n);
        let (stress, its) = s.run(Soil::Elastic).map_err(err)?;
        let e = error_norm(stress.iter().map(|&(y0, syy, _)| (syy, exact_stress(y0))));
        let rate = prev.map(|p| (p / e).log2());
        errors.push((HEIGHT / n as f64, e));
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
    let order = fitted_order(&errors);
    table.push_str(&format!(
        "\nLeast-squares order over the {} refinements: {order:.2}\n",
        errors.len() - 1
    ));
    // The same column, perfectly plastic J2 (κ = 5 kPa): σ_yy is still fixed by equilibrium,
    // σ_xx follows the closed form of `j2_lateral_stress`.
    let (plastic, _) = Setup::new(main_cells).run(Soil::Plastic).map_err(err)?;
    let j2_yy = error_norm(plastic.iter().map(|&(y0, syy, _)| (syy, exact_stress(y0))));
    let j2_xx = error_norm(
        plastic
            .iter()
            .map(|&(y0, _, sxx)| (sxx, j2_lateral_stress(exact_stress(y0)))),
    );
    table.push_str(&format!(
        "\nJ2 (κ = 5 kPa, perfectly plastic) at {main_cells} cells: σ_yy error {j2_yy:.3e}, σ_xx error {j2_xx:.3e}\n"
    ));
    // One particle per row of the plot.
    let per_row = Setup::new(main_cells).ppc;
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
        &format!("Column under self-weight, {main_cells} cells (Hencky, cubic B-splines)"),
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
                points: stress
                    .iter()
                    .step_by(per_row)
                    .map(|&(y, s, _)| (y, s))
                    .collect(),
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
                    .step_by(per_row)
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
            // Goal: 4e-4 at 64 cells (measured 1.83e-4). The reduced run (32 cells) measures
            // 4.05e-4; the goal scaled by the observed order 32 → 64 (1.14) is 8.8e-4, and the
            // bound 6e-4 leaves ~50 % margin over the measurement.
            Metric::at_most(
                CASE,
                "stress_error_norm",
                main_err,
                match size {
                    Size::Full => 4e-4,
                    Size::Reduced => 6e-4,
                },
            ),
            // The slope of log e against log h over all levels (4 refinements in the full run,
            // 2 in the reduced one): measured 1.34 / 1.76. At least first order; the local
            // order falls at fine grids, where the cell-crossing noise of the 40 load steps
            // takes over (docs/verification.md).
            Metric::at_least(CASE, "observed_order", order, 1.0),
            // J2 (no goal in the benchmark definition): measured σ_yy 1.01e-3 / 3.72e-4 and
            // σ_xx 2.82e-4 / 9.88e-5 at 32 / 64 cells; the bounds leave ~25 % margin so that a
            // regression in the return mapping or the tangent shows up.
            Metric::at_most(
                CASE,
                "j2_sigma_yy_error_norm",
                j2_yy,
                match size {
                    Size::Full => 4.7e-4,
                    Size::Reduced => 1.26e-3,
                },
            ),
            Metric::at_most(
                CASE,
                "j2_sigma_xx_error_norm",
                j2_xx,
                match size {
                    Size::Full => 1.25e-4,
                    Size::Reduced => 3.5e-4,
                },
            ),
        ],
        files: vec![csv, png, md],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fitted_order_recovers_a_power_law() {
        // e = 3 h^1.5 exactly: the fit returns 1.5 to round-off; a perturbed point moves it.
        let exact: Vec<(f64, f64)> = [1.0, 0.5, 0.25, 0.125]
            .iter()
            .map(|&h: &f64| (h, 3.0 * h.powf(1.5)))
            .collect();
        assert!((fitted_order(&exact) - 1.5).abs() < 1e-12);
        let mut bent = exact.clone();
        bent[3].1 *= 2.0;
        assert!(fitted_order(&bent) < 1.4);
    }

    #[test]
    fn j2_lateral_stress_is_zero_while_elastic_and_bounded_by_yield() {
        // Near the top the column is elastic (σ_xx = 0 for ν = 0); deep down it has yielded and
        // |σ_yy − σ_xx| = σ_y / J ≥ σ_y (Cauchy vs Kirchhoff).
        assert_eq!(j2_lateral_stress(exact_stress(HEIGHT - 0.1)), 0.0);
        let s = exact_stress(0.0);
        let sxx = j2_lateral_stress(s);
        assert!(sxx < 0.0 && sxx - s >= j2_yield_stress());
    }
}
