//! The constants of the constitutive models, declared once.
//!
//! Each [`Constant`] says which models take it and whether each needs it, its admissible
//! values in a scene file, and, when it is a parameter of `loam gradient` and `loam invert`,
//! its name there, its unit and its physical range ([`Gradient`]). The scene's validation
//! ("required for model …", "only used by …", "must be …"), the gradient's parameter names,
//! the units and ranges of an inversion's parameters and the write-back of a recovered value
//! into a scene all read this table: a new model adds its constants here, its cross-key rules
//! (ψ ≤ φ, κ < λ, …) to the scene's validation, and the seeding of each constant to
//! `loam_inverse::MaterialField`.

use super::ModelKind;
use super::ModelKind as K;

/// Whether a model needs a constant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Need {
    /// The model cannot be built without it.
    Required,
    /// The model has a default, or the constant is one of a pair (see [`ONE_OF`]).
    Optional,
}

/// The admissible values of a numeric constant in a scene file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Range {
    /// `x > 0`.
    Positive,
    /// `x ≥ 0`.
    NonNegative,
    /// `x ≥ lo`.
    AtLeast(f64),
    /// `lo < x < hi`.
    Open(f64, f64),
    /// `lo < x ≤ hi`.
    LeftOpen(f64, f64),
}

impl Range {
    /// `Ok` when the finite `x` is in the range, else what was expected ("must be positive,
    /// got -1"); `unit` is written after an interval (`" degrees"`).
    ///
    /// # Errors
    /// The message for a value outside the range.
    pub fn admit(self, x: f64, unit: &str) -> Result<(), String> {
        let (ok, expected) = match self {
            Self::Positive => (x > 0.0, "must be positive".to_owned()),
            Self::NonNegative => (x >= 0.0, "must be zero or positive".to_owned()),
            Self::AtLeast(lo) => (x >= lo, format!("must be at least {lo}")),
            Self::Open(lo, hi) => (x > lo && x < hi, format!("must be in ({lo}, {hi}){unit}")),
            Self::LeftOpen(lo, hi) => (x > lo && x <= hi, format!("must be in ({lo}, {hi}]{unit}")),
        };
        if ok {
            Ok(())
        } else {
            Err(format!("{expected}, got {x}"))
        }
    }
}

/// A constant as a parameter of `loam gradient` and `loam invert`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gradient {
    /// The name after `materials[k].` (or `material.` in an element test).
    pub name: &'static str,
    /// The unit of the parameter's value (`–` for a pure number).
    pub unit: &'static str,
    /// Whether the scene key is in degrees and the parameter in radians (an angle).
    pub degrees: bool,
    /// `[lo, hi]` in the parameter's unit and what the constant is, where physics bounds it: a
    /// value outside is a placeholder or a value in another unit.
    pub bounds: Option<(f64, f64, &'static str)>,
}

impl Gradient {
    /// The scene key's value for the parameter's value `v` (`v` in degrees for an angle).
    pub fn to_scene(&self, v: f64) -> f64 {
        if self.degrees { v.to_degrees() } else { v }
    }
}

/// One constant of a material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Constant {
    /// The key in a scene file's material entry.
    pub key: &'static str,
    /// What it is, with its unit, for "required" messages.
    pub what: &'static str,
    /// The models that take it and whether each needs it.
    pub models: &'static [(ModelKind, Need)],
    /// The admissible range of a numeric key (`None`: an enumeration, checked when the file
    /// is read, or a range that depends on other keys).
    pub range: Option<Range>,
    /// Its unit as the range message writes it after an interval (`" degrees"`) or `""`.
    pub unit: &'static str,
    /// How `loam gradient` names and bounds it; `None` when it is not a parameter.
    pub gradient: Option<Gradient>,
}

impl Constant {
    /// How `model` needs this constant (`None`: it does not take it).
    pub fn need(&self, model: ModelKind) -> Option<Need> {
        self.models
            .iter()
            .find(|(m, _)| *m == model)
            .map(|(_, n)| *n)
    }

    /// "only used by model(s) …" for a key on a model that does not take it: the models by
    /// name when there are at most three, else "not used by model \"x\"".
    pub fn misplaced(&self, model: ModelKind) -> String {
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

/// The gradient declaration of a constant in pascals bounded by `[0, 10¹³]` (diamond's
/// Young's modulus is 1.2·10¹² Pa).
const fn pascals(name: &'static str) -> Option<Gradient> {
    Some(Gradient {
        name,
        unit: "Pa",
        degrees: false,
        bounds: Some((0.0, 1e13, "a modulus (Pa)")),
    })
}

/// The gradient declaration of a pure number bounded by `[lo, hi]`.
const fn number(name: &'static str, lo: f64, hi: f64, what: &'static str) -> Option<Gradient> {
    Some(Gradient {
        name,
        unit: "–",
        degrees: false,
        bounds: Some((lo, hi, what)),
    })
}

/// The gradient declaration of an angle: radians in `[0, π/2]`, degrees in the scene.
const fn angle(name: &'static str) -> Option<Gradient> {
    Some(Gradient {
        name,
        unit: "rad",
        degrees: true,
        bounds: Some((0.0, std::f64::consts::FRAC_PI_2, "an angle (rad)")),
    })
}

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
const EVERY_MODEL: [(ModelKind, Need); 8] = [
    (K::LinearElastic, Required),
    (K::NeoHookean, Required),
    (K::Hencky, Required),
    (K::J2, Required),
    (K::Fluid, Required),
    (K::DruckerPrager, Required),
    (K::MohrCoulomb, Required),
    (K::ModifiedCamClay, Required),
];
/// The skeletons of a saturated soil (every model but the fluid), which take the hydraulic
/// constants of a coupled run (`[pore_fluid]`); the scene's validation requires the hydraulic
/// conductivity there and refuses the keys without a pore fluid.
const POROUS: [(ModelKind, Need); 7] = [
    (K::LinearElastic, Optional),
    (K::NeoHookean, Optional),
    (K::Hencky, Optional),
    (K::J2, Optional),
    (K::DruckerPrager, Optional),
    (K::MohrCoulomb, Optional),
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

/// The reference density `ρ₀` (kg/m³), which every material has: a parameter in `[0, 10⁵]`
/// (osmium's is 2.26·10⁴ kg/m³). It is not in [`CONSTANTS`], whose keys depend on the model.
pub const DENSITY: Constant = Constant {
    key: "density",
    what: "the reference density, kg/m³",
    models: &EVERY_MODEL,
    range: Some(Range::Positive),
    unit: "",
    gradient: Some(Gradient {
        name: "density",
        unit: "kg/m³",
        degrees: false,
        bounds: Some((0.0, 1e5, "a density (kg/m³)")),
    }),
};

/// Every constant of a material but its `name`, `model` and [`DENSITY`]. Physical ranges of
/// the parameters: moduli, strengths and pressures in `[0, 10¹³]` Pa, a hardening modulus in
/// `±10¹³` Pa; Poisson's ratio in `[−1, ½]`; angles in `[0, π/2]` rad; a fluid's sound speed in
/// `[0, 10⁵]` m/s and its Tait exponent in `[0, 100]`; the `e–ln p′` slopes `λ`, `κ` of Modified
/// Cam-Clay in `[0, 10]` (peats reach `λ` ≈ 3), its critical state slope
/// `M = 6 sin φ′/(3 − sin φ′)` in `[0, 3]` (its value at φ′ = 90°), its void ratio in
/// `[0, 20]` and its overconsolidation ratio in `[1, 10³]` (1: normally consolidated).
/// Viscosities have no range.
pub const CONSTANTS: &[Constant] = &[
    Constant {
        key: "youngs_modulus",
        what: "Young's modulus, Pa",
        models: &YOUNG_MODELS,
        range: Some(Range::Positive),
        unit: "",
        gradient: pascals("young"),
    },
    Constant {
        key: "poisson_ratio",
        what: "Poisson's ratio",
        models: &POISSON_MODELS,
        range: Some(Range::Open(-1.0, 0.5)),
        unit: "",
        gradient: number("poisson", -1.0, 0.5, "Poisson's ratio"),
    },
    Constant {
        key: "yield_stress",
        what: "the uniaxial yield stress, Pa",
        models: &[(K::J2, Required)],
        range: Some(Range::Positive),
        unit: "",
        gradient: pascals("yield_stress"),
    },
    Constant {
        key: "hardening",
        what: "the linear hardening modulus, Pa",
        models: &[(K::J2, Optional)],
        range: Some(Range::NonNegative),
        unit: "",
        gradient: Some(Gradient {
            name: "hardening",
            unit: "Pa",
            degrees: false,
            bounds: Some((-1e13, 1e13, "a hardening modulus (Pa)")),
        }),
    },
    Constant {
        key: "sound_speed",
        what: "the reference sound speed, m/s",
        models: &FLUID_OPTIONAL,
        range: Some(Range::Positive),
        unit: "",
        gradient: Some(Gradient {
            name: "sound_speed",
            unit: "m/s",
            degrees: false,
            bounds: Some((0.0, 1e5, "a sound speed (m/s)")),
        }),
    },
    Constant {
        key: "bulk_modulus",
        what: "the bulk modulus, Pa",
        models: &FLUID_OPTIONAL,
        range: Some(Range::Positive),
        unit: "",
        gradient: pascals("bulk_modulus"),
    },
    Constant {
        key: "gamma",
        what: "the Tait exponent",
        models: &FLUID_OPTIONAL,
        range: Some(Range::AtLeast(1.0)),
        unit: "",
        gradient: number("gamma", 0.0, 100.0, "a Tait exponent"),
    },
    Constant {
        key: "viscosity",
        what: "the dynamic viscosity, Pa·s",
        models: &FLUID_OPTIONAL,
        range: Some(Range::NonNegative),
        unit: "",
        gradient: Some(Gradient {
            name: "viscosity",
            unit: "Pa·s",
            degrees: false,
            bounds: None,
        }),
    },
    Constant {
        key: "friction_angle",
        what: "the friction angle φ in degrees, 0 < φ < 90",
        models: &FRICTIONAL,
        range: Some(Range::Open(0.0, 90.0)),
        unit: " degrees",
        gradient: angle("friction_angle"),
    },
    Constant {
        key: "dilation_angle",
        what: "the dilation angle ψ in degrees, 0 ≤ ψ ≤ φ",
        models: &FRICTIONAL_OPTIONAL,
        range: None,
        unit: " degrees",
        gradient: angle("dilation_angle"),
    },
    Constant {
        key: "cohesion",
        what: "the cohesion c, Pa",
        models: &FRICTIONAL_OPTIONAL,
        range: Some(Range::NonNegative),
        unit: "",
        gradient: pascals("cohesion"),
    },
    Constant {
        key: "tension_cutoff",
        what: "the tension cutoff, Pa (drucker_prager: on the mean stress; mohr_coulomb: on \
               every principal stress)",
        models: &FRICTIONAL_OPTIONAL,
        range: None,
        unit: "",
        gradient: Some(Gradient {
            name: "tension_cutoff",
            unit: "Pa",
            degrees: false,
            bounds: Some((0.0, 1e13, "a tensile strength (Pa)")),
        }),
    },
    Constant {
        key: "cone",
        what: "the Mohr–Coulomb section the cone matches",
        models: &DRUCKER_PRAGER_OPTIONAL,
        range: None,
        unit: "",
        gradient: None,
    },
    Constant {
        key: "elasticity",
        what: "the elastic law, hencky or jaumann",
        models: &DRUCKER_PRAGER_OPTIONAL,
        range: None,
        unit: "",
        gradient: None,
    },
    Constant {
        key: "lambda",
        what: "the slope λ of the normal compression line in e–ln p′",
        models: &CAM_CLAY,
        range: Some(Range::Positive),
        unit: "",
        gradient: number("lambda", 0.0, 10.0, "a slope of the e–ln p′ line"),
    },
    Constant {
        key: "kappa",
        what: "the slope κ of the unloading–reloading line in e–ln p′, 0 < κ < λ",
        models: &CAM_CLAY,
        range: Some(Range::Positive),
        unit: "",
        gradient: number("kappa", 0.0, 10.0, "a slope of the e–ln p′ line"),
    },
    Constant {
        key: "critical_state_slope",
        what: "the slope M of the critical state line in p′–q",
        models: &CAM_CLAY,
        range: Some(Range::Positive),
        unit: "",
        gradient: number("critical_state_slope", 0.0, 3.0, "a critical state slope M"),
    },
    Constant {
        key: "void_ratio",
        what: "the initial void ratio e₀",
        models: &CAM_CLAY,
        range: Some(Range::Positive),
        unit: "",
        gradient: number("void_ratio", 0.0, 20.0, "a void ratio"),
    },
    Constant {
        key: "shear_modulus",
        what: "a constant shear modulus G, Pa",
        models: &CAM_CLAY_OPTIONAL,
        range: Some(Range::Positive),
        unit: "",
        gradient: pascals("shear_modulus"),
    },
    Constant {
        key: "preconsolidation_pressure",
        what: "the initial preconsolidation pressure p′c0, Pa",
        models: &CAM_CLAY_OPTIONAL,
        range: Some(Range::Positive),
        unit: "",
        gradient: Some(Gradient {
            name: "preconsolidation_pressure",
            unit: "Pa",
            degrees: false,
            bounds: Some((0.0, 1e13, "a pressure (Pa)")),
        }),
    },
    Constant {
        key: "ocr",
        what: "the overconsolidation ratio on the yield locus, ≥ 1",
        models: &CAM_CLAY_OPTIONAL,
        range: Some(Range::AtLeast(1.0)),
        unit: "",
        gradient: number("ocr", 1.0, 1e3, "an overconsolidation ratio"),
    },
    Constant {
        key: "hydraulic_conductivity",
        what: "Darcy's hydraulic conductivity k, m/s",
        models: &POROUS,
        range: Some(Range::Positive),
        unit: "",
        gradient: None,
    },
    Constant {
        key: "biot_coefficient",
        what: "Biot's coefficient α, in (0, 1]",
        models: &POROUS,
        range: Some(Range::LeftOpen(0.0, 1.0)),
        unit: "",
        gradient: None,
    },
    Constant {
        key: "porosity",
        what: "the porosity n, in (0, 1)",
        models: &POROUS,
        range: Some(Range::Open(0.0, 1.0)),
        unit: "",
        gradient: None,
    },
];

/// Pairs of constants of which a model needs exactly one: `(model, first, second, what)`.
pub const ONE_OF: &[(ModelKind, &str, &str, &str)] = &[
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

/// The constant whose scene key is `key` ([`DENSITY`] included).
pub fn constant(key: &str) -> Option<&'static Constant> {
    std::iter::once(&DENSITY)
        .chain(CONSTANTS)
        .find(|c| c.key == key)
}

/// The other key of `key`'s [`ONE_OF`] pair for `model`, if it has one: setting one of the
/// pair clears the other.
pub fn partner(model: ModelKind, key: &str) -> Option<&'static str> {
    ONE_OF
        .iter()
        .filter(|o| o.0 == model)
        .find_map(|&(_, a, b, _)| match key {
            k if k == a => Some(b),
            k if k == b => Some(a),
            _ => None,
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Keys and gradient names are unique, every `ONE_OF` key is declared and optional for
    /// its model, and an angle converts to the scene's degrees.
    #[test]
    fn the_declaration_is_consistent() {
        let all: Vec<&Constant> = std::iter::once(&DENSITY).chain(CONSTANTS).collect();
        for (i, a) in all.iter().enumerate() {
            for b in &all[i + 1..] {
                assert_ne!(a.key, b.key);
                if let (Some(ga), Some(gb)) = (a.gradient, b.gradient) {
                    assert_ne!(ga.name, gb.name);
                }
            }
        }
        for &(model, first, second, _) in ONE_OF {
            for key in [first, second] {
                let c = constant(key).unwrap_or_else(|| panic!("{key}"));
                assert_eq!(c.need(model), Some(Need::Optional), "{key}");
            }
            assert_eq!(partner(model, first), Some(second));
            assert_eq!(partner(model, second), Some(first));
        }
        assert_eq!(partner(ModelKind::J2, "ocr"), None);
        let phi = constant("friction_angle").unwrap().gradient.unwrap();
        assert!((phi.to_scene(std::f64::consts::FRAC_PI_6) - 30.0).abs() < 1e-12);
        assert_eq!(
            Range::Open(0.0, 90.0).admit(90.0, " degrees").unwrap_err(),
            "must be in (0, 90) degrees, got 90"
        );
        assert!(Range::AtLeast(1.0).admit(1.0, "").is_ok());
    }
}
