//! # loam-inverse
//!
//! Back-analysis for loam: the exact gradient of a loss over an explicit MPM run with respect
//! to the parameters of the setup (friction coefficients, gravity, material constants) and the
//! initial particle state, by the discrete adjoint of the step.
//!
//! - [`ReverseStep`] maps the adjoint of the state after one step to the state before it,
//!   stage by stage (P2G, grid-node update, G2P, particle end): the transfers' adjoints are
//!   written for the stencil, the per-node and per-particle kernels' local Jacobians come
//!   from forward-mode duals ([`lanes`]).
//! - [`gradient`] runs the forward pass with checkpoints every `K ≈ √T` steps and the reverse
//!   pass segment by segment, so memory grows as `√T`, not `T`.
//! - [`Param`] names a parameter; [`Objective`] is a loss over the run's states
//!   ([`TrackedPositions`]).
//!
//! The forward-mode dual run (`Solver<Dual64, D>` on a configuration lifted with one seeded
//! parameter) is the test oracle: the adjoint agrees with it to round-off.

mod adjoint_state;
mod error;
mod gradient;
pub mod lanes;
mod objective;
mod params;
mod step;

pub use adjoint_state::ParticleAdjoint;
pub use error::AdjointError;
pub use gradient::{Gradient, gradient, segment_length};
pub use objective::{Objective, TrackedPositions};
pub use params::{Acts, MaterialField, Param};
pub use step::ReverseStep;
