//! The JSON summary of a run: what ran, how far it got, how fast, and the energy history.

use super::{OutputError, write_atomically};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// How a run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RunStatus {
    /// The run reached `end_time`.
    Completed,
    /// The run stopped early with an error (see [`RunSummary::error`]).
    Failed,
    /// The run was interrupted (SIGINT / Ctrl-C, or SIGTERM) and stopped after a complete
    /// step; the frames written so far are a valid series.
    Interrupted,
}

/// The energies of the particle system at one step (J; J per metre of depth in 2D).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EnergySample {
    /// Step number.
    pub step: u64,
    /// Simulated time (s).
    pub time: f64,
    /// Kinetic energy `½ Σ m v²`.
    pub kinetic: f64,
    /// Stored elastic (strain) energy `Σ V₀ ψ(F)`.
    pub strain: f64,
    /// Gravitational potential energy `−Σ m g·x`.
    pub gravity: f64,
    /// `kinetic + strain + gravity`.
    pub total: f64,
}

/// One implicit load step: how Newton did, and the reactions.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LoadStepSummary {
    /// Load step number (1-based).
    pub step: u64,
    /// Load factor reached (0 … 1).
    pub load_factor: f64,
    /// Newton iterations of the converged solves.
    pub iterations: u64,
    /// Times the step was cut in half.
    pub cuts: u64,
    /// Final residual norm relative to the step's reference.
    pub residual: f64,
    /// Linear-solver iterations, summed over the Newton iterations.
    pub linear_iterations: u64,
    /// Wall-clock time of the step (s).
    pub wall_time_s: f64,
    /// Per `[[constraints]]` entry, in file order, the total force its prescribed
    /// displacements exert on the material at the end of the step, one component per axis
    /// (N; N per metre run in 2D; a footing pushed down has a negative vertical force); on a
    /// force-controlled component, the applied force it balances.
    #[serde(default)]
    pub constraint_forces: Vec<Vec<f64>>,
    /// Scenes with a force-controlled constraint: per `[[constraints]]` entry, the total
    /// displacement of each force-controlled component since the start (m; the settlement of
    /// a loading plate is negative), `null` for the other components.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub constraint_displacements: Vec<Vec<Option<f64>>>,
    /// Coupled (u–p) runs: the time at the end of the step, in the summary's `time_unit`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<f64>,
    /// Coupled runs: the degree of consolidation `U = 1 − ∫ p_e dV / ∫ p_e,0 dV`, the share
    /// of the excess pore pressure at the end of the loading (`p_e,0`) that has drained.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub degree_of_consolidation: Option<f64>,
    /// Coupled runs: the largest excess pore pressure of the particles (Pa, compression
    /// positive).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_excess_pore_pressure: Option<f64>,
}

/// The history of one `[[probes]]` entry: the particle it follows after every load step.
/// Signs are the geotechnical ones: settlement, pressures and `p′` positive in compression.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ProbeHistory {
    /// The probe's name.
    pub name: String,
    /// The particle it follows.
    pub particle: u64,
    /// The particle's initial position (m).
    pub position: Vec<f64>,
    /// Settlement, the downward displacement `−u_z` along the last axis (m).
    pub settlement: Vec<f64>,
    /// Displacement from the initial position, one component per axis (m).
    pub displacement: Vec<Vec<f64>>,
    /// Mean effective stress `p′ = −tr σ′ / 3` (Pa, compression positive).
    pub mean_effective_stress: Vec<f64>,
    /// Deviatoric stress `q = √(3 J₂)` (Pa).
    pub deviatoric_stress: Vec<f64>,
    /// Coupled runs: the pore pressure (Pa, compression positive).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pore_pressure: Vec<f64>,
    /// Coupled runs: the excess pore pressure over the water table's hydrostatic pressure
    /// (Pa).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub excess_pore_pressure: Vec<f64>,
}

/// The mean force of every rigid obstacle on the material over the interval that ends at a
/// frame of an explicit run (CPU): `(I(t) − I(t_prev)) / (t − t_prev)`, `I` the impulse the
/// obstacle has given the material (`loam_explicit::Solver::obstacle_impulse`). Explicit
/// forces ring from step to step with the material's waves; the mean over the interval
/// between frames is their physically meaningful part.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObstacleForceSample {
    /// Step number at the frame.
    pub step: u64,
    /// Simulated time at the frame (s).
    pub time: f64,
    /// Start of the interval: the time of the previous frame (s).
    pub since: f64,
    /// Per `[[obstacles]]` entry, in file order, the mean force it exerted on the material
    /// over `[since, time]`, one component per axis (N; N per metre run in 2D; a footing
    /// pushed down has a negative vertical force, as the reactions of implicit runs).
    pub forces: Vec<Vec<f64>>,
    /// Per obstacle, its displacement `v t` at `time` (m), one component per axis.
    pub displacements: Vec<Vec<f64>>,
}

/// What a run did, written as `summary.json` next to its frames. Non-finite numbers (say
/// `dt_min` of a run that failed before its first step) are written as JSON `null`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunSummary {
    /// The scene (its file path, or a name).
    pub scene: String,
    /// Spatial dimension, 2 or 3.
    pub dimension: usize,
    /// Number of particles.
    pub particles: usize,
    /// Time steps taken.
    pub steps: u64,
    /// The scene's end time (s; in `time_unit` for a coupled run).
    pub end_time: f64,
    /// Coupled (u–p) runs: the unit of the times in this summary and the frames
    /// (`solver.consolidation.time_unit`, e.g. `"day"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_unit: Option<String>,
    /// Simulated time reached (s): `end_time` unless the run stopped early (with a fixed
    /// step Δt, `steps · Δt`, within half a step of `end_time`).
    pub time_reached: f64,
    /// Smallest time step taken (s).
    pub dt_min: f64,
    /// Largest time step taken (s).
    pub dt_max: f64,
    /// Wall-clock time of the time loop (s).
    pub wall_time_s: f64,
    /// `steps / wall_time_s`.
    pub steps_per_second: f64,
    /// `particles · steps / wall_time_s`.
    pub particle_steps_per_second: f64,
    /// How the run ended.
    pub status: RunStatus,
    /// Why the run failed (`None` when it completed).
    pub error: Option<String>,
    /// Things worth a look that did not stop the run.
    #[serde(default)]
    pub warnings: Vec<String>,
    /// Energy history.
    pub energy: Vec<EnergySample>,
    /// Frame files written, relative to the output folder, in time order.
    pub frames: Vec<String>,
    /// Implicit runs: the Newton report of every load step (empty for explicit runs).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub load_steps: Vec<LoadStepSummary>,
    /// Implicit runs with `[[probes]]`: each probe's history, one sample per entry of
    /// `load_steps` (also written as `probes.csv`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub probes: Vec<ProbeHistory>,
    /// Explicit runs on the CPU with `[[obstacles]]`: the mean force of each obstacle on the
    /// material between consecutive frames (also written as
    /// [`FrameWriter::OBSTACLE_FORCES_NAME`](super::FrameWriter::OBSTACLE_FORCES_NAME)).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub obstacle_forces: Vec<ObstacleForceSample>,
    /// A run continued from a checkpoint (`loam run --resume`): the state it started from.
    /// `steps` and `time_reached` count from the start of the original run; the timings
    /// cover the continued part only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resumed_from: Option<CheckpointNote>,
    /// The last checkpoint this run wrote (`loam run --checkpoint-every`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checkpoint: Option<CheckpointNote>,
    /// Explicit runs on the GPU: the adapter and how P2G added into the grid, e.g.
    /// `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu) (P2G: scatter, native f32 atomics,
    /// subgroup sums)` (a run with the gather gives the same bits every time, one with atomics
    /// to f32 round-off); absent for CPU runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device: Option<String>,
}

/// A checkpoint file and the state it holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CheckpointNote {
    /// The checkpoint file.
    pub path: String,
    /// Steps completed at the checkpoint.
    pub step: u64,
    /// Simulated time at the checkpoint (s).
    pub time: f64,
}

/// Writes the summary as pretty-printed JSON, atomically.
pub fn write_summary(path: &Path, summary: &RunSummary) -> Result<(), OutputError> {
    let mut json = serde_json::to_string_pretty(summary).map_err(OutputError::Json)?;
    json.push('\n');
    write_atomically(path, json.as_bytes())
}

/// Writes the samples of the obstacles' forces as CSV, atomically: one row per sample,
/// `step,time,since` and then per obstacle `k` its force `obstacles[k].f<axis>` (N, N/m in 2D)
/// and displacement `obstacles[k].u<axis>` (m), with the axes `x, y(, z)`.
pub fn write_obstacle_forces(
    path: &Path,
    samples: &[ObstacleForceSample],
) -> Result<(), OutputError> {
    let obstacles = samples.first().map_or(0, |s| s.forces.len());
    let dim = samples
        .first()
        .and_then(|s| s.forces.first())
        .map_or(0, Vec::len);
    let axes = &["x", "y", "z"][..dim];
    let mut text = String::from("step,time,since");
    for k in 0..obstacles {
        for what in ["f", "u"] {
            for a in axes {
                text.push_str(&format!(",obstacles[{k}].{what}{a}"));
            }
        }
    }
    text.push('\n');
    for s in samples {
        text.push_str(&format!("{},{:e},{:e}", s.step, s.time, s.since));
        for (f, u) in s.forces.iter().zip(&s.displacements) {
            for c in f.iter().chain(u) {
                text.push_str(&format!(",{c:e}"));
            }
        }
        text.push('\n');
    }
    write_atomically(path, text.as_bytes())
}
