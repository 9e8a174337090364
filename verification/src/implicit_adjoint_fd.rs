//! `implicit-adjoint-fd`: the adjoint of implicit runs (quasi-static and Newmark) against
//! forward-mode duals, central finite differences and the Taylor test.
//!
//! Scenes (`verification/scenes/implicit_*.toml`):
//!
//! - `implicit_cantilever`: a Hencky cantilever under its weight and a tip load; unknowns E,
//!   ν, the tip load and the density; the loss tracks the tip and a mid-span particle after
//!   every load step and the clamp's vertical reaction after the last;
//! - `implicit_footing`: half a strip footing pushed into J2 clay by a prescribed settlement,
//!   with plasticity from the first steps and a load step cut in half (Newton may take 5
//!   iterations); unknowns σ_y, E, the hardening and the settlement; the loss is the footing
//!   load after every load step and the settlement of a surface point beside it;
//! - `implicit_clay_footing`: the footing pushed 1 cm into lightly overconsolidated Modified
//!   Cam-Clay at rest under gravity (a geostatic initial stress, K0 = 0.6, balanced on the
//!   grid: gravity in full from the first load step); unknowns λ, κ, M and the OCR, which
//!   also move the history that carries the initial stress (held as data, as the balance
//!   is), and K0, which moves the initial stress itself, its history and its balance; the
//!   loss as for the J2 footing;
//! - the same footing pushed by a force of 40 kN/m instead (a force-controlled constraint:
//!   the footing's nodes share one vertical unknown, which carries the force); unknowns
//!   σ_y, E, the hardening and the force; the loss is the settlement under the footing after every
//!   load step and that of the point beside it;
//! - `implicit_cantilever_newmark`, the cantilever in Newmark dynamics (time steps of 0.04 s,
//!   about a twelfth of its first period, the tip load applied suddenly): unknowns E, ν, the tip load and the
//!   density (which now also sets the inertia); the loss tracks the tip's deflection and
//!   velocity after every time step and the clamp's vertical reaction after the last;
//! - the same with the tip load carried by a rigid plate over the beam's end (a
//!   force-controlled constraint, whose force a Newmark residual holds twice: directly and
//!   through the start force): unknowns E, the density and the plate's force;
//! - `implicit_consolidation`, coupled u–p: a strip load on a saturated elastic layer under a
//!   water table, applied undrained and held while the layer drains through its top surface
//!   (a drained free surface) over 10 steps growing by 2 (the pressure stabilisation on);
//!   unknowns E, ν, the hydraulic conductivity, one point of the strip's load and gravity;
//!   the loss tracks the settlement under the strip and the pore pressures of two piezometers
//!   under it after every step;
//! - the same layer with the fluid balance integrated by BDF2 (every step after the first
//!   drained one carries the previous step's fluid-content change and pressure increment):
//!   unknowns E, the conductivity and the point of the load;
//! - `implicit_mandel`, Mandel's problem at a reduced size: a saturated specimen under a
//!   rigid, smooth plate that carries a constant force (force-controlled), drained on its
//!   free side, over 6 steps growing by 2 through the Mandel–Cryer rise of the centre
//!   pressure; unknowns E, ν, the conductivity and the plate's force; the loss tracks the plate's settlement
//!   and two piezometers on the axis after every step;
//! - `implicit_consolidation_3d`, the same in 3D under a square load (a quarter by
//!   symmetry, 512 particles, 7 steps): unknowns E, the conductivity and gravity;
//! - `implicit_consolidation_clay`, the same on prestressed Modified Cam-Clay (K0 = 0.6, OCR
//!   = 1.5), which yields under the strip as it drains, and whose shear modulus, the
//!   stabilisation's weight, follows its mean effective stress: unknowns λ, κ, the
//!   conductivity, the OCR and K0.
//!
//! Observations are recorded from a run at the scene's values and the gradient is taken 5 %
//! away from them (alternating signs), so the loss and its gradient are not zero. Full size
//! doubles the cantilever's load steps (8 instead of 4; the Newmark cantilever halves its
//! time step, 10 steps of 0.02 s instead of 5 of 0.04 s over the same 0.2 s); the footing
//! keeps its 4, whose cut the case exercises. Metrics per scene:
//!
//! - max relative |adjoint − dual| **≤ 1e-10**: both are exact derivatives of the same
//!   discrete map at the same converged Newton solutions; they differ by summation order and
//!   by solving with `J` and `Jᵀ` (backward error ~1e-16 times the tangent's condition number);
//! - max relative |adjoint − central difference| **≤ 1e-6**: Richardson-extrapolated at
//!   δ = 1e-4 |θ| on the reference run's sub-steps (truncation O(δ⁴), round-off of the loss,
//!   Newton converged to 1e-12 of the load, over δ: ~1e-9);
//! - the Taylor test along a mixed-sign relative direction at h = 1e-3 … 1.25e-4: observed
//!   order log₂(r(h₀)/r(h₀/8))/3 **≥ 1.8** (2 for a correct gradient, 1 for a wrong one);
//! - the footing's cut sub-steps **≥ 1**, so that the cut replay is exercised.

use crate::{CaseReport, Metric, Size, VerifyError, scenes, write_text};
use loam_core::{NodeConstraint, Particles};
use loam_implicit::ImplicitConfig;
use loam_implicit::flow::TimeIntegration;
use loam_inverse::implicit::{
    ImplicitObservations, ImplicitParam, ImplicitProblem, Observation, Quantity, check,
    run_recorded,
};
use loam_inverse::{AdjointError, MaterialField};
use std::fmt::Write as _;
use std::path::Path;

const CASE: &str = "implicit-adjoint-fd";

/// What one scene gave.
struct Outcome {
    label: &'static str,
    params: Vec<ImplicitParam>,
    adjoint: Vec<f64>,
    dual: Vec<f64>,
    difference: Vec<f64>,
    order: f64,
    cuts: usize,
}

fn failed(source: AdjointError) -> VerifyError {
    VerifyError::Adjoint {
        case: CASE.into(),
        source,
    }
}

/// The scene `file` with `load_steps` load steps.
fn setup(file: &str, load_steps: usize) -> (ImplicitConfig<2>, Particles<f64, 2>) {
    let built = scenes::build::<2>(&scenes::scene(file));
    let mut config = built
        .implicit_config()
        .expect("the scene's solver is implicit");
    config.load_steps = load_steps;
    (config, built.particles)
}

/// The observations `quantities` after load steps, valued from the run of `problem` at its
/// scene's values.
fn observe<const D: usize>(
    problem: &mut ImplicitProblem<D>,
    quantities: &[(usize, Quantity, f64)],
) -> Result<(), VerifyError> {
    let run = run_recorded(&problem.config, &problem.initial, None).map_err(failed)?;
    problem.observations.items = quantities
        .iter()
        .map(|&(step, quantity, sigma)| Observation::of_run(step, quantity, sigma, &run))
        .collect();
    Ok(())
}

/// The checks on `problem` 5 % away from its scene's values.
fn check_problem<const D: usize>(
    label: &'static str,
    problem: &ImplicitProblem<D>,
) -> Result<Outcome, VerifyError> {
    let scene_values = problem.values().map_err(failed)?;
    let theta: Vec<f64> = (scene_values.iter().enumerate())
        .map(|(k, v)| v * if k % 2 == 0 { 1.05 } else { 0.95 })
        .collect();
    let (config, particles) = problem.setup(&theta).map_err(failed)?;
    let run = run_recorded(&config, &particles, None).map_err(failed)?;
    let schedule = run.schedule();
    let g = problem.gradient(&theta).map_err(failed)?;
    let dual = problem.dual_gradient(&theta).map_err(failed)?;
    let difference = (0..theta.len())
        .map(|k| check::central_difference(problem, &theta, &schedule, k, 1e-4))
        .collect::<Result<Vec<_>, _>>()
        .map_err(failed)?;
    let v: Vec<f64> = (0..theta.len())
        .map(|k| [1.0, -0.6, 0.8, -0.4][k % 4] * theta[k])
        .collect();
    let slope: f64 = g.gradient.iter().zip(&v).map(|(g, v)| g * v).sum();
    let remainders =
        check::taylor_remainders(problem, &theta, &schedule, g.loss, slope, &v, 1e-3, 4)
            .map_err(failed)?;
    Ok(Outcome {
        label,
        params: problem.params.clone(),
        adjoint: g.gradient,
        dual,
        difference,
        order: loam_inverse::check::observed_order(&remainders),
        cuts: run.cuts,
    })
}

/// The cantilever's unknowns: E, ν, the tip load and the density.
fn cantilever_params() -> Vec<ImplicitParam> {
    vec![
        ImplicitParam::Material(0, MaterialField::Young),
        ImplicitParam::Material(0, MaterialField::Poisson),
        ImplicitParam::PointLoad(0, 1),
        ImplicitParam::Material(0, MaterialField::Density),
    ]
}

/// The cantilever's check (`name`) with respect to `params`, for a loss over `quantities`
/// and the clamp's vertical reaction after the last step.
fn check_cantilever(
    name: &'static str,
    config: ImplicitConfig<2>,
    initial: Particles<f64, 2>,
    params: Vec<ImplicitParam>,
    mut quantities: Vec<(usize, Quantity, f64)>,
) -> Result<Outcome, VerifyError> {
    let reaction = Quantity::Reaction {
        constraint: 0,
        component: 1,
    };
    let last = config.load_steps;
    quantities.push((last, reaction, 100.0));
    let mut problem = ImplicitProblem {
        config,
        initial,
        params,
        observations: ImplicitObservations::default(),
    };
    observe(&mut problem, &quantities)?;
    check_problem(name, &problem)
}

/// The cantilever: E, ν, the tip load, the density.
fn cantilever(load_steps: usize) -> Result<Outcome, VerifyError> {
    let (config, initial) = setup("implicit_cantilever", load_steps);
    let tip = config.point_loads[0].particle;
    let mid = nearest(&initial, [1.25, 2.0]);
    let mut quantities = Vec::new();
    for step in 1..=load_steps {
        for particle in [tip, mid] {
            let quantity = Quantity::Displacement {
                particle,
                component: 1,
            };
            quantities.push((step, quantity, 0.01));
        }
    }
    check_cantilever(
        "cantilever",
        config,
        initial,
        cantilever_params(),
        quantities,
    )
}

/// A footing scene `file` (`label`) with respect to `params`: the footing load after every
/// load step and the settlement of a surface point beside the footing after the last.
fn footing(
    label: &'static str,
    file: &str,
    params: Vec<ImplicitParam>,
) -> Result<Outcome, VerifyError> {
    let load_steps = 4;
    let (config, initial) = setup(file, load_steps);
    let side = nearest(&initial, [0.8, 1.0]);
    let load = Quantity::Reaction {
        constraint: 0,
        component: 1,
    };
    let mut quantities: Vec<(usize, Quantity, f64)> =
        (1..=load_steps).map(|step| (step, load, 1e3)).collect();
    let beside = Quantity::displacement(side, 1);
    quantities.push((load_steps, beside, 1e-3));
    let mut problem = ImplicitProblem {
        config,
        initial,
        params,
        observations: ImplicitObservations::default(),
    };
    observe(&mut problem, &quantities)?;
    check_problem(label, &problem)
}

/// The vertical force on the half footing of `implicit_footing` when it is force-controlled
/// (N per metre): about 0.8 of the load its 3 cm settlement takes (49.3 kN/m), so the clay
/// under it yields, and hardens, without the footing plunging.
const FOOTING_FORCE: f64 = -4.0e4;

/// The J2 footing pushed by a force instead of a settlement (a force-controlled constraint:
/// the footing's nodes share one vertical unknown, which carries the force): σ_y, E, the
/// hardening and the force; the loss tracks the settlement of the surface under the footing's middle after
/// every load step and that of a surface point beside it after the last.
fn force_footing() -> Result<Outcome, VerifyError> {
    let load_steps = 4;
    let (mut config, initial) = setup("implicit_footing", load_steps);
    let footing = &mut config.constraints[0];
    footing.displacement[1] = None;
    footing.force[1] = Some(FOOTING_FORCE);
    let under = nearest(&initial, [0.25, 1.0]);
    let side = nearest(&initial, [0.8, 1.0]);
    let mut quantities: Vec<(usize, Quantity, f64)> = (1..=load_steps)
        .map(|step| (step, Quantity::displacement(under, 1), 1e-3))
        .collect();
    quantities.push((load_steps, Quantity::displacement(side, 1), 1e-3));
    let mut problem = ImplicitProblem {
        config,
        initial,
        params: vec![
            ImplicitParam::Material(0, MaterialField::YieldStress),
            ImplicitParam::Material(0, MaterialField::Young),
            ImplicitParam::Material(0, MaterialField::Hardening),
            ImplicitParam::ConstraintForce(0, 1),
        ],
        observations: ImplicitObservations::default(),
    };
    observe(&mut problem, &quantities)?;
    check_problem("force-controlled footing", &problem)
}

/// The J2 footing: σ_y, E, the hardening, the settlement.
///
/// It runs the scene's 4 load steps at both sizes: the cut that the case exercises comes
/// from a load step too large for Newton's 5 iterations, and smaller steps (5 to 16 of them,
/// with 3 to 6 iterations, were tried) either converge uncut or cut so deep that the run
/// fails, depending on round-off at the 1e-12 tolerance.
fn j2_footing() -> Result<Outcome, VerifyError> {
    footing(
        "footing",
        "implicit_footing",
        vec![
            ImplicitParam::Material(0, MaterialField::YieldStress),
            ImplicitParam::Material(0, MaterialField::Young),
            ImplicitParam::Material(0, MaterialField::Hardening),
            ImplicitParam::Displacement(0, 1),
        ],
    )
}

/// The footing on prestressed Modified Cam-Clay: λ, κ, M and the OCR, which act also through
/// the history that carries the initial stress (κ, through the elastic strain; M and the
/// OCR, through `p_c₀`), and K0, through the initial stress, its history and its balance.
fn clay_footing() -> Result<Outcome, VerifyError> {
    footing(
        "prestressed clay footing",
        "implicit_clay_footing",
        vec![
            ImplicitParam::Material(0, MaterialField::Lambda),
            ImplicitParam::Material(0, MaterialField::Kappa),
            ImplicitParam::Material(0, MaterialField::CriticalStateSlope),
            ImplicitParam::Material(0, MaterialField::Ocr),
            ImplicitParam::K0(0),
        ],
    )
}

/// The particle of `initial` nearest to `at`.
fn nearest<const D: usize>(initial: &Particles<f64, D>, at: [f64; D]) -> usize {
    (0..initial.len())
        .min_by(|&a, &b| {
            let d = |p: usize| (0..D).map(|k| (initial.x[p][k] - at[k]).abs()).sum::<f64>();
            d(a).total_cmp(&d(b))
        })
        .expect("particles")
}

/// The strip (2D) or square (3D) load on a saturated layer (coupled u–p, scene `file`)
/// with respect to `params`: the settlement under the load's centre (the surface above the
/// origin) and the pore pressures of two piezometers under it, 0.6 m and 0.3 m above the
/// base, after every step.
fn consolidation<const D: usize>(
    label: &'static str,
    file: &str,
    scheme: TimeIntegration,
    params: Vec<ImplicitParam>,
) -> Result<Outcome, VerifyError> {
    let built = scenes::build::<D>(&scenes::scene(file));
    let mut config = built
        .implicit_config()
        .expect("the scene's solver is implicit");
    if let Some(fluid) = config.pore_fluid.as_mut() {
        fluid.time_integration = scheme;
    }
    let initial = built.particles;
    let above = |height: f64| std::array::from_fn(|k| if k == D - 1 { height } else { 0.0 });
    let surface = nearest(&initial, above(1.0));
    let piezometers = [nearest(&initial, above(0.6)), nearest(&initial, above(0.3))];
    let mut quantities = Vec::new();
    for step in 1..=config.load_steps {
        quantities.push((step, Quantity::displacement(surface, D - 1), 1e-4));
        for &particle in &piezometers {
            quantities.push((step, Quantity::PorePressure { particle }, 100.0));
        }
    }
    let mut problem = ImplicitProblem {
        config,
        initial,
        params,
        observations: ImplicitObservations::default(),
    };
    observe(&mut problem, &quantities)?;
    check_problem(label, &problem)
}

/// The Newmark cantilever over the scene's 0.2 s in `steps` time steps, and its loss's
/// quantities: the tip's deflection and velocity after every time step.
fn newmark_setup(
    steps: usize,
) -> (
    ImplicitConfig<2>,
    Particles<f64, 2>,
    Vec<(usize, Quantity, f64)>,
) {
    let (mut config, initial) = setup("implicit_cantilever_newmark", steps);
    config.dynamics = Some(NEWMARK_DURATION / steps as f64);
    let tip = config.point_loads[0].particle;
    let mut quantities = Vec::new();
    for step in 1..=steps {
        quantities.push((step, Quantity::displacement(tip, 1), 0.01));
        quantities.push((step, Quantity::velocity(tip, 1), 0.1));
    }
    (config, initial, quantities)
}

/// The cantilever in Newmark dynamics: E, ν, the tip load, the density.
fn newmark(steps: usize) -> Result<Outcome, VerifyError> {
    let (config, initial, quantities) = newmark_setup(steps);
    let params = cantilever_params();
    check_cantilever("newmark cantilever", config, initial, params, quantities)
}

/// The Newmark cantilever with its tip load carried by a rigid plate instead of the point
/// load: the nodes at x = 2.25 and 2.5 m (the beam's end and the column beyond it), y = 2 …
/// 2.5 m, share one vertical unknown that carries the load (force-controlled). E, the density
/// and the plate's force, which a Newmark step's residual holds twice (directly and through
/// its start force).
fn newmark_plate(steps: usize) -> Result<Outcome, VerifyError> {
    let (mut config, initial, quantities) = newmark_setup(steps);
    let load = config.point_loads.remove(0);
    config.constraints.push(NodeConstraint {
        lo: [2.2, 1.9],
        hi: [2.6, 2.6],
        displacement: [None, None],
        force: [None, Some(load.force[1])],
    });
    let params = vec![
        ImplicitParam::Material(0, MaterialField::Young),
        ImplicitParam::Material(0, MaterialField::Density),
        ImplicitParam::ConstraintForce(config.constraints.len() - 1, 1),
    ];
    let name = "newmark cantilever, force-controlled plate";
    check_cantilever(name, config, initial, params, quantities)
}

/// The simulated time of the Newmark cantilever (s): the scene's 5 time steps of 0.04 s.
const NEWMARK_DURATION: f64 = 0.2;

/// Runs the case.
///
/// # Errors
/// A run or a gradient that fails, or the table that cannot be written.
pub fn run(size: Size, dir: &Path) -> Result<CaseReport, VerifyError> {
    let (load_steps, newmark_steps) = match size {
        Size::Reduced => (4, 5),
        Size::Full => (8, 10),
    };
    let outcomes = [
        cantilever(load_steps)?,
        j2_footing()?,
        force_footing()?,
        newmark(newmark_steps)?,
        newmark_plate(newmark_steps)?,
        clay_footing()?,
        consolidation::<2>(
            "consolidation (u–p)",
            "implicit_consolidation",
            TimeIntegration::BackwardEuler,
            vec![
                ImplicitParam::Material(0, MaterialField::Young),
                ImplicitParam::Material(0, MaterialField::Poisson),
                ImplicitParam::Conductivity(0),
                ImplicitParam::PointLoad(0, 1),
                ImplicitParam::Gravity(1),
            ],
        )?,
        consolidation::<2>(
            "consolidation, BDF2 (u–p)",
            "implicit_consolidation",
            TimeIntegration::Bdf2,
            vec![
                ImplicitParam::Material(0, MaterialField::Young),
                ImplicitParam::Conductivity(0),
                ImplicitParam::PointLoad(0, 1),
            ],
        )?,
        consolidation::<2>(
            "Mandel, force-controlled plate (u–p)",
            "implicit_mandel",
            TimeIntegration::BackwardEuler,
            vec![
                ImplicitParam::Material(0, MaterialField::Young),
                ImplicitParam::Material(0, MaterialField::Poisson),
                ImplicitParam::Conductivity(0),
                ImplicitParam::ConstraintForce(0, 1),
            ],
        )?,
        consolidation::<3>(
            "consolidation in 3D (u–p)",
            "implicit_consolidation_3d",
            TimeIntegration::BackwardEuler,
            vec![
                ImplicitParam::Material(0, MaterialField::Young),
                ImplicitParam::Conductivity(0),
                ImplicitParam::Gravity(2),
            ],
        )?,
        consolidation::<2>(
            "clay consolidation (u–p)",
            "implicit_consolidation_clay",
            TimeIntegration::BackwardEuler,
            vec![
                ImplicitParam::Material(0, MaterialField::Lambda),
                ImplicitParam::Material(0, MaterialField::Kappa),
                ImplicitParam::Conductivity(0),
                ImplicitParam::Material(0, MaterialField::Ocr),
                ImplicitParam::K0(0),
            ],
        )?,
    ];
    let mut metrics = Vec::new();
    let mut md = String::from(
        "| scene | unknown | adjoint | dual | central difference |\n|---|---|---|---|---|\n",
    );
    for o in &outcomes {
        let relative = |other: &[f64]| {
            (o.adjoint.iter().zip(other))
                .map(|(a, b)| (a - b).abs() / b.abs())
                .fold(0.0, f64::max)
        };
        metrics.push(Metric::at_most(
            CASE,
            &format!("{}: max rel |adjoint − dual|", o.label),
            relative(&o.dual),
            1e-10,
        ));
        metrics.push(Metric::at_most(
            CASE,
            &format!("{}: max rel |adjoint − central diff.|", o.label),
            relative(&o.difference),
            1e-6,
        ));
        metrics.push(Metric::at_least(
            CASE,
            &format!("{}: Taylor order", o.label),
            o.order,
            1.8,
        ));
        for (k, p) in o.params.iter().enumerate() {
            writeln!(
                md,
                "| {} | {p} | {:.12e} | {:.12e} | {:.12e} |",
                o.label, o.adjoint[k], o.dual[k], o.difference[k]
            )
            .expect("writing to a String");
        }
    }
    metrics.push(Metric::at_least(
        CASE,
        "footing: cut sub-steps",
        outcomes[1].cuts as f64,
        1.0,
    ));
    let table = dir.join("implicit_adjoint_fd.md");
    write_text(&table, &md)?;
    Ok(CaseReport {
        metrics,
        files: vec![table],
    })
}
