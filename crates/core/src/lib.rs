//! # loam-core
//!
//! The pure kernels of loam, written once and generic over the scalar type `T: Scalar`
//! (`f32`, `f64`, dual numbers) and the dimension `const D: usize` (2 = plane strain, 3):
//! shape functions, grid, particles, particle–grid transfers, constitutive models and
//! boundary conditions. No solver loop, no files, no clocks.

pub mod boundary;
pub mod constitutive;
pub mod contact;
pub mod energy;
pub mod grid;
pub mod particles;
pub mod scalar;
pub mod serde_form;
pub mod shape;
pub mod spectral;
pub mod stencil;
pub mod step;
pub mod stepping;
pub mod tensor;
pub mod transfer;

pub use boundary::{Boundary, NodeConstraint, PointLoad, Wall, WallKind};
pub use constitutive::{Material, MaterialState, ModelKind};
pub use contact::{Contact, ContactSet, FrictionSegment, Obstacle, ObstacleShape, Touch};
pub use energy::Energy;
pub use grid::Grid;
pub use particles::Particles;
pub use scalar::Scalar;
pub use shape::{Shape, ShapeFunction};
pub use stencil::Stencil;
pub use stepping::{Scheme, TimeStep};
pub use transfer::Transfer;
