//! Factor of safety by strength reduction: ordinary quasi-static runs of one loading (a
//! slope's gravity switch-on) with the strength of every material divided by a trial factor
//! `F` ([`loam_core::Material::strength_reduced`]: `c / F`, `tan φ / F`, `tan ψ / F`), and a
//! bracket search for the factor at which the run fails (Griffiths & Lane 1999, *Géotechnique*
//! 49(3)).
//!
//! **Failure criterion.** A trial *fails* when
//!
//! 1. a load step cannot be completed: Newton does not converge within
//!    `NewtonSettings::max_iterations` (or finds no admissible step) in any attempt, after the
//!    step has been cut in half `NewtonSettings::max_cuts` times
//!    ([`ImplicitError::NoConvergence`]), or a particle leaves the grid or its deformation
//!    gradient stops being invertible; or
//! 2. the displacement runs away: in a converged load step the largest particle displacement
//!    `δ = max_p |x_p − x_p⁰|` grows by more than [`SearchSettings::growth_limit`] times its
//!    growth in the first load step. The load steps are equal increments of the load, so
//!    this is the structure's secant stiffness over the step falling below `1/growth_limit`
//!    of its initial (elastic) value: a mechanism has formed. Material points need this
//!    second test: a slope that slides can come to rest again in a new, converged
//!    configuration far from its start (0.48 m for the slope of `loam verify slope-fos` at
//!    F = 1.47, where the test fails it from F = 1.39 on), which the first test alone would
//!    call stable; or
//! 3. with [`SearchSettings::displacement_limit`], `δ` exceeds that limit after a converged
//!    load step.
//!
//! A trial that completes every load step is *stable*.
//!
//! **Search.** The first trial is at [`SearchSettings::start`]. While no trial has failed the
//! factor doubles; while none is stable it halves; then the bracket `[stable, failed]` is
//! bisected until `failed − stable ≤ tolerance`. The factor of safety lies in the final
//! bracket; [`Search::factor_of_safety`] is its midpoint (within `tolerance / 2` of every
//! factor in it). Each trial starts from the same initial particles: trials are independent
//! runs, not a continuation.

use crate::solver::{ImplicitConfig, ImplicitError, ImplicitSolver};
use loam_core::Particles;

/// How the search runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SearchSettings {
    /// Factor of the first trial (`> 0`).
    pub start: f64,
    /// The search stops when the bracket `[stable, failed]` is this narrow (`> 0`, a
    /// difference of factors).
    pub tolerance: f64,
    /// The most trials the search runs (`≥ 1`).
    pub max_trials: usize,
    /// A trial fails when a load step grows the largest particle displacement by more than
    /// this multiple of its growth in the first load step (`> 1`; see the module docs);
    /// `None`: no such test.
    pub growth_limit: Option<f64>,
    /// A trial also fails when the largest particle displacement (m) exceeds this after a
    /// converged load step; `None`: no such test.
    pub displacement_limit: Option<f64>,
}

impl SearchSettings {
    /// Default of [`SearchSettings::growth_limit`]: a load step whose displacement grows ten
    /// times as much as in the first, elastic one (a secant stiffness a tenth of the elastic
    /// one).
    pub const DEFAULT_GROWTH_LIMIT: f64 = 10.0;
}

impl Default for SearchSettings {
    /// `start = 1`, `tolerance = 0.01`, `max_trials = 30`, `growth_limit = 10`, no
    /// displacement limit.
    fn default() -> Self {
        Self {
            start: 1.0,
            tolerance: 0.01,
            max_trials: 30,
            growth_limit: Some(Self::DEFAULT_GROWTH_LIMIT),
            displacement_limit: None,
        }
    }
}

/// How a trial ended.
#[derive(Clone, Debug, PartialEq)]
pub enum TrialOutcome {
    /// Every load step converged.
    Stable,
    /// A load step failed; the reason.
    Failed(String),
    /// A stop was requested before the trial ended (neither stable nor failed).
    Interrupted,
}

/// The Newton effort of one completed (or the failed) load step of a trial.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadStepEffort {
    /// Load step (1-based).
    pub step: usize,
    /// Load factor at its end (for the failed step, the load factor it was aiming at).
    pub load_factor: f64,
    /// Newton iterations of every attempt, those of the halves a cut left behind included
    /// (0 for a step that failed before Newton, e.g. a particle that left the grid).
    pub iterations: usize,
    /// Times it was cut in half.
    pub cuts: usize,
    /// Largest particle displacement `max_p |x_p − x_p⁰|` (m) at its end (for the failed
    /// step, at the last converged state).
    pub max_displacement: f64,
}

/// One run of the loading with the strength divided by `factor`.
#[derive(Clone, Debug, PartialEq)]
pub struct Trial {
    /// The strength reduction factor `F`.
    pub factor: f64,
    /// Stable, failed (with the reason) or interrupted.
    pub outcome: TrialOutcome,
    /// Load factor reached (1 for a stable trial).
    pub load_factor: f64,
    /// The load steps run, in order (the last one is the failed step of a failed trial).
    pub steps: Vec<LoadStepEffort>,
    /// Largest particle displacement `max_p |x_p − x_p⁰|` (m) at the last converged state.
    pub max_displacement: f64,
    /// Wall time of the trial (s).
    pub wall_time_s: f64,
}

impl Trial {
    /// Whether every load step converged.
    pub fn stable(&self) -> bool {
        self.outcome == TrialOutcome::Stable
    }

    /// Newton iterations over all load steps (failed attempts included).
    pub fn iterations(&self) -> usize {
        self.steps.iter().map(|s| s.iterations).sum()
    }

    /// Step cuts over all load steps.
    pub fn cuts(&self) -> usize {
        self.steps.iter().map(|s| s.cuts).sum()
    }
}

/// Why a search ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SearchEnd {
    /// The bracket is narrower than the tolerance.
    Bracketed,
    /// A stop was requested.
    Interrupted,
    /// `max_trials` trials ran without reaching the tolerance.
    TrialLimit,
}

/// What the trials so far say about the factor of safety: the largest stable and the
/// smallest failed factor.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Bracket {
    /// The largest stable factor.
    pub stable: Option<f64>,
    /// The smallest failed factor.
    pub failed: Option<f64>,
}

impl Bracket {
    /// Takes in the outcome of a trial at `factor`.
    pub fn record(&mut self, factor: f64, stable: bool) {
        if stable {
            self.stable = Some(self.stable.map_or(factor, |s| s.max(factor)));
        } else {
            self.failed = Some(self.failed.map_or(factor, |f| f.min(factor)));
        }
    }

    /// The factor of the next trial: `start` first, then twice the largest stable factor
    /// while none has failed, half the smallest failed one while none is stable, and the
    /// midpoint of the bracket after that; `None` once `failed − stable ≤ tolerance`.
    pub fn next(&self, start: f64, tolerance: f64) -> Option<f64> {
        match (self.stable, self.failed) {
            (None, None) => Some(start),
            (Some(lo), None) => Some(2.0 * lo),
            (None, Some(hi)) => Some(0.5 * hi),
            (Some(lo), Some(hi)) => (hi - lo > tolerance).then_some(0.5 * (lo + hi)),
        }
    }
}

/// The trials of a search and what they bracket.
#[derive(Clone, Debug, PartialEq)]
pub struct Search {
    /// Every trial, in the order run.
    pub trials: Vec<Trial>,
    /// The largest stable and the smallest failed factor.
    pub bracket: Bracket,
    /// Why the search ended.
    pub end: SearchEnd,
}

impl Search {
    /// The midpoint of the bracket when the search narrowed it to the tolerance
    /// ([`SearchEnd::Bracketed`]).
    pub fn factor_of_safety(&self) -> Option<f64> {
        match (self.end, self.bracket.stable, self.bracket.failed) {
            (SearchEnd::Bracketed, Some(lo), Some(hi)) => Some(0.5 * (lo + hi)),
            _ => None,
        }
    }
}

/// The largest distance of a particle from where it started.
fn max_displacement<const D: usize>(start: &Particles<f64, D>, now: &Particles<f64, D>) -> f64 {
    start
        .x
        .iter()
        .zip(&now.x)
        .map(|(a, b)| (b - a).norm())
        .fold(0.0, f64::max)
}

/// `config` with every material's strength divided by `factor` (the materials without a
/// strength unchanged); a [`ImplicitError::Config`] naming `materials` when none has one.
pub fn reduced_config<const D: usize>(
    config: &ImplicitConfig<D>,
    factor: f64,
) -> Result<ImplicitConfig<D>, ImplicitError> {
    if !(factor.is_finite() && factor > 0.0) {
        return Err(ImplicitError::Config {
            field: "factor".into(),
            msg: format!("a strength reduction factor must be positive, got {factor}"),
        });
    }
    if config
        .materials
        .iter()
        .all(|m| m.strength_reduced(1.0).is_none())
    {
        return Err(ImplicitError::Config {
            field: "materials".into(),
            msg: "no material has a strength to reduce (expected a mohr_coulomb, \
                  drucker_prager or j2 material; the elastic models, the fluid and modified \
                  Cam-Clay have none)"
                .into(),
        });
    }
    let mut reduced = config.clone();
    reduced.materials = config
        .materials
        .iter()
        .map(|m| m.strength_reduced(factor).unwrap_or_else(|| m.clone()))
        .collect();
    Ok(reduced)
}

/// Runs the loading of `config` from `particles` with the strength divided by `factor`, load
/// step by load step, until it completes, fails (see the module docs; the displacement tests
/// of `settings`) or `stop()` returns `true` (asked before every load step).
///
/// # Errors
/// A configuration the solver refuses ([`ImplicitError::Config`]); a failing load step is a
/// [`TrialOutcome::Failed`] trial, not an error.
pub fn run_trial<const D: usize>(
    config: &ImplicitConfig<D>,
    particles: &Particles<f64, D>,
    factor: f64,
    settings: &SearchSettings,
    stop: &dyn Fn() -> bool,
) -> Result<Trial, ImplicitError> {
    trial_with_state(config, particles, factor, settings, stop).map(|(trial, _)| trial)
}

/// [`run_trial`], with the particles at the trial's last converged state (for a failed
/// trial, its mechanism).
fn trial_with_state<const D: usize>(
    config: &ImplicitConfig<D>,
    particles: &Particles<f64, D>,
    factor: f64,
    settings: &SearchSettings,
    stop: &dyn Fn() -> bool,
) -> Result<(Trial, Particles<f64, D>), ImplicitError> {
    let clock = std::time::Instant::now();
    let config = reduced_config(config, factor)?;
    let load_steps = config.load_steps;
    let mut solver = ImplicitSolver::new(config, particles)?;
    let mut now = particles.clone();
    let mut steps = Vec::new();
    let mut max_u = 0.0;
    let outcome = loop {
        if solver.finished() {
            break TrialOutcome::Stable;
        }
        if stop() {
            break TrialOutcome::Interrupted;
        }
        match solver.step(&mut now) {
            Ok(report) => {
                let before = max_u;
                max_u = max_displacement(particles, &now);
                steps.push(LoadStepEffort {
                    step: report.step,
                    load_factor: report.load_factor,
                    iterations: report.attempted_iterations(),
                    cuts: report.cuts,
                    max_displacement: max_u,
                });
                // The growth of the first load step, the elastic reference.
                let first = steps[0].max_displacement;
                let growth = max_u - before;
                if let Some(limit) = settings
                    .growth_limit
                    .filter(|&g| steps.len() > 1 && first > 0.0 && growth > g * first)
                {
                    break TrialOutcome::Failed(format!(
                        "load step {}: the largest displacement grew by {growth:.4e} m, more \
                         than {limit} times its growth in the first load step ({first:.4e} m)",
                        report.step
                    ));
                }
                if let Some(limit) = settings.displacement_limit.filter(|&l| max_u > l) {
                    break TrialOutcome::Failed(format!(
                        "load step {}: the largest displacement {max_u:.4e} m exceeds the \
                         limit {limit} m",
                        report.step
                    ));
                }
            }
            Err(ImplicitError::Config { field, msg }) => {
                return Err(ImplicitError::Config { field, msg });
            }
            Err(e) => {
                let step = solver.steps() + 1;
                let (iterations, cuts) = match &e {
                    ImplicitError::NoConvergence {
                        iterations, cuts, ..
                    } => (*iterations, *cuts),
                    _ => (0, 0),
                };
                steps.push(LoadStepEffort {
                    step,
                    load_factor: step as f64 / load_steps as f64,
                    iterations,
                    cuts,
                    max_displacement: max_u,
                });
                break TrialOutcome::Failed(e.to_string());
            }
        }
    };
    let trial = Trial {
        factor,
        outcome,
        load_factor: solver.load_factor(),
        steps,
        max_displacement: max_u,
        wall_time_s: clock.elapsed().as_secs_f64(),
    };
    Ok((trial, now))
}

/// Searches the factor of safety of the loading of `config` from `particles` (see the module
/// docs), calling `on_trial` after every trial with the trial and the particles at its last
/// converged load step (a failed trial's mechanism); `stop()` is asked before every trial and every
/// load step and ends the search with [`SearchEnd::Interrupted`] (a trial it stops part-way
/// is recorded as [`TrialOutcome::Interrupted`] and counts neither way).
///
/// # Errors
/// Settings out of range or a configuration the solver refuses ([`ImplicitError::Config`]).
pub fn search<const D: usize>(
    config: &ImplicitConfig<D>,
    particles: &Particles<f64, D>,
    settings: &SearchSettings,
    stop: &dyn Fn() -> bool,
    mut on_trial: impl FnMut(&Trial, &Particles<f64, D>),
) -> Result<Search, ImplicitError> {
    let bad = |field: &str, msg: String| ImplicitError::Config {
        field: field.into(),
        msg,
    };
    if !(settings.start.is_finite() && settings.start > 0.0) {
        return Err(bad(
            "start",
            format!("must be positive, got {}", settings.start),
        ));
    }
    if !(settings.tolerance.is_finite() && settings.tolerance > 0.0) {
        return Err(bad(
            "tolerance",
            format!("must be positive, got {}", settings.tolerance),
        ));
    }
    if settings.max_trials == 0 {
        return Err(bad("max_trials", "must be at least 1, got 0".into()));
    }
    if let Some(g) = settings
        .growth_limit
        .filter(|g| !(g.is_finite() && *g > 1.0))
    {
        return Err(bad(
            "growth_limit",
            format!("must be a number above 1, got {g}"),
        ));
    }
    if let Some(l) = settings
        .displacement_limit
        .filter(|l| !(l.is_finite() && *l > 0.0))
    {
        return Err(bad(
            "displacement_limit",
            format!("must be positive, got {l}"),
        ));
    }
    let mut found = Search {
        trials: Vec::new(),
        bracket: Bracket::default(),
        end: SearchEnd::TrialLimit,
    };
    while found.trials.len() < settings.max_trials {
        let Some(factor) = found.bracket.next(settings.start, settings.tolerance) else {
            found.end = SearchEnd::Bracketed;
            return Ok(found);
        };
        if stop() {
            found.end = SearchEnd::Interrupted;
            return Ok(found);
        }
        let (trial, state) = trial_with_state(config, particles, factor, settings, stop)?;
        on_trial(&trial, &state);
        let outcome = trial.outcome.clone();
        found.trials.push(trial);
        match outcome {
            TrialOutcome::Interrupted => {
                found.end = SearchEnd::Interrupted;
                return Ok(found);
            }
            outcome => found
                .bracket
                .record(factor, outcome == TrialOutcome::Stable),
        }
    }
    if found
        .bracket
        .next(settings.start, settings.tolerance)
        .is_none()
    {
        found.end = SearchEnd::Bracketed;
    }
    Ok(found)
}
