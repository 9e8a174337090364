//! `loam run`: simulate a scene, writing frames, a progress display or a Newton table, and a
//! run summary.
//!
//! Before anything is built the scene's size is estimated and checked against the memory
//! limit ([`crate::preflight`]); an explicit run also checks its fixed time step against the
//! initial state's stability limit before it writes anything. A signal (Ctrl-C) stops the run
//! after the step in progress ([`interrupt`]).
//!
//! An explicit run can save its state every `N` steps and be continued from it
//! (`--checkpoint-every N`, `--resume DIR`; [`checkpoint`]). A resumed run goes through the
//! same checks and the same stepping loop as a fresh one; it keeps the frames up to the
//! checkpoint and writes the later ones again.

mod checkpoint;
mod explicit;
pub mod gpu;
mod implicit;
pub mod interrupt;
mod probes;
mod progress;

use crate::Outcome;
use crate::preflight::{self, MemoryLimit, StepLimit};
use checkpoint::Resume;
use loam_core::Particles;
use loam_core::energy::energy;
use loam_core::tensor::Vector;
use loam_scene::output::{
    EnergySample, FrameWriter, ObstacleForceSample, OutputError, RunStatus, RunSummary,
    write_obstacle_forces, write_summary,
};
use loam_scene::{Built, Device, Scene, SolverKind, SolverPlan};
use std::path::{Path, PathBuf};

/// The options of `loam run`.
pub struct Options<'a> {
    /// Output folder instead of the scene's.
    pub out: Option<&'a Path>,
    /// No progress display and no Newton table.
    pub quiet: bool,
    /// Seconds between plain progress lines (when stderr is not a terminal).
    pub progress_every: f64,
    /// The memory the run may use.
    pub memory_limit: Option<MemoryLimit>,
    /// The most steps the run may take.
    pub max_steps: StepLimit,
    /// Explicit runs: save the state every this many steps (`--checkpoint-every`).
    pub checkpoint_every: Option<usize>,
    /// Explicit runs: where the steps run (`--device`), instead of the scene's
    /// `solver.device`.
    pub device: Option<Device>,
    /// Runs on the GPU: how P2G adds into the grid (`--p2g`), instead of the adapter's choice.
    pub p2g: Option<gpu::P2g>,
}

/// Loads `scene`, runs it and reports; see the module docs of `main` for exit codes.
pub fn run(path: &Path, options: &Options) -> Outcome {
    let (scene, text) = match Scene::read_path_with_text(path) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    let start = Start {
        checkpoints: options.checkpoint_every.map(|n| (text, n)),
        resume: None,
    };
    start_run(&scene, path, options, start)
}

/// Runs a scene already loaded (from a file or from text, and validated or not), as
/// [`run`] runs a file: the same checks, stepping, frames and summary, without checkpoints.
/// `label` names the scene in messages and in the summary (its file, or a name for a scene
/// made in memory).
pub fn run_scene(scene: &Scene, label: &Path, options: &Options) -> Outcome {
    let start = Start {
        checkpoints: None,
        resume: None,
    };
    start_run(scene, label, options, start)
}

/// Continues the explicit run in `dir` from its checkpoint (`loam run --resume DIR`), with
/// the scene recorded there (with a note when the scene file the run started from has been
/// edited since); `options.out` is replaced by `dir`. With
/// `options.checkpoint_every` it keeps saving its state.
pub fn resume(dir: &Path, options: &Options) -> Outcome {
    let (resume, scene) = match Resume::open(dir) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    if let Some(note) = resume.edited_source() {
        eprintln!("note: {note}");
    }
    let path = resume.header.source.clone();
    let start = Start {
        checkpoints: options.checkpoint_every.map(|n| (resume.text.clone(), n)),
        resume: Some(resume),
    };
    let options = Options {
        out: Some(dir),
        ..*options
    };
    start_run(&scene, &path, &options, start)
}

/// How a run starts: whether it writes checkpoints (the scene text to record beside them
/// and the interval in steps) and whether it continues from one.
pub struct Start {
    checkpoints: Option<(String, usize)>,
    resume: Option<Resume>,
}

/// The checks before a run (solver kind, size, validation), then the run.
fn start_run(scene: &Scene, path: &Path, options: &Options, start: Start) -> Outcome {
    if scene.solver.kind == SolverKind::Implicit
        && (start.checkpoints.is_some() || start.resume.is_some())
    {
        eprintln!(
            "error: {}: checkpoints and --resume are for explicit runs; this scene runs the \
             implicit solver",
            path.display()
        );
        return Outcome::BadInput;
    }
    if scene.solver.kind == SolverKind::Implicit
        && (options.device == Some(Device::Gpu) || options.p2g.is_some())
    {
        eprintln!(
            "error: {}: --device gpu and --p2g run explicit scenes; this scene runs the \
             implicit solver, which is not supported on the GPU",
            path.display()
        );
        return Outcome::BadInput;
    }
    let checked = preflight::size(scene, options.memory_limit)
        .and_then(|_| preflight::implicit_steps(scene, options.max_steps));
    if let Err(msg) = checked {
        eprintln!("error: {}: {msg}", path.display());
        return Outcome::BadInput;
    }
    if let Err(e) = scene.validate() {
        eprintln!("error: {e}");
        return Outcome::BadInput;
    }
    if let Err(e) = interrupt::install() {
        eprintln!("error: {e}");
        return Outcome::Failed;
    }
    match scene.dim() {
        2 => run_dim::<2>(scene, path, options, start),
        _ => run_dim::<3>(scene, path, options, start),
    }
}

fn run_dim<const D: usize>(scene: &Scene, path: &Path, options: &Options, start: Start) -> Outcome {
    let built: Built<D> = match scene.build() {
        Ok(b) => b,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    let dir = options
        .out
        .map_or_else(|| built.output.dir.clone(), Path::to_path_buf);
    let target = Target { scene: path, dir };
    match built.plan {
        SolverPlan::Explicit(plan) => explicit::run(built, plan, target, options, start),
        SolverPlan::Implicit(plan) => implicit::run(built, plan, target, options),
    }
}

/// Where a run writes: the scene file it came from and the output folder.
pub struct Target<'a> {
    scene: &'a Path,
    dir: PathBuf,
}

/// Creates the folder `dir` and writes and removes a file in it, so that a folder that
/// cannot be created or written (a path through a file, a folder without write permission, a
/// read-only file system) is found before any work is done.
pub fn writable_folder(dir: &Path) -> std::io::Result<()> {
    let probe = dir.join(".loam-write-probe");
    std::fs::create_dir_all(dir)
        .and_then(|()| std::fs::write(&probe, b""))
        .and_then(|()| std::fs::remove_file(&probe))
}

impl Target<'_> {
    /// [`writable_folder`] on the output folder: one that cannot be written is invalid input,
    /// refused before the run's first step with the folder's path.
    fn writable(&self) -> Result<(), Outcome> {
        writable_folder(&self.dir).map_err(|e| {
            eprintln!(
                "error: output.dir: cannot write to the output folder {}: {e}; choose \
                     another with --out DIR or the scene's output.dir",
                self.dir.display()
            );
            Outcome::BadInput
        })
    }

    /// Opens the output folder (removing an earlier run's files: frames, collection, summary
    /// and checkpoint) and starts the summary.
    fn recorder<const D: usize>(&self, built: &Built<D>) -> Result<Recorder<D>, Outcome> {
        self.writable()?;
        checkpoint::clear(&self.dir)
            .and_then(|()| {
                let writer = FrameWriter::create(&self.dir, &built.output.fields)
                    .map_err(|e| e.to_string())?
                    .with_water_table(built.water_table());
                Ok(Recorder::new(self.scene, writer, built))
            })
            .map_err(|e| {
                eprintln!("error: {e}");
                Outcome::Failed
            })
    }

    /// Opens the output folder of the run to continue from the checkpoint `from`, keeping
    /// its frames up to the checkpoint ([`Recorder::resume`]).
    fn resumed_recorder<const D: usize>(
        &self,
        built: &Built<D>,
        from: &Resume,
    ) -> Result<Recorder<D>, Outcome> {
        self.writable()?;
        Recorder::resume(self.scene, &self.dir, built, from).map_err(|e| {
            eprintln!("error: {e}");
            Outcome::Failed
        })
    }
}

/// Why a run stopped before its end.
pub enum Stop {
    /// An error (the message).
    Failed(String),
    /// A signal.
    Interrupted,
}

/// Writes frames and the summary of a run, whichever solver drives it.
pub struct Recorder<const D: usize> {
    scene: PathBuf,
    writer: FrameWriter,
    initial: Vec<Vector<f64, D>>,
    gravity: Vector<f64, D>,
    materials: Vec<loam_core::Material<f64>>,
    /// Steps completed before this run started (those of a resumed run's checkpoint).
    first_step: usize,
    /// The time and the obstacles' impulses at the last frame
    /// ([`Recorder::obstacle_forces`]).
    impulse_mark: Option<(f64, Vec<[f64; D]>)>,
    /// The summary being filled in.
    pub summary: RunSummary,
}

impl<const D: usize> Recorder<D> {
    /// A recorder of a run of `scene` that writes its frames with `writer`.
    fn new(scene: &Path, writer: FrameWriter, built: &Built<D>) -> Self {
        Self {
            scene: scene.to_path_buf(),
            writer,
            initial: built.particles.x.clone(),
            gravity: built.gravity,
            materials: built.materials.clone(),
            first_step: 0,
            impulse_mark: None,
            summary: RunSummary {
                scene: scene.display().to_string(),
                dimension: D,
                particles: built.particles.len(),
                steps: 0,
                end_time: 0.0,
                time_unit: None,
                time_reached: 0.0,
                dt_min: f64::INFINITY,
                dt_max: 0.0,
                wall_time_s: 0.0,
                steps_per_second: 0.0,
                particle_steps_per_second: 0.0,
                status: RunStatus::Completed,
                error: None,
                warnings: Vec::new(),
                energy: Vec::new(),
                frames: Vec::new(),
                load_steps: Vec::new(),
                probes: Vec::new(),
                obstacle_forces: Vec::new(),
                resumed_from: None,
                checkpoint: None,
                device: None,
            },
        }
    }

    /// A recorder that continues the run in `dir` from the checkpoint `from`: the frames
    /// after its time are dropped ([`FrameWriter::resume`]), those up to it are kept, and the
    /// earlier run's energy history up to it is kept when its summary can be read.
    /// Displacements stay relative to the scene's initial positions.
    fn resume(scene: &Path, dir: &Path, built: &Built<D>, from: &Resume) -> Result<Self, String> {
        let time = from.header.time;
        let writer = FrameWriter::resume(dir, &built.output.fields, time)
            .map_err(|e| format!("cannot continue the frame series: {e}"))?;
        let earlier = std::fs::read_to_string(dir.join(FrameWriter::SUMMARY_NAME))
            .ok()
            .and_then(|text| serde_json::from_str::<RunSummary>(&text).ok());
        let mut rec = Self::new(scene, writer, built);
        let s = &mut rec.summary;
        s.frames = rec
            .writer
            .entries()
            .iter()
            .map(|e| dir.join(&e.file).display().to_string())
            .collect();
        if let Some(earlier) = earlier {
            s.energy = earlier
                .energy
                .into_iter()
                .filter(|e| e.time <= time)
                .collect();
            s.obstacle_forces = earlier
                .obstacle_forces
                .into_iter()
                .filter(|e| e.time <= time)
                .collect();
        }
        s.resumed_from = Some(from.note());
        rec.first_step = from.header.step as usize;
        Ok(rec)
    }

    /// The output folder.
    pub fn dir(&self) -> &Path {
        self.writer.dir()
    }

    /// Frames in the series so far (a resumed run starts with those it kept).
    pub fn frames_written(&self) -> usize {
        self.writer.entries().len()
    }

    /// Writes a frame at `time` (simulated time, or load factor for implicit runs) and records
    /// the energy. A non-finite value in a field is an error naming the step, the field and
    /// the particles, and the frame is not written.
    pub fn frame(
        &mut self,
        step: usize,
        time: f64,
        particles: &Particles<f64, D>,
    ) -> Result<(), Stop> {
        let e = energy(particles, &self.materials, &self.gravity);
        self.summary.energy.push(EnergySample {
            step: step as u64,
            time,
            kinetic: e.kinetic,
            strain: e.strain,
            gravity: e.gravity,
            total: e.total(),
        });
        let p = self
            .writer
            .write_frame(time, particles, Some(&self.initial))
            .map_err(|e| match e {
                OutputError::NonFinite { .. } => {
                    Stop::Failed(format!("step {step} (t = {time:.6e} s): {e}"))
                }
                e => Stop::Failed(e.to_string()),
            })?;
        self.summary.frames.push(p.display().to_string());
        Ok(())
    }

    /// Records the mean force of each obstacle on the material over the interval since the
    /// last call, `(I − I_mark) / (t − t_mark)`, from the solver's impulses `impulse` at the
    /// frame (`step`, `time`), with each obstacle's displacement `v t` from `velocity`. The
    /// first call, at the run's first frame or its resumed clock (where the solver's impulses
    /// start from zero), only sets the mark.
    pub fn obstacle_forces(
        &mut self,
        step: usize,
        time: f64,
        impulse: &[[f64; D]],
        velocity: &[[f64; D]],
    ) {
        if let Some((since, before)) = &self.impulse_mark
            && time > *since
        {
            let span = time - since;
            self.summary.obstacle_forces.push(ObstacleForceSample {
                step: step as u64,
                time,
                since: *since,
                forces: (impulse.iter().zip(before))
                    .map(|(i, b)| (0..D).map(|a| (i[a] - b[a]) / span).collect())
                    .collect(),
                displacements: (velocity.iter())
                    .map(|v| v.iter().map(|c| c * time).collect())
                    .collect(),
            });
        }
        self.impulse_mark = Some((time, impulse.to_vec()));
    }

    /// Completes the summary, writes it and prints the outcome: `done` on success, the error
    /// or the interruption and what was kept otherwise.
    pub fn finish(
        mut self,
        steps: usize,
        reached: f64,
        wall: f64,
        stop: Option<Stop>,
        done: &str,
    ) -> Outcome {
        let s = &mut self.summary;
        s.steps = steps as u64;
        s.time_reached = reached;
        s.wall_time_s = wall;
        s.steps_per_second = steps.saturating_sub(self.first_step) as f64 / wall.max(1e-9);
        s.particle_steps_per_second = s.steps_per_second * s.particles as f64;
        if steps == 0 || !s.dt_min.is_finite() {
            s.dt_min = 0.0;
        }
        match &stop {
            None => {}
            Some(Stop::Failed(msg)) => {
                s.status = RunStatus::Failed;
                s.error = Some(msg.clone());
            }
            Some(Stop::Interrupted) => s.status = RunStatus::Interrupted,
        }
        let summary_path = self.writer.dir().join(FrameWriter::SUMMARY_NAME);
        if let Err(e) = write_summary(&summary_path, &self.summary) {
            eprintln!("error: {e}");
            return Outcome::Failed;
        }
        let forces = &self.summary.obstacle_forces;
        if !forces.is_empty() {
            let path = self.writer.dir().join(FrameWriter::OBSTACLE_FORCES_NAME);
            if let Err(e) = write_obstacle_forces(&path, forces) {
                eprintln!("error: {e}");
                return Outcome::Failed;
            }
        }
        let mut kept = format!(
            "the {} frame(s) written up to {reached:.4} remain valid in {}; summary: {}",
            self.summary.frames.len(),
            self.writer.pvd_path().display(),
            summary_path.display()
        );
        // The checkpoint in the folder: the one this run wrote last, else the one it resumed
        // from (left in place when it wrote none).
        let s = &self.summary;
        if let Some(c) = s.checkpoint.as_ref().or(s.resumed_from.as_ref()) {
            kept.push_str(&format!(
                "; the checkpoint at step {} (t = {:.4} s) is kept: `loam run --resume {}` \
                 continues the run",
                c.step,
                c.time,
                self.writer.dir().display()
            ));
        }
        match stop {
            None => {
                println!(
                    "{}: {done}; wrote {} frames to {} ({})",
                    self.scene.display(),
                    self.summary.frames.len(),
                    self.writer.dir().display(),
                    self.writer.pvd_path().display()
                );
                Outcome::Ok
            }
            Some(Stop::Failed(msg)) => {
                eprintln!("error: {}: {msg}", self.scene.display());
                eprintln!("{kept}");
                Outcome::Failed
            }
            Some(Stop::Interrupted) => {
                eprintln!(
                    "{}: interrupted after {steps} steps; {kept}",
                    self.scene.display()
                );
                Outcome::Interrupted
            }
        }
    }
}
