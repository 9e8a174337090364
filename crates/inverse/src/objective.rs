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

/// An objective whose terms can also be evaluated in any scalar type, so that a forward-mode
/// dual run (`Solver<Dual64, D>` with one seeded input) gives `dL/dθ` directly: the oracle the
/// adjoint is checked against (`loam gradient --check`).
pub trait ScalarObjective<const D: usize>: Objective<D> {
    /// `ℓ_n` of the state after `step` steps, in the scalar type of the run; its real part
    /// equals [`Objective::term`].
    fn value<T: Scalar>(&self, step: usize, particles: &Particles<T, D>) -> T;

    /// The residuals `rᵢ` of the least-squares form `ℓ_n = Σᵢ rᵢ²` of the state after `step`
    /// steps, appended to `out`: what a Gauss–Newton step linearises
    /// (`∂ℓ_n/∂θ = 2 Σᵢ rᵢ ∂rᵢ/∂θ`, `∂²ℓ_n/∂θ² ≈ 2 Σᵢ (∂rᵢ/∂θ)(∂rᵢ/∂θ)ᵀ`).
    fn residuals<T: Scalar>(&self, step: usize, particles: &Particles<T, D>, out: &mut Vec<T>);
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
        if let (Some(adj), Some(targets)) = (adjoint, self.targets.get(&step)) {
            // ∂ℓ_n/∂x_p = 2 w (x_p − x*).
            for &(p, target) in targets {
                adj.x[p] += (particles.x[p] - target) * (2.0 * self.weight);
            }
        }
        self.value(step, particles)
    }
}

impl<const D: usize> ScalarObjective<D> for TrackedPositions<D> {
    fn value<T: Scalar>(&self, step: usize, particles: &Particles<T, D>) -> T {
        let Some(targets) = self.targets.get(&step) else {
            return T::zero();
        };
        let mut loss = T::zero();
        for (p, target) in targets {
            let d = particles.x[*p] - target.map(T::cst);
            loss += d.norm_squared() * T::cst(self.weight);
        }
        loss
    }

    /// `√w (x_p − x*)`, component by component.
    fn residuals<T: Scalar>(&self, step: usize, particles: &Particles<T, D>, out: &mut Vec<T>) {
        let root = T::cst(self.weight.sqrt());
        for (p, target) in self.targets.get(&step).into_iter().flatten() {
            let d = particles.x[*p] - target.map(T::cst);
            out.extend(d.iter().map(|&d| d * root));
        }
    }
}
