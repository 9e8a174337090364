//! What a gradient is the gradient of: a loss over the states of a run.

use crate::adjoint_state::ParticleAdjoint;
use loam_core::Particles;
use loam_core::tensor::Vector;
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

/// Squared mismatch of tracked particle positions:
/// `ℓ_n = Σ_(p, x*) ∈ targets[n] w ‖x_p − x*‖²` (`w` the weight).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TrackedPositions<const D: usize> {
    /// Per step, the observed particles and their observed positions.
    pub targets: BTreeMap<usize, Vec<(usize, Vector<f64, D>)>>,
    /// Weight `w` of every squared distance.
    pub weight: f64,
}

impl<const D: usize> Objective<D> for TrackedPositions<D> {
    fn term(
        &self,
        step: usize,
        particles: &Particles<f64, D>,
        mut adjoint: Option<&mut ParticleAdjoint<D>>,
    ) -> f64 {
        let Some(targets) = self.targets.get(&step) else {
            return 0.0;
        };
        let mut loss = 0.0;
        for &(p, target) in targets {
            let d = particles.x[p] - target;
            loss += self.weight * d.norm_squared();
            if let Some(adj) = adjoint.as_deref_mut() {
                adj.x[p] += d * (2.0 * self.weight);
            }
        }
        loss
    }
}
