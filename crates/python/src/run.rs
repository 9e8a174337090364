//! `loam.run`: a run of a scene exactly as `loam run` makes it (frames, `summary.json`),
//! through the same driver code.
//!
//! The run goes on a thread of its own ([`crate::signals::watched`]): Ctrl-C stops it after
//! its step in progress, and `KeyboardInterrupt` is raised once it has written its summary.

use crate::errors::{simulation_error, with_issues};
use crate::scene::expect_scene;
use loam_driver::Outcome;
use loam_driver::preflight::{MAX_STEPS, MemoryLimit, StepLimit};
use loam_driver::run::{Options, run_scene};
use loam_scene::Device;
use loam_scene::output::FrameWriter;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::path::PathBuf;

/// Runs `scene` as `loam run` does, writing its frames and `summary.json` to `out` (else the
/// scene's `output.dir`), and returns the output folder. `device` (`"cpu"` or `"gpu"`)
/// overrides the scene's `solver.device`. A failed run raises `SimulationError` with the
/// summary's error, a run refused before its first step `SceneError`, an interrupted one
/// `KeyboardInterrupt`.
#[pyfunction]
#[pyo3(signature = (scene, out = None, quiet = true, device = None))]
pub fn run(
    py: Python<'_>,
    scene: &Bound<'_, PyAny>,
    out: Option<PathBuf>,
    quiet: bool,
    device: Option<&str>,
) -> PyResult<PathBuf> {
    let scene = expect_scene(scene)?;
    let (label, scene) = (scene.label(), &scene.inner);
    let device = match device {
        None => None,
        Some("cpu") => Some(Device::Cpu),
        Some("gpu") => Some(Device::Gpu),
        Some(other) => {
            return Err(PyValueError::new_err(format!(
                "device: expected \"cpu\" or \"gpu\", got {other:?}"
            )));
        }
    };
    let dir = out.clone().unwrap_or_else(|| scene.output_dir());
    let options = Options {
        out: out.as_deref(),
        quiet,
        progress_every: 5.0,
        memory_limit: MemoryLimit::new(None),
        max_steps: StepLimit::new(None, MAX_STEPS),
        checkpoint_every: None,
        device,
        p2g: None,
    };
    let (outcome, signal) = crate::signals::watched(py, || run_scene(scene, &label, &options));
    if let Some(e) = signal {
        return Err(e);
    }
    match outcome {
        Ok(Outcome::Ok) => Ok(dir),
        Ok(Outcome::Interrupted) => Err(simulation_error("the run was interrupted")),
        Ok(Outcome::BadInput) => Err(with_issues(
            py,
            format!(
                "{}: the run refused the scene before its first step (the reason is printed \
                 above, on stderr)",
                label.display()
            ),
            Vec::new(),
        )),
        Ok(Outcome::Failed) => Err(simulation_error(failure(&dir).unwrap_or_else(|| {
            format!(
                "{}: the run failed (the reason is printed above, on stderr)",
                label.display()
            )
        }))),
        Err(_) => Err(simulation_error(format!(
            "{}: the run stopped on an internal error",
            label.display()
        ))),
    }
}

/// The error recorded in the summary of the run in `dir`, if it wrote one.
fn failure(dir: &std::path::Path) -> Option<String> {
    let text = std::fs::read_to_string(dir.join(FrameWriter::SUMMARY_NAME)).ok()?;
    let summary: loam_scene::output::RunSummary = serde_json::from_str(&text).ok()?;
    summary.error
}
