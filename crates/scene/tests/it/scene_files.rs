//! Scene files: malformed fixtures give errors naming the offending field, good ones build
//! with the expected particles, and the example scenes load.

use loam_core::constitutive::{Cone, DruckerPrager, Elasticity, Fluid, J2, Lame, Model};
use loam_core::{NodeConstraint, PointLoad, Scheme, Shape, TimeStep, Transfer, Wall, WallKind};
use loam_implicit::linear::{LinearSolverKind, Preconditioner};
use loam_implicit::strength_reduction::SearchSettings;
use loam_implicit::{NewtonSettings, TangentMethod};
use loam_scene::{
    Device, ExplicitPlan, ImplicitPlan, NewtonSpec, Scene, SceneError, SolverKind, SolverPlan,
};
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

/// Each malformed fixture and substrings its error message must contain: the field path and
/// what was expected.
const BAD: &[(&str, &[&str])] = &[
    (
        "unknown_field.toml",
        &["solver.sheme: unknown field `sheme`", "(line 41, column 1)"],
    ),
    (
        "unknown_material.toml",
        &[r#"bodies[1].material: unknown material "sand"; expected one of "rubber", "steel""#],
    ),
    (
        "poisson_ratio.toml",
        &["materials[0].poisson_ratio: must be in (-1, 0.5), got 0.5"],
    ),
    (
        "negative_cell_size.toml",
        &["grid.cell_size: must be positive, got -0.1"],
    ),
    (
        "cell_size_not_divisor.toml",
        &["grid.cell_size: the domain extent 1 along x is not a whole number of cells"],
    ),
    (
        "body_outside_domain.toml",
        &[
            "bodies[0]: body lies outside the grid domain",
            "[0.1, 1.3] × [0.1, 0.3]",
        ],
    ),
    (
        "wrong_coordinate_count.toml",
        &["bodies[0].shape.lo: expected 2 coordinates (the grid is 2D), got 3"],
    ),
    (
        "toml_syntax.toml",
        &["TOML syntax error at line 16, column 14"],
    ),
    ("missing_section.toml", &["missing field `solver`"]),
    (
        "unknown_model.toml",
        &[
            "materials[0].model: unknown variant `mooney_rivlin`",
            "`hencky`",
        ],
    ),
    (
        "unknown_shape.toml",
        &[
            "bodies[1].shape.type: unknown variant `triangle`",
            "`polygon`",
        ],
    ),
    (
        "unknown_transfer.toml",
        &["solver.transfer: unknown variant `sph`", "`apic`"],
    ),
    (
        "transfer_unknown_field.toml",
        &["solver.transfer: unknown field `alpha`, there are no fields"],
    ),
    (
        "mls_with_gimp.toml",
        &["solver.transfer: MLS-MPM needs a B-spline shape function"],
    ),
    (
        "flip_without_alpha.toml",
        &["solver.transfer: missing field `alpha`"],
    ),
    (
        "cfl_out_of_range.toml",
        &["solver.time_step.cfl: must be in (0, 1], got 1.5"],
    ),
    (
        "fixed_dt_above_end_time.toml",
        &[
            "solver.time_step.dt: 0.001 s is more than twice solver.end_time = 0.0004 s",
            "round(end_time / dt) steps, here none",
        ],
    ),
    (
        "zero_frames.toml",
        &["output.frames: must be at least 1, got 0"],
    ),
    (
        "empty_polygon.toml",
        &["bodies[1].shape.vertices: a polygon needs at least 3 vertices, got 0"],
    ),
    (
        "huge_exponent.toml",
        &["materials[1].youngs_modulus: floating-point number overflowed"],
    ),
    (
        "infinite_modulus.toml",
        &["materials[0].youngs_modulus: must be a finite number, got -inf"],
    ),
    (
        "nan_density.toml",
        &["materials[0].density: must be a finite number, got NaN"],
    ),
    ("no_particles.toml", &["bodies[0]: generates no particles"]),
    (
        "shape_wrong_dimension.toml",
        &["bodies[1].shape.type: a sphere is a 3D shape but the grid is 2D"],
    ),
    (
        "z_face_in_2d.toml",
        &["boundaries.z_min: the grid is 2D; it has no z faces"],
    ),
    (
        "wrong_type.toml",
        &["materials[1].density: invalid type: string \"heavy\", expected f64"],
    ),
    (
        "wall_unknown_field.toml",
        &["boundaries.y_min.sepparable: unknown field `sepparable`"],
    ),
    (
        "wall_unknown_kind.toml",
        &["boundaries.x_min: unknown variant `sticky`", "`no_slip`"],
    ),
    (
        "duplicate_material.toml",
        &[r#"materials[1].name: duplicate material name "rubber""#],
    ),
    (
        "top_level_gravity.toml",
        &["unknown field `gravity`", "`loads`"],
    ),
    (
        "time_step_unknown_field.toml",
        &["solver.time_step: unknown field `maxdt`"],
    ),
    (
        "several_issues.toml",
        &[
            "materials[0].poisson_ratio: must be in (-1, 0.5), got -1.5",
            "bodies[0].particles_per_cell: must be between 1 and 8, got 0",
            "solver.end_time: must be positive, got 0",
        ],
    ),
    (
        "poisson_ratio.json",
        &["materials[1].poisson_ratio: must be in (-1, 0.5), got 0.7"],
    ),
    (
        "unknown_field.json",
        &["grid.cellsize: unknown field `cellsize`", "line 12"],
    ),
    ("json_syntax.json", &["JSON syntax error at line 79"]),
    (
        "j2_without_yield_stress.toml",
        &[r#"materials[0].yield_stress: required for model "j2""#],
    ),
    (
        "fluid_without_sound_speed.toml",
        &[
            r#"materials[0].sound_speed: required for model "fluid" (the reference sound speed, m/s), unless bulk_modulus (Pa) is given instead"#,
        ],
    ),
    (
        "fluid_with_youngs_modulus.toml",
        &[r#"materials[0].youngs_modulus: not used by model "fluid""#],
    ),
    (
        "implicit_without_load_steps.toml",
        &["solver.load_steps: required for the implicit solver (the number of load steps"],
    ),
    (
        "device_in_implicit.toml",
        &["solver.device: only used by the explicit solver"],
    ),
    (
        "unknown_device.toml",
        &[
            "solver.device: unknown variant `tpu`",
            "expected `cpu` or `gpu`",
        ],
    ),
    (
        "implicit_with_time_step.toml",
        &["solver.time_step: only used by the explicit solver"],
    ),
    (
        "fluid_in_implicit.toml",
        &[r#"materials[0].model: "fluid" is for the explicit solver"#],
    ),
    (
        "drucker_prager_without_friction_angle.toml",
        &[
            r#"materials[0].friction_angle: required for model "drucker_prager" (the friction angle φ in degrees, 0 < φ < 90)"#,
        ],
    ),
    (
        "drucker_prager_friction_angle_range.toml",
        &["materials[0].friction_angle: must be in (0, 90) degrees, got 90"],
    ),
    (
        "drucker_prager_dilation_above_friction.toml",
        &["materials[0].dilation_angle: must be in [0, friction_angle] = [0, 30] degrees, got 35"],
    ),
    (
        "drucker_prager_negative_cohesion.toml",
        &["materials[0].cohesion: must be zero or positive, got -1000"],
    ),
    (
        "drucker_prager_tension_cutoff_above_apex.toml",
        &[
            "materials[0].tension_cutoff: must be in [0, c cot φ] = [0, 1000] Pa (the apex, \
             which is the default), got 2000",
        ],
    ),
    (
        "drucker_prager_jaumann_in_implicit.toml",
        &[r#"materials[0].elasticity: "jaumann" is for the explicit solver"#],
    ),
    (
        "friction_angle_on_elastic.toml",
        &[
            r#"materials[0].friction_angle: only used by models "drucker_prager" and "mohr_coulomb""#,
        ],
    ),
    (
        "newmark_dt_negative.toml",
        &["solver.newmark_dt: must be positive"],
    ),
    (
        "velocity_in_quasi_static.toml",
        &["bodies[0].velocity: not used by a quasi-static implicit run"],
    ),
    (
        "explicit_with_constraints.toml",
        &[r#"constraints: only applied by the implicit solver; set solver.type = "implicit""#],
    ),
    (
        "explicit_without_time_step.toml",
        &["solver.time_step: required for the explicit solver"],
    ),
    (
        "constraint_wrong_length.toml",
        &[
            "constraints[0].displacement: expected 2 components (the grid is 2D), each a number \
           (m) or \"free\", got 3",
        ],
    ),
    (
        "constraint_all_free.toml",
        &[
            "constraints[1]: no component is prescribed: give `displacement` (m) or `force` (N) \
             a number for at least one axis",
        ],
    ),
    (
        "constraint_force_and_displacement.toml",
        &["constraints[1].force[1]: axis 1 also has a displacement"],
    ),
    (
        "constraint_force_colour.toml",
        &[
            r#"constraints[1].force: a force-controlled group needs solver.newton.tangent = "local""#,
        ],
    ),
    (
        "constraint_force_overlap.toml",
        &[
            "constraints[2].force[1]: the box overlaps constraints[1], also force-controlled \
             along axis 1",
        ],
    ),
    (
        "constraint_force_wrong_length.toml",
        &[
            "constraints[1].force: expected 2 components (the grid is 2D), each a number (N) or \
             \"free\", got 3",
        ],
    ),
    (
        "constraint_no_node.toml",
        &["constraints[1]: the box contains no grid node; node spacing is h = 0.25 m from grid.lo"],
    ),
    (
        "point_load_zero_count.toml",
        &["point_loads[0].count: must be at least 1, got 0"],
    ),
    (
        "point_load_outside.toml",
        &["point_loads[0].at: the point (20, 9.5) lies outside the grid domain [0, 15] × [0, 15]"],
    ),
    (
        "unknown_tangent.toml",
        &["solver.newton.tangent: unknown variant `exact`", "`colour`"],
    ),
    (
        "cg_unknown_preconditioner.toml",
        &[
            "solver.linear.preconditioner: unknown variant `ilu`",
            "`identity`, `jacobi`, `ilu0`",
        ],
    ),
    (
        "block_without_pore_fluid.toml",
        &[
            "solver.linear.preconditioner: \"block\" splits the unknowns into displacements and \
             pore pressures and needs a [pore_fluid] section",
        ],
    ),
    (
        "friction_on_free_face.toml",
        &[
            "friction[0].wall: friction needs a unilateral slip wall on y_min, which is not \
             declared (free): set boundaries.y_min = { kind = \"slip\", separable = true }",
        ],
    ),
    (
        "friction_on_bilateral_wall.toml",
        &["friction[0].wall: friction needs a unilateral slip wall on y_min, which is a bilateral"],
    ),
    (
        "friction_negative_mu.toml",
        &["friction[0].mu: must be zero or positive, got -0.2"],
    ),
    (
        "friction_overlap.toml",
        &["friction[1]: overlaps friction[0] on the y_min face"],
    ),
    (
        "friction_wrong_dimension.toml",
        &["friction[0].from: expected 1 coordinate along the face ([x]: the axes other than y"],
    ),
    (
        "friction_off_face.toml",
        &["friction[0]: the segment [1, 2.5] ([x]) does not lie on the y_min face [0, 2]"],
    ),
    (
        "friction_without_to.toml",
        &["friction[0].to: give both `from` and `to`"],
    ),
    (
        "friction_z_face_in_2d.toml",
        &["friction[0].wall: the grid is 2D; it has no z faces"],
    ),
    (
        "friction_unknown_face.toml",
        &["friction[0].wall: unknown variant `floor`", "`y_min`"],
    ),
    (
        "friction_in_implicit.toml",
        &[r#"friction: only applied by the explicit solver"#],
    ),
    (
        "obstacle_outside_grid.toml",
        &[
            "obstacles[0]: obstacle lies outside the grid domain: its bounding box [1.5, 2.5] × \
             [0, 0.2] is not inside [0, 2] × [0, 0.5]",
        ],
    ),
    (
        "obstacle_wrong_dimension.toml",
        &["obstacles[0].lo: expected 2 coordinates (the grid is 2D), got 3"],
    ),
    (
        "obstacle_negative_friction.toml",
        &["obstacles[0].friction: must be zero or positive, got -0.1"],
    ),
    (
        "obstacle_key_of_other_shape.toml",
        &[r#"obstacles[0].lo: not used by shape "cylinder""#],
    ),
    (
        "obstacle_axis_in_2d.toml",
        &["obstacles[0].axis: not used in 2D: a cylinder in a 2D (plane-strain) scene is a disk"],
    ),
    (
        "obstacle_cylinder_without_axis.toml",
        &[
            "obstacles[0].axis: required for a cylinder in 3D",
            "obstacles[0].length: required for a cylinder in 3D",
        ],
    ),
    (
        "obstacle_unknown_shape.toml",
        &["obstacles[0].shape: unknown variant `sphere`, expected `box` or `cylinder`"],
    ),
    (
        "obstacle_in_implicit.toml",
        &["obstacles: only applied by the explicit solver"],
    ),
    (
        "body_inside_obstacle.toml",
        &[
            "bodies[0]: generates no particles",
            "and outside the obstacles",
        ],
    ),
];

#[test]
fn malformed_scenes_name_the_offending_field() {
    let mut failures = Vec::new();
    for (name, expected) in BAD {
        let path = fixture(&format!("bad/{name}"));
        match Scene::from_path(&path) {
            Ok(_) => failures.push(format!("{name}: loaded without error")),
            Err(err) => {
                let msg = err.to_string();
                // Every message starts with the file name.
                if !msg.starts_with(&path.display().to_string()) {
                    failures.push(format!(
                        "{name}: message does not start with the path: {msg}"
                    ));
                }
                for want in *expected {
                    if !msg.contains(want) {
                        failures.push(format!("{name}: expected `{want}` in:\n{msg}"));
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn every_bad_fixture_is_in_the_table() {
    let dir = fixture("bad");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    files.sort();
    let mut listed: Vec<String> = BAD.iter().map(|(n, _)| n.to_string()).collect();
    listed.sort();
    assert_eq!(files, listed);
}

#[test]
fn several_issues_are_reported_one_per_line() {
    let err = Scene::from_path(fixture("bad/several_issues.toml")).unwrap_err();
    assert_eq!(err.issues().len(), 3);
    assert_eq!(err.to_string().lines().count(), 3);
}

/// Serde stops at the first key a struct does not know; the loaders go on, so a file with
/// four misspelt keys in four sections (one inside a tagged shape table) lists all four, each
/// with its path, in TOML (with its line) and in JSON.
#[test]
fn every_unknown_key_is_reported_with_its_path() {
    let text = std::fs::read_to_string(fixture("good/box_2d.toml"))
        .unwrap()
        .replace("cell_size = 0.02", "cell_size = 0.02\ncellsize = 0.02")
        .replace("poisson_ratio = 0.3", "poisson_ratio = 0.3\npoisson = 0.3")
        .replace("hi = [0.3, 0.3] }", "hi = [0.3, 0.3], radius = 1.0 }")
        .replace("end_time = 0.5", "end_time = 0.5\nsheme = \"usl\"");
    let err = Scene::from_toml_str(&text).unwrap_err();
    let msg = err.to_string();
    let wanted = [
        "grid.cellsize: unknown field `cellsize`",
        "materials[0].poisson: unknown field `poisson`",
        "bodies[0].shape: unknown field `radius`",
        "solver.sheme: unknown field `sheme`",
    ];
    for want in wanted {
        assert!(msg.contains(want), "{want} missing from:\n{msg}");
    }
    assert_eq!(err.issues().len(), 4, "{msg}");
    assert!(msg.contains("(line 6, column 1)"), "{msg}");
    // The same scene in JSON.
    let scene: toml::Table =
        toml::from_str(&std::fs::read_to_string(fixture("good/box_2d.toml")).unwrap()).unwrap();
    let mut json = serde_json::to_value(&scene).unwrap();
    json["grid"]["cellsize"] = 0.02.into();
    json["materials"][0]["poisson"] = 0.3.into();
    json["bodies"][0]["shape"]["radius"] = 1.0.into();
    json["solver"]["sheme"] = "usl".into();
    let err = Scene::from_json_str(&json.to_string()).unwrap_err();
    let msg = err.to_string();
    for want in wanted {
        assert!(msg.contains(want), "{want} missing from:\n{msg}");
    }
    assert_eq!(err.issues().len(), 4, "{msg}");
}

#[test]
fn unknown_extension_and_missing_file_are_errors() {
    let err = Scene::from_path("scene.yaml").unwrap_err();
    assert!(matches!(err, SceneError::Extension { .. }), "{err}");
    let err = Scene::from_path(fixture("good/does_not_exist.toml")).unwrap_err();
    assert!(matches!(err, SceneError::Read { .. }), "{err}");
    assert!(
        err.to_string()
            .contains("does_not_exist.toml: cannot read the scene file")
    );
}

#[test]
fn strings_without_a_file_have_no_prefix() {
    let err = Scene::from_toml_str("[grid]\nlo = [0.0, 0.0]\n").unwrap_err();
    assert_eq!(
        err.to_string(),
        "grid: missing field `hi` (line 1, column 1)"
    );
    let err = Scene::from_json_str("{").unwrap_err();
    assert!(
        err.to_string().starts_with("JSON syntax error at line 1"),
        "{err}"
    );
}

#[test]
fn box_fixture_builds_400_particles_with_the_expected_state() {
    let scene = Scene::from_path(fixture("good/box_2d.toml")).unwrap();
    assert_eq!(scene.dim(), 2);
    let built = scene.build::<2>().unwrap();
    let p = &built.particles;
    // 10 × 10 cells × 2² particles.
    assert_eq!(p.len(), 400);
    let (h, ppc) = (0.02, 2.0);
    let vol = (h / ppc) * (h / ppc);
    for i in 0..p.len() {
        assert!((p.volume0[i] - vol).abs() < 1e-18);
        assert!((p.mass[i] - 1000.0 * vol).abs() < 1e-15);
        assert!((p.half_width0[i][0] - h / (2.0 * ppc)).abs() < 1e-18);
        assert_eq!(p.v[i], nalgebra::vector![1.0, -0.5]);
        assert_eq!(p.material[i], 0);
        let x = p.x[i];
        assert!(x[0] > 0.1 && x[0] < 0.3 && x[1] > 0.1 && x[1] < 0.3);
    }
    // The first particle sits at the centre of the first sub-cell.
    assert!((p.x[0] - nalgebra::vector![0.105, 0.105]).norm() < 1e-12);
    assert!((p.total_mass() - 1000.0 * 0.04).abs() < 1e-12);

    assert_eq!(built.grid.cells, [50, 50]);
    assert_eq!(built.grid.pad, 2);
    assert_eq!(built.shape, Shape::QuadraticBspline);
    assert_eq!(built.gravity, nalgebra::vector![0.0, -9.81]);
    assert_eq!(built.boundary.walls[1][0], Wall::new(WallKind::NoSlip));
    assert_eq!(built.boundary.walls[0][0], Wall::default());
    assert_eq!(built.material_names, vec!["rubber"]);
    // Left out in the file: `None` as written, the defaults in the plan.
    assert_eq!(built.solver.kind, SolverKind::Explicit);
    assert_eq!(built.solver.scheme, None);
    assert_eq!(built.solver.transfer, None);
    assert_eq!(
        built.plan,
        SolverPlan::Explicit(ExplicitPlan {
            scheme: Scheme::Musl,
            transfer: Transfer::Apic,
            time_step: TimeStep::Fixed { dt: 1e-4 },
            end_time: 0.5,
            device: Device::Cpu,
        })
    );
    assert!(built.constraints.is_empty() && built.point_loads.is_empty());
    // A fixed step: 0.5 s / 1e-4 s = 5000 steps, a frame every 250.
    let frame_steps: Vec<usize> = (0..=20).map(|k| 250 * k).collect();
    assert_eq!(built.frame_steps(), frame_steps);
    assert_eq!(built.output.dir, Path::new("out/box_2d"));
    assert_eq!(built.output.frames, 20);
    // Every field but those of a coupled (u–p) run.
    let fields: Vec<_> = (loam_scene::output::Field::ALL.into_iter())
        .filter(|f| !f.coupled_only())
        .collect();
    assert_eq!(built.output.fields, fields);
    assert_eq!(built.frame_times().len(), 21);
    assert!((built.frame_times()[20] - 0.5).abs() < 1e-15);
}

#[test]
fn disk_fixture_samples_the_disk_area() {
    let built = Scene::from_path(fixture("good/disk_2d.toml"))
        .unwrap()
        .build::<2>()
        .unwrap();
    let spacing: f64 = 0.02 / 2.0;
    let expected = std::f64::consts::PI * 0.2 * 0.2 / (spacing * spacing);
    let n = built.particles.len() as f64;
    assert!(
        (n - expected).abs() / expected < 0.01,
        "{n} particles, expected ≈ {expected}"
    );
    assert_eq!(built.grid.pad, 2);
    assert_eq!(built.shape, Shape::CubicBspline);
    let SolverPlan::Explicit(plan) = built.plan else {
        panic!("{:?}", built.plan)
    };
    assert_eq!(plan.scheme, Scheme::Usl);
    assert_eq!(plan.transfer, Transfer::Flip { alpha: 0.95 });
    assert_eq!(
        built.boundary.walls[1][0],
        Wall {
            kind: WallKind::NoSlip,
            separable: true
        }
    );
    assert_eq!(built.boundary.walls[1][1], Wall::new(WallKind::Fixed));
    assert_eq!(built.output.dir, Path::new("out/gel"));
    assert_eq!(built.output.fields.len(), 3);
}

#[test]
fn the_first_body_owns_an_overlap() {
    let built = Scene::from_path(fixture("good/overlap_2d.toml"))
        .unwrap()
        .build::<2>()
        .unwrap();
    let p = &built.particles;
    assert_eq!(p.len(), 600);
    assert_eq!(p.material.iter().filter(|&&m| m == 0).count(), 400);
    assert_eq!(p.material.iter().filter(|&&m| m == 1).count(), 200);
    assert!(p.x[400..].iter().all(|x| x[0] > 0.3));
    assert_eq!(built.grid.pad, 1);
    assert_eq!(built.grid.cells, [25, 25]);
}

#[test]
fn json_3d_fixture_builds_sphere_and_cylinder() {
    let scene = Scene::from_path(fixture("good/sphere_3d.json")).unwrap();
    assert_eq!(scene.dim(), 3);
    let err = scene.build::<2>().unwrap_err();
    assert_eq!(err.to_string(), "the scene is 3D but was built as 2D");
    let built = scene.build::<3>().unwrap();
    let p = &built.particles;
    let sphere = p.material.len() - p.x.iter().filter(|x| x[2] < 0.25).count();
    let s: f64 = 0.05;
    let expected = 4.0 / 3.0 * std::f64::consts::PI * 0.3f64.powi(3) / s.powi(3);
    assert!(
        (sphere as f64 - expected).abs() / expected < 0.03,
        "{sphere} sphere particles, expected ≈ {expected}"
    );
    // The cylinder: 4 layers of particles spaced 0.025 over a disk of radius 0.2.
    let cylinder = p.len() - sphere;
    let expected = 4.0 * std::f64::consts::PI * 0.2 * 0.2 / (0.025 * 0.025);
    assert!(
        (cylinder as f64 - expected).abs() / expected < 0.05,
        "{cylinder} cylinder particles, expected ≈ {expected}"
    );
    assert_eq!(p.v[0], nalgebra::vector![0.0, 0.0, -1.0]);
    assert_eq!(built.boundary.walls[2][0], Wall::new(WallKind::Slip));
    assert_eq!(built.boundary.walls[2][1], Wall::new(WallKind::Fixed));
    assert_eq!(built.output.dir, Path::new("out/sphere_3d"));
}

/// A `j2` material gets its yield stress and hardening (default 0); the plasticity fields
/// are rejected on an elastic model and checked for range.
#[test]
fn j2_fixture_builds_plastic_materials() {
    let built = Scene::from_path(fixture("good/j2_2d.toml"))
        .unwrap()
        .build::<2>()
        .unwrap();
    let lame = Lame::from_young_poisson(1.0e7, 0.3);
    let expected = [
        (1.0e5, 2.0e5), // hardening given
        (5.0e4, 0.0),   // hardening left out: perfectly plastic
    ];
    for (material, (yield_stress, hardening)) in built.materials.iter().zip(expected) {
        assert_eq!(
            material.model,
            Model::J2(J2 {
                lame,
                yield_stress,
                hardening
            })
        );
        assert_eq!(material.density, 1800.0);
    }
    assert!(matches!(built.materials[2].model, Model::Hencky(_)));
    let p = &built.particles;
    assert_eq!(p.len(), 280);
    assert_eq!(p.material.iter().filter(|&&m| m == 0).count(), 200);
    assert_eq!(p.material.iter().filter(|&&m| m == 2).count(), 80);

    let text = std::fs::read_to_string(fixture("good/j2_2d.toml")).unwrap();
    for (from, to, want) in [
        (
            "poisson_ratio = 0.25",
            "poisson_ratio = 0.25\nhardening = 1.0",
            r#"materials[2].hardening: only used by model "j2""#,
        ),
        (
            "poisson_ratio = 0.25",
            "poisson_ratio = 0.25\nyield_stress = 1.0",
            r#"materials[2].yield_stress: only used by model "j2""#,
        ),
        (
            "hardening = 2.0e5",
            "hardening = -1.0",
            "materials[0].hardening: must be zero or positive, got -1",
        ),
        (
            "yield_stress = 5.0e4",
            "yield_stress = 0.0",
            "materials[1].yield_stress: must be positive, got 0",
        ),
    ] {
        let err = Scene::from_toml_str(&text.replacen(from, to, 1)).unwrap_err();
        assert!(err.to_string().contains(want), "{err}");
    }
}

/// A `fluid` material gets its bulk modulus from the sound speed (`K = ρ₀ c²`) or as written,
/// `γ` (default 7) and the viscosity (default 0); the rules on which keys a fluid takes, and
/// that the solid models still need `E` and `ν`, name the field.
#[test]
fn fluid_fixture_builds_fluid_materials() {
    let built = Scene::from_path(fixture("good/dam_break_2d.toml"))
        .unwrap()
        .build::<2>()
        .unwrap();
    let expected = [
        (
            1000.0,
            Fluid {
                bulk_modulus: 1000.0 * 20.0 * 20.0,
                gamma: 7.0,
                viscosity: 1.0e-3,
            },
        ),
        (
            900.0,
            Fluid {
                bulk_modulus: 2.0e5,
                gamma: 1.0,
                viscosity: 0.0,
            },
        ),
    ];
    for (material, (density, fluid)) in built.materials.iter().zip(expected) {
        assert_eq!(material.model, Model::Fluid(fluid));
        assert_eq!(material.density, density);
    }
    assert!((built.materials[0].wave_speed() - 20.0).abs() < 1e-12);
    let p = &built.particles;
    assert_eq!(p.len(), 480);
    assert_eq!(p.material.iter().filter(|&&m| m == 0).count(), 400);

    let text = std::fs::read_to_string(fixture("good/dam_break_2d.toml")).unwrap();
    for (from, to, want) in [
        (
            "sound_speed = 20.0",
            "sound_speed = 20.0\nbulk_modulus = 1.0",
            r#"materials[0].bulk_modulus: give either sound_speed or bulk_modulus for model "fluid", not both"#,
        ),
        (
            "sound_speed = 20.0",
            "sound_speed = 0.0",
            "materials[0].sound_speed: must be positive, got 0",
        ),
        (
            "bulk_modulus = 2.0e5",
            "bulk_modulus = -2.0e5",
            "materials[1].bulk_modulus: must be positive, got -200000",
        ),
        (
            "gamma = 1.0",
            "gamma = 0.5",
            "materials[1].gamma: must be at least 1, got 0.5",
        ),
        (
            "viscosity = 1.0e-3",
            "viscosity = -1.0",
            "materials[0].viscosity: must be zero or positive, got -1",
        ),
        (
            "gamma = 1.0",
            "gamma = 1.0\npoisson_ratio = 0.3",
            r#"materials[1].poisson_ratio: not used by model "fluid""#,
        ),
        (
            "gamma = 1.0",
            "gamma = 1.0\nyield_stress = 1.0",
            r#"materials[1].yield_stress: only used by model "j2""#,
        ),
        (
            r#"model = "fluid"
density = 900.0"#,
            r#"model = "hencky"
density = 900.0
poisson_ratio = 0.3"#,
            r#"materials[1].youngs_modulus: required for model "hencky" (Young's modulus, Pa)"#,
        ),
        (
            r#"model = "fluid"
density = 900.0"#,
            r#"model = "neo_hookean"
density = 900.0
youngs_modulus = 1.0e6"#,
            r#"materials[1].poisson_ratio: required for model "neo_hookean""#,
        ),
        (
            r#"model = "fluid"
density = 900.0"#,
            r#"model = "hencky"
density = 900.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3"#,
            r#"materials[1].bulk_modulus: only used by model "fluid""#,
        ),
    ] {
        let changed = text.replacen(from, to, 1);
        assert_ne!(changed, text, "{from:?} not in the fixture");
        let err = Scene::from_toml_str(&changed).unwrap_err();
        assert!(err.to_string().contains(want), "{err}");
    }
}

/// A `drucker_prager` material gets its angles converted from degrees to radians, the
/// cohesion and cutoff as written, and the defaults `ψ = 0`, `c = 0`, cutoff at the apex; the
/// range checks and the rules on which keys it takes name the field.
#[test]
fn drucker_prager_fixture_builds_frictional_materials() {
    let built = Scene::from_path(fixture("good/drucker_prager_2d.toml"))
        .unwrap()
        .build::<2>()
        .unwrap();
    let expected = [
        (
            2000.0,
            DruckerPrager {
                lame: Lame::from_young_poisson(5.0e6, 0.3),
                friction_angle: 35f64.to_radians(),
                dilation_angle: 5f64.to_radians(),
                cohesion: 2.0e3,
                tension_cutoff: Some(1.0e3),
                cone: Cone::PlaneStrain,
                elasticity: Elasticity::Jaumann,
            },
        ),
        (
            1600.0,
            DruckerPrager {
                lame: Lame::from_young_poisson(2.0e6, 0.25),
                friction_angle: 30f64.to_radians(),
                dilation_angle: 0.0,
                cohesion: 0.0,
                tension_cutoff: None,
                cone: Cone::PlaneStrain,
                elasticity: Elasticity::Jaumann,
            },
        ),
    ];
    for (material, (density, dp)) in built.materials.iter().zip(expected) {
        assert_eq!(material.model, Model::DruckerPrager(dp));
        assert_eq!(material.density, density);
    }
    // The time-step bound uses the elastic P-wave speed √((λ + 2μ)/ρ₀).
    let m: f64 = Lame::from_young_poisson(5.0e6, 0.3).p_wave_modulus();
    assert!((built.materials[0].wave_speed() - (m / 2000.0).sqrt()).abs() < 1e-9);
    let p = &built.particles;
    assert_eq!(p.len(), 600);
    assert_eq!(p.material.iter().filter(|&&m| m == 0).count(), 400);

    let text = std::fs::read_to_string(fixture("good/drucker_prager_2d.toml")).unwrap();
    for (from, to, want) in [
        (
            "friction_angle = 35.0",
            "friction_angle = 0.0",
            "materials[0].friction_angle: must be in (0, 90) degrees, got 0",
        ),
        (
            "dilation_angle = 5.0",
            "dilation_angle = -1.0",
            "materials[0].dilation_angle: must be in [0, friction_angle] = [0, 35] degrees, got -1",
        ),
        (
            "tension_cutoff = 1.0e3",
            "tension_cutoff = -1.0",
            "materials[0].tension_cutoff: must be in [0, c cot φ] = [0, 2856.3] Pa",
        ),
        (
            "friction_angle = 30.0",
            "friction_angle = 30.0\ntension_cutoff = 1.0",
            "materials[1].tension_cutoff: must be in [0, c cot φ] = [0, 0] Pa",
        ),
        (
            "friction_angle = 30.0",
            "friction_angle = 30.0\nyield_stress = 1.0",
            r#"materials[1].yield_stress: only used by model "j2""#,
        ),
        (
            "friction_angle = 30.0",
            "friction_angle = 30.0\nviscosity = 1.0",
            r#"materials[1].viscosity: only used by model "fluid""#,
        ),
        (
            "poisson_ratio = 0.25\n",
            "",
            r#"materials[1].poisson_ratio: required for model "drucker_prager" (Poisson's ratio)"#,
        ),
        (
            r#"model = "drucker_prager"
density = 1600.0"#,
            r#"model = "fluid"
sound_speed = 10.0
density = 1600.0"#,
            r#"materials[1].friction_angle: only used by models "drucker_prager" and "mohr_coulomb""#,
        ),
        (
            r#"model = "drucker_prager"
density = 1600.0"#,
            r#"model = "j2"
yield_stress = 1.0e4
density = 1600.0"#,
            r#"materials[1].friction_angle: only used by models "drucker_prager" and "mohr_coulomb""#,
        ),
    ] {
        let changed = text.replacen(from, to, 1);
        assert_ne!(changed, text, "{from:?} not in the fixture");
        let err = Scene::from_toml_str(&changed).unwrap_err();
        assert!(err.to_string().contains(want), "{err}");
    }
    // The apex itself is an accepted cutoff (c cot φ written out to round-off).
    let apex = 2.0e3 / 35f64.to_radians().tan();
    let at_apex = text.replacen(
        "tension_cutoff = 1.0e3",
        &format!("tension_cutoff = {apex}"),
        1,
    );
    Scene::from_toml_str(&at_apex).unwrap();
    // Mohr–Coulomb takes the same cutoff, on every principal stress, within the same bounds.
    let mohr = text.replacen(
        r#"model = "drucker_prager""#,
        r#"model = "mohr_coulomb""#,
        1,
    );
    let built = Scene::from_toml_str(&mohr).unwrap().build::<2>().unwrap();
    match &built.materials[0].model {
        Model::MohrCoulomb(m) => assert_eq!(m.tension_cutoff, Some(1.0e3)),
        other => panic!("expected Mohr–Coulomb, got {other:?}"),
    }
    let beyond = mohr.replacen("tension_cutoff = 1.0e3", "tension_cutoff = 3.0e3", 1);
    let err = Scene::from_toml_str(&beyond).unwrap_err().to_string();
    assert!(
        err.contains("materials[0].tension_cutoff: must be in [0, c cot φ] = [0, 2856.3] Pa"),
        "{err}"
    );
}

/// The implicit 2D fixture: constraint boxes as written, each point load on the particles
/// nearest its point (ties to the lower id), the settings written and the defaults.
#[test]
fn implicit_2d_fixture_builds_constraints_and_point_loads() {
    let built = Scene::from_path(fixture("good/implicit_2d.toml"))
        .unwrap()
        .build::<2>()
        .unwrap();
    let p = &built.particles;
    assert_eq!(p.len(), 32);
    // Ids run x fastest: id = column + 8 row.
    assert_eq!(p.x[15], nalgebra::vector![2.375, 1.375]);
    assert_eq!(p.x[23], nalgebra::vector![2.375, 1.625]);
    assert_eq!(p.x[11], nalgebra::vector![1.375, 1.375]);
    assert_eq!(p.x[20], nalgebra::vector![1.625, 1.625]);
    assert_eq!(
        built.constraints,
        vec![
            NodeConstraint {
                lo: [0.5, -1.0e9],
                hi: [0.5, 1.0e9],
                displacement: [Some(0.0), None],
                force: [None, None],
            },
            NodeConstraint {
                lo: [0.5, 1.5],
                hi: [0.5, 1.5],
                displacement: [None, Some(0.0)],
                force: [None, None],
            },
            NodeConstraint {
                lo: [2.5, 1.0],
                hi: [2.5, 2.0],
                displacement: [Some(-0.1), Some(-0.05)],
                force: [None, None],
            },
        ]
    );
    let load = |particle, force| PointLoad { particle, force };
    assert_eq!(
        built.point_loads,
        vec![
            load(15, [0.0, -50.0]),
            load(23, [0.0, -50.0]),
            load(0, [10.0, 0.0]),
            load(11, [1.0, 2.0]),
            load(12, [1.0, 2.0]),
            load(19, [1.0, 2.0]),
        ]
    );
    assert_eq!(built.solver.kind, SolverKind::Implicit);
    assert_eq!(
        built.plan,
        SolverPlan::Implicit(ImplicitPlan {
            newmark_dt: None,
            consolidation: None,
            load_steps: 20,
            newton: NewtonSettings {
                residual_tol: 1e-9,
                increment_tol: 1e-10,
                max_iterations: 40,
                line_search: false,
                max_cuts: 6,
                tangent: TangentMethod::Colour,
                linear: LinearSolverKind::Cg {
                    preconditioner: Preconditioner::Jacobi,
                    rel_tol: 1e-10,
                    max_iter: 500,
                },
            },
            balance_initial_stress: false,
        })
    );
    assert_eq!(built.gravity, nalgebra::vector![0.0, -9.81]);
    assert_eq!(built.boundary.walls[1][0], Wall::new(WallKind::Fixed));
    assert_eq!(built.frame_steps(), vec![0, 5, 10, 15, 20]);
    assert_eq!(built.frame_times(), vec![0.0, 0.25, 0.5, 0.75, 1.0]);
}

/// The minimal 3D implicit scene (JSON): defaults for Newton and the linear solver, every
/// load step a frame when `frames` (default 20) exceeds `load_steps`.
#[test]
fn implicit_3d_fixture_builds_with_the_defaults() {
    let scene = Scene::from_path(fixture("good/implicit_3d.json")).unwrap();
    let built = scene.build::<3>().unwrap();
    assert_eq!(built.particles.len(), 8);
    assert_eq!(
        built.constraints,
        vec![NodeConstraint {
            lo: [-1e9, -1e9, 0.25],
            hi: [1e9, 1e9, 0.25],
            displacement: [None, None, Some(0.0)],
            force: [None, None, None],
        }]
    );
    // The four top particles (z = 0.625) are equally near (0.5, 0.5, 1).
    let loads: Vec<usize> = built.point_loads.iter().map(|l| l.particle).collect();
    assert_eq!(loads, vec![4, 5, 6, 7]);
    assert!(
        built
            .point_loads
            .iter()
            .all(|l| l.force == [0.0, 0.0, -2.0])
    );
    assert!(loads.iter().all(|&i| built.particles.x[i][2] == 0.625));
    assert_eq!(
        built.plan,
        SolverPlan::Implicit(ImplicitPlan {
            newmark_dt: None,
            consolidation: None,
            load_steps: 3,
            newton: NewtonSpec::default().settings(LinearSolverKind::Lu),
            balance_initial_stress: false,
        })
    );
    assert_eq!(NewtonSpec::default().residual_tol, 1e-8);
    assert_eq!(NewtonSpec::default().max_iterations, 25);
    assert_eq!(built.frame_steps(), vec![0, 1, 2, 3]);
    assert_eq!(built.frame_times().last(), Some(&1.0));
}

/// Rules of the implicit solver and its loading, each checked by editing the good fixture.
#[test]
fn implicit_rules_name_the_field() {
    let text = std::fs::read_to_string(fixture("good/implicit_2d.toml")).unwrap();
    for (from, to, want) in [
        (
            "load_steps = 20",
            "load_steps = 20\nend_time = 1.0",
            "solver.end_time: only used by the explicit solver (an implicit run is \
             quasi-static: it applies the loads over solver.load_steps steps, with no time)",
        ),
        (
            "load_steps = 20",
            "load_steps = 20\nscheme = \"usl\"",
            "solver.scheme: only used by the explicit solver",
        ),
        (
            "load_steps = 20",
            "load_steps = 0",
            "solver.load_steps: must be at least 1, got 0",
        ),
        (
            "load_steps = 20",
            "load_steps = -2",
            "solver.load_steps: invalid value: integer `-2`",
        ),
        (
            "residual_tol = 1e-9",
            "residual_tol = 1.0",
            "solver.newton.residual_tol: must be in (0, 1), got 1",
        ),
        (
            "residual_tol = 1e-9",
            "increment_tol = 0.0",
            "solver.newton.increment_tol: must be positive, got 0",
        ),
        (
            "max_iterations = 40",
            "max_iterations = 0",
            "solver.newton.max_iterations: must be at least 1, got 0",
        ),
        (
            "residual_tol = 1e-9",
            "resiudal_tol = 1e-9",
            "solver.newton.resiudal_tol: unknown field `resiudal_tol`",
        ),
        (
            "type = \"cg\"",
            "type = \"lu\"",
            r#"solver.linear.preconditioner: only used by the iterative solvers "cg", "bicgstab" and "gmres""#,
        ),
        (
            "type = \"cg\"",
            "type = \"minres\"",
            "solver.linear.type: unknown variant `minres`",
        ),
        (
            "max_iterations = 500",
            "max_iterations = 500\nrel_tol = 2.0",
            "solver.linear.rel_tol: must be in (0, 1), got 2",
        ),
        (
            "count = 3",
            "count = 33",
            "point_loads[2].count: asks for 33 particles but the scene has 32",
        ),
        (
            "force = [3.0, 6.0]",
            "force = [3.0]",
            "point_loads[2].force: expected 2 components (the grid is 2D), got 1",
        ),
        (
            "force = [3.0, 6.0]",
            "force = [3.0, nan]",
            "point_loads[2].force[1]: must be a finite number, got NaN",
        ),
        (
            "displacement = [-0.1, -0.05]",
            "displacement = [-0.1, inf]",
            "constraints[2].displacement[1]: must be a finite number, got inf",
        ),
        (
            "displacement = [-0.1, -0.05]",
            "displacement = [-0.1, \"fixed\"]",
            r#"constraints[2].displacement[1]: invalid value: string "fixed", expected a number (a displacement in m, a force in N) or "free""#,
        ),
        (
            "hi = [2.5, 2.0]\ndisplacement",
            "hi = [2.5, 0.5]\ndisplacement",
            "constraints[2].hi[1]: must be at least lo[1] = 1, got 0.5",
        ),
        (
            "lo = [2.5, 1.0]",
            "lo = [2.5, 1.0, 0.0]",
            "constraints[2].lo: expected 2 coordinates (the grid is 2D), got 3",
        ),
        (
            "lo = [2.5, 1.0]\nhi = [2.5, 2.0]",
            "lo = [-1.0, 1.0]\nhi = [-0.5, 2.0]",
            "constraints[2]: the box contains no grid node",
        ),
        (
            "x_max = \"slip\"",
            "x_max = { kind = \"slip\", separable = true }",
            "boundaries.x_max: the implicit solver has no separable walls",
        ),
        (
            "particles_per_cell = 2",
            "particles_per_cell = 2\nvelocity = [1.0, 0.0]",
            "bodies[0].velocity: not used by a quasi-static implicit run",
        ),
        (
            "type = \"implicit\"\nload_steps = 20",
            "type = \"explicit\"\ntime_step = { type = \"fixed\", dt = 1e-4 }\nend_time = 1.0",
            "point_loads: only applied by the implicit solver",
        ),
        (
            "type = \"implicit\"\nload_steps = 20",
            "type = \"explicit\"\ntime_step = { type = \"fixed\", dt = 1e-4 }",
            "solver.end_time: required for the explicit solver",
        ),
        (
            "type = \"implicit\"",
            "type = \"explicit\"",
            r#"solver.newton: only used by the implicit solver; remove it or set solver.type = "implicit""#,
        ),
        (
            "type = \"implicit\"",
            "type = \"static\"",
            "solver.type: unknown variant `static`, expected `explicit` or `implicit`",
        ),
    ] {
        assert!(text.contains(from), "{from}");
        match Scene::from_toml_str(&text.replacen(from, to, 1)) {
            Ok(_) => panic!("{to}: loaded without error"),
            Err(err) => assert!(err.to_string().contains(want), "{to}:\n{err}"),
        }
    }
    // A constraint on the nodes of a wall is fine.
    let on_wall = text.replacen(
        "lo = [2.5, 1.0]\nhi = [2.5, 2.0]",
        "lo = [4.0, 0.0]\nhi = [4.0, 4.0]",
        1,
    );
    Scene::from_toml_str(&on_wall).unwrap_or_else(|e| panic!("{e}"));
    // The short form of the linear solver gets the iterative defaults.
    let short = text
        .replacen(
            "[solver.linear]\ntype = \"cg\"\npreconditioner = \"jacobi\"\nmax_iterations = 500\n",
            "",
            1,
        )
        .replacen(
            "load_steps = 20\n",
            "load_steps = 20\nlinear = \"bicgstab\"\n",
            1,
        );
    let built = Scene::from_toml_str(&short)
        .unwrap_or_else(|e| panic!("{e}\n{short}"))
        .build::<2>()
        .unwrap();
    let SolverPlan::Implicit(plan) = built.plan else {
        panic!()
    };
    assert_eq!(
        plan.newton.linear,
        LinearSolverKind::Bicgstab {
            preconditioner: Preconditioner::Ilu0,
            rel_tol: 1e-10,
            max_iter: 1000,
        }
    );
}

/// `[fos]`: the ranges of its keys and what `loam fos` needs (a quasi-static implicit scene
/// loaded by gravity or point loads, with a strength to reduce), each error naming the field;
/// the keys left out take the search's defaults.
#[test]
fn fos_rules_name_the_field() {
    let text = std::fs::read_to_string(fixture("good/implicit_2d.toml")).unwrap();
    let soil = text.replacen(
        "model = \"hencky\"",
        "model = \"mohr_coulomb\"\nfriction_angle = 30.0\ncohesion = 5.0e3",
        1,
    );
    let clay = text
        .replacen(
            "model = \"hencky\"\ndensity = 2000.0\nyoungs_modulus = 1.0e7\n",
            "model = \"modified_cam_clay\"\ndensity = 2000.0\nlambda = 0.2\nkappa = 0.04\n\
             critical_state_slope = 1.0\nvoid_ratio = 1.0\nocr = 1.5\n",
            1,
        )
        .replacen(
            "particles_per_cell = 2",
            "particles_per_cell = 2\ninitial_stress = { type = \"geostatic\", k0 = 0.6 }",
            1,
        );
    assert!(clay.contains("modified_cam_clay") && clay.contains("geostatic"));
    let with = |scene: &str, fos: &str| format!("{scene}\n[fos]\n{fos}\n");
    let scene = Scene::from_toml_str(&with(&soil, "tolerance = 0.02\nmax_trials = 12"))
        .unwrap_or_else(|e| panic!("{e}"));
    let s = scene.fos_settings();
    assert_eq!((s.tolerance, s.max_trials, s.start), (0.02, 12, 1.0));
    assert_eq!((s.growth_limit, s.displacement_limit), (Some(10.0), None));
    let plain = Scene::from_toml_str(&soil).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(plain.fos_settings(), SearchSettings::default());
    plain.check_fos().unwrap_or_else(|e| panic!("{e}"));
    for (bad, want) in [
        (
            with(&soil, "tolerance = 0.0"),
            "fos.tolerance: must be positive, got 0",
        ),
        (
            with(&soil, "start = -1.0"),
            "fos.start: must be positive, got -1",
        ),
        (
            with(&soil, "max_trials = 0"),
            "fos.max_trials: must be at least 1, got 0",
        ),
        (
            with(&soil, "displacement_limit = nan"),
            "fos.displacement_limit: must be a finite number, got NaN",
        ),
        (
            with(&soil, "growth_limit = 1.0"),
            "fos.growth_limit: must be above 1",
        ),
        (
            with(&soil, "tolerence = 0.1"),
            "fos.tolerence: unknown field `tolerence`",
        ),
        (
            with(&text, ""),
            "materials: no material has a strength to reduce",
        ),
        // Modified Cam-Clay's strength comes from its state: it is not reduced.
        (
            with(&clay, ""),
            "materials: no material has a strength to reduce: expected a \"mohr_coulomb\", \
             \"drucker_prager\" or \"j2\" material (the elastic models, \"fluid\" and \
             \"modified_cam_clay\"",
        ),
        (
            with(
                &soil.replacen("load_steps = 20", "load_steps = 20\nnewmark_dt = 0.01", 1),
                "",
            ),
            "solver.newmark_dt: the factor of safety is searched over quasi-static runs",
        ),
    ] {
        match Scene::from_toml_str(&bad) {
            Ok(_) => panic!("{want}: loaded without error"),
            Err(err) => assert!(err.to_string().contains(want), "{want}:\n{err}"),
        }
    }
    // Without a section the same needs are checked by `Scene::check_fos`; the clay scene is
    // sound but for them.
    let clay = Scene::from_toml_str(&clay).unwrap_or_else(|e| panic!("{e}"));
    let err = clay.check_fos().unwrap_err().to_string();
    assert!(
        err.contains("materials: no material has a strength to reduce"),
        "{err}"
    );
    // An initial stress puts gravity in full into the first load step.
    assert!(
        err.contains("bodies[0].initial_stress: the factor of safety is searched over gravity"),
        "{err}"
    );
    let mut unloaded = plain.clone();
    unloaded.point_loads.clear();
    unloaded.loads.gravity = Some(vec![0.0, 0.0]);
    let err = unloaded.check_fos().unwrap_err().to_string();
    assert!(
        err.contains("loads.gravity: nothing loads the scene"),
        "{err}"
    );
    let mut explicit = plain;
    explicit.solver.kind = SolverKind::Explicit;
    let err = explicit.check_fos().unwrap_err().to_string();
    assert!(err.contains("solver.type: the factor of safety"), "{err}");
}

#[test]
fn scenes_round_trip_through_toml_and_json() {
    for name in [
        "box_2d.toml",
        "disk_2d.toml",
        "overlap_2d.toml",
        "sphere_3d.json",
        "j2_2d.toml",
        "implicit_2d.toml",
        "implicit_3d.json",
    ] {
        let mut scene = Scene::from_path(fixture(&format!("good/{name}"))).unwrap();
        scene.source = None;
        let toml_text = toml::to_string(&scene).unwrap();
        assert_eq!(
            Scene::from_toml_str(&toml_text).unwrap(),
            scene,
            "{toml_text}"
        );
        let json_text = serde_json::to_string_pretty(&scene).unwrap();
        assert_eq!(
            Scene::from_json_str(&json_text).unwrap(),
            scene,
            "{json_text}"
        );
    }
}

#[test]
fn example_scenes_load_and_build() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let mut count = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let scene = Scene::from_path(&path).unwrap_or_else(|e| panic!("{e}"));
            let n = build_any(&scene).unwrap_or_else(|e| panic!("{e}"));
            assert!(n > 0, "{}", path.display());
            count += 1;
        }
    }
    assert!(count >= 4);
}

/// The implicit examples build the benchmarks they describe.
#[test]
fn implicit_examples_build_the_benchmarks() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let built = Scene::from_path(dir.join("cantilever.toml"))
        .unwrap()
        .build::<2>()
        .unwrap();
    assert_eq!(built.particles.len(), 5760);
    assert_eq!(built.grid.cells, [60, 60]);
    assert_eq!(built.constraints.len(), 2);
    // The two particles either side of the tip's mid-depth point, 50 kN each.
    assert_eq!(built.point_loads.len(), 2);
    for l in &built.point_loads {
        let x = built.particles.x[l.particle];
        assert!((x[0] - (10.25 - 0.25 / 12.0)).abs() < 1e-12, "{x}");
        assert!(((x[1] - 9.5).abs() - 0.25 / 12.0).abs() < 1e-12, "{x}");
        assert_eq!(l.force, [0.0, -50.0e3]);
    }
    let SolverPlan::Implicit(plan) = built.plan else {
        panic!("{:?}", built.plan)
    };
    assert_eq!(plan.load_steps, 50);
    assert_eq!(plan.newton.linear, LinearSolverKind::Lu);
    assert_eq!(plan.newton.tangent, TangentMethod::Local);
    assert_eq!(
        built.frame_steps(),
        (0..=10).map(|k| 5 * k).collect::<Vec<_>>()
    );
    assert_eq!(built.boundary, loam_core::Boundary::all(Wall::default()));

    let built = Scene::from_path(dir.join("column_compaction.toml"))
        .unwrap()
        .build::<2>()
        .unwrap();
    assert_eq!(built.particles.len(), 1024);
    assert_eq!(built.grid.cells, [1, 66]);
    assert!((built.particles.total_mass() - 80.0 * 0.78125 * 50.0).abs() < 1e-9);
    assert_eq!(built.gravity, nalgebra::vector![0.0, -10.0]);
    assert_eq!(built.boundary.walls[0], [Wall::new(WallKind::Slip); 2]);
    assert_eq!(built.boundary.walls[1][0], Wall::new(WallKind::Fixed));
    assert_eq!(built.boundary.walls[1][1], Wall::default());
    assert!(built.constraints.is_empty() && built.point_loads.is_empty());
    let SolverPlan::Implicit(plan) = built.plan else {
        panic!("{:?}", built.plan)
    };
    assert_eq!(plan.load_steps, 40);
    assert_eq!(built.frame_steps().len(), 11);
}

/// The fenced blocks of `lang` in `text` that hold a whole scene (they set a cell size).
fn scene_blocks<'a>(text: &'a str, lang: &str) -> Vec<&'a str> {
    let fence = format!("```{lang}\n");
    text.split(fence.as_str())
        .skip(1)
        .filter_map(|rest| rest.split("```").next())
        .filter(|block| block.contains("cell_size"))
        .collect()
}

#[test]
fn documented_scenes_are_valid() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let guide = std::fs::read_to_string(root.join("../../docs/scene-format.md")).unwrap();
    let toml_blocks = scene_blocks(&guide, "toml");
    let json_blocks = scene_blocks(&guide, "json");
    // The explicit example in TOML and JSON, and the implicit one.
    assert_eq!((toml_blocks.len(), json_blocks.len()), (2, 1));
    let from_toml = Scene::from_toml_str(toml_blocks[0]).unwrap_or_else(|e| panic!("{e}"));
    let from_json = Scene::from_json_str(json_blocks[0]).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(from_toml, from_json);
    let implicit = Scene::from_toml_str(toml_blocks[1]).unwrap_or_else(|e| panic!("{e}"));
    let built = implicit.build::<2>().unwrap();
    assert_eq!(built.solver.kind, SolverKind::Implicit);
    assert_eq!((built.constraints.len(), built.point_loads.len()), (1, 1));
    assert_eq!(built.frame_steps(), vec![0, 2, 4, 6, 8, 10]);

    // The example in the crate documentation.
    let lib = std::fs::read_to_string(root.join("src/lib.rs")).unwrap();
    let lib_doc: String = lib
        .lines()
        .filter_map(|l| l.strip_prefix("//!"))
        .map(|l| format!("{}\n", l.strip_prefix(' ').unwrap_or(l)))
        .collect();
    let blocks = scene_blocks(&lib_doc, "toml");
    assert_eq!(blocks.len(), 1);
    Scene::from_toml_str(blocks[0]).unwrap_or_else(|e| panic!("{e}"));
}

/// Every material constant of the declaration has a row in the scene format's material
/// table, and every one that is a gradient parameter is named in the inversion format.
#[test]
fn every_declared_constant_is_documented() {
    use loam_core::constitutive::constants::{CONSTANTS, DENSITY};
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = std::fs::read_to_string(root.join("../../docs/scene-format.md")).unwrap();
    let inversion = std::fs::read_to_string(root.join("../../docs/inversion-format.md")).unwrap();
    for c in std::iter::once(&DENSITY).chain(CONSTANTS) {
        let row = format!("| `{}` ", c.key);
        assert!(
            scene.lines().any(|l| l.starts_with(&row)),
            "docs/scene-format.md has no row for `{}`",
            c.key
        );
        if let Some(g) = c.gradient {
            assert!(
                inversion.contains(&format!("`{}`", g.name)),
                "docs/inversion-format.md does not name the parameter `{}`",
                g.name
            );
        }
    }
}

/// Builds a scene in its own dimension, as a solver front end would.
fn build_any(scene: &Scene) -> Result<usize, SceneError> {
    match scene.dim() {
        2 => scene.build::<2>().map(|b| b.particles.len()),
        _ => scene.build::<3>().map(|b| b.particles.len()),
    }
}

#[test]
fn mangled_scenes_give_errors_not_panics() {
    const ODD_VALUES: &[&str] = &[
        "0",
        "-1",
        "1e308",
        "-1e308",
        "nan",
        "-inf",
        "[]",
        "[0.0]",
        "[1.0, 2.0, 3.0]",
        "[1e308, -1e308]",
        "\"x\"",
        "{}",
        "{ type = \"box\" }",
        "true",
    ];
    for name in [
        "box_2d.toml",
        "disk_2d.toml",
        "overlap_2d.toml",
        "j2_2d.toml",
        "implicit_2d.toml",
        "contact_2d.toml",
    ] {
        let text = std::fs::read_to_string(fixture(&format!("good/{name}"))).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            let mut variants = vec![String::new()]; // the line deleted
            if let Some((key, _)) = line.split_once(" = ") {
                variants.extend(ODD_VALUES.iter().map(|v| format!("{key} = {v}")));
            }
            for replacement in variants {
                let mut mangled = lines.clone();
                mangled[i] = &replacement;
                // Loading either fails with a message or gives a scene that builds.
                match Scene::from_toml_str(&mangled.join("\n")) {
                    Ok(scene) => {
                        build_any(&scene).unwrap_or_else(|e| panic!("{name}:{i}: {e}"));
                    }
                    Err(e) => assert!(!e.to_string().is_empty()),
                }
            }
        }
    }
}

/// Friction segments and obstacles build into the core contact: segment ranges along the face
/// (the whole face when `from`/`to` are left out), obstacle shapes, velocities and friction;
/// particles inside an obstacle at t = 0 are not generated.
#[test]
fn contact_fixture_builds_segments_and_obstacles_and_clips_particles() {
    use loam_core::{FrictionSegment, Obstacle, ObstacleShape};
    let built = Scene::from_path(fixture("good/contact_2d.toml"))
        .unwrap()
        .build::<2>()
        .unwrap();
    let c = &built.contact;
    assert_eq!(c.support, 1.5);
    assert_eq!(
        c.segments,
        vec![
            FrictionSegment {
                axis: 1,
                side: 0,
                from: [0.0, 0.0],
                to: [1.0, 0.0],
                mu: 0.1
            },
            FrictionSegment {
                axis: 1,
                side: 0,
                from: [1.0, 0.0],
                to: [2.0, 0.0],
                mu: 0.5
            },
            FrictionSegment {
                axis: 0,
                side: 1,
                from: [2.0, 0.0],
                to: [2.0, 0.5],
                mu: 0.2
            },
        ]
    );
    assert_eq!(
        c.obstacles,
        vec![
            Obstacle {
                shape: ObstacleShape::Box {
                    lo: [0.4, 0.1],
                    hi: [0.6, 0.3]
                },
                velocity: [0.0, 0.0].into(),
                mu: 0.3
            },
            Obstacle {
                shape: ObstacleShape::disk([1.5, 0.3], 0.1),
                velocity: [-1.0, 0.0].into(),
                mu: 0.0
            },
        ]
    );
    // 20 × 10 cells × 4 particles, less the 5 × 5 cells under the box.
    assert_eq!(built.particles.len(), 800 - 100);
    assert!(
        built
            .particles
            .x
            .iter()
            .all(|x| c.penetrated(&[x[0], x[1]], 0.0).is_none())
    );
    assert_eq!(
        built.boundary.walls[1][0],
        Wall {
            kind: WallKind::Slip,
            separable: true
        }
    );
}

#[test]
fn cylinder_fixture_builds_3d_obstacles() {
    use loam_core::ObstacleShape;
    let built = Scene::from_path(fixture("good/cylinders_3d.json"))
        .unwrap()
        .build::<3>()
        .unwrap();
    let c = &built.contact;
    assert_eq!(c.segments.len(), 1);
    assert_eq!(c.segments[0].from, [0.5, 0.0, 0.0]);
    assert_eq!(c.segments[0].to, [1.0, 0.0, 0.4]);
    assert_eq!(
        c.obstacles[0].shape,
        ObstacleShape::cylinder([0.6, 0.2, 0.1], 0.05, 1, 0.4)
    );
    assert_eq!(
        c.obstacles[1].velocity,
        loam_core::tensor::Vector::<f64, 3>::new(0.0, 0.0, 0.1)
    );
    // Without obstacles in the way the column holds 6 × 4 × 8 cells × 8 particles.
    assert_eq!(built.particles.len(), 1536);
}
