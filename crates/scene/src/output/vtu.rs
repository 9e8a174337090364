//! One particle frame as a VTK XML UnstructuredGrid (`.vtu`) file, written with vtkio.
//!
//! Every particle is a `VTK_VERTEX` cell; points and vectors are padded to 3D (`z = 0` in
//! 2D) and tensors are full 3×3 arrays (row-major), so ParaView shows them as tensors.

use super::OutputError;
use super::field::{Field, hencky_strain, pressure, von_mises};
use loam_core::Particles;
use loam_core::tensor::{det, to3};
use nalgebra::{Matrix3, SVector};
use std::path::Path;
use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataArray, DataSet, ElementType, IOBuffer,
    UnstructuredGridPiece, Version, VertexNumbers, Vtk,
};

/// Writes the particles to `path` (which must end in `.vtu`) with the requested point-data
/// `fields`. `initial` holds the initial positions (one per particle) for the
/// `displacement` field, which is left out without them.
pub fn write_vtu<const D: usize>(
    path: &Path,
    particles: &Particles<f64, D>,
    initial: Option<&[SVector<f64, D>]>,
    fields: &[Field],
) -> Result<(), OutputError> {
    let n = particles.len();
    if let Some(x0) = initial.filter(|x0| x0.len() != n) {
        return Err(OutputError::InitialPositions {
            given: x0.len(),
            particles: n,
        });
    }
    let point = fields
        .iter()
        .filter_map(|&field| point_data(field, particles, initial))
        .collect();
    let piece = UnstructuredGridPiece {
        points: IOBuffer::F64(padded(&particles.x)),
        cells: Cells {
            cell_verts: VertexNumbers::XML {
                connectivity: (0..n as u64).collect(),
                offsets: (1..=n as u64).collect(),
            },
            types: vec![CellType::Vertex; n],
        },
        data: Attributes {
            point,
            cell: Vec::new(),
        },
    };
    Vtk {
        version: Version::new((1, 0)),
        title: String::from("loam particles"),
        byte_order: ByteOrder::LittleEndian,
        data: DataSet::inline(piece),
        file_path: None,
    }
    .export(path)
    .map_err(|source| OutputError::Vtk {
        path: path.to_path_buf(),
        source,
    })
}

/// The array of one field (`None` for `displacement` without initial positions).
fn point_data<const D: usize>(
    field: Field,
    p: &Particles<f64, D>,
    initial: Option<&[SVector<f64, D>]>,
) -> Option<Attribute> {
    let name = field.name();
    let scalars = |values: Vec<f64>| scalar_array(name, IOBuffer::F64(values));
    Some(match field {
        Field::Velocity => vector_array(name, &p.v),
        Field::Displacement => {
            let u: Vec<_> = p.x.iter().zip(initial?).map(|(x, x0)| x - x0).collect();
            vector_array(name, &u)
        }
        Field::Stress => tensor_array(name, p.stress.iter().copied()),
        Field::Strain => tensor_array(name, p.f.iter().map(hencky_strain)),
        Field::PlasticStrain => scalars(p.state.iter().map(|s| s.plastic_strain).collect()),
        Field::Pressure => scalars(p.stress.iter().map(pressure).collect()),
        Field::VonMises => scalars(p.stress.iter().map(von_mises).collect()),
        Field::Volume => scalars(
            p.f.iter()
                .zip(&p.volume0)
                .map(|(f, v0)| det(f) * v0)
                .collect(),
        ),
        Field::Mass => scalars(p.mass.clone()),
        Field::MaterialId => scalar_array(name, IOBuffer::U32(p.material.clone())),
        Field::Affine => tensor_array(name, p.c.iter().map(|c| to3(c, 0.0))),
    })
}

/// `D`-vectors as a flat `[x, y, z, …]` buffer, zero-padded to 3 components.
fn padded<const D: usize>(v: &[SVector<f64, D>]) -> Vec<f64> {
    v.iter()
        .flat_map(|x| std::array::from_fn::<f64, 3, _>(|a| if a < D { x[a] } else { 0.0 }))
        .collect()
}

fn vector_array<const D: usize>(name: &str, v: &[SVector<f64, D>]) -> Attribute {
    Attribute::DataArray(DataArray {
        name: name.to_owned(),
        elem: ElementType::Vectors,
        data: IOBuffer::F64(padded(v)),
    })
}

fn tensor_array(name: &str, t: impl Iterator<Item = Matrix3<f64>>) -> Attribute {
    // Row-major: t_00, t_01, t_02, t_10, …
    let data = t
        .flat_map(|m| std::array::from_fn::<f64, 9, _>(|k| m[(k / 3, k % 3)]))
        .collect();
    Attribute::DataArray(DataArray {
        name: name.to_owned(),
        elem: ElementType::Tensors,
        data: IOBuffer::F64(data),
    })
}

fn scalar_array(name: &str, data: IOBuffer) -> Attribute {
    Attribute::DataArray(DataArray {
        name: name.to_owned(),
        elem: ElementType::Scalars {
            num_comp: 1,
            lookup_table: None,
        },
        data,
    })
}
