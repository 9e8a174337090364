//! Wall-clock cost of one explicit MPM step (P2G, grid update, G2P, stress update).
//!
//! Every bench builds a scene (a fluid-like block collapse, the friction dam-break of
//! `loam_benches::dambreak_friction_2d` at 6k, 96k and 1M particles, or the 3D
//! Drucker–Prager column of `loam_benches::granular_column_3d`), takes a few steps so the solver's scratch is
//! allocated and the material is moving, and then times one `Solver::step` per iteration. Each timed step starts from a fresh copy of that warmed
//! particle state (`iter_batched_ref`, the copy is not timed), so every iteration does the
//! same work and a long measurement cannot drift the scene into a different regime.
//! The throughput is set to the particle count, so criterion's elements/s are
//! particle-steps per second. Rayon uses all cores unless `RAYON_NUM_THREADS` says otherwise.

use std::time::Duration;

use criterion::measurement::WallTime;
use criterion::{
    BatchSize, BenchmarkGroup, Criterion, Throughput, criterion_group, criterion_main,
};
use loam_benches::{dambreak_friction_2d, fluid_block_2d, fluid_block_3d, granular_column_3d};
use loam_core::{Particles, Scalar};
use loam_explicit::{Config, Solver};

/// Steps taken before timing starts.
const WARM_UP_STEPS: usize = 5;

/// Adds the bench `name`: one step of the scene `(config, particles)`.
fn bench_step<T: Scalar, const D: usize>(
    group: &mut BenchmarkGroup<'_, WallTime>,
    name: &str,
    (config, mut particles): (Config<T, D>, Particles<T, D>),
) {
    let mut solver = Solver::new(config, &particles).expect("valid bench scene");
    for _ in 0..WARM_UP_STEPS {
        solver
            .step(&mut particles, f64::INFINITY)
            .expect("stable warm-up step");
    }
    group.throughput(Throughput::Elements(particles.len() as u64));
    group.bench_function(name, |b| {
        b.iter_batched_ref(
            || particles.clone(),
            |p| solver.step(p, f64::INFINITY).expect("stable step"),
            BatchSize::PerIteration,
        );
    });
}

/// The `explicit_step` group: 2D and 3D block collapses of about 10k and 100k particles.
fn explicit_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("explicit_step");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));
    bench_step(&mut group, "2d_10k", fluid_block_2d::<f64>(10_000));
    bench_step(&mut group, "2d_100k", fluid_block_2d::<f64>(100_000));
    bench_step(&mut group, "2d_100k_f32", fluid_block_2d::<f32>(100_000));
    bench_step(&mut group, "3d_100k", fluid_block_3d::<f64>(100_000));
    group.finish();
}

/// The `explicit_dambreak` group: the friction dam-break (6,000 water particles, fixed
/// Δt = 3e-5 s), whose per-step fixed costs dominate; f64 and f32.
fn explicit_dambreak(c: &mut Criterion) {
    let mut group = c.benchmark_group("explicit_dambreak");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    bench_step(&mut group, "2d_6k", dambreak_friction_2d::<f64>(1));
    bench_step(&mut group, "2d_6k_f32", dambreak_friction_2d::<f32>(1));
    group.finish();
}

/// The `explicit_large` group: the friction dam-break at 96k (scale 4) and 1M (scale 13)
/// particles and the 3D Drucker–Prager column collapse at 93k particles (resolution 3), f64
/// and f32.
fn explicit_large(c: &mut Criterion) {
    let mut group = c.benchmark_group("explicit_large");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5));
    bench_step(&mut group, "dambreak_96k", dambreak_friction_2d::<f64>(4));
    bench_step(
        &mut group,
        "dambreak_96k_f32",
        dambreak_friction_2d::<f32>(4),
    );
    bench_step(&mut group, "dambreak_1m", dambreak_friction_2d::<f64>(13));
    bench_step(
        &mut group,
        "dambreak_1m_f32",
        dambreak_friction_2d::<f32>(13),
    );
    bench_step(&mut group, "dp_column_3d_93k", granular_column_3d::<f64>(3));
    bench_step(
        &mut group,
        "dp_column_3d_93k_f32",
        granular_column_3d::<f32>(3),
    );
    group.finish();
}

criterion_group!(benches, explicit_step, explicit_dambreak, explicit_large);
criterion_main!(benches);
