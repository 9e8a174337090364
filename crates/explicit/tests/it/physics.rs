//! Conservation laws and failure reports of the explicit step.

use loam_core::tensor::Vector;
use loam_core::*;
use loam_explicit::{Config, Solver, StepError};

fn block(
    transfer: Transfer,
    scheme: Scheme,
    gravity: [f64; 2],
    boundary: Boundary<2>,
) -> (Config<f64, 2>, Particles<f64, 2>) {
    let h = 0.1;
    let config = Config {
        grid: Grid::new([0.0, 0.0], [20, 20], h, 2),
        shape: Shape::QuadraticBspline,
        transfer,
        scheme,
        boundary,
        contact: Default::default(),
        gravity: Vector::<f64, 2>::from(gravity),
        materials: vec![Material::elastic(ModelKind::NeoHookean, 1.0e4, 0.3, 100.0)],
        time_step: TimeStep::Adaptive {
            cfl: 0.4,
            max_dt: 1e-3,
        },
    };
    let mut p = Particles::default();
    let dp = h / 2.0;
    for i in 0..16 {
        for j in 0..12 {
            let x = Vector::<f64, 2>::new(0.6 + (i as f64 + 0.5) * dp, 0.8 + (j as f64 + 0.5) * dp);
            // A spinning, stretching initial velocity so the body deforms.
            let v = Vector::<f64, 2>::new(0.3 - 0.5 * (x[1] - 1.1), 0.5 * (x[0] - 1.0) + 0.1);
            p.push(x, v, 100.0, Vector::<f64, 2>::repeat(dp / 2.0), 0);
        }
    }
    (config, p)
}

/// Without walls or gravity the grid exchanges momentum only internally: total linear momentum
/// is conserved to round-off for every transfer and scheme (P2G and G2P are partitions of unity).
#[test]
fn linear_momentum_is_conserved_without_external_forces() {
    for transfer in [
        Transfer::Pic,
        Transfer::Flip { alpha: 0.95 },
        Transfer::Apic,
        Transfer::Tpic,
        Transfer::Mls,
    ] {
        for scheme in [Scheme::Usl, Scheme::Musl] {
            let (config, mut p) = block(
                transfer,
                scheme,
                [0.0, 0.0],
                Boundary::all(Wall::new(WallKind::Free)),
            );
            let p0 = p.momentum();
            let mass0 = p.total_mass();
            let mut solver = Solver::new(config, &p).expect("valid");
            for _ in 0..200 {
                solver.step(&mut p, f64::INFINITY).expect("stable");
            }
            // ~200 steps × 2e2 particles of O(1) momentum: round-off ≲ 1e-12.
            assert!(
                (p.momentum() - p0).norm() < 1e-12 * p0.norm().max(1.0),
                "{transfer:?} {scheme:?}: {} vs {p0}",
                p.momentum()
            );
            assert_eq!(p.total_mass(), mass0);
        }
    }
}

/// A free body under gravity: the centre of mass accelerates at exactly g, whatever the internal
/// deformation (internal forces sum to zero).
#[test]
fn centre_of_mass_falls_at_g() {
    let g = [0.0, -9.81];
    let (config, mut p) = block(
        Transfer::Apic,
        Scheme::Musl,
        g,
        Boundary::all(Wall::new(WallKind::Free)),
    );
    let v0 = p.centre_of_mass_velocity();
    let mut solver = Solver::new(config, &p).expect("valid");
    solver.advance_to(&mut p, 0.05, |_, _| {}).expect("stable");
    let dv = p.centre_of_mass_velocity() - v0;
    assert!(
        (dv[0]).abs() < 1e-12 && (dv[1] - g[1] * 0.05).abs() < 1e-12,
        "Δv_cm = {dv}"
    );
}

/// MLS-MPM's force needs the constant moment matrix of a B-spline; with any other shape the
/// configuration is refused, naming the field.
#[test]
fn mls_with_a_shape_other_than_a_bspline_is_refused() {
    let (mut config, p) = block(
        Transfer::Mls,
        Scheme::Usl,
        [0.0, 0.0],
        Boundary::all(Wall::new(WallKind::Free)),
    );
    config.shape = Shape::Cpgimp;
    let err = Solver::new(config, &p).err().expect("refused");
    let msg = err.to_string();
    assert!(
        msg.starts_with("transfer:") && msg.contains("B-spline"),
        "{msg}"
    );
}

#[test]
fn a_particle_leaving_the_grid_stops_the_run_with_its_id() {
    let (config, mut p) = block(
        Transfer::Apic,
        Scheme::Musl,
        [0.0, 0.0],
        Boundary::all(Wall::new(WallKind::Free)),
    );
    // The whole body flies left at 40 m/s with free walls: it reaches the ghost layer
    // (x ≈ −0.05 m) after ≈ 0.02 s.
    p.v.iter_mut()
        .for_each(|v| *v = Vector::<f64, 2>::new(-40.0, 0.0));
    let mut solver = Solver::new(config, &p).expect("valid");
    let err = (0..500)
        .find_map(|_| solver.step(&mut p, f64::INFINITY).err())
        .expect("the run must stop");
    match &err {
        StepError::LeftGrid { ids, step, .. } => {
            // Particle 0 is in the leftmost column of the block.
            assert!(ids.contains(&0), "{err}");
            assert!(*step > 1, "{err}");
        }
        other => panic!("expected LeftGrid, got {other}"),
    }
    assert!(err.to_string().contains("left the grid"));
}

#[test]
fn a_fixed_step_above_the_stability_limit_is_refused() {
    let (mut config, p) = block(
        Transfer::Apic,
        Scheme::Musl,
        [0.0, 0.0],
        Boundary::all(Wall::new(WallKind::Free)),
    );
    // c = √(M/ρ) ≈ 11.6 m/s, h = 0.1 m: the limit is ≈ 8e-3 s.
    config.time_step = TimeStep::Fixed { dt: 0.05 };
    let mut p = p;
    let mut solver = Solver::new(config, &p).expect("valid");
    match solver.step(&mut p, f64::INFINITY) {
        Err(StepError::TimeStepTooLarge { step: 1, limit, .. }) => {
            assert!(limit < 0.01 && limit > 0.005)
        }
        other => panic!("expected TimeStepTooLarge, got {other:?}"),
    }
}

#[test]
fn non_finite_values_are_reported_with_the_field() {
    let (mut config, mut p) = block(
        Transfer::Apic,
        Scheme::Musl,
        [0.0, 0.0],
        Boundary::all(Wall::new(WallKind::Free)),
    );
    config
        .materials
        .push(Material::elastic(ModelKind::Hencky, 1.0e4, 0.3, 100.0));
    p.material[3] = 1;
    p.stress[3][(0, 0)] = f64::NAN;
    let mut solver = Solver::new(config, &p).expect("valid");
    let err = solver
        .step(&mut p, f64::INFINITY)
        .expect_err("NaN must stop the run");
    assert!(matches!(err, StepError::NonFinite { .. }), "{err}");
}

#[test]
fn particles_with_unknown_materials_are_rejected() {
    let (config, mut p) = block(
        Transfer::Apic,
        Scheme::Musl,
        [0.0, 0.0],
        Boundary::all(Wall::new(WallKind::Free)),
    );
    p.material[5] = 4;
    let err = Solver::new(config, &p).err().expect("must be rejected");
    assert!(err.to_string().contains("particle 5"), "{err}");
}

/// A slip floor under a resting block: after the block settles the floor carries its weight,
/// so the mean vertical stress at mid-height is ≈ −ρ g (H/2), within the 10 % a short, damped
/// settling run allows.
#[test]
fn slip_floor_supports_a_block_under_gravity() {
    let h = 0.05;
    let config = Config {
        grid: Grid::new([0.0, 0.0], [8, 12], h, 2),
        shape: Shape::QuadraticBspline,
        transfer: Transfer::Pic,
        scheme: Scheme::Musl,
        boundary: Boundary::all(Wall::new(WallKind::Slip)),
        contact: Default::default(),
        gravity: Vector::<f64, 2>::new(0.0, -10.0),
        materials: vec![Material::elastic(
            ModelKind::LinearElastic,
            1.0e6,
            0.0,
            1000.0,
        )],
        time_step: TimeStep::Adaptive {
            cfl: 0.4,
            max_dt: 1e-3,
        },
    };
    let mut p = Particles::default();
    let dp = h / 2.0;
    // Fills the full width (slip side walls) to height H = 0.4 m.
    for i in 0..16 {
        for j in 0..16 {
            let x = Vector::<f64, 2>::new((i as f64 + 0.5) * dp, (j as f64 + 0.5) * dp);
            p.push(
                x,
                Vector::zeros(),
                1000.0,
                Vector::<f64, 2>::repeat(dp / 2.0),
                0,
            );
        }
    }
    let mut solver = Solver::new(config, &p).expect("valid");
    solver.advance_to(&mut p, 0.5, |_, _| {}).expect("stable");
    let (mut s, mut n) = (0.0, 0);
    for k in 0..p.len() {
        if (p.x[k][1] - 0.2).abs() < 0.03 {
            s += p.stress[k][(1, 1)];
            n += 1;
        }
    }
    let mean = s / n as f64;
    let exact = -1000.0 * 10.0 * 0.2;
    assert!(
        (mean - exact).abs() < 0.1 * exact.abs(),
        "σ_yy(H/2) = {mean}, expected {exact}"
    );
}

/// Separable slip walls on every face.
fn unilateral_walls() -> Boundary<2> {
    Boundary::all(Wall {
        kind: WallKind::Slip,
        separable: true,
    })
}

/// A centre a tenth of a cell below a unilateral floor, moving down, is put back onto the face
/// with its downward velocity removed, and the run goes on (USL and MUSL).
#[test]
fn a_shallow_crossing_of_a_unilateral_wall_is_projected_onto_the_face() {
    for scheme in [Scheme::Usl, Scheme::Musl] {
        let (config, mut p) = block(Transfer::Apic, scheme, [0.0, -9.81], unilateral_walls());
        p.x[5] = Vector::<f64, 2>::new(1.0, -0.01);
        p.v[5] = Vector::<f64, 2>::new(0.3, -0.5);
        let mut solver = Solver::new(config, &p).unwrap();
        solver
            .step(&mut p, f64::INFINITY)
            .expect("projected, not stopped");
        assert_eq!(p.x[5][1], 0.0, "{scheme:?}: y = {}", p.x[5][1]);
        assert!(p.v[5][1] >= 0.0, "{scheme:?}: v_y = {}", p.v[5][1]);
        // The tangential motion is untouched by the projection: it still moves along +x.
        assert!(p.x[5][0] > 1.0, "{scheme:?}: x = {}", p.x[5][0]);
    }
}

/// Steps the block of [`block`] once with particle 5 moved to `x5`, and checks that the run
/// stops because that particle (and only it) crossed `wall`.
fn assert_escapes(scheme: Scheme, boundary: Boundary<2>, x5: [f64; 2], wall: &str) {
    let (config, mut p) = block(Transfer::Apic, scheme, [0.0, -9.81], boundary);
    p.x[5] = Vector::<f64, 2>::from(x5);
    let mut solver = Solver::new(config, &p).unwrap();
    match solver.step(&mut p, f64::INFINITY) {
        Err(StepError::Escaped { what, ids, .. }) => {
            assert_eq!(ids, vec![5]);
            assert!(what.contains(wall), "{what}");
        }
        other => panic!("expected Escaped, got {other:?}"),
    }
}

/// A centre more than half a cell beyond a unilateral wall has escaped: the run stops and
/// names it. (0.6 cells below the floor, inside the ghost layer: the stencil is still on the
/// grid.)
#[test]
fn a_deep_crossing_of_a_unilateral_wall_stops_the_run_with_its_id() {
    assert_escapes(Scheme::Musl, unilateral_walls(), [1.0, -0.06], "y_min");
}

/// Particle 5 sits just outside a bilateral x wall (inside the ghost layer, so the grid still
/// covers its stencil): the containment check must name it.
#[test]
fn a_particle_beyond_a_wall_stops_the_run_with_its_id() {
    assert_escapes(
        Scheme::Usl,
        Boundary::all(Wall::new(WallKind::Slip)),
        [-0.01, 1.0],
        "x_min",
    );
}
