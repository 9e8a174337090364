//! Wall-clock cost of the pieces of one Newton iteration of the implicit path: a residual
//! evaluation, the two tangent assemblies, and the sparse LU factorisation + solve.
//!
//! Scenes (scene files, see `loam_benches`): the quadratic-B-spline cantilever of
//! `benches/scenes/cantilever_2d.toml` at three cell sizes (2D, 0.25 / 0.125 / 0.0625 m: 5,760 /
//! 23,040 / 92,160 particles) and the Hencky block of `benches/scenes/hencky_block_3d_27k.toml`
//! settling under gravity on a fixed floor (3D, 27,000 particles). Each bench builds an `ImplicitSolver` and the system of the first load
//! step, `solver.system(&particles, 0.0, 0.02)` (load factor 0 → 0.02), and evaluates
//! everything at one non-zero trial increment `x`: the first Newton correction, i.e. the
//! solution of `K(0) δ = −R(0)` by LU. That is the state the second Newton iteration of the
//! first load step starts from, so `ΔF ≠ I` and every particle does real constitutive work.
//!
//! Timed (`implicit_tangent/<what>/<scene>`):
//!
//! - `residual`: one `StepSystem::residual(&x, …)`.
//! - `tangent_local`: `StepSystem::tangent_local`, the per-particle AD tangent (Newton's
//!   default).
//! - `tangent_colour`: `StepSystem::tangent_colour`, the block-colour-seeded reference (`3^D`
//!   colour passes for quadratic B-splines).
//! - `lu`: numeric LU factorisation + solve of `K(x) δ = −R(x)` with the symbolic analysis
//!   cached, as in every Newton iteration after the first of a load step.
//! - `lu_analyse`: the same from a fresh `LinearSolver` (symbolic analysis included), as in the
//!   first Newton iteration of every load step (the pattern changes with the particles).
//!
//! The throughput is set to the particle count, so criterion's elements/s are particles per
//! second (for `lu` that is only a normalisation). Rayon uses all cores unless
//! `RAYON_NUM_THREADS` says otherwise; the LU is sequential (faer `Par::Seq`).

use std::time::Duration;

use criterion::measurement::WallTime;
use criterion::{
    BenchmarkGroup, BenchmarkId, Criterion, Throughput, criterion_group, criterion_main,
};
use loam_benches::{cantilever_2d, implicit_scene};
use loam_core::Particles;
use loam_implicit::linear::{LinearSolver, LinearSolverKind};
use loam_implicit::{ImplicitConfig, ImplicitSolver};

/// Load factor at the end of the benchmarked (first) load step.
const LOAD_FACTOR: f64 = 0.02;

/// Adds the benches of one scene under the parameter `name`.
fn bench_scene<const D: usize>(
    group: &mut BenchmarkGroup<'_, WallTime>,
    name: &str,
    (config, particles): (ImplicitConfig<D>, Particles<f64, D>),
) {
    let solver = ImplicitSolver::new(config, &particles).expect("valid bench scene");
    let system = solver
        .system(&particles, 0.0, LOAD_FACTOR)
        .expect("particles on the grid");
    let materials = solver.materials();
    let mut lu = LinearSolver::new(LinearSolverKind::Lu);

    // Trial increment: the first Newton correction from x = 0.
    let zero = vec![0.0; system.len()];
    let r0 = system
        .residual(&zero, materials)
        .expect("x = 0 is admissible");
    let k0 = system
        .tangent_local(&zero, materials)
        .expect("x = 0 is admissible");
    let neg_r0: Vec<f64> = r0.iter().map(|v| -v).collect();
    let mut x = vec![0.0; system.len()];
    lu.solve(&k0, &neg_r0, &mut x)
        .expect("non-singular tangent");
    let r = system
        .residual(&x, materials)
        .expect("the first Newton correction inverts no particle");
    let neg_r: Vec<f64> = r.iter().map(|v| -v).collect();
    let k = system
        .tangent_local(&x, materials)
        .expect("the first Newton correction inverts no particle");
    let norm = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>().sqrt();
    eprintln!(
        "{name}: {} particles, {} unknowns, {} tangent non-zeros, \
         max |x| = {:.3e} m (h = {} m), ‖R(0)‖ = {:.3e}, ‖R(x)‖ = {:.3e}",
        particles.len(),
        system.len(),
        system.pattern.nnz(),
        x.iter().fold(0.0f64, |m, v| m.max(v.abs())),
        solver.config().grid.h,
        norm(&r0),
        norm(&r),
    );

    group.throughput(Throughput::Elements(particles.len() as u64));
    group.bench_function(BenchmarkId::new("residual", name), |b| {
        b.iter(|| system.residual(&x, materials).expect("admissible"));
    });
    group.bench_function(BenchmarkId::new("tangent_local", name), |b| {
        b.iter(|| system.tangent_local(&x, materials).expect("admissible"));
    });
    group.bench_function(BenchmarkId::new("tangent_colour", name), |b| {
        b.iter(|| system.tangent_colour(&x, materials).expect("admissible"));
    });
    let mut dx = vec![0.0; system.len()];
    group.bench_function(BenchmarkId::new("lu", name), |b| {
        b.iter(|| lu.solve(&k, &neg_r, &mut dx).expect("non-singular tangent"));
    });
    group.bench_function(BenchmarkId::new("lu_analyse", name), |b| {
        b.iter(|| {
            LinearSolver::new(LinearSolverKind::Lu)
                .solve(&k, &neg_r, &mut dx)
                .expect("non-singular tangent")
        });
    });
}

/// The `implicit_tangent` group: the cantilever at 3 sizes (2D) and the 3D block.
fn implicit_tangent(c: &mut Criterion) {
    let mut group = c.benchmark_group("implicit_tangent");
    // Criterion switches to flat sampling (10 iterations at least) for the slow benches.
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    bench_scene(&mut group, "2d_6k", cantilever_2d(0.25));
    bench_scene(&mut group, "2d_23k", cantilever_2d(0.125));
    bench_scene(&mut group, "2d_92k", cantilever_2d(0.0625));
    bench_scene(
        &mut group,
        "3d_27k",
        implicit_scene::<3>("hencky_block_3d_27k"),
    );
    group.finish();
}

criterion_group!(benches, implicit_tangent);
criterion_main!(benches);
