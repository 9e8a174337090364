//! An inversion file on element tests (`[[tests]]` in place of `scene`): material constants
//! fitted to laboratory curves (`docs/inversion-format.md`, *Element tests*).
//!
//! Each test names an element-test file (`loam material`), the `σ` of every quantity it
//! fits (`q`, `p` in kPa, `volumetric_strain`, `void_ratio`) and, unless `[synthetic]` makes
//! them from the truth values, a CSV of measured points. The parameters are constants of
//! the tests' material, `material.<constant>`, set in every test. The loss is
//! `½ Σ ((m − d)/σ)²` over every observed point, `m` the test's curve interpolated in axial
//! strain ([`loam_inverse::element`]); the default optimiser is Levenberg–Marquardt on the
//! residuals' Jacobian from forward-mode duals.

use super::file::{
    Invalid, OptimizerSpec, ParameterSpec, SYNTHETIC_CLASH, StopSpec, check_optimiser, invalid,
    require_truth, variable,
};
use super::history::{self, Checkpoint, write_atomic};
use super::model::{self, Along};
use super::{Inverse, first_loss, print_checks, print_identifiability};
use crate::Outcome;
use loam_inverse::check::{Convergence, Difference, richardson};
use loam_inverse::element::{
    CurvePoint, ElementProblem, LabTest, Measure, Observed, interpolated, on_path,
};
use loam_inverse::{AdjointError, MaterialField, Variable};
use loam_scene::element::ElementTest;
use loam_scene::{Issue, SceneError};
use loam_verification::{Series, write_plot};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// An inversion file on element tests.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ElementInversionFile {
    /// The element tests and what is observed of each.
    pub tests: Vec<TestSpec>,
    /// The unknowns: constants of the tests' material.
    #[serde(default)]
    pub parameters: Vec<ParameterSpec>,
    /// Make the observations from the curves at the parameters' `truth` values.
    pub synthetic: Option<ElementSyntheticSpec>,
    /// The optimiser (default Levenberg–Marquardt).
    pub optimizer: Option<OptimizerSpec>,
    /// When to stop.
    #[serde(default)]
    pub stop: StopSpec,
}

/// `[[tests]]`: one element test.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TestSpec {
    /// The element-test file (`loam material`), relative to the inversion file.
    pub element: PathBuf,
    /// CSV of measured points (`axial_strain` and a column per fitted quantity), relative to
    /// the inversion file; not with `[synthetic]`.
    pub data: Option<PathBuf>,
    /// The standard deviation of each fitted quantity; the quantities given one are fitted.
    pub sigma: SigmaSpec,
}

/// `tests[i].sigma`: `σ` of the fitted quantities, in the units of the data files.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SigmaSpec {
    /// Of the deviator stress `q` (kPa).
    pub q: Option<f64>,
    /// Of the mean effective stress `p′` (kPa).
    pub p: Option<f64>,
    /// Of the volumetric strain (a fraction).
    pub volumetric_strain: Option<f64>,
    /// Of the void ratio.
    pub void_ratio: Option<f64>,
}

impl SigmaSpec {
    /// The given `σ` of `m`, as written (kPa for a stress).
    fn of(&self, m: Measure) -> Option<f64> {
        match m {
            Measure::DeviatorStress => self.q,
            Measure::MeanStress => self.p,
            Measure::VolumetricStrain => self.volumetric_strain,
            Measure::VoidRatio => self.void_ratio,
        }
    }
}

/// `[synthetic]` of element tests.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ElementSyntheticSpec {
    /// Observe every this many increments of each test's path (default 1).
    pub every: Option<usize>,
}

/// Stresses in data files and `sigma` are in kPa; the problem works in Pa.
const KPA: f64 = 1e3;

/// The factor from a file's unit of `m` to the problem's (kPa to Pa for a stress).
fn unit(m: Measure) -> f64 {
    if m.is_stress() { KPA } else { 1.0 }
}

/// The quantities' names in the messages.
const MEASURES: &str = "q, p (kPa), volumetric_strain, void_ratio";

/// Whether `path` is an inversion of element tests: a TOML file with `[[tests]]` at its top.
pub fn is_element_inversion(path: &Path) -> bool {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|t| t.parse::<toml::Table>().ok())
        .is_some_and(|t| t.contains_key("tests"))
}

/// An inversion of element tests ready to run.
pub struct ElementInversion {
    /// The inversion file.
    pub path: PathBuf,
    /// What it says.
    pub file: ElementInversionFile,
    /// Each test's file, resolved, and its contents.
    pub tests: Vec<(PathBuf, ElementTest)>,
    /// The parameters' names as written.
    pub names: Vec<String>,
    /// The optimiser's view of each parameter.
    pub variables: Vec<Variable>,
    /// The loss as a function of the parameters.
    pub problem: ElementProblem,
    /// The parameters' truth values, when every one has one.
    pub truth: Option<Vec<f64>>,
    /// The first guesses.
    pub initial: Vec<f64>,
    /// The optimiser (the file's, or Levenberg–Marquardt).
    pub optimizer: OptimizerSpec,
    /// Per test, the fitted quantities with their `σ` (Pa for a stress).
    pub fitted: Vec<Vec<(Measure, f64)>>,
}

/// The constant a parameter name `material.<constant>` names, or why it names none.
fn material_field(name: &str) -> Result<MaterialField, String> {
    let constants = || {
        (MaterialField::ALL.iter())
            .filter(|f| **f != MaterialField::Density)
            .map(|f| f.name())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let expected = format!(
        "expected `material.<constant>` with <constant> one of {}",
        constants()
    );
    if let Some(rest) = name.strip_prefix("materials[")
        && let Some((_, field)) = rest.split_once("].")
    {
        return Err(format!(
            "element tests name their material's constants `material.<constant>` (one \
             material, the `[material]` of every test): write `material.{field}`"
        ));
    }
    match name.strip_prefix("material.") {
        Some("density") => Err(
            "`material.density` does not act in an element test (no inertia, no gravity)".into(),
        ),
        Some(field) => MaterialField::named(field)
            .ok_or_else(|| format!("unknown constant `{field}`; {expected}")),
        None => Err(format!("unknown parameter `{name}`; {expected}")),
    }
}

/// The constants the model of `test` takes, for messages.
fn constants_of(test: &ElementTest) -> String {
    let material = test.material();
    (MaterialField::ALL.iter())
        .filter(|f| **f != MaterialField::Density && f.applies_to(&material))
        .map(|f| f.name())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Builds the inversion from the file: its tests, parameters and observations (read from
/// their CSV files, or made from the curves at the truth values). Every problem found is
/// reported at once with its field path; observations off a test's path at the first guess
/// are refused with their line.
pub fn build(path: &Path, memory: Option<u64>) -> Result<ElementInversion, Invalid> {
    let file: ElementInversionFile = super::file::read(path)?;
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut issues = Vec::new();
    let mut issue = |at: String, msg: String| issues.push(Issue::new(at, msg));
    if memory.is_some() {
        issue(
            "--memory".into(),
            "budgets the explicit adjoint's checkpoints; element tests keep none".into(),
        );
    }
    if file.tests.is_empty() {
        issue("tests".into(), "expected at least one element test".into());
    }
    // The tests and what each fits.
    let mut tests = Vec::new();
    let mut fitted = Vec::new();
    for (i, t) in file.tests.iter().enumerate() {
        let at = |f: &str| format!("tests[{i}].{f}");
        let element = dir.join(&t.element);
        let test = match ElementTest::from_path(&element) {
            Ok(test) => Some(test),
            Err(SceneError::Read { .. }) => {
                issue(
                    at("element"),
                    format!("cannot read the element-test file {}", element.display()),
                );
                None
            }
            Err(e) => {
                issue(at("element"), e.to_string());
                None
            }
        };
        let mut measures = Vec::new();
        for m in Measure::ALL {
            let Some(sigma) = t.sigma.of(m) else { continue };
            if !(sigma.is_finite() && sigma > 0.0) {
                issue(
                    at(&format!("sigma.{}", m.name())),
                    format!("expected a standard deviation > 0, got {sigma}"),
                );
            }
            measures.push((m, sigma * unit(m)));
        }
        if measures.is_empty() {
            issue(
                at("sigma"),
                format!(
                    "expected the σ of at least one quantity ({MEASURES}): the quantities \
                     given a σ are fitted"
                ),
            );
        }
        if let Some(test) = &test
            && t.sigma.void_ratio.is_some()
            && test.void_ratio().is_none()
        {
            issue(
                at("sigma.void_ratio"),
                format!(
                    "{} has no initial void ratio (`initial.void_ratio`, or a \
                     modified_cam_clay material's `void_ratio`) to fit a void ratio with",
                    element.display()
                ),
            );
        }
        match (&file.synthetic, &t.data) {
            (Some(_), Some(_)) => issue(at("data"), SYNTHETIC_CLASH.into()),
            (None, None) => issue(
                at("data"),
                "expected a CSV of measured points (axial_strain and a column per fitted \
                 quantity), or a [synthetic] section"
                    .into(),
            ),
            _ => {}
        }
        if let Some(test) = test {
            tests.push((element, test));
        }
        fitted.push(measures);
    }
    // The parameters.
    if file.parameters.is_empty() {
        issue(
            "parameters".into(),
            "expected at least one parameter".into(),
        );
    }
    let mut params = Vec::new();
    let mut variables = Vec::new();
    let mut truth = Some(Vec::new());
    for (i, p) in file.parameters.iter().enumerate() {
        let at = |field: &str| format!("parameters[{i}].{field}");
        for (field, given) in [
            ("direction", p.direction.is_some()),
            ("material", p.material.is_some()),
        ] {
            if given {
                issue(
                    at(field),
                    "only for `name = \"velocity\"` of an explicit scene's inversion".into(),
                );
            }
        }
        match material_field(&p.name) {
            Ok(field) => {
                if params.contains(&field) {
                    issue(at("name"), format!("`{}` is given twice", p.name));
                }
                for (j, (element, test)) in tests.iter().enumerate() {
                    if !field.applies_to(&test.material()) {
                        issue(
                            at("name"),
                            format!(
                                "the material of tests[{j}] ({}, model \"{}\") has no constant \
                                 `{}`; it takes {}",
                                element.display(),
                                test.material.model.name(),
                                field.name(),
                                constants_of(test)
                            ),
                        );
                    }
                }
                params.push(field);
            }
            Err(msg) => issue(at("name"), msg),
        }
        variables.push(variable(p, &mut |f, m| issue(at(f), m)));
        truth = truth.zip(p.truth).map(|(mut t, v)| {
            t.push(v);
            t
        });
    }
    let optimizer = file
        .optimizer
        .clone()
        .unwrap_or(OptimizerSpec::LevenbergMarquardt { damping: 1e-3 });
    check_optimiser(&optimizer, &file.stop, &mut issue);
    if let Some(s) = &file.synthetic {
        if s.every == Some(0) {
            issue(
                "synthetic.every".into(),
                "expected at least 1 increment".into(),
            );
        }
        if truth.is_none() {
            require_truth(&file.parameters, &mut issue);
        }
    }
    // Measured points, with their lines.
    let mut measured: Vec<Vec<(usize, f64, Vec<f64>)>> = Vec::new();
    if file.synthetic.is_none() {
        for (i, t) in file.tests.iter().enumerate() {
            let Some(data) = &t.data else { continue };
            let data = dir.join(data);
            match read_curve(&data, &fitted[i]) {
                Ok(rows) => measured.push(rows),
                Err(msg) => issue(format!("tests[{i}].data"), msg),
            }
        }
    }
    if !issues.is_empty() {
        return Err(invalid(path, issues));
    }
    let initial: Vec<f64> = file.parameters.iter().map(|p| p.initial).collect();
    let mut problem = ElementProblem {
        tests: (tests.iter())
            .map(|(_, test)| LabTest {
                material: test.material(),
                stress: test.initial_stress(),
                stages: test.stages(),
                void_ratio: test.initial.void_ratio,
                observed: Vec::new(),
            })
            .collect(),
        params,
    };
    let bad_run = |when: &str, e: AdjointError| Invalid(format!("{}: {when}: {e}", path.display()));
    match &file.synthetic {
        Some(s) => {
            let truth = truth.as_deref().expect("checked above");
            problem
                .observe(truth, s.every.unwrap_or(1), &fitted)
                .map_err(|e| bad_run("the curves at the truth values", e))?;
        }
        None => {
            // Every measured point must lie on the path the test takes at the first guess.
            let curves = problem
                .curves(&initial)
                .map_err(|e| bad_run("the tests at the first guess", e))?;
            for (i, (rows, curve)) in measured.iter().zip(&curves).enumerate() {
                let (first, last) = (curve[0].axial_strain, curve[curve.len() - 1].axial_strain);
                let (lo, hi) = (first.min(last), first.max(last));
                let data = dir.join(file.tests[i].data.as_ref().expect("read above"));
                for &(line, x, _) in rows {
                    if !on_path(curve, x) {
                        issues.push(Issue::new(
                            format!("tests[{i}].data"),
                            format!(
                                "{} line {line}: axial strain {x} lies outside the test's path \
                                 at the first guess, {lo:.6} to {hi:.6} (the stages of {})",
                                data.display(),
                                tests[i].0.display()
                            ),
                        ));
                    }
                }
                problem.tests[i].observed = (rows.iter())
                    .flat_map(|(_, x, values)| {
                        fitted[i]
                            .iter()
                            .zip(values)
                            .map(|(&(measure, sigma), &value)| Observed {
                                measure,
                                axial_strain: *x,
                                value,
                                sigma,
                            })
                    })
                    .collect();
            }
        }
    }
    // The paths must move monotonically in axial strain (the observations are placed by it).
    if issues.is_empty()
        && let Err(e) = problem.residuals(&initial)
    {
        match e {
            AdjointError::Observation { field, msg } => issues.push(Issue::new(field, msg)),
            e => return Err(bad_run("the tests at the first guess", e)),
        }
    }
    if !issues.is_empty() {
        return Err(invalid(path, issues));
    }
    let names = file.parameters.iter().map(|p| p.name.clone()).collect();
    Ok(ElementInversion {
        path: path.to_path_buf(),
        file,
        tests,
        names,
        variables,
        problem,
        truth,
        initial,
        optimizer,
        fitted,
    })
}

/// The column names a quantity is read from: its name, and for a stress the name with its
/// unit as `element.csv` writes it (`q_kPa`).
fn column_names(m: Measure) -> Vec<String> {
    let mut names = vec![m.name().to_owned()];
    if m.is_stress() {
        names.push(format!("{}_kPa", m.name()));
    }
    names
}

/// Whether `value` (as written, kPa for a stress) can be a value of `m`, or why it cannot.
fn plausible(m: Measure, value: f64) -> Result<(), String> {
    let (ok, why) = match m {
        Measure::DeviatorStress | Measure::MeanStress => (
            value.abs() <= 1e6,
            "beyond 10⁶ kPa (1 GPa): stresses are in kPa",
        ),
        Measure::VolumetricStrain => (
            value.abs() < 0.9,
            "not a strain: strains are fractions (5 % is 0.05)",
        ),
        Measure::VoidRatio => (value > 0.0 && value <= 20.0, "not a void ratio (0 to 20)"),
    };
    if ok {
        Ok(())
    } else {
        Err(format!("{} = {value} is {why}", m.name()))
    }
}

/// Reads a measured curve: a header with `axial_strain` and a column for each quantity of
/// `fitted` (`q` or `q_kPa`, `p` or `p_kPa`, `volumetric_strain`, `void_ratio`; other
/// columns are ignored), then one row per point, in order of growing (or falling) axial
/// strain. Returns per row its line, the axial strain and the fitted values in the problem's
/// units (Pa for a stress). Blank lines and `#` comments are skipped, and so is a byte-order
/// mark. Every problem names the file and the line.
fn read_curve(
    file: &Path,
    fitted: &[(Measure, f64)],
) -> Result<Vec<(usize, f64, Vec<f64>)>, String> {
    let text =
        loam_scene::read_csv(file).map_err(|e| format!("cannot read {}: {e}", file.display()))?;
    let fail = |line: usize, msg: String| format!("{} line {line}: {msg}", file.display());
    let mut lines = (text.lines().enumerate())
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (head_line, header) = lines
        .next()
        .ok_or_else(|| fail(1, "the file is empty".into()))?;
    let cells: Vec<&str> = header.split(',').map(str::trim).collect();
    let column = |names: &[String]| -> Result<usize, String> {
        let found: Vec<usize> = (0..cells.len())
            .filter(|&c| names.iter().any(|n| n == cells[c]))
            .collect();
        match found[..] {
            [c] => Ok(c),
            [] => Err(fail(
                head_line,
                format!(
                    "no column `{}`: expected `axial_strain` and a column for each fitted \
                     quantity (those given a σ); the header has {}",
                    names.join("` or `"),
                    cells.join(", ")
                ),
            )),
            _ => Err(fail(
                head_line,
                format!("the column `{}` is given twice", names.join("` or `")),
            )),
        }
    };
    let x_column = column(&["axial_strain".to_owned()])?;
    let columns: Vec<usize> = (fitted.iter())
        .map(|(m, _)| column(&column_names(*m)))
        .collect::<Result<_, _>>()?;
    let mut rows: Vec<(usize, f64, Vec<f64>)> = Vec::new();
    for (line, row) in lines {
        let cells: Vec<&str> = row.split(',').map(str::trim).collect();
        let number = |c: usize, name: &str| -> Result<f64, String> {
            let cell = cells.get(c).copied().unwrap_or("");
            cell.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    fail(
                        line,
                        format!("`{cell}` (column {name}) is not a finite number"),
                    )
                })
        };
        let x = number(x_column, "axial_strain")?;
        if x.abs() >= 0.9 {
            return Err(fail(
                line,
                format!(
                    "axial strain {x} is not a strain below 0.9 in magnitude: strains are \
                     fractions (5 % is 0.05)"
                ),
            ));
        }
        let mut values = Vec::with_capacity(fitted.len());
        for (&(m, _), &c) in fitted.iter().zip(&columns) {
            let v = number(c, m.name())?;
            plausible(m, v).map_err(|msg| fail(line, msg))?;
            values.push(v * unit(m));
        }
        if let [.., (before_line, before, _)] = rows[..] {
            let rising = match rows[..] {
                [(_, a, _), (_, b, _), ..] => b > a,
                _ => x > before,
            };
            if (rising && x <= before) || (!rising && x >= before) {
                return Err(fail(
                    line,
                    format!(
                        "axial strain {x} after {before} (line {before_line}): the points must \
                         be in order of {} axial strain, as the test moves",
                        if rising { "growing" } else { "falling" }
                    ),
                ));
            }
        }
        rows.push((line, x, values));
    }
    if rows.is_empty() {
        return Err(fail(
            head_line,
            "a header and no rows: nothing to fit (the loss would be 0 whatever the parameters)"
                .into(),
        ));
    }
    Ok(rows)
}

/// The stem of a test's file, for the names of its output files.
fn stem(path: &Path) -> String {
    path.file_stem()
        .map_or("test".into(), |s| s.to_string_lossy().into_owned())
}

/// The observations of a test grouped by axial strain: `(ε_a, value of each fitted
/// quantity)`, in the order observed (every synthetic or measured point has all of them).
fn points(test: &LabTest, fitted: &[(Measure, f64)]) -> Vec<(f64, Vec<f64>)> {
    test.observed
        .chunks(fitted.len().max(1))
        .map(|c| (c[0].axial_strain, c.iter().map(|o| o.value).collect()))
        .collect()
}

impl ElementInversion {
    /// Writes the observations of test `i` as a data file (`observed_<test>.csv`) that
    /// `tests[i].data` reads back.
    fn write_observed(&self, i: usize, dir: &Path) -> Result<(), String> {
        let fitted = &self.fitted[i];
        let mut text = String::from(
            "# observations made by `loam invert` from the truth values (synthetic): q and p in \
             kPa, compression positive, strains as fractions\naxial_strain",
        );
        for (m, _) in fitted {
            write!(text, ",{}", m.name()).expect("string");
        }
        text.push('\n');
        for (x, values) in points(&self.problem.tests[i], fitted) {
            write!(text, "{x}").expect("string");
            for ((m, _), v) in fitted.iter().zip(values) {
                write!(text, ",{}", v / unit(*m)).expect("string");
            }
            text.push('\n');
        }
        let name = format!("observed_{}.csv", stem(&self.tests[i].0));
        write_atomic(&dir.join(name), &text)
    }

    /// Writes the fit of test `i`: `fit_<test>.csv` (per observed point the data, the curve
    /// at the recovered values and at the first guess) and a plot per fitted quantity,
    /// `fit_<test>_<quantity>.png`, with the whole curves; returns the files' names.
    fn write_fit(
        &self,
        i: usize,
        dir: &Path,
        fitted_curve: &[CurvePoint],
        first_curve: &[CurvePoint],
    ) -> Result<Vec<String>, String> {
        let fitted = &self.fitted[i];
        let name = stem(&self.tests[i].0);
        let mut text = String::from(
            "# the data against the curves at the recovered values and at the first guess: q \
             and p in kPa, compression positive\naxial_strain",
        );
        for (m, _) in fitted {
            let m = m.name();
            write!(text, ",{m}_observed,{m}_fitted,{m}_first_guess").expect("string");
        }
        text.push('\n');
        let observed = points(&self.problem.tests[i], fitted);
        for (x, values) in &observed {
            write!(text, "{x}").expect("string");
            for (&(m, _), v) in fitted.iter().zip(values) {
                let at = |curve: &[CurvePoint]| {
                    interpolated(curve, m, *x).map_or(f64::NAN, |v| v / unit(m))
                };
                write!(
                    text,
                    ",{},{},{}",
                    v / unit(m),
                    at(fitted_curve),
                    at(first_curve)
                )
                .expect("string");
            }
            text.push('\n');
        }
        let csv = format!("fit_{name}.csv");
        write_atomic(&dir.join(&csv), &text)?;
        let mut files = vec![csv];
        for (k, &(m, _)) in fitted.iter().enumerate() {
            let line = |label: &str, curve: &[CurvePoint]| Series {
                name: label.into(),
                points: (curve.iter())
                    .filter_map(|c| Some((c.axial_strain, c.value(m)? / unit(m))))
                    .collect(),
                markers: false,
            };
            let series = [
                Series {
                    name: "observed".into(),
                    points: observed.iter().map(|(x, v)| (*x, v[k] / unit(m))).collect(),
                    markers: true,
                },
                line("fitted", fitted_curve),
                line("first guess", first_curve),
            ];
            let y = match m {
                Measure::DeviatorStress => "q = σ′_a − σ′_r (kPa)",
                Measure::MeanStress => "p′ (kPa, compression +)",
                Measure::VolumetricStrain => "volumetric strain ε_v (compression +)",
                Measure::VoidRatio => "void ratio e",
            };
            let png = format!("fit_{name}_{}.png", m.name());
            write_plot(
                &dir.join(&png),
                &format!("{name}: fitted {}", m.name()),
                "axial strain ε_a (compression +)",
                y,
                &series,
            )
            .map_err(|e| e.to_string())?;
            files.push(png);
        }
        Ok(files)
    }
}

impl Inverse for ElementInversion {
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
        &self.optimizer
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
    ) -> Result<super::Evaluated, AdjointError> {
        let model = if first {
            self.problem.gauss_newton(theta)?
        } else {
            self.problem.trial_gauss_newton(theta)?
        };
        Ok((
            model.loss,
            model.gradient,
            gauss_newton.then_some(model.matrix),
        ))
    }
    fn observations(&self) -> Vec<(String, f64, f64)> {
        self.problem.labelled()
    }
    fn observe(&self, theta: &[f64]) -> Result<Vec<f64>, AdjointError> {
        self.problem.modelled(theta)
    }
    fn vjp(&self, theta: &[f64], cotangent: &[f64]) -> Result<Vec<f64>, AdjointError> {
        self.problem.vjp(theta, cotangent)
    }
    fn write_synthetic(&self, dir: &Path) -> Result<(), String> {
        (0..self.tests.len()).try_for_each(|i| self.write_observed(i, dir))
    }
    fn write_recovered(&self, dir: &Path, theta: &[f64]) -> Result<Vec<String>, String> {
        let curves = |theta: &[f64]| {
            (self.problem.curves(theta)).map_err(|e| format!("{}: {e}", self.path.display()))
        };
        let (fitted, first) = (curves(theta)?, curves(&self.initial)?);
        let mut files = Vec::new();
        for (i, (element, test)) in self.tests.iter().enumerate() {
            let mut test = test.clone();
            for (&field, &v) in self.problem.params.iter().zip(theta) {
                history::set_material(&mut test.material, field, v);
            }
            let body = toml::to_string(&test)
                .map_err(|e| format!("cannot write the recovered element test: {e}"))?;
            let head = history::recovered_header(element, &self.names, theta);
            let name = format!(
                "recovered_{}",
                element
                    .file_name()
                    .map_or("test.toml".into(), |n| n.to_string_lossy())
            );
            write_atomic(&dir.join(&name), &(head + "\n" + &body))?;
            files.push(name);
            files.extend(self.write_fit(i, dir, &fitted[i], &first[i])?);
        }
        Ok(files)
    }
    fn report_recovered(&self, theta: &[f64]) -> Result<(), AdjointError> {
        let g = self.problem.identifiability(theta)?;
        print_identifiability(&self.names, self.problem.observations(), &g);
        Ok(())
    }
}

/// How `loam gradient --check` computes its columns on element tests.
const CHECK_LEGEND: &str = "  checks: dual = the loss evaluated in Dual64 with the parameter seeded (Σ r ṙ; the gradient is Jᵀr, J from\n  \
    the same seeded runs); central difference (Richardson, at δ = 1e-4 and 1e-5 |θ|, converged when they agree to 1e-6) and\n  \
    Taylor remainder r(h) = |L(θ + h) − L(θ) − h dL/dθ| for h = 1e-2 |θ| and h/2, h/4, h/8 (r falls 4× per halving where\n  \
    L is smooth; an increment that changes between elastic and plastic within h shows as a smaller ratio); where the\n  \
    differences do not converge or r falls less than 3×, L is searched for a jump: differences across it are left out,\n  \
    \"(jump)\" where none is clear of it, and the Taylor test starts at the first h of 1e-2 … 1e-6 |θ| short of it";

/// `loam gradient` on element tests: the loss and its gradient at the first guess (forward
/// mode), the Gauss–Newton identifiability, and with `check` the checks of every parameter.
pub fn gradient(inv: &ElementInversion, check: bool, json: Option<&Path>) -> Outcome {
    let theta = &inv.initial;
    let start = Instant::now();
    let (loss, grad) = match inv.problem.gauss_newton(theta) {
        Ok(m) => (m.loss, m.gradient),
        Err(e) => return super::failed(&inv.path, e),
    };
    if let Err(outcome) = first_loss(&inv.path, loss) {
        return outcome;
    }
    println!(
        "{}: L = {loss:.10e} over {} observations of {} element test(s); gradient in {:.2} s \
         (forward mode: the tests run once per parameter in Dual64)",
        inv.path.display(),
        inv.problem.observations(),
        inv.tests.len(),
        start.elapsed().as_secs_f64()
    );
    if let Some(json) = json
        && let Err(outcome) =
            super::write_gradient_json(json, &inv.path, loss, &inv.names, theta, &grad)
    {
        return outcome;
    }
    let rows: Vec<(String, usize)> = inv.names.iter().cloned().zip(0..).collect();
    let width = inv.names.iter().map(String::len).max().unwrap_or(0).max(9);
    println!(
        "  {:width$}  {:>14}  {:>18}",
        "parameter", "value", "dL/dθ (forward)"
    );
    for (name, k) in &rows {
        println!(
            "  {name:width$}  {:>14}  {:>18.10e}",
            super::number(theta[*k], 8),
            grad[*k]
        );
    }
    match inv.problem.identifiability(theta) {
        Ok(g) => print_identifiability(&inv.names, inv.problem.observations(), &g),
        Err(e) => return super::failed(&inv.path, e),
    }
    if !check {
        return Outcome::Ok;
    }
    println!("\n{CHECK_LEGEND}");
    let problem = &inv.problem;
    print_checks(&inv.path, "forward", &rows, &grad, |k| {
        let moved = move |d: f64| {
            let mut t = theta.to_vec();
            t[k] += d;
            t
        };
        let size = theta[k].abs();
        let at = |step: f64| -> Result<_, AdjointError> {
            Ok(Some(Difference {
                value: richardson(|d| problem.loss(&moved(d)), step * size)?,
                relative_step: step,
            }))
        };
        let differences = Convergence::of(vec![at(1e-4)?, at(1e-5)?]);
        let along: Along<'_> = Box::new(move |d| problem.loss(&moved(d)));
        let dual = problem.dual_derivative(theta, k)?;
        model::check_row(loss, grad[k], along, size, differences, dual)
    })
}
