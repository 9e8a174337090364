//! Benchmark scenes of loam.
//!
//! The explicit bench scenes are scene files, as `loam run` reads them: `benches/scenes/*.toml`
//! and the reference friction dam-break `examples/dambreak_friction.toml` (listed in
//! [`EXPLICIT_SCENES`]). [`explicit_scene`] builds one through `loam-scene`
//! (`Built::explicit_config` and the built particles, the one way from a scene to the
//! explicit solver) and lifts it to the scalar type of the bench, so the criterion benches of
//! this crate, the `loam bench` command and a `loam run` of the same file start from the same
//! solver inputs. The files are compiled into the crate, so a `loam` binary needs no source
//! tree to run its benches.
//!
//! - `block_2d_10k`, `block_2d_100k`, `block_3d_100k`: a "fluid-like" block collapse (a dam
//!   break of a soft Neo-Hookean solid) in a box twice its size, separable slip walls, APIC,
//!   MUSL and an adaptive step at CFL 0.4; 10,000, 101,124 and 110,592 particles.
//! - `dambreak_friction` (6,000 particles), `dambreak_friction_96k`, `dambreak_friction_1m`:
//!   the water dam-break of the friction study (weakly compressible fluid, fixed step, five
//!   Coulomb floor segments, MLS-MPM with USL), where the fixed costs of a step dominate at
//!   the smallest size, at 1×, 4× and 13× the resolution.
//! - `column_3d_93k`: a Drucker–Prager granular column collapse in 3D (93,312 particles).
//!
//! The implicit benches use two quasi-static scenes ([`cantilever_2d`] and
//! [`hencky_block_3d`]), built here and returned as `ImplicitConfig` + `Particles`.

use loam_core::tensor::Vector;
use loam_core::{Boundary, Grid, Material, ModelKind, Particles, Scalar, Shape, Wall, WallKind};
use loam_explicit::Config;
use loam_implicit::{ImplicitConfig, NewtonSettings};
use loam_scene::Scene;
use loam_verification::cantilever;

/// An explicit bench scene: a scene file of the repository, compiled into the crate.
#[derive(Clone, Copy, Debug)]
pub struct BenchScene {
    /// The file's stem, which [`explicit_scene`] takes.
    pub name: &'static str,
    /// The file, relative to the repository root.
    pub path: &'static str,
    /// The file's text.
    pub toml: &'static str,
}

/// A [`BenchScene`] for the file at `$path` (relative to the repository root).
macro_rules! bench_scene {
    ($name:literal, $path:literal) => {
        BenchScene {
            name: $name,
            path: $path,
            toml: include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../", $path)),
        }
    };
}

/// The explicit bench scenes.
pub const EXPLICIT_SCENES: [BenchScene; 7] = [
    bench_scene!("block_2d_10k", "benches/scenes/block_2d_10k.toml"),
    bench_scene!("block_2d_100k", "benches/scenes/block_2d_100k.toml"),
    bench_scene!("block_3d_100k", "benches/scenes/block_3d_100k.toml"),
    bench_scene!("dambreak_friction", "examples/dambreak_friction.toml"),
    bench_scene!(
        "dambreak_friction_96k",
        "benches/scenes/dambreak_friction_96k.toml"
    ),
    bench_scene!(
        "dambreak_friction_1m",
        "benches/scenes/dambreak_friction_1m.toml"
    ),
    bench_scene!("column_3d_93k", "benches/scenes/column_3d_93k.toml"),
];

/// The solver inputs of the explicit bench scene `name` (a stem of [`EXPLICIT_SCENES`]) in
/// `D` dimensions and precision `T`: the scene is parsed, validated and built by
/// `loam-scene` (`Built::explicit_config` and `Built::particles`), then lifted to `T`
/// (`Config::lift`, `Particles::lift`).
///
/// # Panics
///
/// When `name` is not a bench scene or the scene is not `D`-dimensional: the names and
/// dimensions are fixed by the callers, and the tests build every scene.
pub fn explicit_scene<T: Scalar, const D: usize>(name: &str) -> (Config<T, D>, Particles<T, D>) {
    let Some(scene) = EXPLICIT_SCENES.iter().find(|s| s.name == name) else {
        let known: Vec<&str> = EXPLICIT_SCENES.iter().map(|s| s.name).collect();
        panic!(
            "no bench scene `{name}`; expected one of {}",
            known.join(", ")
        );
    };
    let built = Scene::from_toml_str(scene.toml)
        .and_then(|s| s.build::<D>())
        .unwrap_or_else(|e| panic!("{}: {e}", scene.path));
    let config = built
        .explicit_config()
        .unwrap_or_else(|| panic!("{}: not an explicit scene", scene.path));
    (config.lift(), built.particles.lift())
}

/// Mass density of the implicit 3D block (kg/m³).
const DENSITY: f64 = 1000.0;
/// Side length of the implicit 3D block (m).
const BLOCK_SIDE: f64 = 1.0;
/// Particles per cell along each axis of the implicit 3D block.
const PARTICLES_PER_CELL_AXIS: usize = 2;

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
    use loam_core::{FrictionSegment, Scheme, TimeStep, Transfer};

    /// Builds the bench scene `name` in f64 through the loader.
    fn load<const D: usize>(name: &str) -> (Config<f64, D>, Particles<f64, D>) {
        explicit_scene::<f64, D>(name)
    }

    /// Checks that `p` is the block of `n[0] × … × n[D−1]` particles of spacing `dp` and
    /// density `density` from the origin, at `(i + ½) dp` per axis, axis 0 fastest, at rest:
    /// the lattice the benches used to build by hand.
    fn assert_lattice<const D: usize>(p: &Particles<f64, D>, n: [usize; D], dp: f64, density: f64) {
        assert_eq!(p.len(), n.iter().product::<usize>());
        let volume = dp.powi(D as i32);
        let mut k = 0;
        let mut index = [0usize; D];
        loop {
            for a in 0..D {
                // Round-off: the coordinates are at most 2 m and come from a few operations
                // (~1e-16 m each); 1e-12 m is far below the smallest spacing (3.8e-4 m), so a
                // particle one site off fails.
                let expected = (index[a] as f64 + 0.5) * dp;
                assert!(
                    (p.x[k][a] - expected).abs() < 1e-12,
                    "particle {k} axis {a}"
                );
                assert!((p.half_width0[k][a] - 0.5 * dp).abs() < 1e-15);
            }
            assert!(
                (p.volume0[k] / volume - 1.0).abs() < 1e-12,
                "particle {k} volume"
            );
            assert!(
                (p.mass[k] / (density * volume) - 1.0).abs() < 1e-12,
                "particle {k} mass"
            );
            assert_eq!(p.v[k], Vector::<f64, D>::zeros());
            assert_eq!(p.material[k], 0);
            k += 1;
            let Some(a) = (0..D).find(|&a| index[a] + 1 < n[a]) else {
                break;
            };
            index[a] += 1;
            index[..a].fill(0);
        }
        assert_eq!(k, p.len());
    }

    /// Checks the grid of `config`: `cells` of size `h` from the origin, with the two ghost
    /// cells of quadratic B-splines.
    fn assert_grid<const D: usize>(config: &Config<f64, D>, cells: [usize; D], h: f64) {
        assert_eq!(config.grid.cells, cells);
        assert!(
            (config.grid.h / h - 1.0).abs() < 1e-15,
            "h = {}",
            config.grid.h
        );
        assert_eq!(config.grid.lo, [0.0; D]);
        assert_eq!(config.grid.pad, Shape::QuadraticBspline.ghost_cells());
        assert_eq!(config.shape, Shape::QuadraticBspline);
    }

    /// The block collapse: a 1 m block of `n` particles per axis (2 per cell) in a box twice
    /// its size, separable slip walls everywhere, soft Neo-Hookean, APIC + MUSL at CFL 0.4.
    fn assert_block<const D: usize>(name: &str, n: usize) {
        let (config, particles) = load::<D>(name);
        let h = 1.0 / (n / 2) as f64;
        assert_grid(&config, [n; D], h);
        let separable_slip = Wall {
            kind: WallKind::Slip,
            separable: true,
        };
        assert_eq!(config.boundary, Boundary::all(separable_slip));
        assert!(config.contact.is_empty());
        assert_eq!(config.transfer, Transfer::Apic);
        assert_eq!(config.scheme, Scheme::Musl);
        assert_eq!(
            config.time_step,
            TimeStep::Adaptive {
                cfl: 0.4,
                max_dt: 1e-3
            }
        );
        let mut gravity = Vector::<f64, D>::zeros();
        gravity[1] = -9.81;
        assert_eq!(config.gravity, gravity);
        assert_eq!(
            config.materials,
            vec![Material::elastic(
                ModelKind::NeoHookean,
                1.0e5,
                0.45,
                1000.0
            )]
        );
        assert_lattice(&particles, [n; D], 0.5 * h, 1000.0);
    }

    #[test]
    fn block_scenes_are_the_block_collapse() {
        assert_block::<2>("block_2d_10k", 100);
        assert_block::<2>("block_2d_100k", 318);
        assert_block::<3>("block_3d_100k", 48);
    }

    #[test]
    fn dambreak_scenes_are_the_friction_dam_break_at_their_scale() {
        for (name, scale) in [
            ("dambreak_friction", 1),
            ("dambreak_friction_96k", 4),
            ("dambreak_friction_1m", 13),
        ] {
            let (config, particles) = load::<2>(name);
            let h = 0.01 / scale as f64;
            assert_grid(&config, [200 * scale, 40 * scale], h);
            let mut boundary = Boundary::all(Wall::new(WallKind::Slip));
            boundary.walls[1][0].separable = true;
            assert_eq!(config.boundary, boundary);
            assert_eq!(config.transfer, Transfer::Mls);
            assert_eq!(config.scheme, Scheme::Usl);
            let TimeStep::Fixed { dt } = config.time_step else {
                panic!("{name}: fixed time step expected");
            };
            assert!(
                (dt * scale as f64 / 3e-5 - 1.0).abs() < 1e-15,
                "{name}: dt = {dt}"
            );
            assert_eq!(config.gravity, Vector::<f64, 2>::new(0.0, -9.8));
            assert_eq!(
                config.materials,
                vec![Material::fluid(1000.0 * 35.0 * 35.0, 7.0, 0.0, 1000.0)]
            );
            // Five floor segments of 0.4 m; their ends agree to round-off (k · 0.4).
            let mu = [0.0, 0.5, 0.1, 0.2, 0.0];
            assert_eq!(config.contact.segments.len(), mu.len());
            assert!(config.contact.obstacles.is_empty());
            for (k, s) in config.contact.segments.iter().enumerate() {
                assert_eq!((s.axis, s.side, s.mu), (1, 0, mu[k]));
                assert!((s.from[0] - 0.4 * k as f64).abs() < 1e-12);
                assert!((s.to[0] - 0.4 * (k + 1) as f64).abs() < 1e-12);
                assert_eq!((s.from[1], s.to[1]), (0.0, 0.0));
            }
            assert_lattice(&particles, [100 * scale, 60 * scale], 0.5 * h, 1000.0);
        }
    }

    #[test]
    fn column_scene_is_the_granular_column_at_a_third_of_the_cell_size() {
        let (config, particles) = load::<3>("column_3d_93k");
        let h = 0.01 / 3.0;
        assert_grid(&config, [120, 45, 120], h);
        let mut boundary = Boundary::all(Wall::new(WallKind::Slip));
        boundary.walls[1] = [
            Wall {
                kind: WallKind::Slip,
                separable: true,
            },
            Wall::new(WallKind::Free),
        ];
        assert_eq!(config.boundary, boundary);
        assert_eq!(config.transfer, Transfer::Apic);
        assert_eq!(config.scheme, Scheme::Musl);
        assert_eq!(
            config.time_step,
            TimeStep::Adaptive {
                cfl: 0.4,
                max_dt: 1e-3
            }
        );
        assert_eq!(config.gravity, Vector::<f64, 3>::new(0.0, -9.81, 0.0));
        let phi = 30f64.to_radians();
        assert_eq!(
            config.materials,
            vec![Material::drucker_prager(
                0.84e6, 0.3, phi, 0.0, 0.0, None, 2650.0
            )]
        );
        // The floor, μ = tan φ, over the whole face of the domain.
        assert_eq!(
            config.contact.segments,
            vec![FrictionSegment {
                axis: 1,
                side: 0,
                from: [0.0; 3],
                to: [0.4, 0.0, 0.4],
                mu: phi.tan(),
            }]
        );
        assert_lattice(&particles, [36, 72, 36], 0.5 * h, 2650.0);
    }

    #[test]
    fn scenes_lift_to_single_precision_and_step() {
        let (config, mut particles) = explicit_scene::<f32, 2>("dambreak_friction");
        let reference = load::<2>("dambreak_friction").1;
        assert_eq!(particles.len(), reference.len());
        for (x, y) in particles.x.iter().zip(&reference.x) {
            // f32 round-off of coordinates below 0.5 m.
            assert!((x.map(f64::from) - y).norm() < 1e-7);
        }
        let mut solver = loam_explicit::Solver::new(config, &particles).expect("valid scene");
        solver
            .step(&mut particles, f64::INFINITY)
            .expect("a stable step");
    }

    #[test]
    #[should_panic(expected = "no bench scene `block_2d_1m`")]
    fn an_unknown_scene_is_refused_with_the_known_ones() {
        explicit_scene::<f64, 2>("block_2d_1m");
    }

    #[test]
    fn implicit_particle_counts() {
        assert_eq!(cantilever_2d(0.25).1.len(), 5_760);
        assert_eq!(cantilever_2d(0.125).1.len(), 23_040);
        assert_eq!(cantilever_2d(0.0625).1.len(), 92_160);
        assert_eq!(hencky_block_3d(25_000).1.len(), 27_000);
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
}
