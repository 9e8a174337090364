//! `loam.read_series`: the frames of a run's output folder (`particles.pvd` and the `.vtu`
//! files it lists), read with vtkio.

use crate::fields::Array;
use loam_scene::output::{FrameWriter, read_pvd};
use pyo3::exceptions::{PyFileNotFoundError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};
use vtkio::model::{Attribute, DataSet, ElementType, IOBuffer, Piece, UnstructuredGridPiece, Vtk};

/// The times of the frames of the run in `folder` and, per frame, a dict of its fields by
/// name (`"position"` for the points) as NumPy arrays: float64 for real fields, int64 for
/// integer ones (`material_id`, `id`). Vectors are N × 3 and tensors N × 3 × 3, as written
/// (zero-padded to 3D in 2D runs).
#[pyfunction]
pub fn read_series<'py>(
    py: Python<'py>,
    folder: PathBuf,
) -> PyResult<(Vec<f64>, Vec<Bound<'py, PyDict>>)> {
    let pvd = folder.join(FrameWriter::PVD_NAME);
    if !pvd.is_file() {
        return Err(PyFileNotFoundError::new_err(format!(
            "folder: no {} in {}",
            FrameWriter::PVD_NAME,
            folder.display()
        )));
    }
    let entries = read_pvd(&pvd).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let mut times = Vec::with_capacity(entries.len());
    let mut frames = Vec::with_capacity(entries.len());
    for entry in entries {
        let piece = read_piece(&folder.join(&entry.file))?;
        let frame = PyDict::new(py);
        let n = piece.num_points();
        frame.set_item("position", numbers(py, piece.points, vec![n, 3])?)?;
        for attribute in piece.data.point {
            if let Attribute::DataArray(array) = attribute {
                let shape = match (array.elem, array.data.len() / n.max(1)) {
                    (ElementType::Tensors, _) => vec![n, 3, 3],
                    (_, 1) => vec![n],
                    (_, components) => vec![n, components],
                };
                frame.set_item(array.name, numbers(py, array.data, shape)?)?;
            }
        }
        times.push(entry.time);
        frames.push(frame);
    }
    Ok((times, frames))
}

/// The inline unstructured-grid piece of the frame file `path`.
fn read_piece(path: &Path) -> PyResult<UnstructuredGridPiece> {
    let bad = |what: &str| PyValueError::new_err(format!("{}: {what}", path.display()));
    let vtk = Vtk::import(path).map_err(|e| bad(&format!("cannot read the frame: {e}")))?;
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        return Err(bad("not an unstructured grid"));
    };
    match pieces.into_iter().next() {
        Some(Piece::Inline(piece)) => Ok(*piece),
        _ => Err(bad("no inline piece")),
    }
}

/// A buffer as a NumPy array of `shape`: float64 for floating-point data, int64 for integers.
fn numbers(py: Python<'_>, data: IOBuffer, shape: Vec<usize>) -> PyResult<Py<PyAny>> {
    let floating = matches!(data, IOBuffer::F32(_) | IOBuffer::F64(_));
    let bad = || PyValueError::new_err("a frame array of an unsupported type");
    Ok(if floating {
        let data = data.cast_into::<f64>().ok_or_else(bad)?;
        Array { data, shape }.into_numpy(py)?.into_any().unbind()
    } else {
        let data = data.cast_into::<i64>().ok_or_else(bad)?;
        Array { data, shape }.into_numpy(py)?.into_any().unbind()
    })
}
