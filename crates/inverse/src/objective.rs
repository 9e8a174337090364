//! What a gradient is the gradient of: a loss over the states of a run.

use crate::adjoint_state::ParticleAdjoint;
use loam_core::tensor::Vector;
use loam_core::{Particles, Scalar};
use std::collections::BTreeMap;

/// A loss `L = Σ_n ℓ_n(state after n steps)`, summed over the states of a run (`n = 0` is
/// the initial state).
pub trait Objective<const D: usize>: Sync {
    /// `ℓ_n` of the state after `step` steps; with `adjoint`, also adds `∂ℓ_n/∂(state)` to it.
    fn term(
        &self,
        step: usize,
        particles: &Particles<f64, D>,
        adjoint: Option<&mut ParticleAdjoint<D>>,
    ) -> f64;
}

/// An objective of least-squares form over quantities observed in the states of a run:
/// `ℓ_n = Σᵢ cᵢ (yᵢ − dᵢ)²`, `yᵢ` the quantities [`ScalarObjective::observed`] after `n`
/// steps, `dᵢ` their data and `cᵢ > 0` their weights ([`ScalarObjective::data`]).
///
/// Its terms can be evaluated in any scalar type, so that a forward-mode dual run
/// (`Solver<Dual64, D>` with one seeded input) gives `dL/dθ` directly: the oracle the adjoint
/// is checked against (`loam gradient --check`). And the quantities themselves can be pulled
/// back ([`ScalarObjective::pull`]): the adjoint of a run seeded with any cotangent `ȳ` of the
/// observations instead of `∂L/∂y` ([`Pullback`]) gives the vector–Jacobian product
/// `ȳᵀ ∂y/∂θ`, for losses defined outside loam.
pub trait ScalarObjective<const D: usize>: Objective<D> {
    /// The quantities `yᵢ` observed in the state after `step` steps, in the scalar type of
    /// the run, appended to `out` (none at a step without observations).
    fn observed<T: Scalar>(&self, step: usize, particles: &Particles<T, D>, out: &mut Vec<T>);

    /// The data `dᵢ` and weights `cᵢ` of the quantities observed after `step` steps, in the
    /// order of [`ScalarObjective::observed`], appended to `out`.
    fn data(&self, step: usize, out: &mut Vec<(f64, f64)>);

    /// What each quantity observed after `step` steps is (`x of particle 12`), in the order
    /// of [`ScalarObjective::observed`], appended to `out`.
    fn labels(&self, step: usize, out: &mut Vec<String>);

    /// Adds `Σᵢ ȳᵢ ∂yᵢ/∂(state)` to `adjoint`, `cotangent` holding `ȳᵢ` of every quantity
    /// observed after `step` steps, in order.
    fn pull(
        &self,
        step: usize,
        particles: &Particles<f64, D>,
        cotangent: &[f64],
        adjoint: &mut ParticleAdjoint<D>,
    );

    /// `ℓ_n = Σᵢ cᵢ (yᵢ − dᵢ)²` of the state after `step` steps, in the scalar type of the
    /// run; its real part equals [`Objective::term`].
    fn value<T: Scalar>(&self, step: usize, particles: &Particles<T, D>) -> T {
        let mut loss = T::zero();
        for_each_misfit(self, step, particles, |d, c| loss += d * d * T::cst(c));
        loss
    }

    /// The residuals `rᵢ = √cᵢ (yᵢ − dᵢ)` of the least-squares form `ℓ_n = Σᵢ rᵢ²` of the
    /// state after `step` steps, appended to `out`: what a Gauss–Newton step linearises
    /// (`∂ℓ_n/∂θ = 2 Σᵢ rᵢ ∂rᵢ/∂θ`, `∂²ℓ_n/∂θ² ≈ 2 Σᵢ (∂rᵢ/∂θ)(∂rᵢ/∂θ)ᵀ`).
    fn residuals<T: Scalar>(&self, step: usize, particles: &Particles<T, D>, out: &mut Vec<T>) {
        for_each_misfit(self, step, particles, |d, c| out.push(d * T::cst(c.sqrt())));
    }
}

/// Calls `f(yᵢ − dᵢ, cᵢ)` for every quantity observed after `step` steps.
fn for_each_misfit<T: Scalar, const D: usize, O: ScalarObjective<D> + ?Sized>(
    objective: &O,
    step: usize,
    particles: &Particles<T, D>,
    mut f: impl FnMut(T, f64),
) {
    let mut y = Vec::new();
    objective.observed(step, particles, &mut y);
    if y.is_empty() {
        return;
    }
    let mut data = Vec::with_capacity(y.len());
    objective.data(step, &mut data);
    for (y, (d, c)) in y.into_iter().zip(data) {
        f(y - T::cst(d), c);
    }
}

/// [`Objective::term`] of a least-squares objective: `ℓ_n`, and with `adjoint` the seed
/// `∂ℓ_n/∂(state) = Σᵢ 2cᵢ (yᵢ − dᵢ) ∂yᵢ/∂(state)` ([`ScalarObjective::pull`] with
/// `ȳᵢ = 2cᵢ (yᵢ − dᵢ)`).
pub(crate) fn least_squares_term<const D: usize, O: ScalarObjective<D>>(
    objective: &O,
    step: usize,
    particles: &Particles<f64, D>,
    adjoint: Option<&mut ParticleAdjoint<D>>,
) -> f64 {
    if let Some(adj) = adjoint {
        let mut g = Vec::new();
        for_each_misfit(objective, step, particles, |d, c| g.push(d * (2.0 * c)));
        if !g.is_empty() {
            objective.pull(step, particles, &g, adj);
        }
    }
    objective.value(step, particles)
}

/// The linear functional `Σ_n ȳ_n · y_n` of the quantities an objective `O` observes, with
/// given cotangents `ȳ_n` per step: its gradient by the adjoint is the vector–Jacobian product
/// `ȳᵀ ∂y/∂θ` of the observations.
pub struct Pullback<'a, O> {
    /// The observations.
    pub objective: &'a O,
    /// Per observed step, `ȳ` of its quantities in the order of
    /// [`ScalarObjective::observed`].
    pub cotangent: BTreeMap<usize, Vec<f64>>,
}

impl<const D: usize, O: ScalarObjective<D>> Objective<D> for Pullback<'_, O> {
    /// `ȳ_n · y_n`, and with `adjoint` the seed `Σᵢ ȳᵢ ∂yᵢ/∂(state)`.
    fn term(
        &self,
        step: usize,
        particles: &Particles<f64, D>,
        adjoint: Option<&mut ParticleAdjoint<D>>,
    ) -> f64 {
        let Some(bar) = self.cotangent.get(&step) else {
            return 0.0;
        };
        if let Some(adj) = adjoint {
            self.objective.pull(step, particles, bar, adj);
        }
        let mut y = Vec::new();
        self.objective.observed(step, particles, &mut y);
        y.iter().zip(bar).map(|(y, b)| y * b).sum()
    }
}

/// Squared mismatch of tracked particle positions:
/// `ℓ_n = Σ_(p, x*) ∈ targets[n] w ‖x_p − x*‖²` (`w` the weight).
#[derive(Clone, Debug, PartialEq)]
pub struct TrackedPositions<const D: usize> {
    /// Per step, the observed particles and their observed positions.
    pub targets: BTreeMap<usize, Vec<(usize, Vector<f64, D>)>>,
    /// Weight `w` of every squared distance.
    pub weight: f64,
}

impl<const D: usize> Default for TrackedPositions<D> {
    /// No targets, weight 1.
    fn default() -> Self {
        Self {
            targets: BTreeMap::new(),
            weight: 1.0,
        }
    }
}

impl<const D: usize> Objective<D> for TrackedPositions<D> {
    fn term(
        &self,
        step: usize,
        particles: &Particles<f64, D>,
        adjoint: Option<&mut ParticleAdjoint<D>>,
    ) -> f64 {
        least_squares_term(self, step, particles, adjoint)
    }
}

/// Observed vectors per step (a tracked particle's position, a monitor box's mean velocity):
/// the data and weight `w` of each component of those observed after `step`, appended to
/// `out` ([`ScalarObjective::data`]).
pub(crate) fn vector_data<const D: usize>(
    targets: &BTreeMap<usize, Vec<(usize, Vector<f64, D>)>>,
    step: usize,
    weight: f64,
    out: &mut Vec<(f64, f64)>,
) {
    for (_, target) in targets.get(&step).into_iter().flatten() {
        out.extend(target.iter().map(|&d| (d, weight)));
    }
}

/// The name of axis `a`.
pub(crate) fn axis(a: usize) -> char {
    ['x', 'y', 'z'][a]
}

impl<const D: usize> ScalarObjective<D> for TrackedPositions<D> {
    /// The position components `x_p,a` of the tracked particles.
    fn observed<T: Scalar>(&self, step: usize, particles: &Particles<T, D>, out: &mut Vec<T>) {
        for (p, _) in self.targets.get(&step).into_iter().flatten() {
            out.extend(particles.x[*p].iter().copied());
        }
    }

    fn data(&self, step: usize, out: &mut Vec<(f64, f64)>) {
        vector_data(&self.targets, step, self.weight, out);
    }

    fn labels(&self, step: usize, out: &mut Vec<String>) {
        for (p, _) in self.targets.get(&step).into_iter().flatten() {
            out.extend((0..D).map(|a| format!("{} of particle {p}", axis(a))));
        }
    }

    /// `∂x_p,a/∂x_p = e_a`.
    fn pull(
        &self,
        step: usize,
        _: &Particles<f64, D>,
        cotangent: &[f64],
        adjoint: &mut ParticleAdjoint<D>,
    ) {
        for ((p, _), bar) in self
            .targets
            .get(&step)
            .into_iter()
            .flatten()
            .zip(cotangent.chunks(D))
        {
            adjoint.x[*p] += Vector::<f64, D>::from_column_slice(bar);
        }
    }
}
