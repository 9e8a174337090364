//! `loam.Study`: an inversion file set up once ([`loam_driver::invert::Study`]) and its loss
//! and gradient `L(θ)`, `dL/dθ` at any parameters, what `loam gradient` prints at the
//! file's first guess; the JAX and PyTorch layers of the package call it.
//!
//! An evaluation runs with the GIL released. It is not interrupted by Ctrl-C: the signal is
//! raised as `KeyboardInterrupt` when the evaluation in progress has finished.

use crate::errors::{inversion_error, simulation_error};
use loam_driver::Outcome;
use loam_driver::invert::{Failure, Limits, Study as Inner, output_folder};
use loam_driver::preflight::{MAX_INVERSION_STEPS, MemoryLimit, StepLimit};
use numpy::{IntoPyArray, PyArray1, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use std::path::PathBuf;

/// An inversion file (`docs/inversion-format.md`) read, validated and set up once.
#[pyclass(module = "loam", frozen)]
pub struct Study {
    inner: Inner,
}

/// The Python exception for a study that could not be set up or evaluated: invalid input
/// (the file, a parameter) is `InversionError`, a run that failed `SimulationError`.
fn raised(py: Python<'_>, f: Failure) -> PyErr {
    match f.outcome {
        Outcome::BadInput => inversion_error(py, f.message),
        _ => simulation_error(f.message),
    }
}

/// The parameters `theta` as float64 values: a one-dimensional float64 NumPy array, or a
/// sequence of numbers. An array of another dtype or shape is refused, naming `theta`, so
/// that nothing is converted silently.
fn parameters(theta: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    if let Ok(a) = theta.cast::<PyUntypedArray>() {
        return match a.cast::<PyArray1<f64>>() {
            Ok(a) => Ok(a.readonly().as_array().to_vec()),
            Err(_) => Err(PyTypeError::new_err(format!(
                "theta: expected a one-dimensional float64 array, got shape {:?} and dtype {}",
                a.shape(),
                a.dtype()
            ))),
        };
    }
    theta.extract::<Vec<f64>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "theta: expected a one-dimensional float64 array or a sequence of numbers, got {}",
            theta
                .get_type()
                .name()
                .map_or("?".into(), |n| n.to_string())
        ))
    })
}

#[pymethods]
impl Study {
    /// Reads and sets up the inversion file `path` (with the checks and messages of
    /// `loam check`). `memory`: the bytes the explicit adjoint may keep (`--memory`),
    /// default the least memory. Raises `InversionError` naming the field of an invalid file.
    #[new]
    #[pyo3(signature = (path, memory = None))]
    fn new(py: Python<'_>, path: PathBuf, memory: Option<u64>) -> PyResult<Self> {
        let limits = Limits {
            memory: MemoryLimit::new(None),
            steps: StepLimit::new(None, MAX_INVERSION_STEPS),
        };
        let inner = py
            .detach(|| Inner::open(&path, memory, limits))
            .map_err(|f| raised(py, f))?;
        Ok(Self { inner })
    }

    /// The named parameters, the first unknowns, in the file's order.
    #[getter]
    fn names(&self) -> Vec<String> {
        self.inner.names().to_vec()
    }

    /// The first guess of every unknown (float64): the named parameters in their physical
    /// units, then any velocity field's network weights.
    #[getter]
    fn initial<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.initial().to_vec().into_pyarray(py)
    }

    /// The named parameters' truth values, when the file gives one for each (else None).
    #[getter]
    fn truth<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        (self.inner.truth()).map(|t| t.to_vec().into_pyarray(py))
    }

    /// `(L, dL/dθ)` at `theta` by loam's discrete adjoint (the same code and bits as
    /// `loam gradient`). Raises `InversionError` for a `theta` of the wrong length or with a
    /// value that is not finite, `SimulationError` for a run that fails.
    fn gradient<'py>(
        &self,
        py: Python<'py>,
        theta: &Bound<'py, PyAny>,
    ) -> PyResult<(f64, Bound<'py, PyArray1<f64>>)> {
        let theta = parameters(theta)?;
        let (loss, grad) = py
            .detach(|| self.inner.gradient(&theta))
            .map_err(|f| raised(py, f))?;
        Ok((loss, grad.into_pyarray(py)))
    }

    /// The relative L2 error of each velocity field at `theta` against the `[synthetic]`
    /// truth, `‖v(θ) − v_true‖ / ‖v_true‖` (empty without a truth or a field).
    fn field_errors(&self, py: Python<'_>, theta: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
        let theta = parameters(theta)?;
        let n = self.inner.initial().len();
        if theta.len() != n {
            return Err(inversion_error(
                py,
                format!("theta has {} value(s); expected {n}", theta.len()),
            ));
        }
        Ok(py.detach(|| self.inner.field_errors(&theta)))
    }

    /// Runs the file's optimiser as `loam invert` does (the same code, iterates and files),
    /// writing `history.csv`, `history.json`, the checkpoint after every iteration, the plots
    /// and what was recovered into `out`, else `out/<file stem>`; with `resume` it continues
    /// from the checkpoint there. Returns the output folder. Ctrl-C stops it after the
    /// iteration in progress, keeps what it wrote and raises `KeyboardInterrupt`; an output
    /// folder that cannot be written or a checkpoint of another file raises
    /// `InversionError`, a run that fails `SimulationError` (the reason is printed on stderr).
    #[pyo3(signature = (out = None, resume = false))]
    fn invert(&self, py: Python<'_>, out: Option<PathBuf>, resume: bool) -> PyResult<PathBuf> {
        let path = self.inner.path().to_path_buf();
        let dir = output_folder(&path, out.as_deref());
        let (outcome, signal) = crate::signals::watched(py, || self.inner.invert(&dir, resume));
        if let Some(e) = signal {
            return Err(e);
        }
        let said = |what: &str| {
            format!(
                "{}: {what} (the reason is printed on stderr)",
                path.display()
            )
        };
        match outcome {
            Ok(Outcome::Ok) => Ok(dir),
            Ok(Outcome::BadInput) => Err(inversion_error(py, said("the inversion was refused"))),
            Ok(Outcome::Interrupted) => {
                Err(simulation_error(said("the inversion was interrupted")))
            }
            Ok(Outcome::Failed) => Err(simulation_error(said("the inversion failed"))),
            Err(_) => Err(simulation_error(format!(
                "{}: the inversion stopped on an internal error",
                path.display()
            ))),
        }
    }
}
