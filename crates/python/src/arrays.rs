//! NumPy arguments checked before they reach loam: float64 vectors and matrices of the
//! expected shape, refused by name otherwise, so that nothing is converted silently.

use numpy::{PyArray1, PyArray2, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// The argument `name` as float64 values: a one-dimensional float64 NumPy array, or a
/// sequence of numbers. An array of another dtype or shape is refused, naming the argument,
/// so that nothing is converted silently.
pub fn vector(values: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<f64>> {
    if let Ok(a) = values.cast::<PyUntypedArray>() {
        return match a.cast::<PyArray1<f64>>() {
            Ok(a) => Ok(a.readonly().as_array().to_vec()),
            Err(_) => Err(PyTypeError::new_err(format!(
                "{name}: expected a one-dimensional float64 array, got shape {:?} and dtype {}",
                a.shape(),
                a.dtype()
            ))),
        };
    }
    values.extract::<Vec<f64>>().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name}: expected a one-dimensional float64 array or a sequence of numbers, got {}",
            values
                .get_type()
                .name()
                .map_or("?".into(), |n| n.to_string())
        ))
    })
}

/// The argument `name` as an `shape[0]` × `shape[1]` float64 NumPy array of finite values,
/// row-major. Another dtype is a `TypeError`, another shape or a value that is not finite a
/// `ValueError`, each naming the argument.
pub fn matrix(values: &Bound<'_, PyAny>, name: &str, shape: [usize; 2]) -> PyResult<Vec<f64>> {
    let a = values.cast::<PyUntypedArray>().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name}: expected a float64 NumPy array of shape {shape:?}"
        ))
    })?;
    let Ok(a) = a.cast::<PyArray2<f64>>() else {
        if a.ndim() == 2 {
            return Err(PyTypeError::new_err(format!(
                "{name}: expected dtype float64, got {}",
                a.dtype()
            )));
        }
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape {shape:?}, got {:?}",
            a.shape()
        )));
    };
    let a = a.readonly();
    let view = a.as_array();
    if view.shape() != shape {
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape {shape:?}, got {:?}",
            view.shape()
        )));
    }
    let data: Vec<f64> = view.iter().copied().collect();
    if let Some(k) = data.iter().position(|v| !v.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "{name}[{}, {}] = {}: expected a finite number",
            k / shape[1],
            k % shape[1],
            data[k]
        )));
    }
    Ok(data)
}
