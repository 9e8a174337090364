//! Scene files: malformed fixtures give errors naming the offending field, good ones build
//! with the expected particles, and the example scenes load.

use loam_core::constitutive::{J2, Lame, Model};
use loam_core::{Scheme, Shape, TimeStep, Transfer, Wall, WallKind};
use loam_scene::{Scene, SceneError};
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
        &["solver.transfer: unknown variant `mls`", "`apic`"],
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
    assert_eq!(built.solver.scheme, Scheme::Musl);
    assert_eq!(built.solver.transfer, Transfer::Apic);
    assert_eq!(built.solver.time_step, TimeStep::Fixed { dt: 1e-4 });
    assert_eq!(built.output.dir, Path::new("out/box_2d"));
    assert_eq!(built.output.frames, 20);
    assert_eq!(built.output.fields, loam_scene::output::Field::ALL);
    assert_eq!(built.frame_times().len(), 21);
    assert_eq!(built.frame_times()[20], 0.5);
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
    assert_eq!(built.solver.scheme, Scheme::Usl);
    assert_eq!(built.solver.transfer, Transfer::Flip { alpha: 0.95 });
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

#[test]
fn scenes_round_trip_through_toml_and_json() {
    for name in [
        "box_2d.toml",
        "disk_2d.toml",
        "overlap_2d.toml",
        "sphere_3d.json",
        "j2_2d.toml",
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
    assert!(count >= 2);
}

/// The fenced blocks of `lang` in `text` that hold a whole scene (they set an end time).
fn scene_blocks<'a>(text: &'a str, lang: &str) -> Vec<&'a str> {
    let fence = format!("```{lang}\n");
    text.split(fence.as_str())
        .skip(1)
        .filter_map(|rest| rest.split("```").next())
        .filter(|block| block.contains("end_time"))
        .collect()
}

#[test]
fn documented_scenes_are_valid() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let guide = std::fs::read_to_string(root.join("../../docs/scene-format.md")).unwrap();
    let toml_blocks = scene_blocks(&guide, "toml");
    let json_blocks = scene_blocks(&guide, "json");
    assert_eq!((toml_blocks.len(), json_blocks.len()), (1, 1));
    let from_toml = Scene::from_toml_str(toml_blocks[0]).unwrap_or_else(|e| panic!("{e}"));
    let from_json = Scene::from_json_str(json_blocks[0]).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(from_toml, from_json);

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
