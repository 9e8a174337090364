//! Element-test files (`loam material FILE`): one material point driven through laboratory
//! paths by [`loam_implicit::element`].
//!
//! A TOML (or JSON) file with a `[material]` table (the keys of a scene's `[[materials]]`
//! entry), an `[initial]` state and one or more `[[stages]]`:
//!
//! ```toml
//! [material]
//! name = "dense sand"
//! model = "drucker_prager"
//! density = 2000.0
//! youngs_modulus = 25.0e6
//! poisson_ratio = 0.3
//! friction_angle = 35.0
//! dilation_angle = 5.0
//! cone = "compression"
//!
//! [initial]
//! p = 150.0e3        # mean effective stress p′₀, Pa, compression positive
//!
//! [[stages]]
//! type = "drained_triaxial"
//! axial_strain = 0.10
//! ```
//!
//! **Conventions** (soil mechanics'): stresses and strains in the file are compression
//! positive; the axial direction is `z`. The initial state is `σ′_v = 3p′₀/(1 + 2K0)` along
//! `z` and `K0 σ′_v` across it. A stage's `axial_strain` (or `shear_strain`) is its change of
//! `ε_a = 1 − F_zz` (of `γ = F_xz`), measured on the length at the start of the test.

use crate::error::{Issue, SceneError, SceneFormat};
use crate::schema::MaterialSpec;
use crate::validate::material_issues;
use loam_core::constitutive::{Elasticity, Material};
use loam_implicit::element::{LabStage, Loading, PointState, Stage};
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// An element-test file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ElementTest {
    /// The material, with the keys of a scene's `[[materials]]` entry. A `drucker_prager`
    /// material is Hencky unless it names `elasticity = "jaumann"`.
    pub material: MaterialSpec,
    /// The state the test starts from.
    pub initial: InitialPoint,
    /// The path, stage after stage.
    pub stages: Vec<StageSpec>,
    /// Where the CSV and the plots go (default `out/<file stem>`; `--out` overrides it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_dir: Option<PathBuf>,
}

/// The initial effective stress of the point, compression positive.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialPoint {
    /// Mean effective stress `p′₀` (Pa), `≥ 0`.
    pub p: f64,
    /// `K0 = σ′_h/σ′_v`, positive (default 1: isotropic).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k0: Option<f64>,
    /// Initial void ratio `e₀`, positive: the output then has the void ratio
    /// `e = (1 + e₀) det F − 1` and an `e`–log `p′` plot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub void_ratio: Option<f64>,
}

/// Default increments per stage.
pub const DEFAULT_INCREMENTS: usize = 100;

/// The most increments a stage may ask for.
pub const MAX_INCREMENTS: usize = 1_000_000;

/// One stage of an element test (`type = "…"`); strains compression positive.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum StageSpec {
    /// Axial strain at constant radial stress (drained triaxial compression; extension with a
    /// negative `axial_strain`).
    DrainedTriaxial {
        /// Change of the axial strain over the stage.
        axial_strain: f64,
        /// Increments (default 100).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        increments: Option<usize>,
    },
    /// Axial strain at constant volume (undrained triaxial compression or extension of a
    /// saturated sample with incompressible grains and water: the stresses are effective).
    UndrainedTriaxial {
        /// Change of the axial strain over the stage.
        axial_strain: f64,
        /// Increments (default 100).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        increments: Option<usize>,
    },
    /// Axial strain with no lateral strain (oedometer loading, unloading with a negative
    /// `axial_strain`).
    Oedometer {
        /// Change of the axial strain over the stage.
        axial_strain: f64,
        /// Increments (default 100).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        increments: Option<usize>,
    },
    /// All three normal stresses to `p` (isotropic compression or unloading).
    Isotropic {
        /// The mean effective stress at the end of the stage (Pa, compression positive).
        p: f64,
        /// Increments (default 100).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        increments: Option<usize>,
    },
    /// Simple shear in the `x`–`z` plane: `F_xz` grows by `shear_strain`; the height is kept
    /// (constant-volume simple shear) unless `vertical_stress` is given, which is then held.
    SimpleShear {
        /// Change of `γ = F_xz` over the stage.
        shear_strain: f64,
        /// The vertical effective stress held during the stage (Pa, compression positive).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        vertical_stress: Option<f64>,
        /// Increments (default 100).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        increments: Option<usize>,
    },
}

impl StageSpec {
    /// The `type` name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::DrainedTriaxial { .. } => "drained_triaxial",
            Self::UndrainedTriaxial { .. } => "undrained_triaxial",
            Self::Oedometer { .. } => "oedometer",
            Self::Isotropic { .. } => "isotropic",
            Self::SimpleShear { .. } => "simple_shear",
        }
    }

    fn increments(&self) -> Option<usize> {
        match *self {
            Self::DrainedTriaxial { increments, .. }
            | Self::UndrainedTriaxial { increments, .. }
            | Self::Oedometer { increments, .. }
            | Self::Isotropic { increments, .. }
            | Self::SimpleShear { increments, .. } => increments,
        }
    }

    /// The stage as the driver takes it: its [`Loading`] and increments (default
    /// [`DEFAULT_INCREMENTS`]).
    pub fn lab_stage(&self) -> LabStage {
        let loading = match *self {
            Self::DrainedTriaxial { axial_strain, .. } => Loading::DrainedTriaxial { axial_strain },
            Self::UndrainedTriaxial { axial_strain, .. } => {
                Loading::UndrainedTriaxial { axial_strain }
            }
            Self::Oedometer { axial_strain, .. } => Loading::Oedometer { axial_strain },
            Self::Isotropic { p, .. } => Loading::Isotropic { p },
            Self::SimpleShear {
                shear_strain,
                vertical_stress,
                ..
            } => Loading::SimpleShear {
                shear_strain,
                vertical_stress,
            },
        };
        LabStage {
            loading,
            increments: self.increments().unwrap_or(DEFAULT_INCREMENTS),
        }
    }

    /// The driver's stage from the state at its start (`F` and stress of the previous stage's
    /// end): [`Loading::stage`].
    pub fn stage(&self, f: &Matrix3<f64>, stress: &Matrix3<f64>) -> Stage {
        let s = self.lab_stage();
        s.loading.stage(f, stress, s.increments)
    }
}

impl ElementTest {
    /// Reads, parses and validates an element-test file (`.toml` or `.json`); every problem
    /// names its field.
    pub fn from_path(path: impl AsRef<Path>) -> Result<Self, SceneError> {
        let path = path.as_ref();
        let format = SceneFormat::from_path(path).ok_or_else(|| SceneError::Extension {
            path: path.to_path_buf(),
        })?;
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_str_in(&text, format).map_err(|e| e.in_file(path))
    }

    /// Parses and validates an element test written in `format`.
    pub fn from_str_in(text: &str, format: SceneFormat) -> Result<Self, SceneError> {
        let test: Self = crate::load::parse(text, format)?;
        let issues = test.issues();
        if issues.is_empty() {
            Ok(test)
        } else {
            Err(SceneError::invalid(issues))
        }
    }

    /// The problems with the fields (empty when all are sound).
    pub fn issues(&self) -> Vec<Issue> {
        let mut issues = material_issues("material", &self.material);
        let mut issue = |path: String, message: String| issues.push(Issue::new(path, message));
        let ip = &self.initial;
        if !(ip.p.is_finite() && ip.p >= 0.0) {
            issue(
                "initial.p".into(),
                format!(
                    "must be zero or positive (Pa, compression positive), got {}",
                    ip.p
                ),
            );
        }
        if let Some(k0) = ip.k0
            && !(k0.is_finite() && k0 > 0.0)
        {
            issue("initial.k0".into(), format!("must be positive, got {k0}"));
        }
        if let Some(e0) = ip.void_ratio
            && !(e0.is_finite() && e0 > 0.0)
        {
            issue(
                "initial.void_ratio".into(),
                format!("must be positive, got {e0}"),
            );
        }
        let cam_clay = self.material.model == loam_core::ModelKind::ModifiedCamClay;
        if cam_clay && ip.p.is_finite() && ip.p <= 0.0 {
            issue(
                "initial.p".into(),
                "model \"modified_cam_clay\" has no stiffness at zero stress: give the \
                 initial mean effective stress p (Pa, positive)"
                    .into(),
            );
        }
        if let (Some(e0), Some(model_e0)) = (ip.void_ratio, self.material.void_ratio)
            && e0 != model_e0
        {
            issue(
                "initial.void_ratio".into(),
                format!(
                    "differs from material.void_ratio = {model_e0}, the model's e₀; give it \
                     once, in the material"
                ),
            );
        }
        if ip.p > 0.0 && stateless_model(&self.material) {
            issue(
                "initial.p".into(),
                format!(
                    "model \"{}\" carries no stress at F = I (its stress is a function of the \
                     deformation alone); start it from p = 0",
                    self.material.model.name()
                ),
            );
        }
        if self.stages.is_empty() {
            issue(
                "stages".into(),
                "an element test needs at least one stage".into(),
            );
        }
        for (i, stage) in self.stages.iter().enumerate() {
            let path = format!("stages[{i}]");
            if let Some(n) = stage.increments()
                && !(1..=MAX_INCREMENTS).contains(&n)
            {
                issue(
                    format!("{path}.increments"),
                    format!("must be in 1..={MAX_INCREMENTS}, got {n}"),
                );
            }
            let (key, value, limit) = match *stage {
                StageSpec::DrainedTriaxial { axial_strain, .. }
                | StageSpec::UndrainedTriaxial { axial_strain, .. }
                | StageSpec::Oedometer { axial_strain, .. } => ("axial_strain", axial_strain, 0.9),
                StageSpec::SimpleShear { shear_strain, .. } => ("shear_strain", shear_strain, 10.0),
                StageSpec::Isotropic { p, .. } => {
                    if !(p.is_finite() && p >= 0.0) {
                        issue(
                            format!("{path}.p"),
                            format!("must be zero or positive (Pa), got {p}"),
                        );
                    }
                    continue;
                }
            };
            if !(value.is_finite() && value.abs() < limit) {
                issue(
                    format!("{path}.{key}"),
                    format!("must be a finite strain of magnitude below {limit}, got {value}"),
                );
            }
            if let StageSpec::SimpleShear {
                vertical_stress: Some(sv),
                ..
            } = *stage
                && !(sv.is_finite() && sv >= 0.0)
            {
                issue(
                    format!("{path}.vertical_stress"),
                    format!("must be zero or positive (Pa), got {sv}"),
                );
            }
        }
        if issues.is_empty()
            && let loam_core::constitutive::Model::ModifiedCamClay(m) = self.material().model
        {
            let start = self.start(&self.material());
            let tau = start.stress;
            let p = -tau.trace() / 3.0;
            let q = crate::output::von_mises(&tau);
            let p_c = start.history.hardening;
            if m.yield_function(p, q, p_c) > 1e-9 * p_c * p_c {
                issues.push(Issue::new(
                    "material.preconsolidation_pressure",
                    format!(
                        "{p_c} Pa puts the initial state (p′ = {p} Pa, q = {q} Pa) outside the \
                         yield ellipse; raise it, or give ocr instead"
                    ),
                ));
            }
        }
        issues
    }

    /// The initial void ratio: `initial.void_ratio`, or the material's `e₀`
    /// (`modified_cam_clay`).
    pub fn void_ratio(&self) -> Option<f64> {
        self.initial.void_ratio.or(self.material.void_ratio)
    }

    /// The material (a `drucker_prager` one Hencky unless the file says otherwise).
    pub fn material(&self) -> Material<f64> {
        self.material.material(Elasticity::Hencky)
    }

    /// The initial Cauchy stress (Pa, tension positive): `σ′_v = 3p′₀/(1 + 2K0)` along `z`,
    /// `K0 σ′_v` across.
    pub fn initial_stress(&self) -> Matrix3<f64> {
        let k0 = self.initial.k0.unwrap_or(1.0);
        let sv = 3.0 * self.initial.p / (1.0 + 2.0 * k0);
        Matrix3::from_diagonal(&nalgebra::vector![-k0 * sv, -k0 * sv, -sv])
    }

    /// The state the test starts from: [`ElementTest::initial_stress`] carried by the model's
    /// history at `F = I` ([`PointState::at_rest`]).
    pub fn start(&self, material: &Material<f64>) -> PointState {
        PointState::at_rest(material, &self.initial_stress())
    }

    /// The stages as the driver takes them ([`StageSpec::lab_stage`]).
    pub fn stages(&self) -> Vec<LabStage> {
        self.stages.iter().map(StageSpec::lab_stage).collect()
    }
}

/// Whether the model's stress is a function of `F` alone (no prestressed state).
fn stateless_model(m: &MaterialSpec) -> bool {
    use loam_core::ModelKind as K;
    matches!(
        m.model,
        K::LinearElastic | K::NeoHookean | K::Hencky | K::Fluid
    )
}
