//! An inverse problem: the unknowns of a run (parameters of the setup, initial velocities and
//! initial velocity fields), the loss over the run as a function of them, its gradient by the
//! adjoint and, as the oracle, its derivative by a forward-mode dual run.

use crate::checkpoints::Checkpoints;
use crate::error::AdjointError;
use crate::field::VelocityField;
use crate::gradient::{Phases, gradient};
use crate::k0::K0State;
use crate::objective::{Objective, Pullback, ScalarObjective};
use crate::params::{MaterialField, Param};
use loam_core::constitutive::MaterialState;
use loam_core::{Particles, Scalar};
use loam_explicit::{Config, Solver};
use nalgebra::Matrix3;
use num_dual::Dual64;
use std::collections::BTreeMap;

/// One unknown of an inversion: a scalar `θ`, or a block of them (a velocity field's
/// weights). The unknowns of a [`Problem`] are the controls' values one after the other.
#[derive(Clone, Debug, PartialEq)]
pub enum Control {
    /// A parameter of the step or of the initial masses (the density).
    Param(Param),
    /// The component along the unit vector `direction` of the initial velocity of the
    /// particles of material `material` (all particles when `None`):
    /// `v_p ← v_p + (θ − v_p·d) d`, the other components kept. A uniform velocity vector is
    /// one control per axis; a speed along a direction is one control. Its gradient is
    /// `dL/dθ = Σ_p (∂L/∂v_p⁰)·d` over those particles.
    InitialVelocity {
        /// The material whose particles it sets, or all particles.
        material: Option<u32>,
        /// The unit vector `d` (`D` components).
        direction: Vec<f64>,
    },
    /// The initial velocity along a direction given by an MLP of the initial position: its
    /// [`Mlp::len`](crate::Mlp::len) weights and biases, in the network's order.
    VelocityField(VelocityField),
    /// `K0`, the lateral earth-pressure coefficient of the geostatic initial stress of the
    /// particles of material `material` (`materials[k].k0`, [`K0State`]): it sets their
    /// initial stress and history. Its gradient is
    /// `dL/dK0 = Σ_p σ̄_p : ∂σ_p/∂K0 + h̄_p · ∂h_p/∂K0` over those particles.
    K0 {
        /// The material `k`.
        material: usize,
    },
}

impl Control {
    /// The particles it acts on.
    fn selects(&self, material: u32) -> bool {
        match self {
            Control::InitialVelocity {
                material: Some(m), ..
            } => *m == material,
            Control::VelocityField(f) => f.selects(material),
            _ => true,
        }
    }

    /// How many scalar unknowns it holds (1, or a field's weights).
    pub fn len(&self) -> usize {
        match self {
            Control::VelocityField(f) => f.mlp.len(),
            _ => 1,
        }
    }

    /// Whether it holds no unknown (a field with no layer).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The K0 state a [`Control::K0`] sets, of `particles` under `config`.
    ///
    /// # Errors
    /// A material the scene does not have, or as [`K0State::of`] (named by the parameter).
    fn k0_state<const D: usize>(
        material: usize,
        config: &Config<f64, D>,
        particles: &Particles<f64, D>,
    ) -> Result<K0State, AdjointError> {
        let error = |msg: String| AdjointError::Parameter {
            param: format!("materials[{material}].k0"),
            msg,
        };
        let m = config.materials.get(material).ok_or_else(|| {
            error(format!(
                "no such material: the scene has {}",
                config.materials.len()
            ))
        })?;
        K0State::of(m, &config.gravity, particles, material).map_err(error)
    }
}

/// What one gradient took: the adjoint's segment length `K`, its memory model's bytes
/// ([`crate::Footprint::bytes`]) and the wall time of its parts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GradientCost {
    /// Steps per segment between checkpoints.
    pub segment: usize,
    /// The memory model's bytes at that segment length.
    pub memory: u64,
    /// Where the wall time went.
    pub phases: Phases,
}

/// A Gauss–Newton model of a least-squares loss `L = c Σᵢ rᵢ(θ)²` at a point: `∇L = 2c Jᵀr`
/// and the Hessian less its terms in `∂²r`, `H = 2c JᵀJ`, with `J = ∂r/∂θ`. `c = 1` for
/// an explicit run ([`Problem::gauss_newton`]), `c = ½` for element tests
/// ([`crate::element::ElementProblem::gauss_newton`]).
#[derive(Clone, Debug, PartialEq)]
pub struct GaussNewtonModel {
    /// `L`.
    pub loss: f64,
    /// `∇L = 2c Jᵀr`.
    pub gradient: Vec<f64>,
    /// `H = 2c JᵀJ`, row-major, `n × n`.
    pub matrix: Vec<f64>,
}

impl GaussNewtonModel {
    /// The model of `L = c Σᵢ rᵢ²` from the residuals `r` and the columns `J_{·k} = ∂r/∂θ_k`.
    pub fn new(c: f64, residuals: &[f64], columns: &[Vec<f64>]) -> Self {
        let n = columns.len();
        let dot = |a: &[f64], b: &[f64]| -> f64 { a.iter().zip(b).map(|(a, b)| a * b).sum() };
        let mut matrix = vec![0.0; n * n];
        for k in 0..n {
            for l in 0..=k {
                matrix[k * n + l] = 2.0 * c * dot(&columns[k], &columns[l]);
                matrix[l * n + k] = matrix[k * n + l];
            }
        }
        Self {
            loss: c * dot(residuals, residuals),
            gradient: columns
                .iter()
                .map(|col| 2.0 * c * dot(col, residuals))
                .collect(),
            matrix,
        }
    }

    /// The model at a trial point of `n` unknowns where the run cannot be completed: `L = ∞`,
    /// a zero gradient and a zero matrix, so that an optimiser shortens (or damps) its step
    /// instead of ending the inversion.
    pub fn unbounded(n: usize) -> Self {
        Self {
            loss: f64::INFINITY,
            gradient: vec![0.0; n],
            matrix: vec![0.0; n * n],
        }
    }
}

/// A loss over an explicit run as a function of its unknowns `θ`.
#[derive(Clone, Debug)]
pub struct Problem<const D: usize, O> {
    /// The solver configuration at the scene's values.
    pub config: Config<f64, D>,
    /// The initial particle state at the scene's values.
    pub initial: Particles<f64, D>,
    /// Steps of the run.
    pub steps: usize,
    /// The unknowns, in order.
    pub controls: Vec<Control>,
    /// The loss.
    pub objective: O,
    /// How the adjoint chooses its segment length between checkpoints.
    pub checkpoints: Checkpoints,
}

impl<const D: usize, O: ScalarObjective<D>> Problem<D, O> {
    /// The number of scalar unknowns, `Σ` [`Control::len`].
    pub fn len(&self) -> usize {
        self.controls.iter().map(Control::len).sum()
    }

    /// Whether it has no unknown.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Each control with its slice of `theta` (of [`Problem::len`] values).
    pub fn split<'a>(&'a self, theta: &'a [f64]) -> impl Iterator<Item = (&'a Control, &'a [f64])> {
        let mut at = 0;
        self.controls.iter().map(move |c| {
            at += c.len();
            (c, &theta[at - c.len()..at])
        })
    }

    /// The values of the unknowns in the scene (an initial velocity: the mean of `v_p·d`
    /// over its particles; a velocity field: its Glorot initialisation from its seed).
    ///
    /// # Errors
    /// A parameter the configuration does not have, or a velocity with no particle.
    pub fn values(&self) -> Result<Vec<f64>, AdjointError> {
        let mut out = Vec::with_capacity(self.len());
        for c in &self.controls {
            match c {
                Control::Param(p) => out.push(p.value(&self.config)?),
                Control::VelocityField(f) => out.extend(f.mlp.glorot(f.seed)),
                Control::K0 { material } => {
                    out.push(Control::k0_state(*material, &self.config, &self.initial)?.k0)
                }
                Control::InitialVelocity { direction, .. } => {
                    let along: Vec<f64> = (0..self.initial.len())
                        .filter(|&p| c.selects(self.initial.material[p]))
                        .map(|p| (0..D).map(|a| self.initial.v[p][a] * direction[a]).sum())
                        .collect();
                    let Some(&first) = along.first() else {
                        return Err(AdjointError::Parameter {
                            param: "initial velocity".into(),
                            msg: "no particle has the material it names".into(),
                        });
                    };
                    // The mean as `a₀ + Σ (aᵢ − a₀) / n`: exactly the value when all agree.
                    let spread: f64 = along.iter().map(|a| a - first).sum();
                    out.push(first + spread / along.len() as f64);
                }
            }
        }
        Ok(out)
    }

    /// The configuration and initial state with the unknowns set to `theta`; a density sets
    /// the masses of its material's particles, `m_p = ρ₀ V⁰_p`.
    ///
    /// # Errors
    /// A parameter the configuration does not have.
    pub fn setup(
        &self,
        theta: &[f64],
    ) -> Result<(Config<f64, D>, Particles<f64, D>), AdjointError> {
        let mut config = self.config.clone();
        let mut particles = self.initial.clone();
        for (control, values) in self.split(theta) {
            match control {
                Control::Param(param) => {
                    let value = values[0];
                    param.set(&mut config, value)?;
                    if let Param::Material(m, MaterialField::Density) = *param {
                        for p in 0..particles.len() {
                            if particles.material[p] as usize == m {
                                particles.mass[p] = value * particles.volume0[p];
                            }
                        }
                    }
                }
                Control::InitialVelocity { direction, .. } => {
                    for p in 0..particles.len() {
                        if control.selects(particles.material[p]) {
                            let v = &mut particles.v[p];
                            let along: f64 = (0..D).map(|a| v[a] * direction[a]).sum();
                            for a in 0..D {
                                v[a] += (values[0] - along) * direction[a];
                            }
                        }
                    }
                }
                Control::VelocityField(field) => field.apply(values, &mut particles),
                Control::K0 { material } => {
                    let state = Control::k0_state(*material, &config, &particles)?;
                    (state.set(&config.materials[*material], &mut particles, values[0])).map_err(
                        |msg| AdjointError::Parameter {
                            param: format!("materials[{material}].k0"),
                            msg,
                        },
                    )?;
                }
            }
        }
        // A prestressed body's initial stress is data: the history that carries it follows
        // the final constants of its material.
        for c in &self.controls {
            if let Control::Param(param) = c {
                for (p, h) in param.initial_histories(&config, &particles)? {
                    particles.state[p] = h.map(|c| c.re);
                }
            }
        }
        Ok((config, particles))
    }

    /// The loss at `theta`, by a forward run.
    ///
    /// # Errors
    /// As [`Problem::setup`], or a run that is refused or stops.
    pub fn loss(&self, theta: &[f64]) -> Result<f64, AdjointError> {
        let (config, particles) = self.setup(theta)?;
        run_value(config, particles, self.steps, &self.objective)
    }

    /// The loss and `dL/dθ` at `theta`, by the discrete adjoint ([`gradient`]); a velocity
    /// field's weights chain the adjoint of the initial velocities through the network
    /// ([`VelocityField::gradient`]).
    ///
    /// # Errors
    /// As [`gradient`].
    pub fn gradient(&self, theta: &[f64]) -> Result<(f64, Vec<f64>), AdjointError> {
        self.gradient_and_cost(theta).map(|(loss, g, _)| (loss, g))
    }

    /// [`Problem::gradient`], with what the adjoint took to compute it.
    ///
    /// # Errors
    /// As [`gradient`].
    pub fn gradient_and_cost(
        &self,
        theta: &[f64],
    ) -> Result<(f64, Vec<f64>, GradientCost), AdjointError> {
        let (loss, derivative, cost) = self.adjoint(theta, &self.objective)?;
        Ok((loss, derivative, cost))
    }

    /// The quantities `y` the objective observes in the run at `theta`: every observed
    /// step's ([`ScalarObjective::observed`]) in the order of the steps.
    ///
    /// # Errors
    /// As [`Problem::loss`].
    pub fn observe(&self, theta: &[f64]) -> Result<Vec<f64>, AdjointError> {
        let (config, particles) = self.setup(theta)?;
        run_collected(config, particles, self.steps, |s, p, out| {
            self.objective.observed(s, p, out)
        })
    }

    /// `∂y/∂θ_k` of every observed quantity ([`Problem::observe`]) by a forward-mode dual run
    /// ([`Problem::seeded`]): a column of the observations' Jacobian, the oracle of
    /// [`Problem::vjp`].
    ///
    /// # Errors
    /// As [`Problem::loss`].
    pub fn observe_tangent(&self, theta: &[f64], k: usize) -> Result<Vec<f64>, AdjointError> {
        let (config, particles) = self.seeded(theta, k)?;
        let y = run_collected(config, particles, self.steps, |s, p, out| {
            self.objective.observed(s, p, out)
        })?;
        Ok(y.iter().map(|y| y.eps).collect())
    }

    /// The vector–Jacobian product `ȳᵀ ∂y/∂θ` of the observed quantities
    /// ([`Problem::observe`]) with the cotangent `ȳ` (one value per quantity, in their
    /// order), by the adjoint seeded with `ȳ` ([`Pullback`]) instead of `∂L/∂y`; with
    /// `ȳ = ∂L/∂y = 2c (y − d)` it is `dL/dθ`.
    ///
    /// # Errors
    /// A cotangent whose length is not the number of observed quantities, or as
    /// [`Problem::gradient`].
    pub fn vjp(&self, theta: &[f64], cotangent: &[f64]) -> Result<Vec<f64>, AdjointError> {
        let mut at = 0;
        let mut per_step = BTreeMap::new();
        let mut data = Vec::new();
        for step in 0..=self.steps {
            data.clear();
            self.objective.data(step, &mut data);
            if !data.is_empty() && at + data.len() <= cotangent.len() {
                per_step.insert(step, cotangent[at..at + data.len()].to_vec());
            }
            at += data.len();
        }
        if at != cotangent.len() {
            return Err(AdjointError::cotangent_length(cotangent.len(), at));
        }
        let pullback = Pullback {
            objective: &self.objective,
            cotangent: per_step,
        };
        Ok(self.adjoint(theta, &pullback)?.1)
    }

    /// What each observed quantity is, in the order of [`Problem::observe`]
    /// (`step 100: x of particle 12`), with its data `d` and weight `c`
    /// (`L = Σ c (y − d)²`).
    pub fn labelled(&self) -> Vec<(String, f64, f64)> {
        let (mut labels, mut data) = (Vec::new(), Vec::new());
        let mut out = Vec::new();
        for step in 0..=self.steps {
            labels.clear();
            data.clear();
            self.objective.labels(step, &mut labels);
            self.objective.data(step, &mut data);
            out.extend(
                (labels.drain(..).zip(&data))
                    .map(|(l, &(d, c))| (format!("step {step}: {l}"), d, c)),
            );
        }
        out
    }

    /// The adjoint of the run at `theta` seeded by `objective`: its value, its gradient in
    /// every unknown and what it took.
    fn adjoint(
        &self,
        theta: &[f64],
        objective: &impl Objective<D>,
    ) -> Result<(f64, Vec<f64>, GradientCost), AdjointError> {
        let (config, particles) = self.setup(theta)?;
        let g = gradient(
            &config,
            &particles,
            self.steps,
            &self.params(),
            objective,
            self.checkpoints,
        )?;
        let mut from_params = g.params.iter();
        let mut derivative = Vec::with_capacity(theta.len());
        for (c, values) in self.split(theta) {
            match c {
                // `gradient` returns the parameters in the order asked for.
                Control::Param(_) => {
                    derivative.push(from_params.next().copied().unwrap_or_default())
                }
                Control::InitialVelocity { direction, .. } => derivative.push(
                    (0..particles.len())
                        .filter(|&p| c.selects(particles.material[p]))
                        .map(|p| {
                            (0..D)
                                .map(|a| g.initial.v[p][a] * direction[a])
                                .sum::<f64>()
                        })
                        .sum(),
                ),
                Control::VelocityField(f) => {
                    derivative.extend(f.gradient(values, &particles, &g.initial))
                }
                Control::K0 { material } => {
                    let state = Control::k0_state(*material, &config, &particles)?;
                    let rates = state.rates(&config.materials[*material], &particles);
                    derivative.push(
                        (rates.iter())
                            .map(|(p, ds, dh)| {
                                let bar = g.initial.history[*p].components();
                                g.initial.stress[*p].dot(ds)
                                    + bar
                                        .iter()
                                        .zip(dh.components())
                                        .map(|(b, d)| b * d)
                                        .sum::<f64>()
                            })
                            .sum(),
                    )
                }
            }
        }
        let cost = GradientCost {
            segment: g.segment,
            memory: g.memory,
            phases: g.phases,
        };
        Ok((g.loss, derivative, cost))
    }

    /// The parameters of the step among the controls, in order.
    pub fn params(&self) -> Vec<Param> {
        (self.controls.iter())
            .filter_map(|c| match c {
                Control::Param(p) => Some(*p),
                Control::InitialVelocity { .. }
                | Control::VelocityField(_)
                | Control::K0 { .. } => None,
            })
            .collect()
    }

    /// `dL/dθ_k` at `theta` by a forward-mode dual run ([`Problem::seeded`]).
    ///
    /// # Errors
    /// As [`Problem::loss`].
    pub fn dual_derivative(&self, theta: &[f64], k: usize) -> Result<f64, AdjointError> {
        let (config, particles) = self.seeded(theta, k)?;
        Ok(run_value(config, particles, self.steps, &self.objective)?.eps)
    }

    /// The Gauss–Newton model of the loss at `theta` from the residuals `r` of
    /// `L = Σᵢ rᵢ²` ([`ScalarObjective::residuals`]) and their Jacobian `J = ∂r/∂θ`, one
    /// column per forward-mode dual run ([`Problem::seeded`]): `L`, `∇L = 2 Jᵀr` (exact, as
    /// the adjoint's) and `H = 2 JᵀJ`, the Hessian without the terms in `∂²r/∂θ²` (which
    /// vanish at a zero-residual minimum). It costs one dual run per unknown, so it suits an
    /// inversion of a few parameters.
    ///
    /// # Errors
    /// As [`Problem::loss`].
    pub fn gauss_newton(&self, theta: &[f64]) -> Result<GaussNewtonModel, AdjointError> {
        let n = theta.len();
        let mut residuals = Vec::new();
        let mut columns = Vec::with_capacity(n);
        for k in 0..n {
            let (config, particles) = self.seeded(theta, k)?;
            let r = run_collected(config, particles, self.steps, |s, p, out| {
                self.objective.residuals(s, p, out)
            })?;
            if k == 0 {
                residuals = r.iter().map(|r| r.re).collect();
            }
            columns.push(r.iter().map(|r| r.eps).collect::<Vec<f64>>());
        }
        Ok(GaussNewtonModel::new(1.0, &residuals, &columns))
    }

    /// The configuration and particles at `theta` lifted to `Dual64` with unknown `k` seeded:
    /// the parameter seeded ([`Param::seeded`]; a density also seeds the masses,
    /// `dm_p/dρ₀ = V⁰_p`), or the initial velocities seeded with `dv_p/dθ = d`, or, for a
    /// weight `w` of a velocity field, `dv_p/dw = d ∂f(x̂_p)/∂w` from the network evaluated
    /// with that weight seeded.
    ///
    /// # Errors
    /// As [`Problem::loss`].
    pub fn seeded(
        &self,
        theta: &[f64],
        k: usize,
    ) -> Result<(Config<Dual64, D>, Particles<Dual64, D>), AdjointError> {
        let (config, particles) = self.setup(theta)?;
        let mut lifted: Particles<Dual64, D> = particles.lift();
        let mut start = 0;
        let (control, values) = (self.split(theta))
            .find(|(c, _)| {
                start += c.len();
                k < start
            })
            .expect("k is below the number of unknowns");
        let index = k + control.len() - start;
        let seeded = match control {
            Control::Param(param) => {
                if let Param::Material(m, MaterialField::Density) = *param {
                    for p in 0..lifted.len() {
                        if particles.material[p] as usize == m {
                            lifted.mass[p].eps = particles.volume0[p];
                        }
                    }
                }
                for (p, h) in param.initial_histories(&config, &particles)? {
                    lifted.state[p] = h;
                }
                param.seeded(&config)?
            }
            Control::InitialVelocity { direction, .. } => {
                for p in 0..lifted.len() {
                    if control.selects(particles.material[p]) {
                        for a in 0..D {
                            lifted.v[p][a].eps = direction[a];
                        }
                    }
                }
                config.lift()
            }
            Control::VelocityField(field) => {
                let w: Vec<Dual64> = (values.iter().enumerate())
                    .map(|(i, &w)| Dual64::new(w, if i == index { 1.0 } else { 0.0 }))
                    .collect();
                for p in field.particles(&particles) {
                    let df = field.value(&w, &self.initial, p).eps;
                    for a in 0..D {
                        lifted.v[p][a].eps = field.direction[a] * df;
                    }
                }
                config.lift()
            }
            Control::K0 { material } => {
                let state = Control::k0_state(*material, &config, &particles)?;
                for (p, ds, dh) in state.rates(&config.materials[*material], &particles) {
                    let (s, h) = (particles.stress[p], particles.state[p].components());
                    lifted.stress[p] = Matrix3::from_fn(|i, j| Dual64::new(s[(i, j)], ds[(i, j)]));
                    let dh = dh.components();
                    lifted.state[p] = MaterialState::from_components(|c| Dual64::new(h[c], dh[c]));
                }
                config.lift()
            }
        };
        Ok((seeded, lifted))
    }
}

/// `L = Σ_n ℓ_n` over a forward run of `steps` steps in any scalar type
/// ([`ScalarObjective::value`]).
///
/// # Errors
/// A run that is refused or stops.
pub fn run_value<T: Scalar, const D: usize, O: ScalarObjective<D>>(
    config: Config<T, D>,
    particles: Particles<T, D>,
    steps: usize,
    objective: &O,
) -> Result<T, AdjointError> {
    let mut loss = T::zero();
    run_each(config, particles, steps, |s, p| {
        loss += objective.value(s, p)
    })?;
    Ok(loss)
}

/// What `collect(step, state, out)` appends to `out` for every state of a forward run of
/// `steps` steps (step 0 the initial state), in the order of the steps: the observed
/// quantities ([`ScalarObjective::observed`]) or the residuals
/// ([`ScalarObjective::residuals`]) of a run, in any scalar type.
///
/// # Errors
/// A run that is refused or stops.
pub fn run_collected<T: Scalar, const D: usize>(
    config: Config<T, D>,
    particles: Particles<T, D>,
    steps: usize,
    mut collect: impl FnMut(usize, &Particles<T, D>, &mut Vec<T>) + Send,
) -> Result<Vec<T>, AdjointError> {
    let mut out = Vec::new();
    run_each(config, particles, steps, |s, p| collect(s, p, &mut out))?;
    Ok(out)
}

/// Runs `steps` steps, handing the state after each (and the initial one, step 0) to `visit`,
/// on the rayon pool with its other workers awake ([`loam_explicit::pool::hold`]).
fn run_each<T: Scalar, const D: usize>(
    config: Config<T, D>,
    mut particles: Particles<T, D>,
    steps: usize,
    mut visit: impl FnMut(usize, &Particles<T, D>) + Send,
) -> Result<(), AdjointError> {
    let mut solver = Solver::new(config, &particles)?;
    loam_explicit::pool::hold(|| {
        visit(0, &particles);
        for s in 1..=steps {
            solver.step(&mut particles, f64::INFINITY)?;
            visit(s, &particles);
        }
        Ok(())
    })
}
