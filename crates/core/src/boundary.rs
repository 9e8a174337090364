//! Wall conditions on the faces of the grid domain, applied to nodal velocities.

use crate::grid::Grid;
use crate::scalar::Scalar;
use crate::serde_form::name_or_table;
use crate::tensor::Vector;
use serde::{Deserialize, Deserializer, Serialize};
use std::ops::Range;

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
///
/// Written as its kind, `"slip"`, or as a table `{ kind = "slip", separable = true }`
/// (`separable` defaults to `false`); an unknown key is an error. `Deserialize` is written by
/// hand for that (see [`crate::serde_form`]); `Serialize` writes the table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Wall {
    /// The kind of wall.
    pub kind: WallKind,
    /// For `slip` and `no_slip`: apply the condition only while the node moves into the wall
    /// (`v·n > 0`), so material may leave the wall (free-surface flows). Without it the
    /// condition is bilateral (and `no_slip` is the same as `fixed`).
    pub separable: bool,
}

/// The strict table form of [`Wall`].
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WallTable {
    kind: WallKind,
    #[serde(default)]
    separable: bool,
}

impl<'de> Deserialize<'de> for Wall {
    /// Reads the kind (`"slip"`, the table `{ kind = "slip" }`) or the table.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let WallTable { kind, separable } = name_or_table(d, "kind")?;
        Ok(Self { kind, separable })
    }
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

    /// Applies every wall whose face the node lies on (corners get all of theirs). Returns
    /// the separable walls that acted (the node moved into them), bit `2·axis + side`: the
    /// active set that [`Boundary::enforce`] applies again.
    #[inline]
    pub fn apply<T: Scalar>(&self, grid: &Grid<D>, node: [usize; D], v: &mut Vector<T, D>) -> u8 {
        self.act(grid, node, v, None)
    }

    /// Applies the walls of the node again to another velocity of it (MUSL's second
    /// projection): bilateral walls as in [`Boundary::apply`], separable walls exactly where
    /// `active` (from [`Boundary::apply`]) says they acted, whatever `v` does now.
    #[inline]
    pub fn enforce<T: Scalar>(
        &self,
        grid: &Grid<D>,
        node: [usize; D],
        v: &mut Vector<T, D>,
        active: u8,
    ) {
        self.act(grid, node, v, Some(active));
    }

    /// [`Boundary::apply`] (`given = None`: a separable wall acts when the node moves into it)
    /// and [`Boundary::enforce`] (`given`: the separable walls that act).
    #[inline(always)]
    fn act<T: Scalar>(
        &self,
        grid: &Grid<D>,
        node: [usize; D],
        v: &mut Vector<T, D>,
        given: Option<u8>,
    ) -> u8 {
        let mut acted = 0;
        for axis in 0..D {
            for side in 0..2 {
                let wall = self.walls[axis][side];
                if wall.kind == WallKind::Free || !grid.on_face(node, axis, side) {
                    continue;
                }
                let bit = 1 << (2 * axis + side);
                let active = if !wall.separable {
                    true
                } else if let Some(given) = given {
                    given & bit != 0
                } else {
                    // Outward normal is −e_axis on the lower face, +e_axis on the upper one.
                    let vn = if side == 0 { -v[axis] } else { v[axis] };
                    vn.re() > 0.0
                };
                if wall.separable && active {
                    acted |= bit;
                }
                match wall.kind {
                    WallKind::Fixed => *v = Vector::zeros(),
                    WallKind::Slip if active => v[axis] = T::zero(),
                    WallKind::NoSlip if active => *v = Vector::zeros(),
                    _ => {}
                }
            }
        }
        acted
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

    /// `mirror[i] += image(ghost[i])` over a run (the parity chosen once per run).
    #[inline]
    fn fold_run<T: Scalar, const D: usize>(
        self,
        axis: usize,
        ghost: &[Vector<T, D>],
        mirror: &mut [Vector<T, D>],
    ) {
        match self {
            Parity::AllOdd => mirror.iter_mut().zip(ghost).for_each(|(m, g)| *m -= g),
            Parity::NormalOdd => mirror.iter_mut().zip(ghost).for_each(|(m, g)| {
                *m += Parity::NormalOdd.image(axis, g);
            }),
        }
    }

    /// `ghost[i] = image(mirror[i])` over a run.
    #[inline]
    fn reflect_run<T: Scalar, const D: usize>(
        self,
        axis: usize,
        ghost: &mut [Vector<T, D>],
        mirror: &[Vector<T, D>],
    ) {
        match self {
            Parity::AllOdd => ghost.iter_mut().zip(mirror).for_each(|(g, m)| *g = -m),
            Parity::NormalOdd => ghost.iter_mut().zip(mirror).for_each(|(g, m)| {
                *g = Parity::NormalOdd.image(axis, m);
            }),
        }
    }
}

/// The runs `[ghost, ghost + len)` and `[mirror, mirror + len)` of `v`, which must not overlap.
#[inline]
fn two_runs<X>(v: &mut [X], ghost: usize, mirror: usize, len: usize) -> (&mut [X], &mut [X]) {
    if ghost < mirror {
        let (lo, hi) = v.split_at_mut(mirror);
        (&mut lo[ghost..ghost + len], &mut hi[..len])
    } else {
        let (lo, hi) = v.split_at_mut(ghost);
        (&mut hi[..len], &mut lo[mirror..mirror + len])
    }
}

impl<const D: usize> Boundary<D> {
    /// Calls `f(ghost, mirror, len, axis, parity)` for every run of `len` consecutive ghost
    /// nodes `ghost..ghost + len` beyond a bilateral wall (`fixed`, `slip`, non-separable
    /// `no_slip`) that lies in the flat node range `nodes`, with the run of their mirror
    /// images across the face, `mirror..mirror + len`; axis by axis (so corner ghosts compose
    /// the reflections). A layer normal to `axis` is `outer` runs of `stride` nodes (`stride`
    /// the product of the node counts below `axis`, `outer` of those above), visited in flat
    /// order; the ghost's and the mirror's runs are the same run shifted along `axis`, so they
    /// never overlap. Over a sub-range the calls are those of the whole grid that meet it, in
    /// the same order.
    fn for_each_ghost(
        &self,
        grid: &Grid<D>,
        nodes: Range<usize>,
        mut f: impl FnMut(usize, usize, usize, usize, Parity),
    ) {
        if nodes.is_empty() {
            return;
        }
        let counts = grid.nodes();
        for axis in 0..D {
            let stride: usize = counts[..axis].iter().product();
            let plane = stride * counts[axis];
            // The layers (runs of the same `o`) the range meets.
            let outer = nodes.start / plane..=(nodes.end - 1) / plane;
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
                for k in 1..=grid.pad {
                    let (ghost, mirror) = if side == 0 {
                        (face - k, face + k)
                    } else {
                        (face + k, face - k)
                    };
                    if ghost >= counts[axis] || mirror >= counts[axis] {
                        continue;
                    }
                    for o in outer.clone() {
                        let run = o * plane + ghost * stride;
                        let (lo, hi) = (run.max(nodes.start), (run + stride).min(nodes.end));
                        if lo < hi {
                            f(
                                lo,
                                lo - run + o * plane + mirror * stride,
                                hi - lo,
                                axis,
                                parity,
                            );
                        }
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
        mass: Option<&mut [T]>,
        momentum: &mut [Vector<T, D>],
        force: Option<&mut [Vector<T, D>]>,
    ) {
        self.fold_ghosts_in(grid, 0..grid.num_nodes(), mass, momentum, force);
    }

    /// [`Boundary::fold_ghosts`] on the flat node range `nodes` only: the slices hold those
    /// nodes (entry `n − nodes.start` for node `n`), and the range must hold the mirror of
    /// every ghost in it (whole layers across each bilateral wall: see
    /// [`Boundary::mirror_layers`]). Gives the bits the whole-grid fold gives on those nodes,
    /// so disjoint closed ranges can be folded in parallel.
    pub fn fold_ghosts_in<T: Scalar>(
        &self,
        grid: &Grid<D>,
        nodes: Range<usize>,
        mut mass: Option<&mut [T]>,
        momentum: &mut [Vector<T, D>],
        mut force: Option<&mut [Vector<T, D>]>,
    ) {
        let start = nodes.start;
        self.for_each_ghost(grid, nodes, |g, m, len, axis, parity| {
            let (g, m) = (g - start, m - start);
            if let Some(mass) = mass.as_deref_mut() {
                let (ghost, mirror) = two_runs(mass, g, m, len);
                mirror.iter_mut().zip(ghost).for_each(|(m, g)| *m += *g);
            }
            let (ghost, mirror) = two_runs(momentum, g, m, len);
            parity.fold_run(axis, ghost, mirror);
            if let Some(f) = force.as_deref_mut() {
                let (ghost, mirror) = two_runs(f, g, m, len);
                parity.fold_run(axis, ghost, mirror);
            }
        });
    }

    /// Sets every ghost node's velocity to the mirror image of its mirror node's
    /// (see [`Boundary::fold_ghosts`]), so particles near a wall interpolate the
    /// symmetric field.
    pub fn reflect_ghosts<T: Scalar>(&self, grid: &Grid<D>, v: &mut [Vector<T, D>]) {
        self.reflect_ghosts_in(grid, 0..grid.num_nodes(), v);
    }

    /// [`Boundary::reflect_ghosts`] on the flat node range `nodes` only, under the conditions
    /// of [`Boundary::fold_ghosts_in`].
    pub fn reflect_ghosts_in<T: Scalar>(
        &self,
        grid: &Grid<D>,
        nodes: Range<usize>,
        v: &mut [Vector<T, D>],
    ) {
        let start = nodes.start;
        self.for_each_ghost(grid, nodes, |g, m, len, axis, parity| {
            let (ghost, mirror) = two_runs(v, g - start, m - start, len);
            parity.reflect_run(axis, ghost, mirror);
        });
    }

    /// The ghost runs of [`Boundary::fold_ghosts`] over the whole grid, in the order it
    /// visits them: `(ghost, mirror, len, axis, parity)`.
    fn ghost_runs(&self, grid: &Grid<D>) -> Vec<(usize, usize, usize, usize, Parity)> {
        let mut runs = Vec::new();
        self.for_each_ghost(grid, 0..grid.num_nodes(), |g, m, len, axis, parity| {
            runs.push((g, m, len, axis, parity));
        });
        runs
    }

    /// The adjoint of [`Boundary::fold_ghosts`]: with `mass`, `momentum` and `force` holding
    /// the adjoints of the folded fields (`None` for what the fold did not carry), adds to
    /// each ghost the adjoint of its mirror, `ḡ += image(m̄)` (`image` is its own transpose:
    /// ±1 per component), run by run in the reverse of the fold's order. The fold is linear,
    /// `m ← m + image(g)`, so this is its transpose exactly.
    pub fn fold_ghosts_adjoint(
        &self,
        grid: &Grid<D>,
        mut mass: Option<&mut [f64]>,
        momentum: &mut [Vector<f64, D>],
        mut force: Option<&mut [Vector<f64, D>]>,
    ) {
        for (g, m, len, axis, parity) in self.ghost_runs(grid).into_iter().rev() {
            for k in 0..len {
                if let Some(mass) = mass.as_deref_mut() {
                    mass[g + k] += mass[m + k];
                }
                momentum[g + k] += parity.image(axis, &momentum[m + k]);
                if let Some(force) = force.as_deref_mut() {
                    force[g + k] += parity.image(axis, &force[m + k]);
                }
            }
        }
    }

    /// The adjoint of [`Boundary::reflect_ghosts`]: `m̄ += image(ḡ)`, `ḡ = 0`, run by run in
    /// the reverse of the reflection's order (the ghost's own value before the reflection
    /// does not reach the result).
    pub fn reflect_ghosts_adjoint(&self, grid: &Grid<D>, v: &mut [Vector<f64, D>]) {
        for (g, m, len, axis, parity) in self.ghost_runs(grid).into_iter().rev() {
            for k in 0..len {
                let ghost = std::mem::replace(&mut v[g + k], Vector::zeros());
                v[m + k] += parity.image(axis, &ghost);
            }
        }
    }

    /// Per axis, how many node layers at the (lower, upper) end the ghost folds and
    /// reflections of a bilateral wall reach: the `pad` ghost layers, the face and the `pad`
    /// mirror layers inside it, `2·pad + 1` (at most the node count); 0 where the wall is free
    /// or separable. A range of whole grid rows is closed under the mirror maps (as
    /// [`Boundary::fold_ghosts_in`] needs) when, along every axis above 0, it holds either all
    /// of such an end's layers or none of them (for the same indices along the other axes).
    pub fn mirror_layers(&self, grid: &Grid<D>) -> [[usize; 2]; D] {
        let nodes = grid.nodes();
        std::array::from_fn(|a| {
            std::array::from_fn(|side| {
                let w = self.walls[a][side];
                if w.kind != WallKind::Free && !w.separable {
                    (2 * grid.pad + 1).min(nodes[a])
                } else {
                    0
                }
            })
        })
    }
}

/// A constraint on the grid nodes inside a box (for loading plates, footings, supports,
/// pinned points). Components with `Some(u)` in `displacement` are prescribed to reach the
/// total displacement `u` at the end of the loading, linearly over the load steps
/// (displacement control). Components with `Some(f)` in `force` move as one rigid group,
/// `Δu_{i,c} = w` for every node `i` in the box, with the total force `f` on the group
/// reached over the loading (force control: `w` is an unknown, and the group's nodes share
/// the force through the tangent).
#[derive(Clone, Debug, PartialEq)]
pub struct NodeConstraint<const D: usize> {
    /// Lower corner of the box of nodes (inclusive, with a tolerance of 1e-9 h).
    pub lo: [f64; D],
    /// Upper corner.
    pub hi: [f64; D],
    /// Total prescribed displacement per component; `None` leaves the component free.
    pub displacement: [Option<f64>; D],
    /// Total force per component on a rigid group (N; N per metre run in 2D); `None`: the
    /// component is not force-controlled.
    pub force: [Option<f64>; D],
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

    /// The ghost/mirror pairs of `b` on `g`, in visiting order, enumerated naively by
    /// multi-index: the layers normal to each bilateral wall, the other axes lowest fastest.
    fn reference_pairs<const D: usize>(
        b: &Boundary<D>,
        g: &Grid<D>,
    ) -> Vec<(usize, usize, usize, Parity)> {
        let nodes = g.nodes();
        let mut expected = Vec::new();
        for axis in 0..D {
            let others: Vec<usize> = (0..D).filter(|&a| a != axis).collect();
            let layer: usize = others.iter().map(|&a| nodes[a]).product();
            for side in 0..2 {
                let wall = b.walls[axis][side];
                if wall.kind == WallKind::Free || wall.separable {
                    continue;
                }
                let parity = if wall.kind == WallKind::Slip {
                    Parity::NormalOdd
                } else {
                    Parity::AllOdd
                };
                let face = g.pad + side * g.cells[axis];
                for k in 1..=g.pad {
                    let (gh, m) = if side == 0 {
                        (face - k, face + k)
                    } else {
                        (face + k, face - k)
                    };
                    for r in 0..layer {
                        let (mut idx, mut rest) = ([0; D], r);
                        for &a in &others {
                            idx[a] = rest % nodes[a];
                            rest /= nodes[a];
                        }
                        idx[axis] = m;
                        let mf = g.flat(idx);
                        idx[axis] = gh;
                        expected.push((g.flat(idx), mf, axis, parity));
                    }
                }
            }
        }
        expected
    }

    /// `apply` reports the separable walls that acted; `enforce` applies exactly those again
    /// (whatever the new velocity does) and the bilateral walls as always.
    #[test]
    fn enforce_repeats_the_separable_walls_that_acted() {
        let g = Grid::<2>::new([0.0, 0.0], [4, 4], 1.0, 2);
        let mut b = Boundary::<2>::all(Wall::new(WallKind::Slip));
        b.walls[1][0] = Wall {
            kind: WallKind::Slip,
            separable: true,
        };
        // Corner of the bilateral x_min wall and the separable floor (bit 2·1 + 0 = 4).
        let corner = [2, 2];
        let mut v = Vector::<f64, 2>::new(0.3, -0.2);
        assert_eq!(b.apply(&g, corner, &mut v), 0b100);
        assert_eq!(v, Vector::<f64, 2>::new(0.0, 0.0));
        // The second velocity leaves the floor: held anyway, because the floor acted.
        let mut w = Vector::<f64, 2>::new(0.3, 0.4);
        b.enforce(&g, corner, &mut w, 0b100);
        assert_eq!(w, Vector::<f64, 2>::new(0.0, 0.0));
        // The floor did not act: a velocity into it is left alone by `enforce`, the
        // bilateral wall still acts.
        let mut u = Vector::<f64, 2>::new(0.3, -0.4);
        b.enforce(&g, corner, &mut u, 0);
        assert_eq!(u, Vector::<f64, 2>::new(0.0, -0.4));
        // A leaving node is not reported.
        let mut z = Vector::<f64, 2>::new(0.3, 0.4);
        assert_eq!(b.apply(&g, corner, &mut z), 0);
    }

    /// The ghost/mirror runs, expanded node by node, are the naive pairs in the same order.
    #[test]
    fn ghosts_pair_with_their_mirror_images_in_flat_order() {
        let g = Grid::<3>::new([0.0; 3], [4, 5, 6], 0.5, 2);
        let mut b = Boundary::<3>::all(Wall::new(WallKind::Slip));
        b.walls[0][1] = Wall::new(WallKind::Free);
        b.walls[1][0] = Wall::new(WallKind::Fixed);
        b.walls[2][1] = Wall {
            kind: WallKind::NoSlip,
            separable: true,
        };
        let mut seen = Vec::new();
        b.for_each_ghost(&g, 0..g.num_nodes(), |gh, m, len, axis, parity| {
            seen.extend((0..len).map(|i| (gh + i, m + i, axis, parity)));
        });
        // pad × (x_min layer + y_min and y_max layers + z_min layer).
        assert_eq!(seen.len(), 2 * (10 * 11 + 2 * 9 * 11 + 9 * 10));
        assert_eq!(seen, reference_pairs(&b, &g));
    }

    /// Folding and reflecting by runs give the bits of the node-by-node definitions.
    #[test]
    fn fold_and_reflect_match_the_node_by_node_definitions() {
        let g = Grid::<2>::new([0.0; 2], [5, 4], 0.5, 2);
        let mut b = Boundary::<2>::all(Wall::new(WallKind::Slip));
        b.walls[0][1] = Wall::new(WallKind::Fixed);
        b.walls[1][1] = Wall::new(WallKind::Free);
        let n = g.num_nodes();
        let val = |i: usize, c: usize| ((i * 7 + c * 3) % 11) as f64 * 0.37 - 1.1;
        let mass: Vec<f64> = (0..n).map(|i| val(i, 5).abs()).collect();
        let mom: Vec<Vector<f64, 2>> = (0..n)
            .map(|i| Vector::<f64, 2>::new(val(i, 0), val(i, 1)))
            .collect();
        let force: Vec<Vector<f64, 2>> = (0..n)
            .map(|i| Vector::<f64, 2>::new(val(i, 2), val(i, 3)))
            .collect();
        let (mut m1, mut p1, mut f1) = (mass.clone(), mom.clone(), force.clone());
        b.fold_ghosts(&g, Some(&mut m1), &mut p1, Some(&mut f1));
        let (mut m0, mut p0, mut f0) = (mass, mom, force);
        for (gh, m, axis, parity) in reference_pairs(&b, &g) {
            m0[m] += m0[gh];
            let pg = parity.image(axis, &p0[gh]);
            p0[m] += pg;
            let fg = parity.image(axis, &f0[gh]);
            f0[m] += fg;
        }
        assert_eq!((&m1, &p1, &f1), (&m0, &p0, &f0));
        let mut v1 = p1.clone();
        b.reflect_ghosts(&g, &mut v1);
        for (gh, m, axis, parity) in reference_pairs(&b, &g) {
            p0[gh] = parity.image(axis, &p0[m]);
        }
        assert_eq!(v1, p0);
    }

    /// The adjoints are the transposes of the fold and the reflection:
    /// `⟨A x, y⟩ = ⟨x, Aᵀ y⟩` for random fields on a grid with fixed, slip and free walls
    /// (corner ghosts compose two reflections).
    #[test]
    fn fold_and_reflect_adjoints_are_their_transposes() {
        let g = Grid::<2>::new([0.0; 2], [5, 4], 0.5, 2);
        let mut b = Boundary::<2>::all(Wall::new(WallKind::Slip));
        b.walls[0][1] = Wall::new(WallKind::Fixed);
        b.walls[1][1] = Wall::new(WallKind::Free);
        let n = g.num_nodes();
        let val = |i: usize, c: usize| ((i * 13 + c * 5) % 17) as f64 * 0.29 - 2.3;
        let vec = |c: usize| -> Vec<Vector<f64, 2>> {
            (0..n)
                .map(|i| Vector::<f64, 2>::new(val(i, c), val(i, c + 1)))
                .collect()
        };
        let dot = |a: &[Vector<f64, 2>], b: &[Vector<f64, 2>]| -> f64 {
            a.iter().zip(b).map(|(a, b)| a.dot(b)).sum()
        };
        let (x_m, x_p, x_f) = (
            (0..n).map(|i| val(i, 9)).collect::<Vec<_>>(),
            vec(0),
            vec(2),
        );
        let (y_m, y_p, y_f) = (
            (0..n).map(|i| val(i, 7)).collect::<Vec<_>>(),
            vec(4),
            vec(6),
        );
        let (mut ax_m, mut ax_p, mut ax_f) = (x_m.clone(), x_p.clone(), x_f.clone());
        b.fold_ghosts(&g, Some(&mut ax_m), &mut ax_p, Some(&mut ax_f));
        let (mut aty_m, mut aty_p, mut aty_f) = (y_m.clone(), y_p.clone(), y_f.clone());
        b.fold_ghosts_adjoint(&g, Some(&mut aty_m), &mut aty_p, Some(&mut aty_f));
        let lhs: f64 = ax_m.iter().zip(&y_m).map(|(a, b)| a * b).sum::<f64>()
            + dot(&ax_p, &y_p)
            + dot(&ax_f, &y_f);
        let rhs: f64 = x_m.iter().zip(&aty_m).map(|(a, b)| a * b).sum::<f64>()
            + dot(&x_p, &aty_p)
            + dot(&x_f, &aty_f);
        // Sums of a few hundred O(1) products: agreement to round-off.
        assert!(
            (lhs - rhs).abs() < 1e-12 * lhs.abs().max(1.0),
            "{lhs} vs {rhs}"
        );

        let mut ax = x_p.clone();
        b.reflect_ghosts(&g, &mut ax);
        let mut aty = y_p.clone();
        b.reflect_ghosts_adjoint(&g, &mut aty);
        let (lhs, rhs) = (dot(&ax, &y_p), dot(&x_p, &aty));
        assert!(
            (lhs - rhs).abs() < 1e-12 * lhs.abs().max(1.0),
            "{lhs} vs {rhs}"
        );
    }
}
