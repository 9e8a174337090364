//! Benchmark scenes of loam.
//!
//! The builders here return plain solver inputs (`Config` + `Particles`), so the criterion
//! benches of this crate and the `loam bench` command time exactly the same work.
//!
//! The reference scene is a "fluid-like" block collapse (a dam break of a soft solid): a square
//! (2D) or cubic (3D) block of a Neo-Hookean material with a low shear modulus sits in the
//! lower corner of a box twice its size along every axis and slumps under gravity against
//! separable slip walls. The solver settings are the usual explicit defaults: quadratic
//! B-splines, APIC, MUSL and an adaptive time step at CFL 0.4.

use loam_core::tensor::Vector;
use loam_core::{
    Boundary, Grid, Material, ModelKind, Particles, Scalar, Scheme, Shape, TimeStep, Transfer,
    Wall, WallKind,
};
use loam_explicit::Config;

/// Young's modulus of the block material (Pa): soft, so the block flows like a fluid.
const YOUNG: f64 = 1.0e5;
/// Poisson's ratio of the block material: nearly incompressible, low shear modulus.
const POISSON: f64 = 0.45;
/// Mass density of the block material (kg/m³).
const DENSITY: f64 = 1000.0;
/// Side length of the block (m); the box is twice as large along every axis.
const BLOCK_SIDE: f64 = 1.0;
/// Particles per cell along each axis.
const PARTICLES_PER_CELL_AXIS: usize = 2;

/// A 2D (plane-strain) fluid-like block collapse with at least `target_particles` particles.
///
/// The block is `n × n` particles, 2 × 2 per cell, with `n` the smallest even number such that
/// `n² ≥ target_particles` (at least one cell): 100,000 gives 318² = 101,124 particles and
/// 10,000 gives exactly 10,000. The block is 1 m wide and the box 2 m × 2 m; gravity acts
/// along `-y`.
pub fn fluid_block_2d<T: Scalar>(target_particles: usize) -> (Config<T, 2>, Particles<T, 2>) {
    fluid_block(target_particles)
}

/// A 3D fluid-like block collapse with at least `target_particles` particles.
///
/// The block is `n × n × n` particles, 2 × 2 × 2 per cell, with `n` the smallest even number
/// such that `n³ ≥ target_particles` (at least one cell): 100,000 gives 48³ = 110,592
/// particles. The block is 1 m wide and the box 2 m × 2 m × 2 m; gravity acts along `-y`.
pub fn fluid_block_3d<T: Scalar>(target_particles: usize) -> (Config<T, 3>, Particles<T, 3>) {
    fluid_block(target_particles)
}

/// The block collapse in `D` dimensions (see [`fluid_block_2d`] and [`fluid_block_3d`]).
fn fluid_block<T: Scalar, const D: usize>(
    target_particles: usize,
) -> (Config<T, D>, Particles<T, D>) {
    let per_axis = particles_per_axis(target_particles, D);
    let block_cells = per_axis / PARTICLES_PER_CELL_AXIS;
    let h = BLOCK_SIDE / block_cells as f64;
    let shape = Shape::QuadraticBspline;
    let mut gravity = Vector::<T, D>::zeros();
    gravity[1] = T::cst(-9.81);
    let config = Config {
        grid: Grid::new([0.0; D], [2 * block_cells; D], h, shape.ghost_cells()),
        shape,
        transfer: Transfer::Apic,
        scheme: Scheme::Musl,
        boundary: Boundary::all(Wall {
            kind: WallKind::Slip,
            separable: true,
        }),
        gravity,
        materials: vec![Material::elastic(
            ModelKind::NeoHookean,
            T::cst(YOUNG),
            T::cst(POISSON),
            DENSITY,
        )],
        time_step: TimeStep::Adaptive {
            cfl: 0.4,
            max_dt: 1e-3,
        },
    };

    let dp = h / PARTICLES_PER_CELL_AXIS as f64;
    let half_width = Vector::<T, D>::repeat(T::cst(0.5 * dp));
    let mut particles = Particles::default();
    for k in 0..per_axis.pow(D as u32) {
        let x = Vector::<T, D>::from_fn(|a, _| {
            let i = k / per_axis.pow(a as u32) % per_axis;
            T::cst((i as f64 + 0.5) * dp)
        });
        particles.push(x, Vector::zeros(), T::cst(DENSITY), half_width, 0);
    }
    (config, particles)
}

/// The smallest even `n ≥ 2` with `n^dim ≥ target`.
fn particles_per_axis(target: usize, dim: usize) -> usize {
    (PARTICLES_PER_CELL_AXIS..)
        .step_by(PARTICLES_PER_CELL_AXIS)
        .find(|n| {
            n.checked_pow(dim as u32)
                .is_none_or(|count| count >= target)
        })
        .expect("the search stops at the latest when n^dim overflows")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn particle_counts() {
        assert_eq!(fluid_block_2d::<f64>(100_000).1.len(), 101_124);
        assert_eq!(fluid_block_2d::<f64>(10_000).1.len(), 10_000);
        assert_eq!(fluid_block_3d::<f64>(100_000).1.len(), 110_592);
        assert_eq!(fluid_block_2d::<f32>(0).1.len(), 4);
    }

    #[test]
    fn block_sits_in_the_lower_corner_of_the_box() {
        let (config, particles) = fluid_block_3d::<f64>(1000);
        let hi = config.grid.hi();
        for x in &particles.x {
            for a in 0..3 {
                assert!(x[a] > 0.0 && x[a] < 0.5 * hi[a]);
            }
        }
    }
}
