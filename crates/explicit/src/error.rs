//! Errors of the explicit solver: bad configuration and unstable steps.

use thiserror::Error;

/// A configuration the solver cannot run.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ConfigError {
    /// A parameter is out of range.
    #[error("{field}: {msg}")]
    Invalid {
        /// The offending parameter.
        field: String,
        /// What was expected.
        msg: String,
    },
    /// A particle refers to a material that does not exist.
    #[error(
        "particle {particle}: material index {material} is out of range (there are {count} materials)"
    )]
    UnknownMaterial {
        /// Particle id.
        particle: usize,
        /// Its material index.
        material: u32,
        /// Number of materials.
        count: usize,
    },
}

/// Why a step could not be taken; the particle state is left as it was after the last
/// completed step in the fields the check concerns, so output written so far stays valid.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum StepError {
    /// Particles moved so far that their shape-function support leaves the grid.
    #[error(
        "step {step} (t = {time:.6e} s): {} particle(s) left the grid, first ids {:?} at {:?}; enlarge the grid or add walls",
        ids.len(), &ids[..ids.len().min(8)], &positions[..positions.len().min(3)]
    )]
    LeftGrid {
        /// Step number at which it was detected.
        step: usize,
        /// Simulated time.
        time: f64,
        /// Particle ids.
        ids: Vec<usize>,
        /// Their positions (first few).
        positions: Vec<Vec<f64>>,
    },
    /// A NaN or infinity appeared in a particle field.
    #[error(
        "step {step} (t = {time:.6e} s): non-finite {field} in {} particle(s), first ids {:?}; the run is unstable (reduce the time step or check the material)",
        ids.len(), &ids[..ids.len().min(8)]
    )]
    NonFinite {
        /// Step number.
        step: usize,
        /// Simulated time.
        time: f64,
        /// Which field (`position`, `velocity`, `deformation gradient`, `stress`).
        field: &'static str,
        /// Particle ids.
        ids: Vec<usize>,
    },
    /// A particle's deformation gradient has a non-positive determinant.
    #[error(
        "step {step} (t = {time:.6e} s): {} particle(s) inverted (det F ≤ 0), first ids {:?}",
        ids.len(), &ids[..ids.len().min(8)]
    )]
    Inverted {
        /// Step number.
        step: usize,
        /// Simulated time.
        time: f64,
        /// Particle ids.
        ids: Vec<usize>,
    },
    /// Particles crossed a wall (a face whose condition is not `free`) or entered an obstacle.
    #[error(
        "step {step} (t = {time:.6e} s): {} particle(s) crossed {what}, first ids {:?} at {:?}; reduce the time step or check the initial geometry",
        ids.len(), &ids[..ids.len().min(8)], &positions[..positions.len().min(3)]
    )]
    Escaped {
        /// Step number.
        step: usize,
        /// Simulated time.
        time: f64,
        /// The wall (`x_min`, `y_max`, ...) or obstacle (`obstacles[i]`) crossed.
        what: String,
        /// Particle ids.
        ids: Vec<usize>,
        /// Their positions (first few).
        positions: Vec<Vec<f64>>,
    },
    /// A fixed time step above the stability bound `h / (c + |v|)`.
    #[error(
        "step {step} (t = {time:.6e} s): time step {dt:.3e} s exceeds the stability limit {limit:.3e} s = h/(c + |v|) set by particle {particle} (c = {wave_speed:.4e} m/s, |v| = {speed:.4e} m/s); use a smaller dt or an adaptive step"
    )]
    TimeStepTooLarge {
        /// Step number.
        step: usize,
        /// Simulated time.
        time: f64,
        /// Requested step.
        dt: f64,
        /// Stability bound.
        limit: f64,
        /// Particle that sets the bound.
        particle: usize,
        /// Its elastic wave speed.
        wave_speed: f64,
        /// Its speed.
        speed: f64,
    },
}
