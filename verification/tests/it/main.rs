//! The integration tests of `verification`, one binary (one link) for all of them.

mod cases;
mod dual_derivative;
mod scenes;
