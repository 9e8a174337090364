//! The scene file schema: one serde struct per section, field names as written in the file.
//!
//! Every struct rejects unknown fields, so a misspelt key is an error that names it rather
//! than a silently ignored setting. The types hold the `loam-core` enums directly
//! ([`Shape`], [`ModelKind`], [`Scheme`], [`Transfer`], [`TimeStep`], [`Wall`]) so a loaded
//! scene needs no conversion before it is built; `docs/scene-format.md` documents every field.
//! The implicit solver's settings ([`NewtonSpec`], [`LinearSpec`]) are plain types of this
//! crate, which depends on `loam-core` only: a front end maps them to the solver's own.

use crate::forms;
use crate::output::Field;
use loam_core::constitutive::{Cone, Elasticity};
use loam_core::{ModelKind, Scheme, Shape, TimeStep, Transfer, Wall};
use loam_implicit::TangentMethod;
use loam_implicit::linear::Preconditioner;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A whole scene: what to simulate, how, and what to write.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The background grid, which also fixes the dimension (2 or 3).
    pub grid: GridSpec,
    /// The material table; bodies refer to materials by name.
    pub materials: Vec<MaterialSpec>,
    /// The bodies, filled with particles in this order (see [`BodySpec`] for overlaps).
    pub bodies: Vec<BodySpec>,
    /// Wall conditions on the faces of the domain (default: all free).
    #[serde(default)]
    pub boundaries: BoundarySpec,
    /// Body forces (default: none).
    #[serde(default)]
    pub loads: LoadSpec,
    /// Prescribed displacements of grid nodes (implicit solver only; default: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub constraints: Vec<ConstraintSpec>,
    /// Forces on particles (implicit solver only; default: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub point_loads: Vec<PointLoadSpec>,
    /// Distributed loads on free surfaces (implicit solver only; default: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tractions: Vec<TractionSpec>,
    /// Material points whose history the run records (implicit solver only; default:
    /// none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub probes: Vec<ProbeSpec>,
    /// Coulomb friction segments on walls (explicit solver only; default: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub friction: Vec<FrictionSpec>,
    /// Rigid obstacles (explicit solver only; default: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub obstacles: Vec<ObstacleSpec>,
    /// Pore water of a saturated soil: makes an implicit run coupled (u–p), with the excess
    /// pore pressure as an unknown (default: none, the soil is dry or drained).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pore_fluid: Option<PoreFluidSpec>,
    /// The solver: explicit dynamics or implicit quasi-static load steps.
    pub solver: SolverSpec,
    /// What to write and where (default: every field, 20 frames, `out/<scene file stem>`).
    #[serde(default)]
    pub output: OutputSpec,
    /// Settings of the factor-of-safety search of `loam fos` (default: none, which `loam fos`
    /// reads as the defaults of [`FosSpec`]); `loam run` does not use it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fos: Option<FosSpec>,
    /// The file the scene was read from, if any (not part of the file; sets the default
    /// output folder and prefixes error messages).
    #[serde(skip)]
    pub source: Option<PathBuf>,
}

/// `[grid]`: a uniform Cartesian grid over the box `[lo, hi]`, whose faces are the walls.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// Lower corner of the domain (m); its length (2 or 3) is the scene's dimension.
    pub lo: Vec<f64>,
    /// Upper corner of the domain (m).
    pub hi: Vec<f64>,
    /// Cell size `h` (m); `hi − lo` must be a whole number of cells along every axis.
    pub cell_size: f64,
    /// Shape-function family (default `quadratic_bspline`).
    #[serde(default = "default_shape_function")]
    pub shape_function: Shape,
}

fn default_shape_function() -> Shape {
    Shape::QuadraticBspline
}

/// `[[materials]]`: a named isotropic material, elastic, (model `j2`) elastoplastic, (models
/// `drucker_prager`, `mohr_coulomb`) frictional elastoplastic or (model `fluid`) a weakly
/// compressible Newtonian fluid.
///
/// Which keys apply depends on `model`: the solid models need `youngs_modulus` and
/// `poisson_ratio`; `drucker_prager` and `mohr_coulomb` also need `friction_angle` and take
/// `dilation_angle`, `cohesion` and `tension_cutoff`; `drucker_prager` takes `cone` and
/// `elasticity`; `fluid` needs exactly one of `sound_speed` and
/// `bulk_modulus` and takes `gamma` and `viscosity`. A key of another model is an error naming
/// it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Name bodies use to refer to the material (unique).
    pub name: String,
    /// Constitutive model.
    pub model: ModelKind,
    /// Reference mass density `ρ₀` (kg/m³), positive.
    pub density: f64,
    /// Young's modulus `E` (Pa), positive: required by the solid models, not allowed for
    /// `fluid`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub youngs_modulus: Option<f64>,
    /// Poisson's ratio `ν`, in (−1, 0.5): required by the solid models, not allowed for
    /// `fluid`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub poisson_ratio: Option<f64>,
    /// Uniaxial yield stress `σ_y` (Pa), positive: required by model `j2`, not allowed for
    /// the elastic models.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yield_stress: Option<f64>,
    /// Linear isotropic hardening modulus `H` (Pa), `≥ 0`; model `j2` only (default 0,
    /// perfect plasticity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hardening: Option<f64>,
    /// Model `fluid`: reference sound speed `c` (m/s), positive; the bulk modulus is then
    /// `K = ρ₀ c²`. Exactly one of `sound_speed` and `bulk_modulus` is required.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sound_speed: Option<f64>,
    /// Model `fluid`: bulk modulus `K` (Pa) at the reference density, positive (instead of
    /// `sound_speed`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bulk_modulus: Option<f64>,
    /// Model `fluid`: Tait exponent `γ ≥ 1` of `p = (K/γ)((ρ/ρ₀)^γ − 1)` (default 7).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gamma: Option<f64>,
    /// Model `fluid`: dynamic viscosity `η` (Pa·s), `≥ 0` (default 0, inviscid).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub viscosity: Option<f64>,
    /// Models `drucker_prager`, `mohr_coulomb`: friction angle `φ` in **degrees**,
    /// `0 < φ < 90` (required).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_angle: Option<f64>,
    /// Models `drucker_prager`, `mohr_coulomb`: dilation angle `ψ` in degrees, `0 ≤ ψ ≤ φ`
    /// (default 0, isochoric plastic flow; `ψ = φ` is associated flow).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dilation_angle: Option<f64>,
    /// Models `drucker_prager`, `mohr_coulomb`: cohesion `c` (Pa), `≥ 0` (default 0,
    /// cohesionless).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cohesion: Option<f64>,
    /// Models `drucker_prager` (on the mean stress) and `mohr_coulomb` (on every principal
    /// stress): tension cutoff `σ_t` (Pa), `0 ≤ σ_t ≤ c cot φ` (default: the apex, `c cot φ`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tension_cutoff: Option<f64>,
    /// Model `drucker_prager`: the Mohr–Coulomb section the cone is matched to,
    /// `"plane_strain"` (default), `"compression"` or `"extension"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cone: Option<Cone>,
    /// Model `drucker_prager`: `"hencky"` (hyperelastic in logarithmic strain; the default
    /// and the only choice of the implicit solver) or `"jaumann"` (hypoelastic, the default of
    /// the explicit solver and the one the GPU runs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elasticity: Option<Elasticity>,
    /// Model `modified_cam_clay`: slope `λ` of the normal compression line in `e–ln p′`
    /// (required, positive).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lambda: Option<f64>,
    /// Model `modified_cam_clay`: slope `κ` of the unloading–reloading line in `e–ln p′`,
    /// `0 < κ < λ` (required).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kappa: Option<f64>,
    /// Model `modified_cam_clay`: slope `M` of the critical state line in `p′–q` (required,
    /// positive; `M = 6 sin φ′/(3 − sin φ′)` in triaxial compression).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub critical_state_slope: Option<f64>,
    /// Model `modified_cam_clay`: initial void ratio `e₀` (required, positive), which turns
    /// `λ`, `κ` into the slopes `λ/(1 + e₀)`, `κ/(1 + e₀)` of `ln v–ln p′`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub void_ratio: Option<f64>,
    /// Model `modified_cam_clay`: a constant shear modulus `G` (Pa), instead of
    /// `poisson_ratio` (which gives `G = 3(1 − 2ν)/(2(1 + ν)) · p′/κ̃`, growing with `p′`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shear_modulus: Option<f64>,
    /// Model `modified_cam_clay`: the initial preconsolidation pressure `p′c0` (Pa, the same
    /// for every point), instead of `ocr`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preconsolidation_pressure: Option<f64>,
    /// Model `modified_cam_clay`: the overconsolidation ratio `R ≥ 1` on the size of the yield
    /// locus, `p′c0 = R (p′₀ + q₀²/(M² p′₀))` from each point's initial stress (`1`: normally
    /// consolidated), instead of `preconsolidation_pressure`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ocr: Option<f64>,
    /// With a `[pore_fluid]`: Darcy's hydraulic conductivity `k` (m/s), positive (required
    /// there, for every material a body uses).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hydraulic_conductivity: Option<f64>,
    /// With a `[pore_fluid]`: Biot's coefficient `α` in (0, 1] (default 1, incompressible
    /// grains).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub biot_coefficient: Option<f64>,
    /// With a `[pore_fluid]`: the porosity `n` in (0, 1), for the storage `n/K_w` of a
    /// compressible pore fluid (required when `pore_fluid.bulk_modulus` is given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub porosity: Option<f64>,
}

/// Default Tait exponent of model `fluid` (water).
pub const DEFAULT_FLUID_GAMMA: f64 = 7.0;

impl MaterialSpec {
    /// The bulk modulus of a `fluid` material, `K` as written or `ρ₀ c²` from the sound
    /// speed (`None` when neither is given or the model is not `fluid`).
    pub fn fluid_bulk_modulus(&self) -> Option<f64> {
        if self.model != ModelKind::Fluid {
            return None;
        }
        self.bulk_modulus
            .or_else(|| self.sound_speed.map(|c| self.density * c * c))
    }
}

/// The numeric constants of [`MaterialSpec`] by their keys in
/// [`loam_core::constitutive::constants::CONSTANTS`] (each key is the field's name).
macro_rules! numeric_constants {
    ($($key:ident),* $(,)?) => {
        impl MaterialSpec {
            /// The value of the numeric constant `key` (`Some(None)`: absent), or `None` when
            /// `key` names no numeric constant (`cone` and `elasticity` are enumerations).
            pub fn constant(&self, key: &str) -> Option<Option<f64>> {
                match key {
                    $(stringify!($key) => Some(self.$key),)*
                    _ => None,
                }
            }

            /// The slot of the numeric constant `key`, as [`MaterialSpec::constant`].
            pub fn constant_mut(&mut self, key: &str) -> Option<&mut Option<f64>> {
                match key {
                    $(stringify!($key) => Some(&mut self.$key),)*
                    _ => None,
                }
            }
        }
    };
}

numeric_constants!(
    youngs_modulus,
    poisson_ratio,
    yield_stress,
    hardening,
    sound_speed,
    bulk_modulus,
    gamma,
    viscosity,
    friction_angle,
    dilation_angle,
    cohesion,
    tension_cutoff,
    lambda,
    kappa,
    critical_state_slope,
    void_ratio,
    shear_modulus,
    preconsolidation_pressure,
    ocr,
    hydraulic_conductivity,
    biot_coefficient,
    porosity,
);

impl MaterialSpec {
    /// Whether the key `key` of [`loam_core::constitutive::constants::CONSTANTS`] is given.
    pub fn has(&self, key: &str) -> bool {
        match key {
            "cone" => self.cone.is_some(),
            "elasticity" => self.elasticity.is_some(),
            _ => self.constant(key).flatten().is_some(),
        }
    }
}

/// `[[bodies]]`: a region of one material filled with particles.
///
/// Particles sit on a regular sub-grid of `particles_per_cell` points per axis in every grid
/// cell (at the centres of the sub-cells) and are kept where they lie inside the shape. Where
/// bodies overlap the earlier body wins: a point inside an earlier body's shape is skipped.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodySpec {
    /// Name of the body's material in [`Scene::materials`].
    pub material: String,
    /// The region the body occupies.
    pub shape: BodyShape,
    /// Particles per cell along each axis, 1 to 8 (default 2).
    #[serde(default = "default_particles_per_cell")]
    pub particles_per_cell: u32,
    /// Initial velocity (m/s), one component per axis (default zero); added to `rotation`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<Vec<f64>>,
    /// Initial rigid rotation, `v = ω × (x − x₀)` (added to `velocity`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation: Option<RotationSpec>,
    /// A CSV file giving every particle of the body its initial velocity (instead of
    /// `velocity` and `rotation`); a relative path is relative to the scene file's folder.
    /// See `docs/scene-format.md` for the columns.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_file: Option<PathBuf>,
    /// Initial stress at rest under gravity (default: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial_stress: Option<InitialStressSpec>,
}

/// A body's initial rigid rotation `v = ω × (x − x₀)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotationSpec {
    /// Angular velocity ω (rad/s): a number in 2D (counter-clockwise positive), three
    /// components in 3D.
    #[serde(with = "forms::angular_velocity")]
    pub angular_velocity: Vec<f64>,
    /// The point x₀ on the axis of rotation (default: the body's centre of mass).
    #[serde(default, alias = "center", skip_serializing_if = "Option::is_none")]
    pub centre: Option<Vec<f64>>,
}

/// A body's initial stress, at rest under the scene's gravity (which must act along one
/// coordinate axis). The depth `d` of a particle is measured along gravity from the body's
/// top surface above it (the top particle of its column plus half a particle spacing), or
/// from the level `surface` when given.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum InitialStressSpec {
    /// Soils and other solids: vertical stress `σ_v = −ρ₀ g d`, horizontal `σ_h = K0 σ_v`.
    Geostatic {
        /// Lateral earth-pressure coefficient `K0 > 0` (default: `1 − sin φ` for
        /// `drucker_prager`, raised to the cone's bound where that lies outside it;
        /// `ν/(1 − ν)` for the elastic models and `j2`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        k0: Option<f64>,
        /// The level (coordinate along the vertical axis) depths are measured from.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        surface: Option<f64>,
    },
    /// Fluids (and isotropic solid states): the pressure of a column at rest, `dp/dd = ρ g`
    /// with the fluid's own density `ρ(p)` (`p ≈ ρ₀ g d`), the same in every direction.
    Hydrostatic {
        /// The level (coordinate along the vertical axis) depths are measured from.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        surface: Option<f64>,
    },
}

impl InitialStressSpec {
    /// The name written after `type =`.
    pub fn type_name(&self) -> &'static str {
        match self {
            Self::Geostatic { .. } => "geostatic",
            Self::Hydrostatic { .. } => "hydrostatic",
        }
    }

    /// The level depths are measured from, if given.
    pub fn surface(&self) -> Option<f64> {
        match *self {
            Self::Geostatic { surface, .. } | Self::Hydrostatic { surface } => surface,
        }
    }
}

fn default_particles_per_cell() -> u32 {
    2
}

/// The region a body occupies; coordinates in metres, boundaries included.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum BodyShape {
    /// An axis-aligned box `[lo, hi]` (2D or 3D).
    Box {
        /// Lower corner.
        lo: Vec<f64>,
        /// Upper corner (greater than `lo` along every axis).
        hi: Vec<f64>,
    },
    /// A disk (2D).
    Disk {
        /// Centre.
        #[serde(alias = "center")]
        centre: Vec<f64>,
        /// Radius, positive.
        radius: f64,
    },
    /// A simple or self-intersecting polygon (2D); a point is inside where the winding number
    /// is non-zero.
    Polygon {
        /// At least three `[x, y]` vertices, in either orientation; the last connects to the
        /// first.
        vertices: Vec<Vec<f64>>,
    },
    /// A ball (3D).
    Sphere {
        /// Centre.
        #[serde(alias = "center")]
        centre: Vec<f64>,
        /// Radius, positive.
        radius: f64,
    },
    /// A finite circular cylinder (3D), centred on `centre`, of the given `length` along
    /// `axis`.
    Cylinder {
        /// Centre (the midpoint of the axis segment).
        #[serde(alias = "center")]
        centre: Vec<f64>,
        /// Direction of the axis (any non-zero length).
        axis: Vec<f64>,
        /// Radius, positive.
        radius: f64,
        /// Length along the axis, positive.
        length: f64,
    },
}

/// `[boundaries]`: the wall on each face of the domain; a face left out is free.
///
/// A wall is written as its kind (`"fixed"`, `"slip"`, `"no_slip"`, `"free"`) or as a table
/// `{ kind = "slip", separable = true }`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoundarySpec {
    /// Face `x = lo[0]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x_min: Option<Wall>,
    /// Face `x = hi[0]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x_max: Option<Wall>,
    /// Face `y = lo[1]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub y_min: Option<Wall>,
    /// Face `y = hi[1]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub y_max: Option<Wall>,
    /// Face `z = lo[2]` (3D only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub z_min: Option<Wall>,
    /// Face `z = hi[2]` (3D only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub z_max: Option<Wall>,
}

impl BoundarySpec {
    /// The faces as `(name, axis, side, wall)`, `side` 0 for the lower face and 1 for the
    /// upper one, in the order x_min, x_max, y_min, y_max, z_min, z_max.
    pub fn faces(&self) -> [(&'static str, usize, usize, Option<Wall>); 6] {
        [
            ("x_min", 0, 0, self.x_min),
            ("x_max", 0, 1, self.x_max),
            ("y_min", 1, 0, self.y_min),
            ("y_max", 1, 1, self.y_max),
            ("z_min", 2, 0, self.z_min),
            ("z_max", 2, 1, self.z_max),
        ]
    }
}

/// `[pore_fluid]`: the pore water of a saturated soil, for a coupled (u–p) implicit run.
///
/// Pore pressures are positive in compression (a water pressure, Pa) and the `stress` of the
/// particles is then the effective stress `σ′` (tension positive, as every stress in loam);
/// the total stress is `σ′ − α p I`. The pore pressure is the hydrostatic pressure below the
/// `water_table` plus an excess, which drains through the `drained` faces (every other face
/// and the soil's free surface are impermeable). Each material a body uses needs a
/// `hydraulic_conductivity`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoreFluidSpec {
    /// Unit weight of water `γ_w` (N/m³), positive (default 9810).
    #[serde(default = "default_unit_weight")]
    pub unit_weight: f64,
    /// Bulk modulus of the water `K_w` (Pa), positive (default: incompressible); with it,
    /// each material needs a `porosity` (the storage is `n/K_w`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bulk_modulus: Option<f64>,
    /// Height of the water table on the last axis (m; `y` in 2D, `z` in 3D), inside the grid:
    /// hydrostatic pore pressure `γ_w (z_w − z)` below it, none above it (default: no
    /// hydrostatic pressure, the pore pressure is all excess).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub water_table: Option<f64>,
    /// The faces of the grid's box that drain: the excess pore pressure is zero on them
    /// (default none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub drained: Vec<Face>,
    /// The polynomial pressure projection that removes the pressure's node-to-node
    /// oscillation near the undrained limit (default `true`).
    #[serde(default = "default_stabilisation")]
    pub stabilisation: bool,
    /// How the materials' hydraulic conductivity follows their volume change (default
    /// `constant`).
    #[serde(default)]
    pub permeability: PermeabilityLaw,
    /// Prescribed flows of water into the soil through free surfaces (default none: the
    /// faces that do not drain are impermeable).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inflow: Vec<InflowSpec>,
    /// Free surfaces that drain and move with the soil (default none), beside the drained
    /// faces of the grid.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub drained_surface: Vec<SurfaceSpec>,
}

/// `[[pore_fluid.drained_surface]]`: a free surface of the soil that drains, found as for
/// `[[tractions]]` (among the particles in the box `lo..hi`, the outermost along the face's
/// normal in each column) and followed as the soil moves: the excess pore pressure falls to
/// zero across the half-width `ℓ_p` of each of its particles, which lets water out at the
/// rate `κ A_p p_e / ℓ_p`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurfaceSpec {
    /// The side of the grid the surface faces (its outward normal): `"y_max"` for the top of
    /// a 2D body.
    pub face: Face,
    /// Lower corner of the box that holds the surface's particles (m; default: the grid's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lo: Option<Vec<f64>>,
    /// Upper corner of the box that holds the surface's particles (m; default: the grid's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hi: Option<Vec<f64>>,
}

/// `[[pore_fluid.inflow]]`: a prescribed flux of water `q̄` (m/s: volume per area of surface
/// and per second) into the soil through the free surface that faces `face`, constant from
/// `t = 0` on; negative for an outflow (pumping).
///
/// The surface is found as for `[[tractions]]`: among the particles in the box `lo..hi`, the
/// outermost along the face's normal in each column. Each brings `q̄ A_p` (m³/s; m²/s in 2D)
/// into the nodes of its stencil, `A_p` its share of the surface.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InflowSpec {
    /// The side of the grid the surface faces (its outward normal): `"y_min"` for the base of
    /// a 2D body.
    pub face: Face,
    /// Lower corner of the box that holds the surface's particles (m; default: the grid's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lo: Option<Vec<f64>>,
    /// Upper corner of the box that holds the surface's particles (m; default: the grid's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hi: Option<Vec<f64>>,
    /// The flux `q̄` into the soil (m/s).
    pub rate: f64,
}

/// `pore_fluid.permeability`: the law of the hydraulic conductivity at large strain.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PermeabilityLaw {
    /// `k` constant.
    #[default]
    Constant,
    /// Kozeny–Carman, `k ∝ n³/(1 − n)²` with the porosity `n = 1 − (1 − n₀)/J`: `k` is the
    /// material's `hydraulic_conductivity` at its `porosity` `n₀` (at `F = I`).
    KozenyCarman,
}

fn default_unit_weight() -> f64 {
    9810.0
}

fn default_stabilisation() -> bool {
    true
}

/// A unit of time for the consolidation schedule and the output of a coupled run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeUnit {
    /// Seconds.
    #[default]
    S,
    /// Minutes.
    Min,
    /// Hours.
    H,
    /// Days.
    Day,
    /// Years of 365.25 days.
    Year,
}

impl TimeUnit {
    /// Seconds in one unit.
    pub fn seconds(self) -> f64 {
        match self {
            TimeUnit::S => 1.0,
            TimeUnit::Min => 60.0,
            TimeUnit::H => 3600.0,
            TimeUnit::Day => 86400.0,
            TimeUnit::Year => 365.25 * 86400.0,
        }
    }

    /// The name as written in a scene file (`"day"`).
    pub fn name(self) -> &'static str {
        match self {
            TimeUnit::S => "s",
            TimeUnit::Min => "min",
            TimeUnit::H => "h",
            TimeUnit::Day => "day",
            TimeUnit::Year => "year",
        }
    }
}

/// `[solver.consolidation]`: the time steps of a coupled run after its loading. The loads
/// reach their totals over `solver.load_steps` undrained steps at `t = 0`; the steps after
/// them hold the loads over the times `dt₀, dt₀ r, dt₀ r², …` until `end_time`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConsolidationSpec {
    /// The first time step `dt₀`, positive, in `time_unit`.
    pub time_step: f64,
    /// The factor `r ≥ 1` each step grows by (default 1, equal steps).
    #[serde(default = "default_growth")]
    pub growth: f64,
    /// When the run stops, positive, in `time_unit`.
    pub end_time: f64,
    /// The unit of `time_step`, `end_time` and of the times the run writes (default `"s"`).
    #[serde(default)]
    pub time_unit: TimeUnit,
    /// The time discretisation of the pore water's mass balance (default
    /// `"backward_euler"`).
    #[serde(default)]
    pub scheme: TimeScheme,
}

fn default_growth() -> f64 {
    1.0
}

/// `solver.consolidation.scheme`: how a coupled run integrates the pore water's mass
/// balance over a time step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeScheme {
    /// Backward Euler: first order, and what the adjoint (`loam gradient`, `loam invert`)
    /// differentiates.
    #[default]
    BackwardEuler,
    /// The two-step backward differentiation formula with variable steps: second order,
    /// L-stable, steps growing by at most 2 (a step after the undrained loading, or more than
    /// twice the one before it, takes backward Euler).
    Bdf2,
}

impl ConsolidationSpec {
    /// The number of time steps to `end_time`: `⌈ln(1 + (r − 1) T/dt₀) / ln r⌉` for a growth
    /// `r > 1`, `⌈T/dt₀⌉` for equal steps (the last step is shortened to end at `T`).
    pub fn steps(&self) -> f64 {
        let ratio = self.end_time / self.time_step;
        let steps = if self.growth > 1.0 {
            (1.0 + (self.growth - 1.0) * ratio).ln() / self.growth.ln()
        } else {
            ratio
        };
        // A step count that lands on `end_time` to round-off is not one more.
        (steps - 1e-9).ceil()
    }
}

/// `[loads]`: body forces.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadSpec {
    /// Gravitational acceleration (m/s²), one component per axis (default zero).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<Vec<f64>>,
}

/// Which solver runs the scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SolverKind {
    /// The explicit USL / MUSL loop: dynamics in time up to `end_time`.
    #[default]
    Explicit,
    /// Quasi-static implicit load stepping: the loads (gravity, point loads, prescribed
    /// displacements) are ramped linearly over `load_steps` steps, each solved for
    /// equilibrium by Newton's method.
    Implicit,
}

/// Where an explicit run takes its steps, written `device`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Device {
    /// The CPU solver (`loam-explicit`): every feature, f64.
    #[default]
    Cpu,
    /// The GPU solver (`loam-gpu`, wgpu): f32, the features it supports so far (a scene
    /// using another is refused when the run starts, naming the field).
    Gpu,
}

impl Device {
    /// The name written in the file (`"cpu"`, `"gpu"`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Cpu => "cpu",
            Self::Gpu => "gpu",
        }
    }
}

impl SolverKind {
    /// The name written in the file (`"explicit"`, `"implicit"`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Explicit => "explicit",
            Self::Implicit => "implicit",
        }
    }
}

/// `[solver]`: the solver family and its settings.
///
/// Which keys apply depends on `type`: `scheme`, `transfer`, `time_step`, `end_time` and
/// `device` are for the explicit solver (`time_step` and `end_time` required there); `load_steps`
/// (required), `newmark_dt`, `balance_initial_stress`, `newton` and `linear` for the implicit
/// one. A key of the other family is an
/// error. The absent optional settings take their defaults when the scene is built
/// ([`crate::SolverPlan`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    /// Solver family, written `type` (default `explicit`).
    #[serde(rename = "type", default)]
    pub kind: SolverKind,
    /// Explicit: update order within a step (default `musl`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scheme: Option<Scheme>,
    /// Explicit: particle–grid velocity transfer, `"pic"`, `"apic"` or a table such as
    /// `{ type = "flip", alpha = 0.95 }` (default `apic`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transfer: Option<Transfer>,
    /// Explicit (required): time-step control, `{ type = "fixed", dt = .. }` or
    /// `{ type = "adaptive", cfl = .., max_dt = .. }`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_step: Option<TimeStep>,
    /// Explicit (required): simulated time at which the run stops (s), positive.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end_time: Option<f64>,
    /// Explicit: where the steps run, `"cpu"` or `"gpu"` (default `cpu`); `loam run
    /// --device` overrides it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device: Option<Device>,
    /// Implicit (required): number of load steps over which the loads are ramped, `≥ 1`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load_steps: Option<usize>,
    /// Implicit, optional: run Newmark dynamics (β = ¼, γ = ½, consistent mass) with this time
    /// step (s); every load step is then a time step, loads act in full from the start and
    /// bodies may have an initial `velocity`. Omitted: quasi-static.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub newmark_dt: Option<f64>,
    /// Implicit, optional: balance the bodies' `initial_stress` against gravity on the grid
    /// with a force per particle, so that the initial state is an exact discrete equilibrium
    /// and a K0 state is kept through the first load step (default `false`;
    /// [`loam_implicit::balance`]). For ground under a level surface, where the initial stress
    /// is in equilibrium in the continuum and the out-of-balance is an error of the grid; under
    /// a slope it would hold up a real imbalance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub balance_initial_stress: Option<bool>,
    /// Implicit with a `[pore_fluid]`: the consolidation's time steps,
    /// `[solver.consolidation]` (default: none, the run is the undrained loading alone).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub consolidation: Option<ConsolidationSpec>,
    /// Implicit: Newton settings, `[solver.newton]` (default [`NewtonSpec::default`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub newton: Option<NewtonSpec>,
    /// Implicit: the linear solver of the Newton corrections, `[solver.linear]` or a bare
    /// name such as `"lu"` (default `lu`).
    #[serde(
        default,
        deserialize_with = "forms::linear",
        skip_serializing_if = "Option::is_none"
    )]
    pub linear: Option<LinearSpec>,
}

/// `[solver.newton]`: convergence and robustness settings of the implicit solver's Newton
/// iteration; every key is optional.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NewtonSpec {
    /// Converged when `‖R‖ ≤ residual_tol · max(‖R₀‖, ‖f_ext‖)`; in (0, 1) (default 1e-8).
    #[serde(default = "default_residual_tol")]
    pub residual_tol: f64,
    /// …or when the Newton correction `‖δ‖_∞ ≤ increment_tol · h`; positive (default
    /// 1e-10).
    #[serde(default = "default_increment_tol")]
    pub increment_tol: f64,
    /// Newton iterations per attempt, `≥ 1` (default 25).
    #[serde(default = "default_newton_iterations")]
    pub max_iterations: usize,
    /// Backtracking line search on the Newton step (default `true`).
    #[serde(default = "default_line_search")]
    pub line_search: bool,
    /// How often a failed load step may be cut in half before the run stops, `≥ 0`
    /// (default 6).
    #[serde(default = "default_max_cuts")]
    pub max_cuts: usize,
    /// Tangent assembly (default `local`).
    #[serde(default)]
    pub tangent: TangentMethod,
}

fn default_residual_tol() -> f64 {
    1e-8
}

fn default_increment_tol() -> f64 {
    1e-10
}

fn default_newton_iterations() -> usize {
    25
}

fn default_line_search() -> bool {
    true
}

fn default_max_cuts() -> usize {
    6
}

impl Default for NewtonSpec {
    fn default() -> Self {
        Self {
            residual_tol: default_residual_tol(),
            increment_tol: default_increment_tol(),
            max_iterations: default_newton_iterations(),
            line_search: default_line_search(),
            max_cuts: default_max_cuts(),
            tangent: TangentMethod::default(),
        }
    }
}

/// `[solver.linear]`: the linear solver of the Newton corrections.
///
/// `preconditioner`, `rel_tol` and `max_iterations` belong to the iterative solvers (`cg`,
/// `bicgstab`, `gmres`) and are errors on the direct ones; [`LinearSpec::solver`] fills in their
/// defaults.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinearSpec {
    /// The method, written `type`.
    #[serde(rename = "type")]
    pub kind: LinearKind,
    /// Iterative solvers: the preconditioner (default `ilu0`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preconditioner: Option<Preconditioner>,
    /// Iterative solvers: stop when `‖b − A x‖ < rel_tol ‖b‖`; in (0, 1) (default 1e-10).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rel_tol: Option<f64>,
    /// Iterative solvers: iteration limit, `≥ 1` (default 1000).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_iterations: Option<usize>,
}

/// The linear solver methods.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LinearKind {
    /// Sparse LU with partial pivoting (direct; any non-singular matrix).
    #[default]
    Lu,
    /// Sparse Cholesky (direct; symmetric positive definite matrices only).
    Cholesky,
    /// Preconditioned conjugate gradient (iterative; symmetric positive definite only).
    Cg,
    /// Preconditioned BiCGSTAB (iterative; any non-singular matrix).
    Bicgstab,
    /// Restarted right-preconditioned GMRES (iterative; any non-singular matrix).
    Gmres,
}

impl LinearKind {
    /// Whether the method is iterative (takes a preconditioner and a tolerance).
    pub fn is_iterative(self) -> bool {
        matches!(self, Self::Cg | Self::Bicgstab | Self::Gmres)
    }
}

/// Default relative tolerance of the iterative linear solvers.
pub(crate) const DEFAULT_LINEAR_REL_TOL: f64 = 1e-10;
/// Default iteration limit of the iterative linear solvers.
pub(crate) const DEFAULT_LINEAR_MAX_ITERATIONS: usize = 1000;

/// `[[constraints]]` (implicit solver): prescribed displacements, or forces on rigid groups,
/// of the grid nodes in a box.
///
/// Every grid node `x` with `lo − ε ≤ x ≤ hi + ε` (per axis, `ε = 1e-9 h`) gets, for each
/// component of `displacement` written as a number, that total displacement (m), reached
/// linearly over the load steps (or following the consolidation schedule's load). A
/// component of `force` written as a number makes the nodes' components in the box move as
/// one rigid group along that axis (a loading plate, a rigid footing) under that total
/// force (N; N per metre run in 2D), reached the same way. A component written `"free"` (or
/// left out with the whole key) is left to the solver. Where displacement boxes overlap the
/// later constraint wins, component by component.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConstraintSpec {
    /// Lower corner of the box (m).
    pub lo: Vec<f64>,
    /// Upper corner of the box (m), `≥ lo` on every axis (equal for a plane or a point).
    pub hi: Vec<f64>,
    /// Per component, the total displacement (m) or `"free"` (`None`); empty when the key
    /// is absent. With `force`, at least one number, and no component a number in both.
    #[serde(
        default,
        with = "forms::displacement",
        skip_serializing_if = "Vec::is_empty"
    )]
    pub displacement: Vec<Option<f64>>,
    /// Per component, the total force on the rigid group (N; N per metre run in 2D) or
    /// `"free"`; empty when the key is absent.
    #[serde(
        default,
        with = "forms::displacement",
        skip_serializing_if = "Vec::is_empty"
    )]
    pub force: Vec<Option<f64>>,
}

/// `[[point_loads]]` (implicit solver): a total force shared equally by the `count`
/// particles nearest a point (ties broken by the lower particle id), reached linearly over
/// the load steps.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointLoadSpec {
    /// The point (m), inside the domain.
    pub at: Vec<f64>,
    /// How many particles share the force, `≥ 1` (default 1).
    #[serde(default = "default_point_load_count")]
    pub count: usize,
    /// Total force (N; N per metre of depth in 2D), one component per axis.
    pub force: Vec<f64>,
}

fn default_point_load_count() -> usize {
    1
}

/// `[[tractions]]` (implicit solver): a distributed load `t` (Pa: force per area of the
/// surface, per metre of depth in 2D) on the free surface of the bodies that faces `face`.
///
/// The loaded particles are, among those inside the box `lo..hi` (default: the grid's
/// domain), the outermost along the face's normal in each column of particles (particles
/// with the same coordinates across the normal): the top layer of a body under `face =
/// "y_max"`, whatever the surface's height. Each carries `t A_p`, with `A_p` its share of the
/// surface, `∏_{a ≠ n} 2 h_a` (`h` the particle's half-width), as a point load: a dead load,
/// reached like the point loads (over the load steps, or in the first step of a
/// consolidation) and fixed in direction and magnitude as the surface moves.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TractionSpec {
    /// The side of the grid the loaded surface faces (its outward normal): `"y_max"` for a
    /// top surface in 2D, `"z_max"` in 3D.
    pub face: Face,
    /// Lower corner of the box that holds the loaded particles (m; default: the grid's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lo: Option<Vec<f64>>,
    /// Upper corner of the box that holds the loaded particles (m; default: the grid's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hi: Option<Vec<f64>>,
    /// The traction `t` (Pa), one component per axis: `[0, -q]` for a downward pressure `q`
    /// on a top surface in 2D.
    pub traction: Vec<f64>,
}

/// `[[probes]]` (implicit solver): the material point nearest a point, whose settlement,
/// displacement, effective stress invariants and (coupled runs) pore pressures the run
/// records after every step: a settlement plate or a piezometer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeSpec {
    /// The probe's name in the summary, the CSV and the plots (default `probe_<index>`);
    /// unique.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The point (m), inside the domain: the particle nearest it (by initial position, ties
    /// to the lower id) is followed.
    pub at: Vec<f64>,
}

/// A face of the domain, named as in `[boundaries]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Face {
    /// `x = lo[0]`.
    XMin,
    /// `x = hi[0]`.
    XMax,
    /// `y = lo[1]`.
    YMin,
    /// `y = hi[1]`.
    YMax,
    /// `z = lo[2]` (3D only).
    ZMin,
    /// `z = hi[2]` (3D only).
    ZMax,
}

impl Face {
    /// The axis the face is normal to and its side (0 lower, 1 upper).
    pub fn axis_side(self) -> (usize, usize) {
        match self {
            Self::XMin => (0, 0),
            Self::XMax => (0, 1),
            Self::YMin => (1, 0),
            Self::YMax => (1, 1),
            Self::ZMin => (2, 0),
            Self::ZMax => (2, 1),
        }
    }

    /// The name written in the file (`"y_min"`, ...).
    pub fn name(self) -> &'static str {
        ["x_min", "x_max", "y_min", "y_max", "z_min", "z_max"][self as usize]
    }
}

/// `[[friction]]` (explicit solver): a Coulomb friction segment on a wall.
///
/// The segment covers the part of the face `wall` between `from` and `to`, written in the
/// face's tangential coordinates (the coordinates of the other axes in x, y, z order: one
/// number in 2D, two in 3D; e.g. `[x, z]` on `y_min`), or the whole face when both are left
/// out. The face must be declared a unilateral slip wall in `[boundaries]`
/// (`{ kind = "slip", separable = true }`); segments of one face must not overlap (they may
/// touch: a node on the shared edge takes the segment listed first).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionSpec {
    /// The face.
    pub wall: Face,
    /// Coulomb coefficient `μ ≥ 0`.
    pub mu: f64,
    /// Start of the segment along the face (m), `D − 1` coordinates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from: Option<Vec<f64>>,
    /// End of the segment along the face (m), `D − 1` coordinates, greater than `from`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub to: Option<Vec<f64>>,
}

/// The shape of an obstacle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ObstacleKind {
    /// An axis-aligned box (`lo`, `hi`).
    Box,
    /// A circular cylinder (`centre`, `radius`; in 3D also `axis` and `length`); in 2D a
    /// disk (an infinitely long cylinder, plane strain).
    Cylinder,
}

/// A coordinate axis, written `"x"`, `"y"` or `"z"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisName {
    /// The x axis.
    X,
    /// The y axis.
    Y,
    /// The z axis.
    Z,
}

/// `[[obstacles]]` (explicit solver): a rigid obstacle, static or moving with a constant
/// velocity, with Coulomb friction against the material.
///
/// Which keys apply depends on `shape`: `"box"` takes `lo` and `hi`; `"cylinder"` takes
/// `centre` and `radius`, and in 3D `axis` and `length` (a cylinder of that length along the
/// coordinate axis, centred on `centre`). A key of the other shape is an error. Particles of
/// the bodies that fall strictly inside an obstacle at `t = 0` are not generated.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleSpec {
    /// `"box"` or `"cylinder"`.
    pub shape: ObstacleKind,
    /// Box: lower corner (m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lo: Option<Vec<f64>>,
    /// Box: upper corner (m), greater than `lo` on every axis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hi: Option<Vec<f64>>,
    /// Cylinder: the centre (m) (in 3D the middle of the axis).
    #[serde(default, alias = "center", skip_serializing_if = "Option::is_none")]
    pub centre: Option<Vec<f64>>,
    /// Cylinder: radius (m), positive.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Cylinder, 3D: the coordinate axis the cylinder's axis is parallel to.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<AxisName>,
    /// Cylinder, 3D: length along the axis (m), positive.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<f64>,
    /// Constant velocity (m/s), one component per axis (default zero): the obstacle is at
    /// `x₀ + v t` at time `t`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<Vec<f64>>,
    /// Coulomb coefficient `μ ≥ 0` against the material (default 0, frictionless).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<f64>,
}

/// `[fos]`: the factor-of-safety search of `loam fos` (strength reduction over implicit runs
/// of the scene's gravity loading; see `loam_implicit::strength_reduction`). Every key is
/// optional.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FosSpec {
    /// The search stops when the bracket `[stable, failed]` of factors is at most this wide,
    /// positive (default 0.01); `loam fos --tolerance` overrides it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Factor of the first trial, positive (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<f64>,
    /// The most trials, `≥ 1` (default 30).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_trials: Option<usize>,
    /// A trial fails when a load step grows the largest particle displacement by more than
    /// this multiple of its growth in the first load step, above 1 (default 10: the secant
    /// stiffness of the step below a tenth of the elastic one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub growth_limit: Option<f64>,
    /// A trial also fails when the largest particle displacement exceeds this (m) after a
    /// converged load step, positive (default: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub displacement_limit: Option<f64>,
}

/// `[output]`: what to write and where.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Output folder (default `out/<scene file stem>`, relative to the working directory).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dir: Option<PathBuf>,
    /// Number of frames written after the initial one (at least 1; default 20): at equal
    /// intervals of simulated time up to `end_time` (explicit), or after the load steps
    /// `round(k · load_steps / frames)`, `k = 1..=frames`, repeats dropped (implicit).
    #[serde(default = "default_frames")]
    pub frames: usize,
    /// Particle fields written to each frame (default: all of them).
    #[serde(default = "default_fields")]
    pub fields: Vec<Field>,
}

fn default_frames() -> usize {
    20
}

fn default_fields() -> Vec<Field> {
    Field::ALL.to_vec()
}

impl Default for OutputSpec {
    fn default() -> Self {
        Self {
            dir: None,
            frames: default_frames(),
            fields: default_fields(),
        }
    }
}
