//! The exceptions the module raises: `SceneError` (a `ValueError`) for a scene that cannot
//! be read, is invalid or would be refused by a run, `SimulationError` (a `RuntimeError`) for
//! a run or a step that fails.

use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use std::path::Path;

pyo3::create_exception!(
    loam,
    SceneError,
    PyValueError,
    "A scene that cannot be read, parsed or validated, or that a run refuses. The message is \
     what `loam check` prints; `path` is the field path of the first problem (None when the \
     problem is not about one field) and `issues` lists every problem as (path, message) \
     pairs."
);

pyo3::create_exception!(
    loam,
    SimulationError,
    PyRuntimeError,
    "A simulation or a run that failed: an unstable step (a NaN, a particle leaving the \
     grid), a solver that did not converge, or a run whose outcome was not a success."
);

pyo3::create_exception!(
    loam,
    InversionError,
    PyValueError,
    "An inversion file that cannot be read or is invalid, or parameters it refuses (a wrong \
     length, a value that is not finite, a value out of its range). The message names the \
     file and the field or the parameter, as `loam check` and `loam gradient` print it."
);

/// An `InversionError` with `message`.
pub fn inversion_error(_py: Python<'_>, message: impl Into<String>) -> PyErr {
    InversionError::new_err(message.into())
}

/// The Python exception for a scene error, with its `path` and `issues` attributes.
pub fn scene_error(py: Python<'_>, e: &loam_scene::SceneError) -> PyErr {
    let issues = (e.issues().iter())
        .map(|i| (i.path.clone(), i.message.clone()))
        .collect();
    with_issues(py, e.to_string(), issues)
}

/// A `SceneError` for a scene that parses and validates but that a run would refuse (too
/// large for the memory, a fixed step above the stability limit): `message` starts with the
/// field it names, and the scene file (`source`) goes before it as `loam run` prints it.
pub fn refused_scene(py: Python<'_>, source: Option<&Path>, message: &str) -> PyErr {
    let text = match source {
        Some(file) => format!("{}: {message}", file.display()),
        None => message.to_owned(),
    };
    let issue = match message.split_once(": ") {
        Some((field, rest)) => (field.to_owned(), rest.to_owned()),
        None => (String::new(), message.to_owned()),
    };
    with_issues(py, text, vec![issue])
}

/// A `SceneError` with the message `text`, the attribute `issues` and the attribute `path`,
/// the first issue's field path (None when it has none).
pub fn with_issues(py: Python<'_>, text: String, issues: Vec<(String, String)>) -> PyErr {
    let err = SceneError::new_err(text);
    let path = (issues.first())
        .map(|(path, _)| path.clone())
        .filter(|p| !p.is_empty());
    let value = err.value(py);
    match value
        .setattr("path", path)
        .and_then(|()| value.setattr("issues", issues))
    {
        Ok(()) => err,
        Err(e) => e,
    }
}

/// A `SimulationError` with `message`.
pub fn simulation_error(message: impl Into<String>) -> PyErr {
    SimulationError::new_err(message.into())
}
