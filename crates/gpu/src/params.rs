//! The constants of a run as the kernels read them, built from an explicit-solver
//! [`Config`], with the checks that the GPU path supports the scene.

use crate::error::GpuError;
use bytemuck::{Pod, Zeroable};
use loam_core::constitutive::Model;
use loam_core::step::PROJECTION_DEPTH;
use loam_core::{Scheme, Shape, TimeStep, Transfer, WallKind};
use loam_explicit::{Config, MASS_EPS};

/// The uniform block of `common.wgsl` (`struct Params`), field for field.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct Params {
    pub origin: [f32; 4],
    pub lo: [f32; 4],
    pub hi: [f32; 4],
    pub gravity: [f32; 4],
    pub nodes: [u32; 4],
    pub cells: [u32; 4],
    pub wall_lo: [u32; 4],
    pub wall_hi: [u32; 4],
    pub h: f32,
    pub inv_h: f32,
    pub dt: f32,
    pub mass_floor: f32,
    pub apic_scale: f32,
    pub depth: f32,
    pub particles: u32,
    pub pad: u32,
}

/// The transfer scheme as `common.wgsl` numbers it (`TRANSFER_*`).
pub(crate) fn transfer_code(transfer: Transfer) -> Result<u32, GpuError> {
    match transfer {
        Transfer::Pic => Ok(0),
        Transfer::Apic => Ok(1),
        Transfer::Tpic => Ok(2),
        Transfer::Mls => Ok(3),
        Transfer::Flip { .. } => Err(unsupported("solver.transfer", "FLIP")),
    }
}

fn unsupported(field: &str, what: &str) -> GpuError {
    GpuError::Unsupported {
        field: field.into(),
        what: what.into(),
    }
}

/// A wall as `common.wgsl` encodes it: the kind, plus 16 when separable.
fn wall_code(kind: WallKind, separable: bool) -> u32 {
    let k = match kind {
        WallKind::Free => 0,
        WallKind::Fixed => 1,
        WallKind::Slip => 2,
        WallKind::NoSlip => 3,
    };
    k | if separable { 16 } else { 0 }
}

/// Checks that the GPU path runs `config`, and returns its fixed time step.
pub(crate) fn check<const D: usize>(config: &Config<f32, D>) -> Result<f64, GpuError> {
    if config.shape != Shape::QuadraticBspline {
        return Err(unsupported(
            "grid.shape_function",
            &format!("{:?} (only quadratic_bspline)", config.shape),
        ));
    }
    transfer_code(config.transfer)?;
    if !config.contact.segments.is_empty() {
        return Err(unsupported("friction", "Coulomb friction on walls"));
    }
    if !config.contact.obstacles.is_empty() {
        return Err(unsupported("obstacles", "rigid obstacles"));
    }
    for (k, m) in config.materials.iter().enumerate() {
        if !matches!(m.model, Model::Fluid(_)) {
            return Err(unsupported(
                &format!("materials[{k}].model"),
                "a material other than `fluid`",
            ));
        }
    }
    match config.time_step {
        TimeStep::Fixed { dt } => Ok(dt),
        TimeStep::Adaptive { .. } => Err(unsupported(
            "solver.time_step",
            "an adaptive time step (use type = \"fixed\")",
        )),
    }
}

/// The uniform block of a run of `particles` particles with the largest particle mass
/// `max_mass`.
pub(crate) fn params<const D: usize>(
    config: &Config<f32, D>,
    dt: f64,
    particles: usize,
    max_mass: f64,
) -> Params {
    let grid = &config.grid;
    let (origin, hi, nodes) = (grid.origin(), grid.hi(), grid.nodes());
    let mut p = Params::zeroed();
    for a in 0..D {
        let [lo_wall, hi_wall] = config.boundary.walls[a];
        p.origin[a] = origin[a] as f32;
        p.lo[a] = if lo_wall.kind == WallKind::Free {
            f32::MIN
        } else {
            grid.lo[a] as f32
        };
        p.hi[a] = if hi_wall.kind == WallKind::Free {
            f32::MAX
        } else {
            hi[a] as f32
        };
        p.gravity[a] = config.gravity[a];
        p.nodes[a] = nodes[a] as u32;
        p.cells[a] = grid.cells[a] as u32;
        p.wall_lo[a] = wall_code(lo_wall.kind, lo_wall.separable);
        p.wall_hi[a] = wall_code(hi_wall.kind, hi_wall.separable);
    }
    p.nodes[3] = grid.num_nodes() as u32;
    p.h = grid.h as f32;
    p.inv_h = (1.0 / grid.h) as f32;
    p.dt = dt as f32;
    p.mass_floor = (MASS_EPS * max_mass) as f32;
    // 1/(κ h²) with κ = 1/4 for the quadratic B-spline.
    p.apic_scale = (Shape::QuadraticBspline
        .apic_inverse_inertia()
        .expect("a B-spline")
        / (grid.h * grid.h)) as f32;
    p.depth = (PROJECTION_DEPTH * grid.h) as f32;
    p.particles = particles as u32;
    p.pad = grid.pad as u32;
    p
}

/// Per material, as `common.wgsl` reads it: bulk modulus, Tait exponent, viscosity, and the
/// exponent as a whole number up to 64 (0 otherwise: the power goes through exp and ln, as on
/// the CPU).
pub(crate) fn materials<const D: usize>(config: &Config<f32, D>) -> Vec<[f32; 4]> {
    config
        .materials
        .iter()
        .map(|m| match &m.model {
            Model::Fluid(f) => {
                let n = f.gamma as u32;
                let whole = if n as f32 == f.gamma && n <= 64 { n } else { 0 };
                [f.bulk_modulus, f.gamma, f.viscosity, whole as f32]
            }
            _ => unreachable!("checked by `check`"),
        })
        .collect()
}

/// Whether the step is MUSL (a second transfer of momentum) rather than USL.
pub(crate) fn is_musl<const D: usize>(config: &Config<f32, D>) -> bool {
    config.scheme == Scheme::Musl
}
