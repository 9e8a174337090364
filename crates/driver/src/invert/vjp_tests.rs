//! The vector–Jacobian product of a study's observations ([`Study::vjp`]) on the explicit
//! path (the friction dam-break), the implicit coupled one (the consolidating clay layer) and
//! element tests (Modified Cam-Clay triaxial tests): seeded with the loss's own cotangent it
//! is the gradient; seeded with any cotangent it matches forward-mode duals and central
//! differences of `ȳ · y(θ)`.

use super::*;
use crate::invert::file::Inversion;
use crate::invert::model::Model;
use crate::preflight::{MAX_INVERSION_STEPS, StepLimit};
use std::path::PathBuf;

fn open(name: &str) -> Study {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/inverse")
        .join(name);
    let limits = Limits {
        memory: None,
        steps: StepLimit::new(None, MAX_INVERSION_STEPS),
    };
    Study::open(&path, None, limits).expect("the example is valid")
}

/// The 2D scene's model of a study.
fn model(study: &Study) -> &Model<2> {
    match &study.0 {
        SetUp::Two(Inversion { problem, .. }) => problem,
        _ => panic!("a 2D scene's inversion"),
    }
}

/// A cotangent with entries of both signs and different sizes, `ȳᵢ = sin(1 + i)`, scaled by
/// `scale` per quantity.
fn cotangent(scale: &[f64]) -> Vec<f64> {
    (scale.iter().enumerate())
        .map(|(i, s)| (1.0 + i as f64).sin() * s)
        .collect()
}

/// `L = Σ c (y − d)²` from the observed quantities, and the cotangent `ȳ = 2c (y − d)`.
fn loss_and_cotangent(study: &Study, theta: &[f64]) -> (f64, Vec<f64>) {
    let y = study.observe(theta).unwrap();
    let obs = study.observations();
    assert_eq!(y.len(), obs.len());
    let loss = (y.iter().zip(&obs))
        .map(|(y, (_, d, c))| c * (y - d) * (y - d))
        .sum();
    let bar = (y.iter().zip(&obs))
        .map(|(y, (_, d, c))| 2.0 * c * (y - d))
        .collect();
    (loss, bar)
}

/// Relative difference of two vectors, against the larger norm.
fn relative(a: &[f64], b: &[f64]) -> f64 {
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let d: Vec<f64> = a.iter().zip(b).map(|(a, b)| a - b).collect();
    norm(&d) / norm(a).max(norm(b))
}

/// With the cotangent of the file's own loss, `ȳ = ∂L/∂y = 2c (y − d)`, the VJP is the
/// gradient, and the loss rebuilt from the observed quantities, their data and weights is the
/// study's. Both differ from the gradient's only in how the seed is rounded (`2c (y − d)`
/// against `(y − d)/σ²` on the implicit path), so 1e-12 relative.
#[test]
fn with_the_loss_cotangent_the_vjp_is_the_gradient() {
    for name in ["friction.toml", "consolidation.toml", "triaxial_mcc.toml"] {
        let study = open(name);
        let theta = study.initial().to_vec();
        let (loss, g) = study.gradient(&theta).unwrap();
        let (rebuilt, bar) = loss_and_cotangent(&study, &theta);
        assert!(
            (rebuilt - loss).abs() <= 1e-12 * loss,
            "{name}: L from y {rebuilt} against {loss}"
        );
        let vjp = study.vjp(&theta, &bar).unwrap();
        let rel = relative(&vjp, &g);
        assert!(
            rel < 1e-12,
            "{name}: vjp {vjp:?} gradient {g:?} ({rel:.1e})"
        );
    }
}

/// Against forward-mode duals, `Σᵢ ȳᵢ ∂yᵢ/∂θ_k` from one dual run per unknown: the adjoint
/// is the exact transpose of the same discrete steps, so they agree to round-off (1e-10).
#[test]
fn the_vjp_matches_forward_mode_duals() {
    let study = open("friction.toml");
    let theta = study.initial().to_vec();
    let Model::Explicit(problem) = model(&study) else {
        panic!("the dam-break is explicit")
    };
    let y = study.observe(&theta).unwrap();
    let bar = cotangent(&vec![1.0; y.len()]);
    let vjp = study.vjp(&theta, &bar).unwrap();
    let dual: Vec<f64> = (0..theta.len())
        .map(|k| {
            let t = problem.observe_tangent(&theta, k).unwrap();
            t.iter().zip(&bar).map(|(t, b)| t * b).sum()
        })
        .collect();
    let rel = relative(&vjp, &dual);
    assert!(
        rel < 1e-10,
        "explicit: vjp {vjp:?} dual {dual:?} ({rel:.1e})"
    );

    let study = open("consolidation.toml");
    let theta = study.initial().to_vec();
    let Model::Implicit { problem, .. } = model(&study) else {
        panic!("the consolidation is implicit")
    };
    // Settlements (m) and pore pressures (Pa) scaled alike in the cotangent.
    let scale: Vec<f64> = (study.observations().iter())
        .map(|(l, _, _)| {
            if l.contains("pore pressure") {
                1e-4
            } else {
                1.0
            }
        })
        .collect();
    let bar = cotangent(&scale);
    let vjp = study.vjp(&theta, &bar).unwrap();
    let dual: Vec<f64> = (problem.sensitivities(&theta).unwrap().iter())
        .map(|column| column.iter().zip(&bar).map(|(t, b)| t * b).sum())
        .collect();
    let rel = relative(&vjp, &dual);
    assert!(
        rel < 1e-10,
        "implicit: vjp {vjp:?} dual {dual:?} ({rel:.1e})"
    );
}

/// Against central differences of `ȳ · y(θ)` with a step of 1e-6 of each unknown: the
/// difference's truncation (h² relative) and round-off (ε/h ≈ 1e-10 relative) leave
/// agreement well inside 1e-5 where `y` is smooth (no particle changing between sticking
/// and sliding within ±h on the floor; the element tests' paths are smooth).
#[test]
fn the_vjp_matches_central_differences() {
    for name in ["friction.toml", "triaxial_mcc.toml"] {
        let study = open(name);
        let theta = study.initial().to_vec();
        let n = study.observations().len();
        let bar = cotangent(&vec![1.0; n]);
        let vjp = study.vjp(&theta, &bar).unwrap();
        for k in 0..theta.len() {
            let h = 1e-6 * theta[k].abs().max(1e-3);
            let at = |d: f64| {
                let mut t = theta.clone();
                t[k] += d;
                let y = study.observe(&t).unwrap();
                y.iter().zip(&bar).map(|(y, b)| y * b).sum::<f64>()
            };
            let central = (at(h) - at(-h)) / (2.0 * h);
            let rel = (vjp[k] - central).abs() / central.abs().max(1e-300);
            assert!(
                rel < 1e-5,
                "{name} θ[{k}]: vjp {} central {central}",
                vjp[k]
            );
        }
    }
}

#[test]
fn a_cotangent_of_the_wrong_length_or_not_finite_is_refused_by_name() {
    let study = open("friction.toml");
    let theta = study.initial().to_vec();
    let n = study.observations().len();
    let e = study.vjp(&theta, &vec![1.0; n + 1]).unwrap_err();
    assert_eq!(e.outcome, Outcome::BadInput);
    assert!(
        e.message
            .contains(&format!("cotangent has {} value(s); expected {n}", n + 1)),
        "{e}"
    );
    let mut bar = vec![0.0; n];
    bar[2] = f64::INFINITY;
    let e = study.vjp(&theta, &bar).unwrap_err();
    assert!(e.message.contains("cotangent[2] = inf"), "{e}");
    let e = study.observe(&theta[..1]).unwrap_err();
    assert!(e.message.contains("theta has 1 value(s)"), "{e}");
}

/// The labels say what each quantity is and when.
#[test]
fn the_observed_quantities_are_labelled() {
    let study = open("friction.toml");
    let obs = study.observations();
    assert!(
        obs.iter()
            .all(|(l, _, c)| l.starts_with("step ") && *c > 0.0)
    );
    assert!(
        obs.iter().any(|(l, _, _)| l.contains("x of particle")),
        "{obs:?}"
    );
    let study = open("triaxial_mcc.toml");
    let obs = study.observations();
    assert!(obs[0].0.starts_with("tests[0]: "), "{:?}", obs[0]);
}
