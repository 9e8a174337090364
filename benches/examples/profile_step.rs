//! Runs explicit steps of a bench scene and prints the time per step (for profilers).
//!
//! `cargo run --release -p loam-benches --example profile_step -- [SCENE] [STEPS] [f32|f64]`
//! with `SCENE` one of `dambreak` (the friction dam-break of
//! `examples/dambreak_friction.toml`, 6,000 particles, MLS-MPM with USL; default),
//! `dambreak_apic` (the same with APIC's gradient force), `dambreak_apic_musl` (APIC with
//! MUSL), `dambreak4` (at 4× the resolution, 96,000 particles,
//! `benches/scenes/dambreak_friction_96k.toml`), `dambreak13` (at 13×, 1,014,000 particles,
//! `dambreak_friction_1m.toml`), `column3d` (the 3D Drucker–Prager column,
//! 93,312 particles, `column_3d_93k.toml`), `block2d` (2D block collapse, 101,124 particles,
//! `block_2d_100k.toml`) or `block3d` (3D block collapse, 110,592 particles,
//! `block_3d_100k.toml`).

use loam_benches::explicit_scene;
use loam_core::{Scalar, Scheme, Transfer};
use loam_explicit::{Config, Solver};

/// Takes `steps` steps of the bench scene `file` (a stem of `loam_benches::EXPLICIT_SCENES`)
/// with its configuration changed by `adjust`, and prints the time per step.
fn run<T: Scalar, const D: usize>(
    name: &str,
    file: &str,
    steps: usize,
    adjust: impl FnOnce(&mut Config<T, D>),
) {
    let (mut config, mut p) = explicit_scene::<T, D>(file);
    adjust(&mut config);
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

/// Leaves a configuration as the scene file has it.
fn keep<C>(_: &mut C) {}

/// Runs `scene` with the scalar type `T`.
fn scene<T: Scalar>(scene: &str, steps: usize) {
    match scene {
        "dambreak" => run::<T, 2>(scene, "dambreak_friction", steps, keep),
        "dambreak4" => run::<T, 2>(scene, "dambreak_friction_96k", steps, keep),
        "dambreak13" => run::<T, 2>(scene, "dambreak_friction_1m", steps, keep),
        "column3d" => run::<T, 3>(scene, "column_3d_93k", steps, keep),
        "dambreak_apic" => run::<T, 2>(scene, "dambreak_friction", steps, |c| {
            c.transfer = Transfer::Apic;
        }),
        "dambreak_apic_musl" => run::<T, 2>(scene, "dambreak_friction", steps, |c| {
            c.transfer = Transfer::Apic;
            c.scheme = Scheme::Musl;
        }),
        "block2d" => run::<T, 2>(scene, "block_2d_100k", steps, keep),
        "block3d" => run::<T, 3>(scene, "block_3d_100k", steps, keep),
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
