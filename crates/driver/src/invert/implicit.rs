//! An inversion file on an implicit scene (`[solver] type = "implicit"`): quasi-static
//! load steps (the time steps of a coupled u–p scene), parameters of the implicit path
//! ([`ImplicitParam`]), observations of particle displacements, constraint reactions and (in
//! a coupled scene) piezometers' pore pressures after chosen load steps
//! (`docs/inversion-format.md`).

use super::Limits;
use super::common::{
    Solver, Unknowns, check_observed, check_sources, check_tracked, observed_steps, unknowns,
    valid, velocity_only,
};
use super::file::{
    Invalid, Inversion, InversionFile, OptimizerSpec, ParameterSpec, check_optimiser, for_path,
    require_truth, tracked_ids,
};
use super::limits;
use super::model::Model;
use super::observed;
use loam_core::Particles;
use loam_core::tensor::Vector;
use loam_implicit::ImplicitConfig;
use loam_inverse::Param;
use loam_inverse::implicit::{
    ImplicitObservations, ImplicitParam, ImplicitProblem, Observation, Quantity, run_recorded,
};
use loam_scene::{Built, Issue, Scene};
use std::path::{Path, PathBuf};

/// What an explicit-only field is told on an implicit scene.
const EXPLICIT_ONLY: &str = "applies to explicit scenes; this scene is implicit (`[solver] type = \
                             \"implicit\"`), whose inversions observe particle `displacement`s \
                             and constraint `reaction`s";

/// Builds the inversion of an implicit scene from the file, as [`super::file::build`] does
/// for an explicit one. Every problem found is reported at once with its field path.
pub fn build<const D: usize>(
    path: &Path,
    file: InversionFile,
    scene_path: PathBuf,
    scene: Scene,
    built: Built<D>,
    memory: Option<u64>,
    limits: Limits,
) -> Result<Inversion<D>, Invalid> {
    let mut issues = Vec::new();
    let mut issue = |at: String, msg: String| issues.push(Issue::new(at, msg));
    let mut config = built.implicit_config().expect("an implicit scene");
    let unit = built.time_unit().seconds();
    let n = built.particles.len();
    let o = &file.observations;
    let explicit_only = [
        ("end_time", file.end_time.is_some()),
        ("segment", file.segment.is_some()),
        ("velocity_field", !file.velocity_field.is_empty()),
    ];
    let truth_scene = file.synthetic.as_ref().is_some_and(|s| s.scene.is_some());
    let fields = (explicit_only.iter())
        .filter(|(_, given)| *given)
        .map(|(field, _)| field.to_string())
        .chain(o.given_for(Solver::Explicit))
        .chain(truth_scene.then(|| "synthetic.scene".to_owned()));
    for field in fields {
        issue(field, EXPLICIT_ONLY.into());
    }
    if memory.is_some() {
        issue(
            "--memory".into(),
            "budgets the explicit adjoint's checkpoints; an implicit run keeps every load step"
                .into(),
        );
    }
    let coupled = config.pore_fluid.is_some();
    match file.steps {
        Some(_) if coupled => issue(
            "steps".into(),
            "a coupled (u–p) scene's steps are its [solver.consolidation] schedule's; set the \
             steps there"
                .into(),
        ),
        Some(0) => issue("steps".into(), "expected at least 1 load step".into()),
        Some(steps) => config.load_steps = steps,
        None => {}
    }
    if file.parameters.is_empty() {
        issue(
            "parameters".into(),
            "expected at least one parameter".into(),
        );
    }
    // The unknowns, as the scene numbers them and as the solver does.
    let Unknowns {
        controls,
        variables,
        truth,
    } = unknowns(&file.parameters, &mut issue, |p, issue| {
        velocity_only(p, &format!(", which {EXPLICIT_ONLY}"), issue);
        (solver_param(p, &scene, &config, &built.particles))
            .map_err(|msg| issue("name", msg))
            .ok()
    });
    let (scene_params, params): (Vec<_>, Vec<_>) = controls.into_iter().unzip();
    check_optimiser(&file.optimizer, &file.stop, &mut issue);
    if matches!(file.optimizer, OptimizerSpec::LevenbergMarquardt { .. }) {
        issue(
            "optimizer.method".into(),
            "levenberg_marquardt applies to explicit scenes; an implicit scene's inversion uses \
             lbfgs or adam"
                .into(),
        );
    }
    for (field, sigma) in [
        ("displacement_sigma", o.displacement_sigma),
        ("reaction_sigma", o.reaction_sigma),
        ("pore_pressure_sigma", o.pore_pressure_sigma),
    ] {
        if let Some(v) = sigma
            && !(v.is_finite() && v > 0.0)
        {
            issue(
                format!("observations.{field}"),
                format!("expected a standard deviation > 0, got {v}"),
            );
        }
    }
    let mut reaction_names: Vec<String> = Vec::new();
    for (i, r) in o.reactions.iter().enumerate() {
        let at = |f: &str| format!("observations.reactions[{i}].{f}");
        if reaction_names.contains(&r.name) {
            issue(
                at("name"),
                format!("reaction `{}` is defined twice", r.name),
            );
        }
        reaction_names.push(r.name.clone());
        match config.constraints.get(r.constraint) {
            None => issue(
                at("constraint"),
                format!(
                    "constraint {} does not exist: the scene has {} [[constraints]]",
                    r.constraint,
                    config.constraints.len()
                ),
            ),
            Some(_) if r.axis >= D => {
                issue(at("axis"), format!("expected an axis 0 to {}", D - 1));
            }
            Some(c) if c.displacement[r.axis].is_none() => issue(
                at("axis"),
                format!(
                    "component {} of constraint {} is free and has no reaction; expected a \
                     prescribed axis",
                    r.axis, r.constraint
                ),
            ),
            Some(_) => {}
        }
    }
    let piezometers = piezometers(o, &built.particles, coupled, &mut issue);
    check_sources(
        file.synthetic.is_some(),
        &o.files(Solver::Implicit),
        &[
            (
                o.reaction.is_some() && o.reactions.is_empty(),
                "reactions",
                "the reaction file needs [[observations.reactions]]",
            ),
            (
                o.pore_pressure.is_some() && o.piezometers.is_empty(),
                "piezometers",
                "the pore-pressure file needs [[observations.piezometers]]",
            ),
        ],
        &mut issue,
    );
    if let Some(s) = &file.synthetic {
        if s.every == Some(0) {
            issue(
                "synthetic.every".into(),
                "expected at least 1 load step".into(),
            );
        }
        if s.first == Some(0) {
            issue(
                "synthetic.first".into(),
                "expected a load step ≥ 1 (step 0 is the initial state)".into(),
            );
        }
        let every = s.every.unwrap_or(1).max(1);
        check_observed(s, every, config.load_steps, &mut issue);
        check_tracked(s, n, &mut issue);
        if s.particles == 0
            && s.ids.is_empty()
            && o.reactions.is_empty()
            && o.piezometers.is_empty()
        {
            issue(
                "synthetic.particles".into(),
                "nothing to observe: choose particles (`particles`, `ids`) or define \
                 [[observations.reactions]] or [[observations.piezometers]]"
                    .into(),
            );
        }
        require_truth(&file.parameters, &mut issue);
    }
    // The length of the run and the memory of its record, before a step is run.
    let rows = file.synthetic.as_ref().map_or(0, |s| {
        let every = s.every.unwrap_or(1).max(1);
        let per_step = tracked_ids(n, s).len() * D + o.reactions.len() + o.piezometers.len();
        observed_steps(s, every, config.load_steps) * per_step
    });
    let bytes = limits::implicit::<D>(config.load_steps, n, rows as f64);
    if let Some(msg) = limits.exceeded(config.load_steps, bytes) {
        let field = match file.steps {
            Some(_) => "steps",
            None => "scene",
        };
        issue(field.into(), msg);
    }
    valid(path, issues)?;
    let mut problem = ImplicitProblem {
        config,
        initial: built.particles,
        params,
        observations: ImplicitObservations::default(),
    };
    let steps = problem.config.load_steps;
    let sigmas = Sigmas {
        displacement: o.displacement_sigma.unwrap_or(1.0),
        reaction: o.reaction_sigma.unwrap_or(1.0),
        pore_pressure: o.pore_pressure_sigma.unwrap_or(1.0),
    };
    let reactions: Vec<(usize, usize)> =
        o.reactions.iter().map(|r| (r.constraint, r.axis)).collect();
    problem.observations.items = match &file.synthetic {
        Some(s) => {
            let truth = truth.as_deref().expect("checked above");
            let (config, particles) = problem.setup(truth).map_err(|e| Invalid(e.to_string()))?;
            let run = run_recorded(&config, &particles, None)
                .map_err(|e| Invalid(format!("{}: the truth run: {e}", path.display())))?;
            let every = s.every.unwrap_or(1);
            let first = s.first.unwrap_or(every);
            let ids = tracked_ids(n, s);
            let mut items = Vec::new();
            for step in (first..=steps).step_by(every) {
                for &particle in &ids {
                    for component in 0..D {
                        let quantity = Quantity::Displacement {
                            particle,
                            component,
                        };
                        items.push((step, quantity, sigmas.displacement));
                    }
                }
                for &(constraint, component) in &reactions {
                    let quantity = Quantity::Reaction {
                        constraint,
                        component,
                    };
                    items.push((step, quantity, sigmas.reaction));
                }
                for &particle in &piezometers {
                    let quantity = Quantity::PorePressure { particle };
                    items.push((step, quantity, sigmas.pore_pressure));
                }
            }
            (items.into_iter())
                .map(|(step, quantity, sigma)| Observation::of_run(step, quantity, sigma, &run))
                .collect()
        }
        None => {
            // A `time` column reads as the load factor `step / load_steps`, or in a coupled
            // scene as the schedule's time (in the scene's time unit) at the end of a step.
            let times = (problem.config.pore_fluid.as_ref())
                .map(|f| f.schedule.time[1..].iter().map(|t| t / unit).collect());
            let grid = observed::Grid {
                times,
                dt: 1.0 / steps as f64,
                steps,
                particles: n,
                domain: (scene.grid.lo.clone(), scene.grid.hi.clone()),
                cell: scene.grid.cell_size,
            };
            read_observations::<D>(path, &file, &grid, &sigmas, &reactions, &piezometers)?
        }
    };
    let initial = file.parameters.iter().map(|p| p.initial).collect();
    let names = file.parameters.iter().map(|p| p.name.clone()).collect();
    Ok(Inversion {
        path: path.to_path_buf(),
        file,
        scene_path,
        scene,
        names,
        variables,
        problem: Model::Implicit {
            problem,
            scene_params,
            piezometers,
        },
        truth,
        truth_initial: None,
        initial,
        monitor_names: Vec::new(),
        station_names: Vec::new(),
    })
}

/// The parameter `p` names, as the scene numbers it and as the solver does (a point load
/// `k` of the scene is the load on its particle, `Σ_{j<k} count_j`); an error message
/// naming what is expected otherwise.
fn solver_param<const D: usize>(
    p: &ParameterSpec,
    scene: &Scene,
    config: &ImplicitConfig<D>,
    particles: &Particles<f64, D>,
) -> Result<(ImplicitParam, ImplicitParam), String> {
    let named = p.name.parse::<ImplicitParam>().map_err(|msg| {
        let explicit = p.name == "velocity" || p.name.parse::<Param>().is_ok();
        for_path(&msg, explicit, "explicit")
    })?;
    let solver = match named {
        ImplicitParam::PointLoad(k, a) => {
            let Some(load) = scene.point_loads.get(k) else {
                return Err(format!(
                    "no such point load: the scene has {} [[point_loads]]",
                    scene.point_loads.len()
                ));
            };
            if load.count != 1 {
                return Err(format!(
                    "point load {k} is shared by `count` = {} particles; a parameter needs a \
                     point load on one particle (`count = 1`)",
                    load.count
                ));
            }
            let particle: usize = scene.point_loads[..k].iter().map(|l| l.count).sum();
            ImplicitParam::PointLoad(particle, a)
        }
        other => other,
    };
    solver.value(config, particles).map_err(|e| e.to_string())?;
    Ok((named, solver))
}

/// The standard deviations of the observations, by kind.
struct Sigmas {
    displacement: f64,
    reaction: f64,
    pore_pressure: f64,
}

/// The particle each `[[observations.piezometers]]` entry reads: the nearest to its `at` in
/// the initial state. Issues name the field (a piezometer on a dry scene, a position of the
/// wrong length or outside every body's reach, a name given twice).
fn piezometers<const D: usize>(
    o: &super::file::ObservationsSpec,
    particles: &Particles<f64, D>,
    coupled: bool,
    issue: &mut impl FnMut(String, String),
) -> Vec<usize> {
    if !coupled {
        for (field, given) in [
            ("piezometers", !o.piezometers.is_empty()),
            ("pore_pressure", o.pore_pressure.is_some()),
            ("pore_pressure_sigma", o.pore_pressure_sigma.is_some()),
        ] {
            if given {
                issue(
                    format!("observations.{field}"),
                    "observes the pore pressure of a coupled scene; this scene has no \
                     [pore_fluid]"
                        .into(),
                );
            }
        }
        return Vec::new();
    }
    let mut names: Vec<&str> = Vec::new();
    let mut out = Vec::new();
    for (i, p) in o.piezometers.iter().enumerate() {
        let at = |f: &str| format!("observations.piezometers[{i}].{f}");
        if names.contains(&p.name.as_str()) {
            issue(
                at("name"),
                format!("piezometer `{}` is defined twice", p.name),
            );
        }
        names.push(&p.name);
        if p.at.len() != D || p.at.iter().any(|v| !v.is_finite()) {
            issue(at("at"), format!("expected {D} finite coordinates"));
            continue;
        }
        let distance = |k: usize| {
            (0..D)
                .map(|a| (particles.x[k][a] - p.at[a]).powi(2))
                .sum::<f64>()
        };
        match (0..particles.len()).min_by(|&a, &b| distance(a).total_cmp(&distance(b))) {
            Some(k) => out.push(k),
            None => issue(at("at"), "the scene has no particles".into()),
        }
    }
    out
}

/// The observations of `[observations]`'s CSV files: per load step, every component of each
/// listed particle's displacement, each named reaction (`reactions[i]` = (constraint, axis)
/// of reaction `i`) and each piezometer's pore pressure (`piezometers[i]` its particle).
fn read_observations<const D: usize>(
    path: &Path,
    file: &InversionFile,
    grid: &observed::Grid,
    sigmas: &Sigmas,
    reactions: &[(usize, usize)],
    piezometers: &[usize],
) -> Result<Vec<Observation>, Invalid> {
    let dir = path.parent().unwrap_or(Path::new(""));
    let o = &file.observations;
    let steps = grid.steps;
    let initial_state = |field: &str| {
        Issue::new(
            format!("observations.{field}"),
            format!("a row at step 0, the initial state; expected load steps 1 to {steps}"),
        )
    };
    let mut items = Vec::new();
    let mut errors = Vec::new();
    if let Some(f) = &o.displacement {
        match observed::read_displacement::<D>(&dir.join(f), grid) {
            Ok(t) if t.contains_key(&0) => errors.push(initial_state("displacement")),
            Ok(t) => {
                for (step, rows) in t {
                    for (particle, u) in rows {
                        for component in 0..D {
                            items.push(Observation {
                                step,
                                quantity: Quantity::Displacement {
                                    particle,
                                    component,
                                },
                                value: u[component],
                                sigma: sigmas.displacement,
                            });
                        }
                    }
                }
            }
            Err(msg) => errors.push(Issue::new("observations.displacement", msg)),
        }
    }
    if let Some(f) = &o.reaction {
        let names: Vec<String> = o.reactions.iter().map(|r| r.name.clone()).collect();
        match observed::read_reaction(&dir.join(f), grid, &names) {
            Ok(t) if t.contains_key(&0) => errors.push(initial_state("reaction")),
            Ok(t) => {
                for (step, rows) in t {
                    for (r, force) in rows {
                        let (constraint, component) = reactions[r];
                        items.push(Observation {
                            step,
                            quantity: Quantity::Reaction {
                                constraint,
                                component,
                            },
                            value: force,
                            sigma: sigmas.reaction,
                        });
                    }
                }
            }
            Err(msg) => errors.push(Issue::new("observations.reaction", msg)),
        }
    }
    if let Some(f) = &o.pore_pressure {
        let names: Vec<String> = o.piezometers.iter().map(|p| p.name.clone()).collect();
        match observed::read_pore_pressure(&dir.join(f), grid, &names) {
            Ok(t) if t.contains_key(&0) => errors.push(initial_state("pore_pressure")),
            Ok(t) => {
                for (step, rows) in t {
                    for (k, value) in rows {
                        items.push(Observation {
                            step,
                            quantity: Quantity::PorePressure {
                                particle: piezometers[k],
                            },
                            value,
                            sigma: sigmas.pore_pressure,
                        });
                    }
                }
            }
            Err(msg) => errors.push(Issue::new("observations.pore_pressure", msg)),
        }
    }
    valid(path, errors)?;
    Ok(items)
}

/// The observations of an implicit inversion as the CSV files hold them: per load step, the
/// displacement of every observed particle (all components), the named reactions (indices
/// into `[[observations.reactions]]`) and the piezometers' pore pressures (indices into
/// `[[observations.piezometers]]`, whose particles are `piezometers`).
pub fn targets<const D: usize>(
    file: &InversionFile,
    observations: &ImplicitObservations,
    piezometers: &[usize],
) -> Targets<D> {
    let mut displacements = observed::Targets::<D>::new();
    let mut reactions = observed::Targets::<1>::new();
    let mut pressures = observed::Targets::<1>::new();
    for o in &observations.items {
        match o.quantity {
            Quantity::Displacement {
                particle,
                component,
            } => {
                let rows = displacements.entry(o.step).or_default();
                if rows.last().is_none_or(|r| r.0 != particle) {
                    rows.push((particle, Vector::zeros()));
                }
                if let Some(row) = rows.last_mut() {
                    row.1[component] = o.value;
                }
            }
            // An inversion file observes displacements, reactions and pore pressures.
            Quantity::Velocity { .. } => {}
            Quantity::PorePressure { particle } => {
                if let Some(k) = piezometers.iter().position(|&p| p == particle) {
                    (pressures.entry(o.step).or_default()).push((k, Vector::from([o.value])));
                }
            }
            Quantity::Reaction {
                constraint,
                component,
            } => {
                let named = (file.observations.reactions.iter())
                    .position(|r| r.constraint == constraint && r.axis == component);
                if let Some(r) = named {
                    (reactions.entry(o.step).or_default()).push((r, Vector::from([o.value])));
                }
            }
        }
    }
    Targets {
        displacements,
        reactions,
        pressures,
    }
}

/// An implicit inversion's observations by kind ([`targets`]).
pub struct Targets<const D: usize> {
    /// Particle displacements.
    pub displacements: observed::Targets<D>,
    /// Named reactions.
    pub reactions: observed::Targets<1>,
    /// Piezometers' pore pressures.
    pub pressures: observed::Targets<1>,
}
