//! Stage 2: the grid-node update.
//!
//! Per node with mass above the floor: `v_iⁿ = (m v)_i / m_i`,
//! `v_i = v_iⁿ + Δt (f_i / m_i + g)` ([`momentum_update`]), then the per-node law on `v_i`
//! ([`NodeLaw::apply`]): Coulomb contact with friction segments and obstacles at the
//! end-of-step time, then the walls of the faces the node lies on.

use crate::boundary::Boundary;
use crate::contact::{Contact, ContactSet};
use crate::grid::Grid;
use crate::scalar::Scalar;
use crate::tensor::Vector;

/// The momentum update of a node: the start-of-step velocity `v_iⁿ = p_i / m_i` and the
/// trial velocity `v_i = v_iⁿ + Δt (f_i / m_i + g)`, returned as `(v_iⁿ, v_i)`.
#[inline(always)]
pub fn momentum_update<T: Scalar, const D: usize>(
    m: T,
    p: &Vector<T, D>,
    f: &Vector<T, D>,
    gravity: &Vector<T, D>,
    dt: T,
) -> (Vector<T, D>, Vector<T, D>) {
    let v_old = p / m;
    (v_old, v_old + (f / m + gravity) * dt)
}

/// What the per-node law did at a node: the unilateral constraints that acted (which MUSL's
/// second projection enforces again, and which a reverse pass replays), and on which contact
/// constraints the node slid rather than stuck. A node with no bit set was free (or only
/// under bilateral walls, which act the same way every step).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NodeState {
    /// Friction segments and obstacles ([`Contact::apply`]).
    pub contact: ContactSet,
    /// Separable walls that acted, bit `2·axis + side` ([`Boundary::apply`]).
    pub walls: u8,
}

impl NodeState {
    /// Whether no unilateral constraint acted.
    #[inline]
    pub fn is_free(&self) -> bool {
        self.contact.active == 0 && self.walls == 0
    }
}

/// The conditions on a nodal velocity after the momentum update: contact (friction segments
/// and obstacles) at the end-of-step time, then the plain walls.
#[derive(Clone, Copy, Debug)]
pub struct NodeLaw<'a, T: Scalar, const D: usize> {
    grid: &'a Grid<D>,
    boundary: &'a Boundary<D>,
    contact: &'a Contact<T, D>,
    /// Whether there are friction segments (they act on face nodes only) and obstacles
    /// (anywhere).
    segments: bool,
    obstacles: bool,
    time: f64,
}

impl<'a, T: Scalar, const D: usize> NodeLaw<'a, T, D> {
    /// The law at simulated time `time` (the end of the step, where the obstacles are when the
    /// grid velocity is reached).
    pub fn new(
        grid: &'a Grid<D>,
        boundary: &'a Boundary<D>,
        contact: &'a Contact<T, D>,
        time: f64,
    ) -> Self {
        Self {
            grid,
            boundary,
            contact,
            segments: !contact.segments.is_empty(),
            obstacles: !contact.obstacles.is_empty(),
            time,
        }
    }

    /// Applies contact and the walls to the trial velocity `v` of `node`; returns what acted.
    #[inline(always)]
    pub fn apply(&self, node: [usize; D], v: &mut Vector<T, D>) -> NodeState {
        self.apply_measured(node, v, |_, _| ())
    }

    /// [`NodeLaw::apply`], telling `on_obstacle(k, Δv)` the change of velocity obstacle `k`
    /// made ([`Contact::apply_measured`]).
    #[inline(always)]
    pub fn apply_measured(
        &self,
        node: [usize; D],
        v: &mut Vector<T, D>,
        on_obstacle: impl FnMut(usize, Vector<T, D>),
    ) -> NodeState {
        let face = on_a_face(self.grid, node);
        let mut state = NodeState::default();
        if face && self.segments || self.obstacles {
            state.contact = self
                .contact
                .apply_measured(self.grid, node, self.time, v, on_obstacle);
        }
        if face {
            state.walls = self.boundary.apply(self.grid, node, v);
        }
        state
    }

    /// MUSL's second projection: non-penetration on the velocity `v` of `node` for the
    /// constraints that acted in [`NodeLaw::apply`] (`state`), and the bilateral walls.
    #[inline(always)]
    pub fn enforce(&self, node: [usize; D], v: &mut Vector<T, D>, state: NodeState) {
        self.contact
            .enforce(self.grid, node, self.time, v, state.contact.active);
        if on_a_face(self.grid, node) {
            self.boundary.enforce(self.grid, node, v, state.walls);
        }
    }
}

/// Whether a node lies on (or beyond) a face of the domain, where walls and friction segments
/// act; elsewhere [`Boundary::apply`] and the segments of [`Contact::apply`] do nothing.
#[inline(always)]
pub fn on_a_face<const D: usize>(grid: &Grid<D>, node: [usize; D]) -> bool {
    (0..D).any(|a| node[a] <= grid.pad || node[a] >= grid.pad + grid.cells[a])
}
