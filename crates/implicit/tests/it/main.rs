//! The integration tests of `implicit`, one binary (one link) for all of them.

mod coupled;
mod newmark;
mod rigid;
mod strength_reduction;
