//! The integration tests of `cli`, one binary (one link) for all of them.

mod cli;
mod common;
mod coupled;
mod fos;
mod gpu;
mod initial_state;
mod invert;
mod invert_element;
mod invert_implicit;
mod obstacle_forces;
mod restart;
