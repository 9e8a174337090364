//! Numbering of the unknowns: which grid-node components are free, which are prescribed, and
//! which are mirror images of others across a wall.
//!
//! The unknowns of a load step are the displacement increments `Δu` of the nodes touched by
//! particles. Walls are treated as in the explicit solver (`loam_core::Boundary`): the face
//! nodes of a fixed wall are prescribed to zero (a slip wall: their normal component), and a
//! ghost node beyond a bilateral wall is the mirror image of its mirror node, `Δu_ghost = P Δu_mirror`
//! with `P` negating the constrained components. The mirror image makes the wall a symmetry plane
//! for wide supports (B-splines, GIMP): without it the displacement field would be pinned a
//! fraction of a cell outside the wall, an O(h) error.
//!
//! A coupled (u–p) step has one more unknown per node, the excess pore pressure (component
//! `D`; [`DofMap::coupled`]). It has walls of its own: across a drained face the ghost node is
//! the negative mirror image (the interpolated excess pressure vanishes on the face, whose own
//! nodes are prescribed to zero); across any other wall the positive one (no flow through it);
//! across a free face none.
//!
//! A force-controlled rigid constraint (a loading plate, a footing) makes one component of a
//! group of nodes share one unknown ([`DofMap::tie`]): the group moves as one along that
//! axis and carries the force applied to the unknown. Such an unknown couples with every
//! unknown near any node of the group, so the sparsity pattern adds its row and column
//! explicitly (`crate::system::Structure`).

use loam_core::{Boundary, Grid, WallKind};

/// How one component of one grid node is determined in a load step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NodeDof {
    /// Not in the support of any particle.
    Inactive,
    /// `Δu = sign · x[dof]` for the unknown vector `x`.
    Free {
        /// Index of the unknown.
        dof: usize,
        /// `+1`, or `−1` for a mirror image across a wall.
        sign: f64,
    },
    /// A prescribed increment.
    Prescribed {
        /// The value of `Δu` in this load step.
        value: f64,
    },
}

/// The map from grid-node components to unknowns for one load step: `fields` components per
/// node, the `D` displacement increments and, in a coupled step, the excess pore pressure.
#[derive(Clone, Debug)]
pub struct DofMap<const D: usize> {
    /// `fields` entries per node (flat index), component-fastest.
    nodes: Vec<NodeDof>,
    owners: Vec<(usize, usize)>,
    fields: usize,
    ties: Vec<Tie>,
}

/// An unknown shared by one component of several nodes ([`DofMap::tie`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Tie {
    /// The shared unknown.
    pub dof: usize,
    /// The nodes (flat indices, ascending) with a component mapped to it: the group and the
    /// ghost or weak nodes that follow its nodes.
    pub nodes: Vec<usize>,
}

/// Which grid faces drain the pore fluid, `[axis][side]` (side 0 the low face): the excess
/// pore pressure is zero on them.
pub type Drained<const D: usize> = [[bool; 2]; D];

/// Reflects `idx` across face `(axis, side)` of the domain when it lies beyond it; `true` when
/// it did.
fn reflect<const D: usize>(grid: &Grid<D>, idx: &mut [usize; D], axis: usize, side: usize) -> bool {
    let face = if side == 0 {
        grid.pad
    } else {
        grid.pad + grid.cells[axis]
    };
    let beyond = if side == 0 {
        idx[axis] < face
    } else {
        idx[axis] > face
    };
    if beyond {
        idx[axis] = 2 * face - idx[axis];
    }
    beyond
}

/// The node whose pressure unknown a ghost node mirrors and the sign (module docs).
fn pressure_owner<const D: usize>(
    grid: &Grid<D>,
    boundary: &Boundary<D>,
    drained: &Drained<D>,
    node: [usize; D],
) -> ([usize; D], f64) {
    let mut idx = node;
    let mut sign = 1.0;
    for axis in 0..D {
        for side in 0..2 {
            let wall = boundary.walls[axis][side];
            let negate = drained[axis][side];
            if !negate && (wall.separable || wall.kind == WallKind::Free) {
                continue;
            }
            if reflect(grid, &mut idx, axis, side) && negate {
                sign = -sign;
            }
        }
    }
    (idx, sign)
}

/// The node whose unknowns a ghost node mirrors, and the sign per component; `None` for the
/// node itself (not beyond any bilateral wall).
fn owner<const D: usize>(
    grid: &Grid<D>,
    boundary: &Boundary<D>,
    node: [usize; D],
) -> ([usize; D], [f64; D]) {
    let mut idx = node;
    let mut sign = [1.0; D];
    for axis in 0..D {
        for side in 0..2 {
            let wall = boundary.walls[axis][side];
            let reflect_all = match wall.kind {
                _ if wall.separable => continue,
                WallKind::Free => continue,
                WallKind::Fixed | WallKind::NoSlip => true,
                WallKind::Slip => false,
            };
            if reflect(grid, &mut idx, axis, side) {
                if reflect_all {
                    sign.iter_mut().for_each(|s| *s = -*s);
                } else {
                    sign[axis] = -sign[axis];
                }
            }
        }
    }
    (idx, sign)
}

impl<const D: usize> DofMap<D> {
    /// Numbers the unknowns of a step of the solid alone (`D` per node): `active[n]` says
    /// whether node `n` (flat index) is in the support of a particle; `prescribed(node,
    /// component)` gives this step's increment of a constrained component, if any (user
    /// constraints), on top of the walls.
    pub fn new(
        grid: &Grid<D>,
        boundary: &Boundary<D>,
        active: &[bool],
        prescribed: impl Fn([usize; D], usize) -> Option<f64>,
    ) -> Self {
        Self::build(grid, boundary, None, active, prescribed)
    }

    /// Numbers the unknowns of a coupled step, `D + 1` per node: as [`DofMap::new`], plus the
    /// excess pore pressure (component `D`), zero on the `drained` faces and wherever
    /// `prescribed(node, D)` says (above a water table).
    pub fn coupled(
        grid: &Grid<D>,
        boundary: &Boundary<D>,
        drained: &Drained<D>,
        active: &[bool],
        prescribed: impl Fn([usize; D], usize) -> Option<f64>,
    ) -> Self {
        Self::build(grid, boundary, Some(drained), active, prescribed)
    }

    fn build(
        grid: &Grid<D>,
        boundary: &Boundary<D>,
        drained: Option<&Drained<D>>,
        active: &[bool],
        prescribed: impl Fn([usize; D], usize) -> Option<f64>,
    ) -> Self {
        let n = grid.num_nodes();
        let fields = if drained.is_some() { D + 1 } else { D };
        // The owner of every component of node `f` and its sign.
        let owner_of = |f: usize, c: usize| -> (usize, f64) {
            let node = grid.multi(f);
            match drained {
                Some(dr) if c == D => {
                    let (o, sign) = pressure_owner(grid, boundary, dr, node);
                    (grid.flat(o), sign)
                }
                _ => {
                    let (o, sign) = owner(grid, boundary, node);
                    (grid.flat(o), sign[c])
                }
            }
        };
        // Owners of active nodes are active too (a particle just outside a wall may reach a
        // ghost without reaching its mirror).
        let mut owned = vec![false; n * fields];
        for (f, &a) in active.iter().enumerate() {
            if a {
                for c in 0..fields {
                    owned[owner_of(f, c).0 * fields + c] = true;
                }
            }
        }
        // Constraints of the owner nodes: walls (drained faces for the pressure), then user
        // constraints.
        let constraint = |node: [usize; D], c: usize| -> Option<f64> {
            for axis in 0..D {
                for side in 0..2 {
                    if !grid.on_face(node, axis, side) {
                        continue;
                    }
                    if c == D {
                        if drained.is_some_and(|dr| dr[axis][side]) {
                            return Some(0.0);
                        }
                        continue;
                    }
                    let wall = boundary.walls[axis][side];
                    if wall.separable {
                        continue;
                    }
                    match wall.kind {
                        WallKind::Fixed | WallKind::NoSlip => return Some(0.0),
                        WallKind::Slip if c == axis => return Some(0.0),
                        _ => {}
                    }
                }
            }
            prescribed(node, c)
        };
        let mut own_dof = vec![NodeDof::Inactive; n * fields];
        let mut owners = Vec::new();
        for f in 0..n {
            for c in 0..fields {
                if !owned[f * fields + c] {
                    continue;
                }
                own_dof[f * fields + c] = match constraint(grid.multi(f), c) {
                    Some(value) => NodeDof::Prescribed { value },
                    None => {
                        owners.push((f, c));
                        NodeDof::Free {
                            dof: owners.len() - 1,
                            sign: 1.0,
                        }
                    }
                };
            }
        }
        let mut nodes = vec![NodeDof::Inactive; n * fields];
        for f in 0..n {
            for c in 0..fields {
                if !active[f] && !owned[f * fields + c] {
                    continue;
                }
                let (of, sign) = owner_of(f, c);
                nodes[f * fields + c] = match own_dof[of * fields + c] {
                    NodeDof::Free { dof, .. } => NodeDof::Free { dof, sign },
                    NodeDof::Prescribed { value } => NodeDof::Prescribed {
                        value: sign * value,
                    },
                    NodeDof::Inactive => NodeDof::Inactive,
                };
            }
        }
        Self {
            nodes,
            owners,
            fields,
            ties: Vec::new(),
        }
    }

    /// Makes the free node components `members` (flat node, component) share one unknown,
    /// `Δu_{i,c} = w` for every member, and returns it (`None` when no member is free).
    /// Prescribed or inactive members are left as they are; a member already tied merges its
    /// group into the new one. The unknowns are renumbered: the others keep their order and
    /// the shared one comes last, owned by the first member's owner.
    pub fn tie(&mut self, members: &[(usize, usize)]) -> Option<usize> {
        let old: std::collections::BTreeSet<usize> = members
            .iter()
            .filter_map(|&(f, c)| match self.get(f, c) {
                NodeDof::Free { dof, .. } => Some(dof),
                _ => None,
            })
            .collect();
        let first = *old.first()?;
        let mut map = vec![usize::MAX; self.owners.len()];
        let mut owners = Vec::with_capacity(self.owners.len() + 1 - old.len());
        for (d, &o) in self.owners.iter().enumerate() {
            if !old.contains(&d) {
                map[d] = owners.len();
                owners.push(o);
            }
        }
        let w = owners.len();
        owners.push(self.owners[first]);
        for &d in &old {
            map[d] = w;
        }
        for n in &mut self.nodes {
            if let NodeDof::Free { dof, .. } = n {
                *dof = map[*dof];
            }
        }
        self.owners = owners;
        self.ties.retain_mut(|t| {
            t.dof = map[t.dof];
            t.dof != w
        });
        let k = self.fields;
        let mut nodes: Vec<usize> = (0..self.nodes.len())
            .filter(|&i| matches!(self.nodes[i], NodeDof::Free { dof, .. } if dof == w))
            .map(|i| i / k)
            .collect();
        nodes.dedup();
        self.ties.push(Tie { dof: w, nodes });
        Some(w)
    }

    /// The shared unknowns ([`DofMap::tie`]).
    pub fn ties(&self) -> &[Tie] {
        &self.ties
    }

    /// Makes the inactive node `node` (flat index) follow `target`: every component of `node`
    /// takes the unknown (or prescribed value) of the same component of `target`, so a
    /// uniform `Δu` stays uniform over the stencils that reach `node`. A node that already
    /// has unknowns is left as it is.
    pub fn follow(&mut self, node: usize, target: usize) {
        let k = self.fields;
        if self.nodes[node * k..(node + 1) * k]
            .iter()
            .all(|d| *d == NodeDof::Inactive)
        {
            self.nodes
                .copy_within(target * k..(target + 1) * k, node * k);
        }
    }

    /// Unknowns per node: `D`, or `D + 1` in a coupled step.
    pub fn fields(&self) -> usize {
        self.fields
    }

    /// Number of unknowns.
    pub fn len(&self) -> usize {
        self.owners.len()
    }

    /// `true` when there is no unknown.
    pub fn is_empty(&self) -> bool {
        self.owners.is_empty()
    }

    /// How component `c` of node `flat` is determined.
    #[inline]
    pub fn get(&self, flat: usize, c: usize) -> NodeDof {
        self.nodes[flat * self.fields + c]
    }

    /// The (owner node, component) of unknown `dof`.
    pub fn owner_of(&self, dof: usize) -> (usize, usize) {
        self.owners[dof]
    }

    /// The value of a node component of a field given on the unknowns (velocities,
    /// accelerations): `sign · v[dof]` for a free component, zero otherwise.
    #[inline]
    pub fn field(&self, flat: usize, c: usize, v: &[f64]) -> f64 {
        match self.nodes[flat * self.fields + c] {
            NodeDof::Free { dof, sign } => sign * v[dof],
            _ => 0.0,
        }
    }

    /// `Δu` of a node component for the unknown vector `x`.
    #[inline]
    pub fn value(&self, flat: usize, c: usize, x: &[f64]) -> f64 {
        match self.nodes[flat * self.fields + c] {
            NodeDof::Free { dof, sign } => sign * x[dof],
            NodeDof::Prescribed { value } => value,
            NodeDof::Inactive => 0.0,
        }
    }
}
