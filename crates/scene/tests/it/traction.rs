//! `[[tractions]]`: distributed loads on the surface layer of particles, turned into point
//! loads, refused with the field named when malformed.

use loam_implicit::ImplicitSolver;
use loam_scene::Scene;

/// A column 0.5 m wide and `height` high of linear elastic soil (E = 10 MPa, ν = 0.25) on
/// cells of 0.125 m with linear shape functions, between slip walls on a fixed base, with
/// `extra` TOML appended (and, for [`coupled_column`], more keys in its material).
pub(crate) fn column(height: f64, extra: &str) -> String {
    coupled_column(height, "", extra)
}

/// [`column`] with `material` added to the material's table (e.g. a hydraulic conductivity).
pub(crate) fn coupled_column(height: f64, material: &str, extra: &str) -> String {
    format!(
        r#"
[grid]
lo = [0.0, 0.0]
hi = [0.5, 2.0]
cell_size = 0.125
shape_function = "linear"

[[materials]]
name = "soil"
model = "linear_elastic"
density = 1.0
youngs_modulus = 1.0e7
poisson_ratio = 0.25
{material}

[[bodies]]
material = "soil"
shape = {{ type = "box", lo = [0.0, 0.0], hi = [0.5, {height}] }}
particles_per_cell = 2

[boundaries]
x_min = "slip"
x_max = "slip"
y_min = "fixed"

[solver]
type = "implicit"
load_steps = 2
{extra}
"#
    )
}

#[test]
fn a_traction_loads_the_top_particle_of_every_column_by_its_share_of_the_surface() {
    // A stepped surface: a second body on the left half, 0.25 m higher.
    let text = column(
        1.0,
        r#"
[[bodies]]
material = "soil"
shape = { type = "box", lo = [0.0, 1.0], hi = [0.25, 1.25] }
particles_per_cell = 2

[[tractions]]
face = "y_max"
traction = [0.0, -1.0e3]
"#,
    );
    let built = Scene::from_toml_str(&text).unwrap().build::<2>().unwrap();
    let loads = &built.point_loads;
    // Particles 0.0625 m apart: 8 columns, each loaded by 1 kPa × 0.0625 m.
    assert_eq!(loads.len(), 8);
    let x = &built.particles.x;
    for l in loads {
        assert_eq!(l.force, [0.0, -62.5]);
        let top = if x[l.particle][0] < 0.25 { 1.25 } else { 1.0 };
        assert!((x[l.particle][1] - (top - 0.03125)).abs() < 1e-12);
    }
    // The box limits the loaded columns, on any face.
    let text = column(
        1.0,
        r#"
[[tractions]]
face = "x_max"
lo = [0.0, 0.5]
hi = [0.5, 1.0]
traction = [-2.0e3, 0.0]
"#,
    );
    let built = Scene::from_toml_str(&text).unwrap().build::<2>().unwrap();
    let total: f64 = built.point_loads.iter().map(|l| l.force[0]).sum();
    assert_eq!(built.point_loads.len(), 8);
    assert!((total + 2.0e3 * 0.5).abs() < 1e-9, "{total}");
}

#[test]
fn a_column_under_a_traction_carries_it_uniformly() {
    // Confined compression: σ_yy = −q everywhere and the top settles by q H / M, M the
    // constrained modulus E(1 − ν)/((1 + ν)(1 − 2ν)) = 12 MPa. Small strain (q/M = 8e-4):
    // the updated geometry changes the settlement by O(q/M) relative, hence 2e-3.
    let q = 1.0e4;
    let text = column(
        2.0,
        &format!(
            "\n[[tractions]]\nface = \"y_max\"\ntraction = [0.0, {}]\n",
            -q
        ),
    );
    let built = Scene::from_toml_str(&text).unwrap().build::<2>().unwrap();
    let config = built.implicit_config().unwrap();
    let mut particles = built.particles;
    let y0: Vec<f64> = particles.x.iter().map(|x| x[1]).collect();
    let mut solver = ImplicitSolver::new(config, &particles).unwrap();
    while !solver.finished() {
        solver.step(&mut particles).unwrap();
    }
    // Below the top cell: the load reaches the nodes through the top particles' shape
    // functions, so the top cell's two particle rows share it unevenly.
    for (p, s) in particles.stress.iter().enumerate() {
        if y0[p] < 2.0 - 0.125 {
            assert!((s[(1, 1)] / -q - 1.0).abs() < 2e-3, "{p}: {}", s[(1, 1)]);
        }
    }
    // The highest particle below the top cell: the column beneath it is uniformly stressed.
    let top = (0..particles.len())
        .filter(|&p| y0[p] < 2.0 - 0.125)
        .max_by(|&a, &b| y0[a].total_cmp(&y0[b]))
        .unwrap();
    let settlement = y0[top] - particles.x[top][1];
    let exact = q * y0[top] / 1.2e7;
    assert!(
        (settlement / exact - 1.0).abs() < 2e-3,
        "{settlement} vs {exact}"
    );
}

#[test]
fn a_malformed_traction_is_refused_with_its_field_named() {
    for (extra, field) in [
        (
            "face = \"z_max\"\ntraction = [0.0, -1.0]",
            "tractions[0].face",
        ),
        (
            "face = \"y_max\"\ntraction = [-1.0]",
            "tractions[0].traction",
        ),
        (
            "face = \"y_max\"\nlo = [0.4, 0.0]\nhi = [0.1, 2.0]\ntraction = [0.0, -1.0]",
            "tractions[0].hi[0]",
        ),
        (
            "face = \"y_max\"\nlo = [0.0, 1.5]\nhi = [0.5, 2.0]\ntraction = [0.0, -1.0]",
            "tractions[0]",
        ),
    ] {
        let text = column(1.0, &format!("\n[[tractions]]\n{extra}\n"));
        let err = Scene::from_toml_str(&text)
            .and_then(|s| s.build::<2>().map(|_| ()))
            .unwrap_err()
            .to_string();
        assert!(err.contains(field), "{extra}: {err}");
    }
}
