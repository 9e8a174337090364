//! `loam run`: simulate a scene, writing frames, a progress bar or a Newton table, and a run
//! summary.

mod checkpoint;
mod explicit;
mod implicit;

use crate::Outcome;
use checkpoint::{Checkpointer, Resume};
use loam_core::Particles;
use loam_core::energy::energy;
use loam_core::tensor::Vector;
use loam_scene::output::{EnergySample, FrameWriter, RunStatus, RunSummary, write_summary};
use loam_scene::{Built, Scene, SolverPlan};
use std::path::{Path, PathBuf};

/// Loads `scene`, runs it and reports; with `checkpoint_every`, an explicit run saves its
/// state every that many steps. See the module docs of `main` for exit codes.
pub fn run(
    path: &Path,
    out: Option<&Path>,
    quiet: bool,
    checkpoint_every: Option<usize>,
) -> Outcome {
    let (scene, text) = match Scene::from_path_with_text(path) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    let start = Start {
        checkpoints: checkpoint_every.map(|n| (text, n)),
        resume: None,
    };
    match scene.dim() {
        2 => run_dim::<2>(&scene, path, out, quiet, start),
        _ => run_dim::<3>(&scene, path, out, quiet, start),
    }
}

/// Continues the explicit run in `dir` from its checkpoint (`loam run --resume DIR`), with
/// the scene recorded there; with `checkpoint_every` it keeps saving its state.
pub fn resume(dir: &Path, quiet: bool, checkpoint_every: Option<usize>) -> Outcome {
    let (resume, scene) = match Resume::open(dir) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    let path = resume.header.source.clone();
    let start = Start {
        checkpoints: checkpoint_every.map(|n| (resume.text.clone(), n)),
        resume: Some(resume),
    };
    match scene.dim() {
        2 => run_dim::<2>(&scene, &path, Some(dir), quiet, start),
        _ => run_dim::<3>(&scene, &path, Some(dir), quiet, start),
    }
}

/// How a run starts: whether it writes checkpoints (the scene text to record and the
/// interval) and whether it continues from one.
struct Start {
    checkpoints: Option<(String, usize)>,
    resume: Option<Resume>,
}

fn run_dim<const D: usize>(
    scene: &Scene,
    path: &Path,
    out: Option<&Path>,
    quiet: bool,
    start: Start,
) -> Outcome {
    let built: Built<D> = match scene.build() {
        Ok(b) => b,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    let dir = out.map_or_else(|| built.output.dir.clone(), Path::to_path_buf);
    let plan = match built.plan {
        SolverPlan::Explicit(plan) => plan,
        SolverPlan::Implicit(plan) => {
            if start.checkpoints.is_some() || start.resume.is_some() {
                eprintln!(
                    "error: {}: checkpoints and --resume are for explicit runs; this scene \
                     runs the implicit solver",
                    path.display()
                );
                return Outcome::BadInput;
            }
            return match Recorder::new(path, &dir, &built) {
                Ok(rec) => implicit::run(built, plan, rec, quiet),
                Err(e) => {
                    eprintln!("error: {e}");
                    Outcome::Failed
                }
            };
        }
    };
    let restart = match &start.resume {
        None => None,
        Some(r) => match r.particles::<D>(built.particles.len()) {
            Ok(p) => Some((r, p)),
            Err(e) => {
                eprintln!("error: {e}");
                return Outcome::BadInput;
            }
        },
    };
    let rec = match &restart {
        None => checkpoint::clear(&dir)
            .and_then(|()| Recorder::new(path, &dir, &built).map_err(|e| e.to_string())),
        Some((r, _)) => Recorder::resume(path, &dir, &built, r),
    };
    let rec = match rec {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::Failed;
        }
    };
    let checkpoints = match start.checkpoints {
        None => None,
        Some((text, every)) => match Checkpointer::create(&dir, path, &text, every) {
            Ok(c) => Some(c),
            Err(e) => {
                eprintln!("error: {e}");
                return Outcome::Failed;
            }
        },
    };
    let restart = restart.map(|(r, particles)| explicit::Restart {
        particles,
        time: r.header.time,
        steps: r.header.step as usize,
    });
    explicit::run(built, plan, rec, quiet, checkpoints, restart)
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
    /// The summary being filled in.
    pub summary: RunSummary,
}

impl<const D: usize> Recorder<D> {
    fn new(
        scene: &Path,
        dir: &Path,
        built: &Built<D>,
    ) -> Result<Self, loam_scene::output::OutputError> {
        Ok(Self {
            scene: scene.to_path_buf(),
            writer: FrameWriter::create(dir, &built.output.fields)?,
            initial: built.particles.x.clone(),
            gravity: built.gravity,
            materials: built.materials.clone(),
            first_step: 0,
            summary: RunSummary {
                scene: scene.display().to_string(),
                dimension: D,
                particles: built.particles.len(),
                steps: 0,
                end_time: 0.0,
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
                resumed_from: None,
                checkpoint: None,
            },
        })
    }

    /// A recorder that continues the run in `dir` from the checkpoint `from`: the frames
    /// after its time are dropped ([`FrameWriter::resume`]), and the earlier run's energy
    /// history up to it is kept when its summary can be read. Displacements stay relative to
    /// the scene's initial positions.
    fn resume(scene: &Path, dir: &Path, built: &Built<D>, from: &Resume) -> Result<Self, String> {
        let mut rec = Self::new(scene, dir, built).map_err(|e| e.to_string())?;
        let time = from.header.time;
        rec.writer = FrameWriter::resume(dir, &built.output.fields, time)
            .map_err(|e| format!("cannot continue the frame series: {e}"))?;
        let s = &mut rec.summary;
        s.frames = rec
            .writer
            .entries()
            .iter()
            .map(|e| dir.join(&e.file).display().to_string())
            .collect();
        let earlier = std::fs::read_to_string(dir.join("summary.json"))
            .ok()
            .and_then(|text| serde_json::from_str::<RunSummary>(&text).ok());
        if let Some(earlier) = earlier {
            s.energy = earlier
                .energy
                .into_iter()
                .filter(|e| e.time <= time)
                .collect();
        }
        s.resumed_from = Some(from.note());
        rec.first_step = from.header.step as usize;
        Ok(rec)
    }

    /// Frames in the series so far (a resumed run starts with those it kept).
    pub fn frames_written(&self) -> usize {
        self.writer.entries().len()
    }

    /// Writes a frame at `time` (simulated time, or load factor for implicit runs) and records
    /// the energy.
    pub fn frame(
        &mut self,
        step: usize,
        time: f64,
        particles: &Particles<f64, D>,
    ) -> Result<(), String> {
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
            .map_err(|e| e.to_string())?;
        self.summary.frames.push(p.display().to_string());
        Ok(())
    }

    /// Completes the summary, writes it and prints the outcome: `done` on success, the error
    /// and what was kept otherwise.
    pub fn finish(
        mut self,
        steps: usize,
        reached: f64,
        wall: f64,
        failure: Option<String>,
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
        if let Some(msg) = &failure {
            s.status = RunStatus::Failed;
            s.error = Some(msg.clone());
        }
        let summary_path = self.writer.dir().join("summary.json");
        if let Err(e) = write_summary(&summary_path, &self.summary) {
            eprintln!("error: {e}");
            return Outcome::Failed;
        }
        match failure {
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
            Some(msg) => {
                eprintln!("error: {}: {msg}", self.scene.display());
                eprintln!(
                    "the {} frame(s) written up to {reached:.4} remain valid in {}; summary: {}",
                    self.summary.frames.len(),
                    self.writer.pvd_path().display(),
                    summary_path.display()
                );
                Outcome::Failed
            }
        }
    }
}
