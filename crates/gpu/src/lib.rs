//! The explicit MPM step of loam on a GPU, through wgpu (Vulkan, Metal, DX12), in f32.
//!
//! [`GpuSolver`] runs the same step as `loam_explicit::Solver` with `T = f32` (the test
//! oracle): every shape function (linear hat, uGIMP and cpGIMP, quadratic and cubic
//! B-splines; the scene's 1D weights compiled into the kernels), PIC / FLIP / APIC / TPIC /
//! MLS transfers (FLIP:
//! `v_p ← α (v_p + Σ w (v_i − v_iⁿ)) + (1 − α) Σ w v_i`, the grid keeping the start-of-step
//! velocity `v_iⁿ = p_i / m_i` beside `v_i`), USL or MUSL, the
//! domain walls (fixed, slip, no-slip; bilateral through mirrored ghost layers, or separable),
//! Coulomb friction segments on the faces, rigid obstacles (boxes and cylinders, fixed or
//! moving, frictionless or Coulomb), the weakly compressible fluid, small-strain linear
//! elasticity, Neo-Hookean and Hencky hyperelasticity, J2 plasticity in Hencky strain space
//! (its state rebuilt from the stress), Drucker–Prager plasticity (its Jaumann update and
//! closed-form return with the tension cutoff), fixed and adaptive time steps. Particles and grid
//! live on the device; the host reads back the stability flags every [`CHECK_EVERY`] steps and
//! the particles when asked.
//!
//! Every scene the explicit CPU solver runs, runs here; a scene whose buffers are larger than
//! the adapter binds gets [`GpuError::Unsupported`] naming the field that sizes them.

mod device;
mod error;
mod params;
mod solver;
mod step;

pub use device::{Atomics, Gpu};
pub use error::GpuError;
pub use solver::{CHECK_EVERY, GpuSolver, Profile};
