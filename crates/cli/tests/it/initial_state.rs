//! Initial states from scene files, run: a rotating disk keeps its angular momentum (audited
//! from the frames, with the affine field), columns with a geostatic or hydrostatic initial
//! stress stay at rest under gravity, and a clay column's time step follows its pressure.

use loam_core::Particles;
use loam_explicit::Solver;
use loam_scene::{Built, Scene};
use std::path::Path;
use std::process::Command;
use vtkio::model::{Attribute, DataSet, Piece, Vtk};

/// One array of a frame.
fn array(frame: &Path, name: &str) -> Vec<f64> {
    let vtk = Vtk::import(frame).expect("a readable frame");
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("not an unstructured grid");
    };
    let Some(Piece::Inline(piece)) = pieces.into_iter().next() else {
        panic!("no inline piece");
    };
    if name == "points" {
        return piece.points.into_vec().expect("f64 points");
    }
    piece
        .data
        .point
        .into_iter()
        .find_map(|a| match a {
            Attribute::DataArray(d) if d.name == name => d.data.into_vec(),
            _ => None,
        })
        .unwrap_or_else(|| panic!("no `{name}` in {}", frame.display()))
}

/// The angular momentum about the origin of the particles of a 2D frame, with the APIC
/// part: `L = Σ m (x v_y − y v_x) + Σ m κh² (C_yx − C_xy)` (quadratic B-spline, κ = ¼).
fn angular_momentum(frame: &Path, h: f64) -> f64 {
    let (x, v) = (array(frame, "points"), array(frame, "velocity"));
    let (m, c) = (array(frame, "mass"), array(frame, "affine"));
    let d = 0.25 * h * h;
    (0..m.len())
        .map(|i| {
            let (px, py, vx, vy) = (x[3 * i], x[3 * i + 1], v[3 * i], v[3 * i + 1]);
            // Row-major 3×3: C_xy at 1, C_yx at 3.
            m[i] * (px * vy - py * vx + d * (c[9 * i + 3] - c[9 * i + 1]))
        })
        .sum()
}

#[test]
fn a_rotating_elastic_disk_keeps_its_angular_momentum_with_apic() {
    let (omega, h) = (2.0, 0.025);
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("spin.toml");
    std::fs::write(
        &scene,
        format!(
            r#"
[grid]
lo = [0.0, 0.0]
hi = [1.0, 1.0]
cell_size = {h}

[[materials]]
name = "rubber"
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3

[[bodies]]
material = "rubber"
shape = {{ type = "disk", centre = [0.5, 0.5], radius = 0.2 }}
rotation = {{ angular_velocity = {omega} }}

[solver]
transfer = "apic"
time_step = {{ type = "adaptive", cfl = 0.4, max_dt = 1e-3 }}
end_time = 0.1

[output]
frames = 2
fields = ["velocity", "mass", "affine"]
"#
        ),
    )
    .expect("write scene");
    let out = dir.path().join("out");
    let run = Command::new(env!("CARGO_BIN_EXE_loam"))
        .args([
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ])
        .output()
        .expect("loam runs");
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let first = out.join("frame_0000.vtu");
    // Initially: ω Σ m |x − x₀|² about the centre of mass (the disk's centre) plus the affine
    // part Σ m κh² · 2ω of C = [[0, −ω], [ω, 0]].
    let (x, m) = (array(&first, "points"), array(&first, "mass"));
    let total: f64 = m.iter().sum();
    let expected: f64 = (0..m.len())
        .map(|i| {
            let (rx, ry) = (x[3 * i] - 0.5, x[3 * i + 1] - 0.5);
            m[i] * omega * (rx * rx + ry * ry)
        })
        .sum::<f64>()
        + total * 0.25 * h * h * 2.0 * omega;
    let l0 = angular_momentum(&first, h);
    // Round-off of the sums (1e-13 relative) and of the frame's centre-of-mass offset.
    assert!(
        (l0 - expected).abs() < 1e-12 * expected,
        "{l0} vs {expected}"
    );
    // APIC with B-splines conserves L exactly in the transfers, and the grid update with a
    // symmetric stress exerts no torque: what remains is the round-off of some 200 steps
    // (measured 2e-15 relative).
    for k in 1..=2 {
        let l = angular_momentum(&out.join(format!("frame_{k:04}.vtu")), h);
        assert!(
            (l - l0).abs() < 1e-12 * l0,
            "frame {k}: L = {l}, initially {l0}"
        );
    }
}

/// Runs `steps` steps of a built scene in process; returns the particles and the largest
/// particle speed seen.
fn run(built: &Built<2>, steps: usize) -> (Particles<f64, 2>, f64) {
    let mut p = built.particles.clone();
    let mut solver = Solver::new(built.explicit_config().expect("an explicit scene"), &p)
        .expect("a valid scene");
    let mut fastest = 0.0f64;
    for _ in 0..steps {
        solver.step(&mut p, f64::INFINITY).expect("a stable step");
        fastest = p.v.iter().map(|v| v.norm()).fold(fastest, f64::max);
    }
    (p, fastest)
}

/// A column 0.4 m wide and 0.4 m high on a fixed floor between slip walls, of `material`,
/// with or without `initial_stress`.
fn column(material: &str, name: &str, initial_stress: Option<&str>, transfer: &str) -> Built<2> {
    let stress = initial_stress.map_or_else(String::new, |s| format!("initial_stress = {s}"));
    let text = format!(
        r#"
[grid]
lo = [0.0, 0.0]
hi = [0.4, 0.6]
cell_size = 0.02

{material}

[[bodies]]
material = "{name}"
shape = {{ type = "box", lo = [0.0, 0.0], hi = [0.4, 0.4] }}
{stress}

[boundaries]
x_min = "slip"
x_max = "slip"
y_min = "fixed"

[loads]
gravity = [0.0, -9.81]

[solver]
transfer = "{transfer}"
time_step = {{ type = "adaptive", cfl = 0.4, max_dt = 1e-3 }}
end_time = 1.0
"#
    );
    Scene::from_toml_str(&text)
        .unwrap_or_else(|e| panic!("{e}"))
        .build::<2>()
        .unwrap_or_else(|e| panic!("{e}"))
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

const WATER: &str = r#"
[[materials]]
name = "water"
model = "fluid"
density = 1000.0
sound_speed = 20.0
"#;

const SOIL: &str = r#"
[[materials]]
name = "soil"
model = "hencky"
density = 2000.0
youngs_modulus = 5.0e6
poisson_ratio = 0.25
"#;

#[test]
fn columns_with_an_initial_stress_at_rest_stay_at_rest() {
    // A column released without its stress springs under its weight: within 400 steps its
    // particles reach 2–9 % of √(gH) (measured). With the stress at rest the only forces left
    // are the discretisation's (the stress gradient across the top row of particles and at
    // the floor is resolved to O(h)): measured 3e-5 to 2e-4 √(gH). The bound, 1e-3 √(gH), is
    // five times the largest of these and twenty times below the released columns.
    let scale = (9.81f64 * 0.4).sqrt();
    for (material, name, stress) in [
        (SAND, "sand", "{ type = \"geostatic\" }"),
        (SOIL, "soil", "{ type = \"geostatic\" }"),
        (WATER, "water", "{ type = \"hydrostatic\" }"),
    ] {
        for transfer in ["apic", "mls"] {
            let steps = 400;
            let (p, still) = run(&column(material, name, Some(stress), transfer), steps);
            let (_, released) = run(&column(material, name, None, transfer), steps);
            assert!(
                still < 1e-3 * scale && released > 2e-2 * scale,
                "{name} {transfer}: {:.3e} √(gH) with the stress, {:.3e} without",
                still / scale,
                released / scale
            );
            // Nothing yielded on the way.
            assert!(p.state.iter().all(|s| s.plastic_strain == 0.0), "{name}");
        }
    }
    // Modified Cam-Clay has no stiffness at zero stress, so only its column at rest can run
    // (over 400 steps bounded by every particle's own wave speed); it stays at rest within
    // the same bound, and inside its ellipse (OCR 1.5).
    for transfer in ["apic", "mls"] {
        let (p, still) = run(&column(CLAY, "clay", Some(GEOSTATIC), transfer), 400);
        assert!(
            still < 1e-3 * scale,
            "clay {transfer}: {:.3e} √(gH)",
            still / scale
        );
        assert!(p.state.iter().all(|s| s.plastic_strain == 0.0), "clay");
    }
}

const GEOSTATIC: &str = "{ type = \"geostatic\" }";

/// A lightly overconsolidated soft clay (λ = 0.2, κ = 0.04, M = 1,
/// e₀ = 1, ν = 0.3, OCR 1.5).
const CLAY: &str = r#"
[[materials]]
name = "clay"
model = "modified_cam_clay"
density = 1800.0
lambda = 0.2
kappa = 0.04
critical_state_slope = 1.0
void_ratio = 1.0
poisson_ratio = 0.3
ocr = 1.5
"#;

/// An explicit step on Modified Cam-Clay is bounded by each particle's own wave speed: in a
/// geostatic column the deepest particles, with the largest `p′`, set it, at
/// `c = √((K + 4G/3 + ‖dev τ‖/κ̃)/ρ₀)` with `K = p′/κ̃`, `G = 3(1 − 2ν)/(2(1 + ν)) K`,
/// `p′ = (1 + 2K0)/3 · σ_v`, `‖dev τ‖ = √6 (1 − K0) σ_v / 3`, `σ_v = ρ₀ g d` (K0 = Jaky's
/// `1 − 3M/(6 + M)`, the default; the last term is `2 (dG/dε_v) ‖dev εₑ‖` of
/// `p_wave_modulus_in`; 1e-9: the stress goes through the elastic strain and back,
/// `exp ∘ ln`).
#[test]
fn an_explicit_clay_step_is_bounded_by_its_deepest_particles() {
    let built = column(CLAY, "clay", Some(GEOSTATIC), "apic");
    let p = &built.particles;
    let solver = Solver::new(built.explicit_config().expect("explicit"), p).expect("valid");
    let (limit, particle, c, _) = solver.stability_limit(p);
    let deepest = p.x.iter().map(|x| x[1]).fold(f64::INFINITY, f64::min);
    assert_eq!(
        p.x[particle][1], deepest,
        "particle {particle} sets the bound"
    );
    let (rho, kappa, nu) = (1800.0, 0.04 / 2.0, 0.3);
    let k0 = 1.0 - 3.0 / 7.0;
    let vertical = rho * 9.81 * (0.4 - deepest);
    let pressure = (1.0 + 2.0 * k0) / 3.0 * vertical;
    let bulk = pressure / kappa;
    let shear = 1.5 * (1.0 - 2.0 * nu) / (1.0 + nu) * bulk;
    let distortion = 6f64.sqrt() * (1.0 - k0) * vertical / 3.0 / kappa;
    let expected = ((bulk + 4.0 / 3.0 * shear + distortion) / rho).sqrt();
    assert!(
        (c - expected).abs() <= 1e-9 * expected,
        "c = {c} vs {expected}"
    );
    assert!((limit - 0.02 / expected).abs() <= 1e-9 * limit, "{limit}");
}
