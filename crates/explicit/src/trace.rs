//! What a step leaves behind for a reverse pass: the grid of its first projection
//! ([`crate::Solver::step_traced`]).

use loam_core::Scalar;
use loam_core::step::{NodeState, NodeSums};
use loam_core::tensor::Vector;
use rayon::prelude::*;

/// Grid nodes per parallel task when a trace is written out or kept.
pub(crate) const NODES_PER_TASK: usize = 1024;

/// The grid of one step's first projection, as the step computed it, kept compactly (only
/// the nodes whose values are not zero): a reverse pass reads it instead of forming the step's
/// grid again, so its local derivatives are taken at exactly the forward pass's values, sums
/// and branches included.
#[derive(Clone, Debug)]
pub struct StepTrace<T: Scalar, const D: usize> {
    /// The step size taken.
    pub dt: f64,
    /// The node floor of the step, `MASS_EPS · max_p m_p`: node `i` took part when `m_i` is
    /// above it.
    pub mass_floor: f64,
    /// Whether the transfer reads `vⁿ` (FLIP), so that it is kept.
    pub flip: bool,
    /// The nodes kept (flat index, increasing): those whose sums or velocities are not zero.
    pub index: Vec<u32>,
    /// Per kept node, the P2G sums `(m_i, P_i, f_i)` after the fold of the ghosts: the node
    /// update's inputs.
    pub sums: Vec<NodeSums<T, D>>,
    /// Per kept node, the updated velocity `v̂_i` (contact, walls, reflection).
    pub velocity: Vec<Vector<T, D>>,
    /// Per kept node, the start-of-step velocity `vⁿ_i = P_i / m_i` (reflected), when `flip`;
    /// empty otherwise.
    pub velocity_old: Vec<Vector<T, D>>,
    /// The nodes where a unilateral constraint acted (flat index, what acted and whether it
    /// stuck or slid), in increasing order; every other node that took part was free.
    pub nodes: Vec<(usize, NodeState)>,
}

impl<T: Scalar, const D: usize> Default for StepTrace<T, D> {
    fn default() -> Self {
        Self {
            dt: 0.0,
            mass_floor: 0.0,
            flip: false,
            index: Vec::new(),
            sums: Vec::new(),
            velocity: Vec::new(),
            velocity_old: Vec::new(),
            nodes: Vec::new(),
        }
    }
}

/// The grid of a step on every node: what [`StepTrace::expand`] writes.
pub struct GridFields<'a, T: Scalar, const D: usize> {
    /// P2G sums after the fold.
    pub sums: &'a mut [NodeSums<T, D>],
    /// `v̂_i`.
    pub velocity: &'a mut [Vector<T, D>],
    /// `vⁿ_i` (written when the trace keeps it).
    pub velocity_old: &'a mut [Vector<T, D>],
    /// What the node law did (free where nothing acted).
    pub states: &'a mut [NodeState],
}

impl<T: Scalar, const D: usize> StepTrace<T, D> {
    /// Writes the step's grid on every node into `out` (zero, or free, on the nodes not
    /// kept): the arrays the step itself held. In parallel over fixed ranges of nodes, each
    /// range finding its kept nodes by bisection of the increasing `index` and `nodes`.
    pub fn expand(&self, out: GridFields<'_, T, D>) {
        let GridFields {
            sums,
            velocity,
            velocity_old,
            states,
        } = out;
        let flip = self.flip;
        sums.par_chunks_mut(NODES_PER_TASK)
            .zip(velocity.par_chunks_mut(NODES_PER_TASK))
            .zip(velocity_old.par_chunks_mut(NODES_PER_TASK))
            .zip(states.par_chunks_mut(NODES_PER_TASK))
            .enumerate()
            .for_each(|(chunk, (((sums, velocity), velocity_old), states))| {
                let lo = chunk * NODES_PER_TASK;
                let hi = lo + sums.len();
                sums.fill(NodeSums::zero());
                velocity.fill(Vector::zeros());
                velocity_old.fill(Vector::zeros());
                states.fill(NodeState::default());
                let k0 = self.index.partition_point(|&i| (i as usize) < lo);
                let k1 = self.index.partition_point(|&i| (i as usize) < hi);
                for k in k0..k1 {
                    let i = self.index[k] as usize - lo;
                    sums[i] = self.sums[k];
                    velocity[i] = self.velocity[k];
                    if flip {
                        velocity_old[i] = self.velocity_old[k];
                    }
                }
                let n0 = self.nodes.partition_point(|&(i, _)| i < lo);
                for &(i, state) in self.nodes[n0..].iter().take_while(|(i, _)| *i < hi) {
                    states[i - lo] = state;
                }
            });
    }

    /// Bytes held by the trace's buffers.
    pub fn bytes(&self) -> usize {
        self.index.capacity() * size_of::<u32>()
            + self.sums.capacity() * size_of::<NodeSums<T, D>>()
            + (self.velocity.capacity() + self.velocity_old.capacity()) * size_of::<Vector<T, D>>()
            + self.nodes.capacity() * size_of::<(usize, NodeState)>()
    }
}
