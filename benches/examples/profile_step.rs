//! Runs explicit steps of a bench scene and prints the time per step (for profilers).
//!
//! `cargo run --release -p loam-benches --example profile_step -- [SCENE] [STEPS] [f32|f64]`
//! with `SCENE` one of `dambreak` (the friction dam-break, 6,000 particles, MLS-MPM with USL;
//! default), `dambreak_apic` (the same with APIC's gradient force), `dambreak_apic_musl`
//! (APIC with MUSL), `dambreak4` (at scale 4, 96,000
//! particles), `dambreak13` (at scale 13, 1,014,000 particles), `column3d` (the 3D
//! Drucker–Prager column at resolution 3, 93,312 particles), `block2d` (2D block collapse,
//! 101k particles) or `block3d` (3D block collapse, 111k particles).

use loam_core::{Particles, Scalar};
use loam_explicit::{Config, Solver};

/// Takes `steps` steps of `(config, particles)` and prints the time per step.
fn run<T: Scalar, const D: usize>(
    name: &str,
    steps: usize,
    (config, mut p): (Config<T, D>, Particles<T, D>),
) {
    let mut s = Solver::new(config, &p).expect("valid scene");
    let t = std::time::Instant::now();
    for _ in 0..steps {
        s.step(&mut p, f64::INFINITY).expect("stable step");
    }
    let per_step = t.elapsed().as_secs_f64() / steps as f64;
    println!(
        "{name}: {} particles, {steps} steps, {:.1} µs/step, {:.2} M particle-steps/s",
        p.len(),
        per_step * 1e6,
        p.len() as f64 / per_step * 1e-6
    );
}

/// Runs `scene` with the scalar type `T`.
fn scene<T: Scalar>(scene: &str, steps: usize) {
    use loam_benches::*;
    match scene {
        "dambreak" => run(scene, steps, dambreak_friction_2d::<T>(1)),
        "dambreak4" => run(scene, steps, dambreak_friction_2d::<T>(4)),
        "dambreak13" => run(scene, steps, dambreak_friction_2d::<T>(13)),
        "column3d" => run(scene, steps, granular_column_3d::<T>(3)),
        "dambreak_apic" => {
            let (mut config, particles) = dambreak_friction_2d::<T>(1);
            config.transfer = loam_core::Transfer::Apic;
            run(scene, steps, (config, particles))
        }
        "dambreak_apic_musl" => {
            let (mut config, particles) = dambreak_friction_2d::<T>(1);
            config.transfer = loam_core::Transfer::Apic;
            config.scheme = loam_core::Scheme::Musl;
            run(scene, steps, (config, particles))
        }
        "block2d" => run(scene, steps, fluid_block_2d::<T>(100_000)),
        "block3d" => run(scene, steps, fluid_block_3d::<T>(100_000)),
        _ => panic!(
            "unknown scene {scene} \
             (dambreak, dambreak_apic, dambreak_apic_musl, dambreak4, dambreak13, column3d, block2d, block3d)"
        ),
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map_or("dambreak", String::as_str);
    let steps = args.get(2).map_or(2000, |s| s.parse().expect("STEPS"));
    match args.get(3).map_or("f64", String::as_str) {
        "f32" => scene::<f32>(name, steps),
        _ => scene::<f64>(name, steps),
    }
}
