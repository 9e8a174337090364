//! What a step leaves behind for a reverse pass: the grid of its first projection
//! ([`crate::Solver::step_traced`]).

use loam_core::Scalar;
use loam_core::step::{NodeState, NodeSums};
use loam_core::tensor::Vector;
use rayon::prelude::*;

/// The grid of one step's first projection, as the step computed it, kept compactly (only
/// the nodes whose values are not zero): a reverse pass reads it instead of forming the step's
/// grid again, so its local derivatives are taken at exactly the forward pass's values, sums
/// and branches included. It is kept row group by row group of the grid (the groups the grid
/// update runs in parallel), as each group's update ends.
#[derive(Clone, Debug)]
pub struct StepTrace<T: Scalar, const D: usize> {
    /// The step size taken.
    pub dt: f64,
    /// The node floor of the step, `MASS_EPS · max_p m_p`: node `i` took part when `m_i` is
    /// above it.
    pub mass_floor: f64,
    /// Whether the transfer reads `vⁿ` (FLIP), so that it is kept.
    pub flip: bool,
    /// The kept nodes of each row group of the grid, the groups in order: together they
    /// cover every node once.
    pub groups: Vec<GroupTrace<T, D>>,
}

/// The kept nodes of one row group of a step's grid (a contiguous range of flat node
/// indices), in increasing order.
#[derive(Clone, Debug, PartialEq)]
pub struct GroupTrace<T: Scalar, const D: usize> {
    /// The group's flat node indices, `start..end`.
    pub span: (usize, usize),
    /// The nodes kept (flat index, increasing): those whose sums or velocities are not zero.
    pub index: Vec<u32>,
    /// Per kept node, the P2G sums `(m_i, P_i, f_i)` after the fold of the ghosts: the node
    /// update's inputs.
    pub sums: Vec<NodeSums<T, D>>,
    /// Per kept node, the updated velocity `v̂_i` (contact, walls, reflection).
    pub velocity: Vec<Vector<T, D>>,
    /// Per kept node, the start-of-step velocity `vⁿ_i = P_i / m_i` (reflected), when the
    /// trace's `flip`; empty otherwise.
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
            groups: Vec::new(),
        }
    }
}

impl<T: Scalar, const D: usize> Default for GroupTrace<T, D> {
    fn default() -> Self {
        Self {
            span: (0, 0),
            index: Vec::new(),
            sums: Vec::new(),
            velocity: Vec::new(),
            velocity_old: Vec::new(),
            nodes: Vec::new(),
        }
    }
}

impl<T: Scalar, const D: usize> GroupTrace<T, D> {
    /// Keeps the nodes `span` of a step's grid, given as the group's slices: the folded P2G
    /// sums, the velocities `v̂`, `vⁿ`, the masses and what the node law did. A node is kept
    /// where its sums or velocities are not zero (`vⁿ` only with `flip`); a node that took
    /// part (`m_i` above `floor`) and was not free is an acted node. The buffers are reused.
    pub(crate) fn keep(
        &mut self,
        span: (usize, usize),
        sums: &[NodeSums<T, D>],
        velocity: &[Vector<T, D>],
        velocity_old: &[Vector<T, D>],
        active: &[NodeState],
        floor: f64,
        flip: bool,
    ) {
        let zero = Vector::<T, D>::zeros();
        let kept = |k: usize| {
            sums[k] != NodeSums::zero() || velocity[k] != zero || (flip && velocity_old[k] != zero)
        };
        let acted = |k: usize| sums[k].m.re() > floor && !active[k].is_free();
        // Counted first, so that each buffer holds exactly what the largest use of it needs
        // (a trace is one of many kept at once; growth by doubling would hold up to twice).
        let (n_kept, n_acted) = (0..sums.len()).fold((0, 0), |(a, b), k| {
            (a + kept(k) as usize, b + acted(k) as usize)
        });
        self.span = span;
        fit(&mut self.index, n_kept);
        fit(&mut self.sums, n_kept);
        fit(&mut self.velocity, n_kept);
        fit(&mut self.velocity_old, if flip { n_kept } else { 0 });
        fit(&mut self.nodes, n_acted);
        for k in 0..sums.len() {
            if kept(k) {
                self.index.push((span.0 + k) as u32);
                self.sums.push(sums[k]);
                self.velocity.push(velocity[k]);
                if flip {
                    self.velocity_old.push(velocity_old[k]);
                }
            }
            if acted(k) {
                self.nodes.push((span.0 + k, active[k]));
            }
        }
    }
}

/// Empties `v` and makes room for `n` entries, allocating no more than that.
fn fit<X>(v: &mut Vec<X>, n: usize) {
    v.clear();
    v.reserve_exact(n);
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
    /// kept): the arrays the step itself held. In parallel over the row groups.
    pub fn expand(&self, out: GridFields<'_, T, D>) {
        let GridFields {
            mut sums,
            mut velocity,
            mut velocity_old,
            mut states,
        } = out;
        let mut parts = Vec::with_capacity(self.groups.len());
        for g in &self.groups {
            let len = g.span.1 - g.span.0;
            let (s, rest) = std::mem::take(&mut sums).split_at_mut(len);
            let (v, rest_v) = std::mem::take(&mut velocity).split_at_mut(len);
            let (vo, rest_vo) = std::mem::take(&mut velocity_old).split_at_mut(len);
            let (st, rest_st) = std::mem::take(&mut states).split_at_mut(len);
            (sums, velocity, velocity_old, states) = (rest, rest_v, rest_vo, rest_st);
            parts.push((g, s, v, vo, st));
        }
        let flip = self.flip;
        parts
            .into_par_iter()
            .for_each(|(g, sums, velocity, velocity_old, states)| {
                let lo = g.span.0;
                sums.fill(NodeSums::zero());
                velocity.fill(Vector::zeros());
                velocity_old.fill(Vector::zeros());
                states.fill(NodeState::default());
                for (k, &i) in g.index.iter().enumerate() {
                    let i = i as usize - lo;
                    sums[i] = g.sums[k];
                    velocity[i] = g.velocity[k];
                    if flip {
                        velocity_old[i] = g.velocity_old[k];
                    }
                }
                for &(i, state) in &g.nodes {
                    states[i - lo] = state;
                }
            });
    }

    /// The nodes kept, over all groups.
    pub fn kept(&self) -> usize {
        self.groups.iter().map(|g| g.index.len()).sum()
    }

    /// The nodes where a unilateral constraint acted, in increasing order.
    pub fn acted(&self) -> impl Iterator<Item = (usize, NodeState)> + '_ {
        self.groups.iter().flat_map(|g| g.nodes.iter().copied())
    }

    /// Bytes held by the trace's buffers.
    pub fn bytes(&self) -> usize {
        self.groups
            .iter()
            .map(|g| {
                g.index.capacity() * size_of::<u32>()
                    + g.sums.capacity() * size_of::<NodeSums<T, D>>()
                    + (g.velocity.capacity() + g.velocity_old.capacity())
                        * size_of::<Vector<T, D>>()
                    + g.nodes.capacity() * size_of::<(usize, NodeState)>()
            })
            .sum::<usize>()
            + self.groups.capacity() * size_of::<GroupTrace<T, D>>()
    }
}
