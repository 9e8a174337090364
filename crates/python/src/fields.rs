//! The particle state as flat arrays with their shapes, ready to become NumPy arrays.

use loam_core::Particles;
use loam_core::tensor::Tensor;
use numpy::{IntoPyArray, PyArrayDyn, PyArrayMethods};
use pyo3::prelude::*;

/// A per-particle quantity of the state.
#[derive(Clone, Copy, Debug)]
pub enum Field {
    /// Positions, N × D (m).
    Positions,
    /// Velocities, N × D (m/s).
    Velocities,
    /// Cauchy stress, N × 3 × 3 (Pa, tension positive).
    Stress,
    /// Deformation gradient, N × D × D.
    DeformationGradient,
    /// Pore pressure, N (Pa).
    PorePressure,
    /// Mass, N (kg; per metre of thickness in 2D).
    Mass,
}

/// Values in row-major order and their shape.
pub struct Array<T> {
    /// The values, row-major.
    pub data: Vec<T>,
    /// The shape.
    pub shape: Vec<usize>,
}

impl<T: numpy::Element> Array<T> {
    /// The NumPy array.
    pub fn into_numpy(self, py: Python<'_>) -> PyResult<Bound<'_, PyArrayDyn<T>>> {
        self.data.into_pyarray(py).reshape(self.shape)
    }
}

/// `field` of every particle of `p`, copied.
pub fn field<const D: usize>(p: &Particles<f64, D>, field: Field) -> Array<f64> {
    let n = p.len();
    match field {
        Field::Positions => Array {
            data: p.x.iter().flat_map(|x| x.iter().copied()).collect(),
            shape: vec![n, D],
        },
        Field::Velocities => Array {
            data: p.v.iter().flat_map(|v| v.iter().copied()).collect(),
            shape: vec![n, D],
        },
        Field::Stress => Array {
            data: p.stress.iter().flat_map(row_major::<3>).collect(),
            shape: vec![n, 3, 3],
        },
        Field::DeformationGradient => Array {
            data: p.f.iter().flat_map(row_major::<D>).collect(),
            shape: vec![n, D, D],
        },
        Field::PorePressure => Array {
            data: p.pore_pressure.clone(),
            shape: vec![n],
        },
        Field::Mass => Array {
            data: p.mass.clone(),
            shape: vec![n],
        },
    }
}

/// The material index of every particle (its place in the scene's `[[materials]]`).
pub fn material<const D: usize>(p: &Particles<f64, D>) -> Array<i64> {
    Array {
        data: p.material.iter().map(|&m| i64::from(m)).collect(),
        shape: vec![p.len()],
    }
}

/// The entries of a square matrix row by row (nalgebra stores columns).
fn row_major<const N: usize>(m: &Tensor<f64, N>) -> Vec<f64> {
    m.transpose().iter().copied().collect()
}
