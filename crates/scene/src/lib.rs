//! # loam-scene
//!
//! Scene files for loam: reading and validating them, filling bodies with particles, and
//! writing what a run produces.
//!
//! A scene is a TOML file (JSON is accepted too, chosen by the `.json` extension) with the
//! sections `[grid]`, `[[materials]]`, `[[bodies]]`, `[boundaries]`, `[loads]`, `[solver]`
//! and `[output]`, and for quasi-static implicit runs (`[solver] type = "implicit"`)
//! `[[constraints]]`, `[[point_loads]]` and `[[tractions]]`, for explicit runs `[[friction]]` (Coulomb
//! friction segments on walls) and `[[obstacles]]` (rigid boxes and cylinders), and `[fos]`
//! (the factor-of-safety search of `loam fos`); `docs/scene-format.md` documents every field.
//! A small 2D example:
//!
//! ```toml
//! [grid]
//! lo = [0.0, 0.0]
//! hi = [1.0, 1.0]
//! cell_size = 0.02
//!
//! [[materials]]
//! name = "rubber"
//! model = "neo_hookean"
//! density = 1000.0
//! youngs_modulus = 1.0e6
//! poisson_ratio = 0.3
//!
//! [[bodies]]
//! material = "rubber"
//! shape = { type = "disk", centre = [0.5, 0.5], radius = 0.2 }
//!
//! [boundaries]
//! y_min = "slip"
//!
//! [loads]
//! gravity = [0.0, -9.81]
//!
//! [solver]
//! time_step = { type = "adaptive", cfl = 0.4, max_dt = 1e-3 }
//! end_time = 1.0
//! ```
//!
//! - [`Scene::from_path`], [`Scene::from_toml_str`], [`Scene::from_json_str`] parse and
//!   [validate](Scene::validate); every error ([`SceneError`]) names the field path and what
//!   was expected.
//! - [`Scene::build`] returns a [`Built`] of plain `loam-core` structs (grid, boundary,
//!   materials, particles, node constraints, point loads) and the solver settings with their
//!   defaults ([`SolverPlan`]) for a solver; dispatch on [`Scene::dim`] to pick `D`.
//! - [`Scene::read_path`], [`Scene::read_path_with_text`] (which also returns the file's
//!   text), [`Scene::read_text_of`] and [`Scene::parse_str`] check the fields only, so that
//!   [`Scene::estimate`] can size a scene (particles, grid nodes) before a single particle
//!   is generated; [`Scene::validate`] then checks the particle generation.
//! - [`output`] writes `.vtu` frames, the `.pvd` series and the JSON run summary.
//! - [`checkpoint`] writes and reads the restartable state of an explicit run.
//! - [`read_csv`] reads the CSV files scenes and inversions take (a spreadsheet's
//!   byte-order mark dropped).
//! - [`element`] reads element-test files (`loam material`): one material point through
//!   laboratory paths.
//!
//! This crate depends on `loam-core`, and on `loam-explicit` for
//! [`Built::explicit_config`] only: solvers take the plain structs it builds.

mod build;
pub mod checkpoint;
mod contact;
mod csv;
pub mod element;
mod error;
mod estimate;
mod forms;
mod geometry;
mod initial;
mod load;
pub mod output;
mod schema;
mod traction;
mod validate;

pub use build::{Built, ExplicitPlan, ImplicitPlan, OutputPlan, Probe, SolverPlan};
pub use csv::read_csv;
pub use error::{Issue, Location, SceneError, SceneFormat};
pub use estimate::Estimate;
pub use load::parse_file;
pub use schema::{
    AxisName, BodyShape, BodySpec, BoundarySpec, ConsolidationSpec, ConstraintSpec,
    DEFAULT_FLUID_GAMMA, Device, Face, FosSpec, FrictionSpec, GridSpec, InflowSpec,
    InitialStressSpec, LinearKind, LinearSpec, LoadSpec, MaterialSpec, NewtonSpec, ObstacleKind,
    ObstacleSpec, OutputSpec, PermeabilityLaw, PointLoadSpec, PoreFluidSpec, ProbeSpec,
    RotationSpec, Scene, SolverKind, SolverSpec, SurfaceSpec, TimeScheme, TimeUnit, TractionSpec,
};
