//! The integration tests of `inverse`, one binary (one link) for all of them.

mod adjoint;
mod common;
mod implicit_adjoint;
mod implicit_inversion;
mod observations;
mod obstacle_velocity;
