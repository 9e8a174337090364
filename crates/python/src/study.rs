//! `loam.Study`: an inversion file set up once ([`loam_driver::invert::Study`]) and its loss
//! and gradient `L(θ)`, `dL/dθ` at any parameters, what `loam gradient` prints at the
//! file's first guess; the JAX and PyTorch layers of the package call it.
//!
//! An evaluation runs with the GIL released. It is not interrupted by Ctrl-C: the signal is
//! raised as `KeyboardInterrupt` when the evaluation in progress has finished.

use crate::arrays::vector;
use crate::errors::{inversion_error, simulation_error};
use loam_driver::Outcome;
use loam_driver::invert::{Failure, Limits, Study as Inner, output_folder};
use loam_driver::preflight::{MAX_INVERSION_STEPS, MemoryLimit, StepLimit};
use numpy::{IntoPyArray, PyArray1};
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

/// The parameters `theta` as float64 values ([`vector`]).
fn parameters(theta: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    vector(theta, "theta")
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

    /// The observed quantities of the file, in the order of `observe` and `vjp`: their labels
    /// (`step 120: x of particle 7`), data `d` and weights `c`, so that the file's loss is
    /// `L = Σ c (y − d)²`.
    fn observations<'py>(
        &self,
        py: Python<'py>,
    ) -> (
        Vec<String>,
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray1<f64>>,
    ) {
        let obs = self.inner.observations();
        let data: Vec<f64> = obs.iter().map(|o| o.1).collect();
        let weights: Vec<f64> = obs.iter().map(|o| o.2).collect();
        let labels = obs.into_iter().map(|o| o.0).collect();
        (labels, data.into_pyarray(py), weights.into_pyarray(py))
    }

    /// The observed quantities `y(θ)` at `theta` (float64, the model's values, not misfits)
    /// by a forward run. Raises `InversionError` for a bad `theta`, `SimulationError` for a
    /// run that fails.
    fn observe<'py>(
        &self,
        py: Python<'py>,
        theta: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let theta = parameters(theta)?;
        let y = py
            .detach(|| self.inner.observe(&theta))
            .map_err(|f| raised(py, f))?;
        Ok(y.into_pyarray(py))
    }

    /// `ȳᵀ ∂y/∂θ` at `theta` for the cotangent `ȳ` of the observed quantities, by loam's
    /// discrete adjoint seeded with `ȳ`. Raises `InversionError` for a `theta` or a
    /// cotangent of the wrong length or with a value that is not finite.
    fn vjp<'py>(
        &self,
        py: Python<'py>,
        theta: &Bound<'py, PyAny>,
        cotangent: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let theta = parameters(theta)?;
        let cotangent = vector(cotangent, "cotangent")?;
        let g = py
            .detach(|| self.inner.vjp(&theta, &cotangent))
            .map_err(|f| raised(py, f))?;
        Ok(g.into_pyarray(py))
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
