//! Time-integration choices shared by the solvers and the scene files (plain data).

use serde::{Deserialize, Serialize};

/// Order of the explicit update within a step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Scheme {
    /// Update Stress Last: the velocity gradient comes from the grid velocity of the step.
    Usl,
    /// Modified USL: particle velocities are mapped back to the grid (second P2G) and the
    /// velocity gradient is taken from that smoother field; the usual default.
    #[default]
    Musl,
}

/// How the time step is chosen.
///
/// Written as a table tagged by `type`, `{ type = "fixed", dt = 1e-4 }` or
/// `{ type = "adaptive", cfl = 0.4, max_dt = 1e-3 }`; an unknown key is an error (see
/// [`crate::serde_form`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum TimeStep {
    /// A constant `Δt`; the run stops if it exceeds the stability bound
    /// `h / (c + |v|_max)` (`c` the elastic P-wave speed).
    Fixed {
        /// The step size.
        dt: f64,
    },
    /// `Δt = cfl · h / (c + |v|_max)` every step, capped by `max_dt`.
    Adaptive {
        /// Courant number (0 < cfl ≤ 1; 0.3–0.5 usual).
        cfl: f64,
        /// Upper bound on `Δt`.
        max_dt: f64,
    },
}
