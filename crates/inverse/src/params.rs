//! The parameters a gradient is taken with respect to, and how each one is seeded.
//!
//! A parameter of the step (a friction coefficient, gravity, a material constant) is a `T` of
//! the configuration from the setup on (`loam_explicit::Config::lift`). Seeding it means: the
//! configuration lifted to `Dual64` with a unit derivative on that one parameter. The reverse
//! step evaluates a node's or a particle's kernel once with such a configuration (and constant
//! inputs) to get that parameter's share of the gradient, `ȳ · ∂y/∂θ`.
//!
//! The particle density enters through the particle masses `m_p = ρ₀ V_p⁰`, which are part of
//! the initial state: its gradient is `Σ_p m̄_p V_p⁰` over the material's particles, formed from
//! the adjoint of the initial state ([`crate::Gradient`]).

use crate::error::AdjointError;
use loam_core::constitutive::constants::{self, Constant, Gradient};
use loam_core::constitutive::{Lame, MaterialState, Model, Preconsolidation, Shear};
use loam_core::{Material, ModelKind};
use loam_explicit::Config;
use nalgebra::Matrix3;
use num_dual::Dual64;
use std::fmt;
use std::str::FromStr;

/// A material constant.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MaterialField {
    /// Young's modulus `E` (elastic and elastoplastic models), ν held.
    Young,
    /// Poisson's ratio `ν`, `E` held.
    Poisson,
    /// Reference density `ρ₀` (through the particle masses).
    Density,
    /// Fluid bulk modulus `K`.
    BulkModulus,
    /// Fluid sound speed `c = √(K/ρ₀)`, ρ₀ held (`dK/dc = 2 ρ₀ c`).
    SoundSpeed,
    /// Fluid Tait exponent `γ`.
    Gamma,
    /// Fluid dynamic viscosity `η`.
    Viscosity,
    /// Drucker–Prager friction angle `φ` (radians).
    FrictionAngle,
    /// Drucker–Prager dilation angle `ψ` (radians).
    DilationAngle,
    /// Drucker–Prager cohesion `c`.
    Cohesion,
    /// J2 yield stress `σ_y`.
    YieldStress,
    /// J2 linear hardening modulus `H`.
    Hardening,
    /// Modified Cam-Clay slope `λ` of the normal compression line.
    Lambda,
    /// Modified Cam-Clay slope `κ` of the unloading–reloading line.
    Kappa,
    /// Modified Cam-Clay critical state slope `M`.
    CriticalStateSlope,
    /// Modified Cam-Clay initial void ratio `e₀` (through `λ/(1 + e₀)`, `κ/(1 + e₀)`).
    VoidRatio,
    /// Modified Cam-Clay constant shear modulus `G`.
    ShearModulus,
    /// Modified Cam-Clay overconsolidation ratio `R` (`p_c₀ = R p_y`): acts only through the
    /// initial state of a prestressed body.
    Ocr,
    /// Modified Cam-Clay initial preconsolidation pressure `p_c₀` (Pa): acts only through the
    /// initial state of a prestressed body.
    PreconsolidationPressure,
    /// Tension cutoff `σ_t` (Pa) of Drucker–Prager (on the mean stress) or Mohr–Coulomb (on
    /// every principal stress), of a material that has one.
    TensionCutoff,
}

impl MaterialField {
    /// The scene key of the constant, which declares it
    /// ([`loam_core::constitutive::constants`]).
    pub fn key(self) -> &'static str {
        match self {
            Self::Young => "youngs_modulus",
            Self::Poisson => "poisson_ratio",
            Self::Density => "density",
            Self::BulkModulus => "bulk_modulus",
            Self::SoundSpeed => "sound_speed",
            Self::Gamma => "gamma",
            Self::Viscosity => "viscosity",
            Self::FrictionAngle => "friction_angle",
            Self::DilationAngle => "dilation_angle",
            Self::Cohesion => "cohesion",
            Self::YieldStress => "yield_stress",
            Self::Hardening => "hardening",
            Self::Lambda => "lambda",
            Self::Kappa => "kappa",
            Self::CriticalStateSlope => "critical_state_slope",
            Self::VoidRatio => "void_ratio",
            Self::ShearModulus => "shear_modulus",
            Self::Ocr => "ocr",
            Self::PreconsolidationPressure => "preconsolidation_pressure",
            Self::TensionCutoff => "tension_cutoff",
        }
    }

    /// The constant's declaration: its models, units and physical range.
    pub fn constant(self) -> &'static Constant {
        constants::constant(self.key()).expect("every field's key is declared")
    }

    /// How `loam gradient` names and bounds it.
    pub fn gradient(self) -> Gradient {
        self.constant()
            .gradient
            .expect("every field's constant is declared a parameter")
    }

    /// The name used in messages and files (`young`, `poisson`, …), from its declaration.
    pub fn name(self) -> &'static str {
        self.gradient().name
    }

    /// The constant named `name` (as [`MaterialField::name`] writes it).
    pub fn named(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.name() == name)
    }

    /// Whether an implicit scene can have it: some model that takes it is a solid (the fluid
    /// is explicit only).
    pub fn implicit(self) -> bool {
        (self.constant().models.iter()).any(|&(m, _)| m != ModelKind::Fluid)
    }
}

impl MaterialField {
    /// Whether the model of `material` has this constant (a Modified Cam-Clay material given
    /// by its shear modulus has no Poisson's ratio, and the other way round).
    pub fn applies_to(self, material: &Material<f64>) -> bool {
        seed_material(material, self).is_some()
    }
}

/// One scalar parameter of an explicit run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Param {
    /// Coulomb coefficient `μ` of friction segment `k` (`Contact::segments[k]`).
    Friction(usize),
    /// Coulomb coefficient of obstacle `k`.
    ObstacleFriction(usize),
    /// Component `a` of obstacle `k`'s velocity.
    ObstacleVelocity(usize, usize),
    /// Component `a` of gravity.
    Gravity(usize),
    /// A constant of material `k` (`Config::materials[k]`).
    Material(usize, MaterialField),
}

impl fmt::Display for Param {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Param::Friction(k) => write!(f, "friction[{k}]"),
            Param::ObstacleFriction(k) => write!(f, "obstacle[{k}].friction"),
            Param::ObstacleVelocity(k, a) => write!(f, "obstacle[{k}].velocity[{a}]"),
            Param::Gravity(a) => write!(f, "gravity[{a}]"),
            Param::Material(k, field) => write!(f, "materials[{k}].{}", field.name()),
        }
    }
}

impl MaterialField {
    /// Every constant, in the order of the enum.
    pub const ALL: [MaterialField; 20] = [
        Self::Young,
        Self::Poisson,
        Self::Density,
        Self::BulkModulus,
        Self::SoundSpeed,
        Self::Gamma,
        Self::Viscosity,
        Self::FrictionAngle,
        Self::DilationAngle,
        Self::Cohesion,
        Self::YieldStress,
        Self::Hardening,
        Self::Lambda,
        Self::Kappa,
        Self::CriticalStateSlope,
        Self::VoidRatio,
        Self::ShearModulus,
        Self::Ocr,
        Self::PreconsolidationPressure,
        Self::TensionCutoff,
    ];
}

impl FromStr for Param {
    type Err = String;

    /// Reads the form [`Param`]'s `Display` writes: `friction[k]`, `obstacle[k].friction`,
    /// `obstacle[k].velocity[a]`, `gravity[a]`, `materials[k].<constant>`.
    fn from_str(s: &str) -> Result<Self, String> {
        let expected = || {
            format!(
                "unknown parameter `{s}`; expected `friction[k]`, `obstacle[k].friction`, \
                 `obstacle[k].velocity[a]`, `gravity[a]` or `materials[k].<constant>` with \
                 <constant> one of {}",
                MaterialField::ALL.map(MaterialField::name).join(", ")
            )
        };
        // `name[index]` and the rest after it.
        let indexed = |t: &str, name: &str| -> Option<(usize, String)> {
            let rest = t.strip_prefix(name)?.strip_prefix('[')?;
            let (index, rest) = rest.split_once(']')?;
            Some((index.parse().ok()?, rest.to_owned()))
        };
        if let Some((k, rest)) = indexed(s, "friction") {
            return rest
                .is_empty()
                .then_some(Param::Friction(k))
                .ok_or_else(expected);
        }
        if let Some((a, rest)) = indexed(s, "gravity") {
            return rest
                .is_empty()
                .then_some(Param::Gravity(a))
                .ok_or_else(expected);
        }
        if let Some((k, rest)) = indexed(s, "obstacle") {
            if rest == ".friction" {
                return Ok(Param::ObstacleFriction(k));
            }
            return match indexed(&rest, ".velocity") {
                Some((a, tail)) if tail.is_empty() => Ok(Param::ObstacleVelocity(k, a)),
                _ => Err(expected()),
            };
        }
        if let Some((k, rest)) = indexed(s, "materials") {
            let field = rest.strip_prefix('.').ok_or_else(expected)?;
            return MaterialField::named(field)
                .map(|f| Param::Material(k, f))
                .ok_or_else(expected);
        }
        Err(expected())
    }
}

/// Where a parameter acts in the step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Acts {
    /// In the grid-node update (contact, gravity).
    Nodes,
    /// In the particle end of the step (the constitutive update of material `k`).
    Particles(usize),
    /// Only in the initial state (the density, through the masses).
    Initial,
}

impl Param {
    /// Where the parameter acts.
    pub fn acts(&self) -> Acts {
        match *self {
            Param::Friction(_)
            | Param::ObstacleFriction(_)
            | Param::ObstacleVelocity(..)
            | Param::Gravity(_) => Acts::Nodes,
            Param::Material(
                _,
                MaterialField::Density
                | MaterialField::Ocr
                | MaterialField::PreconsolidationPressure,
            ) => Acts::Initial,
            Param::Material(k, _) => Acts::Particles(k),
        }
    }

    /// Its value in `config`.
    pub fn value<const D: usize>(&self, config: &Config<f64, D>) -> Result<f64, AdjointError> {
        Ok(seed(config, *self)?.1)
    }

    /// `config` lifted to `Dual64` with a unit derivative on this parameter.
    pub fn seeded<const D: usize>(
        &self,
        config: &Config<f64, D>,
    ) -> Result<Config<Dual64, D>, AdjointError> {
        Ok(seed(config, *self)?.0)
    }

    /// `config` with this parameter set to `value` (the other constants of its law held, as
    /// in [`MaterialField`]).
    pub fn set<const D: usize>(
        &self,
        config: &mut Config<f64, D>,
        value: f64,
    ) -> Result<(), AdjointError> {
        let d = value - self.value(config)?;
        // Every field is affine in its parameter along the seeded direction except the
        // Lamé constants (E, ν) and the sound speed: rebuild those from the new value.
        let unknown = self.unknown(config);
        match *self {
            Param::Friction(k) => config.contact.segments.get_mut(k).ok_or(unknown)?.mu += d,
            Param::ObstacleFriction(k) => {
                config.contact.obstacles.get_mut(k).ok_or(unknown)?.mu += d
            }
            Param::ObstacleVelocity(k, a) => {
                config.contact.obstacles.get_mut(k).ok_or(unknown)?.velocity[a] += d
            }
            Param::Gravity(a) => config.gravity[a] += d,
            Param::Material(k, field) => {
                let m = config.materials.get_mut(k).ok_or(unknown)?;
                set_material(m, field, value).ok_or_else(|| AdjointError::Parameter {
                    param: self.to_string(),
                    msg: no_such_constant(m),
                })?;
            }
        }
        Ok(())
    }

    /// For a constant of material `k` (not its density): per particle of the material that
    /// carries an initial stress, the history `h₀(θ)` that carries its initial Kirchhoff
    /// stress `τ₀ = J σ₀` (held: a prestressed body's initial stress is data, as in implicit
    /// runs) in the material with `θ` seeded ([`Material::prestressed_state`]), the
    /// derivative `dh₀/dθ` on the dual parts; none for a particle without stress or a model
    /// that carries its stress in `F` (the elastic models). Modified Cam-Clay's `ocr` and
    /// `preconsolidation_pressure` act only through it (`p_c₀`).
    ///
    /// # Errors
    /// `ocr` or `preconsolidation_pressure` of a material none of whose particles carries
    /// an initial stress (they would move nothing).
    pub fn initial_histories<const D: usize>(
        &self,
        config: &Config<f64, D>,
        particles: &loam_core::Particles<f64, D>,
    ) -> Result<Vec<(usize, MaterialState<Dual64>)>, AdjointError> {
        let Param::Material(k, field) = *self else {
            return Ok(Vec::new());
        };
        if field == MaterialField::Density {
            return Ok(Vec::new());
        }
        let (seeded, _) = seed(config, *self)?;
        let material = &seeded.materials[k];
        let out: Vec<(usize, MaterialState<Dual64>)> = (0..particles.len())
            .filter(|&p| {
                particles.material[p] as usize == k && particles.stress[p] != Matrix3::zeros()
            })
            .filter_map(|p| {
                let j = loam_core::tensor::det(&particles.f[p]);
                let tau = (particles.stress[p] * j).map(Dual64::from_re);
                Some((p, material.prestressed_state(&tau)?))
            })
            .collect();
        if out.is_empty()
            && matches!(
                field,
                MaterialField::Ocr | MaterialField::PreconsolidationPressure
            )
        {
            return Err(AdjointError::Parameter {
                param: self.to_string(),
                msg: "sets p_c₀ of a prestressed body: no particle of the material carries an \
                      initial stress (give its bodies an `initial_stress`)"
                    .into(),
            });
        }
        Ok(out)
    }

    fn unknown<const D: usize>(&self, config: &Config<f64, D>) -> AdjointError {
        AdjointError::Parameter {
            param: self.to_string(),
            msg: format!(
                "no such item: the scene has {} friction segments, {} obstacles and {} materials",
                config.contact.segments.len(),
                config.contact.obstacles.len(),
                config.materials.len()
            ),
        }
    }
}

/// The lifted configuration with `param` seeded, and the parameter's value.
fn seed<const D: usize>(
    config: &Config<f64, D>,
    param: Param,
) -> Result<(Config<Dual64, D>, f64), AdjointError> {
    let mut lifted: Config<Dual64, D> = config.lift();
    let unknown = || param.unknown(config);
    let value = match param {
        Param::Friction(k) => {
            let s = lifted.contact.segments.get_mut(k).ok_or_else(unknown)?;
            s.mu.eps = 1.0;
            s.mu.re
        }
        Param::ObstacleFriction(k) => {
            let o = lifted.contact.obstacles.get_mut(k).ok_or_else(unknown)?;
            o.mu.eps = 1.0;
            o.mu.re
        }
        Param::ObstacleVelocity(k, a) if a < D => {
            let o = lifted.contact.obstacles.get_mut(k).ok_or_else(unknown)?;
            o.velocity[a].eps = 1.0;
            o.velocity[a].re
        }
        Param::Gravity(a) if a < D => {
            lifted.gravity[a].eps = 1.0;
            lifted.gravity[a].re
        }
        Param::ObstacleVelocity(..) | Param::Gravity(_) => {
            return Err(AdjointError::Parameter {
                param: param.to_string(),
                msg: format!("the component must be below the dimension {D}"),
            });
        }
        Param::Material(k, field) => {
            let m = config.materials.get(k).ok_or_else(unknown)?;
            let (seeded, value) =
                seed_material(m, field).ok_or_else(|| AdjointError::Parameter {
                    param: param.to_string(),
                    msg: no_such_constant(m),
                })?;
            lifted.materials[k] = seeded;
            value
        }
    };
    Ok((lifted, value))
}

/// `E` and `ν` of Lamé constants ([`Lame::young`], [`Lame::poisson`]).
fn young_poisson(l: &Lame<f64>) -> (f64, f64) {
    (l.young(), l.poisson())
}

/// Lamé constants with the derivative with respect to `E` (`young`) or `ν` on their dual
/// parts, and the primal parts exactly those stored (so the seeded run takes the forward's
/// branches bit for bit).
fn seed_lame(l: &Lame<f64>, young: bool) -> (Lame<Dual64>, f64) {
    let (e, nu) = young_poisson(l);
    let (e_d, nu_d) = if young {
        (Dual64::new(e, 1.0), Dual64::from_re(nu))
    } else {
        (Dual64::from_re(e), Dual64::new(nu, 1.0))
    };
    let d = Lame::from_young_poisson(e_d, nu_d);
    (
        Lame {
            mu: Dual64::new(l.mu, d.mu.eps),
            lambda: Dual64::new(l.lambda, d.lambda.eps),
        },
        if young { e } else { nu },
    )
}

/// Why a constant is not one of `m`'s: its model, and the constants it has (those
/// [`seed_material`] accepts, in [`MaterialField::ALL`]'s order).
pub(crate) fn no_such_constant(m: &Material<f64>) -> String {
    let names: Vec<&str> = (MaterialField::ALL.iter())
        .filter(|&&f| seed_material(m, f).is_some())
        .map(|f| f.name())
        .collect();
    format!(
        "model \"{}\" has no such constant; its constants are {}",
        m.model.kind().name(),
        names.join(", ")
    )
}

/// The material lifted to `Dual64` with `field` seeded, and the field's value; `None` when
/// the model has no such constant.
pub(crate) fn seed_material(
    m: &Material<f64>,
    field: MaterialField,
) -> Option<(Material<Dual64>, f64)> {
    use MaterialField as F;
    let mut out: Material<Dual64> = m.lift();
    let value = match (field, &mut out.model) {
        (F::Density, _) => {
            out.density.eps = 1.0;
            out.density.re
        }
        (F::Young | F::Poisson, model) if has_lame(model) => {
            let mut stored = m.model.clone();
            let (seeded, value) = seed_lame(lame_of(&mut stored)?, field == F::Young);
            *lame_of(model)? = seeded;
            value
        }
        (F::SoundSpeed, Model::Fluid(x)) => {
            // K = ρ₀ c², dK/dc = 2 ρ₀ c = 2 √(K ρ₀).
            let (k, rho) = (x.bulk_modulus.re, m.density);
            x.bulk_modulus.eps = 2.0 * (k * rho).sqrt();
            (k / rho).sqrt()
        }
        (_, model) => {
            let x = slot(model, field)?;
            x.eps = 1.0;
            x.re
        }
    };
    Some((out, value))
}

/// The stored value of `field` in `model` where the model holds it as it is (every constant
/// but the density, `E` and `ν` of a model with Lamé constants, and a fluid's sound speed);
/// `None` when the model has no such constant.
fn slot<T>(model: &mut Model<T>, field: MaterialField) -> Option<&mut T> {
    use MaterialField as F;
    Some(match (field, model) {
        (F::Poisson, Model::ModifiedCamClay(x)) => match &mut x.shear {
            Shear::Poisson(nu) => nu,
            Shear::Modulus(_) => return None,
        },
        (F::ShearModulus, Model::ModifiedCamClay(x)) => match &mut x.shear {
            Shear::Modulus(g) => g,
            Shear::Poisson(_) => return None,
        },
        (F::Lambda, Model::ModifiedCamClay(x)) => &mut x.lambda,
        (F::Kappa, Model::ModifiedCamClay(x)) => &mut x.kappa,
        (F::CriticalStateSlope, Model::ModifiedCamClay(x)) => &mut x.critical_state_slope,
        (F::VoidRatio, Model::ModifiedCamClay(x)) => &mut x.void_ratio,
        (F::Ocr, Model::ModifiedCamClay(x)) => match &mut x.preconsolidation {
            Preconsolidation::Ratio(r) => r,
            Preconsolidation::Pressure(_) => return None,
        },
        (F::PreconsolidationPressure, Model::ModifiedCamClay(x)) => match &mut x.preconsolidation {
            Preconsolidation::Pressure(p) => p,
            Preconsolidation::Ratio(_) => return None,
        },
        (F::BulkModulus, Model::Fluid(x)) => &mut x.bulk_modulus,
        (F::Gamma, Model::Fluid(x)) => &mut x.gamma,
        (F::Viscosity, Model::Fluid(x)) => &mut x.viscosity,
        (F::FrictionAngle, Model::DruckerPrager(x)) => &mut x.friction_angle,
        (F::DilationAngle, Model::DruckerPrager(x)) => &mut x.dilation_angle,
        (F::Cohesion, Model::DruckerPrager(x)) => &mut x.cohesion,
        (F::TensionCutoff, Model::DruckerPrager(x)) => x.tension_cutoff.as_mut()?,
        (F::FrictionAngle, Model::MohrCoulomb(x)) => &mut x.friction_angle,
        (F::DilationAngle, Model::MohrCoulomb(x)) => &mut x.dilation_angle,
        (F::Cohesion, Model::MohrCoulomb(x)) => &mut x.cohesion,
        (F::TensionCutoff, Model::MohrCoulomb(x)) => x.tension_cutoff.as_mut()?,
        (F::YieldStress, Model::J2(x)) => &mut x.yield_stress,
        (F::Hardening, Model::J2(x)) => &mut x.hardening,
        _ => return None,
    })
}

/// Whether the model has Lamé constants (every model but the fluid and Modified Cam-Clay,
/// whose elasticity depends on the pressure).
fn has_lame<T>(model: &Model<T>) -> bool {
    !matches!(model, Model::Fluid(_) | Model::ModifiedCamClay(_))
}

/// The Lamé constants of a model that has them ([`has_lame`]).
fn lame_of<T>(model: &mut Model<T>) -> Option<&mut Lame<T>> {
    match model {
        Model::LinearElastic(x) => Some(&mut x.lame),
        Model::NeoHookean(x) => Some(&mut x.lame),
        Model::Hencky(x) => Some(&mut x.lame),
        Model::J2(x) => Some(&mut x.lame),
        Model::DruckerPrager(x) => Some(&mut x.lame),
        Model::MohrCoulomb(x) => Some(&mut x.lame),
        Model::Fluid(_) | Model::ModifiedCamClay(_) => None,
    }
}

/// Sets `field` of `m` to `value`; `None` when the model has no such constant.
pub(crate) fn set_material(m: &mut Material<f64>, field: MaterialField, value: f64) -> Option<()> {
    use MaterialField as F;
    let density = m.density;
    match (field, &mut m.model) {
        (F::Density, _) => m.density = value,
        (F::Young | F::Poisson, model) if has_lame(model) => {
            let lame = lame_of(model)?;
            let (e, nu) = young_poisson(lame);
            *lame = if field == F::Young {
                Lame::from_young_poisson(value, nu)
            } else {
                Lame::from_young_poisson(e, value)
            };
        }
        (F::SoundSpeed, Model::Fluid(x)) => x.bulk_modulus = density * value * value,
        (_, model) => *slot(model, field)? = value,
    }
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A constant the model lacks is refused with the model's name and the constants it has.
    #[test]
    fn a_missing_constant_names_the_ones_the_model_has() {
        let j2 = Material::j2(25e6, 0.3, 1e5, 0.0, 2000.0);
        let msg = no_such_constant(&j2);
        assert_eq!(
            msg,
            "model \"j2\" has no such constant; its constants are young, poisson, density, \
             yield_stress, hardening"
        );
    }

    #[test]
    fn names_read_back_what_display_writes() {
        let mut all = vec![
            Param::Friction(3),
            Param::ObstacleFriction(0),
            Param::ObstacleVelocity(1, 2),
            Param::Gravity(1),
        ];
        all.extend(MaterialField::ALL.map(|f| Param::Material(2, f)));
        for p in all {
            assert_eq!(p.to_string().parse::<Param>(), Ok(p));
        }
        for bad in [
            "friction",
            "friction[x]",
            "friction[1].mu",
            "materials[0].stiffness",
            "mu",
        ] {
            let err = bad.parse::<Param>().unwrap_err();
            assert!(err.contains(bad) && err.contains("expected"), "{err}");
        }
    }
}
