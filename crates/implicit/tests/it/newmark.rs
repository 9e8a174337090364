//! Newmark dynamics of the implicit solver: exact rigid motion under gravity and exact energy
//! conservation for a linear-elastic body (the identity derived on `loam_implicit::system::Inertia`).

use loam_core::energy::energy;
use loam_core::tensor::Vector;
use loam_core::{Boundary, Grid, Material, ModelKind, Particles, Shape, Wall, WallKind};
use loam_implicit::{ImplicitConfig, ImplicitSolver, NewtonSettings};

/// A `width × width` m block of `model` (E = 100 Pa, ν = 0.3, ρ = 1 kg/m³; P-wave speed
/// c ≈ 11.6 m/s, explicit limit h/c ≈ 0.011 s) with its lower-left corner at `corner` on a
/// free 4 × 4 m grid of 0.125 m cells, 2 × 2 particles per cell, quadratic B-splines;
/// `velocity(x)` gives the initial particle velocity.
fn block(
    model: ModelKind,
    corner: [f64; 2],
    width: f64,
    gravity: Vector<f64, 2>,
    dt: f64,
    steps: usize,
    velocity: impl Fn(Vector<f64, 2>) -> Vector<f64, 2>,
) -> (ImplicitConfig<2>, Particles<f64, 2>) {
    let h = 0.125;
    let shape = Shape::QuadraticBspline;
    let grid = Grid::new([0.0, 0.0], [32, 32], h, shape.ghost_cells());
    let dp = h / 2.0;
    let n = (width / dp).round() as usize;
    let mut particles = Particles::default();
    for i in 0..n {
        for j in 0..n {
            let x = Vector::<f64, 2>::new(
                corner[0] + (i as f64 + 0.5) * dp,
                corner[1] + (j as f64 + 0.5) * dp,
            );
            particles.push(x, velocity(x), 1.0, Vector::repeat(dp / 2.0), 0);
        }
    }
    let config = ImplicitConfig {
        grid,
        shape,
        boundary: Boundary::all(Wall::new(WallKind::Free)),
        materials: vec![Material::elastic(model, 100.0, 0.3, 1.0)],
        gravity,
        constraints: Vec::new(),
        point_loads: Vec::new(),
        load_steps: steps,
        newton: NewtonSettings::default(),
        dynamics: Some(dt),
        gravity_in_full: false,
        min_node_support: ImplicitConfig::<2>::DEFAULT_MIN_NODE_SUPPORT,
        balance: Vec::new(),
        pore_fluid: None,
    };
    (config, particles)
}

/// A free block falling from rest: Newmark integrates a constant acceleration exactly, so after
/// every step `v = g t`, `a = g`, `x − x₀ = ½ g t²` and the block stays unstrained, however
/// long the step (here 0.1 s, nine times the explicit limit; the block falls 1.8 m, across
/// 14 cells, and its lowest particles reach nodes whose support is too weak to take part).
/// The motion is a rigid translation, so Newton's first correction is exact and what remains
/// is round-off and the regularisation `ε = 1e-10` of the mass solves: 1e-8 relative on `x`
/// and `v`, 1e-6 on `a` (its solve takes the first one's error times 2/Δt). Before, the
/// start-of-step acceleration came from the particles (zero at rest), which halved the first
/// displacement, and a weakly supported node held at Δu = 0 strained the particles reaching it.
#[test]
fn free_fall_is_exact() {
    let g = Vector::<f64, 2>::new(0.0, -9.81);
    let (dt, steps) = (0.1, 6);
    let (config, mut particles) =
        block(ModelKind::NeoHookean, [1.0, 2.5], 0.5, g, dt, steps, |_| {
            Vector::zeros()
        });
    let x0 = particles.x.clone();
    let mut solver = ImplicitSolver::new(config, &particles).expect("valid set-up");
    while !solver.finished() {
        solver.step(&mut particles).expect("step converges");
        let t = solver.steps() as f64 * dt;
        for p in 0..particles.len() {
            let dx = particles.x[p] - x0[p];
            assert!(
                (dx - g * (0.5 * t * t)).norm() <= 1e-8 * (0.5 * 9.81 * t * t),
                "particle {p} at t = {t}: displacement {dx:?}"
            );
            assert!(
                (particles.v[p] - g * t).norm() <= 1e-8 * 9.81 * t,
                "particle {p} at t = {t}: velocity {:?}",
                particles.v[p]
            );
            assert!(
                (particles.a[p] - g).norm() <= 1e-6 * 9.81,
                "particle {p} at t = {t}: acceleration {:?}",
                particles.a[p]
            );
            assert!(
                particles.stress[p].norm() <= 1e-9,
                "particle {p} at t = {t}: stress {:?}",
                particles.stress[p]
            );
        }
    }
}

/// A linear-elastic block translating at 0.5 m/s while it vibrates in shear and stretch: the
/// stored energy is quadratic in the step's `Δu`, so the trapezoidal work is exact and
/// `K + U` must be conserved step by step although the block crosses 12 cells and its
/// particles change stencils and nodes all the time. 120 steps of 0.025 s (2.3 times the
/// explicit limit). The residual is linear, so Newton's first correction is exact; what remains
/// is the regularisation `ε diag M` (`ε = 1e-10`) of the mass solve, which shifts the
/// near-singular modes of `M` (nodes touched by one particle at the block's corners) by a
/// relative `ε/λ`. 1e-5 bounds that and is three orders below the percent-level loss of a
/// lumped-mass-weighted projection.
#[test]
fn linear_elastic_energy_is_conserved() {
    let (dt, steps) = (0.025, 120);
    let velocity = |x: Vector<f64, 2>| {
        let (s, r) = (x[0] - 1.5, x[1] - 1.5);
        Vector::<f64, 2>::new(0.5 + 0.2 * r + 0.1 * s, 0.3 * s * s - 0.1 * r)
    };
    let (config, mut particles) = block(
        ModelKind::LinearElastic,
        [1.0, 1.0],
        1.0,
        Vector::zeros(),
        dt,
        steps,
        velocity,
    );
    let materials = config.materials.clone();
    let total = |p: &Particles<f64, 2>| energy(p, &materials, &Vector::zeros()).total();
    let e0 = total(&particles);
    // Energy of the motion relative to the centre of mass: what the vibration carries.
    let vibration =
        e0 - 0.5 * particles.total_mass() * particles.centre_of_mass_velocity().norm_squared();
    let mut solver = ImplicitSolver::new(config, &particles).expect("valid set-up");
    let mut worst: f64 = 0.0;
    let mut stored: f64 = 0.0;
    while !solver.finished() {
        solver.step(&mut particles).expect("step converges");
        worst = worst.max((total(&particles) - e0).abs() / e0);
        stored = stored.max(energy(&particles, &materials, &Vector::zeros()).strain);
    }
    // The vibration exchanges energy with the strain (a check that the test tests something).
    assert!(
        stored > 0.1 * vibration,
        "stored energy only {stored:.3e} of {vibration:.3e}"
    );
    assert!(
        worst <= 1e-5,
        "max |E − E₀|/E₀ = {worst:.3e} over {steps} steps"
    );
}
