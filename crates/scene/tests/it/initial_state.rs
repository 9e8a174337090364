//! Initial states set in scene files: rigid rotations (with the APIC affine matrix),
//! per-particle velocities from CSV files, and geostatic and hydrostatic stresses that the
//! materials carry consistently.

use loam_core::constitutive::{Kinematics, Model};
use loam_core::tensor::{det, to3};
use loam_core::{Material, MaterialState, Particles};
use loam_scene::{Built, Scene};
use nalgebra::Matrix3;
use std::path::Path;

/// A 2D scene around one body (`body` holds the keys after `material`), with the given
/// transfer, material table and gravity.
fn scene_2d(materials: &str, body: &str, transfer: &str, gravity: &str) -> String {
    format!(
        r#"
[grid]
lo = [0.0, 0.0]
hi = [1.0, 1.0]
cell_size = 0.05

{materials}

[[bodies]]
{body}

[boundaries]
x_min = "slip"
x_max = "slip"
y_min = "fixed"

[loads]
gravity = {gravity}

[solver]
transfer = "{transfer}"
time_step = {{ type = "adaptive", cfl = 0.4, max_dt = 1e-3 }}
end_time = 1.0
"#
    )
}

const RUBBER: &str = r#"
[[materials]]
name = "rubber"
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
"#;

fn build_2d(text: &str) -> Built<2> {
    Scene::from_toml_str(text)
        .unwrap_or_else(|e| panic!("{e}"))
        .build::<2>()
        .unwrap_or_else(|e| panic!("{e}"))
}

fn build_error(text: &str) -> String {
    match Scene::from_toml_str(text) {
        Err(e) => e.to_string(),
        Ok(scene) => scene.build::<2>().expect_err("an error").to_string(),
    }
}

/// `Σ m (x × v)` about the origin (2D).
fn particle_angular_momentum(p: &Particles<f64, 2>) -> f64 {
    (0..p.len())
        .map(|i| p.mass[i] * (p.x[i][0] * p.v[i][1] - p.x[i][1] * p.v[i][0]))
        .sum()
}

#[test]
fn a_rotating_disk_starts_with_angular_momentum_omega_sum_m_r2_and_the_matching_c() {
    let omega = 3.0;
    let centre = [0.5, 0.5];
    for (transfer, affine) in [("apic", true), ("mls", true), ("pic", false)] {
        let text = scene_2d(
            RUBBER,
            &format!(
                r#"material = "rubber"
shape = {{ type = "disk", centre = [0.5, 0.5], radius = 0.3 }}
rotation = {{ angular_velocity = {omega}, centre = [0.5, 0.5] }}"#
            ),
            transfer,
            "[0.0, 0.0]",
        );
        let p = build_2d(&text).particles;
        // L = Σ m (x × v) and the analytic ω Σ m |x − x₀|² (the disk's lattice is symmetric
        // about its centre, so Σ m (x − x₀) = 0 and the origin does not matter): equal to
        // round-off (a few ulps per term, 1e-13 relative over the sum).
        let expected: f64 = (0..p.len())
            .map(|i| {
                let r = [p.x[i][0] - centre[0], p.x[i][1] - centre[1]];
                p.mass[i] * omega * (r[0] * r[0] + r[1] * r[1])
            })
            .sum();
        let l = particle_angular_momentum(&p);
        assert!(
            (l - expected).abs() < 1e-13 * expected,
            "{transfer}: {l} vs {expected}"
        );
        // The continuum value ½ M R² ω, up to the lattice's sampling of the disk (the
        // particle masses sum to the lattice area, within a few % of π R² at h = 0.05).
        let m: f64 = p.mass.iter().sum();
        let r2_mean = expected / (omega * m);
        assert!(
            (r2_mean - 0.5 * 0.3 * 0.3).abs() < 0.03 * 0.045,
            "{r2_mean}"
        );
        for c in &p.c {
            let want = if affine {
                nalgebra::Matrix2::new(0.0, -omega, omega, 0.0)
            } else {
                nalgebra::Matrix2::zeros()
            };
            assert_eq!(*c, want, "{transfer}");
        }
    }
}

#[test]
fn a_rotation_about_the_default_centre_adds_to_the_velocity() {
    // A box whose centre of mass is (0.3, 0.2); ω = −2 plus a drift (1, 0.5).
    let text = scene_2d(
        RUBBER,
        r#"material = "rubber"
shape = { type = "box", lo = [0.1, 0.1], hi = [0.5, 0.3] }
velocity = [1.0, 0.5]
rotation = { angular_velocity = -2.0 }"#,
        "apic",
        "[0.0, 0.0]",
    );
    let p = build_2d(&text).particles;
    for i in 0..p.len() {
        let r = [p.x[i][0] - 0.3, p.x[i][1] - 0.2];
        let want = [1.0 + 2.0 * r[1], 0.5 - 2.0 * r[0]];
        assert!(
            (p.v[i][0] - want[0]).abs() < 1e-14 && (p.v[i][1] - want[1]).abs() < 1e-14,
            "{i}"
        );
    }
    let momentum = p.momentum();
    let m = p.total_mass();
    assert!((momentum[0] - m).abs() < 1e-12 * m && (momentum[1] - 0.5 * m).abs() < 1e-12 * m);
}

#[test]
fn a_3d_rotation_takes_a_vector() {
    let text = r#"
[grid]
lo = [0.0, 0.0, 0.0]
hi = [1.0, 1.0, 1.0]
cell_size = 0.1

[[materials]]
name = "rubber"
model = "hencky"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3

[[bodies]]
material = "rubber"
shape = { type = "sphere", centre = [0.5, 0.5, 0.5], radius = 0.3 }
rotation = { angular_velocity = [0.0, 1.0, 2.0], center = [0.5, 0.5, 0.5] }

[solver]
time_step = { type = "fixed", dt = 1e-4 }
end_time = 0.1
"#;
    let p = Scene::from_toml_str(text)
        .unwrap()
        .build::<3>()
        .unwrap()
        .particles;
    let w = nalgebra::Vector3::new(0.0, 1.0, 2.0);
    for i in 0..p.len() {
        let r = p.x[i] - nalgebra::Vector3::repeat(0.5);
        assert!((p.v[i] - w.cross(&r)).amax() < 1e-15);
        assert!((p.c[i] * r - w.cross(&r)).amax() < 1e-15);
    }
}

/// A scene file in `dir` whose one body takes its velocities from `v.csv`.
fn csv_scene(dir: &Path, csv: &str) -> String {
    std::fs::write(dir.join("v.csv"), csv).unwrap();
    let text = scene_2d(
        RUBBER,
        r#"material = "rubber"
shape = { type = "box", lo = [0.1, 0.1], hi = [0.3, 0.2] }
velocity_file = "v.csv""#,
        "apic",
        "[0.0, -9.81]",
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, &text).unwrap();
    path.to_str().unwrap().to_owned()
}

/// The particle positions of the CSV scene's body (4 × 2 cells of 2 × 2 particles).
fn csv_positions() -> Vec<[f64; 2]> {
    let text = scene_2d(
        RUBBER,
        r#"material = "rubber"
shape = { type = "box", lo = [0.1, 0.1], hi = [0.3, 0.2] }"#,
        "apic",
        "[0.0, -9.81]",
    );
    build_2d(&text)
        .particles
        .x
        .iter()
        .map(|x| [x[0], x[1]])
        .collect()
}

fn csv_error(csv: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = csv_scene(dir.path(), csv);
    match Scene::from_path(&path) {
        Err(e) => e.to_string(),
        Ok(scene) => scene.build::<2>().expect_err("an error").to_string(),
    }
}

#[test]
fn a_velocity_field_from_csv_round_trips() {
    let x = csv_positions();
    assert_eq!(x.len(), 32);
    let field = |x: &[f64; 2]| [x[1].sin() * 3.0, -x[0] * x[0] / 7.0];
    // With the positions (checked against the particles) and without them.
    for with_positions in [true, false] {
        let mut csv = String::from("# velocities of the block\n");
        csv.push_str(if with_positions {
            "x, y, vx, vy\n"
        } else {
            "vy,vx\n"
        });
        for p in &x {
            let v = field(p);
            if with_positions {
                csv.push_str(&format!("{}, {}, {}, {}\n", p[0], p[1], v[0], v[1]));
            } else {
                csv.push_str(&format!("{},{}\n\n", v[1], v[0]));
            }
        }
        let dir = tempfile::tempdir().unwrap();
        let path = csv_scene(dir.path(), &csv);
        let built = Scene::from_path(&path).unwrap().build::<2>().unwrap();
        for (p, v) in x.iter().zip(&built.particles.v) {
            // Rust prints floats in their shortest round-trip form: the bits come back.
            let want = field(p);
            assert_eq!([v[0].to_bits(), v[1].to_bits()], want.map(f64::to_bits));
        }
        assert!(
            built
                .particles
                .c
                .iter()
                .all(|c| *c == nalgebra::Matrix2::zeros())
        );
    }
}

#[test]
fn malformed_velocity_files_name_the_field_the_line_and_the_problem() {
    let x = csv_positions();
    let rows = |n: usize| -> String {
        x.iter()
            .take(n)
            .map(|p| format!("{},{},0.1,0.2\n", p[0], p[1]))
            .collect()
    };
    let cases: Vec<(String, &str)> = vec![
        (
            format!("x,y,vx,vy\n{}", rows(31)),
            "has 31 rows of velocities but the body has 32 particles",
        ),
        (
            format!("x,y,vx,vy\n{}0.1,0.1,abc,0.0\n", rows(31)),
            "line 33, column vx: `abc` is not a number",
        ),
        (
            format!("x,y,vx,vy\n{}0.1,0.1\n", rows(5)),
            "line 7: expected 4 values (x,y,vx,vy), got 2",
        ),
        (
            "x,y,w,vy\n".to_owned(),
            "line 1: unknown column `w`; expected x, y, vx, vy",
        ),
        ("x,y,vx\n".to_owned(), "the header must name all of vx, vy"),
        ("x,vx,vy\n".to_owned(), "the header must name all of x, y"),
        ("vx,vy,vx\n".to_owned(), "column `vx` is given twice"),
        (String::new(), "is empty; expected a header"),
        (
            format!("x,y,vx,vy\n{},{},1,1\n", x[1][0], x[1][1]),
            "line 2: the position (0.1375",
        ),
        (
            format!("vx,vy\n{}", "1,inf\n".repeat(32)),
            "line 2, column vy: must be finite, got inf",
        ),
    ];
    for (csv, expected) in cases {
        let err = csv_error(&csv);
        assert!(
            err.contains("bodies[0].velocity_file: ") && err.contains(expected),
            "{expected}\n{err}"
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let path = csv_scene(dir.path(), "");
    std::fs::remove_file(dir.path().join("v.csv")).unwrap();
    let err = Scene::from_path(&path)
        .unwrap()
        .build::<2>()
        .unwrap_err()
        .to_string();
    assert!(err.contains("v.csv: cannot read it"), "{err}");
}

#[test]
fn misused_initial_state_keys_are_errors_naming_the_field() {
    let body = |extra: &str| {
        format!(
            "material = \"rubber\"\nshape = {{ type = \"box\", lo = [0.1, 0.1], hi = [0.3, 0.2] }}\n{extra}"
        )
    };
    // The scene with an implicit solver that balances the initial stress.
    let implicit = |text: &str| {
        let head = text.split("[solver]").next().expect("a solver section");
        format!(
            "{head}[solver]\ntype = \"implicit\"\nload_steps = 1\nbalance_initial_stress = true\n"
        )
    };
    let water = r#"
[[materials]]
name = "water"
model = "fluid"
density = 1000.0
sound_speed = 20.0
"#;
    let cases = [
        (
            scene_2d(
                RUBBER,
                &body("rotation = { angular_velocity = [1.0, 2.0] }"),
                "apic",
                "[0.0, -9.81]",
            ),
            "bodies[0].rotation.angular_velocity: expected a number in 2D",
        ),
        (
            scene_2d(
                RUBBER,
                &body("rotation = { angular_velocity = 1.0, axis = [0, 0, 1] }"),
                "apic",
                "[0.0, -9.81]",
            ),
            "unknown field `axis`",
        ),
        (
            scene_2d(
                RUBBER,
                &body("velocity = [1.0, 0.0]\nvelocity_file = \"v.csv\""),
                "apic",
                "[0.0, -9.81]",
            ),
            "bodies[0].velocity_file: gives every particle its velocity",
        ),
        (
            scene_2d(
                RUBBER,
                &body("initial_stress = { type = \"geostatic\" }"),
                "apic",
                "[0.0, 0.0]",
            ),
            "bodies[0].initial_stress: needs gravity along one coordinate axis",
        ),
        (
            scene_2d(
                RUBBER,
                &body("initial_stress = { type = \"geostatic\" }"),
                "apic",
                "[1.0, -9.81]",
            ),
            "needs gravity along one coordinate axis (depth is measured along it), got loads.gravity = (1, -9.81)",
        ),
        (
            scene_2d(
                RUBBER,
                &body("initial_stress = { type = \"geostatic\", kk0 = 0.5 }"),
                "apic",
                "[0.0, -9.81]",
            ),
            "unknown field `kk0`",
        ),
        (
            scene_2d(
                RUBBER,
                &body("initial_stress = { type = \"geostatic\", k0 = -0.5 }"),
                "apic",
                "[0.0, -9.81]",
            ),
            "bodies[0].initial_stress.k0: must be positive, got -0.5",
        ),
        (
            scene_2d(
                RUBBER,
                &body("initial_stress = { type = \"lithostatic\" }"),
                "apic",
                "[0.0, -9.81]",
            ),
            "unknown variant `lithostatic`",
        ),
        (
            scene_2d(
                water,
                &body("initial_stress = { type = \"geostatic\" }").replace("rubber", "water"),
                "apic",
                "[0.0, -9.81]",
            ),
            "bodies[0].initial_stress.type: a fluid carries no shear stress",
        ),
        (
            scene_2d(
                RUBBER,
                &body("initial_stress = { type = \"geostatic\", surface = 0.15 }"),
                "apic",
                "[0.0, -9.81]",
            ),
            "bodies[0].initial_stress: surface = 0.15 lies below particles of the body (the \
             highest at y = 0.1875)",
        ),
        // The balance of an initial stress is an implicit setting, and needs one.
        (
            scene_2d(
                RUBBER,
                &body("initial_stress = { type = \"geostatic\" }"),
                "apic",
                "[0.0, -9.81]",
            )
            .replace("[solver]\n", "[solver]\nbalance_initial_stress = true\n"),
            "solver.balance_initial_stress: only used by the implicit solver",
        ),
        (
            implicit(&scene_2d(RUBBER, &body(""), "apic", "[0.0, -9.81]")),
            "solver.balance_initial_stress: no body has an initial_stress to balance",
        ),
    ];
    for (text, expected) in cases {
        let err = build_error(&text);
        assert!(err.contains(expected), "{expected}\n{err}");
    }
}

/// The stress a material's own update gives for `F` at rest from the reference state.
fn model_stress(material: &Material<f64>, f: &nalgebra::Matrix2<f64>) -> Matrix3<f64> {
    let f3 = to3(f, 1.0);
    let zero = Matrix3::zeros();
    let kin = Kinematics {
        f: &f3,
        delta_f: &f3,
        velocity_gradient: &zero,
        dt: 0.0,
        stress: &zero,
    };
    material.update(&kin, &mut MaterialState::default())
}

/// A 0.4 m × 0.3 m column of `material` on the floor under g = 9.81, with `stress` as its
/// initial stress.
fn column(material: &str, stress: &str) -> Built<2> {
    let name = material
        .split("name = \"")
        .nth(1)
        .and_then(|s| s.split('"').next())
        .unwrap();
    build_2d(&scene_2d(
        material,
        &format!(
            "material = \"{name}\"\nshape = {{ type = \"box\", lo = [0.2, 0.0], hi = [0.6, 0.3] }}\ninitial_stress = {stress}"
        ),
        "apic",
        "[0.0, -9.81]",
    ))
}

/// Depth below the column's top, y = 0.3.
fn depth(y: f64) -> f64 {
    0.3 - y
}

const SAND: &str = r#"
[[materials]]
name = "sand"
model = "drucker_prager"
density = 1800.0
youngs_modulus = 1.0e7
poisson_ratio = 0.3
friction_angle = 30.0
"#;

#[test]
fn a_geostatic_drucker_prager_column_carries_rho_g_depth_with_its_elastic_strain_state() {
    let built = column(SAND, "{ type = \"geostatic\" }");
    let p = &built.particles;
    let Model::DruckerPrager(dp) = &built.materials[0].model else {
        unreachable!()
    };
    let k0 = 1.0 - 30f64.to_radians().sin();
    let volume = 0.025 * 0.025;
    for i in 0..p.len() {
        // σ_v = −ρ g d and σ_h = K0 σ_v, exactly as formed (a product of the inputs).
        let sv = -1800.0 * 9.81 * depth(p.x[i][1]);
        let s = p.stress[i];
        assert!((s[(1, 1)] - sv).abs() <= 1e-12 * sv.abs(), "{i}: {s}");
        assert!((s[(0, 0)] - k0 * sv).abs() <= 1e-12 * sv.abs());
        assert!((s[(2, 2)] - k0 * sv).abs() <= 1e-12 * sv.abs());
        assert_eq!(s[(0, 1)], 0.0);
        // The state I + 2εₑ stands for the same stress; F = I, so mass and volume are those
        // of the lattice.
        let back = dp.stress_of_state(&p.state[i]);
        assert!((back - s).amax() <= 1e-9 * sv.abs(), "{back} {s}");
        assert_eq!(p.f[i], nalgebra::Matrix2::identity());
        assert!((p.volume0[i] - volume).abs() < 1e-18 && p.state[i].plastic_strain == 0.0);
        assert!(dp.yield_function(&s) <= 0.0);
    }
}

#[test]
fn geostatic_elastic_columns_have_the_deformation_that_carries_the_stress() {
    let solids = ["linear_elastic", "neo_hookean", "hencky", "j2"];
    for model in solids {
        let extra = if model == "j2" {
            "yield_stress = 1.0e6\n"
        } else {
            ""
        };
        let material = format!(
            "[[materials]]\nname = \"soil\"\nmodel = \"{model}\"\ndensity = 2000.0\n\
             youngs_modulus = 5.0e6\npoisson_ratio = 0.25\n{extra}"
        );
        let built = column(&material, "{ type = \"geostatic\", k0 = 0.6 }");
        let p = &built.particles;
        let m = &built.materials[0];
        for i in 0..p.len() {
            let sv = -2000.0 * 9.81 * depth(p.x[i][1]);
            // The in-plane stresses are the targets, to the solver's tolerance: 1e-12 of the
            // stress plus the round-off of a stress of strains of 1e-5 (16 ε (λ + 2μ) =
            // 2e-8 Pa, 1e-10 of ρ g d at the shallowest particle).
            let s = p.stress[i];
            let tol = 1e-12 * sv.abs() + 2.5e-8;
            assert!((s[(1, 1)] - sv).abs() <= tol, "{model} {i}: {s}");
            assert!((s[(0, 0)] - 0.6 * sv).abs() <= tol, "{model}: {s}");
            // ... and what the model itself gives for the particle's F.
            let again = model_stress(m, &p.f[i]);
            assert!(
                (again - s).amax() <= 1e-10 * sv.abs(),
                "{model}: {again} {s}"
            );
            // The particle keeps its lattice volume: V⁰ det F = (h/2)².
            let v = p.volume0[i] * det(&p.f[i]);
            assert!((v - 0.025 * 0.025).abs() < 1e-15, "{model}: {v}");
            assert!((p.mass[i] - 2000.0 * p.volume0[i]).abs() < 1e-12);
        }
    }
    // Linear elasticity with the default K0 = ν/(1 − ν) is a state of uniaxial strain:
    // F_xx = 1 and σ_zz = K0 σ_v too.
    let material = "[[materials]]\nname = \"soil\"\nmodel = \"linear_elastic\"\ndensity = 2000.0\n\
                    youngs_modulus = 5.0e6\npoisson_ratio = 0.25\n";
    let built = column(material, "{ type = \"geostatic\" }");
    let p = &built.particles;
    let k0 = 0.25 / 0.75;
    for i in 0..p.len() {
        let sv = -2000.0 * 9.81 * depth(p.x[i][1]);
        assert!((p.f[i][(0, 0)] - 1.0).abs() < 1e-12, "{}", p.f[i]);
        assert!((p.stress[i][(2, 2)] - k0 * sv).abs() <= 1e-9 * sv.abs());
    }
}

#[test]
fn a_hydrostatic_fluid_column_has_the_pressure_of_its_weight_and_the_matching_volume() {
    let water = r#"
[[materials]]
name = "water"
model = "fluid"
density = 1000.0
sound_speed = 10.0
"#;
    let built = column(water, "{ type = \"hydrostatic\" }");
    let p = &built.particles;
    let Model::Fluid(fluid) = &built.materials[0].model else {
        unreachable!()
    };
    let (k, gamma) = (fluid.bulk_modulus, fluid.gamma);
    for i in 0..p.len() {
        let w = 1000.0 * 9.81 * depth(p.x[i][1]);
        let pressure = -p.stress[i][(1, 1)];
        // Isotropic, from the model's own p(J) of the particle's F.
        assert_eq!(p.stress[i][(0, 0)], p.stress[i][(1, 1)]);
        let j = det(&p.f[i]);
        assert!((fluid.pressure(j) - pressure).abs() < 1e-12 * w);
        // The column's pressure: dp/dd = ρ(p) g with ρ = ρ₀ (1 + γp/K)^{1/γ}, whose
        // solution is (K/γ)[(1 + (γ−1)w/K)^{γ/(γ−1)} − 1], w = ρ₀ g d; checked here as
        // ρ g d to first order, p − w = w²/(2K) + O(w³/K²).
        let excess = pressure - w;
        assert!(
            (excess - w * w / (2.0 * k)).abs() < 2.0 * gamma * w * w * w / (k * k),
            "{i}: p = {pressure}, ρ₀gd = {w}"
        );
        // The particle is denser by 1/J and fills its share of the column: m = ρ V / J.
        let v = p.volume0[i] * j;
        assert!((v - 0.025 * 0.025).abs() < 1e-15);
        assert!((p.mass[i] - 1000.0 * v / j).abs() < 1e-12);
    }
}

#[test]
fn inadmissible_initial_stresses_are_errors_naming_the_depth_and_the_bound() {
    // K0 = 0.2 lies outside the cone of φ = 30° (without cohesion K0 must be ≥ 0.465).
    let err = build_error(&scene_2d(
        SAND,
        "material = \"sand\"\nshape = { type = \"box\", lo = [0.2, 0.0], hi = [0.6, 0.3] }\n\
         initial_stress = { type = \"geostatic\", k0 = 0.2 }",
        "apic",
        "[0.0, -9.81]",
    ));
    assert!(
        err.contains("bodies[0].initial_stress: at depth 0.0125 m")
            && err.contains("K0 = 0.2 lies outside the Drucker–Prager cone")
            && err.contains("K0 in [0.4648"),
        "{err}"
    );
    // J2 yields where the von Mises stress q exceeds σ_y. In plane strain with Hencky
    // elasticity (λ = μ = 2 MPa) and σ_x = 0.5 σ_v, σ_zz = λ(e_x + e_y) = 0.375 σ_v, so
    // q = 0.5728 |σ_v| > 1e3 Pa below d = 1745.8 / (2000 · 9.81) = 0.0890 m: the first
    // particle row below is at d = 0.1125 m.
    let material = "[[materials]]\nname = \"clay\"\nmodel = \"j2\"\ndensity = 2000.0\n\
                    youngs_modulus = 5.0e6\npoisson_ratio = 0.25\nyield_stress = 1.0e3\n";
    let err = build_error(&scene_2d(
        material,
        "material = \"clay\"\nshape = { type = \"box\", lo = [0.2, 0.0], hi = [0.6, 0.3] }\n\
         initial_stress = { type = \"geostatic\", k0 = 0.5 }",
        "apic",
        "[0.0, -9.81]",
    ));
    assert!(
        err.contains("lies outside the yield surface of model \"j2\"")
            && err.contains("at depth 0.1125 m"),
        "{err}"
    );
}
