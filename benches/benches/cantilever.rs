//! The reference large-deflection cantilever end to end: 50 load steps of quasi-static Newton
//! on 5,760 particles (`loam_verification::cantilever::Setup::reference` with cpGIMP as in
//! `examples/cantilever.toml`, the default Newton settings: per-particle AD tangent, sparse LU).
//!
//! A plain `main` (no criterion): one run takes seconds, so it is run [`RUNS`] times and each
//! run is reported with its wall time, Newton iterations, and the split of the Newton time
//! between tangent assembly, linear solves and residual evaluations (the `NewtonReport`
//! timings summed over every solve of every load step); "other" is the rest of the wall time
//! (building each step's system and sparsity pattern, the particle updates). The tip
//! deflection at full load is compared with the elastica (`EI`) and with Reissner's
//! plane-strain beam.
//!
//! `cargo bench -p loam-benches --bench cantilever` runs it; under `cargo test --benches`
//! (no `--bench` argument) it only prints how to run it.

use std::time::Instant;

use loam_core::Shape;
use loam_implicit::StepReport;
use loam_verification::cantilever::{self, Beam, Setup};

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

fn run_once(setup: &Setup) -> Run {
    let start = Instant::now();
    let (tips, reports) = setup.run().expect("the reference cantilever converges");
    let wall = start.elapsed().as_secs_f64();
    let solves = || reports.iter().flat_map(|r| &r.solves);
    let last = tips.last().copied().expect("50 load steps");
    Run {
        wall,
        iterations: reports.iter().map(StepReport::iterations).sum(),
        attempted: solves().map(|s| s.iterations()).sum(),
        cuts: reports.iter().map(|r| r.cuts).sum(),
        tangent: solves().map(|s| s.time_tangent).sum(),
        linear: solves().map(|s| s.time_linear).sum(),
        residual: solves().map(|s| s.time_residual).sum(),
        tip: (-last[0], -last[1]),
    }
}

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        println!("cantilever: run with `cargo bench -p loam-benches --bench cantilever`");
        return;
    }
    let setup = Setup::reference(Shape::Cpgimp);
    let (_, particles, _) = setup.build();
    let n = particles.len();
    println!(
        "cantilever: reference set-up, {n} particles, {} load steps, h = {} m, {}×{} particles/cell, {} rayon threads",
        setup.steps,
        setup.cell,
        setup.ppc,
        setup.ppc,
        rayon::current_num_threads(),
    );
    let mut runs = Vec::new();
    for k in 0..RUNS {
        let r = run_once(&setup);
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
    for (name, beam) in [
        ("elastica (EI)", Beam::Elastica),
        ("Reissner (plane strain)", Beam::Reissner),
    ] {
        let (ur, vr) = cantilever::reference_tip(1.0, beam);
        println!(
            "  vs {name}: v = {vr:.4} m, u = {ur:.4} m; error v {:.3} %, u {:.3} %",
            100.0 * (v - vr).abs() / vr,
            100.0 * (u - ur).abs() / ur,
        );
    }
}
