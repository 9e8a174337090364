//! The limits an inversion is held to before anything runs: the steps of one run
//! (`--max-steps`) and the memory its runs, its adjoint and its observations keep
//! (`--memory-limit`), estimated from the file, the scene's particles and grid.

use crate::preflight::{MemoryLimit, StepLimit};
use loam_core::constitutive::MaterialState;
use loam_core::tensor::{Tensor, Vector};
use loam_explicit::Config;
use loam_inverse::{Checkpoints, Footprint};
use std::mem::size_of;

/// The limits of `loam gradient`, `loam invert` and `loam check` on an inversion file.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// The memory the inversion may use (`None`: unknown, no check).
    pub memory: Option<MemoryLimit>,
    /// The most steps of one run.
    pub steps: StepLimit,
}

/// Bytes an observed row keeps (rounded up): its step and index, `D` values and a share of
/// the map that holds it, in the observations and in the truth run's record.
fn row_bytes<const D: usize>() -> f64 {
    (2 * size_of::<usize>() + size_of::<Vector<f64, D>>() + 32) as f64
}

/// The rows a synthetic inversion observes: `per_step` rows at every observed step
/// `first, first + every, …` up to `steps` (none when `first > steps`).
pub fn observed_steps(first: usize, every: usize, steps: usize) -> usize {
    if first > steps || every == 0 {
        0
    } else {
        (steps - first) / every + 1
    }
}

/// The memory of a gradient of an explicit run of `steps` steps of `config` from `initial`
/// with the segment length `checkpoints` chooses ([`Footprint`]; for the least memory, its
/// minimum `F + 2√(T C R)` at `K ≈ √(T C / R)`, computed directly so that a long run is not
/// scanned; for a budget, the budget), and `rows` observed rows.
pub fn explicit<const D: usize>(
    config: &Config<f64, D>,
    initial: &loam_core::Particles<f64, D>,
    steps: usize,
    checkpoints: Checkpoints,
    rows: f64,
) -> f64 {
    let footprint = Footprint::new(config, initial, steps);
    let gradient = match checkpoints {
        Checkpoints::Segment(k) => footprint.bytes(k) as f64,
        Checkpoints::Memory(budget) => budget as f64,
        Checkpoints::Least => {
            let (t, c, r) = (
                steps as f64,
                footprint.state as f64,
                footprint.traced as f64,
            );
            let k = (t * c / r).sqrt().round().clamp(1.0, t.max(1.0));
            footprint.bytes(k as usize) as f64
        }
    };
    gradient + rows * row_bytes::<D>()
}

/// The memory of an implicit inversion of `steps` load steps of `particles` particles: the
/// recorded run keeps, per step, every particle's start-of-step position, velocity,
/// deformation gradient and history, its positions and velocities after the step and a
/// share of the step's unknowns (`D` per particle, at most); and `rows` observed values.
pub fn implicit<const D: usize>(steps: usize, particles: usize, rows: f64) -> f64 {
    let per_particle = 4 * size_of::<Vector<f64, D>>()
        + size_of::<Tensor<f64, D>>()
        + size_of::<MaterialState<f64>>()
        + D * size_of::<f64>();
    steps as f64 * particles as f64 * per_particle as f64 + rows * row_bytes::<1>()
}

impl Limits {
    /// What is wrong, when a run of `steps` steps is longer than the step limit or the
    /// estimate `bytes` is above the memory limit.
    pub fn exceeded(&self, steps: usize, bytes: f64) -> Option<String> {
        let what = format!("the runs, the adjoint and the observations of {steps} steps");
        self.steps
            .exceeded(steps as f64, "in every run of the inversion")
            .or_else(|| self.memory.and_then(|m| m.exceeded(bytes, &what)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn observed_steps_count_the_steps_from_first_by_every() {
        assert_eq!(observed_steps(20, 20, 800), 40);
        assert_eq!(observed_steps(5, 10, 800), 80);
        assert_eq!(observed_steps(801, 801, 800), 0);
        assert_eq!(observed_steps(800, 1, 800), 1);
    }

    #[test]
    fn an_implicit_record_grows_with_steps_and_particles() {
        // Per particle and step in 2D at least a position, a velocity (2 each), F (4) and
        // the history (10 numbers): 18 numbers.
        let one = implicit::<2>(1, 1, 0.0);
        assert!(one >= 18.0 * 8.0, "{one}");
        assert_eq!(implicit::<2>(10, 64, 0.0), 640.0 * one);
    }
}
