//! Wall conditions on the faces of the grid domain, applied to nodal velocities.

use crate::grid::Grid;
use crate::scalar::Scalar;
use crate::tensor::Vector;
use serde::{Deserialize, Serialize};

/// What a wall does to the velocity `v` of a node on or beyond it (outward normal `n`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WallKind {
    /// No condition (the grid simply ends; a particle that reaches the ghost layer stops the run).
    #[default]
    Free,
    /// Clamped: `v = 0` whatever the motion.
    Fixed,
    /// Frictionless roller: `v·n = 0`, tangential velocity free.
    Slip,
    /// Sticking wall: `v = 0` for nodes in contact (see [`Wall::separable`]).
    NoSlip,
}

/// One face's condition.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Wall {
    /// The kind of wall.
    pub kind: WallKind,
    /// For `slip` and `no_slip`: apply the condition only while the node moves into the wall
    /// (`v·n > 0`), so material may leave the wall (free-surface flows). Without it the
    /// condition is bilateral (and `no_slip` is the same as `fixed`).
    #[serde(default)]
    pub separable: bool,
}

impl Wall {
    /// A wall of the given kind, bilateral.
    pub fn new(kind: WallKind) -> Self {
        Self {
            kind,
            separable: false,
        }
    }
}

/// The walls of all `2·D` faces: `walls[axis][0]` is the lower face, `walls[axis][1]` the upper.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Boundary<const D: usize> {
    /// Per axis, the (lower, upper) walls.
    pub walls: [[Wall; 2]; D],
}

impl<const D: usize> Boundary<D> {
    /// The same wall on every face.
    pub fn all(wall: Wall) -> Self {
        Self {
            walls: [[wall; 2]; D],
        }
    }

    /// Applies every wall whose face the node lies on (corners get all of theirs).
    #[inline]
    pub fn apply<T: Scalar>(&self, grid: &Grid<D>, node: [usize; D], v: &mut Vector<T, D>) {
        for axis in 0..D {
            for side in 0..2 {
                let wall = self.walls[axis][side];
                if wall.kind == WallKind::Free || !grid.on_face(node, axis, side) {
                    continue;
                }
                // Outward normal is −e_axis on the lower face, +e_axis on the upper one.
                let vn = if side == 0 { -v[axis] } else { v[axis] };
                let active = !wall.separable || vn.re() > 0.0;
                match wall.kind {
                    WallKind::Fixed => *v = Vector::zeros(),
                    WallKind::Slip if active => v[axis] = T::zero(),
                    WallKind::NoSlip if active => *v = Vector::zeros(),
                    _ => {}
                }
            }
        }
    }
}

/// How a quantity maps under the mirror image across a wall.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Parity {
    /// Every component changes sign (fixed / no-slip walls).
    AllOdd,
    /// The normal component changes sign, the tangential ones are copied (slip walls).
    NormalOdd,
}

impl Parity {
    #[inline]
    fn image<T: Scalar, const D: usize>(self, axis: usize, v: &Vector<T, D>) -> Vector<T, D> {
        match self {
            Parity::AllOdd => -v,
            Parity::NormalOdd => {
                let mut w = *v;
                w[axis] = -w[axis];
                w
            }
        }
    }
}

impl<const D: usize> Boundary<D> {
    /// Calls `f(ghost, mirror, axis, parity)` for every ghost node beyond a bilateral wall
    /// (`fixed`, `slip`, non-separable `no_slip`) and its mirror image across the face, axis
    /// by axis (so corner ghosts compose the reflections).
    fn for_each_ghost(&self, grid: &Grid<D>, mut f: impl FnMut(usize, usize, usize, Parity)) {
        let nodes = grid.nodes();
        for axis in 0..D {
            for side in 0..2 {
                let wall = self.walls[axis][side];
                let parity = match wall.kind {
                    _ if wall.separable => continue,
                    WallKind::Free => continue,
                    WallKind::Fixed | WallKind::NoSlip => Parity::AllOdd,
                    WallKind::Slip => Parity::NormalOdd,
                };
                let face = if side == 0 {
                    grid.pad
                } else {
                    grid.pad + grid.cells[axis]
                };
                let layer: usize = (0..D).filter(|&a| a != axis).map(|a| nodes[a]).product();
                for k in 1..=grid.pad {
                    let (ghost, mirror) = if side == 0 {
                        (face - k, face + k)
                    } else {
                        (face + k, face - k)
                    };
                    if ghost >= nodes[axis] || mirror >= nodes[axis] {
                        continue;
                    }
                    for r in 0..layer {
                        let mut rest = r;
                        let mut idx = [0usize; D];
                        for a in (0..D).filter(|&a| a != axis) {
                            idx[a] = rest % nodes[a];
                            rest /= nodes[a];
                        }
                        idx[axis] = mirror;
                        let m = grid.flat(idx);
                        idx[axis] = ghost;
                        f(grid.flat(idx), m, axis, parity);
                    }
                }
            }
        }
    }

    /// Folds what particles deposited on ghost nodes into the mirror nodes, as if the mirror
    /// image of the body across each bilateral wall were present: mass adds, and momentum and
    /// force add through the wall's parity (constrained components change sign). Pass `None`
    /// for what was not deposited (MUSL's second transfer carries momentum only).
    ///
    /// With supports wider than the hat (B-splines, GIMP) particles near a wall reach ghost
    /// nodes; the mirror image makes the wall a symmetry plane, so `v = 0` (or `v·n = 0`) holds
    /// exactly at the wall and the boundary error is of the interior's order instead of O(h).
    /// Separable walls are unilateral and only get [`Boundary::apply`].
    pub fn fold_ghosts<T: Scalar>(
        &self,
        grid: &Grid<D>,
        mut mass: Option<&mut [T]>,
        momentum: &mut [Vector<T, D>],
        mut force: Option<&mut [Vector<T, D>]>,
    ) {
        self.for_each_ghost(grid, |g, m, axis, parity| {
            if let Some(mass) = mass.as_deref_mut() {
                let mg = mass[g];
                mass[m] += mg;
            }
            let pg = parity.image(axis, &momentum[g]);
            momentum[m] += pg;
            if let Some(f) = force.as_deref_mut() {
                let fg = parity.image(axis, &f[g]);
                f[m] += fg;
            }
        });
    }

    /// Sets every ghost node's velocity to the mirror image of its mirror node's
    /// (see [`Boundary::fold_ghosts`]), so particles near a wall interpolate the
    /// symmetric field.
    pub fn reflect_ghosts<T: Scalar>(&self, grid: &Grid<D>, v: &mut [Vector<T, D>]) {
        self.for_each_ghost(grid, |g, m, axis, parity| {
            v[g] = parity.image(axis, &v[m]);
        });
    }
}

/// A displacement constraint on the grid nodes inside a box (for loading plates, supports,
/// pinned points). Components with `Some(u)` are prescribed to reach the total displacement
/// `u` at the end of the loading, linearly over the load steps.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeConstraint<const D: usize> {
    /// Lower corner of the box of nodes (inclusive, with a tolerance of 1e-9 h).
    pub lo: [f64; D],
    /// Upper corner.
    pub hi: [f64; D],
    /// Total prescribed displacement per component; `None` leaves the component free.
    pub displacement: [Option<f64>; D],
}

impl<const D: usize> NodeConstraint<D> {
    /// Whether a node at `x` lies in the constraint's box (tolerance 1e-9·h).
    pub fn contains(&self, x: &[f64; D], h: f64) -> bool {
        let tol = 1e-9 * h;
        (0..D).all(|a| x[a] >= self.lo[a] - tol && x[a] <= self.hi[a] + tol)
    }
}

/// A force on one particle (a point load), reaching `force` at the end of the loading.
#[derive(Clone, Debug, PartialEq)]
pub struct PointLoad<const D: usize> {
    /// Particle id.
    pub particle: usize,
    /// Total force (N per metre of thickness in plane strain).
    pub force: [f64; D],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn walls_act_on_face_nodes_only() {
        let g = Grid::<2>::new([0.0, 0.0], [4, 4], 1.0, 2);
        let mut b = Boundary::<2>::all(Wall::new(WallKind::Slip));
        b.walls[1][0] = Wall {
            kind: WallKind::NoSlip,
            separable: true,
        };
        // Lower x face, slip: normal component removed, tangential kept.
        let mut v = Vector::<f64, 2>::new(-1.0, 0.5);
        b.apply(&g, [1, 4], &mut v);
        assert_eq!(v, Vector::<f64, 2>::new(0.0, 0.5));
        // Interior node untouched.
        let mut v = Vector::<f64, 2>::new(-1.0, 0.5);
        b.apply(&g, [3, 4], &mut v);
        assert_eq!(v, Vector::<f64, 2>::new(-1.0, 0.5));
        // Separable no-slip floor: approaching node stops, leaving node is free.
        let mut v = Vector::<f64, 2>::new(0.3, -0.2);
        b.apply(&g, [4, 2], &mut v);
        assert_eq!(v, Vector::<f64, 2>::zeros());
        let mut v = Vector::<f64, 2>::new(0.3, 0.2);
        b.apply(&g, [4, 2], &mut v);
        assert_eq!(v, Vector::<f64, 2>::new(0.3, 0.2));
    }
}
