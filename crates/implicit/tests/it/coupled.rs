//! The coupled (u–p) step's tangent against differences of its residual. (Its physics is
//! verified against Terzaghi's solution by `loam verify terzaghi`.)

use loam_core::tensor::Vector;
use loam_core::{Boundary, Grid, Material, ModelKind, Particles, Shape, Wall, WallKind};
use loam_implicit::flow::{
    CoupledTangent, Hydraulic, Permeability, PoreFluid, Schedule, TimeIntegration,
};
use loam_implicit::system::StepSystem;
use loam_implicit::{ImplicitConfig, ImplicitSolver, NewtonSettings};

/// Deterministic pseudo-random numbers in [−1, 1).
fn rng(seed: &mut u64) -> f64 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    2.0 * ((*seed >> 11) as f64 / (1u64 << 53) as f64) - 1.0
}

/// A saturated block `[0, 1]^D` (cells of 0.25, 2^D particles per cell, slightly jittered)
/// on a fixed base with slip side walls, drained at the top, under a water table at 1.5 (so
/// the hydrostatic pressure enters the total stress); the first material is `material`.
fn block<const D: usize>(
    material: Material<f64>,
    shape: Shape,
    stabilisation: bool,
) -> (ImplicitConfig<D>, Particles<f64, D>) {
    let h = 0.25;
    let mut cells = [4; D];
    cells[D - 1] = 5;
    let grid = Grid::<D>::new([0.0; D], cells, h, shape.ghost_cells());
    let mut boundary = Boundary::all(Wall::new(WallKind::Slip));
    boundary.walls[D - 1][0] = Wall::new(WallKind::Fixed);
    boundary.walls[D - 1][1] = Wall::new(WallKind::Free);
    let mut drained = [[false; 2]; D];
    drained[D - 1][1] = true;
    let mut seed = 7 + D as u64;
    let mut particles = Particles::<f64, D>::default();
    let spacing = h / 2.0;
    let n = 8usize;
    for k in 0..n.pow(D as u32) {
        let mut r = k;
        let x = Vector::<f64, D>::from_fn(|_, _| {
            let i = r % n;
            r /= n;
            (i as f64 + 0.5 + 0.2 * rng(&mut seed)) * spacing
        });
        particles.push(x, Vector::zeros(), 1800.0, Vector::repeat(spacing / 2.0), 0);
        let i = particles.len() - 1;
        particles.pore_pressure[i] = 9810.0 * (1.5 - x[D - 1]) + 2e3 * rng(&mut seed);
    }
    let mut gravity = Vector::<f64, D>::zeros();
    gravity[D - 1] = -9.81;
    let schedule = Schedule::geometric(1, 10.0, 1.0, 20.0);
    let config = ImplicitConfig {
        grid,
        shape,
        boundary,
        materials: vec![material],
        gravity,
        constraints: Vec::new(),
        point_loads: Vec::new(),
        load_steps: schedule.steps(),
        newton: NewtonSettings::default(),
        dynamics: None,
        gravity_in_full: true,
        min_node_support: ImplicitConfig::<D>::DEFAULT_MIN_NODE_SUPPORT,
        balance: Vec::new(),
        pore_fluid: Some(PoreFluid {
            hydraulic: vec![Hydraulic {
                mobility: 1e-7,
                biot: 0.9,
                storage: 1e-9,
                permeability: Permeability::KozenyCarman { porosity: 0.4 },
            }],
            unit_weight: 9810.0,
            water_table: Some(1.5),
            drained,
            stabilisation,
            schedule,
            inflow: Vec::new(),
            drains: Vec::new(),
            time_integration: TimeIntegration::BackwardEuler,
        }),
    };
    (config, particles)
}

/// The solver of [`block`] (stabilisation on) and the system of its second step (Δt = 10 s).
fn second_step<const D: usize>(
    material: Material<f64>,
    shape: Shape,
) -> (ImplicitSolver<D>, Particles<f64, D>, StepSystem<D>) {
    let (config, particles) = block::<D>(material, shape, true);
    let solver = ImplicitSolver::new(config, &particles).expect("valid");
    let progress = 1.0 / solver.config().load_steps as f64;
    let system = solver
        .system(&particles, progress, 2.0 * progress)
        .expect("system");
    (solver, particles, system)
}

/// The coupled tangent, per-particle and colour-seeded, against central differences of the
/// residual at a random trial state (displacement increments of ~1 % strain, pressures of
/// ~10 kPa) of the second step (Δt = 10 s), with the stabilisation on.
fn check_coupled_tangent<const D: usize>(material: Material<f64>, shape: Shape) {
    let (solver, _, system) = second_step::<D>(material, shape);
    assert!(system.flow.as_ref().is_some_and(|f| f.dt == 10.0));
    let mats = solver.materials();
    let mut seed = 99;
    let x: Vec<f64> = (0..system.len())
        .map(|d| {
            let (_, c) = system.dofs.owner_of(d);
            // Displacements ~1e-3 m over cells of 0.25 m; pressure unknowns (scaled by
            // G/h) of ~10 kPa.
            let scale = if c < D {
                2.5e-3
            } else {
                1e4 / system.flow.as_ref().unwrap().scale
            };
            scale * rng(&mut seed)
        })
        .collect();
    let plastic = system
        .particle_updates(&x, None, mats)
        .expect("updates")
        .iter()
        .filter(|u| u.state.plastic_strain > 0.0)
        .count();
    let local = system.tangent_local(&x, mats).expect("local");
    let colour = system.tangent_colour(&x, mats).expect("colour");
    let n = system.len();
    let pressure = |d: usize| usize::from(system.dofs.owner_of(d).1 == D);
    // Per block (mixture/fluid rows × displacement/pressure columns): the largest entry and
    // the largest differences to the colour-seeded tangent and to central differences.
    let mut kmax = [[0.0f64; 2]; 2];
    let mut worst_fd = [[0.0f64; 2]; 2];
    let mut worst_colour = [[0.0f64; 2]; 2];
    let at = |k: &loam_implicit::linear::SparseMatrix, i: usize, j: usize| {
        k.pattern.position(i, j).map_or(0.0, |p| k.values[p])
    };
    // Both kinds of unknown are lengths (the pressure scaled by h/G), of ~1e-3 m.
    crate::central_differences(&system, mats, &x, |i, j, fd| {
        let (bi, bj) = (pressure(i), pressure(j));
        let kl = at(&local, i, j);
        kmax[bi][bj] = kmax[bi][bj].max(kl.abs());
        worst_fd[bi][bj] = worst_fd[bi][bj].max((kl - fd).abs());
        worst_colour[bi][bj] = worst_colour[bi][bj].max((kl - at(&colour, i, j)).abs());
    });
    for (bi, row) in ["mixture", "fluid"].iter().enumerate() {
        for (bj, col) in ["u", "p"].iter().enumerate() {
            let (fd, co, k) = (worst_fd[bi][bj], worst_colour[bi][bj], kmax[bi][bj]);
            println!(
                "{D}D {shape:?} ({n} unknowns, {plastic} plastic particles) {row}/{col}: max |K| {k:.2e}, |K_local − FD| {:.1e}, |K_local − K_colour| {:.1e}",
                fd / k,
                co / k
            );
            assert!(k > 0.0, "{row}/{col} block is empty");
            // The two AD tangents are the same derivative summed in another order.
            assert!(co <= 1e-12 * k, "{row}/{col} colour {co:e} vs {k:e}");
            // Differences: the truncation and round-off of the step above.
            assert!(fd <= 1e-6 * k, "{row}/{col} differences {fd:e} vs {k:e}");
        }
    }
}

#[test]
fn the_coupled_tangent_is_the_derivative_of_the_residual() {
    use loam_core::constitutive::{Lame, Model, MohrCoulomb};
    let sand = Material {
        density: 1800.0,
        model: Model::MohrCoulomb(MohrCoulomb {
            lame: Lame::from_young_poisson(20e6, 0.3),
            friction_angle: 30f64.to_radians(),
            dilation_angle: 5f64.to_radians(),
            cohesion: 1e3,
            tension_cutoff: None,
        }),
    };
    let hencky = Material::elastic(ModelKind::Hencky, 20e6, 0.3, 1800.0);
    for shape in [Shape::QuadraticBspline, Shape::Linear] {
        check_coupled_tangent::<2>(hencky.clone(), shape);
        check_coupled_tangent::<2>(sand.clone(), shape);
    }
    check_coupled_tangent::<3>(sand, Shape::QuadraticBspline);
}

#[test]
fn kozeny_carman_follows_the_porosity() {
    use num_dual::Dual64;
    let law = Permeability::KozenyCarman { porosity: 0.4 };
    // κ₀ at F = I.
    assert_eq!(law.factor(1.0f64), Some(1.0));
    // J = 0.8: n = 1 − 0.6/0.8 = 0.25, so κ/κ₀ = (0.25³/0.75²)/(0.4³/0.6²) = 5/32.
    let k = law.factor(0.8f64).expect("porous");
    assert!((k - 5.0 / 32.0).abs() < 1e-15, "{k}");
    // No porosity left at J ≤ 1 − n₀.
    assert_eq!(law.factor(0.6f64), None);
    // The dual derivative (the tangent's) against central differences, whose truncation
    // O(ε² f‴) at ε = 1e-6 is ~1e-12.
    for j in [0.7, 1.0, 1.3] {
        let d = law
            .factor(Dual64::from_re(j).derivative())
            .expect("porous")
            .eps;
        let eps = 1e-6;
        let fd = (law.factor(j + eps).unwrap() - law.factor(j - eps).unwrap()) / (2.0 * eps);
        assert!((d - fd).abs() < 1e-8 * d.abs(), "J = {j}: {d} vs {fd}");
    }
    assert_eq!(Permeability::Constant.factor(0.3f64), Some(1.0));
}

/// A small 3D consolidation (the saturated block of [`block`], 4 × 4 × 5 cells, 512 particles,
/// Hencky-elastic soil, undrained loading under gravity and two drained steps) run with GMRES
/// and BiCGSTAB preconditioned by the block preconditioner ends where the run with the sparse
/// LU ends. The Krylov solves stop at a relative residual of 1e-10, so each Newton correction
/// differs from LU's by about 1e-10 of its size times the conditioning the block
/// preconditioner leaves; Newton then converges to the same state, and what is left is the
/// difference of where the iterations stopped (every run reaches `‖R‖ ≤ 1e-8` of the
/// reference, in the same number of iterations). Pore pressures (~10 kPa) and displacements
/// (~1e-4 m) agree to 1e-8 relative (the largest difference over the particles against the
/// largest value), the Newton tolerance; measured: 4e-12 and 3e-15.
#[test]
fn krylov_with_the_block_preconditioner_matches_lu_in_3d() {
    use loam_implicit::linear::{LinearSolverKind, Preconditioner};
    let soil = Material::elastic(ModelKind::Hencky, 20e6, 0.3, 1800.0);
    let run = |linear: LinearSolverKind| {
        let (mut config, mut particles) = block::<3>(soil.clone(), Shape::QuadraticBspline, true);
        config.newton.linear = linear;
        let start = particles.x.clone();
        let mut solver = ImplicitSolver::new(config, &particles).expect("valid");
        let mut krylov = Vec::new();
        while !solver.finished() {
            let report = solver
                .step(&mut particles)
                .unwrap_or_else(|e| panic!("{}: {e}", linear.name()));
            assert_eq!(report.cuts, 0, "{}", linear.name());
            krylov.extend(
                report
                    .solves
                    .iter()
                    .flat_map(|s| s.linear_iterations.clone()),
            );
        }
        let displacement: Vec<f64> = (particles.x.iter().zip(&start))
            .flat_map(|(x, x0)| (x - x0).iter().copied().collect::<Vec<_>>())
            .collect();
        (displacement, particles.pore_pressure.clone(), krylov)
    };
    let relative = |a: &[f64], b: &[f64]| {
        let diff = a
            .iter()
            .zip(b)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        diff / b.iter().map(|b| b.abs()).fold(0.0, f64::max)
    };
    let (u_lu, p_lu, _) = run(LinearSolverKind::Lu);
    for linear in [
        LinearSolverKind::Gmres {
            preconditioner: Preconditioner::Block,
            rel_tol: 1e-10,
            max_iter: 500,
        },
        LinearSolverKind::Bicgstab {
            preconditioner: Preconditioner::Block,
            rel_tol: 1e-10,
            max_iter: 500,
        },
    ] {
        let (u, p, krylov) = run(linear);
        let (du, dp) = (relative(&u, &u_lu), relative(&p, &p_lu));
        println!(
            "{}: Krylov iterations per Newton iteration {krylov:?}; displacement {du:.1e}, \
             pore pressure {dp:.1e} relative to LU",
            linear.name()
        );
        assert!(
            du <= 1e-8 && dp <= 1e-8,
            "{}: {du:e}, {dp:e}",
            linear.name()
        );
        // Measured at most 15 per solve (the undrained loading step; 3–5 when drained); 50
        // with the Schur augmentation's diagonal alone, without the pressure mass's shape.
        assert!(krylov.iter().all(|&k| k <= 30), "{krylov:?}");
    }
}

/// The pressure mass matrix that shapes the block preconditioner's Schur approximation,
/// `M_ij = Σ_p w_p N_i(x_p) N_j(x_p)`, on a saturated block without drained faces (every
/// pressure unknown free): symmetric, nonzero only between pressures, with a positive
/// diagonal, and by the partition of unity `Σ_i N_i = 1` its entries sum to `Σ_p w_p`. With
/// linear shape functions, which interpolate the height `z` from its nodal values, also
/// `Σ_ij M_ij z_j = Σ_p w_p z(x_p)` (the quadratic B-splines' boundary-modified functions
/// reproduce `z` from other coefficients than the nodes' heights). Round-off bound: 1e-12
/// relative.
#[test]
fn the_pressure_mass_integrates_the_stabilisation_weights() {
    for shape in [Shape::QuadraticBspline, Shape::Linear] {
        let soil = Material::elastic(ModelKind::LinearElastic, 20e6, 0.3, 1800.0);
        let (mut config, particles) = block::<2>(soil, shape, true);
        let fluid = config.pore_fluid.as_mut().expect("coupled");
        fluid.drained = [[false; 2]; 2];
        let solver = ImplicitSolver::new(config, &particles).expect("valid");
        let progress = 1.0 / solver.config().load_steps as f64;
        let system = solver.system(&particles, 0.0, progress).expect("system");
        let flow = system.flow.as_ref().expect("coupled");
        let m = system.pressure_mass();
        let grid = &solver.config().grid;
        let (mut total, mut moment) = (0.0, 0.0);
        for j in 0..system.len() {
            let (node, c) = system.dofs.owner_of(j);
            let height: f64 = grid.node_position::<f64>(grid.multi(node))[1];
            for k in m.pattern.col_ptr()[j]..m.pattern.col_ptr()[j + 1] {
                let i = m.pattern.row_idx()[k];
                let v = m.values[k];
                if v == 0.0 {
                    continue;
                }
                assert_eq!((system.dofs.owner_of(i).1, c), (2, 2), "entry ({i}, {j})");
                let t = m.pattern.position(j, i).map_or(0.0, |t| m.values[t]);
                assert!((v - t).abs() <= 1e-14 * v.abs(), "({i}, {j}): {v} vs {t}");
                total += v;
                moment += v * height;
            }
            if c == 2 {
                let d = m.pattern.position(j, j).map_or(0.0, |d| m.values[d]);
                assert!(d > 0.0, "{shape:?}: diagonal {j}: {d}");
            }
        }
        let weights: f64 = flow.particles.iter().map(|f| f.weight).sum();
        let weighted: f64 = (flow.particles.iter().zip(&particles.x))
            .map(|(f, x)| f.weight * x[1])
            .sum();
        println!(
            "{shape:?}: Σ M = {total:e} (Σ w = {weights:e}), Σ M z = {moment:e} (Σ w z = {weighted:e})"
        );
        assert!(
            (total - weights).abs() <= 1e-12 * weights,
            "{shape:?}: {total} vs {weights}"
        );
        if shape == Shape::Linear {
            assert!(
                (moment - weighted).abs() <= 1e-12 * weighted.abs(),
                "{moment} vs {weighted}"
            );
        }
    }
}

/// The BDF2 weights: `c₁ = ω²/(1 + 2ω)`, `c₂ = (1 + ω)/(1 + 2ω)` (`ΔΞ − ΔΞⁿ/3 + (2/3) Δt ∇·q`
/// at equal steps), and backward Euler `(0, 1)` without a previous step with time, beyond the
/// largest ratio, or with the default scheme.
#[test]
fn bdf2_weights_follow_the_step_ratio() {
    let close = |(a, b): (f64, f64), (c, d): (f64, f64)| (a - c).abs() + (b - d).abs() < 1e-15;
    let bdf2 = TimeIntegration::Bdf2;
    assert!(close(bdf2.weights(1.0, 1.0), (1.0 / 3.0, 2.0 / 3.0)));
    // ω = 2: c₁ = 4/5, c₂ = 3/5; ω = 1/2: c₁ = 1/8, c₂ = 3/4.
    assert!(close(bdf2.weights(2.0, 1.0), (0.8, 0.6)));
    assert!(close(bdf2.weights(0.5, 1.0), (0.125, 0.75)));
    // A doubling step computed as a difference of times, a few ulp above 2, is still BDF2.
    let (t1, t2) = (0.1, 0.1 + 0.2);
    assert!((t2 - t1) / t1 > 2.0);
    let (c1, c2) = bdf2.weights(t2 - t1, t1);
    assert!(
        (c1 - 0.8).abs() < 1e-14 && (c2 - 0.6).abs() < 1e-14,
        "{c1} {c2}"
    );
    for (dt, previous) in [(1.0, 0.0), (2.5, 1.0), (2.001, 1.0), (0.0, 1.0)] {
        assert_eq!(
            bdf2.weights(dt, previous),
            (0.0, 1.0),
            "{dt} after {previous}"
        );
    }
    assert_eq!(TimeIntegration::BackwardEuler.weights(1.0, 1.0), (0.0, 1.0));
}

/// The order in time of the consolidation of the saturated block of [`block`] (2D, linear
/// elastic, c_v ≈ 1.3 m²/s over about 1 m: T_v ≈ 0.2 at t = 0.2 s; the pressure stabilisation
/// on, and busy: the initial pressures are noisy): the pore pressures at t = 0.2 s with 4, 8
/// and 16 equal steps against a run of 512 BDF2 steps (whose own time error is ~(1/32)² of
/// the 16-step run's). Every error halves with the step under backward Euler (observed order
/// 0.8–1.3; measured 1.02) and falls 4× under BDF2 (order ≥ 1.7; measured 1.9 and 2.2: the
/// first step after the undrained loading takes backward Euler, a local error of second order
/// that leaves the global order at two), and BDF2 is the more accurate at every step. (With
/// the stabilisation integrated as a backward-Euler increment instead, BDF2 fell to first
/// order here and converged to another limit.)
#[test]
fn bdf2_converges_at_second_order_in_time() {
    let soil = Material::elastic(ModelKind::LinearElastic, 1e7, 0.3, 1800.0);
    let end = 0.2;
    let run = |scheme: TimeIntegration, steps: usize| {
        let (mut config, mut particles) = block::<2>(soil.clone(), Shape::QuadraticBspline, true);
        let fluid = config.pore_fluid.as_mut().expect("coupled");
        fluid.schedule = Schedule::geometric(1, end / steps as f64, 1.0, end);
        fluid.time_integration = scheme;
        config.load_steps = fluid.schedule.steps();
        let mut solver = ImplicitSolver::new(config, &particles).expect("valid");
        while !solver.finished() {
            solver.step(&mut particles).expect("converges");
        }
        assert!((solver.time() - end).abs() < 1e-12);
        particles.pore_pressure
    };
    let reference = run(TimeIntegration::Bdf2, 512);
    let error = |p: Vec<f64>| {
        p.iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f64, f64::max)
    };
    let errors = |scheme| [4, 8, 16].map(|n| error(run(scheme, n)));
    let euler = errors(TimeIntegration::BackwardEuler);
    let bdf2 = errors(TimeIntegration::Bdf2);
    for k in 0..2 {
        let order = |e: &[f64; 3]| (e[k] / e[k + 1]).log2();
        assert!(
            (0.8..=1.3).contains(&order(&euler)),
            "backward Euler: errors {euler:?}"
        );
        assert!(order(&bdf2) >= 1.7, "BDF2: errors {bdf2:?}");
    }
    for k in 0..3 {
        assert!(
            bdf2[k] < euler[k],
            "BDF2 {bdf2:?} against backward Euler {euler:?}"
        );
    }
}

/// The coupled tangent as the operator `v ↦ Kᵀ v` (what the adjoint's solves multiply by)
/// against the transposed product of the assembled tangent, for arbitrary kernel derivatives
/// `Aₚ` (the operator is linear in them, so arbitrary ones test every entry's path) on the
/// saturated block with the stabilisation on.
fn check_transposed_operator<const D: usize, const L: usize>() {
    let elastic = Material::elastic(ModelKind::LinearElastic, 20e6, 0.3, 1800.0);
    let (_, particles, system) = second_step::<D>(elastic, Shape::QuadraticBspline);
    let mut seed = 5;
    let local: Vec<CoupledTangent<L>> = (0..particles.len())
        .map(|_| std::array::from_fn(|_| std::array::from_fn(|_| 1e6 * rng(&mut seed))))
        .collect();
    let k = system
        .coupled_tangent_from::<L>(|p| Some(local[p]))
        .expect("assembled");
    let operator = system.coupled_tangent_transposed(local);
    let v: Vec<f64> = (0..system.len()).map(|_| rng(&mut seed)).collect();
    let (mut assembled, mut free) = (vec![0.0; v.len()], vec![1.0; v.len()]);
    k.mul_vec_transpose(&v, &mut assembled);
    operator.apply(&v, &mut free);
    let scale = assembled.iter().fold(0.0f64, |m, y| m.max(y.abs()));
    let worst = (assembled.iter().zip(&free)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    println!(
        "{D}D: max |Kᵀv| {scale:.3e}, operator vs assembled {:.1e}",
        worst / scale
    );
    assert!(scale > 0.0);
    // The same products summed in another order: round-off of sums of ~100 terms.
    assert!(worst <= 1e-13 * scale, "{worst:e} vs {scale:e}");
}

#[test]
fn the_transposed_tangent_operator_is_the_assembled_tangent() {
    check_transposed_operator::<2, 7>();
    check_transposed_operator::<3, 13>();
}

/// The adjoint's solve `Kᵀλ = b` by GMRES preconditioned with the LU factors of a nearby
/// tangent (a Newton iterate 1 % of an increment away, as the last correction of a step),
/// against a direct solve with `K` itself; and a preconditioner of another matrix, which
/// must be declined rather than return a poor solution.
#[test]
fn the_factors_of_a_nearby_tangent_solve_the_adjoint_system() {
    use loam_implicit::linear::{LinearSolver, LinearSolverKind, NEAR_REL_TOL};
    let hencky = Material::elastic(ModelKind::Hencky, 20e6, 0.3, 1800.0);
    let (solver, _, system) = second_step::<2>(hencky, Shape::QuadraticBspline);
    let mats = solver.materials();
    let n = system.len();
    let mut seed = 11;
    let scale = |d: usize| {
        if system.dofs.owner_of(d).1 < 2 {
            2.5e-3
        } else {
            1e4 / system.flow.as_ref().unwrap().scale
        }
    };
    let x: Vec<f64> = (0..n).map(|d| scale(d) * rng(&mut seed)).collect();
    let near_x: Vec<f64> = (x.iter().enumerate())
        .map(|(d, x)| x + 1e-2 * scale(d) * rng(&mut seed))
        .collect();
    let b: Vec<f64> = (0..n).map(|_| rng(&mut seed)).collect();
    let k = system.tangent_local(&x, mats).expect("tangent");
    let mut direct = LinearSolver::new(LinearSolverKind::Lu);
    let mut exact = vec![0.0; n];
    direct.solve_transpose(&k, &b, &mut exact).expect("direct");
    let product = |v: &[f64], out: &mut [f64]| k.mul_vec_transpose(v, out);
    let factors = |m: &loam_implicit::linear::SparseMatrix| {
        let mut lu = LinearSolver::new(LinearSolverKind::Lu);
        lu.solve(m, &b, &mut vec![0.0; n]).expect("factorised");
        lu.factorisation().expect("LU keeps its factors")
    };
    let mut lambda = vec![0.0; n];
    let iterations = factors(&system.tangent_local(&near_x, mats).expect("tangent"))
        .solve_transpose(&k.pattern, product, &b, &mut lambda)
        .expect("finite")
        .expect("converges");
    let norm = |v: &[f64]| v.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut r = vec![0.0; n];
    k.mul_vec_transpose(&lambda, &mut r);
    r.iter_mut().zip(&b).for_each(|(r, b)| *r = b - *r);
    let difference: Vec<f64> = lambda.iter().zip(&exact).map(|(a, e)| a - e).collect();
    let error = norm(&difference) / norm(&exact);
    println!(
        "{n} unknowns: {iterations} iterations, relative residual {:.1e}, vs direct {error:.1e}",
        norm(&r) / norm(&b)
    );
    // A 1 % change of the increment changes K by a small fraction of itself, and each
    // iteration gains about three decades (5 to reach 1e-14 here).
    assert!((1..=10).contains(&iterations), "{iterations} iterations");
    // The stopping rule, checked on the true residual (GMRES's estimate can drift from it by
    // round-off).
    assert!(norm(&r) <= 10.0 * NEAR_REL_TOL * norm(&b));
    // Both solutions within the round-off that the tangent's conditioning amplifies.
    assert!(error <= 1e-10, "{error:e}");
    // Factors of the tangent with every entry scaled at random by 0.5 to 1.5, a perturbation
    // of full rank: GMRES is not given the iterations it would need, and says so.
    let mut far = k.clone();
    (far.values.iter_mut()).for_each(|v| *v *= 1.0 + 0.5 * rng(&mut seed));
    let declined = factors(&far).solve_transpose(&k.pattern, product, &b, &mut lambda);
    assert!(matches!(declined, Ok(None)), "{declined:?}");
}
