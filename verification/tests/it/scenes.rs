//! The reference scenes of `verification/scenes/`: every file is compiled into the crate,
//! parses, builds with its solver's configuration, and the velocity files hold the initial
//! fields the cases set.

use loam_scene::{Built, Scene, SolverKind};
use loam_verification::scenes::{SCENES, scene};
use loam_verification::{axial_bar, newmark_energy};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A scene read from its file (so that a velocity file resolves next to it) and built.
fn built<const D: usize>(name: &str) -> Built<D> {
    let path = root().join(format!("verification/scenes/{name}.toml"));
    Scene::from_path(&path)
        .and_then(|s| s.build::<D>())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn every_scene_file_is_compiled_in_and_builds() {
    let mut files: Vec<String> = std::fs::read_dir(root().join("verification/scenes"))
        .expect("verification/scenes")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .map(|p| p.file_stem().expect("stem").to_string_lossy().into_owned())
        .collect();
    files.sort();
    let mut listed: Vec<String> = SCENES.iter().map(|s| s.name.to_string()).collect();
    listed.sort();
    assert_eq!(
        files, listed,
        "verification/scenes/*.toml and SCENES differ"
    );
    for s in &SCENES {
        let text = std::fs::read_to_string(root().join(s.path)).expect("scene file");
        assert_eq!(text, s.toml, "{}: compiled text is stale", s.path);
        assert!(
            s.toml.starts_with("# "),
            "{}: the file starts with a header comment",
            s.path
        );
        let parsed = scene(s.name);
        let kind = parsed.solver.kind;
        let (explicit, implicit) = match parsed.dim() {
            2 => {
                let b = built::<2>(s.name);
                assert!(!b.particles.is_empty());
                (b.explicit_config().is_some(), b.implicit_config().is_some())
            }
            3 => {
                let b = built::<3>(s.name);
                assert!(!b.particles.is_empty());
                (b.explicit_config().is_some(), b.implicit_config().is_some())
            }
            d => panic!("{}: dimension {d}", s.path),
        };
        assert_eq!(explicit, kind == SolverKind::Explicit, "{}", s.path);
        assert_eq!(implicit, kind == SolverKind::Implicit, "{}", s.path);
    }
}

/// The bar's velocity file is its first mode, `v₀ sin(β₁ x)` along the bar and nothing across
/// it, at every particle; the explicit and the Newmark scene are the same bar.
#[test]
fn axial_bar_files_start_in_the_first_mode() {
    let bar = built::<2>("axial_bar");
    assert_eq!(bar.particles.len(), 320);
    for (x, v) in bar.particles.x.iter().zip(&bar.particles.v) {
        let mode = axial_bar::V0 * (axial_bar::beta1() * x[0]).sin();
        assert!((v[0] - mode).abs() <= 1e-15 * axial_bar::V0, "{x:?}: {v:?}");
        assert_eq!(v[1], 0.0);
    }
    let newmark = built::<2>("axial_bar_newmark");
    assert_eq!(newmark.particles, bar.particles);
    let (a, b) = (scene("axial_bar"), scene("axial_bar_newmark"));
    assert_eq!(
        (&a.grid, &a.materials, &a.bodies),
        (&b.grid, &b.materials, &b.bodies)
    );
}

/// The cantilever's velocity file is the Euler–Bernoulli first mode of the case at its full
/// size: zero at the root, largest (the tip speed ω₁A/φ(1)·φ(ξ)) at the free end, downward.
#[test]
fn newmark_energy_file_starts_in_the_first_mode() {
    let from_file = built::<2>("newmark_energy");
    let setup = newmark_energy::Setup {
        cell: 0.25,
        ppc: 3,
        steps_per_period: 20,
        periods: 10,
        amplitude: 0.1,
    };
    let (_, case) = setup.build();
    assert_eq!(from_file.particles.x, case.x);
    let tip_speed = newmark_energy::omega1() * setup.amplitude;
    for (v, w) in from_file.particles.v.iter().zip(&case.v) {
        assert_eq!(v[0], 0.0);
        assert!(v[1] <= 0.0 && v[1] >= -tip_speed * (1.0 + 1e-12));
        assert!((v[1] - w[1]).abs() <= 1e-13 * tip_speed, "{v:?} vs {w:?}");
    }
}
