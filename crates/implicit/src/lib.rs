//! # loam-implicit
//!
//! Implicit MPM: Newton–Krylov solves of quasi-static (and Newmark dynamic) load steps with the
//! tangent assembled by sparse forward-mode AD over the same generic kernels as the explicit
//! path.

pub mod linear;
