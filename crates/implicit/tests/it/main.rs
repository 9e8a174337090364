//! The integration tests of `implicit`, one binary (one link) for all of them.

mod coupled;
mod newmark;
mod strength_reduction;
