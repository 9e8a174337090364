//! Back-analyses through the implicit path with synthetic data from a truth run, at reduced
//! size: the cantilever's stiffness from tip displacements and from the displacements of all
//! particles, the footing's strength and stiffness from its load–settlement curve, and how
//! far the "last step only" gradient is from the exact one.

use loam_core::Particles;
use loam_implicit::ImplicitConfig;
use loam_inverse::implicit::adjoint::{reverse, reverse_last_substep};
use loam_inverse::implicit::{
    ImplicitObservations, ImplicitParam, ImplicitProblem, Observation, Quantity, run_recorded,
};
use loam_inverse::optimise::norm;
use loam_inverse::{Evaluation, Lbfgs, MaterialField, Optimiser};
use loam_scene::Scene;

fn scene(toml: &str, load_steps: usize) -> (ImplicitConfig<2>, Particles<f64, 2>) {
    let built = Scene::from_toml_str(toml)
        .and_then(|s| s.build::<2>())
        .unwrap_or_else(|e| panic!("{e}"));
    let mut config = built.implicit_config().expect("implicit");
    config.load_steps = load_steps;
    (config, built.particles)
}

/// The observations `quantities` (load step, what) with the values of the run of `config`
/// from `initial` and standard deviation `sigma`.
fn synthetic(
    config: &ImplicitConfig<2>,
    initial: &Particles<f64, 2>,
    quantities: &[(usize, Quantity)],
    sigma: f64,
) -> ImplicitObservations {
    let run = run_recorded(config, initial, None).expect("truth run");
    let items = quantities
        .iter()
        .map(|&(step, quantity)| Observation::of_run(step, quantity, sigma, &run))
        .collect();
    ImplicitObservations { items }
}

/// L-BFGS on the scaled unknowns `z = θ / scale`, kept in `[0.5, 2]` by projection, from
/// `start` until the scaled gradient falls below `1e-10` of its first value or the line
/// search finds no decrease; returns `θ` and the iterations taken. A trial point whose
/// forward run stops (a beam too soft to carry its load within the allowed step cuts) has an
/// infinite loss (`trial_gradient`), so the line search shortens the step.
fn invert(problem: &ImplicitProblem<2>, start: &[f64], scale: &[f64]) -> (Vec<f64>, usize) {
    let mut evaluate = |z: &[f64]| -> Result<Evaluation, loam_inverse::AdjointError> {
        let theta: Vec<f64> = z.iter().zip(scale).map(|(z, s)| z * s).collect();
        let (loss, g) = problem.trial_gradient(&theta)?;
        Ok(Evaluation {
            x: z.to_vec(),
            loss,
            gradient: g.iter().zip(scale).map(|(g, s)| g * s).collect(),
            curvature: None,
        })
    };
    let project = |z: &mut [f64]| z.iter_mut().for_each(|v| *v = v.clamp(0.5, 2.0));
    let z0: Vec<f64> = start.iter().zip(scale).map(|(t, s)| t / s).collect();
    let mut at = evaluate(&z0).expect("first evaluation");
    let g0 = norm(&at.gradient);
    let mut optimiser = Optimiser::Lbfgs(Lbfgs::new(10, 0.1));
    let mut iterations = 0;
    while iterations < 60 && norm(&at.gradient) > 1e-10 * g0 {
        match optimiser
            .iterate(&at, &mut evaluate, &project)
            .expect("evaluation")
        {
            Some(next) => at = next,
            None => break,
        }
        iterations += 1;
    }
    let theta = at.x.iter().zip(scale).map(|(z, s)| z * s).collect();
    (theta, iterations)
}

/// The relative error of each recovered value.
fn errors(found: &[f64], truth: &[f64]) -> Vec<f64> {
    found
        .iter()
        .zip(truth)
        .map(|(f, t)| (f / t - 1.0).abs())
        .collect()
}

const CANTILEVER: &str = include_str!("../../../../verification/scenes/implicit_cantilever.toml");
const FOOTING: &str = include_str!("../../../../verification/scenes/implicit_footing.toml");

/// E of the cantilever from the tip deflection after each of 10 load steps (ν known), from
/// a start 50 % off. The data are noise-free, so the minimum is the truth and the tolerance
/// (0.1 %) only bounds how far L-BFGS stops short of it.
#[test]
fn cantilever_young_from_tip_deflection() {
    let (config, initial) = scene(CANTILEVER, 10);
    let tip = config.point_loads[0].particle;
    let quantities = Quantity::Displacement {
        particle: tip,
        component: 1,
    }
    .after_each(1..=10);
    let observations = synthetic(&config, &initial, &quantities, 1e-3);
    let problem = ImplicitProblem {
        config,
        initial,
        params: vec![ImplicitParam::Material(0, MaterialField::Young)],
        observations,
    };
    let truth = problem.values().expect("values");
    let (found, iterations) = invert(&problem, &[1.5 * truth[0]], &truth);
    let err = errors(&found, &truth);
    println!("cantilever E from the tip: {found:?} after {iterations} iterations, error {err:?}");
    assert!(err[0] < 1e-3, "E error {:.2e}", err[0]);
}

/// E and ν together from the displacements of every particle after 3 load steps, from a
/// start 30 % (E) and 40 % (ν) off; within 1 % each.
#[test]
fn cantilever_young_and_poisson_from_all_particles() {
    let (config, initial) = scene(CANTILEVER, 3);
    let quantities: Vec<(usize, Quantity)> = (1..=3)
        .flat_map(|step| {
            (0..initial.len()).flat_map(move |particle| {
                (0..2).map(move |component| {
                    (
                        step,
                        Quantity::Displacement {
                            particle,
                            component,
                        },
                    )
                })
            })
        })
        .collect();
    let observations = synthetic(&config, &initial, &quantities, 1e-3);
    let problem = ImplicitProblem {
        config,
        initial,
        params: vec![
            ImplicitParam::Material(0, MaterialField::Young),
            ImplicitParam::Material(0, MaterialField::Poisson),
        ],
        observations,
    };
    let truth = problem.values().expect("values");
    let start = [1.3 * truth[0], 1.4 * truth[1]];
    let (found, iterations) = invert(&problem, &start, &truth);
    let err = errors(&found, &truth);
    println!(
        "cantilever E, ν from all particles: {found:?} after {iterations} iterations, errors {err:?}"
    );
    assert!(err.iter().all(|e| *e < 1e-2), "errors {err:?}");
}

/// σ_y (√3 c_u) and E of the footing's clay from the footing load (the reaction of the
/// prescribed nodes) after each of 8 load steps: the early steps see mostly E, the later ones
/// the plastic zone's strength. Newton may take 25 iterations, so no step is cut between the
/// optimiser's trial points. Within 0.5 % each.
#[test]
fn footing_strength_and_stiffness_from_load_settlement() {
    let (mut config, initial) = scene(FOOTING, 8);
    config.newton.max_iterations = 25;
    let quantities = Quantity::Reaction {
        constraint: 0,
        component: 1,
    }
    .after_each(1..=8);
    let observations = synthetic(&config, &initial, &quantities, 100.0);
    let problem = ImplicitProblem {
        config,
        initial,
        params: vec![
            ImplicitParam::Material(0, MaterialField::YieldStress),
            ImplicitParam::Material(0, MaterialField::Young),
        ],
        observations,
    };
    let truth = problem.values().expect("values");
    let start = [0.7 * truth[0], 1.3 * truth[1]];
    let (found, iterations) = invert(&problem, &start, &truth);
    let err = errors(&found, &truth);
    println!(
        "footing σ_y, E from the load–settlement curve: {found:?} after {iterations} iterations, errors {err:?}"
    );
    assert!(err.iter().all(|e| *e < 5e-3), "errors {err:?}");
}

/// `dL/dθ` exact and "last step only" (the reverse pass of the last sub-step alone, the load
/// path before it held fixed) for `param` at `factor` times its value, with the observations
/// `quantities` of the run at the scene's values.
fn last_step_ratio(
    config: &ImplicitConfig<2>,
    initial: &Particles<f64, 2>,
    quantities: &[(usize, Quantity)],
    param: ImplicitParam,
    factor: f64,
) -> f64 {
    let observations = synthetic(config, initial, quantities, 1.0);
    let (mut c, mut p) = (config.clone(), initial.clone());
    let value = param.value(config, initial).expect("value");
    param.set(&mut c, &mut p, factor * value).expect("set");
    let run = run_recorded(&c, &p, None).expect("run");
    let exact = reverse(&c, &p, &run, &observations, &[param]).expect("adjoint");
    let last = reverse_last_substep(&c, &p, &run, &observations, &[param]).expect("last step");
    println!(
        "{param}: dL/dθ exact {:.6e}, last step only {:.6e} (ratio {:.4})",
        exact[0],
        last[0],
        last[0] / exact[0]
    );
    last[0] / exact[0]
}

/// How far the "last step only" gradient is from the exact one, away from the minimum (the
/// parameter 20 % low), for the final observation of each study. The last step's residual,
/// at its start state held fixed, still carries the whole stress (for the Hencky beam
/// `τ ∝ E` at a given F; for the plastic zone under the footing a stress on the yield surface
/// `∝ σ_y`), so the truncated gradient is close; what it misses is how the earlier steps'
/// geometry (positions, F) and, for J2, the plastic history (εᵖ, bₑ) move with the parameter.
/// Measured: 2.2 % (E of the cantilever) and 1.7 % (σ_y of the footing) short. The bounds say
/// that the difference is real (far above the 1e-10 agreement of the exact gradient with the
/// dual one) and of that order.
#[test]
fn last_step_gradient_misses_the_load_path() {
    let (config, initial) = scene(CANTILEVER, 10);
    let tip = Quantity::Displacement {
        particle: config.point_loads[0].particle,
        component: 1,
    };
    let young = ImplicitParam::Material(0, MaterialField::Young);
    let cantilever = last_step_ratio(&config, &initial, &[(10, tip)], young, 0.8);
    assert!((cantilever - 1.0).abs() > 1e-3 && (cantilever - 1.0).abs() < 0.1);
    let (mut config, initial) = scene(FOOTING, 8);
    config.newton.max_iterations = 25;
    let load = Quantity::Reaction {
        constraint: 0,
        component: 1,
    };
    let strength = ImplicitParam::Material(0, MaterialField::YieldStress);
    let footing = last_step_ratio(&config, &initial, &[(8, load)], strength, 0.8);
    assert!(
        (footing - 1.0).abs() > 1e-3 && (footing - 1.0).abs() < 0.1,
        "ratio {footing}"
    );
}
