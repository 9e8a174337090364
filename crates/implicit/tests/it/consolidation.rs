//! Coupled (u–p) consolidation against Terzaghi's one-dimensional solution: a weightless
//! column of linear-elastic soil on an impermeable, fixed base, drained at the top, loaded
//! there by a traction `q` applied undrained at `t = 0` and held.

use loam_core::tensor::Vector;
use loam_core::{Boundary, Grid, Material, ModelKind, Particles, PointLoad, Shape, Wall, WallKind};
use loam_implicit::flow::{Hydraulic, PoreFluid, Schedule};
use loam_implicit::{ImplicitConfig, ImplicitSolver, NewtonSettings};

/// GeoWarp's Terzaghi configuration: a 10 m column, E = 1.5 MPa, ν = 0.25, mobility
/// k/γ_w = 1e-6 m²/(kPa·s) = 1e-9 m²/(Pa·s), q = 1 kPa.
const HEIGHT: f64 = 10.0;
const YOUNG: f64 = 1.5e6;
const POISSON: f64 = 0.25;
const MOBILITY: f64 = 1e-9;
const LOAD: f64 = 1e3;

/// The constrained modulus `M = E(1−ν)/((1+ν)(1−2ν))` and consolidation coefficient
/// `c_v = κ M`.
fn consolidation_coefficient() -> f64 {
    let m = YOUNG * (1.0 - POISSON) / ((1.0 + POISSON) * (1.0 - 2.0 * POISSON));
    MOBILITY * m
}

/// Terzaghi's excess pore pressure `p/q = Σ (2/M) sin(M z/H) exp(−M² T_v)`, `M = π(2m+1)/2`,
/// at depth `z` below the drained top.
fn terzaghi_pressure(depth: f64, tv: f64) -> f64 {
    (0..2000)
        .map(|m| {
            let mm = std::f64::consts::PI * (2 * m + 1) as f64 / 2.0;
            2.0 / mm * (mm * depth / HEIGHT).sin() * (-mm * mm * tv).exp()
        })
        .sum()
}

/// The settlement of the material point at depth `d` relative to the final settlement of
/// the top, `s(d)/s_∞ = [(H − d) − Σ (2H/M²) cos(M d/H) exp(−M² T_v)] / H` (the integral of
/// the strain `(q − p)/M_c` from `d` to the base); at `d = 0` it is Terzaghi's degree of
/// consolidation `U = 1 − Σ (2/M²) exp(−M² T_v)`.
fn terzaghi_settlement(depth: f64, tv: f64) -> f64 {
    let series: f64 = (0..2000)
        .map(|m| {
            let mm = std::f64::consts::PI * (2 * m + 1) as f64 / 2.0;
            2.0 * HEIGHT / (mm * mm) * (mm * depth / HEIGHT).cos() * (-mm * mm * tv).exp()
        })
        .sum();
    (HEIGHT - depth - series) / HEIGHT
}

/// The column one cell wide with cells of `h`, 2 × 2 particles per cell, slip side walls,
/// a fixed base, the top face drained; the load on the top row of particles.
fn column(
    h: f64,
    shape: Shape,
    schedule: Schedule,
    stabilisation: bool,
) -> (ImplicitConfig<2>, Particles<f64, 2>) {
    let cells = [1, (HEIGHT / h).round() as usize];
    let grid = Grid::new([0.0, 0.0], cells, h, shape.ghost_cells());
    let mut boundary = Boundary::all(Wall::new(WallKind::Slip));
    boundary.walls[1][0] = Wall::new(WallKind::Fixed);
    boundary.walls[1][1] = Wall::new(WallKind::Free);
    let spacing = h / 2.0;
    let mut particles = Particles::default();
    let mut point_loads = Vec::new();
    let rows = (HEIGHT / spacing).round() as usize;
    for j in 0..rows {
        for i in 0..2 {
            let x = Vector::<f64, 2>::new((i as f64 + 0.5) * spacing, (j as f64 + 0.5) * spacing);
            if j == rows - 1 {
                point_loads.push(PointLoad {
                    particle: particles.len(),
                    force: [0.0, -LOAD * spacing],
                });
            }
            particles.push(x, Vector::zeros(), 1.0, Vector::repeat(spacing / 2.0), 0);
        }
    }
    let load_steps = schedule.steps();
    let config = ImplicitConfig {
        grid,
        shape,
        boundary,
        materials: vec![Material::elastic(
            ModelKind::LinearElastic,
            YOUNG,
            POISSON,
            1.0,
        )],
        gravity: Vector::zeros(),
        constraints: Vec::new(),
        point_loads,
        load_steps,
        newton: NewtonSettings::default(),
        dynamics: None,
        gravity_in_full: false,
        min_node_support: ImplicitConfig::<2>::DEFAULT_MIN_NODE_SUPPORT,
        balance: Vec::new(),
        pore_fluid: Some(PoreFluid {
            hydraulic: vec![Hydraulic {
                mobility: MOBILITY,
                biot: 1.0,
                storage: 0.0,
            }],
            unit_weight: 9810.0,
            water_table: None,
            drained: [[false, false], [false, true]],
            stabilisation,
            schedule,
        }),
    };
    (config, particles)
}

/// Runs the column with steps of `first × growth^k` (in T_v) through `times` (T_v) and
/// returns, at each, the largest error of the particles' excess pore pressure against
/// Terzaghi's, relative to q, and the relative error of the settlement of the top row of
/// particles against the exact settlement of the same material points.
fn run(h: f64, shape: Shape, first: f64, growth: f64, times: &[f64]) -> Vec<(f64, f64, f64)> {
    let cv = consolidation_coefficient();
    let to_time = |tv: f64| tv * HEIGHT * HEIGHT / cv;
    let end = to_time(*times.last().unwrap());
    let mut schedule = Schedule::geometric(1, to_time(first), growth, end);
    for &tv in times {
        schedule.land_on(to_time(tv));
    }
    let (config, mut particles) = column(h, shape, schedule, true);
    let m = YOUNG * (1.0 - POISSON) / ((1.0 + POISSON) * (1.0 - 2.0 * POISSON));
    let settlement_final = LOAD * HEIGHT / m;
    let top0: Vec<f64> = particles.x.iter().map(|x| x[1]).collect();
    let mut solver = ImplicitSolver::new(config, &particles).expect("valid");
    let mut out = Vec::new();
    let mut next = 0;
    while !solver.finished() {
        let report = solver.step(&mut particles).expect("step converges");
        let t = solver.time();
        assert!(
            report.iterations() <= 6,
            "{} Newton iterations at t = {t}",
            report.iterations()
        );
        if next < times.len() && (t - to_time(times[next])).abs() <= 1e-9 * t {
            let tv = times[next];
            let err = (0..particles.len())
                .map(|p| {
                    let exact = terzaghi_pressure(HEIGHT - top0[p], tv);
                    (particles.pore_pressure[p] / LOAD - exact).abs()
                })
                .fold(0.0f64, f64::max);
            let top: Vec<usize> = (0..particles.len())
                .filter(|&p| top0[p] > HEIGHT - h / 2.0)
                .collect();
            let s = top
                .iter()
                .map(|&p| top0[p] - particles.x[p][1])
                .sum::<f64>()
                / top.len() as f64;
            let exact = terzaghi_settlement(HEIGHT - top0[top[0]], tv);
            out.push((tv, err, s / settlement_final / exact - 1.0));
            next += 1;
        }
    }
    out
}

/// Steps of ΔT_v = 1.8e-3 (GeoWarp's 100 s) on cells of 0.25 m (40 in the column):
/// backward Euler lags the exact decay of the first mode by `exp(M⁴ ΔT_v T_v / 2)` − 1
/// ≈ 0.55 % × T_v, which with the spatial error bounds the pressure error by ~3e-3 q at
/// T_v = 0.1 (the steep profile near the drained top) and ~1.5e-3 q later. The settlement
/// of the top particles is held to the 1 % asked of the degree of consolidation (its
/// spatial error falls from ~0.5 % on these cells to ~0.04 % on cells of 0.1 m).
#[test]
fn terzaghi_with_constant_time_steps() {
    let times = [0.1, 0.2, 0.5, 1.0];
    let rows = run(0.25, Shape::QuadraticBspline, 1.8e-3, 1.0, &times);
    for (tv, err, settlement) in rows {
        println!("T_v {tv}: max |p − p_exact|/q = {err:.2e}, settlement {settlement:+.2e}");
        assert!(
            err <= if tv < 0.15 { 3e-3 } else { 1.5e-3 },
            "T_v {tv}: {err:e}"
        );
        assert!(settlement.abs() <= 1e-2, "T_v {tv}: {settlement:e}");
    }
}

/// Geometrically growing steps, ΔT_v = 1e-3 × 1.1^k (48 steps to T_v = 1, plus the four
/// output times): the degree of consolidation within 1 %; the pressure error is backward
/// Euler's with steps up to ΔT_v ≈ 0.09 (about 1.5 % of q).
#[test]
fn terzaghi_with_growing_time_steps() {
    let times = [0.1, 0.2, 0.5, 1.0];
    let rows = run(0.25, Shape::QuadraticBspline, 1e-3, 1.1, &times);
    for (tv, err, settlement) in rows {
        println!("T_v {tv}: max |p − p_exact|/q = {err:.2e}, settlement {settlement:+.2e}");
        assert!(err <= 2e-2, "T_v {tv}: {err:e}");
        assert!(settlement.abs() <= 1e-2, "T_v {tv}: {settlement:e}");
    }
}

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
            }],
            unit_weight: 9810.0,
            water_table: Some(1.5),
            drained,
            stabilisation,
            schedule,
        }),
    };
    (config, particles)
}

/// The coupled tangent, per-particle and colour-seeded, against central differences of the
/// residual at a random trial state (displacement increments of ~1 % strain, pressures of
/// ~10 kPa) of the second step (Δt = 10 s), with the stabilisation on.
fn check_coupled_tangent<const D: usize>(material: Material<f64>, shape: Shape) {
    let (config, particles) = block::<D>(material, shape, true);
    let solver = ImplicitSolver::new(config, &particles).expect("valid");
    let progress = 1.0 / solver.config().load_steps as f64;
    let system = solver
        .system(&particles, progress, 2.0 * progress)
        .expect("system");
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
    for j in 0..n {
        // Central differences: truncation O(ε²) against round-off O(1e-16 |R| / ε). Both
        // kinds of unknown are lengths (the pressure scaled by h/G), of ~1e-3 m; ε = 1e-8 m
        // balances the two near 1e-8 of the block's largest entry.
        let eps = 1e-8;
        let mut xp = x.clone();
        xp[j] += eps;
        let rp = system.residual(&xp, mats).expect("residual");
        xp[j] -= 2.0 * eps;
        let rm = system.residual(&xp, mats).expect("residual");
        for i in 0..n {
            let (bi, bj) = (pressure(i), pressure(j));
            let fd = (rp[i] - rm[i]) / (2.0 * eps);
            let kl = at(&local, i, j);
            kmax[bi][bj] = kmax[bi][bj].max(kl.abs());
            worst_fd[bi][bj] = worst_fd[bi][bj].max((kl - fd).abs());
            worst_colour[bi][bj] = worst_colour[bi][bj].max((kl - at(&colour, i, j)).abs());
        }
    }
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
