//! `loam run`: simulate a scene, writing frames, a progress bar or a Newton table, and a run
//! summary.

mod explicit;
mod implicit;

use crate::Outcome;
use loam_core::Particles;
use loam_core::energy::energy;
use loam_core::tensor::Vector;
use loam_scene::output::{EnergySample, FrameWriter, RunStatus, RunSummary, write_summary};
use loam_scene::{Built, Scene, SolverPlan};
use std::path::{Path, PathBuf};

/// Loads `scene`, runs it and reports; see the module docs of `main` for exit codes.
pub fn run(path: &Path, out: Option<&Path>, quiet: bool) -> Outcome {
    let scene = match Scene::from_path(path) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    match scene.dim() {
        2 => run_dim::<2>(&scene, path, out, quiet),
        _ => run_dim::<3>(&scene, path, out, quiet),
    }
}

fn run_dim<const D: usize>(scene: &Scene, path: &Path, out: Option<&Path>, quiet: bool) -> Outcome {
    let built: Built<D> = match scene.build() {
        Ok(b) => b,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    let dir = out.map_or_else(|| built.output.dir.clone(), Path::to_path_buf);
    let rec = match Recorder::new(path, &dir, &built) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::Failed;
        }
    };
    match built.plan {
        SolverPlan::Explicit(plan) => explicit::run(built, plan, rec, quiet),
        SolverPlan::Implicit(plan) => implicit::run(built, plan, rec, quiet),
    }
}

/// Writes frames and the summary of a run, whichever solver drives it.
pub struct Recorder<const D: usize> {
    scene: PathBuf,
    writer: FrameWriter,
    initial: Vec<Vector<f64, D>>,
    gravity: Vector<f64, D>,
    materials: Vec<loam_core::Material<f64>>,
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
            },
        })
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
        s.steps_per_second = steps as f64 / wall.max(1e-9);
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
