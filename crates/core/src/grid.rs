//! The structured Cartesian background grid.
//!
//! Nodes sit at `x_i = origin + i·h` with a flat index `i + nx·(j + ny·k)`. The physical
//! domain `[lo, hi]` is surrounded by `pad` ghost cells on every side so that the stencil of a
//! particle near a wall stays on the grid; wall conditions act on the nodes on or beyond a face.

use crate::scalar::Scalar;
use crate::tensor::Vector;

/// A uniform grid in `D` dimensions (geometry is plain `f64`: it is never differentiated).
#[derive(Clone, Debug, PartialEq)]
pub struct Grid<const D: usize> {
    /// Lower corner of the physical domain (where the walls are).
    pub lo: [f64; D],
    /// Number of cells of the physical domain along each axis.
    pub cells: [usize; D],
    /// Cell size `h`.
    pub h: f64,
    /// Ghost cells added outside the domain on every side.
    pub pad: usize,
}

impl<const D: usize> Grid<D> {
    /// A grid of `cells` cells of size `h` from `lo`, padded by `pad` ghost cells per side.
    pub fn new(lo: [f64; D], cells: [usize; D], h: f64, pad: usize) -> Self {
        Self { lo, cells, h, pad }
    }

    /// Upper corner of the physical domain, `lo + cells·h`.
    #[inline]
    pub fn hi(&self) -> [f64; D] {
        std::array::from_fn(|a| self.lo[a] + self.cells[a] as f64 * self.h)
    }

    /// Position of node 0 (the first ghost node), `lo − pad·h`.
    #[inline]
    pub fn origin(&self) -> [f64; D] {
        std::array::from_fn(|a| self.lo[a] - self.pad as f64 * self.h)
    }

    /// Number of nodes along each axis, `cells + 2·pad + 1`.
    #[inline]
    pub fn nodes(&self) -> [usize; D] {
        std::array::from_fn(|a| self.cells[a] + 2 * self.pad + 1)
    }

    /// Total number of nodes.
    #[inline]
    pub fn num_nodes(&self) -> usize {
        self.nodes().iter().product()
    }

    /// Flat index `i + nx·(j + ny·k)` of a node given by its multi-index.
    #[inline]
    pub fn flat(&self, idx: [usize; D]) -> usize {
        let n = self.nodes();
        let mut f = 0;
        for a in (0..D).rev() {
            f = f * n[a] + idx[a];
        }
        f
    }

    /// Multi-index of a flat node index.
    #[inline]
    pub fn multi(&self, mut flat: usize) -> [usize; D] {
        let n = self.nodes();
        std::array::from_fn(|a| {
            let i = flat % n[a];
            flat /= n[a];
            i
        })
    }

    /// Position of a node.
    #[inline]
    pub fn node_position<T: Scalar>(&self, idx: [usize; D]) -> Vector<T, D> {
        let o = self.origin();
        Vector::<T, D>::from_fn(|a, _| T::cst(o[a] + idx[a] as f64 * self.h))
    }

    /// `true` when the node lies on or beyond the lower (`side = 0`) or upper (`side = 1`)
    /// face of the physical domain normal to `axis`.
    #[inline]
    pub fn on_face(&self, idx: [usize; D], axis: usize, side: usize) -> bool {
        if side == 0 {
            idx[axis] <= self.pad
        } else {
            idx[axis] >= self.pad + self.cells[axis]
        }
    }

    /// `true` when a stencil of width `b` starting at node `base` lies inside the node array.
    #[inline]
    pub fn contains_stencil(&self, base: [isize; D], b: usize) -> bool {
        let n = self.nodes();
        (0..D).all(|a| base[a] >= 0 && base[a] as usize + b <= n[a])
    }

    /// `true` when a point lies inside the physical domain (walls included).
    pub fn in_domain(&self, x: &[f64; D]) -> bool {
        let hi = self.hi();
        (0..D).all(|a| x[a] >= self.lo[a] && x[a] <= hi[a])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_and_multi_index_round_trip() {
        let g = Grid::<3>::new([0.0; 3], [4, 5, 6], 0.5, 2);
        assert_eq!(g.nodes(), [9, 10, 11]);
        for f in [0, 1, 17, 500, g.num_nodes() - 1] {
            assert_eq!(g.flat(g.multi(f)), f);
        }
        assert_eq!(g.flat([1, 2, 3]), 1 + 9 * (2 + 10 * 3));
        let x: Vector<f64, 3> = g.node_position([2, 2, 2]);
        assert_eq!(x, Vector::<f64, 3>::zeros());
        assert!(g.on_face([2, 5, 5], 0, 0) && !g.on_face([3, 5, 5], 0, 0));
        assert!(g.on_face([5, 7, 5], 1, 1));
    }
}
