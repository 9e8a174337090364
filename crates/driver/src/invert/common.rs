//! What the builds of a scene's inversion file share, explicit ([`super::file::build`]) and
//! implicit ([`super::implicit::build`]): the unknowns of `[[parameters]]`, the checks of
//! `[synthetic]` and of where the observations come from, and the issues found gathered into
//! one error.

use super::file::{
    Invalid, ObservationsSpec, ParameterSpec, SYNTHETIC_CLASH, SyntheticSpec, invalid, variable,
};
use super::limits;
use loam_inverse::Variable;
use loam_scene::Issue;
use std::path::Path;

/// The `[[parameters]]` of an inversion file as unknowns.
pub struct Unknowns<C> {
    /// What each parameter with a valid name sets, in the file's order.
    pub controls: Vec<C>,
    /// The optimiser's view of every parameter.
    pub variables: Vec<Variable>,
    /// The parameters' truth values, when every parameter has one.
    pub truth: Option<Vec<f64>>,
}

/// The unknowns of `parameters`. `control` reads what a parameter sets on the scene's solver
/// path, or reports by field name why it cannot (`None`); a control given twice and the
/// problems of a parameter's values, transform and bounds ([`variable`]) are reported too,
/// every issue as `parameters[i].FIELD`.
pub fn unknowns<C: PartialEq>(
    parameters: &[ParameterSpec],
    issue: &mut dyn FnMut(String, String),
    mut control: impl FnMut(&ParameterSpec, &mut dyn FnMut(&str, String)) -> Option<C>,
) -> Unknowns<C> {
    let mut controls = Vec::new();
    let mut variables = Vec::new();
    for (i, p) in parameters.iter().enumerate() {
        let mut at = |field: &str, msg: String| issue(format!("parameters[{i}].{field}"), msg);
        if let Some(c) = control(p, &mut at) {
            if controls.contains(&c) {
                at("name", format!("`{}` is given twice", p.name));
            }
            controls.push(c);
        }
        variables.push(variable(p, &mut at));
    }
    Unknowns {
        controls,
        variables,
        truth: parameters.iter().map(|p| p.truth).collect(),
    }
}

/// Reports the `direction` and `material` of parameter `p`, which is not an initial velocity:
/// they are only for `name = "velocity"`, which `note` follows in the message.
pub fn velocity_only(p: &ParameterSpec, note: &str, issue: &mut dyn FnMut(&str, String)) {
    for (field, given) in [
        ("direction", p.direction.is_some()),
        ("material", p.material.is_some()),
    ] {
        if given {
            issue(field, format!("only for `name = \"velocity\"`{note}"));
        }
    }
}

/// The solver path of a scene, which decides the fields of `[observations]` that apply.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Solver {
    /// `[solver] type = "explicit"`.
    Explicit,
    /// `[solver] type = "implicit"`, coupled u–p or not.
    Implicit,
}

/// Whether a field of `[observations]` is given: an option set, or a list not empty.
trait Given {
    /// Whether the file gives it.
    fn given(&self) -> bool;
}

impl<T> Given for Option<T> {
    fn given(&self) -> bool {
        self.is_some()
    }
}

impl<T> Given for Vec<T> {
    fn given(&self) -> bool {
        !self.is_empty()
    }
}

impl ObservationsSpec {
    /// Every field, `(NAME, the field, the solver path whose scenes it applies to)`.
    fn fields(&self) -> [(&'static str, &dyn Given, Solver); 16] {
        use Solver::{Explicit, Implicit};
        [
            ("tracked", &self.tracked, Explicit),
            ("tracked_weight", &self.tracked_weight, Explicit),
            ("velocity", &self.velocity, Explicit),
            ("velocity_weight", &self.velocity_weight, Explicit),
            ("monitors", &self.monitors, Explicit),
            ("deposit", &self.deposit, Explicit),
            ("deposit_weight", &self.deposit_weight, Explicit),
            ("stations", &self.stations, Explicit),
            ("displacement", &self.displacement, Implicit),
            ("displacement_sigma", &self.displacement_sigma, Implicit),
            ("reaction", &self.reaction, Implicit),
            ("reaction_sigma", &self.reaction_sigma, Implicit),
            ("reactions", &self.reactions, Implicit),
            ("pore_pressure", &self.pore_pressure, Implicit),
            ("pore_pressure_sigma", &self.pore_pressure_sigma, Implicit),
            ("piezometers", &self.piezometers, Implicit),
        ]
    }

    /// The fields given that apply to `solver`'s scenes, as `observations.NAME`.
    pub fn given_for(&self, solver: Solver) -> impl Iterator<Item = String> {
        (self.fields().into_iter())
            .filter(move |&(_, field, s)| field.given() && s == solver)
            .map(|(name, ..)| format!("observations.{name}"))
    }

    /// The observation files that `solver`'s scenes read, `(NAME, given)`.
    pub fn files(&self, solver: Solver) -> [(&'static str, bool); 3] {
        match solver {
            Solver::Explicit => [
                ("tracked", self.tracked.is_some()),
                ("velocity", self.velocity.is_some()),
                ("deposit", self.deposit.is_some()),
            ],
            Solver::Implicit => [
                ("displacement", self.displacement.is_some()),
                ("reaction", self.reaction.is_some()),
                ("pore_pressure", self.pore_pressure.is_some()),
            ],
        }
    }
}

/// Checks where the observations come from. With `[synthetic]` (`synthetic`) they come from
/// the truth run, and each of the observation `files` (`(NAME, given)`, the field
/// `observations.NAME`) that is given is refused. Without, one file at least is expected, and
/// each of `needs`, `(missing, ENTRIES, message)`, reports a file given without the entries
/// its rows name as `observations.ENTRIES`.
pub fn check_sources(
    synthetic: bool,
    files: &[(&str, bool)],
    needs: &[(bool, &str, &str)],
    issue: &mut dyn FnMut(String, String),
) {
    if synthetic {
        for (name, _) in files.iter().filter(|(_, given)| *given) {
            issue(format!("observations.{name}"), SYNTHETIC_CLASH.into());
        }
        return;
    }
    if files.iter().all(|(_, given)| !given) {
        let names: Vec<String> = files.iter().map(|(name, _)| format!("`{name}`")).collect();
        let (last, rest) = names.split_last().expect("observation files");
        issue(
            "observations".into(),
            format!(
                "expected {} or {last} (a CSV file), or a [synthetic] section",
                rest.join(", ")
            ),
        );
    }
    for &(missing, entries, msg) in needs {
        if missing {
            issue(format!("observations.{entries}"), msg.into());
        }
    }
}

/// Checks the tracked particles of `[synthetic]` `s` against the `n` particles of the scene:
/// no more chosen at random than there are, and every given id one of them.
pub fn check_tracked(s: &SyntheticSpec, n: usize, issue: &mut dyn FnMut(String, String)) {
    if s.particles > n {
        issue(
            "synthetic.particles".into(),
            format!("the scene has only {n} particles"),
        );
    }
    for (j, &id) in s.ids.iter().enumerate() {
        if id >= n {
            issue(
                format!("synthetic.ids[{j}]"),
                format!("particle {id} does not exist: the scene has {n} particles"),
            );
        }
    }
}

/// How many steps `[synthetic]` `s` observes, `every` steps apart from its first (`first`,
/// by default `every`) up to `steps`.
pub fn observed_steps(s: &SyntheticSpec, every: usize, steps: usize) -> usize {
    limits::observed_steps(s.first.unwrap_or(every), every, steps)
}

/// Reports a `[synthetic]` section `s`, observing every `every` steps of a run of `steps`,
/// whose first observed step is after the last: it observes nothing (nothing is reported
/// when `steps` is 0). The field is `first` when the file gives it, else `every` (of which
/// `first` is the default).
pub fn check_observed(
    s: &SyntheticSpec,
    every: usize,
    steps: usize,
    issue: &mut dyn FnMut(String, String),
) {
    if steps == 0 || observed_steps(s, every, steps) > 0 {
        return;
    }
    let first = s.first.unwrap_or(every);
    let field = match s.first {
        Some(_) => "synthetic.first",
        None => "synthetic.every",
    };
    issue(
        field.into(),
        format!(
            "the first observed step, {first}, is after the last step of the run, {steps}: \
             nothing would be observed (the loss would be 0 whatever the parameters)"
        ),
    );
}

/// `Ok` when no issue was found, else the invalid-file error listing `issues` ([`invalid`]).
pub fn valid(path: &Path, issues: Vec<Issue>) -> Result<(), Invalid> {
    if issues.is_empty() {
        Ok(())
    } else {
        Err(invalid(path, issues))
    }
}
