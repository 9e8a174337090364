//! Rigid obstacles through the public solver API: blocks hitting static and moving obstacles
//! without entering them, momentum and energy of frictionless and frictional impacts.
//!
//! The friction walls and the large contact set-ups are verification cases of
//! `loam-verification` (run at reduced size by its test suite, at full size by
//! `loam verify`): `incline-friction` (a block on an incline against
//! `g (sin α − μ cos α)`, sticking for `μ > tan α`, `μ = 0` as the slip wall) and
//! `dambreak-obstacles-3d` (a 3D dam break against two cylinders). The nodal Coulomb law
//! itself is unit-tested in `loam_core::contact`.

use loam_core::tensor::Vector;
use loam_core::*;
use loam_explicit::{Config, Solver};

/// A 2D elastic block (0.1 m square, NeoHookean, E = 1 MPa) flying at `v0` towards a box
/// obstacle, no gravity, free walls; returns the particles before and after `t_end` and the
/// smallest signed distance of any particle to the obstacle over the run.
fn impact(
    obstacle: Obstacle<f64, 2>,
    v0: [f64; 2],
    t_end: f64,
    transfer: Transfer,
    scheme: Scheme,
) -> (Particles<f64, 2>, Particles<f64, 2>, Solver<f64, 2>, f64) {
    let shape = Shape::QuadraticBspline;
    let h = 0.02;
    let mut contact = Contact::new(shape);
    contact.obstacles.push(obstacle.clone());
    let config = Config {
        grid: Grid::new([0.0, 0.0], [50, 30], h, shape.ghost_cells()),
        shape,
        transfer,
        scheme,
        boundary: Boundary::all(Wall::new(WallKind::Free)),
        contact,
        gravity: Vector::zeros(),
        materials: vec![Material::elastic(ModelKind::NeoHookean, 1.0e6, 0.3, 1000.0)],
        time_step: TimeStep::Adaptive {
            cfl: 0.4,
            max_dt: 1e-3,
        },
    };
    let mut p = Particles::default();
    let dp = h / 2.0;
    for i in 0..10 {
        for j in 0..10 {
            let x =
                Vector::<f64, 2>::new(0.25 + (i as f64 + 0.5) * dp, 0.25 + (j as f64 + 0.5) * dp);
            p.push(x, Vector::from(v0), 1000.0, Vector::repeat(dp / 2.0), 0);
        }
    }
    let before = p.clone();
    let mut solver = Solver::new(config, &p).expect("valid");
    let mut closest = f64::INFINITY;
    solver
        .advance_to(&mut p, t_end, |info, p| {
            for x in &p.x {
                let d = obstacle.distance(&[x[0], x[1]], info.time).0;
                closest = closest.min(d);
            }
        })
        .expect("no particle enters the obstacle");
    (before, p, solver, closest)
}

/// A tall static box in the block's way: `[0.6, 0.7] × [0.05, 0.55]`.
fn wall_box(mu: f64) -> Obstacle<f64, 2> {
    Obstacle::fixed(
        ObstacleShape::Box {
            lo: [0.6, 0.05],
            hi: [0.7, 0.55],
        },
        mu,
    )
}

/// A block thrown at 2 m/s at a static box is stopped by it and bounces back, never entering
/// it (the run would stop with `StepError::Escaped`; no particle is ever strictly inside). The
/// contact layer of the obstacle (`φ < 1.5 h ‖n‖₁` at the nodes) stops the block's front about
/// 2h before the face: the block reverses at ≈ 0.038 m.
#[test]
fn a_block_stops_at_a_static_box_without_entering_it() {
    for (transfer, scheme) in [(Transfer::Apic, Scheme::Musl), (Transfer::Pic, Scheme::Usl)] {
        let (before, after, _, closest) = impact(wall_box(0.0), [2.0, 0.0], 0.3, transfer, scheme);
        let (p0, p1) = (before.momentum(), after.momentum());
        println!(
            "{transfer:?} {scheme:?}: closest approach {closest:.4} m, p_x {} → {}",
            p0[0], p1[0]
        );
        assert!((-1e-9..0.05).contains(&closest), "{closest}");
        assert!(p1[0] < 0.0, "not stopped: {p1} from {p0}");
        let right = after.x.iter().fold(0.0f64, |m, x| m.max(x[0]));
        assert!(right <= 0.6, "{right}");
    }
}

/// Frictionless impact on a flat face: only the normal (x) momentum changes, the tangential
/// (y) momentum is conserved to round-off, and the energy does not grow (a rigid obstacle does
/// no work). With friction the tangential impulse obeys the Coulomb bound
/// `|Δp_y| ≤ μ |Δp_x|` and is not zero.
///
/// MUSL enforces in its second projection exactly the constraints that acted in the first;
/// re-testing the approach there made PIC MUSL rebound with 25 J of the 20 J it came with
/// (`docs/architecture.md`).
#[test]
fn oblique_impacts_conserve_tangential_momentum_without_friction() {
    let v0 = [2.0, 0.5];
    for (transfer, scheme) in [
        (Transfer::Apic, Scheme::Musl),
        (Transfer::Pic, Scheme::Musl),
        (Transfer::Apic, Scheme::Usl),
        (Transfer::Pic, Scheme::Usl),
    ] {
        let (before, after, solver, _) = impact(wall_box(0.0), v0, 0.2, transfer, scheme);
        let (p0, p1) = (before.momentum(), after.momentum());
        let (e0, e1) = (solver.energy(&before), solver.energy(&after));
        println!(
            "frictionless, {transfer:?} {scheme:?}: p ({:.4}, {:.4}) → ({:.4}, {:.4}), energy \
             {:.4} → {:.4} J",
            p0[0],
            p0[1],
            p1[0],
            p1[1],
            e0.total(),
            e1.total()
        );
        assert!(p1[0] < 0.0, "the impact happened: {p1}");
        assert!((p1[1] - p0[1]).abs() < 1e-10 * p0.norm(), "{p0} → {p1}");
        assert!(
            e1.total() <= e0.total(),
            "{transfer:?} {scheme:?}: {e0:?} → {e1:?}"
        );
    }
    let mu = 0.3;
    let (before, after, _, _) = impact(wall_box(mu), v0, 0.2, Transfer::Apic, Scheme::Musl);
    let (p0, p1) = (before.momentum(), after.momentum());
    let (dx, dy) = ((p1[0] - p0[0]).abs(), (p1[1] - p0[1]).abs());
    println!(
        "μ = {mu}: |Δp_x| = {dx:.4}, |Δp_y| = {dy:.4} (bound {:.4})",
        mu * dx
    );
    assert!(dy > 0.1 * mu * dx, "friction acted: {dy} vs {dx}");
    assert!(dy <= mu * dx * (1.0 + 1e-9), "{dy} > μ {dx}");
}

/// A box moving at 1 m/s into a resting block pushes it ahead without the block entering it:
/// the block ends up at least as fast as the box along x.
#[test]
fn a_moving_box_pushes_a_block() {
    let plate = Obstacle {
        shape: ObstacleShape::Box {
            lo: [0.05, 0.1],
            hi: [0.15, 0.5],
        },
        velocity: Vector::from([1.0, 0.0]),
        mu: 0.0,
    };
    // The block spans x ∈ [0.25, 0.35]: the plate (right face at 0.15 m) reaches it at 0.1 s.
    let (_, after, _, closest) = impact(plate, [0.0, 0.0], 0.3, Transfer::Apic, Scheme::Musl);
    let v = after.centre_of_mass_velocity();
    println!(
        "closest {closest:.2e}, block v_cm = ({:.4}, {:.4})",
        v[0], v[1]
    );
    assert!(closest > -1e-9, "{closest}");
    assert!(after.centre_of_mass_velocity()[0] > 0.95, "{after:?}");
    let left = after.x.iter().fold(f64::INFINITY, |m, x| m.min(x[0]));
    assert!(left >= 0.15 + 0.3 - 1e-9, "{left}");
}
