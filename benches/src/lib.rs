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
//!
//! The second explicit scene, [`dambreak_friction_2d`], is the 6,000-particle water dam-break of
//! the friction study (a weakly compressible fluid at a fixed time step, five Coulomb floor
//! segments), where the fixed costs of a step dominate; it scales to 100k and 1M particles.
//! The third, [`granular_column_3d`], is a Drucker–Prager column collapse in 3D.
//!
//! The implicit benches use two quasi-static scenes ([`cantilever_2d`] and [`hencky_block_3d`]),
//! returned as `ImplicitConfig` + `Particles`.

use loam_core::tensor::Vector;
use loam_core::{
    Boundary, Contact, FrictionSegment, Grid, Material, ModelKind, Particles, Scalar, Scheme,
    Shape, TimeStep, Transfer, Wall, WallKind,
};
use loam_explicit::Config;
use loam_implicit::{ImplicitConfig, NewtonSettings};
use loam_verification::cantilever;

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
        contact: Default::default(),
        gravity,
        materials: vec![Material::elastic(
            ModelKind::NeoHookean,
            T::cst(YOUNG),
            T::cst(POISSON),
            T::cst(DENSITY),
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

/// Height of the friction dam-break tank (m); its length is [`DAMBREAK_LENGTH`].
const DAMBREAK_HEIGHT: f64 = 0.4;
/// Length of the friction dam-break tank (m).
const DAMBREAK_LENGTH: f64 = 2.0;
/// Width and height of the water block of the friction dam-break (m).
const DAMBREAK_WATER: [f64; 2] = [0.5, 0.3];
/// Cell size of the friction dam-break at scale 1 (m).
const DAMBREAK_CELL: f64 = 0.01;
/// Fixed time step of the friction dam-break at scale 1 (s).
pub const DAMBREAK_DT: f64 = 3e-5;
/// Coulomb coefficients of the five equal floor segments of the friction dam-break, from
/// x = 0 to x = 2 m.
pub const DAMBREAK_FRICTION: [f64; 5] = [0.0, 0.5, 0.1, 0.2, 0.0];

/// The 2D "friction dam-break" of `examples/dambreak_friction.toml` (forward only): a water
/// block of 0.5 m × 0.3 m in the lower left corner of a 2.0 m × 0.4 m tank, collapsing under
/// gravity (9.8 m/s² along −y). Slip walls; the floor is a separable slip wall split into five
/// Coulomb segments of 0.4 m with μ = [`DAMBREAK_FRICTION`].
///
/// Water is the weakly compressible [`Material::fluid`] with ρ₀ = 1000 kg/m³, sound speed
/// 35 m/s (K = ρ₀c² = 1.225 MPa), γ = 7 and no viscosity. Quadratic B-splines, MLS-MPM
/// (APIC transfers, moving-least-squares force and `L = C`) with USL, as the reference solver
/// runs this scene: one P2G and one G2P per step. 2 × 2 particles per cell and a fixed time step of [`DAMBREAK_DT`]` / scale`. `scale = 1` is
/// the reference: 200 × 40 cells of 0.01 m and 6,000 particles (13,333 steps make 0.4 s);
/// `scale = k` divides the cell size and the time step by `k` (6,000·k² particles).
pub fn dambreak_friction_2d<T: Scalar>(scale: usize) -> (Config<T, 2>, Particles<T, 2>) {
    assert!(scale >= 1, "dambreak_friction_2d: scale must be at least 1");
    let h = DAMBREAK_CELL / scale as f64;
    let cells = [
        (DAMBREAK_LENGTH / h).round() as usize,
        (DAMBREAK_HEIGHT / h).round() as usize,
    ];
    let shape = Shape::QuadraticBspline;
    let sound_speed = 35.0;
    let mut boundary = Boundary::all(Wall::new(WallKind::Slip));
    boundary.walls[1][0] = Wall {
        kind: WallKind::Slip,
        separable: true,
    };
    let mut contact = Contact::new(shape);
    let segment = DAMBREAK_LENGTH / DAMBREAK_FRICTION.len() as f64;
    for (k, &mu) in DAMBREAK_FRICTION.iter().enumerate() {
        contact.segments.push(FrictionSegment {
            axis: 1,
            side: 0,
            from: [k as f64 * segment, 0.0],
            to: [(k + 1) as f64 * segment, 0.0],
            mu: T::cst(mu),
        });
    }
    let config = Config {
        grid: Grid::new([0.0; 2], cells, h, shape.ghost_cells()),
        shape,
        transfer: Transfer::Mls,
        scheme: Scheme::Usl,
        boundary,
        contact,
        gravity: Vector::<T, 2>::new(T::zero(), T::cst(-9.8)),
        materials: vec![Material::fluid(
            T::cst(DENSITY * sound_speed * sound_speed),
            T::cst(7.0),
            T::zero(),
            T::cst(DENSITY),
        )],
        time_step: TimeStep::Fixed {
            dt: DAMBREAK_DT / scale as f64,
        },
    };
    let dp = h / PARTICLES_PER_CELL_AXIS as f64;
    let n: [usize; 2] = std::array::from_fn(|a| (DAMBREAK_WATER[a] / dp).round() as usize);
    let half_width = Vector::<T, 2>::repeat(T::cst(0.5 * dp));
    let mut particles = Particles::default();
    for j in 0..n[1] {
        for i in 0..n[0] {
            let x =
                Vector::<T, 2>::new(T::cst((i as f64 + 0.5) * dp), T::cst((j as f64 + 0.5) * dp));
            particles.push(x, Vector::zeros(), T::cst(DENSITY), half_width, 0);
        }
    }
    (config, particles)
}

/// Cell size of the 3D granular column at `resolution = 1` (m).
const COLUMN_CELL: f64 = 0.01;

/// The 3D granular column collapse of `examples/granular_collapse_3d.toml` at `resolution`
/// times its cell count per axis (cell size `0.01 m / resolution`).
///
/// A quarter of a square column, 0.06 m × 0.12 m × 0.06 m (x, y up, z), in the corner of a
/// 0.4 m × 0.15 m × 0.4 m box whose planes x = 0 and z = 0 are symmetry (slip) walls;
/// cohesionless non-associated Drucker–Prager sand (ρ = 2650 kg/m³, E = 0.84 MPa, ν = 0.3,
/// φ = 30°, ψ = 0) on a Coulomb floor with μ = tan φ, stress-free at t = 0. Quadratic B-splines,
/// APIC, MUSL, 2 × 2 × 2 particles per cell, adaptive time step at CFL 0.4. `resolution = 1`
/// gives 3,456 particles, 3 gives 93,312.
pub fn granular_column_3d<T: Scalar>(resolution: usize) -> (Config<T, 3>, Particles<T, 3>) {
    assert!(
        resolution >= 1,
        "granular_column_3d: resolution must be at least 1"
    );
    let h = COLUMN_CELL / resolution as f64;
    let cells = |length: f64| (length / h).round() as usize;
    let shape = Shape::QuadraticBspline;
    let mut boundary = Boundary::all(Wall::new(WallKind::Slip));
    boundary.walls[1] = [
        Wall {
            kind: WallKind::Slip,
            separable: true,
        },
        Wall::new(WallKind::Free),
    ];
    let mut contact = Contact::new(shape);
    contact.segments.push(FrictionSegment::whole_face(
        1,
        0,
        T::cst(30f64.to_radians().tan()),
    ));
    let config = Config {
        grid: Grid::new([0.0; 3], [cells(0.4), cells(0.15), cells(0.4)], h, 2),
        shape,
        transfer: Transfer::Apic,
        scheme: Scheme::Musl,
        boundary,
        contact,
        gravity: Vector::<T, 3>::new(T::zero(), T::cst(-9.81), T::zero()),
        materials: vec![Material::drucker_prager(
            T::cst(0.84e6),
            T::cst(0.3),
            T::cst(30f64.to_radians()),
            T::zero(),
            T::zero(),
            None,
            T::cst(2650.0),
        )],
        time_step: TimeStep::Adaptive {
            cfl: 0.4,
            max_dt: 1e-3,
        },
    };
    let dp = h / PARTICLES_PER_CELL_AXIS as f64;
    let n = [0.06, 0.12, 0.06].map(|l: f64| (l / dp).round() as usize);
    let half_width = Vector::<T, 3>::repeat(T::cst(0.5 * dp));
    let mut particles = Particles::default();
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let x = Vector::<T, 3>::from_fn(|a, _| T::cst(([i, j, k][a] as f64 + 0.5) * dp));
                particles.push(x, Vector::zeros(), T::cst(2650.0), half_width, 0);
            }
        }
    }
    (config, particles)
}

/// The reference large-deflection cantilever of the implicit benchmark
/// (`loam_verification::cantilever::Setup::reference` with quadratic B-splines) at cell size
/// `cell` (m), 6 × 6 particles per cell.
///
/// The 10 m × 1 m Hencky beam (E = 12 MPa, ν = 0.2) is held at its root and loaded by a tip
/// load on the two particles nearest the tip's neutral axis, over 50 load steps. `cell = 0.25`
/// is the reference (5,760 particles); 0.125 gives 23,040 and 0.0625 gives 92,160 particles.
/// `cell` must divide 15 m and put a node row on the neutral axis y = 9.5 m.
pub fn cantilever_2d(cell: f64) -> (ImplicitConfig<2>, Particles<f64, 2>) {
    let setup = cantilever::Setup {
        cell,
        ..cantilever::Setup::reference(Shape::QuadraticBspline)
    };
    let (config, particles, _loaded) = setup.build();
    (config, particles)
}

/// Young's modulus of the implicit 3D block (Pa).
const BLOCK_YOUNG: f64 = 1.0e6;
/// Poisson's ratio of the implicit 3D block.
const BLOCK_POISSON: f64 = 0.3;
/// Load steps of the implicit 3D block (gravity is ramped over them).
const BLOCK_LOAD_STEPS: usize = 10;

/// A quasi-static 3D block settling under gravity, with at least `target_particles` particles.
///
/// A 1 m cube of Hencky material (E = 1 MPa, ν = 0.3, ρ = 1000 kg/m³) rests on a fixed floor
/// (y = 0) between frictionless (slip) walls on the four sides, which coincide with the block's
/// faces; the top is free and the grid is one cell taller than the block. Gravity 9.81 m/s²
/// along −y is ramped over 10 load steps (vertical strain ≈ ρgH/E ≈ 1 % at the bottom).
/// Quadratic B-splines, 2 × 2 × 2 particles per cell; the block side in particles is the
/// smallest even `n` with `n³ ≥ target_particles`: 25,000 gives 30³ = 27,000 particles on
/// 15 × 16 × 15 cells.
pub fn hencky_block_3d(target_particles: usize) -> (ImplicitConfig<3>, Particles<f64, 3>) {
    const D: usize = 3;
    let per_axis = particles_per_axis(target_particles, D);
    let block_cells = per_axis / PARTICLES_PER_CELL_AXIS;
    let h = BLOCK_SIDE / block_cells as f64;
    let shape = Shape::QuadraticBspline;
    let mut boundary = Boundary::all(Wall::new(WallKind::Slip));
    boundary.walls[1][0] = Wall::new(WallKind::Fixed);
    boundary.walls[1][1] = Wall::new(WallKind::Free);
    let config = ImplicitConfig {
        grid: Grid::new(
            [0.0; D],
            [block_cells, block_cells + 1, block_cells],
            h,
            shape.ghost_cells(),
        ),
        shape,
        boundary,
        materials: vec![Material::elastic(
            ModelKind::Hencky,
            BLOCK_YOUNG,
            BLOCK_POISSON,
            DENSITY,
        )],
        gravity: Vector::<f64, D>::new(0.0, -9.81, 0.0),
        constraints: Vec::new(),
        point_loads: Vec::new(),
        load_steps: BLOCK_LOAD_STEPS,
        newton: NewtonSettings::default(),
        dynamics: None,
        min_node_support: ImplicitConfig::<D>::DEFAULT_MIN_NODE_SUPPORT,
    };
    let dp = h / PARTICLES_PER_CELL_AXIS as f64;
    let half_width = Vector::<f64, D>::repeat(0.5 * dp);
    let mut particles = Particles::default();
    for k in 0..per_axis.pow(D as u32) {
        let x = Vector::<f64, D>::from_fn(|a, _| {
            let i = k / per_axis.pow(a as u32) % per_axis;
            (i as f64 + 0.5) * dp
        });
        particles.push(x, Vector::zeros(), DENSITY, half_width, 0);
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
        assert_eq!(cantilever_2d(0.25).1.len(), 5_760);
        assert_eq!(cantilever_2d(0.125).1.len(), 23_040);
        assert_eq!(cantilever_2d(0.0625).1.len(), 92_160);
        assert_eq!(hencky_block_3d(25_000).1.len(), 27_000);
        assert_eq!(dambreak_friction_2d::<f64>(1).1.len(), 6_000);
        assert_eq!(dambreak_friction_2d::<f32>(2).1.len(), 24_000);
    }

    #[test]
    fn implicit_scenes_make_solvers() {
        let (config, particles) = cantilever_2d(0.25);
        loam_implicit::ImplicitSolver::new(config, &particles).expect("valid cantilever");
        let (config, particles) = hencky_block_3d(1000);
        assert_eq!(config.grid.cells, [5, 6, 5]);
        let solver =
            loam_implicit::ImplicitSolver::new(config, &particles).expect("valid 3D block");
        let system = solver
            .system(&particles, 0.0, 0.1)
            .expect("block on the grid");
        assert!(!system.is_empty());
        // Gravity pushes down: the external force on the unknowns sums to −ρ g V λ along y.
        assert!(system.f_ext.iter().sum::<f64>() < 0.0);
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
