//! Bearing capacity of a rigid strip footing on weightless soil: Prandtl's limit pressure for
//! Tresca soil (`footing-prandtl`) and for c–φ soil (`footing-cphi`).
//!
//! A smooth rigid footing of half-width b = 1 m is pushed into a weightless, perfectly plastic
//! soil (plane strain). By symmetry half the problem is modelled: the soil fills
//! `x ∈ [0, W]` (slip walls on both sides) by `y ∈ [0, H]` (fixed base), free surface on top.
//! The footing prescribes the vertical displacement of the grid nodes under it (the surface
//! row and the row above it, which the surface particles' B-spline supports reach); the
//! pressure is the reaction of those nodes over b.
//!
//! - `footing-prandtl`: J2 (von Mises with `σ_y = √3 c_u` is Tresca with the undrained
//!   strength `c_u` in plane strain), W = H = 5b: `q_u = (2 + π) c_u`.
//! - `footing-cphi`: Mohr–Coulomb, c = 10 kPa, φ = ψ = 30° (associated), W = 12b, H = 6b
//!   (Prandtl's mechanism for φ = 30° reaches 9.6b from the centre line and about 2.5b deep):
//!   `q_u = c N_c`, `N_c = (N_q − 1) cot φ`, `N_q = e^{π tan φ} tan²(45° + φ/2)`, so
//!   `N_c = 30.14`. E = 100 MPa (E/c = 10⁴), so the curve levels off at a settlement of about
//!   0.013b, before the geometry has changed much: Prandtl's value is a small-deformation
//!   limit, and on a softer soil the settlement to reach it moves the surface and lifts the
//!   curve. The limit pressure is read as the pressure at the end of the loading, a
//!   settlement of 0.02b, where the curve has levelled off: the case checks that its secant
//!   stiffness over the last quarter of the settlement is below 2 % of the initial secant
//!   stiffness (the first load step), i.e. the pressure there changes by less than 2 % of
//!   its elastic rate. It runs two cell sizes (h = b/4 and b/8 at full size, b/2 and b/4
//!   reduced) and checks that the finer one is closer to `c N_c`.

use crate::{CaseReport, Metric, Series, Size, VerifyError, scenes, write_csv, write_plot};
use loam_implicit::ImplicitSolver;
use loam_scene::{BodyShape, Scene};
use std::f64::consts::PI;
use std::path::Path;

/// Footing half-width b (m).
pub const HALF_WIDTH: f64 = 1.0;
/// Undrained shear strength c_u of the Tresca soil (Pa).
pub const CU: f64 = 10.0e3;
/// Young's modulus of the Tresca soil (Pa): E / c_u = 1000.
pub const YOUNG: f64 = 10.0e6;
/// Cohesion c of the c–φ soil (Pa).
pub const COHESION: f64 = 10.0e3;
/// Friction angle φ of the c–φ soil (degrees).
pub const FRICTION_ANGLE: f64 = 30.0;

/// Prandtl's bearing capacity factor `N_c = (N_q − 1) cot φ` with
/// `N_q = e^{π tan φ} tan²(45° + φ/2)` (φ in degrees): 30.14 at φ = 30°.
pub fn prandtl_nc(phi_deg: f64) -> f64 {
    let phi = phi_deg.to_radians();
    let nq = (PI * phi.tan()).exp() * (PI / 4.0 + phi / 2.0).tan().powi(2);
    (nq - 1.0) / phi.tan()
}

/// `base` (a footing scene: one box of soil from the origin, the footing as its first
/// constraint) with `n` cells per half-width, the grid two cells taller than the soil, the
/// footing's node rows (the surface row and the one above it) moved to that cell size and
/// pushed `settlement` into the soil in `steps` load steps.
fn refined(mut scene: Scene, n: usize, steps: usize, settlement: f64) -> Scene {
    let BodyShape::Box { hi: soil, .. } = &scene.bodies[0].shape else {
        panic!("a footing scene's soil is a box")
    };
    let (width, depth) = (soil[0], soil[1]);
    let h = HALF_WIDTH / n as f64;
    scene.grid.cell_size = h;
    scene.grid.hi = vec![width, depth + 2.0 * h];
    let footing = &mut scene.constraints[0];
    footing.lo = vec![0.0, depth];
    footing.hi = vec![HALF_WIDTH, depth + h];
    footing.displacement = vec![None, Some(-settlement)];
    scene.solver.load_steps = Some(steps);
    scene
}

/// The Tresca footing with `n` cells per half-width pushed `settlement` into the soil in
/// `steps` load steps: `verification/scenes/footing_prandtl.toml` at that cell size.
pub fn scene(n: usize, steps: usize, settlement: f64) -> Scene {
    refined(scenes::scene("footing_prandtl"), n, steps, settlement)
}

/// The c–φ footing with `n` cells per half-width pushed `settlement` into the soil in `steps`
/// load steps: `verification/scenes/footing_cphi.toml` at that cell size.
pub fn cphi_scene(n: usize, steps: usize, settlement: f64) -> Scene {
    refined(scenes::scene("footing_cphi"), n, steps, settlement)
}

/// Runs a footing scene whose footing settles by `settlement`; returns (settlement, pressure /
/// `strength`) per load step, from (0, 0).
pub fn load_curve(
    scene: &Scene,
    settlement: f64,
    strength: f64,
) -> Result<Vec<(f64, f64)>, loam_implicit::ImplicitError> {
    let built = scenes::build::<2>(scene);
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
            -r.constraint_forces[0][1] / HALF_WIDTH / strength,
        ));
    }
    Ok(curve)
}

/// Runs `footing-prandtl`.
pub fn run(size: Size, out: &Path) -> Result<CaseReport, VerifyError> {
    const CASE: &str = "footing-prandtl";
    let n = match size {
        Size::Reduced => 4,
        Size::Full => 8,
    };
    let settlement = 0.1 * HALF_WIDTH;
    let curve = load_curve(&scene(n, 40, settlement), settlement, CU).map_err(|source| {
        VerifyError::Implicit {
            case: CASE.into(),
            source,
        }
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
                points: vec![(0.0, exact), (settlement, exact)],
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

/// The secant stiffness of a load curve over its last quarter (from the first point at or
/// beyond three quarters of the final settlement to the end) over the secant stiffness of its
/// first load step: how far from a plateau the end of the curve is.
fn plateau_stiffness_ratio(curve: &[(f64, f64)]) -> f64 {
    let (s_end, q_end) = curve[curve.len() - 1];
    let &(s_q, q_q) = curve
        .iter()
        .find(|c| c.0 >= 0.75 * s_end)
        .expect("the curve reaches its end");
    let (s1, q1) = curve[1];
    ((q_end - q_q) / (s_end - s_q)) / (q1 / s1)
}

/// Runs `footing-cphi`.
pub fn run_cphi(size: Size, out: &Path) -> Result<CaseReport, VerifyError> {
    const CASE: &str = "footing-cphi";
    // (cells per half-width, tolerance on the limit pressure's error), coarse then fine.
    let (sizes, steps) = match size {
        // Goal of the benchmark: within 5 % of c N_c at both sizes.
        Size::Full => ([(4, 0.05), (8, 0.05)], 20),
        // h = b/2 puts two cells under the half footing: the coarsest mesh on which the
        // footing's edge is a node between loaded and free surface nodes. The error about
        // halves per halving of h over b/2 → b/4 → b/8 (4.1 %, 1.6 % with these 10 load
        // steps; 1.7 %, 0.8 % with 20: docs/verification.md), so b/2 is allowed twice the
        // goal; b/4 must meet the goal itself. Load steps of 0.002b instead of 0.001b move
        // the pressure at 0.02b by 0.1 % (at b/4).
        Size::Reduced => ([(2, 0.10), (4, 0.05)], 10),
    };
    let settlement = 0.02 * HALF_WIDTH;
    let nc = prandtl_nc(FRICTION_ANGLE);
    let mut metrics = Vec::new();
    let mut curves = Vec::new();
    let mut errors = Vec::new();
    for (n, tolerance) in sizes {
        let curve = load_curve(&cphi_scene(n, steps, settlement), settlement, COHESION).map_err(
            |source| VerifyError::Implicit {
                case: CASE.into(),
                source,
            },
        )?;
        let limit = curve.last().map_or(0.0, |c| c.1);
        let error = (limit - nc).abs() / nc;
        metrics.push(Metric::at_most(
            CASE,
            &format!("limit_pressure_rel_error_h=b/{n}"),
            error,
            tolerance,
        ));
        // A plateau: the pressure's rate at the end below 2 % of its elastic rate.
        metrics.push(Metric::at_most(
            CASE,
            &format!("plateau_stiffness_ratio_h=b/{n}"),
            plateau_stiffness_ratio(&curve),
            0.02,
        ));
        metrics.push(Metric::info(
            CASE,
            &format!("limit_pressure_over_c_h=b/{n}"),
            limit,
        ));
        errors.push(error);
        curves.push((n, curve));
    }
    // First-order convergence halves the error per halving of h (ratio 0.5); 0.75 asks for a
    // clear decrease, not just any.
    metrics.push(Metric::at_most(
        CASE,
        "refinement_error_ratio_fine_over_coarse",
        errors[1] / errors[0],
        0.75,
    ));
    let csv = out.join("footing_cphi.csv");
    let (coarse, fine) = (&curves[0], &curves[1]);
    let rows: Vec<Vec<f64>> = coarse
        .1
        .iter()
        .zip(&fine.1)
        .map(|(&(s, qc), &(_, qf))| vec![s / HALF_WIDTH, qc, qf, nc])
        .collect();
    let header_coarse = format!("pressure_over_c_h=b/{}", coarse.0);
    let header_fine = format!("pressure_over_c_h=b/{}", fine.0);
    write_csv(
        &csv,
        &[
            "settlement_over_b",
            header_coarse.as_str(),
            header_fine.as_str(),
            "prandtl_nc",
        ],
        &rows,
    )?;
    let png = out.join("footing_cphi.png");
    let mut series = vec![Series {
        name: format!("Prandtl c N_c = {nc:.2} c"),
        points: vec![(0.0, nc), (settlement / HALF_WIDTH, nc)],
        markers: false,
    }];
    for (n, curve) in &curves {
        series.push(Series {
            name: format!("loam, h = b/{n}"),
            points: curve.iter().map(|&(s, q)| (s / HALF_WIDTH, q)).collect(),
            markers: true,
        });
    }
    write_plot(
        &png,
        "Strip footing on c–φ soil (φ = ψ = 30°)",
        "settlement / b",
        "q / c",
        &series,
    )?;
    Ok(CaseReport {
        metrics,
        files: vec![csv, png],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Prandtl's factors at φ = 30° (Terzaghi's tables: N_q = 18.40, N_c = 30.14).
    #[test]
    fn prandtl_factor_at_thirty_degrees() {
        assert!((prandtl_nc(30.0) - 30.14).abs() < 5e-3);
        // φ → 0 gives 2 + π (Tresca).
        assert!((prandtl_nc(1e-6) - (2.0 + PI)).abs() < 1e-5);
    }
}
