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
//! - [`gradient`] runs the forward pass with checkpoints every `K` steps (`K ≈ √T` for the
//!   least memory, or the largest `K` a memory budget allows: [`Checkpoints`]) and the reverse
//!   pass segment by segment over traced steps, so memory grows as `√T`, not `T`.
//! - [`Param`] names a parameter; [`Objective`] is a loss over the run's states
//!   ([`TrackedPositions`], [`VelocityMonitors`], [`DepositProfile`], their sum
//!   [`Observations`]).
//! - [`Problem`] is an inversion's loss as a function of its unknowns ([`Control`]: the
//!   parameters, initial velocities and velocity fields given by an MLP, [`VelocityField`]),
//!   with its gradient by the adjoint and, as the oracle,
//!   by a forward-mode dual run; [`Variable`] reparameterises an unknown for an optimiser
//!   (softplus, bounds); [`Optimiser`] is Adam with a decaying rate or L-BFGS.
//!
//! - [`implicit`]: the same for an implicit run, quasi-static or Newmark, by the adjoint of
//!   its load steps (one transposed solve with each accepted sub-step's tangent).
//!
//! - [`element`]: the same for element tests (one material point through laboratory paths),
//!   by forward-mode duals through the element driver: material constants fitted to
//!   laboratory curves.
//!
//! - [`check`] compares a gradient with branch-aware central differences and runs the
//!   Taylor test; [`choose`] picks tracked particles reproducibly.
//!
//! The forward-mode dual run (`Solver<Dual64, D>` on a configuration lifted with one seeded
//! parameter) is the test oracle: the adjoint agrees with it to round-off.

mod adjoint_state;
pub mod check;
mod checkpoints;
mod deposit;
pub mod element;
mod error;
mod field;
mod gradient;
pub mod implicit;
mod k0;
pub mod lanes;
mod objective;
mod observe;
pub mod optimise;
mod params;
mod problem;
mod step;
mod variable;

pub use adjoint_state::ParticleAdjoint;
pub use checkpoints::{Checkpoints, Footprint};
pub use deposit::{DepositProfile, Station};
pub use error::AdjointError;
pub use field::{Mlp, SplitMix64, VelocityField};
pub use gradient::{Gradient, Phases, gradient};
pub use k0::K0State;
pub use objective::{Objective, Pullback, ScalarObjective, TrackedPositions};
pub use observe::{MonitorBox, Observations, VelocityMonitors, choose};
pub use optimise::{Adam, Evaluation, Lbfgs, LevenbergMarquardt, Optimiser};
pub use params::{Acts, MaterialField, Param};
pub use problem::{Control, GaussNewtonModel, GradientCost, Problem, run_collected, run_value};
pub use step::ReverseStep;
pub use variable::{Transform, Variable, softplus, softplus_inverse};
