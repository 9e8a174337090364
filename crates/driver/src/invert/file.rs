//! The inversion file: its schema, reading it with field-path errors, and turning it into an
//! inverse problem on the scene it names (`docs/inversion-format.md`).

use super::Limits;
use super::common::{
    Solver, Unknowns, check_observed, check_sources, check_tracked, observed_steps, unknowns,
    valid, velocity_only,
};
use super::limits;
use super::model::Model;
use super::observed;
use super::units::quantity;
use loam_core::Particles;
use loam_core::TimeStep;
use loam_core::tensor::Vector;
use loam_explicit::Config;
use loam_inverse::implicit::ImplicitParam;
use loam_inverse::{
    Checkpoints, Control, K0State, MonitorBox, Observations, Param, Problem, ReverseStep, Station,
    Transform, Variable, VelocityField,
};
use loam_scene::{Built, Issue, Scene, SceneError, SceneFormat, SolverPlan};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// A whole inversion file.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InversionFile {
    /// The forward scene, relative to the inversion file's folder.
    pub scene: PathBuf,
    /// Steps of every run (default: the scene's fixed step count); not with `end_time`.
    pub steps: Option<usize>,
    /// Simulated time of every run, `round(end_time / Δt)` steps; not with `steps`.
    pub end_time: Option<f64>,
    /// Steps between the adjoint's checkpoints (default: the segment length of least
    /// memory, or the longest that `--memory` allows); not with `--memory`.
    pub segment: Option<usize>,
    /// The scalar unknowns.
    #[serde(default)]
    pub parameters: Vec<ParameterSpec>,
    /// Initial velocity fields given by an MLP (their weights are unknowns too).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub velocity_field: Vec<VelocityFieldSpec>,
    /// Observation files and monitor boxes.
    #[serde(default)]
    pub observations: ObservationsSpec,
    /// Make the observations from a truth run instead of reading them.
    pub synthetic: Option<SyntheticSpec>,
    /// The optimiser (default L-BFGS).
    #[serde(default)]
    pub optimizer: OptimizerSpec,
    /// When to stop.
    #[serde(default)]
    pub stop: StopSpec,
}

/// `[[parameters]]`: one unknown.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterSpec {
    /// `friction[k]`, `obstacle[k].friction`, `obstacle[k].velocity[a]`, `gravity[a]`,
    /// `materials[k].<constant>`, or `velocity` (an initial velocity).
    pub name: String,
    /// The first guess.
    pub initial: f64,
    /// The value of the truth run (`[synthetic]`), and the reference in the report.
    pub truth: Option<f64>,
    /// `identity` (default) or `softplus`.
    #[serde(default)]
    pub transform: Transform,
    /// The scale `s` of `θ = s z` or `θ = s softplus(z)` (default 1).
    pub scale: Option<f64>,
    /// `[lo, hi]` on the value.
    pub bounds: Option<[f64; 2]>,
    /// `velocity`: the direction (normalised).
    pub direction: Option<Vec<f64>>,
    /// `velocity`: the material whose particles it sets (default all).
    pub material: Option<String>,
}

/// `[[velocity_field]]`: the initial velocity along `direction` of a material's particles
/// given by an MLP of the initial position.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VelocityFieldSpec {
    /// The direction (normalised).
    pub direction: Vec<f64>,
    /// The material whose particles it sets (default all).
    pub material: Option<String>,
    /// The hidden layers' widths (default `[30, 30, 30]`).
    #[serde(default = "hidden")]
    pub hidden: Vec<usize>,
    /// The seed of the Glorot initialisation (default 0).
    #[serde(default)]
    pub seed: u64,
}

fn hidden() -> Vec<usize> {
    vec![30, 30, 30]
}

/// `[observations]`.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObservationsSpec {
    /// CSV of tracked positions (`step|time, id, x, y[, z]`).
    pub tracked: Option<PathBuf>,
    /// Weight of every squared position mismatch (default 1).
    pub tracked_weight: Option<f64>,
    /// CSV of monitor velocities (`step|time, monitor, vx, vy[, vz]`).
    pub velocity: Option<PathBuf>,
    /// Weight of every squared velocity mismatch (default 1).
    pub velocity_weight: Option<f64>,
    /// The monitor boxes.
    #[serde(default)]
    pub monitors: Vec<MonitorSpec>,
    /// CSV of deposit depths (`step|time, station, depth`).
    pub deposit: Option<PathBuf>,
    /// Weight of every squared depth mismatch (default 1).
    pub deposit_weight: Option<f64>,
    /// The deposit stations.
    #[serde(default)]
    pub stations: Vec<StationSpec>,
    /// Implicit: CSV of particle displacements after load steps (`step, id, ux, uy[, uz]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub displacement: Option<PathBuf>,
    /// Implicit: the standard deviation `σ` of every displacement (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub displacement_sigma: Option<f64>,
    /// Implicit: CSV of reactions after load steps (`step, reaction, force`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reaction: Option<PathBuf>,
    /// Implicit: the standard deviation `σ` of every reaction (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reaction_sigma: Option<f64>,
    /// Implicit: the observed reactions.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub reactions: Vec<ReactionSpec>,
    /// Implicit, coupled: CSV of pore pressures after load steps (`step, piezometer,
    /// pore_pressure`; Pa, compression positive).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pore_pressure: Option<PathBuf>,
    /// Implicit, coupled: the standard deviation `σ` of every pore pressure (Pa; default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pore_pressure_sigma: Option<f64>,
    /// Implicit, coupled: the piezometers.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub piezometers: Vec<PiezometerSpec>,
}

/// `[[observations.piezometers]]` (coupled implicit scenes): a piezometer, which reads the
/// pore pressure of the particle nearest to `at` in the initial state (as a run's
/// `[[probes]]` do) and follows it as the soil deforms.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PiezometerSpec {
    /// Its name in the pore-pressure CSV.
    pub name: String,
    /// Where it is (m), `D` numbers.
    pub at: Vec<f64>,
}

/// `[[observations.reactions]]` (implicit scenes): the reaction force of a constraint
/// (`[[constraints]]` of the scene) along one of its prescribed axes.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReactionSpec {
    /// Its name in the reaction CSV.
    pub name: String,
    /// The index of the constraint in the scene's `[[constraints]]`.
    pub constraint: usize,
    /// The axis, a prescribed component of the constraint.
    pub axis: usize,
}

/// `[[observations.stations]]`: where on the floor the deposit depth is measured.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StationSpec {
    /// Its name in the deposit CSV.
    pub name: String,
    /// Its horizontal coordinates: `D − 1` numbers, the axes in order without the vertical
    /// one (the axis of gravity).
    pub at: Vec<f64>,
    /// The width `b` of the smoothing kernel (default: the grid's cell size).
    pub width: Option<f64>,
}

/// `[[observations.monitors]]`: a box `[lo, hi]` with smoothed edges
/// ([`loam_inverse::MonitorBox`]).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MonitorSpec {
    /// Its name in the velocity CSV.
    pub name: String,
    /// Lower corner.
    pub lo: Vec<f64>,
    /// Upper corner.
    pub hi: Vec<f64>,
    /// Width of the smoothed edges (default: the grid's cell size; 0 for a sharp box).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub edge: Option<f64>,
}

/// `[synthetic]`: observations made from a run at the parameters' `truth` values.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SyntheticSpec {
    /// Tracked particles, chosen pseudo-randomly (default 0).
    #[serde(default)]
    pub particles: usize,
    /// Seed of the choice (default 0).
    #[serde(default)]
    pub seed: u64,
    /// Tracked particles given by id, besides the `particles` chosen at random.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ids: Vec<usize>,
    /// Observe the tracked particles and the monitors every this many steps (needed when
    /// there are any).
    pub every: Option<usize>,
    /// First observed step (default `every`).
    pub first: Option<usize>,
    /// The truth run's scene (default the forward scene), relative to the inversion file:
    /// where a velocity field's truth comes from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<PathBuf>,
}

/// `[optimizer]`.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "method", rename_all = "snake_case", deny_unknown_fields)]
pub enum OptimizerSpec {
    /// Adam with the rate `learning_rate · decay_rate^(t / decay_steps)`.
    Adam {
        /// `α₀`.
        learning_rate: f64,
        /// `r` (default 1, no decay).
        #[serde(default = "one")]
        decay_rate: f64,
        /// `T` (default 100).
        #[serde(default = "hundred")]
        decay_steps: f64,
    },
    /// L-BFGS with a backtracking Armijo line search.
    Lbfgs {
        /// Pairs kept (default 10).
        #[serde(default = "ten")]
        memory: usize,
        /// Length of the first step in the optimiser's variables (default 0.1).
        #[serde(default = "tenth")]
        first_step: f64,
    },
    /// Levenberg–Marquardt on the Gauss–Newton model, the Jacobian of the residuals by one
    /// forward-mode dual run per unknown (explicit scenes, at most
    /// [`LEVENBERG_MARQUARDT_UNKNOWNS`] unknowns).
    LevenbergMarquardt {
        /// The first damping `λ` (default 1e-3).
        #[serde(default = "thousandth")]
        damping: f64,
    },
}

/// The most unknowns `method = "levenberg_marquardt"` takes: each costs a dual run per
/// iteration, against one adjoint run for all of them with L-BFGS.
pub const LEVENBERG_MARQUARDT_UNKNOWNS: usize = 16;

impl Default for OptimizerSpec {
    fn default() -> Self {
        Self::Lbfgs {
            memory: ten(),
            first_step: tenth(),
        }
    }
}

fn one() -> f64 {
    1.0
}
fn hundred() -> f64 {
    100.0
}
fn ten() -> usize {
    10
}
fn tenth() -> f64 {
    0.1
}
fn thousandth() -> f64 {
    1e-3
}

/// `[stop]`: stop at the first rule met.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StopSpec {
    /// Iterations (default 100).
    #[serde(default = "hundred_iterations")]
    pub max_iterations: usize,
    /// Stop when the loss is at most this (default 0).
    #[serde(default)]
    pub loss: f64,
    /// Stop when the gradient norm in the optimiser's variables is at most this (default 0).
    #[serde(default)]
    pub gradient: f64,
}

fn hundred_iterations() -> usize {
    100
}

impl Default for StopSpec {
    fn default() -> Self {
        Self {
            max_iterations: hundred_iterations(),
            loss: 0.0,
            gradient: 0.0,
        }
    }
}

/// An inversion ready to run.
pub struct Inversion<const D: usize> {
    /// The inversion file.
    pub path: PathBuf,
    /// What it says.
    pub file: InversionFile,
    /// The scene it names, resolved.
    pub scene_path: PathBuf,
    /// The scene.
    pub scene: Scene,
    /// The parameters' names as written (the first unknowns; the fields' weights follow).
    pub names: Vec<String>,
    /// The optimiser's view of each unknown.
    pub variables: Vec<Variable>,
    /// The loss as a function of the unknowns.
    pub problem: Model<D>,
    /// The parameters' truth values, when every parameter has one.
    pub truth: Option<Vec<f64>>,
    /// The truth run's initial state, against which the velocity fields are measured
    /// (`[synthetic]` with velocity fields).
    pub truth_initial: Option<Particles<f64, D>>,
    /// The first guess of every unknown (the fields' weights: their Glorot initialisation).
    pub initial: Vec<f64>,
    /// The monitors' names.
    pub monitor_names: Vec<String>,
    /// The deposit stations' names.
    pub station_names: Vec<String>,
}

/// Why an inversion could not be set up: the message is printed as is (exit 2).
pub struct Invalid(pub String);

impl From<SceneError> for Invalid {
    fn from(e: SceneError) -> Self {
        Invalid(e.to_string())
    }
}

/// Reads and parses an inversion file (fields only): a scene's ([`InversionFile`]) or element
/// tests' ([`super::element::ElementInversionFile`]).
pub fn read<S: serde::de::DeserializeOwned>(path: &Path) -> Result<S, Invalid> {
    if SceneFormat::from_path(path) != Some(SceneFormat::Toml) {
        return Err(Invalid(format!(
            "{}: unknown inversion file extension; expected `.toml`",
            path.display()
        )));
    }
    let text = std::fs::read_to_string(path).map_err(|e| {
        Invalid(format!(
            "{}: cannot read the inversion file: {e}",
            path.display()
        ))
    })?;
    Ok(loam_scene::parse_file(path, &text, SceneFormat::Toml)?)
}

/// Why an observation file is refused beside `[synthetic]`.
pub const SYNTHETIC_CLASH: &str = "not with [synthetic]: synthetic observations come from the \
                                   truth run (and are written to the output folder)";

/// An invalid-file error listing `issues`, each line starting with the file name.
pub fn invalid(path: &Path, issues: Vec<Issue>) -> Invalid {
    Invalid(
        SceneError::Invalid {
            file: Some(path.to_path_buf()),
            issues,
        }
        .to_string(),
    )
}

/// The scene an inversion file names, resolved against the file's folder, read and
/// validated, and its dimension.
pub fn scene_of(path: &Path, file: &InversionFile) -> Result<(PathBuf, Scene), Invalid> {
    let scene_path = path.parent().unwrap_or(Path::new("")).join(&file.scene);
    let scene = Scene::from_path(&scene_path).map_err(|e| match e {
        SceneError::Read { .. } => invalid(
            path,
            vec![Issue::new(
                "scene",
                format!("cannot read the scene file {}", scene_path.display()),
            )],
        ),
        e => Invalid(e.to_string()),
    })?;
    Ok((scene_path, scene))
}

/// Builds the inversion from the file: the scene's solver inputs, the unknowns and the
/// observations (read from their CSV files, or made by the truth run of `[synthetic]`).
/// Every problem found is reported at once with its field path. `memory` is the adjoint's
/// memory budget in bytes (`--memory`), which chooses the segment length unless the file
/// gives one. A run longer than the step limit, or an inversion whose estimated memory is
/// above the memory limit (`limits`), is refused before a step is run.
pub fn build<const D: usize>(
    path: &Path,
    file: InversionFile,
    scene_path: PathBuf,
    scene: Scene,
    memory: Option<u64>,
    limits: Limits,
) -> Result<Inversion<D>, Invalid> {
    let built: Built<D> = scene.build()?;
    if let SolverPlan::Implicit(_) = built.plan {
        return super::implicit::build(path, file, scene_path, scene, built, memory, limits);
    }
    let mut issues = Vec::new();
    let mut issue = |at: String, msg: String| issues.push(Issue::new(at, msg));
    let config = match (&built.plan, built.explicit_config()) {
        (SolverPlan::Explicit(_), Some(c)) => Some(c),
        _ => {
            issue(
                "scene".into(),
                "the inversion needs an explicit scene".into(),
            );
            None
        }
    };
    let dt = match config.as_ref().map(|c| c.time_step) {
        Some(TimeStep::Fixed { dt }) => dt,
        Some(TimeStep::Adaptive { .. }) => {
            issue(
                "scene".into(),
                "the inversion needs a fixed time step (`solver.time_step = { type = \"fixed\", \
                 dt = .. }`), so that observations fall on steps"
                    .into(),
            );
            f64::NAN
        }
        None => f64::NAN,
    };
    let steps = match (file.steps, file.end_time) {
        (Some(_), Some(_)) => {
            issue(
                "end_time".into(),
                "give `steps` or `end_time`, not both".into(),
            );
            0
        }
        (Some(0), None) => {
            issue("steps".into(), "expected at least 1 step".into());
            0
        }
        (Some(n), None) => n,
        (None, Some(t)) if t.is_finite() && (t / dt).round() >= 1.0 => (t / dt).round() as usize,
        (None, Some(t)) => {
            issue(
                "end_time".into(),
                format!("expected at least one step of {dt} s, got {t}"),
            );
            0
        }
        (None, None) => match built.plan {
            SolverPlan::Explicit(p) => p.fixed_steps().unwrap_or(0),
            SolverPlan::Implicit(_) => 0,
        },
    };
    if file.segment == Some(0) {
        issue("segment".into(), "expected at least 1 step".into());
    }
    if file.segment.is_some() && memory.is_some() {
        issue(
            "segment".into(),
            "gives the segment length, which --memory would choose; drop one of them".into(),
        );
    }
    if file.parameters.is_empty() && file.velocity_field.is_empty() {
        issue(
            "parameters".into(),
            "expected at least one parameter or velocity field".into(),
        );
    }
    // The unknowns.
    let Unknowns {
        mut controls,
        mut variables,
        truth,
    } = unknowns(&file.parameters, &mut issue, |p, issue| {
        explicit_control(p, &built, config.as_ref(), issue)
    });
    // The velocity fields come after the parameters.
    let scalars = controls.len();
    for (i, f) in file.velocity_field.iter().enumerate() {
        let at = |field: &str| format!("velocity_field[{i}].{field}");
        let material = material_index(&f.material, &built, &mut |m| issue(at("material"), m));
        let direction = unit::<D>(&f.direction, &mut |m| issue(at("direction"), m));
        if f.hidden.is_empty() || f.hidden.contains(&0) {
            issue(
                at("hidden"),
                "expected at least one hidden layer, each of at least 1 unit".into(),
            );
            continue;
        }
        if let (Some(material), Some(direction)) = (material, direction) {
            // `material_index` checked the material exists, so it has particles.
            if let Some(field) =
                VelocityField::new(&built.particles, material, direction, &f.hidden, f.seed)
            {
                variables.extend(std::iter::repeat_n(
                    Variable {
                        transform: Transform::Identity,
                        scale: 1.0,
                        bounds: None,
                    },
                    field.mlp.len(),
                ));
                controls.push(Control::VelocityField(field));
            }
        }
    }
    check_velocities(&controls, scalars, &mut issue);
    if let Some(c) = &config {
        let params: Vec<Param> = (controls.iter())
            .filter_map(|c| match c {
                Control::Param(p) => Some(*p),
                _ => None,
            })
            .collect();
        if let Err(e) = ReverseStep::new(c, &params) {
            issue("scene".into(), e.to_string());
        }
    }
    check_optimiser(&file.optimizer, &file.stop, &mut issue);
    if matches!(file.optimizer, OptimizerSpec::LevenbergMarquardt { .. }) {
        let unknowns: usize = controls.iter().map(Control::len).sum();
        if unknowns > LEVENBERG_MARQUARDT_UNKNOWNS {
            issue(
                "optimizer.method".into(),
                format!(
                    "levenberg_marquardt takes one forward-mode run per unknown and iteration, \
                     at most {LEVENBERG_MARQUARDT_UNKNOWNS}; this inversion has {unknowns} (a \
                     velocity field's weights count one each): use lbfgs or adam"
                ),
            );
        }
    }
    for field in file.observations.given_for(Solver::Implicit) {
        issue(
            field,
            "applies to implicit scenes (`[solver] type = \"implicit\"`); an explicit scene \
             observes `tracked` positions, monitor `velocity` or `deposit` depths"
                .into(),
        );
    }
    // Monitors.
    let mut monitor_names: Vec<String> = Vec::new();
    let mut boxes = Vec::new();
    for (i, m) in file.observations.monitors.iter().enumerate() {
        let at = |f: &str| format!("observations.monitors[{i}].{f}");
        if monitor_names.contains(&m.name) {
            issue(at("name"), format!("monitor `{}` is defined twice", m.name));
        }
        monitor_names.push(m.name.clone());
        if m.lo.len() != D || m.hi.len() != D {
            issue(
                at("lo"),
                format!("expected {D} coordinates in `lo` and `hi`"),
            );
            continue;
        }
        if (0..D).any(|a| m.lo[a].partial_cmp(&m.hi[a]) != Some(std::cmp::Ordering::Less)) {
            issue(at("hi"), "expected hi > lo on every axis".into());
        }
        let edge = m.edge.unwrap_or(scene.grid.cell_size);
        if !(edge.is_finite() && edge >= 0.0) {
            issue(at("edge"), format!("expected a width ≥ 0, got {edge}"));
        }
        boxes.push(MonitorBox {
            lo: Vector::from_iterator(m.lo.iter().copied()),
            hi: Vector::from_iterator(m.hi.iter().copied()),
            edge,
        });
    }
    // Deposit stations, on the floor: the vertical is the axis of gravity (the last axis
    // without gravity).
    let g = (built.explicit_config()).map_or_else(Vector::zeros, |c| c.gravity);
    let up = (0..D)
        .rev()
        .max_by(|&a, &b| g[a].abs().total_cmp(&g[b].abs()))
        .filter(|&a| g[a] != 0.0)
        .unwrap_or(D - 1);
    let mut station_names: Vec<String> = Vec::new();
    let mut stations = Vec::new();
    for (i, s) in file.observations.stations.iter().enumerate() {
        let at = |f: &str| format!("observations.stations[{i}].{f}");
        if station_names.contains(&s.name) {
            issue(at("name"), format!("station `{}` is defined twice", s.name));
        }
        station_names.push(s.name.clone());
        let width = s.width.unwrap_or(scene.grid.cell_size);
        if !(width.is_finite() && width > 0.0) {
            issue(
                at("width"),
                format!("expected a positive width, got {width}"),
            );
        }
        if s.at.len() != D - 1 || s.at.iter().any(|x| !x.is_finite()) {
            issue(
                at("at"),
                format!(
                    "expected {} finite horizontal coordinate{} (the axes other than the \
                     vertical, axis {up})",
                    D - 1,
                    if D == 2 { "" } else { "s" }
                ),
            );
            continue;
        }
        let mut horizontal = s.at.iter();
        let point = Vector::from_fn(|a, _| {
            if a == up {
                0.0
            } else {
                *horizontal.next().expect("D − 1 coordinates")
            }
        });
        stations.push(Station { at: point, width });
    }
    let o = &file.observations;
    let weights = (
        o.tracked_weight.unwrap_or(1.0),
        o.velocity_weight.unwrap_or(1.0),
        o.deposit_weight.unwrap_or(1.0),
    );
    for (field, w) in [
        ("tracked_weight", weights.0),
        ("velocity_weight", weights.1),
        ("deposit_weight", weights.2),
    ] {
        if !(w.is_finite() && w >= 0.0) {
            issue(
                format!("observations.{field}"),
                format!("expected a weight ≥ 0, got {w}"),
            );
        }
    }
    check_sources(
        file.synthetic.is_some(),
        &o.files(Solver::Explicit),
        &[
            (
                o.deposit.is_some() && stations.is_empty(),
                "stations",
                "the deposit file needs deposit stations",
            ),
            (
                o.velocity.is_some() && boxes.is_empty(),
                "monitors",
                "the velocity file needs monitor boxes",
            ),
        ],
        &mut issue,
    );
    if let Some(s) = &file.synthetic {
        let watched = s.particles > 0 || !s.ids.is_empty() || !boxes.is_empty();
        match s.every {
            Some(0) => issue("synthetic.every".into(), "expected at least 1 step".into()),
            None if watched => issue(
                "synthetic.every".into(),
                "expected the steps between observations of the tracked particles and \
                 monitors"
                    .into(),
            ),
            Some(every) if watched => check_observed(s, every, steps, &mut issue),
            _ => {}
        }
        check_tracked(s, built.particles.len(), &mut issue);
        if s.particles == 0 && s.ids.is_empty() && boxes.is_empty() && stations.is_empty() {
            issue(
                "synthetic.particles".into(),
                "nothing to observe: track particles, or define monitors or deposit \
                 stations"
                    .into(),
            );
        }
        if !file.velocity_field.is_empty() && s.scene.is_none() {
            issue(
                "synthetic.scene".into(),
                "a velocity field's truth comes from a truth scene: the forward scene with \
                 the truth velocities (e.g. a body's `velocity_file`)"
                    .into(),
            );
        }
        require_truth(&file.parameters, &mut issue);
    }
    let checkpoints = match (file.segment, memory) {
        (Some(k), _) => Checkpoints::Segment(k),
        (None, Some(bytes)) => Checkpoints::Memory(bytes),
        (None, None) => Checkpoints::Least,
    };
    // The length of the runs and the memory, before a step is run or an observation kept.
    if let Some(c) = config.as_ref().filter(|_| steps > 0) {
        let rows = file.synthetic.as_ref().map_or(0, |s| {
            let every = s.every.unwrap_or(steps + 1);
            let per_step = tracked_ids(built.particles.len(), s).len() + boxes.len();
            observed_steps(s, every, steps) * per_step + stations.len()
        });
        let bytes = limits::explicit(c, &built.particles, steps, checkpoints, rows as f64);
        if let Some(msg) = limits.exceeded(steps, bytes) {
            let field = if file.end_time.is_some() {
                "end_time"
            } else {
                "steps"
            };
            issue(field.into(), msg);
        }
    }
    valid(path, issues)?;
    let config = config.expect("an explicit scene");
    let mut problem = Problem {
        config,
        initial: built.particles,
        steps,
        controls,
        objective: Observations::default(),
        checkpoints,
    };
    let mut initial: Vec<f64> = file.parameters.iter().map(|p| p.initial).collect();
    let values = problem.values().map_err(|e| Invalid(e.to_string()))?;
    initial.extend_from_slice(&values[scalars..]);
    let mut truth_initial = None;
    let mut sensors = Observations::with_monitors(boxes);
    sensors.tracked.weight = weights.0;
    sensors.monitors.weight = weights.1;
    sensors.deposit.weight = weights.2;
    sensors.deposit.stations = stations;
    sensors.deposit.up = up;
    problem.objective = match &file.synthetic {
        Some(s) => {
            let truth = truth.as_deref().expect("checked above");
            // The truth run: the truth scene (or the forward scene) with the parameters'
            // truth values; the fields' truth is the truth scene's velocities.
            let truth_problem = match &s.scene {
                Some(scene) => Problem {
                    controls: problem.controls[..scalars].to_vec(),
                    ..truth_scene::<D>(path, scene, &problem)?
                },
                None => problem.clone(),
            };
            let (config, particles) = truth_problem
                .setup(truth)
                .map_err(|e| Invalid(e.to_string()))?;
            if s.scene.is_some() {
                truth_initial = Some(particles.clone());
            }
            // Without `every` nothing but the final deposit is observed.
            let every = s.every.unwrap_or(steps + 1);
            let first = s.first.unwrap_or(every);
            let observed: BTreeSet<usize> = (first..=steps).step_by(every).collect();
            let ids = tracked_ids(particles.len(), s);
            Observations::record(&config, &particles, steps, &observed, &ids, sensors)
                .map_err(|e| Invalid(format!("{}: the truth run: {e}", path.display())))?
        }
        None => {
            let dir = path.parent().unwrap_or(Path::new(""));
            let at = observed::Grid {
                times: None,
                dt,
                steps,
                particles: problem.initial.len(),
                domain: (scene.grid.lo.clone(), scene.grid.hi.clone()),
                cell: scene.grid.cell_size,
            };
            let mut out = sensors;
            let mut errors = Vec::new();
            if let Some(f) = &o.tracked {
                match observed::read_tracked::<D>(&dir.join(f), &at) {
                    Ok(t) => out.tracked.targets = t,
                    Err(msg) => errors.push(Issue::new("observations.tracked", msg)),
                }
            }
            if let Some(f) = &o.velocity {
                match observed::read_velocity::<D>(&dir.join(f), &at, &monitor_names) {
                    Ok(t) => out.monitors.targets = t,
                    Err(msg) => errors.push(Issue::new("observations.velocity", msg)),
                }
            }
            if let Some(f) = &o.deposit {
                match observed::read_deposit(&dir.join(f), &at, &station_names, up) {
                    Ok(t) => out.deposit.targets = t,
                    Err(msg) => errors.push(Issue::new("observations.deposit", msg)),
                }
            }
            valid(path, errors)?;
            out
        }
    };
    Ok(Inversion {
        path: path.to_path_buf(),
        file,
        scene_path,
        scene,
        names: Vec::new(),
        variables,
        problem: Model::Explicit(problem),
        truth,
        truth_initial,
        initial,
        monitor_names,
        station_names,
    }
    .named())
}

/// The truth scene of `[synthetic]`, read and built: `problem` with its configuration and
/// initial state. It must have the forward scene's particles (the same positions).
fn truth_scene<const D: usize>(
    path: &Path,
    scene: &Path,
    problem: &Problem<D, Observations<D>>,
) -> Result<Problem<D, Observations<D>>, Invalid> {
    let at = |msg: String| invalid(path, vec![Issue::new("synthetic.scene", msg)]);
    let file = path.parent().unwrap_or(Path::new("")).join(scene);
    let built: Built<D> = match Scene::from_path(&file) {
        Ok(s) if s.dim() == D => s.build()?,
        Ok(_) => return Err(at(format!("{}: expected a {D}D scene", file.display()))),
        Err(SceneError::Read { .. }) => {
            return Err(at(format!("cannot read the scene file {}", file.display())));
        }
        Err(e) => return Err(e.into()),
    };
    let same = built.particles.len() == problem.initial.len()
        && (built.particles.x.iter().zip(&problem.initial.x)).all(|(a, b)| a == b);
    let config = built.explicit_config().filter(|_| same).ok_or_else(|| {
        at(format!(
            "{}: expected an explicit scene with the forward scene's {} particles",
            file.display(),
            problem.initial.len()
        ))
    })?;
    Ok(Problem {
        config,
        initial: built.particles,
        ..problem.clone()
    })
}

impl<const D: usize> Inversion<D> {
    /// The relative L2 error of each velocity field at `theta` against the truth run's
    /// velocities ([`VelocityField::relative_error`]); empty without a truth.
    pub fn field_errors(&self, theta: &[f64]) -> Vec<f64> {
        let Some(truth) = &self.truth_initial else {
            return Vec::new();
        };
        let Model::Explicit(problem) = &self.problem else {
            return Vec::new();
        };
        (problem.split(theta))
            .filter_map(|(c, w)| match c {
                Control::VelocityField(f) => Some(f.relative_error(w, truth)),
                _ => None,
            })
            .collect()
    }

    fn named(mut self) -> Self {
        self.names = (self.file.parameters.iter())
            .map(|p| match (&p.direction, &p.material) {
                (Some(d), m) => format!(
                    "velocity{}({})",
                    m.as_ref().map_or_else(String::new, |m| format!("[{m}]")),
                    d.iter()
                        .map(|x| format!("{x}"))
                        .collect::<Vec<_>>()
                        .join(",")
                ),
                _ => p.name.clone(),
            })
            .collect();
        self
    }
}

/// The optimiser's view of parameter `p` (transform, scale, bounds), its `initial` and
/// `truth` checked against them and against the [physical range](quantity) of the
/// parameter; each problem is reported by its field name.
pub fn variable(p: &ParameterSpec, issue: &mut dyn FnMut(&str, String)) -> Variable {
    let scale = p.scale.unwrap_or(1.0);
    if !(scale.is_finite() && scale > 0.0) {
        issue("scale", format!("expected a positive number, got {scale}"));
    }
    let bounds = p.bounds.map(|[lo, hi]| (lo, hi));
    if let Some((lo, hi)) = bounds
        && lo.partial_cmp(&hi) != Some(std::cmp::Ordering::Less)
    {
        issue(
            "bounds",
            format!("expected [lo, hi] with lo < hi, got [{lo}, {hi}]"),
        );
    }
    for (field, value) in [("initial", Some(p.initial)), ("truth", p.truth)] {
        let Some(v) = value else { continue };
        if !v.is_finite() {
            issue(field, format!("expected a finite number, got {v}"));
        } else if p.transform == Transform::Softplus && field == "initial" && v <= 0.0 {
            issue(
                field,
                format!("a softplus parameter starts positive; got {v}"),
            );
        } else if p.transform == Transform::Softplus && v < 0.0 {
            // The truth may sit on the softplus's limit (a frictionless segment, μ = 0):
            // the optimiser approaches it, the truth run uses it as it is.
            issue(
                field,
                format!("a softplus parameter is not negative; got {v}"),
            );
        } else if let Some((lo, hi)) = bounds
            && !(lo..=hi).contains(&v)
        {
            let (v, lo, hi) = (readable(v), readable(lo), readable(hi));
            issue(field, format!("{v} is outside the bounds [{lo}, {hi}]"));
        } else if let Some((lo, hi, what)) = quantity(&p.name).range
            && !(lo..=hi).contains(&v)
        {
            let (v, lo, hi) = (readable(v), readable(lo), readable(hi));
            issue(
                field,
                format!("{v} is outside [{lo}, {hi}], the physical range of {what}"),
            );
        }
    }
    Variable {
        transform: p.transform,
        scale,
        bounds,
    }
}

/// `msg` about a parameter name or observation kind, noting when `other` (it fits the
/// `path` solver's scenes instead).
pub fn for_path(msg: &str, other: bool, path: &str) -> String {
    if other {
        format!("{msg} (it applies to {path} scenes, `[solver] type = \"{path}\"`)")
    } else {
        msg.to_owned()
    }
}

/// The tracked particles of `[synthetic]`: `particles` chosen at random among `n` and
/// the given `ids`, ascending, each once.
pub fn tracked_ids(n: usize, s: &SyntheticSpec) -> Vec<usize> {
    let mut ids = loam_inverse::choose(n, s.particles, s.seed);
    ids.extend(&s.ids);
    ids.sort_unstable();
    ids.dedup();
    ids
}

/// What parameter `p` sets on an explicit scene, checked against the scene's configuration
/// `config` (`None` when the scene is not explicit); `None` after an issue.
fn explicit_control<const D: usize>(
    p: &ParameterSpec,
    built: &Built<D>,
    config: Option<&Config<f64, D>>,
    issue: &mut dyn FnMut(&str, String),
) -> Option<Control> {
    if p.name == "velocity" {
        return velocity_control::<D>(p, built, issue);
    }
    velocity_only(p, "", issue);
    match p.name.parse::<Param>() {
        Err(_) if let Ok(ImplicitParam::K0(k)) = p.name.parse::<ImplicitParam>() => {
            let state = config.map(|c| match c.materials.get(k) {
                Some(m) => K0State::of(m, &c.gravity, &built.particles, k),
                None => Err(format!(
                    "no such material: the scene has {}",
                    c.materials.len()
                )),
            });
            match state {
                Some(Err(msg)) => {
                    issue("name", format!("parameter `{}`: {msg}", p.name));
                    None
                }
                _ => Some(Control::K0 { material: k }),
            }
        }
        Ok(param) => match config.map(|c| param.value(c)) {
            Some(Err(e)) => {
                issue("name", e.to_string());
                None
            }
            _ => Some(Control::Param(param)),
        },
        Err(msg) => {
            let other = p.name.parse::<ImplicitParam>().is_ok();
            issue("name", for_path(&msg, other, "implicit"));
            None
        }
    }
}

/// An initial-velocity unknown: its direction (normalised) and material.
fn velocity_control<const D: usize>(
    p: &ParameterSpec,
    built: &Built<D>,
    issue: &mut dyn FnMut(&str, String),
) -> Option<Control> {
    let material = material_index(&p.material, built, &mut |m| issue("material", m))?;
    let Some(d) = &p.direction else {
        issue(
            "direction",
            format!("expected the direction of the velocity, {D} components"),
        );
        return None;
    };
    let direction = unit::<D>(d, &mut |m| issue("direction", m))?;
    Some(Control::InitialVelocity {
        material,
        direction,
    })
}

/// The index of a named material (`Some(None)`: all particles); `None` after an issue.
fn material_index<const D: usize>(
    name: &Option<String>,
    built: &Built<D>,
    issue: &mut dyn FnMut(String),
) -> Option<Option<u32>> {
    let Some(name) = name else { return Some(None) };
    let found = built.material_names.iter().position(|n| n == name);
    if found.is_none() {
        issue(format!(
            "unknown material `{name}`; the scene has {}",
            built.material_names.join(", ")
        ));
    }
    found.map(|m| Some(m as u32))
}

/// `d / |d|`; `None` after an issue when `d` is not a non-zero vector of `D` components.
fn unit<const D: usize>(d: &[f64], issue: &mut dyn FnMut(String)) -> Option<Vec<f64>> {
    let n = d.iter().map(|x| x * x).sum::<f64>().sqrt();
    if d.len() != D || !(n.is_finite() && n > 0.0) {
        issue(format!("expected a non-zero vector of {D} components"));
        return None;
    }
    Some(d.iter().map(|x| x / n).collect())
}

/// Initial velocities and velocity fields on the same particles must be along orthogonal
/// directions, so that each sets its own component. The first `scalars` controls are the
/// `[[parameters]]`, the rest the `[[velocity_field]]`s.
fn check_velocities(controls: &[Control], scalars: usize, issue: &mut dyn FnMut(String, String)) {
    let velocity = |c: &Control| match c {
        Control::InitialVelocity {
            material,
            direction,
        } => Some((*material, direction.clone())),
        Control::VelocityField(f) => Some((f.material, f.direction.clone())),
        Control::Param(_) | Control::K0 { .. } => None,
    };
    for (i, a) in controls.iter().enumerate() {
        for b in &controls[..i] {
            if let (Some((ma, da)), Some((mb, db))) = (velocity(a), velocity(b)) {
                let overlap = ma.is_none() || mb.is_none() || ma == mb;
                let dot: f64 = da.iter().zip(&db).map(|(x, y)| x * y).sum();
                if overlap && dot.abs() > 1e-12 {
                    let at = if i < scalars {
                        format!("parameters[{i}].direction")
                    } else {
                        format!("velocity_field[{}].direction", i - scalars)
                    };
                    issue(
                        at,
                        "two velocities on the same particles need orthogonal directions".into(),
                    );
                }
            }
        }
    }
}

/// Names every parameter without a `truth`, which `[synthetic]` needs.
pub fn require_truth(parameters: &[ParameterSpec], issue: &mut dyn FnMut(String, String)) {
    for (i, p) in parameters.iter().enumerate() {
        if p.truth.is_none() {
            issue(
                format!("parameters[{i}].truth"),
                "[synthetic] needs the truth value of every parameter".into(),
            );
        }
    }
}

/// Checks the optimiser's settings and the stop rules.
pub fn check_optimiser(
    optimizer: &OptimizerSpec,
    stop: &StopSpec,
    issue: &mut dyn FnMut(String, String),
) {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    match *optimizer {
        OptimizerSpec::Adam {
            learning_rate,
            decay_rate,
            decay_steps,
        } => {
            for (field, v) in [
                ("learning_rate", learning_rate),
                ("decay_steps", decay_steps),
            ] {
                if !positive(v) {
                    issue(
                        format!("optimizer.{field}"),
                        format!("expected a positive number, got {v}"),
                    );
                }
            }
            if !(decay_rate > 0.0 && decay_rate <= 1.0) {
                issue(
                    "optimizer.decay_rate".into(),
                    format!("expected 0 < rate ≤ 1, got {decay_rate}"),
                );
            }
        }
        OptimizerSpec::Lbfgs { memory, first_step } => {
            if memory == 0 {
                issue("optimizer.memory".into(), "expected at least 1 pair".into());
            }
            if !positive(first_step) {
                issue(
                    "optimizer.first_step".into(),
                    format!("expected a positive number, got {first_step}"),
                );
            }
        }
        OptimizerSpec::LevenbergMarquardt { damping } => {
            if !positive(damping) {
                issue(
                    "optimizer.damping".into(),
                    format!("expected a positive number, got {damping}"),
                );
            }
        }
    }
    for (field, v) in [("loss", stop.loss), ("gradient", stop.gradient)] {
        if !(v.is_finite() && v >= 0.0) {
            issue(
                format!("stop.{field}"),
                format!("expected a number ≥ 0, got {v}"),
            );
        }
    }
}

/// `v` as a person reads it in a message: as written for 0 and magnitudes in [10⁻⁴, 10⁷),
/// else in scientific notation (`1.5e300`, not 301 digits).
fn readable(v: f64) -> String {
    if v == 0.0 || (1e-4..1e7).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::readable;

    /// A placeholder such as 1.5e300 reads as such, ordinary values as written.
    #[test]
    fn messages_show_numbers_readably() {
        assert_eq!(readable(1.5e300), "1.5e300");
        assert_eq!(readable(-2e-9), "-2e-9");
        assert_eq!(readable(1500.0), "1500");
        assert_eq!(readable(0.25), "0.25");
        assert_eq!(readable(0.0), "0");
    }
}
