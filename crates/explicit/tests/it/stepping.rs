//! Time stepping towards a target time: a fixed step is never shortened by `advance_to`,
//! `advance_exactly_to` lands on the target, an adaptive run lands on it too.

use loam_core::tensor::Vector;
use loam_core::*;
use loam_explicit::{Config, Solver, StepInfo};

/// A small elastic block falling freely (no walls) under gravity, with the given step
/// control. The block's wave speed is √(M/ρ) ≈ 11.6 m/s with M = E(1−ν)/((1+ν)(1−2ν)), so
/// h/c ≈ 8.6e-3 s: far above the steps used here.
fn falling_block(time_step: TimeStep) -> (Solver<f64, 2>, Particles<f64, 2>) {
    let h = 0.1;
    let config = Config {
        grid: Grid::new([0.0, 0.0], [10, 10], h, 2),
        shape: Shape::QuadraticBspline,
        transfer: Transfer::Apic,
        scheme: Scheme::Musl,
        boundary: Boundary::all(Wall::new(WallKind::Free)),
        contact: Default::default(),
        gravity: Vector::<f64, 2>::new(0.0, -9.81),
        materials: vec![Material::elastic(ModelKind::NeoHookean, 1.0e5, 0.3, 1000.0)],
        time_step,
    };
    let mut p = Particles::default();
    let dp = h / 2.0;
    for i in 0..4 {
        for j in 0..4 {
            let x = Vector::<f64, 2>::new(0.4 + (i as f64 + 0.5) * dp, 0.4 + (j as f64 + 0.5) * dp);
            p.push(x, Vector::zeros(), 1000.0, Vector::repeat(dp / 2.0), 0);
        }
    }
    let solver = Solver::new(config, &p).expect("valid set-up");
    (solver, p)
}

#[test]
fn a_fixed_step_is_never_shortened_and_stops_at_the_first_step_past_the_target() {
    let dt = 1e-4;
    let (mut solver, mut p) = falling_block(TimeStep::Fixed { dt });
    let mut taken: Vec<StepInfo> = Vec::new();
    // 12.5 steps to 1.25e-3 s: the 13th step is the first to reach or pass it.
    solver
        .advance_to(&mut p, 1.25e-3, |info, _| taken.push(*info))
        .expect("stable");
    assert_eq!(taken.len(), 13);
    assert!(taken.iter().all(|i| i.dt == dt), "a step was shortened");
    // 13 · 1e-4 summed in f64: within round-off of 1.3e-3.
    assert!((solver.time() - 1.3e-3).abs() < 1e-15);
    // 1.3e-3 is reached already (up to the round-off of the sum): no step.
    solver
        .advance_to(&mut p, 1.3e-3, |info, _| taken.push(*info))
        .expect("stable");
    assert_eq!(taken.len(), 13);
    assert_eq!(solver.next_step_cap(1.3e-3), None);
    assert_eq!(solver.next_step_cap(1.31e-3), Some(f64::INFINITY));
    // Landing exactly: one step of half the size.
    solver
        .advance_exactly_to(&mut p, 1.35e-3, |info, _| taken.push(*info))
        .expect("stable");
    assert_eq!(taken.len(), 14);
    assert!((taken[13].dt - 0.5e-4).abs() < 1e-15);
    // The last step is 1.35e-3 − t, so the sum ends on 1.35e-3 to within an ulp.
    assert!((solver.time() - 1.35e-3).abs() <= 1e-15 * 1.35e-3);
}

#[test]
fn an_adaptive_step_lands_on_the_target() {
    let (mut solver, mut p) = falling_block(TimeStep::Adaptive {
        cfl: 0.5,
        max_dt: 1e-4,
    });
    let mut dts = Vec::new();
    solver
        .advance_to(&mut p, 1.25e-3, |info, _| dts.push(info.dt))
        .expect("stable");
    // max_dt caps every step but the last, which is shortened to end on 1.25e-3 s.
    assert_eq!(dts.len(), 13);
    assert!(dts[..12].iter().all(|&dt| dt == 1e-4));
    assert!((dts[12] - 0.5e-4).abs() < 1e-15);
    assert!((solver.time() - 1.25e-3).abs() <= 1e-12 * 1.25e-3);
    // The centre of mass falls freely: Δv = g t exactly, whatever the step sizes.
    let v = p.centre_of_mass_velocity()[1];
    assert!((v + 9.81 * solver.time()).abs() < 1e-12, "v_cm = {v}");
}
