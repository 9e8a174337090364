//! # loam-implicit
//!
//! Implicit MPM: Newton–Krylov solves of quasi-static load steps with the tangent assembled by
//! sparse forward-mode AD over the same generic kernels as the explicit path.
//!
//! - [`kernel`]: the per-particle stress kernel of the updated-Lagrangian step, generic over
//!   the scalar type.
//! - [`balance`]: the per-particle force that balances a prestressed body's initial stress
//!   against gravity on the grid, so a K0 state is kept through the first load step.
//! - [`dofs`]: unknowns, walls (mirror images), prescribed displacements.
//! - [`flow`]: the pore fluid of a coupled (u–p) step: the mixture and fluid balances,
//!   their AD tangents, the pressure stabilisation and the time schedule.
//! - [`system`]: residual, the per-particle AD tangent and the block-colour-seeded reference
//!   tangent, particle update.
//! - [`newton`]: Newton with line search; [`solver`]: load stepping with step cutting.
//! - [`linear`]: sparse direct (faer LU / Cholesky) and preconditioned Krylov solvers.
//! - [`element`]: element tests, one material point under mixed strain and stress control.
//! - [`strength_reduction`]: the factor of safety of a loading by strength reduction, a
//!   search over ordinary runs with the strength divided by a trial factor.

pub mod balance;
pub mod dofs;
pub mod element;
pub mod flow;
pub mod kernel;
pub mod linear;
pub mod newton;
pub mod solver;
pub mod strength_reduction;
pub mod system;

pub use balance::{Balance, balance_initial_stress, balance_rate};
pub use dofs::NodeDof;
pub use loam_core::{NodeConstraint, PointLoad};
pub use newton::{NewtonReport, NewtonSettings, TangentMethod};
pub use solver::{
    AcceptedStep, FluidHistory, ImplicitConfig, ImplicitError, ImplicitSolver, StepReport,
};
