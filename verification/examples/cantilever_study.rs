//! The `cantilever` case's beam with any root, cell size, particle density and load-step count,
//! for the load-path and refinement tables of docs/verification.md.
//!
//! ```text
//! cargo run --release -p loam-verification --example cantilever_study -- ROOT H PPC STEPS... \
//!     [tol=T] [min_support=S] [load_scale=F]
//! cargo run --release -p loam-verification --example cantilever_study -- fe STEPS...
//! ```
//!
//! `ROOT` is `reference` (the benchmark's node columns), `symmetry` or `clamped`
//! (`loam_verification::cantilever::Root`), `H` the cell size in metres, `PPC` the particles per
//! cell per axis, `STEPS` one or more load-step counts (cpGIMP throughout). Options: `T` the
//! Newton residual tolerance (default 1e-8), `S` the implicit solver's node-support threshold
//! (default 1e-4 of a cell), `F` a factor on the tip load (e.g. `1.000000000001` to probe
//! how sensitive a run is to a perturbation). Prints per run the tip (mean displacement of
//! the two loaded particles: `v` down, `u` inward), the mean deflection of the last particle
//! column (the end face), Newton iterations, step cuts and wall time. `fe STEPS...` prints the
//! finite-element continuum's tip (80 × 8 Q9, clamped, tip shear) for each load-step count.

use loam_core::Shape;
use loam_core::tensor::Vector;
use loam_implicit::ImplicitSolver;
use loam_verification::cantilever::{LENGTH, Root, Setup, continuum_tip};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (options, positional): (Vec<&String>, Vec<&String>) =
        args.iter().partition(|a| a.contains('='));
    let count = |s: &String| -> usize { s.parse().expect("STEPS is a whole number") };
    let root = match positional.first().map(|s| s.as_str()) {
        Some("fe") => {
            for steps in positional[1..].iter().map(|s| count(s)) {
                let tip = continuum_tip(80, 8, steps).expect("the continuum reference runs");
                let &(u, v) = tip.last().expect("at least one step");
                println!("continuum (FE 80 × 8), {steps} load steps: v = {v:.8} m, u = {u:.8} m");
            }
            return;
        }
        Some("reference") => Root::Reference,
        Some("symmetry") => Root::Symmetry,
        Some("clamped") => Root::Clamped,
        other => panic!("ROOT {other:?}: expected reference, symmetry, clamped or fe"),
    };
    let cell: f64 = positional
        .get(1)
        .expect("H, the cell size")
        .parse()
        .expect("H is a cell size in metres");
    let ppc: usize = positional
        .get(2)
        .expect("PPC, particles per cell per axis")
        .parse()
        .expect("PPC is a whole number");
    let mut base = Setup {
        root,
        cell,
        ppc,
        ..Setup::reference(Shape::Cpgimp)
    };
    let (mut min_support, mut load_scale) = (None, 1.0);
    for option in options {
        let (key, value) = option.split_once('=').expect("an option is key=value");
        let number: f64 = value
            .parse()
            .unwrap_or_else(|_| panic!("{key}={value}: expected a number"));
        match key {
            "tol" => base.newton.residual_tol = number,
            "min_support" => min_support = Some(number),
            "load_scale" => load_scale = number,
            other => panic!("unknown option {other}: expected tol, min_support or load_scale"),
        }
    }
    println!(
        "| root | h (m) | ppc | load steps | tip v (m) | tip u (m) | end face v (m) | Newton its | cuts | wall (s) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for steps in positional[3..].iter().map(|s| count(s)) {
        let setup = Setup {
            steps,
            load: load_scale * base.load,
            ..base
        };
        let start = std::time::Instant::now();
        let (mut config, mut particles, loaded) = setup.build();
        if let Some(s) = min_support {
            config.min_node_support = s;
        }
        let x0 = particles.x.clone();
        let spacing = cell / ppc as f64;
        let face: Vec<usize> = (0..particles.len())
            .filter(|&p| x0[p][0] > 0.25 + LENGTH - spacing)
            .collect();
        let mean = |x: &[Vector<f64, 2>], ids: &[usize]| {
            ids.iter().fold(Vector::<f64, 2>::zeros(), |s, &p| {
                s + (x[p] - x0[p]) / ids.len() as f64
            })
        };
        let mut solver = ImplicitSolver::new(config, &particles).expect("a valid set-up");
        let (mut iterations, mut cuts) = (0, 0);
        let mut failure = None;
        while !solver.finished() {
            match solver.step(&mut particles) {
                Ok(r) => {
                    iterations += r.iterations();
                    cuts += r.cuts;
                }
                Err(e) => {
                    failure = Some(e);
                    break;
                }
            }
        }
        if let Some(e) = failure {
            println!("| {root:?} | {cell} | {ppc} | {steps} | failed: {e} |");
            continue;
        }
        let tip = mean(&particles.x, &loaded);
        let end = mean(&particles.x, &face);
        println!(
            "| {root:?} | {cell} | {ppc} | {steps} | {:.5} | {:.5} | {:.5} | {iterations} | {cuts} | {:.1} |",
            -tip[1],
            -tip[0],
            -end[1],
            start.elapsed().as_secs_f64()
        );
    }
}
