//! What loam does with a scene or an inversion file, behind its front ends: the `loam`
//! command-line program and the Python package call the same functions.
//!
//! - [`run`]: a run of a scene (explicit on the CPU or the GPU, or implicit), its frames,
//!   summary, probes and checkpoints, and a Ctrl-C that stops it cleanly;
//! - [`check`]: a scene's validation and its size, memory and step estimates
//!   ([`preflight`]);
//! - [`fos`]: the factor of safety by strength reduction;
//! - [`material`]: element tests of one material point;
//! - [`invert`]: the gradient and the back-analysis of an inversion file.
//!
//! Each command prints its own messages and returns an [`Outcome`], which a front end turns
//! into an exit code or an exception.

pub mod check;
pub mod fos;
pub mod invert;
pub mod material;
pub mod preflight;
pub mod run;

/// The outcome of a command: which exit code, after the command printed its own messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Everything passed.
    Ok,
    /// A run or a check of results failed (exit 1).
    Failed,
    /// The input was invalid (exit 2).
    BadInput,
    /// A signal stopped the run (exit 130).
    Interrupted,
}
