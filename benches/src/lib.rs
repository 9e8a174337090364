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
//! - `dambreak_3d_125k`, `dambreak_3d_1m`, `dambreak_3d_1920k`: a 3D water dam-break (MLS-MPM,
//!   USL, fixed step), on the CPU or the GPU.
//! - `dambreak_obstacles_3d_123k`, `_1m`, `_1920k`: the 3D dam-break against two rigid
//!   columns (122,880, 983,040 and 1,920,000 particles), on the CPU or the GPU.
//! - `cylinder_collapse_3d_100k`, `_1m`, `_2710k`: a full cylinder of Drucker–Prager sand
//!   collapsing on a Coulomb floor (101,592, 993,208 and 2,712,288 particles; APIC, MUSL,
//!   fixed step), on the CPU or the GPU.
//!
//! The implicit bench scenes are scene files too ([`IMPLICIT_SCENES`]): the reference
//! cantilever `examples/cantilever.toml` (cpGIMP), its quadratic-B-spline twin
//! `benches/scenes/cantilever_2d.toml`, which [`cantilever_2d`] builds at other cell sizes,
//! and the 3D block `benches/scenes/hencky_block_3d_27k.toml`. [`implicit_scene`] builds one
//! the same way through `Built::implicit_config`, in `f64`.

use loam_core::{Particles, Scalar};
use loam_explicit::Config;
use loam_implicit::ImplicitConfig;
use loam_scene::{Scene, SceneFormat};

/// A bench scene: a scene file of the repository, compiled into the crate.
#[derive(Clone, Copy, Debug)]
pub struct BenchScene {
    /// The file's stem, which [`explicit_scene`] or [`implicit_scene`] takes.
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
pub const EXPLICIT_SCENES: [BenchScene; 16] = [
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
    bench_scene!("dambreak_3d_125k", "benches/scenes/dambreak_3d_125k.toml"),
    bench_scene!("dambreak_3d_1m", "benches/scenes/dambreak_3d_1m.toml"),
    bench_scene!("dambreak_3d_1920k", "benches/scenes/dambreak_3d_1920k.toml"),
    bench_scene!(
        "dambreak_obstacles_3d_123k",
        "benches/scenes/dambreak_obstacles_3d_123k.toml"
    ),
    bench_scene!(
        "dambreak_obstacles_3d_1m",
        "benches/scenes/dambreak_obstacles_3d_1m.toml"
    ),
    bench_scene!(
        "dambreak_obstacles_3d_1920k",
        "benches/scenes/dambreak_obstacles_3d_1920k.toml"
    ),
    bench_scene!(
        "cylinder_collapse_3d_100k",
        "benches/scenes/cylinder_collapse_3d_100k.toml"
    ),
    bench_scene!(
        "cylinder_collapse_3d_1m",
        "benches/scenes/cylinder_collapse_3d_1m.toml"
    ),
    bench_scene!(
        "cylinder_collapse_3d_2710k",
        "benches/scenes/cylinder_collapse_3d_2710k.toml"
    ),
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
    let scene = find(&EXPLICIT_SCENES, name);
    let built = Scene::from_toml_str(scene.toml)
        .and_then(|s| s.build::<D>())
        .unwrap_or_else(|e| panic!("{}: {e}", scene.path));
    let config = built
        .explicit_config()
        .unwrap_or_else(|| panic!("{}: not an explicit scene", scene.path));
    (config.lift(), built.particles.lift())
}

/// The implicit bench scenes (quasi-static load stepping, `f64` only).
///
/// - `cantilever` (`examples/cantilever.toml`): the reference large-deflection cantilever
///   with cpGIMP, 5,760 particles, 50 load steps; `loam bench cantilever` and the
///   `cantilever` bench run it end to end.
/// - `cantilever_2d`: the same beam with quadratic B-splines, 5,760 particles at its cell
///   size of 0.25 m; [`cantilever_2d`] builds it at other cell sizes.
/// - `hencky_block_3d_27k`: a 1 m Hencky cube settling under gravity on a fixed floor
///   between slip walls, 27,000 particles, 10 load steps.
pub const IMPLICIT_SCENES: [BenchScene; 3] = [
    bench_scene!("cantilever", "examples/cantilever.toml"),
    bench_scene!("cantilever_2d", "benches/scenes/cantilever_2d.toml"),
    bench_scene!(
        "hencky_block_3d_27k",
        "benches/scenes/hencky_block_3d_27k.toml"
    ),
];

/// The solver inputs of the implicit bench scene `name` (a stem of [`IMPLICIT_SCENES`]) in
/// `D` dimensions: the scene is parsed, validated and built by `loam-scene`
/// (`Built::implicit_config` and `Built::particles`), as `loam run` does.
///
/// # Panics
///
/// When `name` is not an implicit bench scene or the scene is not `D`-dimensional (fixed by
/// the callers; the tests build every scene).
pub fn implicit_scene<const D: usize>(name: &str) -> (ImplicitConfig<D>, Particles<f64, D>) {
    let scene = find(&IMPLICIT_SCENES, name);
    let parsed = Scene::from_toml_str(scene.toml).unwrap_or_else(|e| panic!("{}: {e}", scene.path));
    build_implicit(&parsed, scene.path)
}

/// The quadratic-B-spline cantilever of `benches/scenes/cantilever_2d.toml` at cell size
/// `cell` (m): the file's scene with `grid.cell_size = cell`, validated and built through
/// `loam-scene`.
///
/// The beam, its support boxes and its tip load are given in metres, so only the
/// resolution changes: 6 × 6 particles per cell make `(10 / cell) · (6 / cell)` particles,
/// 5,760 at the file's 0.25 m, 23,040 at 0.125 m and 92,160 at 0.0625 m. `cell` must divide
/// 15 m and 0.25 m, so that the beam's ends and the neutral axis y = 9.5 m lie on node lines.
///
/// # Panics
///
/// When the scene is not valid at that cell size.
pub fn cantilever_2d(cell: f64) -> (ImplicitConfig<2>, Particles<f64, 2>) {
    let file = find(&IMPLICIT_SCENES, "cantilever_2d");
    let mut scene = Scene::parse_str(file.toml, SceneFormat::Toml)
        .unwrap_or_else(|e| panic!("{}: {e}", file.path));
    scene.grid.cell_size = cell;
    scene
        .validate()
        .unwrap_or_else(|e| panic!("{} at cell size {cell} m: {e}", file.path));
    build_implicit(&scene, file.path)
}

/// The bench scene `name` of `scenes`.
///
/// # Panics
///
/// When there is none, listing the known names.
fn find<'a>(scenes: &'a [BenchScene], name: &str) -> &'a BenchScene {
    scenes.iter().find(|s| s.name == name).unwrap_or_else(|| {
        let known: Vec<&str> = scenes.iter().map(|s| s.name).collect();
        panic!(
            "no bench scene `{name}`; expected one of {}",
            known.join(", ")
        )
    })
}

/// Builds the validated implicit scene `scene` (read from `path`) in `D` dimensions.
fn build_implicit<const D: usize>(
    scene: &Scene,
    path: &str,
) -> (ImplicitConfig<D>, Particles<f64, D>) {
    let built = scene.build::<D>().unwrap_or_else(|e| panic!("{path}: {e}"));
    let config = built
        .implicit_config()
        .unwrap_or_else(|| panic!("{path}: not an implicit scene"));
    (config, built.particles)
}

#[cfg(test)]
mod tests {
    use super::*;
    use loam_core::tensor::Vector;
    use loam_core::{
        Boundary, FrictionSegment, Material, ModelKind, NodeConstraint, Scheme, Shape, TimeStep,
        Transfer, Wall, WallKind,
    };
    use loam_implicit::{ImplicitSolver, NewtonSettings};

    /// Builds the bench scene `name` in f64 through the loader.
    fn load<const D: usize>(name: &str) -> (Config<f64, D>, Particles<f64, D>) {
        explicit_scene::<f64, D>(name)
    }

    /// Checks that `p` is the block of `n[0] × … × n[D−1]` particles of spacing `dp` and
    /// density `density` from the corner `lo`, at `lo + (i + ½) dp` per axis, axis 0 fastest,
    /// at rest: the lattice the benches used to build by hand.
    fn assert_lattice<const D: usize>(
        p: &Particles<f64, D>,
        lo: [f64; D],
        n: [usize; D],
        dp: f64,
        density: f64,
    ) {
        assert_eq!(p.len(), n.iter().product::<usize>());
        let volume = dp.powi(D as i32);
        let mut k = 0;
        let mut index = [0usize; D];
        loop {
            for a in 0..D {
                // Round-off: the coordinates are at most 10.25 m and come from a few
                // operations (~2e-15 m each); 1e-12 m is far below the smallest spacing
                // (3.8e-4 m), so a particle one site off fails.
                let expected = lo[a] + (index[a] as f64 + 0.5) * dp;
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
        assert_lattice(&particles, [0.0; D], [n; D], 0.5 * h, 1000.0);
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
            assert_lattice(
                &particles,
                [0.0; 2],
                [100 * scale, 60 * scale],
                0.5 * h,
                1000.0,
            );
        }
    }

    /// The smallest sizes of the GPU bench families: the dam-break's water is the lattice of
    /// 2 × 2 × 2 particles per cell over 0.6 m × 0.5 m × 0.8 m, clear of its two columns; the
    /// cylinder of sand holds the particles of its volume `π R² H / dp³` up to those of one
    /// layer at its surface, `A / dp²` (`A = 2π R H + 2π R²`), all inside it.
    #[test]
    fn gpu_bench_families_are_their_geometry() {
        let (config, particles) = load::<3>("dambreak_obstacles_3d_123k");
        let h = 0.025;
        assert_grid(&config, [64, 32, 32], h);
        assert_lattice(&particles, [0.0; 3], [48, 40, 64], 0.5 * h, 1000.0);
        assert_eq!(config.contact.obstacles.len(), 2);
        for x in &particles.x {
            assert_eq!(config.contact.penetrated(&[x[0], x[1], x[2]], 0.0), None);
        }
        let (config, particles) = load::<3>("cylinder_collapse_3d_100k");
        let (h, r, height) = (0.0075, 0.0942, 0.19);
        assert_eq!(config.grid.cells, [74, 28, 74]);
        assert_eq!(config.grid.lo, [-0.2775, 0.0, -0.2775]);
        assert!((config.grid.h / h - 1.0).abs() < 1e-15);
        let dp = 0.5 * h;
        let volume = std::f64::consts::PI * r * r * height;
        let surface = 2.0 * std::f64::consts::PI * r * (height + r);
        let n = particles.len() as f64;
        assert!(
            (n - volume / dp.powi(3)).abs() <= surface / (dp * dp),
            "{n} particles"
        );
        for x in &particles.x {
            assert!(x[0] * x[0] + x[2] * x[2] <= r * r && x[1] > 0.0 && x[1] < height);
        }
        assert_eq!(config.contact.segments.len(), 1);
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
        assert_lattice(&particles, [0.0; 3], [36, 72, 36], 0.5 * h, 2650.0);
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

    /// Checks the cantilever of `examples/cantilever.toml` and `benches/scenes/cantilever_2d.toml`
    /// at cell size `h` with shape functions `shape`: the 10 m × 1 m Hencky beam from
    /// (0.25, 9) m at 6 × 6 particles per cell on 15 m × 15 m, held on the nodes of
    /// x ∈ [0, 0.25] m, 100 kN on the two particles nearest (10.25, 9.5) m, 50 load steps.
    fn assert_cantilever(
        (config, particles): &(ImplicitConfig<2>, Particles<f64, 2>),
        h: f64,
        shape: Shape,
    ) {
        let cells = (15.0 / h).round() as usize;
        assert_eq!(config.grid.cells, [cells; 2]);
        assert!(
            (config.grid.h / h - 1.0).abs() < 1e-15,
            "h = {}",
            config.grid.h
        );
        assert_eq!(config.grid.lo, [0.0; 2]);
        assert_eq!(config.grid.pad, shape.ghost_cells());
        assert_eq!(config.shape, shape);
        assert_eq!(config.boundary, Boundary::all(Wall::new(WallKind::Free)));
        assert_eq!(
            config.materials,
            vec![Material::elastic(ModelKind::Hencky, 12.0e6, 0.2, 1.0)]
        );
        assert_eq!(config.gravity, Vector::<f64, 2>::zeros());
        assert_eq!(
            config.constraints,
            vec![
                NodeConstraint {
                    lo: [0.0, -1.0e9],
                    hi: [0.25, 1.0e9],
                    displacement: [Some(0.0), None],
                    force: [None, None],
                },
                NodeConstraint {
                    lo: [0.0, 9.5],
                    hi: [0.25, 9.5],
                    displacement: [None, Some(0.0)],
                    force: [None, None],
                },
            ]
        );
        // The last particle column, either side of the neutral axis (in either order: which
        // is nearer is decided by round-off), 50 kN down each.
        let dp = h / 6.0;
        assert_eq!(config.point_loads.len(), 2);
        let mut loaded: Vec<Vector<f64, 2>> = config
            .point_loads
            .iter()
            .map(|load| {
                assert_eq!(load.force, [0.0, -50.0e3]);
                particles.x[load.particle]
            })
            .collect();
        loaded.sort_by(|a, b| a[1].total_cmp(&b[1]));
        for (x, y) in loaded.iter().zip([9.5 - 0.5 * dp, 9.5 + 0.5 * dp]) {
            assert!(
                (x - Vector::<f64, 2>::new(10.25 - 0.5 * dp, y)).norm() < 1e-12,
                "{x}"
            );
        }
        assert_eq!(config.load_steps, 50);
        assert_eq!(config.newton, NewtonSettings::default());
        assert_eq!(config.dynamics, None);
        let n = [(10.0 / dp).round() as usize, (1.0 / dp).round() as usize];
        assert_lattice(particles, [0.25, 9.0], n, dp, 1.0);
    }

    #[test]
    fn cantilever_scenes_are_the_reference_beam_at_their_cell_size() {
        let reference = implicit_scene::<2>("cantilever");
        assert_cantilever(&reference, 0.25, Shape::Cpgimp);
        assert_eq!(reference.1.len(), 5_760);
        for (h, count) in [(0.25, 5_760), (0.125, 23_040), (0.0625, 92_160)] {
            let scene = cantilever_2d(h);
            assert_cantilever(&scene, h, Shape::QuadraticBspline);
            assert_eq!(scene.1.len(), count);
        }
        let (config, particles) = implicit_scene::<2>("cantilever_2d");
        assert_eq!(config.grid.h, 0.25);
        assert_eq!(particles.x, cantilever_2d(0.25).1.x);
        ImplicitSolver::new(config, &particles).expect("valid cantilever");
    }

    #[test]
    fn block_scene_is_the_hencky_block_settling_on_a_fixed_floor() {
        let (config, particles) = implicit_scene::<3>("hencky_block_3d_27k");
        let h = 1.0 / 15.0;
        assert_eq!(config.grid.cells, [15, 16, 15]);
        assert!(
            (config.grid.h / h - 1.0).abs() < 1e-15,
            "h = {}",
            config.grid.h
        );
        assert_eq!(config.grid.lo, [0.0; 3]);
        assert_eq!(config.grid.pad, Shape::QuadraticBspline.ghost_cells());
        assert_eq!(config.shape, Shape::QuadraticBspline);
        let mut boundary = Boundary::all(Wall::new(WallKind::Slip));
        boundary.walls[1] = [Wall::new(WallKind::Fixed), Wall::new(WallKind::Free)];
        assert_eq!(config.boundary, boundary);
        assert_eq!(
            config.materials,
            vec![Material::elastic(ModelKind::Hencky, 1.0e6, 0.3, 1000.0)]
        );
        assert_eq!(config.gravity, Vector::<f64, 3>::new(0.0, -9.81, 0.0));
        assert!(config.constraints.is_empty() && config.point_loads.is_empty());
        assert_eq!(config.load_steps, 10);
        assert_eq!(config.newton, NewtonSettings::default());
        assert_eq!(config.dynamics, None);
        assert_lattice(&particles, [0.0; 3], [30; 3], 0.5 * h, 1000.0);

        let solver = ImplicitSolver::new(config, &particles).expect("valid 3D block");
        let system = solver
            .system(&particles, 0.0, 0.1)
            .expect("block on the grid");
        assert!(!system.is_empty());
        // Gravity pushes down: the external force on the unknowns sums to −ρ g V λ along y.
        assert!(system.f_ext.iter().sum::<f64>() < 0.0);
    }

    #[test]
    #[should_panic(expected = "no bench scene `cantilever_3d`; expected one of cantilever")]
    fn an_unknown_implicit_scene_is_refused_with_the_known_ones() {
        implicit_scene::<3>("cantilever_3d");
    }
}
