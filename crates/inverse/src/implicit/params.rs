//! The parameters of an implicit run a gradient is taken with respect to.

use super::kernel::{Loads, lift_loads, mass_index, state_len};
use crate::error::AdjointError;
use crate::k0::K0State;
use crate::params::{MaterialField, no_such_constant, seed_material, set_material};
use loam_core::constitutive::{HISTORY_LEN, MaterialState};
use loam_core::tensor::Vector;
use loam_core::{Material, Particles};
use loam_implicit::ImplicitConfig;
use loam_implicit::flow::Hydraulic;
use nalgebra::Matrix3;
use num_dual::Dual64;
use std::fmt;
use std::str::FromStr;

/// One scalar parameter of an implicit run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ImplicitParam {
    /// A constant of material `k` (`ImplicitConfig::materials[k]`, a
    /// [`MaterialField`]); `density` acts through the masses `m_p = ρ₀ V⁰_p` of its particles,
    /// and in a prestressed scene the constants also move the histories that carry the bodies'
    /// initial stress ([`ImplicitParam::initial_tangent`]).
    Material(usize, MaterialField),
    /// Component `a` of gravity.
    Gravity(usize),
    /// Component `a` of the total force of point load `k` (`ImplicitConfig::point_loads[k]`).
    PointLoad(usize, usize),
    /// Component `a` of the total prescribed displacement of constraint `k`
    /// (`ImplicitConfig::constraints[k]`).
    Displacement(usize, usize),
    /// Component `a` of the total force of force-controlled constraint `k`
    /// (`ImplicitConfig::constraints[k].force[a]`): the force on the unknown its nodes share,
    /// `f_ext = ℓ F` at load factor `ℓ` ([`loam_implicit::system::Controlled`]).
    ConstraintForce(usize, usize),
    /// `K0 = σ′_h/σ′_v` of the geostatic initial stress of material `k`'s particles
    /// (`materials[k].k0`; see [`ImplicitParam::k0_rates`]): it moves their initial stress,
    /// the history that carries it and, where the scene balances it, the balancing forces.
    K0(usize),
    /// The hydraulic conductivity `k` (m/s) of material `k` in a coupled (u–p) run
    /// (`materials[k].hydraulic_conductivity`; the mobility is `k/γ_w`).
    Conductivity(usize),
}

impl fmt::Display for ImplicitParam {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Material(k, field) => write!(f, "materials[{k}].{}", field.name()),
            Self::K0(k) => write!(f, "materials[{k}].k0"),
            Self::Conductivity(k) => write!(f, "materials[{k}].hydraulic_conductivity"),
            Self::Gravity(a) => write!(f, "gravity[{a}]"),
            Self::PointLoad(k, a) => write!(f, "point_loads[{k}].force[{a}]"),
            Self::Displacement(k, a) => write!(f, "constraints[{k}].displacement[{a}]"),
            Self::ConstraintForce(k, a) => write!(f, "constraints[{k}].force[{a}]"),
        }
    }
}

impl FromStr for ImplicitParam {
    type Err = String;

    /// Reads the form `Display` writes.
    fn from_str(s: &str) -> Result<Self, String> {
        let expected = || {
            let constants: Vec<&str> = (MaterialField::ALL.into_iter())
                .filter(|f| f.implicit())
                .map(MaterialField::name)
                .collect();
            format!(
                "unknown parameter `{s}`; expected `materials[k].<constant>` (a constant of the \
                 material's model: {}), `materials[k].k0`, \
                 `materials[k].hydraulic_conductivity`, `gravity[a]`, \
                 `point_loads[k].force[a]`, `constraints[k].displacement[a]` or \
                 `constraints[k].force[a]`",
                constants.join(", ")
            )
        };
        let indexed = |t: &str, name: &str| -> Option<(usize, String)> {
            let rest = t.strip_prefix(name)?.strip_prefix('[')?;
            let (index, rest) = rest.split_once(']')?;
            Some((index.parse().ok()?, rest.to_owned()))
        };
        let pair = |name: &str, inner: &str| -> Option<(usize, usize)> {
            let (k, rest) = indexed(s, name)?;
            let (a, tail) = indexed(&rest, inner)?;
            tail.is_empty().then_some((k, a))
        };
        if let Some((k, a)) = pair("point_loads", ".force") {
            return Ok(Self::PointLoad(k, a));
        }
        if let Some((k, a)) = pair("constraints", ".displacement") {
            return Ok(Self::Displacement(k, a));
        }
        if let Some((k, a)) = pair("constraints", ".force") {
            return Ok(Self::ConstraintForce(k, a));
        }
        if let Some((a, rest)) = indexed(s, "gravity") {
            return rest
                .is_empty()
                .then_some(Self::Gravity(a))
                .ok_or_else(expected);
        }
        if let Some((k, rest)) = indexed(s, "materials") {
            let field = rest.strip_prefix('.').ok_or_else(expected)?;
            if field == "k0" {
                return Ok(Self::K0(k));
            }
            if field == "hydraulic_conductivity" {
                return Ok(Self::Conductivity(k));
            }
            return MaterialField::named(field)
                .filter(|f| f.implicit())
                .map(|f| Self::Material(k, f))
                .ok_or_else(expected);
        }
        Err(expected())
    }
}

impl ImplicitParam {
    fn error(&self, msg: impl Into<String>) -> AdjointError {
        AdjointError::Parameter {
            param: self.to_string(),
            msg: msg.into(),
        }
    }

    fn material<'a, const D: usize>(
        &self,
        config: &'a ImplicitConfig<D>,
        k: usize,
    ) -> Result<&'a Material<f64>, AdjointError> {
        config.materials.get(k).ok_or_else(|| {
            self.error(format!(
                "no such material: the scene has {}",
                config.materials.len()
            ))
        })
    }

    /// Its value in `config` with the initial particles `particles` (which hold a K0).
    ///
    /// # Errors
    /// An item the configuration does not have, a constant its model does not have, a
    /// constraint component that is left free, or a K0 the particles do not carry
    /// ([`ImplicitParam::k0_rates`]).
    pub fn value<const D: usize>(
        &self,
        config: &ImplicitConfig<D>,
        particles: &Particles<f64, D>,
    ) -> Result<f64, AdjointError> {
        match *self {
            Self::Material(k, field) => {
                let m = self.material(config, k)?;
                seed_material(m, field)
                    .map(|s| s.1)
                    .ok_or_else(|| self.error(no_such_constant(m)))
            }
            Self::K0(k) => self.k0_rates(config, particles, k).map(|r| r.k0),
            Self::Conductivity(k) => {
                let (fluid, h) = self.hydraulic(config, k)?;
                Ok(h.mobility * fluid.unit_weight)
            }
            Self::Gravity(a) => self.component::<D>(a).map(|a| config.gravity[a]),
            Self::PointLoad(k, a) => {
                let a = self.component::<D>(a)?;
                let load = config.point_loads.get(k).ok_or_else(|| {
                    self.error(format!(
                        "no such point load: the scene has {}",
                        config.point_loads.len()
                    ))
                })?;
                Ok(load.force[a])
            }
            Self::Displacement(k, a) => {
                let a = self.component::<D>(a)?;
                self.constraint(config, k)?.displacement[a]
                    .ok_or_else(|| self.error("this component of the constraint is not prescribed"))
            }
            Self::ConstraintForce(k, a) => {
                let a = self.component::<D>(a)?;
                self.constraint(config, k)?.force[a].ok_or_else(|| {
                    self.error("this component of the constraint is not force-controlled")
                })
            }
        }
    }

    /// User constraint `k` of `config`.
    fn constraint<'a, const D: usize>(
        &self,
        config: &'a ImplicitConfig<D>,
        k: usize,
    ) -> Result<&'a loam_core::NodeConstraint<D>, AdjointError> {
        config.constraints.get(k).ok_or_else(|| {
            self.error(format!(
                "no such constraint: the scene has {}",
                config.constraints.len()
            ))
        })
    }

    /// A component index checked against the dimension `D`.
    fn component<const D: usize>(&self, a: usize) -> Result<usize, AdjointError> {
        if a < D {
            Ok(a)
        } else {
            Err(self.error(format!("component {a} does not exist in {D}D")))
        }
    }

    /// Sets the parameter to `value` in `config` and, for a density, the masses of its
    /// material's particles (`m_p = ρ₀ V⁰_p`).
    ///
    /// # Errors
    /// As [`ImplicitParam::value`].
    pub fn set<const D: usize>(
        &self,
        config: &mut ImplicitConfig<D>,
        particles: &mut Particles<f64, D>,
        value: f64,
    ) -> Result<(), AdjointError> {
        self.value(config, particles)?;
        match *self {
            Self::K0(k) => self.set_k0(config, particles, k, value)?,
            Self::Material(k, field) => {
                // A prestressed body's initial stress is data: the history that carries it
                // follows the material (the elastic strain of E, ν, κ, …; MCC's p_c₀).
                let held = config
                    .gravity_in_full
                    .then(|| initial_stresses(config, particles, k));
                let m = &mut config.materials[k];
                set_material(m, field, value).ok_or_else(|| self.error(no_such_constant(m)))?;
                for (p, tau0) in held.into_iter().flatten() {
                    if let Some(h) = config.materials[k].prestressed_state(&tau0) {
                        particles.state[p] = h;
                    }
                }
                if field == MaterialField::Density {
                    for p in 0..particles.len() {
                        if particles.material[p] as usize == k {
                            particles.mass[p] = value * particles.volume0[p];
                        }
                    }
                }
            }
            Self::Gravity(a) => config.gravity[a] = value,
            Self::PointLoad(k, a) => config.point_loads[k].force[a] = value,
            Self::Displacement(k, a) => config.constraints[k].displacement[a] = Some(value),
            Self::ConstraintForce(k, a) => config.constraints[k].force[a] = Some(value),
            Self::Conductivity(k) => {
                if !(value > 0.0 && value.is_finite()) {
                    return Err(self.error(format!("must be positive, got {value}")));
                }
                if let Some(fluid) = config.pore_fluid.as_mut() {
                    fluid.hydraulic[k].mobility = value / fluid.unit_weight;
                }
            }
        }
        Ok(())
    }

    /// The pore fluid of a coupled run and material `k`'s hydraulic properties.
    ///
    /// # Errors
    /// A run without a pore fluid or a material it does not have.
    fn hydraulic<'a, const D: usize>(
        &self,
        config: &'a ImplicitConfig<D>,
        k: usize,
    ) -> Result<(&'a loam_implicit::flow::PoreFluid<D>, &'a Hydraulic), AdjointError> {
        let fluid = config.pore_fluid.as_ref().ok_or_else(|| {
            self.error("the scene has no [pore_fluid]: a hydraulic conductivity needs one")
        })?;
        let h = fluid.hydraulic.get(k).ok_or_else(|| {
            self.error(format!(
                "no such material: the scene has {}",
                fluid.hydraulic.len()
            ))
        })?;
        Ok((fluid, h))
    }

    /// Particle `p`'s loads lifted to `Dual64`, with this parameter seeded where it acts on
    /// them: gravity `∂g/∂g_a`, the point load on `p`, and the balance of the initial
    /// stress at its rate `balance_rate[p]` (empty where the parameter does not move it).
    pub fn seeded_loads<const D: usize>(
        &self,
        config: &ImplicitConfig<D>,
        loads: &Loads<f64, D>,
        p: usize,
        balance_rate: &[Vector<f64, D>],
    ) -> Loads<Dual64, D> {
        let mut loads = lift_loads(loads);
        match *self {
            Self::Gravity(a) => loads.gravity[a].eps = 1.0,
            Self::PointLoad(j, a) if config.point_loads[j].particle == p => {
                loads.point[a].eps = 1.0
            }
            _ => {}
        }
        if let Some(rate) = balance_rate.get(p) {
            for a in 0..D {
                loads.balance[a].eps = rate[a];
            }
        }
        loads
    }

    /// Material `k`'s hydraulic properties lifted to `Dual64`, with the mobility seeded
    /// (`dκ/dk = 1/γ_w`) when this is its conductivity.
    pub fn seeded_hydraulic<const D: usize>(
        &self,
        fluid: &loam_implicit::flow::PoreFluid<D>,
        k: usize,
    ) -> Hydraulic<Dual64> {
        let mut h = fluid.hydraulic[k].lift::<Dual64>();
        if *self == Self::Conductivity(k) {
            h.mobility.eps = 1.0 / fluid.unit_weight;
        }
        h
    }

    /// `ds_p/dθ` of the initial particle states ([`super::kernel::ParticleState::components`]
    /// order) that depend on this parameter, as `(particle, tangent)`: a density moves the
    /// masses `m_p = ρ₀ V⁰_p`; in a prestressed scene ([`ImplicitConfig::gravity_in_full`]) a
    /// constant of a model with elastic history moves the history that carries the particle's
    /// initial Kirchhoff stress `τ₀` (held: it is data), `h₀ = h(τ₀; θ)`
    /// ([`Material::prestressed_state`] with the constant seeded). Empty for every other
    /// parameter.
    pub fn initial_tangent<const D: usize>(
        &self,
        config: &ImplicitConfig<D>,
        initial: &Particles<f64, D>,
    ) -> Vec<(usize, Vec<f64>)> {
        if let Self::K0(k) = *self {
            let Ok(rates) = self.k0_rates(config, initial, k) else {
                return Vec::new();
            };
            return (rates.rates(&config.materials[k], initial).into_iter())
                .map(|(p, _, h)| (p, state_tangent::<D>(&h)))
                .collect();
        }
        let Self::Material(k, field) = *self else {
            return Vec::new();
        };
        let mine = (0..initial.len()).filter(|&p| initial.material[p] as usize == k);
        if field == MaterialField::Density {
            return mine
                .map(|p| {
                    let mut t = vec![0.0; state_len(D)];
                    t[mass_index(D)] = initial.volume0[p];
                    (p, t)
                })
                .collect();
        }
        let Some(seeded) = (config.gravity_in_full)
            .then(|| self.seeded_material(k, &config.materials[k]))
            .flatten()
        else {
            return Vec::new();
        };
        initial_stresses(config, initial, k)
            .into_iter()
            .filter_map(|(p, tau0)| {
                let h = seeded.prestressed_state(&tau0.map(Dual64::from_re))?;
                Some((p, state_tangent::<D>(&h.map(|c| c.eps))))
            })
            .collect()
    }

    /// Per particle, the derivative of its balancing force ([`ImplicitConfig::balance`]) by
    /// this parameter: for a K0 in a scene that balances its initial stress, the balance of
    /// the stress rates ∂τ₀/∂K0 ([`loam_implicit::balance_rate`]); empty for every other
    /// parameter, whose balance is data of the initial state (the stress it balances is
    /// held).
    ///
    /// # Errors
    /// As [`ImplicitParam::value`], or a balance that cannot be computed.
    pub fn balance_tangent<const D: usize>(
        &self,
        config: &ImplicitConfig<D>,
        initial: &Particles<f64, D>,
    ) -> Result<Vec<Vector<f64, D>>, AdjointError> {
        let Self::K0(k) = *self else {
            return Ok(Vec::new());
        };
        if config.balance.is_empty() {
            return Ok(Vec::new());
        }
        let mut rates = vec![Matrix3::zeros(); initial.len()];
        for (p, _, rate) in self.k0_rates(config, initial, k)?.particles {
            rates[p] = rate;
        }
        Ok(loam_implicit::balance_rate(config, initial, &rates)?)
    }

    /// The K0 state of material `k`'s particles ([`K0State::of`]).
    ///
    /// # Errors
    /// As [`K0State::of`], named by the parameter.
    pub fn k0_rates<const D: usize>(
        &self,
        config: &ImplicitConfig<D>,
        particles: &Particles<f64, D>,
        k: usize,
    ) -> Result<K0State, AdjointError> {
        let material = self.material(config, k)?;
        K0State::of(material, &config.gravity, particles, k).map_err(|m| self.error(m))
    }

    /// Sets the K0 of material `k`'s particles to `value` ([`ImplicitParam::k0_rates`]): their
    /// initial stress `τ₀ + (K0′ − K0) ∂τ₀/∂K0`, the history that carries it, their Cauchy
    /// stress `τ₀/J`, and the balancing forces where the scene balances its initial stress.
    fn set_k0<const D: usize>(
        &self,
        config: &mut ImplicitConfig<D>,
        particles: &mut Particles<f64, D>,
        k: usize,
        value: f64,
    ) -> Result<(), AdjointError> {
        let state = self.k0_rates(config, particles, k)?;
        (state.set(&config.materials[k], particles, value)).map_err(|m| self.error(m))?;
        if !config.balance.is_empty() {
            config.balance = loam_implicit::balance_initial_stress(config, particles)?.forces;
        }
        Ok(())
    }

    /// Material `k` lifted to `Dual64` with this parameter seeded when it is one of its
    /// constants (other than the density, which acts through the masses); `None` otherwise.
    pub fn seeded_material(&self, k: usize, material: &Material<f64>) -> Option<Material<Dual64>> {
        match *self {
            Self::Material(j, field) if j == k && field != MaterialField::Density => {
                seed_material(material, field).map(|s| s.0)
            }
            _ => None,
        }
    }
}

/// A particle state's tangent ([`super::kernel::ParticleState::components`] order) that moves
/// only its history, by `dh`.
fn state_tangent<const D: usize>(dh: &MaterialState<f64>) -> Vec<f64> {
    let mut t = vec![0.0; state_len(D)];
    let h0 = D + D * D;
    t[h0..h0 + HISTORY_LEN].copy_from_slice(&dh.components());
    t
}

/// The Kirchhoff stress `τ₀` each particle of material `k` carries at rest in `particles`:
/// the material's update with `ΔF = I` from its history (the particles of a prestressed body
/// start at `F = I`).
fn initial_stresses<const D: usize>(
    config: &ImplicitConfig<D>,
    particles: &Particles<f64, D>,
    k: usize,
) -> Vec<(usize, Matrix3<f64>)> {
    let material = &config.materials[k];
    let identity = Matrix3::identity();
    (0..particles.len())
        .filter(|&p| particles.material[p] as usize == k)
        .map(|p| {
            let (tau, _) = material.kirchhoff_update(&identity, &identity, &particles.state[p]);
            (p, tau)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_read_back_what_display_writes() {
        for p in [
            ImplicitParam::Material(1, MaterialField::YieldStress),
            ImplicitParam::Material(0, MaterialField::Density),
            ImplicitParam::K0(3),
            ImplicitParam::Gravity(1),
            ImplicitParam::PointLoad(2, 0),
            ImplicitParam::Displacement(0, 1),
            ImplicitParam::ConstraintForce(1, 0),
            ImplicitParam::Conductivity(2),
        ] {
            assert_eq!(p.to_string().parse::<ImplicitParam>(), Ok(p));
        }
        for bad in [
            "materials[0].viscosity",
            "point_loads[0].force",
            "constraints[1].displacement[x]",
            "constraints[1].force",
            "friction[0]",
        ] {
            let err = bad.parse::<ImplicitParam>().unwrap_err();
            assert!(err.contains(bad) && err.contains("expected"), "{err}");
        }
    }
}
