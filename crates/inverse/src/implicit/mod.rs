//! Back-analysis through the implicit path: the exact gradient of a loss over a quasi-static
//! load-stepped or a Newmark run (`loam_implicit::ImplicitSolver`) by the discrete adjoint of
//! its accepted sub-steps, with plastic history.
//!
//! - [`record`]: the forward pass, keeping per accepted sub-step the particle state at its
//!   start, its load factors and its converged unknowns (a cut load step is the sequence of
//!   sub-steps it was accepted as).
//! - [`kernel`]: one particle's part of a sub-step, generic over the scalar.
//! - [`pullback`]: a particle's sub-step linearised (the Jacobians of its stencil and of its
//!   stress update, one multi-lane dual evaluation each) and its local vector–Jacobian
//!   products by the chain rule.
//! - [`adjoint`]: backwards over the sub-steps, one transposed solve `Jᵀλ = …` with the
//!   sub-step's tangent, then the state's adjoint and the parameters' shares per particle.
//! - [`inertia`]: the grid terms of a Newmark sub-step (mass matrix, momentum, the mass
//!   solve of the velocity update) in both passes.
//! - [`tangent`]: the forward-mode dual derivative (the oracle); [`check`]: central
//!   differences and the Taylor test on the reference run's sub-steps.
//! - [`ImplicitParam`], [`ImplicitObservations`]: what is differentiated and observed;
//!   [`Identifiability`]: how well they identify the parameters (Gauss–Newton).

pub mod adjoint;
pub mod check;
pub mod coupled;
mod identify;
pub mod inertia;
pub mod kernel;
mod observe;
mod params;
pub mod pullback;
pub mod record;
mod seeds;
pub mod tangent;

pub use identify::Identifiability;
pub use observe::{ImplicitObservations, Observation, Quantity};
pub use params::ImplicitParam;
pub use record::{Schedule, Trajectory, run_for_gradient, run_recorded};

use crate::error::AdjointError;
use loam_core::Particles;
use loam_implicit::ImplicitConfig;
use std::time::Instant;

/// A least-squares loss over an implicit run (quasi-static or Newmark) as a function of parameters `θ`.
#[derive(Clone, Debug)]
pub struct ImplicitProblem<const D: usize> {
    /// The solver configuration at the scene's values.
    pub config: ImplicitConfig<D>,
    /// The initial particles at the scene's values.
    pub initial: Particles<f64, D>,
    /// The parameters, in the order of `θ`.
    pub params: Vec<ImplicitParam>,
    /// The observations.
    pub observations: ImplicitObservations,
}

/// A loss and its gradient, with the time of each pass.
#[derive(Clone, Debug, PartialEq)]
pub struct ImplicitGradient {
    /// `L(θ)`.
    pub loss: f64,
    /// `dL/dθ`.
    pub gradient: Vec<f64>,
    /// Seconds of the forward run (with its recording).
    pub forward_seconds: f64,
    /// Seconds of the reverse pass.
    pub reverse_seconds: f64,
}

impl<const D: usize> ImplicitProblem<D> {
    /// Checks the parameters and observations against the scene.
    ///
    /// # Errors
    /// A parameter or an observation that does not fit (named by its field).
    pub fn validate(&self) -> Result<(), AdjointError> {
        for p in &self.params {
            p.value(&self.config, &self.initial)?;
        }
        self.observations.validate(&self.config, &self.initial)
    }

    /// The parameters' values in the scene.
    ///
    /// # Errors
    /// As [`ImplicitProblem::validate`].
    pub fn values(&self) -> Result<Vec<f64>, AdjointError> {
        self.params
            .iter()
            .map(|p| p.value(&self.config, &self.initial))
            .collect()
    }

    /// The configuration and particles with the parameters set to `theta`.
    ///
    /// # Errors
    /// As [`ImplicitProblem::validate`].
    pub fn setup(
        &self,
        theta: &[f64],
    ) -> Result<(ImplicitConfig<D>, Particles<f64, D>), AdjointError> {
        let mut config = self.config.clone();
        let mut particles = self.initial.clone();
        for (p, &v) in self.params.iter().zip(theta) {
            p.set(&mut config, &mut particles, v)?;
        }
        Ok((config, particles))
    }

    /// `L(θ)`, the run taking its own sub-steps (cutting where Newton fails), or those of
    /// `schedule` (see [`run_recorded`]).
    ///
    /// # Errors
    /// As [`ImplicitProblem::validate`], or a forward run that stops.
    pub fn loss(&self, theta: &[f64], schedule: Option<&Schedule>) -> Result<f64, AdjointError> {
        let (config, particles) = self.setup(theta)?;
        Ok(self
            .observations
            .loss(&run_recorded(&config, &particles, schedule)?))
    }

    /// The sub-steps the run at `theta` takes.
    ///
    /// # Errors
    /// As [`ImplicitProblem::loss`].
    pub fn schedule(&self, theta: &[f64]) -> Result<Schedule, AdjointError> {
        let (config, particles) = self.setup(theta)?;
        Ok(run_recorded(&config, &particles, None)?.schedule())
    }

    /// `L(θ)` and `dL/dθ` by the adjoint.
    ///
    /// # Errors
    /// As [`ImplicitProblem::loss`], or an adjoint system that cannot be solved.
    pub fn gradient(&self, theta: &[f64]) -> Result<ImplicitGradient, AdjointError> {
        self.validate()?;
        let (config, particles) = self.setup(theta)?;
        let clock = Instant::now();
        let run = run_for_gradient(&config, &particles)?;
        let forward_seconds = clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        let gradient =
            adjoint::reverse(&config, &particles, &run, &self.observations, &self.params)?;
        Ok(ImplicitGradient {
            loss: self.observations.loss(&run),
            gradient,
            forward_seconds,
            reverse_seconds: clock.elapsed().as_secs_f64(),
        })
    }

    /// The model value `m_k` of every observation ([`ImplicitObservations::model`]) in the run
    /// at `theta`, in the order of the observations.
    ///
    /// # Errors
    /// As [`ImplicitProblem::loss`].
    pub fn observe(&self, theta: &[f64]) -> Result<Vec<f64>, AdjointError> {
        self.with_run(theta, |_, _, run| {
            let items = &self.observations.items;
            Ok(items
                .iter()
                .map(|o| ImplicitObservations::model(o, run))
                .collect())
        })
    }

    /// The vector–Jacobian product `ȳᵀ ∂m/∂θ` of the observations' model values
    /// ([`ImplicitProblem::observe`]) with `cotangent` (one value per observation), by the
    /// adjoint seeded with `ȳ` ([`adjoint::pull_back`]); with `ȳ_k = (m_k − d_k)/σ_k²` it is
    /// `dL/dθ`.
    ///
    /// # Errors
    /// A cotangent whose length is not the number of observations, or as
    /// [`ImplicitProblem::gradient`].
    pub fn vjp(&self, theta: &[f64], cotangent: &[f64]) -> Result<Vec<f64>, AdjointError> {
        let n = self.observations.items.len();
        if cotangent.len() != n {
            return Err(AdjointError::cotangent_length(cotangent.len(), n));
        }
        self.with_run(theta, |config, particles, run| {
            adjoint::pull_back(
                config,
                particles,
                run,
                &self.observations,
                cotangent,
                &self.params,
            )
        })
    }

    /// `(L, dL/dθ)` at an optimiser's trial point: as [`ImplicitProblem::gradient`], but a
    /// forward run that stops (Newton fails on every cut of a load step: a material too soft
    /// to carry its load) gives `L = ∞` and a zero gradient, so that a line search shortens
    /// its step instead of ending the inversion.
    ///
    /// # Errors
    /// As [`ImplicitProblem::gradient`], but for a run that stops.
    pub fn trial_gradient(&self, theta: &[f64]) -> Result<(f64, Vec<f64>), AdjointError> {
        match self.gradient(theta) {
            Ok(g) => Ok((g.loss, g.gradient)),
            Err(AdjointError::Implicit(_)) => Ok((f64::INFINITY, vec![0.0; theta.len()])),
            Err(e) => Err(e),
        }
    }

    /// `dL/dθ` by forward-mode duals, one parameter at a time (the oracle).
    ///
    /// # Errors
    /// As [`ImplicitProblem::gradient`].
    pub fn dual_gradient(&self, theta: &[f64]) -> Result<Vec<f64>, AdjointError> {
        self.with_run(theta, |config, particles, run| {
            (self.params.iter())
                .map(|&p| tangent::dual_derivative(config, particles, run, &self.observations, p))
                .collect()
        })
    }

    /// `dL/dθ_k` by forward-mode duals.
    ///
    /// # Errors
    /// As [`ImplicitProblem::gradient`].
    pub fn dual_derivative(&self, theta: &[f64], k: usize) -> Result<f64, AdjointError> {
        self.with_run(theta, |config, particles, run| {
            tangent::dual_derivative(config, particles, run, &self.observations, self.params[k])
        })
    }

    /// `dm_k/dθ_j` of every observed quantity (index `[j][k]`) by forward-mode duals.
    ///
    /// # Errors
    /// As [`ImplicitProblem::gradient`].
    pub fn sensitivities(&self, theta: &[f64]) -> Result<Vec<Vec<f64>>, AdjointError> {
        self.with_run(theta, |config, particles, run| {
            (self.params.iter())
                .map(|&p| tangent::model_tangents(config, particles, run, &self.observations, p))
                .collect()
        })
    }

    /// The Gauss–Newton analysis of the observations at `theta` ([`Identifiability`]).
    ///
    /// # Errors
    /// As [`ImplicitProblem::gradient`].
    pub fn identifiability(&self, theta: &[f64]) -> Result<Identifiability, AdjointError> {
        let sigma: Vec<f64> = self.observations.items.iter().map(|o| o.sigma).collect();
        Ok(Identifiability::new(
            &self.sensitivities(theta)?,
            theta,
            &sigma,
        ))
    }

    /// The "last step only" gradient ([`adjoint::reverse_last_substep`]): the reverse pass
    /// of the last accepted sub-step alone, the load path before it held fixed.
    ///
    /// # Errors
    /// As [`ImplicitProblem::gradient`].
    pub fn last_step_gradient(&self, theta: &[f64]) -> Result<Vec<f64>, AdjointError> {
        self.with_run(theta, |config, particles, run| {
            adjoint::reverse_last_substep(config, particles, run, &self.observations, &self.params)
        })
    }

    /// `f` of the configuration, the initial particles and the recorded run at `theta`.
    fn with_run<T>(
        &self,
        theta: &[f64],
        f: impl FnOnce(
            &ImplicitConfig<D>,
            &Particles<f64, D>,
            &Trajectory<D>,
        ) -> Result<T, AdjointError>,
    ) -> Result<T, AdjointError> {
        self.validate()?;
        let (config, particles) = self.setup(theta)?;
        let run = run_recorded(&config, &particles, None)?;
        f(&config, &particles, &run)
    }
}
