//! `loam run`: simulate a scene, writing frames, a progress bar and a run summary.

use crate::Outcome;
use indicatif::{ProgressBar, ProgressStyle};
use loam_explicit::{Config, Solver};
use loam_scene::output::{EnergySample, FrameWriter, RunStatus, RunSummary, write_summary};
use loam_scene::{Built, Scene, SolverKind};
use std::path::Path;
use std::time::{Duration, Instant};

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
    let SolverKind::Explicit = built.solver.kind;
    let dir = out.map_or_else(|| built.output.dir.clone(), Path::to_path_buf);
    let frame_times = built.frame_times();
    let config = Config {
        grid: built.grid.clone(),
        shape: built.shape,
        transfer: built.solver.transfer,
        scheme: built.solver.scheme,
        boundary: built.boundary,
        gravity: built.gravity,
        materials: built.materials.clone(),
        time_step: built.solver.time_step,
    };
    let mut particles = built.particles;
    let initial = particles.x.clone();
    let mut solver = match Solver::new(config, &particles) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {}: {e}", path.display());
            return Outcome::BadInput;
        }
    };
    let mut writer = match FrameWriter::create(&dir, &built.output.fields) {
        Ok(w) => w,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::Failed;
        }
    };
    let end_time = built.solver.end_time;
    let mut summary = RunSummary {
        scene: path.display().to_string(),
        dimension: D,
        particles: particles.len(),
        steps: 0,
        end_time,
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
    };
    let bar = progress_bar(quiet);
    let start = Instant::now();
    let mut last_draw = Instant::now();
    let mut failure: Option<String> = None;
    for (k, &t) in frame_times.iter().enumerate() {
        if k > 0 {
            let result = solver.advance_to(&mut particles, t, |info, _| {
                summary.dt_min = summary.dt_min.min(info.dt);
                summary.dt_max = summary.dt_max.max(info.dt);
                if last_draw.elapsed() > Duration::from_millis(100) {
                    last_draw = Instant::now();
                    draw(
                        &bar,
                        info.step,
                        info.time,
                        end_time,
                        start.elapsed().as_secs_f64(),
                    );
                }
            });
            if let Err(e) = result {
                failure = Some(e.to_string());
                break;
            }
        }
        let e = solver.energy(&particles);
        summary.energy.push(EnergySample {
            step: solver.steps() as u64,
            time: solver.time(),
            kinetic: e.kinetic,
            strain: e.strain,
            gravity: e.gravity,
            total: e.total(),
        });
        match writer.write_frame(solver.time(), &particles, Some(&initial)) {
            Ok(p) => summary.frames.push(p.display().to_string()),
            Err(e) => {
                failure = Some(e.to_string());
                break;
            }
        }
    }
    bar.finish_and_clear();
    let wall = start.elapsed().as_secs_f64();
    summary.steps = solver.steps() as u64;
    summary.time_reached = solver.time();
    summary.wall_time_s = wall;
    summary.steps_per_second = summary.steps as f64 / wall.max(1e-9);
    summary.particle_steps_per_second = summary.steps_per_second * particles.len() as f64;
    if summary.steps == 0 {
        summary.dt_min = 0.0;
    }
    if let Some(msg) = &failure {
        summary.status = RunStatus::Failed;
        summary.error = Some(msg.clone());
    }
    let summary_path = dir.join("summary.json");
    if let Err(e) = write_summary(&summary_path, &summary) {
        eprintln!("error: {e}");
        return Outcome::Failed;
    }
    match failure {
        None => {
            println!(
                "{}: {} steps to t = {:.4} s in {:.2} s ({:.3e} particle-steps/s, {} particles); wrote {} frames to {} ({})",
                path.display(),
                summary.steps,
                summary.time_reached,
                wall,
                summary.particle_steps_per_second,
                summary.particles,
                summary.frames.len(),
                writer.dir().display(),
                writer.pvd_path().display()
            );
            Outcome::Ok
        }
        Some(msg) => {
            eprintln!("error: {}: {msg}", path.display());
            eprintln!(
                "the {} frame(s) written up to t = {:.4} s remain valid in {}; summary: {}",
                summary.frames.len(),
                summary.time_reached,
                writer.pvd_path().display(),
                summary_path.display()
            );
            Outcome::Failed
        }
    }
}

fn progress_bar(quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(1000);
    bar.set_style(
        ProgressStyle::with_template("{bar:40.cyan/blue} {percent:>3}% {msg}")
            .expect("static template is valid"),
    );
    bar
}

fn draw(bar: &ProgressBar, step: usize, time: f64, end: f64, wall: f64) {
    let frac = (time / end).clamp(0.0, 1.0);
    bar.set_position((frac * 1000.0) as u64);
    let rate = step as f64 / wall.max(1e-9);
    let eta = if frac > 0.0 {
        wall * (1.0 - frac) / frac
    } else {
        f64::NAN
    };
    bar.set_message(format!(
        "t = {time:.4e} / {end:.4e} s, step {step}, {rate:.0} steps/s, ETA {eta:.0} s"
    ));
}
