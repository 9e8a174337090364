//! `loam gradient` and `loam invert`: back-analysis from an inversion file
//! (`docs/inversion-format.md`).
//!
//! `loam gradient FILE` prints the loss and `dL/dθ` of every parameter at the first guess,
//! by the discrete adjoint; `--check` adds, per parameter, the forward-mode dual derivative,
//! central finite differences at steps a decade apart and a Taylor test; it exits 1 when the
//! adjoint and the dual differ, or when they agree with each other but not with a converged
//! central difference (one that does not change with the step). `loam invert FILE` runs the optimiser,
//! printing one line per iteration, and writes the history, its plots, the recovered scene
//! and a checkpoint that `--resume` continues from. A signal (Ctrl-C) stops it after the
//! iteration in progress, with everything written so far kept.

mod common;
mod element;
mod file;
mod history;
mod implicit;
mod limits;
mod model;
mod observed;
mod study;
mod units;

use crate::Outcome;
use crate::run::{interrupt, writable_folder};
use element::ElementInversion;
use file::{Invalid, Inversion, OptimizerSpec, StopSpec};
use history::{Checkpoint, Entry, History, write_atomic};
pub use limits::Limits;
use loam_core::tensor::Vector;
use loam_inverse::check::Jump;
use loam_inverse::implicit::Identifiability;
use loam_inverse::optimise::{free_gradient_norm, norm};
use loam_inverse::{
    Adam, AdjointError, Control, Evaluation, GaussNewtonModel, Lbfgs, LevenbergMarquardt,
    Optimiser, Variable,
};
use model::{CheckRow, Cost, Model};
use std::cell::{Cell, RefCell};
use std::path::{Path, PathBuf};
use std::time::Instant;
pub use study::{Failure, Study};

/// An inversion file read and set up: a scene's inversion in 2D or 3D, or element tests.
enum SetUp {
    /// A 2D scene's inversion.
    Two(Inversion<2>),
    /// A 3D scene's inversion.
    Three(Inversion<3>),
    /// Element tests ([`element`]: a file with `[[tests]]`).
    Element(ElementInversion),
}

impl SetUp {
    /// Reads the inversion file and sets it up for the scene's dimension (with the adjoint's
    /// memory budget `memory` in bytes, `--memory`, within `limits`), or for element tests.
    fn read(path: &Path, memory: Option<u64>, limits: Limits) -> Result<Self, Invalid> {
        if element::is_element_inversion(path) {
            return Ok(Self::Element(element::build(path, memory)?));
        }
        let f: file::InversionFile = file::read(path)?;
        let (scene_path, scene) = file::scene_of(path, &f)?;
        Ok(match scene.dim() {
            2 => Self::Two(file::build(path, f, scene_path, scene, memory, limits)?),
            _ => Self::Three(file::build(path, f, scene_path, scene, memory, limits)?),
        })
    }

    /// The inversion, whatever it runs.
    fn inverse(&self) -> &dyn Inverse {
        match self {
            Self::Two(i) => i,
            Self::Three(i) => i,
            Self::Element(i) => i,
        }
    }
}

/// Reads the inversion file and sets it up ([`SetUp::read`]), then runs the matching `then`;
/// an invalid file is reported and is [`Outcome::BadInput`].
fn with_inversion(
    path: &Path,
    memory: Option<u64>,
    limits: Limits,
    then2: impl FnOnce(Inversion<2>) -> Outcome,
    then3: impl FnOnce(Inversion<3>) -> Outcome,
    then_element: impl FnOnce(ElementInversion) -> Outcome,
) -> Outcome {
    match SetUp::read(path, memory, limits) {
        Ok(SetUp::Two(i)) => then2(i),
        Ok(SetUp::Three(i)) => then3(i),
        Ok(SetUp::Element(i)) => then_element(i),
        Err(Invalid(msg)) => {
            eprintln!("error: {msg}");
            Outcome::BadInput
        }
    }
}

/// A point evaluated: `L`, `dL/dθ` and, when asked for, the Gauss–Newton matrix in `θ`
/// (row-major).
type Evaluated = (f64, Vec<f64>, Option<Vec<f64>>);

/// What the optimisation loop, its history and its report need of an inversion, whatever it
/// runs: a scene's run, explicit or implicit ([`Inversion`]), or element tests
/// ([`ElementInversion`]).
trait Inverse {
    /// The inversion file.
    fn path(&self) -> &Path;
    /// The named parameters, the first unknowns.
    fn names(&self) -> &[String];
    /// The optimiser's view of every unknown.
    fn variables(&self) -> &[Variable];
    /// The first guess of every unknown.
    fn initial(&self) -> &[f64];
    /// The named parameters' truth values, when every one has one.
    fn truth(&self) -> Option<&[f64]>;
    /// The file as a checkpoint records it (without `[stop]`).
    fn key(&self) -> serde_json::Value;
    /// The optimiser asked for.
    fn optimizer(&self) -> &OptimizerSpec;
    /// When to stop.
    fn stop(&self) -> &StopSpec;
    /// Whether the observations come from a truth run.
    fn synthetic(&self) -> bool;
    /// `L(θ)`, `dL/dθ` and, with `gauss_newton`, the Gauss–Newton matrix in `θ`. Past the
    /// `first` point a run that cannot be completed may count as an infinite loss.
    fn evaluate(
        &self,
        theta: &[f64],
        first: bool,
        gauss_newton: bool,
    ) -> Result<Evaluated, AdjointError>;
    /// What each observed quantity is, with its data `d` and weight `c`
    /// (`L = Σ c (y − d)²`), in the order of [`Inverse::observe`].
    fn observations(&self) -> Vec<(String, f64, f64)>;
    /// The observed quantities `y(θ)`.
    fn observe(&self, theta: &[f64]) -> Result<Vec<f64>, AdjointError>;
    /// `ȳᵀ ∂y/∂θ` for the cotangent `ȳ` of the observed quantities.
    fn vjp(&self, theta: &[f64], cotangent: &[f64]) -> Result<Vec<f64>, AdjointError>;
    /// The velocity fields' relative errors against the truth at `theta` (none by default).
    fn field_errors(&self, _theta: &[f64]) -> Vec<f64> {
        Vec::new()
    }
    /// Writes the synthetic observations into `dir` as files the inversion can read.
    fn write_synthetic(&self, dir: &Path) -> Result<(), String>;
    /// Writes what the inversion recovered at `theta` into `dir` (the recovered scene or
    /// element files, the fitted curves), returning the files' names.
    fn write_recovered(&self, dir: &Path, theta: &[f64]) -> Result<Vec<String>, String>;
    /// Prints what follows the recovered values in the report (identifiability, the velocity
    /// fields' errors).
    fn report_recovered(&self, theta: &[f64]) -> Result<(), AdjointError>;
}

impl<const D: usize> Inverse for Inversion<D> {
    fn path(&self) -> &Path {
        &self.path
    }
    fn names(&self) -> &[String] {
        &self.names
    }
    fn variables(&self) -> &[Variable] {
        &self.variables
    }
    fn initial(&self) -> &[f64] {
        &self.initial
    }
    fn truth(&self) -> Option<&[f64]> {
        self.truth.as_deref()
    }
    fn key(&self) -> serde_json::Value {
        Checkpoint::key(&self.file)
    }
    fn optimizer(&self) -> &OptimizerSpec {
        &self.file.optimizer
    }
    fn stop(&self) -> &StopSpec {
        &self.file.stop
    }
    fn synthetic(&self) -> bool {
        self.file.synthetic.is_some()
    }
    fn evaluate(
        &self,
        theta: &[f64],
        first: bool,
        gauss_newton: bool,
    ) -> Result<Evaluated, AdjointError> {
        if gauss_newton {
            let GaussNewtonModel {
                loss,
                gradient,
                matrix,
            } = self.problem.gauss_newton(theta)?;
            return Ok((loss, gradient, Some(matrix)));
        }
        let (loss, g) = if first {
            self.problem.gradient(theta)?
        } else {
            self.problem.trial_gradient(theta)?
        };
        Ok((loss, g, None))
    }
    fn observations(&self) -> Vec<(String, f64, f64)> {
        self.problem.labelled()
    }
    fn observe(&self, theta: &[f64]) -> Result<Vec<f64>, AdjointError> {
        self.problem.observe(theta)
    }
    fn vjp(&self, theta: &[f64], cotangent: &[f64]) -> Result<Vec<f64>, AdjointError> {
        self.problem.vjp(theta, cotangent)
    }
    fn field_errors(&self, theta: &[f64]) -> Vec<f64> {
        Inversion::field_errors(self, theta)
    }
    fn write_synthetic(&self, dir: &Path) -> Result<(), String> {
        write_synthetic(self, dir)
    }
    fn write_recovered(&self, dir: &Path, theta: &[f64]) -> Result<Vec<String>, String> {
        write_recovered_scene(self, dir, theta)
    }
    fn report_recovered(&self, theta: &[f64]) -> Result<(), AdjointError> {
        if let Model::Implicit { problem, .. } = &self.problem {
            let g = problem.identifiability(theta)?;
            print_identifiability(&self.names, problem.observations.items.len(), &g);
        }
        let errors = self.field_errors(theta);
        for (f, (start, len)) in field_blocks(self).into_iter().enumerate() {
            match errors.get(f) {
                Some(r) => println!(
                    "  velocity_field[{f}]: {len} weights; relative L2 error against the truth {:.3} % (first guess {:.3} %)",
                    100.0 * r,
                    100.0 * self.field_errors(&self.initial)[f],
                ),
                None => println!(
                    "  velocity_field[{f}]: {len} weights, |w| = {:.6}",
                    norm(&theta[start..start + len])
                ),
            }
        }
        Ok(())
    }
}

/// Whether `path` is an inversion file rather than a scene: a TOML file whose top level
/// names a `scene` (or lists element `tests`) and has no `grid`.
pub fn is_inversion(path: &Path) -> bool {
    let table = std::fs::read_to_string(path)
        .ok()
        .and_then(|t| t.parse::<toml::Table>().ok());
    table.is_some_and(|t| {
        (t.contains_key("scene") || t.contains_key("tests")) && !t.contains_key("grid")
    })
}

/// Validates an inversion file, its scene and observations (`loam check` on an inversion
/// file), within `limits`.
pub fn check(path: &Path, limits: Limits) -> Outcome {
    fn report<const D: usize>(inv: Inversion<D>) -> Outcome {
        let observed = match &inv.problem {
            Model::Explicit(p) => format!(
                "{} velocity field(s), {} steps, {} observed step(s)",
                inv.file.velocity_field.len(),
                p.steps,
                p.objective.steps().len()
            ),
            Model::Implicit { problem, .. } => {
                let items = &problem.observations.items;
                let mut steps: Vec<usize> = items.iter().map(|o| o.step).collect();
                steps.dedup();
                format!(
                    "implicit, {}, {} observation(s) after {} step(s)",
                    inv.problem.run_length(),
                    items.len(),
                    steps.len()
                )
            }
        };
        println!(
            "{}: valid {D}D inversion of {}: {} parameter(s), {observed}",
            inv.path.display(),
            inv.scene_path.display(),
            inv.names.len(),
        );
        Outcome::Ok
    }
    with_inversion(path, None, limits, report::<2>, report::<3>, |inv| {
        println!(
            "{}: valid inversion of {} element test(s): {} parameter(s), {} observation(s)",
            inv.path.display(),
            inv.tests.len(),
            inv.names.len(),
            inv.problem.observations()
        );
        Outcome::Ok
    })
}

/// `loam gradient FILE [--check] [--memory SIZE] [--json PATH]`.
pub fn gradient(
    path: &Path,
    check: bool,
    memory: Option<u64>,
    json: Option<&Path>,
    limits: Limits,
) -> Outcome {
    with_inversion(
        path,
        memory,
        limits,
        |i| gradient_dim(i, check, json),
        |i| gradient_dim(i, check, json),
        |i| element::gradient(&i, check, json),
    )
}

/// Writes `loam gradient --json PATH`: the file, `L`, and per named parameter its value and
/// `dL/dθ`, then every unknown's value and `dL/dθ` (`theta`, `gradient`: the named
/// parameters first, then any velocity field's weights), each number written so that it
/// reads back to the same bits.
fn write_gradient_json(
    json: &Path,
    path: &Path,
    loss: f64,
    names: &[String],
    theta: &[f64],
    grad: &[f64],
) -> Result<(), Outcome> {
    let parameters: Vec<serde_json::Value> = (names.iter().zip(theta.iter().zip(grad)))
        .map(
            |(name, (value, g))| serde_json::json!({ "name": name, "value": value, "gradient": g }),
        )
        .collect();
    let doc = serde_json::json!({
        "file": path.display().to_string(),
        "loss": loss,
        "parameters": parameters,
        "theta": theta,
        "gradient": grad,
    });
    let text = serde_json::to_string_pretty(&doc).expect("numbers and strings serialise");
    write_atomic(json, &text).map_err(|e| {
        eprintln!("error: --json {}: {e}", json.display());
        Outcome::Failed
    })
}

/// A failed run, reported.
fn failed(path: &Path, e: AdjointError) -> Outcome {
    eprintln!("error: {}: {e}", path.display());
    outcome_of(&e)
}

/// The outcome of a run that failed with `e`: invalid input (a parameter out of its range,
/// a feature the adjoint lacks, a memory budget too small) or a failed run.
fn outcome_of(e: &AdjointError) -> Outcome {
    match e {
        AdjointError::Parameter { .. }
        | AdjointError::Unsupported { .. }
        | AdjointError::Memory { .. } => Outcome::BadInput,
        _ => Outcome::Failed,
    }
}

fn gradient_dim<const D: usize>(inv: Inversion<D>, check: bool, json: Option<&Path>) -> Outcome {
    let theta = &inv.initial;
    let start = Instant::now();
    let (loss, grad, cost) = match inv.problem.gradient_and_cost(theta) {
        Ok(g) => g,
        Err(e) => return failed(&inv.path, e),
    };
    if let Err(outcome) = first_loss(&inv.path, loss) {
        return outcome;
    }
    let wall = start.elapsed().as_secs_f64();
    println!(
        "{}: L = {loss:.10e} over {}; gradient in {wall:.2} s",
        inv.path.display(),
        inv.problem.run_length()
    );
    if let Cost::Implicit { forward, reverse } = cost {
        println!(
            "  forward run {forward:.2} s, reverse pass {reverse:.2} s (adjoint/forward {:.2})",
            reverse / forward
        );
    }
    if let Cost::Explicit(c) = cost {
        let p = c.phases;
        println!(
            "  forward pass {:.2} s, recomputation {:.2} s, reverse steps {:.2} s; \
             segments of {} steps, {} MB kept (--memory trades memory for recomputation)",
            p.forward,
            p.recomputed,
            p.reverse,
            c.segment,
            c.memory.div_ceil(1_000_000)
        );
    }
    if let Some(json) = json
        && let Err(outcome) = write_gradient_json(json, &inv.path, loss, &inv.names, theta, &grad)
    {
        return outcome;
    }
    let rows = rows(&inv);
    let width = rows.iter().map(|r| r.0.len()).max().unwrap_or(0).max(9);
    println!(
        "  {:width$}  {:>14}  {:>18}",
        "parameter", "value", "dL/dθ (adjoint)"
    );
    for (name, k) in &rows {
        println!(
            "  {name:width$}  {:>14}  {:>18.10e}",
            number(theta[*k], 8),
            grad[*k]
        );
    }
    for (f, (start, len)) in field_blocks(&inv).into_iter().enumerate() {
        println!(
            "  velocity_field[{f}]: {len} weights, |dL/dw| = {:.10e}",
            norm(&grad[start..start + len])
        );
    }
    if let Model::Implicit { problem, .. } = &inv.problem {
        let last = match problem.last_step_gradient(theta) {
            Ok(g) => g,
            Err(e) => return failed(&inv.path, e),
        };
        println!(
            "\n  \"last load step only\" (the reverse pass of the last sub-step, the load path before it held fixed):"
        );
        for (name, k) in &rows {
            println!(
                "  {name:width$}  {:>18.10e}  ({:.4} of the exact dL/dθ)",
                last[*k],
                last[*k] / grad[*k]
            );
        }
        match problem.identifiability(theta) {
            Ok(g) => print_identifiability(&inv.names, problem.observations.items.len(), &g),
            Err(e) => return failed(&inv.path, e),
        }
    }
    if !check {
        return Outcome::Ok;
    }
    println!("\n{}", inv.problem.check_legend());
    print_checks(&inv.path, "adjoint", &rows, &grad, |k| {
        inv.problem.check_one(theta, loss, grad[k], k)
    })
}

/// The table of `loam gradient --check`: per unknown of `rows` (name, index in `θ`) the
/// gradient `grad` (computed as `what` says: `adjoint`, `forward`) against the dual
/// derivative, the central differences and the Taylor remainders that `check_one` measures,
/// then the jumps found. Exits 1 when the gradient and the dual derivative differ beyond
/// round-off, or agree with each other but not with a converged central difference.
fn print_checks(
    path: &Path,
    what: &str,
    rows: &[(String, usize)],
    grad: &[f64],
    mut check_one: impl FnMut(usize) -> Result<CheckRow, AdjointError>,
) -> Outcome {
    let width = rows.iter().map(|r| r.0.len()).max().unwrap_or(0).max(9);
    println!(
        "  {:width$}  {:>18}  {:>18}  {:>9}  {:>18}  {:>9}  {:>5}  {:>10} {:>10} {:>10} {:>10}  {:>5} {:>5} {:>5}",
        "parameter",
        what,
        "dual",
        "rel.diff",
        "central diff.",
        "rel.diff",
        "conv.",
        "r(h)",
        "r(h/2)",
        "r(h/4)",
        "r(h/8)",
        "ratio",
        "ratio",
        "ratio"
    );
    let mut worst = 0.0f64;
    // Unknowns where the gradient and the dual agree but a converged central difference does
    // not: the derivative misses a dependence of the forward run on the parameter.
    let mut missed = Vec::new();
    // What was found of jumps of the loss, one line per unknown, printed after the table.
    let mut jumps = Vec::new();
    for (name, k) in rows {
        let k = *k;
        let row = match check_one(k) {
            Ok(row) => row,
            Err(e) => return failed(path, e),
        };
        let rel = |a: f64| (a - grad[k]).abs() / grad[k].abs().max(1e-300);
        worst = worst.max(rel(row.dual));
        let conv = match row.converged {
            Some((step, _)) => format!("{step:.0e}"),
            None => "no".into(),
        };
        let (fd, fd_rel) = match row.difference {
            Some(fd) => (format!("{fd:.10e}"), format!("{:.1e}", rel(fd))),
            None => ("(jump)".into(), "-".into()),
        };
        print!(
            "  {name:width$}  {:>18.10e}  {:>18.10e}  {:>9.1e}  {fd:>18}  {fd_rel:>9}  {conv:>5} ",
            grad[k],
            row.dual,
            rel(row.dual)
        );
        for x in row.remainders {
            print!(" {x:>10.3e}");
        }
        print!(" ");
        for w in row.remainders.windows(2) {
            print!(" {:>5.2}", w[0] / w[1]);
        }
        println!();
        if row.misses_the_difference() {
            missed.push(format!(
                "{name} (dual {:.6e}, central difference {fd})",
                row.dual
            ));
        }
        for j in &row.jumps {
            jumps.push(jump_note(name, j, &row));
        }
        if let Some(note) = failed_note(name, &row) {
            jumps.push(note);
        }
    }
    for note in &jumps {
        println!("{note}");
    }
    // The gradient and the dual run are the same derivative of the same discrete map:
    // anything above round-off (1e-8 leaves room for losses summed over many steps) is a bug.
    if worst > 1e-8 {
        eprintln!("error: the {what} and the dual derivative differ by {worst:.1e} (relative)");
        return Outcome::Failed;
    }
    if !missed.is_empty() {
        eprintln!(
            "error: the {what} and the dual derivative agree but differ from a converged \
             central difference by more than {:.0e} (relative): {}",
            model::DIFFERENCE_TOLERANCE,
            missed.join("; ")
        );
        return Outcome::Failed;
    }
    Outcome::Ok
}

/// What `loam gradient --check` says of a jump `j` of the loss along the unknown `name`: where
/// it is, that the differences across it are left out and where the Taylor test starts.
fn jump_note(name: &str, j: &Jump, row: &model::CheckRow) -> String {
    let differences = match row.difference {
        Some(_) => "the central differences whose stencil reaches it are left out",
        None => "every central difference tried reaches it, so none is shown",
    };
    let taylor = if j.straddled_by(0.0, row.taylor_step) {
        "every Taylor step reaches it too".to_owned()
    } else {
        format!(
            "the Taylor test starts at h = {:.1e}, short of the jumps",
            row.taylor_step
        )
    };
    format!(
        "  jump along {name}: L changes by {:.3e} between θ {:+.6e} and θ {:+.6e} (the adjoint \
         and the dual give the slope of the smooth piece at θ); {differences}; {taylor}",
        j.size, j.lo, j.hi
    )
}

/// What `loam gradient --check` says of the perturbed runs along `name` that failed: where,
/// and that the checks that needed them are left out.
fn failed_note(name: &str, row: &model::CheckRow) -> Option<String> {
    let (first, last) = (row.failed.first()?, row.failed.last()?);
    let taylor = if row.remainders.iter().all(|r| r.is_finite()) {
        format!("the Taylor test starts at h = {:.1e}", row.taylor_step)
    } else {
        "no Taylor step ran clear of them".to_owned()
    };
    Some(format!(
        "  along {name}: {} perturbed run(s) failed (θ {first:+.3e} … {last:+.3e}: the run does not \
         converge or goes unstable there on the sub-steps of the run at θ); the checks that \
         need them are left out; {taylor}",
        row.failed.len()
    ))
}

/// The unknowns `loam gradient` prints, with their index in `θ`: every named parameter, and
/// of each velocity field the first, the middle and the last weight (the output bias).
fn rows<const D: usize>(inv: &Inversion<D>) -> Vec<(String, usize)> {
    let mut rows: Vec<(String, usize)> = inv.names.iter().cloned().zip(0..).collect();
    for (f, (start, len)) in field_blocks(inv).into_iter().enumerate() {
        for i in [0, len / 2, len - 1] {
            rows.push((format!("velocity_field[{f}].w[{i}]"), start + i));
        }
    }
    rows
}

/// Where each velocity field's weights start in `θ`, and how many there are.
fn field_blocks<const D: usize>(inv: &Inversion<D>) -> Vec<(usize, usize)> {
    let mut start = 0;
    let mut out = Vec::new();
    for c in inv.problem.controls() {
        if let Control::VelocityField(f) = c {
            out.push((start, f.mlp.len()));
        }
        start += c.len();
    }
    out
}

/// The output folder of `loam invert FILE [--out DIR]`: `DIR`, else `out/<FILE's stem>`.
pub fn output_folder(path: &Path, out: Option<&Path>) -> PathBuf {
    out.map_or_else(
        || {
            let stem = path
                .file_stem()
                .map_or("inversion".into(), |s| s.to_string_lossy().into_owned());
            PathBuf::from("out").join(stem)
        },
        Path::to_path_buf,
    )
}

/// `loam invert FILE [--out DIR] [--resume] [--memory SIZE]`.
pub fn invert(
    path: &Path,
    out: Option<&Path>,
    resume: bool,
    memory: Option<u64>,
    limits: Limits,
) -> Outcome {
    let dir = output_folder(path, out);
    with_inversion(
        path,
        memory,
        limits,
        |i| invert_with(&i, &dir, resume),
        |i| invert_with(&i, &dir, resume),
        |i| invert_with(&i, &dir, resume),
    )
}

/// The optimiser an inversion file asks for, for `n` unknowns.
fn optimiser(spec: &OptimizerSpec, n: usize) -> Optimiser {
    match *spec {
        OptimizerSpec::Adam {
            learning_rate,
            decay_rate,
            decay_steps,
        } => Optimiser::Adam(Adam::new(n, learning_rate, decay_rate, decay_steps)),
        OptimizerSpec::Lbfgs { memory, first_step } => {
            Optimiser::Lbfgs(Lbfgs::new(memory, first_step))
        }
        OptimizerSpec::LevenbergMarquardt { damping } => {
            Optimiser::LevenbergMarquardt(LevenbergMarquardt::new(damping))
        }
    }
}

/// Runs the optimiser of `inv` to a stop rule, writing the history and the checkpoint into
/// `dir` after every iteration (from the checkpoint there with `resume`), then the report.
fn invert_with(inv: &dyn Inverse, dir: &Path, resume: bool) -> Outcome {
    let started = Instant::now();
    let vars = inv.variables();
    let key = inv.key();
    let physical =
        |z: &[f64]| -> Vec<f64> { z.iter().zip(vars).map(|(z, v)| v.physical(*z)).collect() };
    // Runs of the loss this iteration, and dL/dθ at the last point evaluated (for the history).
    let runs = Cell::new(0usize);
    let last_physical = RefCell::new(Vec::new());
    // z ↦ (L, ∇_z L) with ∇_z L = dL/dθ · dθ/dz.
    // After the first point, a trial point whose run stops may count as an infinite loss.
    let first_done = Cell::new(resume);
    let gauss_newton = matches!(inv.optimizer(), OptimizerSpec::LevenbergMarquardt { .. });
    let mut evaluate = |z: &[f64]| -> Result<Evaluation, AdjointError> {
        runs.set(runs.get() + 1);
        let theta = physical(z);
        let slopes: Vec<f64> = z.iter().zip(vars).map(|(z, v)| v.slope(*z)).collect();
        let (loss, g, matrix) = inv.evaluate(&theta, !first_done.get(), gauss_newton)?;
        first_done.set(true);
        // The Gauss–Newton matrix in z: Sᵀ H S with S = diag(dθ/dz).
        let n = z.len();
        let curvature = matrix.map(|m| {
            (0..n * n)
                .map(|i| m[i] * slopes[i / n] * slopes[i % n])
                .collect()
        });
        let gz = g.iter().zip(&slopes).map(|(g, s)| g * s).collect();
        *last_physical.borrow_mut() = g;
        Ok(Evaluation {
            x: z.to_vec(),
            loss,
            gradient: gz,
            curvature,
        })
    };
    let project = |z: &mut [f64]| z.iter_mut().zip(vars).for_each(|(z, v)| *z = v.project(*z));
    let (mut optimiser, mut current, mut history) = if resume {
        let file = dir.join(Checkpoint::NAME);
        let cp: Checkpoint = match std::fs::read_to_string(&file)
            .map_err(|e| e.to_string())
            .and_then(|t| serde_json::from_str(&t).map_err(|e| e.to_string()))
        {
            Ok(cp) => cp,
            Err(e) => {
                eprintln!("error: --resume: cannot read {}: {e}", file.display());
                return Outcome::BadInput;
            }
        };
        if cp.file != key {
            eprintln!(
                "error: --resume: {} differs from the inversion the checkpoint in {} was made \
                 for (only [stop] may change); start afresh without --resume",
                inv.path().display(),
                dir.display()
            );
            return Outcome::BadInput;
        }
        println!(
            "{}: resuming from iteration {} (L = {:.6e}) in {}",
            inv.path().display(),
            cp.history.entries.last().map_or(0, |e| e.iteration),
            cp.current.loss,
            dir.display()
        );
        (cp.optimiser, cp.current, cp.history)
    } else {
        // An output folder that cannot be written is invalid input, as for `loam run`.
        if let Err(e) = writable_folder(dir) {
            eprintln!(
                "error: --out: cannot write to the output folder {}: {e}",
                dir.display()
            );
            return Outcome::BadInput;
        }
        if inv.synthetic()
            && let Err(e) = inv.write_synthetic(dir)
        {
            eprintln!("error: {e}");
            return Outcome::Failed;
        }
        let mut z0: Vec<f64> = (inv.initial().iter())
            .zip(vars)
            .map(|(t, v)| v.internal(*t))
            .collect();
        project(&mut z0);
        let first = match evaluate(&z0) {
            Ok(e) => e,
            Err(e) => return failed(inv.path(), e),
        };
        if let Err(outcome) = first_loss(inv.path(), first.loss) {
            return outcome;
        }
        let history = History {
            names: inv.names().to_vec(),
            truth: inv.truth().map(<[f64]>::to_vec),
            entries: vec![entry(
                inv,
                0,
                &first,
                &physical(&first.x),
                &last_physical.borrow(),
                runs.get(),
                started,
            )],
        };
        (optimiser(inv.optimizer(), vars.len()), first, history)
    };
    if let Err(e) = interrupt::install() {
        eprintln!("error: {e}");
        return Outcome::Failed;
    }
    let stop = inv.stop();
    let mut fresh = !resume;
    // Set when the optimiser stops without a decrease away from a minimum.
    let mut stalled = false;
    let reason = loop {
        let last = history.entries.last().expect("the first entry").clone();
        let checkpoint = Checkpoint {
            file: key.clone(),
            optimiser: optimiser.clone(),
            current: current.clone(),
            history: history.clone(),
        };
        let saved = history.write(dir).and_then(|()| {
            let text = serde_json::to_string(&checkpoint).expect("the checkpoint serialises");
            write_atomic(&dir.join(Checkpoint::NAME), &text)
        });
        if let Err(e) = saved {
            eprintln!("error: {e}");
            return Outcome::Failed;
        }
        // Printed after it is saved: a line on the screen is an iteration on disk, also when
        // the reader of stdout goes away (SIGPIPE) or Ctrl-C follows.
        if fresh {
            print_line(inv, &history, &last);
        }
        fresh = true;
        if last.iteration >= stop.max_iterations {
            break format!("reached stop.max_iterations = {}", stop.max_iterations);
        }
        if last.loss <= stop.loss {
            break format!("loss {:.3e} ≤ stop.loss = {:e}", last.loss, stop.loss);
        }
        if last.gradient_norm <= stop.gradient {
            break format!(
                "gradient norm {:.3e} ≤ stop.gradient = {:e}",
                last.gradient_norm, stop.gradient
            );
        }
        if interrupt::requested() {
            eprintln!(
                "{}: interrupted after iteration {}; the history and the checkpoint are kept in \
                 {}: `loam invert {} --out {} --resume` continues",
                inv.path().display(),
                last.iteration,
                dir.display(),
                inv.path().display(),
                dir.display()
            );
            return Outcome::Interrupted;
        }
        let t0 = Instant::now();
        runs.set(0);
        match optimiser.iterate(&current, &mut evaluate, &project) {
            Ok(Some(next)) => {
                let theta = physical(&next.x);
                let e = entry(
                    inv,
                    last.iteration + 1,
                    &next,
                    &theta,
                    &last_physical.borrow(),
                    runs.get(),
                    t0,
                );
                history.entries.push(e);
                current = next;
            }
            Ok(None) => {
                let free = free_gradient_norm(&current, &project);
                let verdict = no_decrease(&history.entries[0], current.loss, free);
                stalled = verdict.is_err();
                break verdict.unwrap_or_else(|e| e);
            }
            Err(e) => return failed(inv.path(), e),
        }
    };
    match finish(inv, dir, &history, &current, &reason, started) {
        Outcome::Ok if stalled => {
            eprintln!(
                "error: {}: the optimiser stopped away from a minimum (the results are \
                 written, but are not a fit): {reason}",
                inv.path().display()
            );
            Outcome::Failed
        }
        outcome => outcome,
    }
}

/// How far below the first the gradient over the free variables must have fallen for a
/// point where no step decreases the loss to be a minimum: a line search stalls on round-off
/// only where the predicted decrease `|g|²/H` is at the loss's last digits, which for a
/// quadratic loss is about `10⁻⁸ |g₀| √(L/L₀)`; a gradient still above `10⁻⁶ |g₀|` is a
/// loss the optimiser cannot follow (a jump the gradient does not see, a wrong gradient).
const MINIMUM_GRADIENT: f64 = 1e-6;

/// How far below the first a loss is a fit to round-off wherever the optimiser stops.
const MINIMUM_LOSS: f64 = 1e-12;

/// Why the optimiser stopped when no step found a decrease at a point of loss `loss` and
/// free gradient norm `free` ([`free_gradient_norm`]): `Ok` at a minimum to the loss's
/// precision (the free gradient has fallen to [`MINIMUM_GRADIENT`] of the first one, or the
/// loss to [`MINIMUM_LOSS`] of the first), `Err` elsewhere, saying so.
fn no_decrease(first: &Entry, loss: f64, free: f64) -> Result<String, String> {
    if free <= MINIMUM_GRADIENT * first.gradient_norm || loss <= MINIMUM_LOSS * first.loss {
        return Ok(format!(
            "no step found a decrease: a minimum to the loss's precision (|g| {:.3e} → {free:.3e})",
            first.gradient_norm
        ));
    }
    Err(format!(
        "no step found a decrease at L = {loss:.6e} (first {:.6e}) with |g| = {free:.3e} \
         (first {:.3e}): not a minimum. The loss may jump where the gradient does not see it \
         (a particle crossing a sharp monitor box, a contact switch), or the gradient may be \
         wrong: `loam gradient --check` at these values shows which",
        first.loss, first.gradient_norm
    ))
}

/// `v` with `digits` decimals, in scientific notation where fixed decimals would hide its
/// digits (a hydraulic conductivity of 1e-8 m/s) or run long (|v| ≥ 1e9).
pub(crate) fn number(v: f64, digits: usize) -> String {
    if v == 0.0 || (1e-3..1e9).contains(&v.abs()) {
        format!("{v:.digits$}")
    } else {
        format!("{v:.digits$e}")
    }
}

/// A loss that is not finite at the first guess: invalid input (exit 2), naming the file.
fn first_loss(path: &Path, loss: f64) -> Result<(), Outcome> {
    if loss.is_finite() {
        return Ok(());
    }
    eprintln!(
        "error: {}: the loss at the first guess is {loss}: the observations cannot be \
         compared with the run (values in another unit, or far from anything the scene \
         produces), or the run at the first guesses fails; check both",
        path.display()
    );
    Err(Outcome::BadInput)
}

/// The history entry of an evaluated point: the named parameters' values and derivatives,
/// the velocity fields' errors.
fn entry(
    inv: &dyn Inverse,
    iteration: usize,
    at: &Evaluation,
    theta: &[f64],
    dl: &[f64],
    runs: usize,
    since: Instant,
) -> Entry {
    let n = inv.names().len();
    Entry {
        iteration,
        loss: at.loss,
        gradient_norm: norm(&at.gradient),
        parameters: theta[..n].to_vec(),
        gradient: dl[..n].to_vec(),
        field_errors: inv.field_errors(theta),
        evaluations: runs,
        seconds: since.elapsed().as_secs_f64(),
    }
}

/// One progress line: iteration, loss, gradient norm, parameters, seconds per iteration and
/// the time left to `stop.max_iterations` at that pace.
fn print_line(inv: &dyn Inverse, history: &History, e: &Entry) {
    let timed: Vec<f64> = history.entries.iter().skip(1).map(|e| e.seconds).collect();
    let per = if timed.is_empty() {
        e.seconds
    } else {
        timed.iter().sum::<f64>() / timed.len() as f64
    };
    let left = inv.stop().max_iterations.saturating_sub(e.iteration) as f64 * per;
    let params: Vec<String> = (inv.names().iter().zip(&e.parameters))
        .map(|(n, v)| format!("{n} = {}", number(*v, 6)))
        .chain(
            (e.field_errors.iter().enumerate())
                .map(|(k, r)| format!("velocity_field[{k}] error {:.2} %", 100.0 * r)),
        )
        .collect();
    println!(
        "iter {:>4}  L {:.6e}  |g| {:.3e}  {}  {:.2} s/it  ETA ≤ {:.0} s",
        e.iteration,
        e.loss,
        e.gradient_norm,
        params.join("  "),
        per,
        left
    );
}

/// Writes the synthetic observations as CSV files in `dir` (the format `[observations]`
/// reads).
fn write_synthetic<const D: usize>(inv: &Inversion<D>, dir: &Path) -> Result<(), String> {
    let err = |f: &Path, e: std::io::Error| format!("cannot write {}: {e}", f.display());
    let o = match &inv.problem {
        Model::Explicit(p) => &p.objective,
        Model::Implicit {
            problem,
            piezometers,
            ..
        } => {
            let implicit::Targets {
                displacements,
                reactions,
                pressures,
            } = implicit::targets::<D>(&inv.file, &problem.observations, piezometers);
            if !pressures.is_empty() {
                let f = dir.join("pore_pressure.csv");
                let names: Vec<String> = (inv.file.observations.piezometers.iter())
                    .map(|p| p.name.clone())
                    .collect();
                let columns = ["pore_pressure", "", ""];
                observed::write(&f, &pressures, "piezometer", columns, Some(&names))
                    .map_err(|e| err(&f, e))?;
            }
            if !displacements.is_empty() {
                let f = dir.join("displacement.csv");
                observed::write(&f, &displacements, "id", ["ux", "uy", "uz"], None)
                    .map_err(|e| err(&f, e))?;
            }
            if !reactions.is_empty() {
                let f = dir.join("reaction.csv");
                let names: Vec<String> = (inv.file.observations.reactions.iter())
                    .map(|r| r.name.clone())
                    .collect();
                observed::write(&f, &reactions, "reaction", ["force", "", ""], Some(&names))
                    .map_err(|e| err(&f, e))?;
            }
            return Ok(());
        }
    };
    if !o.tracked.targets.is_empty() {
        let f = dir.join("tracked.csv");
        observed::write(&f, &o.tracked.targets, "id", ["x", "y", "z"], None)
            .map_err(|e| err(&f, e))?;
    }
    if !o.monitors.targets.is_empty() {
        let f = dir.join("velocity.csv");
        observed::write(
            &f,
            &o.monitors.targets,
            "monitor",
            ["vx", "vy", "vz"],
            Some(&inv.monitor_names),
        )
        .map_err(|e| err(&f, e))?;
    }
    if !o.deposit.targets.is_empty() {
        let f = dir.join("deposit.csv");
        let rows: observed::Targets<1> = (o.deposit.targets.iter())
            .map(|(&s, r)| (s, r.iter().map(|&(i, h)| (i, Vector::from([h]))).collect()))
            .collect();
        observed::write(
            &f,
            &rows,
            "station",
            ["depth", "", ""],
            Some(&inv.station_names),
        )
        .map_err(|e| err(&f, e))?;
    }
    Ok(())
}

/// The end of an inversion: plots, what it recovered ([`Inverse::write_recovered`]), and
/// the recovered values against the truth when known.
fn finish(
    inv: &dyn Inverse,
    dir: &Path,
    history: &History,
    current: &Evaluation,
    reason: &str,
    started: Instant,
) -> Outcome {
    let theta: Vec<f64> = (current.x.iter())
        .zip(inv.variables())
        .map(|(z, v)| v.physical(*z))
        .collect();
    let written = history
        .plot(dir)
        .and_then(|()| inv.write_recovered(dir, &theta));
    let files = match written {
        Ok(files) => files,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::Failed;
        }
    };
    let last = history.entries.last().map_or(0, |e| e.iteration);
    println!(
        "{}: stopped after {last} iterations ({reason}); L = {:.6e}; {:.1} s wall",
        inv.path().display(),
        current.loss,
        started.elapsed().as_secs_f64()
    );
    let initial = inv.initial();
    for (k, name) in inv.names().iter().enumerate() {
        match inv.truth() {
            Some(t) => println!(
                "  {name}: {} (truth {}, error {:.3e}, first guess {})",
                number(theta[k], 6),
                number(t[k], 6),
                theta[k] - t[k],
                number(initial[k], 6)
            ),
            None => println!(
                "  {name}: {} (first guess {})",
                number(theta[k], 6),
                number(initial[k], 6)
            ),
        }
    }
    if let Err(e) = inv.report_recovered(&theta) {
        return failed(inv.path(), e);
    }
    let mut plots = vec!["history_loss.png".to_owned()];
    if !inv.names().is_empty() {
        plots.push("history_parameters.png".into());
    }
    if !inv.field_errors(&theta).is_empty() {
        plots.push("history_field_error.png".into());
    }
    println!(
        "  wrote {}/history.csv, history.json, {}",
        dir.display(),
        plots
            .into_iter()
            .chain(files)
            .collect::<Vec<_>>()
            .join(", ")
    );
    Outcome::Ok
}

/// Writes the recovered scene of a scene's inversion at `theta` (and with velocity fields
/// every particle's recovered initial velocity); returns the files' names.
fn write_recovered_scene<const D: usize>(
    inv: &Inversion<D>,
    dir: &Path,
    theta: &[f64],
) -> Result<Vec<String>, String> {
    let material_names: Vec<String> = inv.scene.materials.iter().map(|m| m.name.clone()).collect();
    let scene_name = inv
        .scene_path
        .file_name()
        .map_or("scene.toml".into(), |n| n.to_string_lossy().into_owned());
    let recovered = format!("recovered_{scene_name}");
    let velocity_file = (!field_blocks(inv).is_empty()).then(|| Path::new(VELOCITY_FILE));
    let mut files = Vec::new();
    if velocity_file.is_some() {
        write_velocities(inv, theta, &dir.join(VELOCITY_FILE))?;
        files.push(VELOCITY_FILE.to_owned());
    }
    let mut scene = inv.scene.clone();
    match &inv.problem {
        Model::Explicit(p) => {
            history::set_controls(&mut scene, &p.controls, theta, &material_names);
        }
        Model::Implicit { scene_params, .. } => {
            history::set_implicit(&mut scene, scene_params, theta);
            if let Some(steps) = inv.file.steps {
                scene.solver.load_steps = Some(steps);
            }
        }
    }
    let text = history::recovered_scene(scene, &inv.names, theta, &inv.scene_path, velocity_file)?;
    write_atomic(&dir.join(&recovered), &text)?;
    files.push(recovered);
    Ok(files)
}

/// Prints a Gauss–Newton analysis `g` of `residuals` observations
/// ([`Identifiability`]): the eigenvalues and condition number of `JᵀJ` in relative
/// parameter changes, each parameter's relative standard deviation under unit noise (`σ`
/// of the observations) and the correlations of the estimates.
fn print_identifiability(names: &[String], residuals: usize, g: &Identifiability) {
    let eigen: Vec<String> = g.eigenvalues.iter().map(|e| format!("{e:.4e}")).collect();
    println!(
        "\n  identifiability (Gauss–Newton JᵀJ of the {residuals} residuals (m − d)/σ, θ scaled by its value):\n  \
         eigenvalues {}; condition number {:.4e}",
        eigen.join(", "),
        g.condition
    );
    let width = names.iter().map(String::len).max().unwrap_or(0).max(9);
    print!("  {:width$}  {:>14}", "parameter", "rel. std");
    for n in names {
        print!("  {:>12}", format!("corr. {}", short(n)));
    }
    println!();
    for (i, n) in names.iter().enumerate() {
        match (&g.relative_std, &g.correlation) {
            (Some(std), Some(c)) => {
                print!("  {n:width$}  {:>14.4e}", std[i]);
                for j in 0..names.len() {
                    print!("  {:>12.6}", c[(i, j)]);
                }
                println!();
            }
            _ => println!("  {n:width$}  {:>14}", "∞ (JᵀJ singular)"),
        }
    }
}

/// The last field of a parameter name (`materials[0].young` → `young`).
fn short(name: &str) -> &str {
    name.rsplit('.').next().unwrap_or(name)
}

/// The file of every particle's recovered initial velocity (with velocity fields).
const VELOCITY_FILE: &str = "recovered_velocity.csv";

/// Writes every particle's initial velocity at `theta` in the scene's `velocity_file` format
/// (positions, then velocities, in particle order).
fn write_velocities<const D: usize>(
    inv: &Inversion<D>,
    theta: &[f64],
    file: &Path,
) -> Result<(), String> {
    let Model::Explicit(problem) = &inv.problem else {
        return Err("velocity fields are unknowns of explicit scenes only".into());
    };
    let (_, particles) = problem.setup(theta).map_err(|e| e.to_string())?;
    let axes = ["x", "y", "z"];
    let mut text = format!(
        "# the initial velocities recovered by `loam invert` from {}\n{}, {}\n",
        inv.path.display(),
        axes[..D].join(", "),
        axes[..D]
            .iter()
            .map(|a| format!("v{a}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    for p in 0..particles.len() {
        let row: Vec<String> = (particles.x[p].iter().chain(particles.v[p].iter()))
            .map(|v| format!("{v:e}"))
            .collect();
        text.push_str(&row.join(", "));
        text.push('\n');
    }
    write_atomic(file, &text)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first entry of a history with loss `loss` and gradient norm `gradient`.
    fn first(loss: f64, gradient: f64) -> Entry {
        Entry {
            iteration: 0,
            loss,
            gradient_norm: gradient,
            parameters: vec![0.5],
            gradient: vec![gradient],
            field_errors: Vec::new(),
            evaluations: 1,
            seconds: 0.1,
        }
    }

    /// A stall halfway down, with the gradient a tenth of the first (a loss that jumps where
    /// its gradient does not see it) is not a minimum; a loss fitted to round-off, a gradient
    /// down by 10⁷ and a minimum on a bound (no free gradient) are.
    #[test]
    fn a_stall_far_from_a_small_loss_or_gradient_is_not_a_minimum() {
        let f = first(21.6, 19.5);
        let err = no_decrease(&f, 0.497, 1.95).unwrap_err();
        assert!(
            err.contains("not a minimum") && err.contains("--check"),
            "{err}"
        );
        assert!(no_decrease(&f, 4.6e-24, 1e-3).is_ok());
        assert!(no_decrease(&f, 0.2, 1.95e-6).is_ok());
        assert!(no_decrease(&f, 0.2, 0.0).is_ok());
    }
}
