//! Observations and inverse problems against forward-mode duals.
//!
//! Synthetic observations (tracked positions, velocity monitors and the final deposit
//! depth at stations) are recorded from a truth run; the loss at other values of the unknowns must have the adjoint gradient of
//! [`Problem::gradient`] equal to the dual derivative of [`Problem::dual_derivative`] (both
//! exact derivatives of the same discrete map: 1e-10 relative, the round-off of summing the
//! nodal contributions in another order, as in `adjoint.rs`), and the dual derivative must
//! equal a central difference (1e-5 relative: steps of 10⁻⁴ |θ| taking the same branches,
//! truncation O(δ²) ≈ 1e-8 relative, round-off of a loss of order 1e-4 about 1e-12 / δ).

use loam_core::Particles;
use loam_core::tensor::Vector;
use loam_explicit::Config;
use loam_inverse::{
    Checkpoints, Control, DepositProfile, MaterialField, MonitorBox, Observations, Param, Problem,
    Station, TrackedPositions, VelocityField, VelocityMonitors,
};
use std::collections::BTreeSet;

use crate::common::FLUID_2D;

/// The fluid scene's solver inputs.
fn scene() -> (Config<f64, 2>, Particles<f64, 2>) {
    crate::common::scene(FLUID_2D)
}

const STEPS: usize = 50;

/// Two boxes on the floor in the path of the flow (the first with edges smoothed over one
/// cell, so particles crossing them carry position derivatives; the second sharp),
/// observed every 10 steps with every 9th particle, and the final depth at three stations
/// (under the column, at its toe and ahead of it).
fn truth_observations(config: &Config<f64, 2>, particles: &Particles<f64, 2>) -> Observations<2> {
    let boxes = vec![
        MonitorBox {
            lo: Vector::from([0.04, 0.0]),
            hi: Vector::from([0.1, 0.04]),
            edge: 0.02,
        },
        MonitorBox {
            lo: Vector::from([0.1, 0.0]),
            hi: Vector::from([0.2, 0.06]),
            edge: 0.0,
        },
    ];
    let observed: BTreeSet<usize> = (10..=STEPS).step_by(10).collect();
    let ids: Vec<usize> = (0..particles.len()).step_by(9).collect();
    let stations = [0.03, 0.08, 0.125].map(|x| Station {
        at: Vector::from([x, 0.0]),
        width: 0.02,
    });
    let sensors = Observations {
        tracked: TrackedPositions {
            weight: 1.0,
            ..Default::default()
        },
        monitors: VelocityMonitors {
            boxes,
            weight: 0.5,
            ..Default::default()
        },
        deposit: DepositProfile {
            stations: stations.to_vec(),
            up: 1,
            weight: 10.0,
            ..Default::default()
        },
    };
    Observations::record(config, particles, STEPS, &observed, &ids, sensors).expect("truth run")
}

fn controls() -> Vec<Control> {
    vec![
        Control::Param(Param::Friction(0)),
        Control::Param(Param::Friction(1)),
        Control::Param(Param::Material(0, MaterialField::Viscosity)),
        Control::Param(Param::Material(0, MaterialField::Density)),
        Control::InitialVelocity {
            material: None,
            direction: vec![1.0, 0.0],
        },
        Control::InitialVelocity {
            material: Some(0),
            direction: vec![0.0, 1.0],
        },
    ]
}

/// Checks the unknowns `indices` of `theta`.
fn check(
    problem: &Problem<2, Observations<2>>,
    theta: &[f64],
    indices: &[usize],
    difference: bool,
) {
    let (loss, grad) = problem.gradient(theta).expect("gradient");
    assert_eq!(grad.len(), problem.len());
    let plain = problem.loss(theta).expect("loss");
    assert!((loss - plain).abs() <= 1e-12 * plain, "{loss} vs {plain}");
    for &k in indices {
        let dual = problem.dual_derivative(theta, k).expect("dual");
        println!("θ[{k}]: adjoint {:.12e}, dual {dual:.12e}", grad[k]);
        assert!(
            (grad[k] - dual).abs() <= 1e-10 * dual.abs().max(1e-12 * loss),
            "θ[{k}]: adjoint {:e} vs dual {dual:e}",
            grad[k]
        );
        if difference {
            let delta = 1e-4 * theta[k].abs().max(1e-2);
            let at = |d: f64| {
                let mut t = theta.to_vec();
                t[k] += d;
                problem.loss(&t).expect("loss")
            };
            let fd = (at(delta) - at(-delta)) / (2.0 * delta);
            println!("  central difference {fd:.12e}");
            assert!(
                (fd - dual).abs() <= 1e-5 * dual.abs().max(1e-8 * loss),
                "θ[{k}]: central difference {fd:e} vs dual {dual:e}"
            );
        }
    }
}

#[test]
fn tracked_monitor_and_deposit_losses_have_exact_adjoints() {
    let (config, particles) = scene();
    let objective = truth_observations(&config, &particles);
    assert!(!objective.monitors.targets.is_empty() && !objective.tracked.targets.is_empty());
    // The deposit is observed once, after the last step, at every station, and the flow
    // has reached the stations (a depth of zero would test nothing).
    assert_eq!(
        objective.deposit.targets.keys().collect::<Vec<_>>(),
        [&STEPS]
    );
    assert!(
        objective.deposit.targets[&STEPS]
            .iter()
            .all(|&(_, h)| h > 1e-3)
    );
    let problem = Problem {
        config,
        initial: particles,
        steps: STEPS,
        controls: controls(),
        objective,
        checkpoints: Checkpoints::Least,
    };
    let truth = problem.values().expect("values");
    assert_eq!(truth, vec![0.3, 0.1, 0.05, 1000.0, 0.3, 0.0]);
    // At the truth the synthetic observations are matched exactly.
    assert_eq!(problem.loss(&truth).expect("loss"), 0.0);
    let guess = [0.5, 0.2, 0.08, 1050.0, 0.5, -0.1];
    check(&problem, &guess, &[0, 1, 2, 3, 4, 5], false);
}

#[test]
fn monitor_loss_alone_matches_the_dual_run_and_differences() {
    let (config, particles) = scene();
    let all = truth_observations(&config, &particles);
    let objective = Observations {
        monitors: VelocityMonitors {
            weight: 2.0,
            ..all.monitors
        },
        ..Default::default()
    };
    let problem = Problem {
        config,
        initial: particles,
        steps: STEPS,
        controls: vec![
            Control::Param(Param::Material(0, MaterialField::Viscosity)),
            Control::InitialVelocity {
                material: None,
                direction: vec![0.6, 0.8],
            },
        ],
        objective,
        checkpoints: Checkpoints::Segment(7),
    };
    check(&problem, &[0.07, 0.45], &[0, 1], true);
}

#[test]
fn deposit_loss_alone_matches_the_dual_run_and_differences() {
    // The depth is a smooth (C¹ B-spline) function of the positions and `det F`, so central
    // differences of the loss converge like those of the other observations.
    let (config, particles) = scene();
    let all = truth_observations(&config, &particles);
    let objective = Observations {
        deposit: all.deposit,
        ..Default::default()
    };
    let problem = Problem {
        config,
        initial: particles,
        steps: STEPS,
        controls: vec![
            Control::Param(Param::Friction(1)),
            Control::InitialVelocity {
                material: None,
                direction: vec![1.0, 0.0],
            },
        ],
        objective,
        checkpoints: Checkpoints::Segment(9),
    };
    check(&problem, &[0.2, 0.5], &[0, 1], true);
}

#[test]
fn velocity_field_weights_have_exact_adjoints() {
    // An MLP velocity field (2 → 30 → 30 → 30 → 1 along x) next to a scalar parameter: the
    // adjoint chained through the network's backpropagation equals the dual run with one
    // weight seeded, for weights of the first, a middle and the last layer and a bias.
    let (config, particles) = scene();
    let objective = truth_observations(&config, &particles);
    let field = VelocityField::new(&particles, Some(0), vec![1.0, 0.0], &[30, 30, 30], 5)
        .expect("the field's particles");
    assert_eq!(field.mlp.len(), 1981);
    let problem = Problem {
        config,
        initial: particles,
        steps: STEPS,
        controls: vec![
            Control::Param(Param::Material(0, MaterialField::Viscosity)),
            Control::VelocityField(field),
        ],
        objective,
        checkpoints: Checkpoints::Least,
    };
    let mut theta = problem.values().expect("values");
    assert_eq!(theta.len(), 1982);
    // Non-zero biases, so that their derivatives are not those of the Glorot start alone.
    for (i, t) in theta.iter_mut().enumerate().skip(1) {
        *t += 0.01 * ((i % 7) as f64 - 3.0);
    }
    // θ[0] viscosity; θ[1 + i] weight i: layer 1 weight 3, layer 2 weight 100, layer 3
    // bias 5 (offset 90 + 930 + 900), the output weight 7 and bias.
    check(&problem, &theta, &[0, 4, 191, 1926, 1958, 1981], false);
}
