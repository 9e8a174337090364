//! The integration tests of `scene`, one binary (one link) for all of them.

mod checkpoint;
mod initial_state;
mod output;
mod pore_fluid;
mod scene_files;
mod traction;
