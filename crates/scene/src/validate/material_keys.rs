//! The material keys of a scene file, declared once: which models take each key, whether it
//! is required, its unit and its admissible range. The checks of a material's keys ("required
//! for model …", "only used by …", "must be positive …") and the table in
//! `docs/scene-format.md` come from this declaration; a new model adds its keys here and its
//! cross-key rules (ψ ≤ φ, κ < λ, …) in [`super::check_material`].

use super::Checker;
use crate::schema::MaterialSpec;
use loam_core::ModelKind;
use loam_core::ModelKind as K;

/// Whether a model needs a key.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Need {
    /// The model cannot be built without it.
    Required,
    /// The model has a default, or the key is one of a pair (see [`ONE_OF`]).
    Optional,
}

/// The admissible values of a numeric key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Range {
    /// `x > 0`.
    Positive,
    /// `x ≥ 0`.
    NonNegative,
    /// `x ≥ lo`.
    AtLeast(f64),
    /// `lo < x < hi`.
    Open(f64, f64),
}

impl Range {
    /// Records an issue under `path` when `x` is not finite or not in the range; whether it is.
    pub(crate) fn check(self, c: &mut Checker, path: &str, x: f64, unit: &str) -> bool {
        if !c.finite(path, x) {
            return false;
        }
        let (ok, expected) = match self {
            Self::Positive => (x > 0.0, "must be positive".to_owned()),
            Self::NonNegative => (x >= 0.0, "must be zero or positive".to_owned()),
            Self::AtLeast(lo) => (x >= lo, format!("must be at least {lo}")),
            Self::Open(lo, hi) => (x > lo && x < hi, format!("must be in ({lo}, {hi}){unit}")),
        };
        if !ok {
            c.issue(path, format!("{expected}, got {x}"));
        }
        ok
    }
}

/// One material key.
pub(crate) struct MaterialKey {
    /// The key as written in the file.
    pub name: &'static str,
    /// What it is, with its unit, for "required" messages.
    pub what: &'static str,
    /// The models that take it and whether each needs it.
    pub models: &'static [(ModelKind, Need)],
    /// The admissible range of a numeric key (`None`: an enumeration, checked by serde).
    pub range: Option<Range>,
    /// Its unit as the range message writes it after an interval (`" degrees"`) or `""`.
    pub unit: &'static str,
    /// The value in a material entry (`Some(NaN)`-free: `None` when absent; enumerations give
    /// `Some(0.0)` when present).
    pub value: fn(&MaterialSpec) -> Option<f64>,
}

impl MaterialKey {
    /// How `model` needs this key (`None`: it does not take it).
    pub(crate) fn need(&self, model: ModelKind) -> Option<Need> {
        self.models
            .iter()
            .find(|(m, _)| *m == model)
            .map(|(_, n)| *n)
    }

    /// "only used by model(s) …" for a key on a model that does not take it: the models by
    /// name when there are at most three, else "not used by model \"x\"".
    fn misplaced(&self, model: ModelKind) -> String {
        let names: Vec<String> = (self.models.iter())
            .map(|(m, _)| format!("\"{}\"", m.name()))
            .collect();
        let used_by = match names.as_slice() {
            [one] => format!("only used by model {one}"),
            [a, b] => format!("only used by models {a} and {b}"),
            [a, b, c] => format!("only used by models {a}, {b} and {c}"),
            _ => format!("not used by model \"{}\"", model.name()),
        };
        format!("{used_by}; remove it or change the model")
    }
}

use Need::{Optional, Required};

/// `E`: required by the solid models with an elastic law in `E` and `ν`.
const YOUNG_MODELS: [(ModelKind, Need); 6] = [
    (K::LinearElastic, Required),
    (K::NeoHookean, Required),
    (K::Hencky, Required),
    (K::J2, Required),
    (K::DruckerPrager, Required),
    (K::MohrCoulomb, Required),
];
/// `ν`: the same, and one way of giving Modified Cam-Clay's shear stiffness.
const POISSON_MODELS: [(ModelKind, Need); 7] = [
    (K::LinearElastic, Required),
    (K::NeoHookean, Required),
    (K::Hencky, Required),
    (K::J2, Required),
    (K::DruckerPrager, Required),
    (K::MohrCoulomb, Required),
    (K::ModifiedCamClay, Optional),
];
const FRICTIONAL: [(ModelKind, Need); 2] =
    [(K::DruckerPrager, Required), (K::MohrCoulomb, Required)];
const FRICTIONAL_OPTIONAL: [(ModelKind, Need); 2] =
    [(K::DruckerPrager, Optional), (K::MohrCoulomb, Optional)];
const CAM_CLAY: [(ModelKind, Need); 1] = [(K::ModifiedCamClay, Required)];
const CAM_CLAY_OPTIONAL: [(ModelKind, Need); 1] = [(K::ModifiedCamClay, Optional)];
const FLUID_OPTIONAL: [(ModelKind, Need); 1] = [(K::Fluid, Optional)];
const DRUCKER_PRAGER_OPTIONAL: [(ModelKind, Need); 1] = [(K::DruckerPrager, Optional)];

/// Every material key but `name`, `model` and `density` (which every material has).
pub(crate) const MATERIAL_KEYS: &[MaterialKey] = &[
    MaterialKey {
        name: "youngs_modulus",
        what: "Young's modulus, Pa",
        models: &YOUNG_MODELS,
        range: Some(Range::Positive),
        unit: "",
        value: |m| m.youngs_modulus,
    },
    MaterialKey {
        name: "poisson_ratio",
        what: "Poisson's ratio",
        models: &POISSON_MODELS,
        range: Some(Range::Open(-1.0, 0.5)),
        unit: "",
        value: |m| m.poisson_ratio,
    },
    MaterialKey {
        name: "yield_stress",
        what: "the uniaxial yield stress, Pa",
        models: &[(K::J2, Required)],
        range: Some(Range::Positive),
        unit: "",
        value: |m| m.yield_stress,
    },
    MaterialKey {
        name: "hardening",
        what: "the linear hardening modulus, Pa",
        models: &[(K::J2, Optional)],
        range: Some(Range::NonNegative),
        unit: "",
        value: |m| m.hardening,
    },
    MaterialKey {
        name: "sound_speed",
        what: "the reference sound speed, m/s",
        models: &FLUID_OPTIONAL,
        range: Some(Range::Positive),
        unit: "",
        value: |m| m.sound_speed,
    },
    MaterialKey {
        name: "bulk_modulus",
        what: "the bulk modulus, Pa",
        models: &FLUID_OPTIONAL,
        range: Some(Range::Positive),
        unit: "",
        value: |m| m.bulk_modulus,
    },
    MaterialKey {
        name: "gamma",
        what: "the Tait exponent",
        models: &FLUID_OPTIONAL,
        range: Some(Range::AtLeast(1.0)),
        unit: "",
        value: |m| m.gamma,
    },
    MaterialKey {
        name: "viscosity",
        what: "the dynamic viscosity, Pa·s",
        models: &FLUID_OPTIONAL,
        range: Some(Range::NonNegative),
        unit: "",
        value: |m| m.viscosity,
    },
    MaterialKey {
        name: "friction_angle",
        what: "the friction angle φ in degrees, 0 < φ < 90",
        models: &FRICTIONAL,
        range: Some(Range::Open(0.0, 90.0)),
        unit: " degrees",
        value: |m| m.friction_angle,
    },
    MaterialKey {
        name: "dilation_angle",
        what: "the dilation angle ψ in degrees, 0 ≤ ψ ≤ φ",
        models: &FRICTIONAL_OPTIONAL,
        range: None,
        unit: " degrees",
        value: |m| m.dilation_angle,
    },
    MaterialKey {
        name: "cohesion",
        what: "the cohesion c, Pa",
        models: &FRICTIONAL_OPTIONAL,
        range: Some(Range::NonNegative),
        unit: "",
        value: |m| m.cohesion,
    },
    MaterialKey {
        name: "tension_cutoff",
        what: "the tension cutoff, Pa (drucker_prager: on the mean stress; mohr_coulomb: on \
               every principal stress)",
        models: &FRICTIONAL_OPTIONAL,
        range: None,
        unit: "",
        value: |m| m.tension_cutoff,
    },
    MaterialKey {
        name: "cone",
        what: "the Mohr–Coulomb section the cone matches",
        models: &DRUCKER_PRAGER_OPTIONAL,
        range: None,
        unit: "",
        value: |m| m.cone.map(|_| 0.0),
    },
    MaterialKey {
        name: "elasticity",
        what: "the elastic law, hencky or jaumann",
        models: &DRUCKER_PRAGER_OPTIONAL,
        range: None,
        unit: "",
        value: |m| m.elasticity.map(|_| 0.0),
    },
    MaterialKey {
        name: "lambda",
        what: "the slope λ of the normal compression line in e–ln p′",
        models: &CAM_CLAY,
        range: Some(Range::Positive),
        unit: "",
        value: |m| m.lambda,
    },
    MaterialKey {
        name: "kappa",
        what: "the slope κ of the unloading–reloading line in e–ln p′, 0 < κ < λ",
        models: &CAM_CLAY,
        range: Some(Range::Positive),
        unit: "",
        value: |m| m.kappa,
    },
    MaterialKey {
        name: "critical_state_slope",
        what: "the slope M of the critical state line in p′–q",
        models: &CAM_CLAY,
        range: Some(Range::Positive),
        unit: "",
        value: |m| m.critical_state_slope,
    },
    MaterialKey {
        name: "void_ratio",
        what: "the initial void ratio e₀",
        models: &CAM_CLAY,
        range: Some(Range::Positive),
        unit: "",
        value: |m| m.void_ratio,
    },
    MaterialKey {
        name: "shear_modulus",
        what: "a constant shear modulus G, Pa",
        models: &CAM_CLAY_OPTIONAL,
        range: Some(Range::Positive),
        unit: "",
        value: |m| m.shear_modulus,
    },
    MaterialKey {
        name: "preconsolidation_pressure",
        what: "the initial preconsolidation pressure p′c0, Pa",
        models: &CAM_CLAY_OPTIONAL,
        range: Some(Range::Positive),
        unit: "",
        value: |m| m.preconsolidation_pressure,
    },
    MaterialKey {
        name: "ocr",
        what: "the overconsolidation ratio on the yield locus, ≥ 1",
        models: &CAM_CLAY_OPTIONAL,
        range: Some(Range::AtLeast(1.0)),
        unit: "",
        value: |m| m.ocr,
    },
];

/// Pairs of keys of which a model needs exactly one: `(model, first, second, what)`.
pub(crate) const ONE_OF: &[(ModelKind, &str, &str, &str)] = &[
    (
        K::Fluid,
        "sound_speed",
        "bulk_modulus",
        "the reference sound speed, m/s), unless bulk_modulus (Pa) is given instead",
    ),
    (
        K::ModifiedCamClay,
        "poisson_ratio",
        "shear_modulus",
        "Poisson's ratio), unless shear_modulus (Pa) is given instead",
    ),
    (
        K::ModifiedCamClay,
        "ocr",
        "preconsolidation_pressure",
        "the overconsolidation ratio, ≥ 1), unless preconsolidation_pressure (Pa) is given \
         instead",
    ),
];

/// The key named `name`.
fn key(name: &str) -> &'static MaterialKey {
    MATERIAL_KEYS
        .iter()
        .find(|k| k.name == name)
        .expect("ONE_OF names declared keys")
}

/// Checks which keys a material's model takes and the range of each given key: "required for
/// model …", "only used by …", "give either … or …, not both", "must be …". Returns the keys
/// whose values are in range (cross-key rules only look at those).
pub(crate) fn check_keys(c: &mut Checker, path: &str, m: &MaterialSpec) -> Vec<&'static str> {
    let model = m.model;
    let mut sound = Vec::new();
    for key in MATERIAL_KEYS {
        let kpath = format!("{path}.{}", key.name);
        let value = (key.value)(m);
        match (key.need(model), value) {
            (None, Some(_)) => c.issue(kpath, key.misplaced(model)),
            (Some(Need::Required), None) => c.issue(
                kpath,
                format!("required for model \"{}\" ({})", model.name(), key.what),
            ),
            (Some(_), Some(x)) if key.range.is_none_or(|r| r.check(c, &kpath, x, key.unit)) => {
                sound.push(key.name);
            }
            _ => {}
        }
    }
    for &(owner, first, second, what) in ONE_OF.iter().filter(|o| o.0 == model) {
        match ((key(first).value)(m), (key(second).value)(m)) {
            (None, None) => c.issue(
                format!("{path}.{first}"),
                format!("required for model \"{}\" ({what}", owner.name()),
            ),
            (Some(_), Some(_)) => c.issue(
                format!("{path}.{second}"),
                format!(
                    "give either {first} or {second} for model \"{}\", not both",
                    owner.name()
                ),
            ),
            _ => {}
        }
    }
    sound
}
