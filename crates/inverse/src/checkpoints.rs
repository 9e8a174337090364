//! How many steps the adjoint's segments hold: given, or chosen from a memory budget.
//!
//! The gradient keeps `⌈T/K⌉ − 1` checkpoints (particle states, `C` bytes each) and one traced
//! segment of `K` steps (a start-of-step state and the step's grid trace, `R` bytes each), plus
//! a fixed part `F` (the adjoint, the running states): `M(K) = F + (⌈T/K⌉ − 1) C + K R`, which
//! is `O(N √T)` at its least, near `K = √(T C / R)`. Its work is the forward run, the
//! recomputation of the `T − K` steps before the last segment, and the reverse steps, so a
//! larger `K` recomputes less: a budget takes the largest `K` whose `M(K)` fits in it
//! (`K = T`, nothing recomputed, when the whole run fits).

use crate::adjoint_state::ParticleAdjoint;
use crate::error::AdjointError;
use loam_core::Particles;
use loam_core::step::NodeSums;
use loam_core::tensor::Vector;
use loam_explicit::Config;

/// How the adjoint chooses its segment length `K`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Checkpoints {
    /// The `K` of least memory.
    #[default]
    Least,
    /// `K` steps per segment, as given.
    Segment(usize),
    /// The largest `K` (fewest recomputed steps) whose memory `M(K)` fits in this many bytes.
    Memory(u64),
}

/// The memory model `M(K) = F + (⌈T/K⌉ − 1) C + K R` of a gradient, in bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// Steps of the run, `T`.
    pub steps: usize,
    /// One particle state, `C`.
    pub state: u64,
    /// One traced step, `R`: a state and a bound on its grid trace (every node kept).
    pub traced: u64,
    /// The fixed part `F`: the adjoint and four running states.
    pub fixed: u64,
}

/// Bytes of a `Vec` of `n` values of type `X`.
fn bytes<X>(n: usize) -> u64 {
    (n * size_of::<X>()) as u64
}

impl Footprint {
    /// The footprint of a run of `steps` steps of `config` from `initial`.
    pub fn new<const D: usize>(
        config: &Config<f64, D>,
        initial: &Particles<f64, D>,
        steps: usize,
    ) -> Self {
        let Particles {
            x,
            v,
            a,
            f,
            c,
            stress,
            mass,
            volume0,
            half_width0,
            material,
            state,
            pore_pressure,
        } = initial;
        let state = bytes::<Vector<f64, D>>(x.len() + v.len() + a.len() + half_width0.len())
            + bytes::<loam_core::tensor::Tensor<f64, D>>(f.len() + c.len())
            + bytes::<nalgebra::Matrix3<f64>>(stress.len())
            + bytes::<f64>(mass.len() + volume0.len() + pore_pressure.len())
            + bytes::<u32>(material.len())
            + bytes::<loam_core::constitutive::MaterialState<f64>>(state.len());
        let velocities = if config.transfer.needs_old_grid_velocity() {
            2
        } else {
            1
        };
        let per_node = size_of::<u32>()
            + size_of::<NodeSums<f64, D>>()
            + velocities * size_of::<Vector<f64, D>>();
        let trace = bytes::<u8>(config.grid.num_nodes() * per_node);
        let adjoint = ParticleAdjoint::<D>::bytes(initial.len());
        Self {
            steps,
            state,
            traced: state + trace,
            fixed: adjoint + 4 * state,
        }
    }

    /// `M(K)`.
    pub fn bytes(&self, k: usize) -> u64 {
        let k = k.clamp(1, self.steps.max(1));
        let checkpoints = (self.steps.div_ceil(k).max(1) - 1) as u64;
        self.fixed + checkpoints * self.state + k as u64 * self.traced
    }

    /// The `K` of least memory (the larger on a tie).
    pub fn least(&self) -> usize {
        (1..=self.steps.max(1))
            .min_by_key(|&k| (self.bytes(k), std::cmp::Reverse(k)))
            .unwrap_or(1)
    }

    /// The segment length for `choice`.
    ///
    /// # Errors
    /// [`AdjointError::Memory`] for a budget below the least memory.
    pub fn segment(&self, choice: Checkpoints) -> Result<usize, AdjointError> {
        let top = self.steps.max(1);
        match choice {
            Checkpoints::Least => Ok(self.least()),
            Checkpoints::Segment(k) => Ok(k.clamp(1, top)),
            Checkpoints::Memory(budget) => (1..=top)
                .rev()
                .find(|&k| self.bytes(k) <= budget)
                .ok_or_else(|| AdjointError::Memory {
                    budget,
                    least: self.bytes(self.least()),
                }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 10,000 steps of 1 MB states and 2 MB traced steps, 10 MB fixed.
    const RUN: Footprint = Footprint {
        steps: 10_000,
        state: 1_000_000,
        traced: 2_000_000,
        fixed: 10_000_000,
    };

    #[test]
    fn the_least_memory_is_near_the_square_root_and_a_budget_buys_longer_segments() {
        // M(K) ≈ F + T C / K + K R is least at K = √(T C / R) ≈ 71.
        let least = RUN.least();
        assert!((65..=77).contains(&least), "{least}");
        assert_eq!(RUN.segment(Checkpoints::Least).unwrap(), least);
        // A budget takes the largest K that fits: M(K) ≤ 1 GB near K = 495.
        let k = RUN.segment(Checkpoints::Memory(1_000_000_000)).unwrap();
        assert!(RUN.bytes(k) <= 1_000_000_000 && RUN.bytes(k + 1) > 1_000_000_000);
        assert!(k > 400, "{k}");
        // The whole run when it fits, a given length as given (at most the run).
        let all = RUN.bytes(RUN.steps);
        assert_eq!(RUN.segment(Checkpoints::Memory(all)).unwrap(), RUN.steps);
        assert_eq!(RUN.segment(Checkpoints::Segment(50)).unwrap(), 50);
        assert_eq!(
            RUN.segment(Checkpoints::Segment(50_000)).unwrap(),
            RUN.steps
        );
    }

    #[test]
    fn a_budget_below_the_least_memory_is_refused_with_both_figures() {
        let least = RUN.bytes(RUN.least());
        let err = RUN.segment(Checkpoints::Memory(least - 1)).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, AdjointError::Memory { .. }), "{msg}");
        assert!(
            msg.contains(&format!("{} MB", least.div_ceil(1_000_000))),
            "{msg}"
        );
    }
}
