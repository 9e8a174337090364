//! Observations of an implicit run and the least-squares loss over them.

use super::record::Trajectory;
use crate::error::AdjointError;
use loam_core::Particles;
use loam_implicit::ImplicitConfig;

/// What one observation measures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Quantity {
    /// Component `component` of the displacement `x_p − x_p⁰` of particle `particle`.
    Displacement {
        /// Particle id.
        particle: usize,
        /// Axis.
        component: usize,
    },
    /// Component `component` of the velocity `v_p` of particle `particle` (changes in a
    /// Newmark run only).
    Velocity {
        /// Particle id.
        particle: usize,
        /// Axis.
        component: usize,
    },
    /// Component `component` of the reaction of constraint `constraint` (the force the
    /// prescribed node components exert on the material, `StepReport::constraint_forces`).
    Reaction {
        /// Index into `ImplicitConfig::constraints`.
        constraint: usize,
        /// Axis (a prescribed component of the constraint).
        component: usize,
    },
    /// The pore pressure `p = p_h(x_p) + p_e` (Pa, compression positive: what a piezometer
    /// at the particle reads) of particle `particle` in a coupled (u–p) run.
    PorePressure {
        /// Particle id.
        particle: usize,
    },
}

impl Quantity {
    /// Component `component` of particle `particle`'s displacement.
    pub fn displacement(particle: usize, component: usize) -> Self {
        Quantity::Displacement {
            particle,
            component,
        }
    }

    /// Component `component` of particle `particle`'s velocity.
    pub fn velocity(particle: usize, component: usize) -> Self {
        Quantity::Velocity {
            particle,
            component,
        }
    }

    /// This quantity observed after each load step of `steps`: `(n, self)` for every `n`.
    pub fn after_each(self, steps: impl IntoIterator<Item = usize>) -> Vec<(usize, Quantity)> {
        steps.into_iter().map(|n| (n, self)).collect()
    }
}

/// One measured value after a load step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation {
    /// The load step after which it is measured (1-based).
    pub step: usize,
    /// What is measured.
    pub quantity: Quantity,
    /// The measured value.
    pub value: f64,
    /// Its standard deviation `σ` (the weight of its squared misfit is `1/σ²`).
    pub sigma: f64,
}

impl Observation {
    /// The observation of `quantity` after load step `step` that `run` makes, `d = m(run)`
    /// ([`ImplicitObservations::model`]: a synthetic observation), with standard deviation
    /// `sigma`.
    pub fn of_run<const D: usize>(
        step: usize,
        quantity: Quantity,
        sigma: f64,
        run: &Trajectory<D>,
    ) -> Self {
        let mut o = Self {
            step,
            quantity,
            value: 0.0,
            sigma,
        };
        o.value = ImplicitObservations::model(&o, run);
        o
    }
}

/// A least-squares loss `L = ½ Σ_k ((m_k − d_k)/σ_k)²` over observations `d_k` of model
/// quantities `m_k` of the run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ImplicitObservations {
    /// The observations.
    pub items: Vec<Observation>,
}

impl ImplicitObservations {
    /// Checks every observation against the run; errors name the entry and its field
    /// (`observations[3].particle`).
    ///
    /// # Errors
    /// A load step outside `1..=load_steps`, a particle, constraint or axis that does not
    /// exist, a reaction along a free component, or `σ ≤ 0`.
    pub fn validate<const D: usize>(
        &self,
        config: &ImplicitConfig<D>,
        particles: &Particles<f64, D>,
    ) -> Result<(), AdjointError> {
        for (i, o) in self.items.iter().enumerate() {
            let bad = |field: &str, msg: String| AdjointError::Observation {
                field: format!("observations[{i}].{field}"),
                msg,
            };
            if o.step == 0 || o.step > config.load_steps {
                return Err(bad(
                    "step",
                    format!("must lie in 1..={} (the load steps)", config.load_steps),
                ));
            }
            if !(o.sigma > 0.0 && o.sigma.is_finite()) {
                return Err(bad("sigma", format!("must be positive, got {}", o.sigma)));
            }
            if !o.value.is_finite() {
                return Err(bad("value", "must be finite".into()));
            }
            let missing = |particle: usize| {
                (particle >= particles.len()).then(|| {
                    bad(
                        "particle",
                        format!(
                            "particle {particle} does not exist ({} particles)",
                            particles.len()
                        ),
                    )
                })
            };
            let component = match o.quantity {
                Quantity::PorePressure { particle } => {
                    if config.pore_fluid.is_none() {
                        return Err(bad(
                            "quantity",
                            "a pore pressure is observed in a coupled run only (the scene has \
                             no [pore_fluid])"
                                .into(),
                        ));
                    }
                    if let Some(e) = missing(particle) {
                        return Err(e);
                    }
                    0
                }
                Quantity::Displacement {
                    particle,
                    component,
                }
                | Quantity::Velocity {
                    particle,
                    component,
                } => {
                    if let Some(e) = missing(particle) {
                        return Err(e);
                    }
                    component
                }
                Quantity::Reaction {
                    constraint,
                    component,
                } => {
                    let Some(c) = config.constraints.get(constraint) else {
                        return Err(bad(
                            "constraint",
                            format!(
                                "constraint {constraint} does not exist ({} constraints)",
                                config.constraints.len()
                            ),
                        ));
                    };
                    if c.displacement.get(component).is_some_and(|d| d.is_none()) {
                        return Err(bad(
                            "component",
                            format!(
                                "component {component} of constraint {constraint} is free: it \
                                 has no reaction"
                            ),
                        ));
                    }
                    component
                }
            };
            if component >= D {
                return Err(bad(
                    "component",
                    format!("component {component} does not exist in {D}D"),
                ));
            }
        }
        Ok(())
    }

    /// The model value `m_k` of observation `o` in a run.
    pub fn model<const D: usize>(o: &Observation, run: &Trajectory<D>) -> f64 {
        match o.quantity {
            Quantity::Displacement {
                particle,
                component,
            } => run.positions[o.step][particle][component] - run.positions[0][particle][component],
            Quantity::Velocity {
                particle,
                component,
            } => run.velocities[o.step][particle][component],
            Quantity::Reaction {
                constraint,
                component,
            } => run.reactions[o.step - 1][constraint][component],
            Quantity::PorePressure { particle } => run.pore_pressures[o.step][particle],
        }
    }

    /// What each observation is, in order (`load step 3: y displacement of particle 12`),
    /// with its data `d_k` and weight `c_k = 1/(2σ_k²)` (`L = Σ_k c_k (m_k − d_k)²`).
    pub fn labelled(&self) -> Vec<(String, f64, f64)> {
        let axis = |a: usize| ['x', 'y', 'z'].get(a).copied().unwrap_or('?');
        (self.items.iter())
            .map(|o| {
                let what = match o.quantity {
                    Quantity::Displacement {
                        particle,
                        component,
                    } => format!("{} displacement of particle {particle}", axis(component)),
                    Quantity::Velocity {
                        particle,
                        component,
                    } => format!("{} velocity of particle {particle}", axis(component)),
                    Quantity::Reaction {
                        constraint,
                        component,
                    } => format!("{} reaction of constraint {constraint}", axis(component)),
                    Quantity::PorePressure { particle } => {
                        format!("pore pressure at particle {particle}")
                    }
                };
                let c = 0.5 / (o.sigma * o.sigma);
                (format!("load step {}: {what}", o.step), o.value, c)
            })
            .collect()
    }

    /// `L` of a run.
    pub fn loss<const D: usize>(&self, run: &Trajectory<D>) -> f64 {
        self.items
            .iter()
            .map(|o| 0.5 * ((Self::model(o, run) - o.value) / o.sigma).powi(2))
            .sum()
    }

    /// `∂L/∂m_k = (m_k − d_k)/σ_k²` of every observation, in order.
    pub fn residual_weights<const D: usize>(&self, run: &Trajectory<D>) -> Vec<f64> {
        self.items
            .iter()
            .map(|o| (Self::model(o, run) - o.value) / (o.sigma * o.sigma))
            .collect()
    }
}
