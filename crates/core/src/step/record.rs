//! What a step records for its reverse pass.

use super::node::NodeState;
use crate::constitutive::Region;

/// The branches one particle took at the end of a step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ParticleBranch {
    /// Which unilateral faces its centre was projected back onto ([`super::EndOfStep::project`]),
    /// bit `2·axis + side`; a projected coordinate is a constant of the step.
    pub projected: u8,
    /// The branch of its stress update.
    pub region: Region,
}

/// What a reverse pass needs to replay one step's branches.
///
/// The stencils are not stored: they are a pure function of the start-of-step position, `F`
/// (cpGIMP) and half-width of each particle, which the state at the start of the step holds,
/// so a reverse pass recomputes them (cheaper than `b^D` weights and gradients per particle).
/// `Δt` is stored because an adaptive step is held fixed in the reverse pass.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StepRecord {
    /// The step number (1 for the first step of a run).
    pub step: usize,
    /// Simulated time at the start of the step.
    pub time: f64,
    /// The step size taken.
    pub dt: f64,
    /// Per node of the first projection where a unilateral constraint acted (flat node index,
    /// what acted and whether it stuck or slid), in increasing node order; every other node
    /// with mass was free.
    pub nodes: Vec<(usize, NodeState)>,
    /// Per particle, by id: wall projection and stress-update branch.
    pub particles: Vec<ParticleBranch>,
}
