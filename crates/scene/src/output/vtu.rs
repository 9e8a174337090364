//! One particle frame as a VTK XML UnstructuredGrid (`.vtu`) file, written with vtkio.
//!
//! Every particle is a `VTK_VERTEX` cell; points and vectors are padded to 3D (`z = 0` in
//! 2D) and tensors are full 3×3 arrays (row-major), so ParaView shows them as tensors.
//!
//! A frame is checked before it is written: a NaN or an infinity in the positions or in any
//! requested field is an error ([`OutputError::NonFinite`]) naming the field and the
//! particles, and nothing is written. The file is written to a temporary name and renamed, so
//! a run killed while writing never leaves a truncated frame.

use super::field::{Field, WaterTable, hencky_strain, pressure, von_mises};
use super::{OutputError, write_atomically};
use loam_core::Particles;
use loam_core::tensor::{det, to3};
use nalgebra::{Matrix3, SVector};
use std::path::Path;
use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataArray, DataSet, ElementType, IOBuffer,
    UnstructuredGridPiece, Version, VertexNumbers, Vtk,
};

/// Writes the particles to `path` (a `.vtu` file) with the requested point-data `fields`.
/// `initial` holds the initial positions (one per particle) for the `displacement` field,
/// which is left out without them; `water` the water table of a coupled run, for the excess
/// pore pressure. A non-finite value in the positions or a field is an error, and nothing is
/// written.
pub fn write_vtu<const D: usize>(
    path: &Path,
    particles: &Particles<f64, D>,
    initial: Option<&[SVector<f64, D>]>,
    fields: &[Field],
    water: Option<WaterTable>,
) -> Result<(), OutputError> {
    let n = particles.len();
    if let Some(x0) = initial.filter(|x0| x0.len() != n) {
        return Err(OutputError::InitialPositions {
            given: x0.len(),
            particles: n,
        });
    }
    let points = padded(&particles.x);
    check_finite("position", &points, 3, particles)?;
    let point: Vec<Attribute> = fields
        .iter()
        .filter_map(|&field| point_data(field, particles, initial, water))
        .collect();
    for attribute in &point {
        if let Attribute::DataArray(DataArray {
            name,
            elem,
            data: IOBuffer::F64(values),
        }) = attribute
        {
            let components = match elem {
                ElementType::Vectors => 3,
                ElementType::Tensors => 9,
                ElementType::Scalars { num_comp, .. } => *num_comp as usize,
                _ => 1,
            };
            check_finite(name, values, components, particles)?;
        }
    }
    let piece = UnstructuredGridPiece {
        points: IOBuffer::F64(points),
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
    let mut xml = Vec::new();
    Vtk {
        version: Version::new((1, 0)),
        title: String::from("loam particles"),
        byte_order: ByteOrder::LittleEndian,
        data: DataSet::inline(piece),
        file_path: None,
    }
    .write_xml(&mut xml)
    .map_err(|source| OutputError::Vtk {
        path: path.to_path_buf(),
        source,
    })?;
    write_atomically(path, &xml)
}

/// The error for the particles whose values in `values` (`components` per particle) hold a
/// NaN or an infinity, if any. For the strain it adds the smallest `det F` among them: the
/// strain `½ ln(F Fᵀ)` stops being computable in `f64` when a particle is crushed (its
/// smallest stretch lost in the round-off of the largest), while the solver's checks of F
/// (finite, `det F > 0`) still pass.
fn check_finite<const D: usize>(
    field: &str,
    values: &[f64],
    components: usize,
    particles: &Particles<f64, D>,
) -> Result<(), OutputError> {
    let ids: Vec<usize> = values
        .chunks(components.max(1))
        .enumerate()
        .filter(|(_, v)| !v.iter().all(|x| x.is_finite()))
        .map(|(i, _)| i)
        .collect();
    if ids.is_empty() {
        return Ok(());
    }
    let hint = if field == Field::Strain.name() {
        let smallest = ids
            .iter()
            .map(|&i| det(&particles.f[i]))
            .fold(f64::INFINITY, f64::min);
        format!(
            "; det F is down to {smallest:.3e} there: the particles are crushed (a material too \
             soft for its load, or a step too large)"
        )
    } else {
        String::new()
    };
    Err(OutputError::NonFinite {
        field: field.to_owned(),
        ids,
        hint,
    })
}

/// The array of one field (`None` for `displacement` without initial positions).
fn point_data<const D: usize>(
    field: Field,
    p: &Particles<f64, D>,
    initial: Option<&[SVector<f64, D>]>,
    water: Option<WaterTable>,
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
        Field::PreconsolidationPressure => scalars(p.state.iter().map(|s| s.hardening).collect()),
        Field::Pressure => scalars(p.stress.iter().map(pressure).collect()),
        Field::PorePressure => scalars(p.pore_pressure.clone()),
        Field::ExcessPorePressure => scalars(
            (p.pore_pressure.iter().zip(&p.x))
                .map(|(pw, x)| pw - water.map_or(0.0, |w| w.hydrostatic(x[D - 1])))
                .collect(),
        ),
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
        Field::Id => scalar_array(name, IOBuffer::U64((0..p.len() as u64).collect())),
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
