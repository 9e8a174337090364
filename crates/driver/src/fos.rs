//! `loam fos`: the factor of safety of a scene by strength reduction
//! ([`loam_implicit::strength_reduction`]): trial runs of the scene's quasi-static loading with
//! the strength divided by `F`, doubled or halved until one stands and one fails, then
//! bisected to the tolerance. It prints a line per trial and keeps `fos.json` (every trial,
//! the bracket, the failure criterion) and `fos.png` (`F` against the largest displacement)
//! up to date in the output folder. At the end it writes the failure mechanism as frames in
//! `mechanism/` ([`MECHANISM`]). Ctrl-C stops it before the next load step with what was
//! done so far written (status `interrupted`, exit 130).

use crate::Outcome;
use crate::preflight::{self, MemoryLimit, StepLimit};
use crate::run::interrupt;
use loam_core::Particles;
use loam_implicit::ImplicitError;
use loam_implicit::strength_reduction::{
    Search, SearchEnd, SearchSettings, Trial, TrialOutcome, search,
};
use loam_scene::output::{Field, FrameWriter};
use loam_scene::{Built, Scene};
use loam_verification::{Series, write_plot};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The options of `loam fos`.
pub struct Options<'a> {
    /// Output folder instead of the scene's `output.dir`.
    pub out: Option<&'a Path>,
    /// Bracket width at which the search stops, instead of the scene's `fos.tolerance`.
    pub tolerance: Option<f64>,
    /// No table of trials.
    pub quiet: bool,
    /// The memory the runs may use.
    pub memory_limit: Option<MemoryLimit>,
    /// The most load steps one trial may take.
    pub max_steps: StepLimit,
}

/// The summary file's name in the output folder.
const SUMMARY: &str = "fos.json";
/// The plot's name in the output folder.
const PLOT: &str = "fos.png";
/// The folder of the failure mechanism in the output folder: a frame series
/// (`particles.pvd`) of the last converged state of the largest stable trial and of the
/// smallest failed one, in that order, each at the "time" of its factor `F`, with the
/// displacement and plastic strain among its fields: the mechanism is where the two differ.
const MECHANISM: &str = "mechanism";

/// What `fos.json` holds.
#[derive(Serialize)]
struct Summary {
    /// The scene file.
    scene: String,
    /// 2 or 3.
    dimension: usize,
    /// Particles of the scene.
    particles: usize,
    /// `running` (while trials remain), `completed`, `interrupted` or `failed`.
    status: &'static str,
    /// Why the search failed.
    error: Option<String>,
    /// When a trial counts as failed.
    failure_criterion: String,
    /// The settings of the search.
    tolerance: f64,
    /// Factor of the first trial.
    start: f64,
    /// The most trials.
    max_trials: usize,
    /// The growth of the largest displacement in a load step, over its growth in the first,
    /// that fails a trial, if any.
    growth_limit: Option<f64>,
    /// The displacement that fails a trial (m), if any.
    displacement_limit: Option<f64>,
    /// The largest stable factor.
    stable_factor: Option<f64>,
    /// The smallest failed factor.
    failed_factor: Option<f64>,
    /// The midpoint of the bracket once it is within the tolerance.
    factor_of_safety: Option<f64>,
    /// Wall time so far (s).
    wall_time_s: f64,
    /// The frame series of the mechanism ([`MECHANISM`]), once written.
    mechanism: Option<String>,
    /// Every trial in the order run.
    trials: Vec<TrialSummary>,
}

/// The states of the bracket's two trials, for the frames of the mechanism: the largest
/// stable factor and the smallest failed one, each with its particles at the trial's last
/// converged load step.
#[derive(Default)]
struct Mechanism<const D: usize> {
    stable: Option<(f64, Particles<f64, D>)>,
    failed: Option<(f64, Particles<f64, D>)>,
}

impl<const D: usize> Mechanism<D> {
    /// Keeps `state` when `trial` is a new end of the bracket.
    fn record(&mut self, trial: &Trial, state: &Particles<f64, D>) {
        let (slot, closer): (_, fn(f64, f64) -> bool) = match trial.outcome {
            TrialOutcome::Stable => (&mut self.stable, |new, old| new > old),
            TrialOutcome::Failed(_) => (&mut self.failed, |new, old| new < old),
            TrialOutcome::Interrupted => return,
        };
        if slot.as_ref().is_none_or(|(f, _)| closer(trial.factor, *f)) {
            *slot = Some((trial.factor, state.clone()));
        }
    }

    /// Writes the kept states as frames into `dir` with `fields` (plus the displacement from
    /// `initial` and the plastic strain); returns the series' path, or `None` when no trial
    /// was kept.
    fn write(
        &self,
        dir: &Path,
        fields: &[Field],
        initial: &[loam_core::tensor::Vector<f64, D>],
    ) -> Result<Option<PathBuf>, String> {
        let states: Vec<&(f64, Particles<f64, D>)> =
            self.stable.iter().chain(&self.failed).collect();
        if states.is_empty() {
            return Ok(None);
        }
        let mut fields = fields.to_vec();
        for f in [Field::Displacement, Field::PlasticStrain] {
            if !fields.contains(&f) {
                fields.push(f);
            }
        }
        let mut writer = FrameWriter::create(dir, &fields).map_err(|e| e.to_string())?;
        for (factor, particles) in states {
            writer
                .write_frame(*factor, particles, Some(initial))
                .map_err(|e| e.to_string())?;
        }
        Ok(Some(writer.pvd_path()))
    }
}

/// One trial in `fos.json`.
#[derive(Serialize)]
struct TrialSummary {
    /// The strength reduction factor.
    factor: f64,
    /// Whether every load step converged.
    converged: bool,
    /// `stable`, `failed` or `interrupted`.
    outcome: &'static str,
    /// Why it failed.
    reason: Option<String>,
    /// Load factor reached.
    load_factor: f64,
    /// Newton iterations, every attempt included.
    iterations: usize,
    /// Load-step cuts.
    cuts: usize,
    /// Largest particle displacement at the last converged state (m).
    max_displacement: f64,
    /// Wall time (s).
    wall_time_s: f64,
    /// Per load step run: step, load factor, Newton iterations, cuts, largest displacement.
    load_steps: Vec<StepSummary>,
}

/// One load step of a trial in `fos.json`.
#[derive(Serialize)]
struct StepSummary {
    step: usize,
    load_factor: f64,
    iterations: usize,
    cuts: usize,
    max_displacement: f64,
}

impl TrialSummary {
    fn new(t: &Trial) -> Self {
        let (outcome, reason) = match &t.outcome {
            TrialOutcome::Stable => ("stable", None),
            TrialOutcome::Failed(why) => ("failed", Some(why.clone())),
            TrialOutcome::Interrupted => ("interrupted", None),
        };
        Self {
            factor: t.factor,
            converged: t.stable(),
            outcome,
            reason,
            load_factor: t.load_factor,
            iterations: t.iterations(),
            cuts: t.cuts(),
            max_displacement: t.max_displacement,
            wall_time_s: t.wall_time_s,
            load_steps: t
                .steps
                .iter()
                .map(|s| StepSummary {
                    step: s.step,
                    load_factor: s.load_factor,
                    iterations: s.iterations,
                    cuts: s.cuts,
                    max_displacement: s.max_displacement,
                })
                .collect(),
        }
    }
}

/// The failure criterion in words, for the summary.
fn criterion(settings: &SearchSettings, newton: &loam_implicit::NewtonSettings) -> String {
    let mut text = format!(
        "a load step that does not converge (Newton: {} iterations per attempt, the step \
         halved up to {} times), or a particle that leaves the grid or inverts",
        newton.max_iterations, newton.max_cuts
    );
    if let Some(g) = settings.growth_limit {
        text.push_str(&format!(
            ", or a load step that grows the largest particle displacement by more than {g} \
             times its growth in the first load step"
        ));
    }
    if let Some(limit) = settings.displacement_limit {
        text.push_str(&format!(
            ", or a largest particle displacement above {limit} m"
        ));
    }
    text
}

/// Searches the factor of safety of the scene at `path`; see the module docs.
pub fn fos(path: &Path, options: &Options) -> Outcome {
    let scene = match Scene::read_path(path) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    let checked = preflight::size(&scene, options.memory_limit)
        .and_then(|_| preflight::implicit_steps(&scene, options.max_steps));
    if let Err(msg) = checked {
        eprintln!("error: {}: {msg}", path.display());
        return Outcome::BadInput;
    }
    if let Err(e) = scene.validate().and_then(|()| scene.check_fos()) {
        eprintln!("error: {e}");
        return Outcome::BadInput;
    }
    let mut settings = scene.fos_settings();
    if let Some(t) = options.tolerance {
        settings.tolerance = t;
    }
    if let Err(e) = interrupt::install() {
        eprintln!("error: {e}");
        return Outcome::Failed;
    }
    match scene.dim() {
        2 => fos_dim::<2>(&scene, path, &settings, options),
        _ => fos_dim::<3>(&scene, path, &settings, options),
    }
}

/// The writer of `fos.json` and `fos.png`, kept up to date after every trial.
struct Record {
    dir: PathBuf,
    summary: Summary,
    clock: Instant,
}

impl Record {
    /// Writes the summary (through a temporary file, so a killed search leaves a whole one)
    /// and the plot.
    fn write(&mut self) -> Result<(), String> {
        self.summary.wall_time_s = self.clock.elapsed().as_secs_f64();
        let path = self.dir.join(SUMMARY);
        let tmp = self.dir.join(format!("{SUMMARY}.tmp"));
        let text = serde_json::to_string_pretty(&self.summary).map_err(|e| e.to_string())?;
        std::fs::write(&tmp, text)
            .and_then(|()| std::fs::rename(&tmp, &path))
            .map_err(|e| format!("{}: {e}", path.display()))?;
        let points = |converged: bool| -> Vec<(f64, f64)> {
            self.summary
                .trials
                .iter()
                .filter(|t| t.converged == converged && t.outcome != "interrupted")
                .map(|t| (t.factor, t.max_displacement))
                .collect()
        };
        write_plot(
            &self.dir.join(PLOT),
            "Strength reduction: largest displacement against F",
            "strength reduction factor F",
            "largest displacement (m)",
            &[
                Series {
                    name: "stable".into(),
                    points: points(true),
                    markers: true,
                },
                Series {
                    name: "failed (last converged load step)".into(),
                    points: points(false),
                    markers: true,
                },
            ],
        )
        .map_err(|e| e.to_string())
    }

    /// Takes in the search's bracket.
    fn bracket(&mut self, found: &Search) {
        self.summary.stable_factor = found.bracket.stable;
        self.summary.failed_factor = found.bracket.failed;
        self.summary.factor_of_safety = found.factor_of_safety();
    }
}

fn fos_dim<const D: usize>(
    scene: &Scene,
    path: &Path,
    settings: &SearchSettings,
    options: &Options,
) -> Outcome {
    let built: Built<D> = match scene.build() {
        Ok(b) => b,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    let Some(config) = built.implicit_config() else {
        // `check_fos` refuses explicit scenes.
        eprintln!("error: {}: not an implicit scene", path.display());
        return Outcome::BadInput;
    };
    let dir = options
        .out
        .map_or_else(|| built.output.dir.clone(), Path::to_path_buf);
    if let Err(e) = std::fs::create_dir_all(&dir) {
        eprintln!("error: {}: {e}", dir.display());
        return Outcome::Failed;
    }
    let mut record = Record {
        dir,
        clock: Instant::now(),
        summary: Summary {
            scene: path.display().to_string(),
            dimension: D,
            particles: built.particles.len(),
            status: "running",
            error: None,
            failure_criterion: criterion(settings, &config.newton),
            tolerance: settings.tolerance,
            start: settings.start,
            max_trials: settings.max_trials,
            growth_limit: settings.growth_limit,
            displacement_limit: settings.displacement_limit,
            stable_factor: None,
            failed_factor: None,
            factor_of_safety: None,
            wall_time_s: 0.0,
            mechanism: None,
            trials: Vec::new(),
        },
    };
    let mut mechanism = Mechanism::<D>::default();
    let quiet = options.quiet;
    if !quiet {
        println!(
            "{}: {} particles, {} load steps per trial, tolerance {}",
            path.display(),
            built.particles.len(),
            config.load_steps,
            settings.tolerance
        );
        println!(
            "{:>5} {:>9} {:>11} {:>6} {:>6} {:>5} {:>12} {:>9}",
            "trial", "F", "result", "load", "its", "cuts", "max|u| (m)", "time (s)"
        );
    }
    let mut write_error = None;
    let found = loam_explicit::pool::hold(|| {
        search(
            &config,
            &built.particles,
            settings,
            &interrupt::requested,
            |t, state| {
                mechanism.record(t, state);
                record.summary.trials.push(TrialSummary::new(t));
                if !quiet {
                    println!(
                        "{:>5} {:>9.4} {:>11} {:>6.3} {:>6} {:>5} {:>12.4e} {:>9.2}",
                        record.summary.trials.len(),
                        t.factor,
                        record.summary.trials.last().map_or("", |s| s.outcome),
                        t.load_factor,
                        t.iterations(),
                        t.cuts(),
                        t.max_displacement,
                        t.wall_time_s
                    );
                }
                if let Err(e) = record.write() {
                    write_error.get_or_insert(e);
                }
            },
        )
    });
    let found = match found {
        Ok(f) => f,
        Err(e @ ImplicitError::Config { .. }) => {
            eprintln!("error: {}: {e}", path.display());
            return Outcome::BadInput;
        }
        Err(e) => {
            eprintln!("error: {}: {e}", path.display());
            return Outcome::Failed;
        }
    };
    record.bracket(&found);
    let (status, outcome) = match found.end {
        SearchEnd::Bracketed => ("completed", Outcome::Ok),
        SearchEnd::Interrupted => ("interrupted", Outcome::Interrupted),
        SearchEnd::TrialLimit => ("failed", Outcome::Failed),
    };
    record.summary.status = status;
    if found.end == SearchEnd::TrialLimit {
        record.summary.error = Some(format!(
            "{} trials did not narrow the bracket to {} (stable at {}, fails at {}); raise \
             fos.max_trials or move fos.start",
            found.trials.len(),
            settings.tolerance,
            factor_text(found.bracket.stable),
            factor_text(found.bracket.failed),
        ));
    }
    let frames = mechanism.write(
        &record.dir.join(MECHANISM),
        &built.output.fields,
        &built.particles.x,
    );
    match frames {
        Ok(path) => record.summary.mechanism = path.map(|p| p.display().to_string()),
        Err(e) => {
            write_error.get_or_insert(e);
        }
    }
    if let Err(e) = record.write() {
        write_error.get_or_insert(e);
    }
    if let Some(e) = write_error {
        eprintln!("error: {e}");
        return Outcome::Failed;
    }
    let wall = record.summary.wall_time_s;
    let mut files = format!(
        "{} and {}",
        record.dir.join(SUMMARY).display(),
        record.dir.join(PLOT).display()
    );
    if let Some(m) = &record.summary.mechanism {
        files = format!("{files}; the mechanism: {m}");
    }
    match (found.end, found.factor_of_safety()) {
        (SearchEnd::Bracketed, Some(f)) => println!(
            "{}: factor of safety F = {f:.4} (stable at {}, fails at {}; {} trials in \
             {wall:.1} s); wrote {files}",
            path.display(),
            factor_text(found.bracket.stable),
            factor_text(found.bracket.failed),
            found.trials.len(),
        ),
        (SearchEnd::Interrupted, _) => eprintln!(
            "{}: interrupted after {} trial(s) (stable at {}, fails at {}); wrote {files}",
            path.display(),
            found.trials.len(),
            factor_text(found.bracket.stable),
            factor_text(found.bracket.failed),
        ),
        _ => eprintln!(
            "error: {}: {}; wrote {files}",
            path.display(),
            record.summary.error.as_deref().unwrap_or("no bracket")
        ),
    }
    outcome
}

/// A factor for messages, `none` when no trial gave one.
fn factor_text(f: Option<f64>) -> String {
    f.map_or_else(|| "none".into(), |f| format!("{f:.4}"))
}
