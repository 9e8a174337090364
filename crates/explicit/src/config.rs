//! Everything an explicit run needs besides the particles.

use crate::error::ConfigError;
use loam_core::tensor::Vector;
use loam_core::{Boundary, Contact, Grid, Material, Scalar, Scheme, Shape, TimeStep, Transfer};

/// Parameters of an explicit simulation (plain data; scenes build it).
#[derive(Clone, Debug)]
pub struct Config<T: Scalar, const D: usize> {
    /// Background grid.
    pub grid: Grid<D>,
    /// Shape-function family.
    pub shape: Shape,
    /// Particle-velocity update scheme.
    pub transfer: Transfer,
    /// USL or MUSL.
    pub scheme: Scheme,
    /// Walls on the grid faces.
    pub boundary: Boundary<D>,
    /// Frictional wall segments and rigid obstacles (applied before `boundary`).
    pub contact: Contact<T, D>,
    /// Body-force acceleration `g`.
    pub gravity: Vector<T, D>,
    /// Material table, indexed by `Particles::material`.
    pub materials: Vec<Material<T>>,
    /// Fixed or adaptive time step.
    pub time_step: TimeStep,
}

impl<T: Scalar, const D: usize> Config<T, D> {
    /// Checks the parameters for values the solver cannot run with.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |field: &str, msg: String| {
            Err(ConfigError::Invalid {
                field: field.into(),
                msg,
            })
        };
        if !(self.grid.h > 0.0 && self.grid.h.is_finite()) {
            return bad(
                "grid.h",
                format!("must be positive and finite, got {}", self.grid.h),
            );
        }
        if self.grid.cells.contains(&0) {
            return bad("grid.cells", "every axis needs at least one cell".into());
        }
        if self.grid.pad < self.shape.ghost_cells() {
            return bad(
                "grid.pad",
                format!(
                    "{:?} needs {} ghost cells, got {}",
                    self.shape,
                    self.shape.ghost_cells(),
                    self.grid.pad
                ),
            );
        }
        if self.materials.is_empty() {
            return bad("materials", "at least one material is needed".into());
        }
        let obstacles = self.contact.obstacles.len();
        if obstacles > loam_core::Contact::<T, D>::MAX_OBSTACLES {
            return bad(
                "contact.obstacles",
                format!(
                    "at most {} obstacles (one bit each in a node's contact state), got {obstacles}",
                    loam_core::Contact::<T, D>::MAX_OBSTACLES
                ),
            );
        }
        if self.transfer.is_mls() && self.shape.apic_inverse_inertia().is_none() {
            return bad(
                "transfer",
                format!(
                    "MLS-MPM needs a B-spline shape function (quadratic or cubic), got {:?}",
                    self.shape
                ),
            );
        }
        if let Transfer::Flip { alpha } = self.transfer
            && !(0.0..=1.0).contains(&alpha)
        {
            return bad("transfer.alpha", format!("must be in [0, 1], got {alpha}"));
        }
        match self.time_step {
            TimeStep::Fixed { dt } if !(dt > 0.0 && dt.is_finite()) => {
                bad("time_step.dt", format!("must be positive, got {dt}"))
            }
            TimeStep::Adaptive { cfl, .. } if !(cfl > 0.0 && cfl <= 1.0) => {
                bad("time_step.cfl", format!("must be in (0, 1], got {cfl}"))
            }
            TimeStep::Adaptive { max_dt, .. } if !(max_dt > 0.0 && max_dt.is_finite()) => bad(
                "time_step.max_dt",
                format!("must be positive, got {max_dt}"),
            ),
            _ => Ok(()),
        }
    }
}

impl<const D: usize> Config<f64, D> {
    /// The same configuration with every parameter a back-analysis may ask for as constants of
    /// another scalar type: the materials ([`loam_core::Material::lift`]), friction
    /// coefficients and obstacle velocities ([`Contact::lift`]) and gravity. Seed the
    /// derivative part of one of them in the result to differentiate a run with respect to it;
    /// lift the particles with [`loam_core::Particles::lift`].
    pub fn lift<T: Scalar>(&self) -> Config<T, D> {
        Config {
            grid: self.grid.clone(),
            shape: self.shape,
            transfer: self.transfer,
            scheme: self.scheme,
            boundary: self.boundary,
            contact: self.contact.lift(),
            gravity: self.gravity.map(T::cst),
            materials: self.materials.iter().map(Material::lift).collect(),
            time_step: self.time_step,
        }
    }
}
