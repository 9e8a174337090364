//! # loam-explicit
//!
//! Explicit MPM time stepping (USL and MUSL) on the CPU with rayon.
//!
//! One step maps `(particles, parameters) → particles`; the grid is scratch rebuilt every step.
//! P2G is deterministic: particles are sorted into blocks of 4^D cells, every block accumulates
//! into its own buffer, and each node then sums the buffers that cover it in a fixed order, so
//! the result has the same bits at any thread count (no atomics, no races).
//! Everything is generic over `T: Scalar`, so a whole run can be carried with dual numbers to
//! get derivatives of the trajectory with respect to material parameters.

mod blocks;
mod config;
mod error;
pub mod pool;
mod solver;
mod trace;

pub use config::Config;
pub use error::{ConfigError, StepError};
pub use loam_core::Energy;
pub use solver::{MASS_EPS, Solver, StepInfo};
pub use trace::{GridFields, GroupTrace, StepTrace};
