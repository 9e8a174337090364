//! The integration tests of `explicit`, one binary (one link) for all of them.

mod contact;
mod determinism;
mod physics;
mod record;
mod stepping;
