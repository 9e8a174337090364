//! The reference large-deflection cantilever end to end: 50 load steps of quasi-static Newton
//! on 5,760 particles (`examples/cantilever.toml`, built by `loam_benches::implicit_scene` as
//! `loam run` builds it: cpGIMP, the default Newton settings, i.e. per-particle AD tangent
//! and sparse LU).
//!
//! A plain `main` (no criterion): one run takes seconds, so it is run [`RUNS`] times and each
//! run is reported with its wall time, Newton iterations, and the split of the Newton time
//! between tangent assembly, linear solves and residual evaluations (the `NewtonReport`
//! timings summed over every solve of every load step); "other" is the rest of the wall time
//! (building each step's system and sparsity pattern, the particle updates). The tip
//! deflection at full load (the mean displacement of the two loaded particles) is compared
//! with the elastica (`EI`) and with Reissner's plane-strain beam.
//!
//! `cargo bench -p loam-benches --bench cantilever` runs it; under `cargo test --benches`
//! (no `--bench` argument) it only prints how to run it.

use std::time::Instant;

use loam_benches::implicit_scene;
use loam_core::Particles;
use loam_core::tensor::Vector;
use loam_implicit::{ImplicitConfig, ImplicitSolver, StepReport};
use loam_verification::elastica::{tip_displacement, tip_displacement_reissner};

/// Timed runs.
const RUNS: usize = 3;

/// What one run did.
struct Run {
    wall: f64,
    iterations: usize,
    attempted: usize,
    cuts: usize,
    tangent: f64,
    linear: f64,
    residual: f64,
    /// Tip displacement at full load: (inward u, downward v), m.
    tip: (f64, f64),
}

// The beam of `examples/cantilever.toml`, for the reference tip displacements.
/// Beam length `L` (m).
const LENGTH: f64 = 10.0;
/// Beam depth `d` (m).
const DEPTH: f64 = 1.0;
/// Young's modulus `E` (Pa).
const YOUNG: f64 = 12.0e6;
/// Poisson's ratio `ν`.
const POISSON: f64 = 0.2;
/// Total tip load `P` (N per m of thickness).
const LOAD: f64 = 100.0e3;

fn run_once(config: &ImplicitConfig<2>, particles: &Particles<f64, 2>) -> Run {
    let mut particles = particles.clone();
    let loaded: Vec<usize> = config.point_loads.iter().map(|l| l.particle).collect();
    let start_x: Vec<Vector<f64, 2>> = loaded.iter().map(|&p| particles.x[p]).collect();
    let start = Instant::now();
    let mut solver = ImplicitSolver::new(config.clone(), &particles).expect("a valid scene");
    let mut reports = Vec::new();
    while !solver.finished() {
        reports.push(
            solver
                .step(&mut particles)
                .expect("the reference cantilever converges"),
        );
    }
    let wall = start.elapsed().as_secs_f64();
    let solves = || reports.iter().flat_map(|r| &r.solves);
    let tip = loaded
        .iter()
        .zip(&start_x)
        .map(|(&p, x0)| particles.x[p] - x0)
        .sum::<Vector<f64, 2>>()
        / loaded.len() as f64;
    Run {
        wall,
        iterations: reports.iter().map(StepReport::iterations).sum(),
        attempted: solves().map(|s| s.iterations()).sum(),
        cuts: reports.iter().map(|r| r.cuts).sum(),
        tangent: solves().map(|s| s.time_tangent).sum(),
        linear: solves().map(|s| s.time_linear).sum(),
        residual: solves().map(|s| s.time_residual).sum(),
        tip: (-tip[0], -tip[1]),
    }
}

/// The tip displacement `(inward u, downward v)` (m) at full load of the elastica (`EI`,
/// `α = PL²/EI`) and of Reissner's beam with the plane-strain moduli (`E′ = E/(1 − ν²)` in
/// bending and axial stiffness, shear stiffness `κGA` with κ = 5/6).
fn reference_tips() -> [(&'static str, (f64, f64)); 2] {
    let i = DEPTH.powi(3) / 12.0;
    let elastica = tip_displacement(LOAD * LENGTH * LENGTH / (YOUNG * i));
    let plane = YOUNG / (1.0 - POISSON * POISSON);
    let shear = YOUNG / (2.0 * (1.0 + POISSON));
    let ei = plane * i;
    let reissner = tip_displacement_reissner(
        LOAD * LENGTH * LENGTH / ei,
        ei / (plane * DEPTH * LENGTH * LENGTH),
        ei / (5.0 / 6.0 * shear * DEPTH * LENGTH * LENGTH),
    );
    [
        ("elastica (EI)", elastica),
        ("Reissner (plane strain)", reissner),
    ]
    .map(|(name, (v, u))| (name, (u * LENGTH, v * LENGTH)))
}

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        println!("cantilever: run with `cargo bench -p loam-benches --bench cantilever`");
        return;
    }
    let (config, particles) = implicit_scene::<2>("cantilever");
    let n = particles.len();
    println!(
        "cantilever: examples/cantilever.toml, {n} particles, {} load steps, h = {} m, {} rayon threads",
        config.load_steps,
        config.grid.h,
        rayon::current_num_threads(),
    );
    let mut runs = Vec::new();
    for k in 0..RUNS {
        let r = run_once(&config, &particles);
        let newton = r.tangent + r.linear + r.residual;
        println!(
            "run {}: wall {:.3} s, Newton iterations {} (attempted {}, cuts {}), \
             tangent {:.3} s ({:.1} %), linear {:.3} s ({:.1} %), residual {:.3} s ({:.1} %), \
             other {:.3} s ({:.1} %); per tangent {:.2} ms = {:.2} µs/particle",
            k + 1,
            r.wall,
            r.iterations,
            r.attempted,
            r.cuts,
            r.tangent,
            100.0 * r.tangent / r.wall,
            r.linear,
            100.0 * r.linear / r.wall,
            r.residual,
            100.0 * r.residual / r.wall,
            r.wall - newton,
            100.0 * (r.wall - newton) / r.wall,
            1e3 * r.tangent / r.attempted as f64,
            1e6 * r.tangent / (r.attempted * n) as f64,
        );
        runs.push(r);
    }
    let best = runs
        .iter()
        .min_by(|a, b| a.wall.total_cmp(&b.wall))
        .expect("at least one run");
    let mean = runs.iter().map(|r| r.wall).sum::<f64>() / runs.len() as f64;
    println!(
        "wall time: min {:.3} s, mean {mean:.3} s over {} runs",
        best.wall,
        runs.len()
    );
    let (u, v) = best.tip;
    println!("tip at full load: v = {v:.4} m (down), u = {u:.4} m (inward)");
    for (name, (ur, vr)) in reference_tips() {
        println!(
            "  vs {name}: v = {vr:.4} m, u = {ur:.4} m; error v {:.3} %, u {:.3} %",
            100.0 * (v - vr).abs() / vr,
            100.0 * (u - ur).abs() / ur,
        );
    }
}
