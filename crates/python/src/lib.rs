//! The compiled module `loam._loam` of the Python package `loam` (distribution `loam-mpm`):
//! scenes ([`scene`]), a simulation stepped from Python ([`simulation`]), runs as `loam run`
//! makes them ([`run`]), the frames they write ([`series`]) and inversion files' gradients
//! and optimisations ([`study`]).
//!
//! The package's Python layer (`python/loam/`) re-exports these with docstrings and type
//! hints; `docs/python.md` documents the API.

mod arrays;
mod engine;
mod errors;
mod fields;
mod run;
mod scene;
mod series;
mod signals;
mod simulation;
mod study;

use pyo3::prelude::*;

/// The module `loam._loam`.
#[pymodule]
fn _loam(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    // The interpreter owns SIGINT (`KeyboardInterrupt`): runs started from Python never
    // install loam's own signal handler, and the run functions report a Ctrl-C themselves.
    loam_driver::run::interrupt::leave_signals_to_front_end();
    m.add("SceneError", py.get_type::<errors::SceneError>())?;
    m.add("SimulationError", py.get_type::<errors::SimulationError>())?;
    m.add("InversionError", py.get_type::<errors::InversionError>())?;
    m.add_class::<scene::Scene>()?;
    m.add_class::<simulation::Simulation>()?;
    m.add_class::<study::Study>()?;
    m.add_function(wrap_pyfunction!(run::run, m)?)?;
    m.add_function(wrap_pyfunction!(series::read_series, m)?)?;
    Ok(())
}
