//! The reference scenes of the cases: scene files under `verification/scenes/`, compiled into
//! the crate so that a `loam` binary needs no source tree to verify.
//!
//! Each file is the full-size reference problem of a case, with a header saying what it is and
//! what the case measures; `loam run verification/scenes/NAME.toml` runs it as any scene. A
//! case parses its file ([`scene`]), changes the typed fields it varies (cell size, transfer,
//! friction coefficient, ...) and builds its solver inputs through `loam-scene`
//! ([`build`], then `Built::explicit_config` / `Built::implicit_config` and the built
//! particles), the one way from a scene to a solver that the command line and the benches use
//! too.
//!
//! A case that sets an initial velocity field (the first mode of a bar or a beam) removes the
//! body's `velocity_file` and sets the field on the built particles at every resolution it
//! runs: the file names a velocity CSV for `loam run` at the reference resolution (a test
//! checks it against the case's field), and the case's other resolutions have no such file.

use loam_scene::{Built, Scene};

/// A reference scene of a case: a scene file of `verification/scenes/`, compiled in.
#[derive(Clone, Copy, Debug)]
pub struct CaseScene {
    /// The file's stem.
    pub name: &'static str,
    /// The file, relative to the repository root.
    pub path: &'static str,
    /// The file's text.
    pub toml: &'static str,
}

/// A [`CaseScene`] for `verification/scenes/$name.toml`.
macro_rules! case_scene {
    ($name:literal) => {
        CaseScene {
            name: $name,
            path: concat!("verification/scenes/", $name, ".toml"),
            toml: include_str!(concat!("../scenes/", $name, ".toml")),
        }
    };
}

/// Every reference scene, in the order of [`crate::cases`].
pub const SCENES: [CaseScene; 35] = [
    case_scene!("axial_bar"),
    case_scene!("axial_bar_newmark"),
    case_scene!("newmark_energy"),
    case_scene!("cantilever"),
    case_scene!("column_compaction"),
    case_scene!("footing_prandtl"),
    case_scene!("footing_cphi"),
    case_scene!("slope_fos"),
    case_scene!("k0_layer"),
    case_scene!("terzaghi"),
    case_scene!("mandel"),
    case_scene!("consolidation_large"),
    case_scene!("footing_consolidation_3d"),
    case_scene!("disk_collision"),
    case_scene!("bui_collapse"),
    case_scene!("column_runout"),
    case_scene!("dambreak_2d"),
    case_scene!("incline_friction"),
    case_scene!("dambreak_obstacles_3d"),
    case_scene!("adjoint_fluid"),
    case_scene!("adjoint_block"),
    case_scene!("adjoint_column"),
    case_scene!("adjoint_block_3d"),
    case_scene!("obstacle_velocity"),
    case_scene!("inverse_v0"),
    case_scene!("inverse_friction"),
    case_scene!("inverse_mlp"),
    case_scene!("implicit_cantilever"),
    case_scene!("implicit_footing"),
    case_scene!("implicit_clay_footing"),
    case_scene!("implicit_consolidation"),
    case_scene!("implicit_consolidation_3d"),
    case_scene!("implicit_consolidation_clay"),
    case_scene!("implicit_mandel"),
    case_scene!("implicit_cantilever_newmark"),
];

/// The reference scene `name` (a stem of [`SCENES`]), parsed and validated.
///
/// # Panics
///
/// When `name` is not a reference scene or its file is invalid: the names are fixed by the
/// cases, and the tests parse and build every file.
pub fn scene(name: &str) -> Scene {
    let Some(file) = SCENES.iter().find(|s| s.name == name) else {
        panic!("no reference scene `{name}`");
    };
    Scene::from_toml_str(file.toml).unwrap_or_else(|e| panic!("{}: {e}", file.path))
}

/// Builds a case's scene (after the case changed its fields) in `D` dimensions.
///
/// # Panics
///
/// When the scene does not build: the changes a case makes are fixed, and the reduced-size
/// tests build every case.
pub fn build<const D: usize>(scene: &Scene) -> Built<D> {
    scene
        .build()
        .unwrap_or_else(|e| panic!("a verification scene does not build: {e}"))
}
