//! How the observations of one load step enter the reverse and the tangent pass.

use super::kernel::velocity_index;
use super::observe::{ImplicitObservations, Quantity};
use loam_core::tensor::Vector;
use loam_implicit::ImplicitConfig;

/// `∂L/∂(quantity)` of the observations after one load step: per observed component of a
/// particle's state (displacement, velocity), and per grid node the weight of its internal force that the
/// observed reactions read.
#[derive(Clone, Debug)]
pub struct StepSeeds<const D: usize> {
    /// `(particle, k, ∂L/∂s_p,k)` with `k` the index of the observed component in
    /// `ParticleState::components` (`a` for the displacement along axis `a`: `x_p − x_p⁰`
    /// moves with `x_p`).
    pub states: Vec<(usize, usize, f64)>,
    /// `(particle, ∂L/∂p_p)` of the observed pore pressures (coupled runs).
    pub pressures: Vec<(usize, f64)>,
    /// Per grid node (flat index), `r̄_a` summed over the observed reactions whose constraint
    /// prescribes component `a` of that node: a reaction is `Σ` of the internal force
    /// `f_int,i,a` over the nodes `i` of its box, before any folding of ghost nodes.
    pub reaction_weights: Option<Vec<Vector<f64, D>>>,
}

impl<const D: usize> StepSeeds<D> {
    /// The seeds of load step `step`, from `weights = ∂L/∂m_k` of every observation.
    pub fn new(
        config: &ImplicitConfig<D>,
        observations: &ImplicitObservations,
        weights: &[f64],
        step: usize,
    ) -> Self {
        let mut states = Vec::new();
        let mut pressures = Vec::new();
        let mut reactions = vec![Vector::<f64, D>::zeros(); config.constraints.len()];
        let mut any_reaction = false;
        for (o, &w) in observations.items.iter().zip(weights) {
            if o.step != step {
                continue;
            }
            match o.quantity {
                Quantity::Displacement {
                    particle,
                    component,
                } => states.push((particle, component, w)),
                Quantity::Velocity {
                    particle,
                    component,
                } => states.push((particle, velocity_index(D) + component, w)),
                Quantity::Reaction {
                    constraint,
                    component,
                } => {
                    reactions[constraint][component] += w;
                    any_reaction = true;
                }
                Quantity::PorePressure { particle } => pressures.push((particle, w)),
            }
        }
        let reaction_weights = any_reaction.then(|| Self::node_weights(config, &reactions));
        Self {
            states,
            pressures,
            reaction_weights,
        }
    }

    /// Per grid node (flat index), `r̄_a` summed over the constraints whose box holds the
    /// node and prescribes its component `a`, given `r̄` per constraint (`reactions[c]`).
    pub fn node_weights(
        config: &ImplicitConfig<D>,
        reactions: &[Vector<f64, D>],
    ) -> Vec<Vector<f64, D>> {
        let grid = &config.grid;
        (0..grid.num_nodes())
            .map(|n| {
                let x: Vector<f64, D> = grid.node_position(grid.multi(n));
                let x: [f64; D] = std::array::from_fn(|a| x[a]);
                let mut w = Vector::<f64, D>::zeros();
                for (c, r) in config.constraints.iter().zip(reactions) {
                    if c.contains(&x, grid.h) {
                        for a in 0..D {
                            if c.displacement[a].is_some() {
                                w[a] += r[a];
                            }
                        }
                    }
                }
                w
            })
            .collect()
    }
}
