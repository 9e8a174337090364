//! Errors of gradient computations.

use loam_explicit::{ConfigError, StepError};
use loam_implicit::ImplicitError;
use loam_implicit::element::ElementError;
use loam_implicit::linear::LinearError;
use thiserror::Error;

/// Why a gradient could not be computed.
#[derive(Debug, Error)]
pub enum AdjointError {
    /// A parameter that the configuration does not have, or that its model does not use.
    #[error("parameter `{param}`: {msg}")]
    Parameter {
        /// The parameter, as written in messages (`friction[2]`, `materials[0].young`).
        param: String,
        /// What is wrong.
        msg: String,
    },
    /// A configuration the adjoint does not cover (yet).
    #[error("the adjoint does not support {what}: {why}")]
    Unsupported {
        /// The feature, as the scene names it.
        what: String,
        /// Why, and what to use instead.
        why: String,
    },
    /// The forward run was refused.
    #[error("forward run: {0}")]
    Config(#[from] ConfigError),
    /// The forward run stopped.
    #[error("forward run: {0}")]
    Step(#[from] StepError),
    /// An observation that does not fit the run.
    #[error("{field}: {msg}")]
    Observation {
        /// The entry and field, e.g. `observations[3].particle`.
        field: String,
        /// What is wrong.
        msg: String,
    },
    /// The implicit forward run was refused or stopped.
    #[error("forward run: {0}")]
    Implicit(#[from] ImplicitError),
    /// An element test stopped: a stage could not be completed.
    #[error("element test {test}: {source}")]
    Element {
        /// The test (from 0).
        test: usize,
        /// The driver's error.
        source: ElementError,
    },
    /// An adjoint or tangent system of an implicit sub-step could not be solved.
    #[error("load step {step}: {what} system: {source}")]
    Linear {
        /// The load step.
        step: usize,
        /// `adjoint` or `tangent`.
        what: &'static str,
        /// The linear solver's error.
        source: LinearError,
    },
    /// A memory budget below what the gradient of the run needs at least.
    #[error(
        "a memory budget of {} MB is too small: the gradient of this run keeps at least {} MB \
         (checkpoints, one traced segment and the adjoint)",
        budget.div_ceil(1_000_000),
        least.div_ceil(1_000_000)
    )]
    Memory {
        /// The budget, in bytes.
        budget: u64,
        /// The least memory of the run's gradient, in bytes.
        least: u64,
    },
    /// The recomputation of a segment in the reverse pass did not reproduce the forward pass.
    #[error(
        "the reverse pass recomputed step {step} differently from the forward pass ({what}); \
         the forward map is not deterministic here"
    )]
    Replay {
        /// The step.
        step: usize,
        /// What differed.
        what: String,
    },
}

impl AdjointError {
    /// A cotangent of `got` values for `expected` observed quantities.
    pub fn cotangent_length(got: usize, expected: usize) -> Self {
        Self::Observation {
            field: "cotangent".into(),
            msg: format!("has {got} value(s); expected one per observed quantity, {expected}"),
        }
    }
}
