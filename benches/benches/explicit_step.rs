//! Wall-clock cost of one explicit MPM step (P2G, grid update, G2P, stress update).
//!
//! Every bench builds a scene file with `loam_benches::explicit_scene` (a fluid-like block
//! collapse of `benches/scenes/block_*.toml`, the friction dam-break of
//! `examples/dambreak_friction.toml` and `benches/scenes/dambreak_friction_*.toml` at 6k, 96k
//! and 1M particles, or the 3D Drucker–Prager column of `benches/scenes/column_3d_93k.toml`),
//! takes a few steps so the solver's scratch is allocated and the material is moving, and
//! then times one `Solver::step` per iteration. Each timed step starts from a fresh copy of
//! that warmed
//! particle state (`iter_batched_ref`, the copy is not timed), so every iteration does the
//! same work and a long measurement cannot drift the scene into a different regime.
//! The throughput is set to the particle count, so criterion's elements/s are
//! particle-steps per second. Rayon uses all cores unless `RAYON_NUM_THREADS` says otherwise.

use std::time::Duration;

use criterion::measurement::WallTime;
use criterion::{
    BatchSize, BenchmarkGroup, Criterion, Throughput, criterion_group, criterion_main,
};
use loam_benches::explicit_scene;
use loam_core::Scalar;
use loam_explicit::Solver;

/// Steps taken before timing starts.
const WARM_UP_STEPS: usize = 5;

/// Adds the bench `name`: one step of the bench scene `scene` (a stem of
/// `loam_benches::EXPLICIT_SCENES`) in `D` dimensions and precision `T`.
fn bench_step<T: Scalar, const D: usize>(
    group: &mut BenchmarkGroup<'_, WallTime>,
    name: &str,
    scene: &str,
) {
    let (config, mut particles) = explicit_scene::<T, D>(scene);
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
    bench_step::<f64, 2>(&mut group, "2d_10k", "block_2d_10k");
    bench_step::<f64, 2>(&mut group, "2d_100k", "block_2d_100k");
    bench_step::<f32, 2>(&mut group, "2d_100k_f32", "block_2d_100k");
    bench_step::<f64, 3>(&mut group, "3d_100k", "block_3d_100k");
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
    bench_step::<f64, 2>(&mut group, "2d_6k", "dambreak_friction");
    bench_step::<f32, 2>(&mut group, "2d_6k_f32", "dambreak_friction");
    group.finish();
}

/// The `explicit_large` group: the friction dam-break at 96k (4× the resolution) and 1M
/// (13×) particles and the 3D Drucker–Prager column collapse at 93k particles (a third of
/// the example's cell size), f64 and f32.
fn explicit_large(c: &mut Criterion) {
    let mut group = c.benchmark_group("explicit_large");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5));
    bench_step::<f64, 2>(&mut group, "dambreak_96k", "dambreak_friction_96k");
    bench_step::<f32, 2>(&mut group, "dambreak_96k_f32", "dambreak_friction_96k");
    bench_step::<f64, 2>(&mut group, "dambreak_1m", "dambreak_friction_1m");
    bench_step::<f32, 2>(&mut group, "dambreak_1m_f32", "dambreak_friction_1m");
    bench_step::<f64, 3>(&mut group, "dp_column_3d_93k", "column_3d_93k");
    bench_step::<f32, 3>(&mut group, "dp_column_3d_93k_f32", "column_3d_93k");
    group.finish();
}

criterion_group!(benches, explicit_step, explicit_dambreak, explicit_large);
criterion_main!(benches);
