//! Deterministic, lock-free particle-to-grid accumulation, and the part of the grid a step
//! touches.
//!
//! Particles are sorted (counting sort, stable) into blocks of `BLOCK^D` cells by the first
//! node of their stencil. Each occupied block accumulates its particles, in sorted order, into
//! a private buffer covering the `(BLOCK + b − 1)^D` nodes its stencils can reach; blocks run in
//! parallel without sharing anything. A node then sums the (at most `2^D`) buffers that cover
//! it in a fixed block order. Every floating-point sum therefore happens in an order that does
//! not depend on the thread count, so P2G gives the same bits with 1 or N threads.
//!
//! The grid is visited by *rows* (all nodes with the same `(j, k)`; contiguous in the flat
//! numbering, so rows can be handed to threads as disjoint slices). In each row only the nodes
//! a step can touch are visited: the span of the buffers that cover the row, plus the layers
//! next to the faces of bilateral walls, where [`loam_core::Boundary::fold_ghosts`] and
//! [`loam_core::Boundary::reflect_ghosts`] read and write. Every other node of the grid arrays
//! is kept at zero: a row first clears the span it had in the previous step.

use loam_core::stencil::Layout;
use loam_core::step::NodeSums;
use loam_core::tensor::Vector;
use loam_core::{Boundary, Grid, Scalar};
use rayon::prelude::*;

/// Block edge in cells. Must be at least `b − 1` so a node is covered by at most two blocks
/// per axis (true for every shape: b ≤ 4).
pub(crate) const BLOCK: usize = 4;

/// Slot of an unoccupied block.
const EMPTY: u32 = u32::MAX;

/// Sort key of a particle whose stencil is not on the grid.
pub(crate) const OFF_GRID: u32 = u32::MAX;

/// Blocks handed to one rayon task at least (a block holds tens of particles).
const MIN_BLOCKS_PER_TASK: usize = 4;

/// Grid rows handed to one rayon task at least.
pub(crate) const MIN_ROWS_PER_TASK: usize = 8;

/// A half-open range of node indices along axis 0 of one row.
type Span = (usize, usize);

/// The block rows (blocks with the same `(by, bz)`) that cover one node row: the flat block
/// index of the row's block `bx = 0` and the buffer index of the node row's first entry.
#[derive(Clone, Copy, Debug, Default)]
struct Source {
    block: usize,
    local: usize,
}

/// Sorted particle order, occupied blocks and their buffers, and the visited part of each row.
pub(crate) struct Blocks<T: Scalar, const D: usize> {
    /// Blocks per axis.
    dims: [usize; D],
    /// Grid nodes per axis.
    nodes: [usize; D],
    /// Support width `b` of the stencils.
    b: usize,
    /// Buffer edge `BLOCK + b − 1` in nodes.
    width: usize,
    /// Sorted position → particle.
    order: Vec<u32>,
    /// Particle → sorted position.
    rank: Vec<u32>,
    /// Occupied blocks in block order: (block, first sorted position, end).
    occupied: Vec<(usize, usize, usize)>,
    /// Block → index into `occupied` / `buffers`, or `EMPTY`.
    slot: Vec<u32>,
    /// One buffer per occupied block (only the first `occupied.len()` are in use).
    buffers: Vec<Vec<NodeSums<T, D>>>,
    /// Counting-sort histogram (block `k` holds positions `counts[k]..counts[k + 1]`).
    counts: Vec<u32>,
    /// Counting-sort insertion cursors.
    cursor: Vec<u32>,
    /// Per block row, the occupied `bx` range (empty when none).
    block_span: Vec<Span>,
    /// Per node row, the span the buffers reach this step.
    span: Vec<Span>,
    /// Per node row, the span of the previous step (cleared before the gather).
    prev_span: Vec<Span>,
    /// Per axis, nodes always visited at the low and high ends (the mirror layers of bilateral
    /// walls: ghosts and the nodes they fold into, `2·pad + 1`), 0 where no wall mirrors.
    caps: [[usize; 2]; D],
    /// The grid rows in groups closed under the ghost/mirror maps of the walls (half-open
    /// row ranges, in order, covering every row once): see [`Blocks::groups`].
    groups: Vec<Span>,
}

impl<T: Scalar, const D: usize> Blocks<T, D> {
    /// Blocks for `grid`, stencils of width `b` and the walls in `boundary`.
    pub fn new(grid: &Grid<D>, b: usize, boundary: &Boundary<D>) -> Self {
        let nodes = grid.nodes();
        let dims = std::array::from_fn(|a| nodes[a].div_ceil(BLOCK));
        let total: usize = dims.iter().product();
        let rows: usize = nodes[1..].iter().product();
        let block_rows: usize = dims[1..].iter().product();
        // `fold_ghosts` / `reflect_ghosts` act beyond bilateral walls: on the `pad` ghost
        // layers and the `pad` layers inside the face that mirror them.
        let caps = boundary.mirror_layers(grid);
        let mut groups = Vec::new();
        row_groups(&nodes, &caps, D - 1, 0, &mut groups);
        Self {
            dims,
            nodes,
            b,
            width: BLOCK + b - 1,
            order: Vec::new(),
            rank: Vec::new(),
            occupied: Vec::new(),
            slot: vec![EMPTY; total],
            buffers: Vec::new(),
            counts: Vec::new(),
            cursor: Vec::new(),
            block_span: vec![(0, 0); block_rows],
            span: vec![(0, 0); rows],
            prev_span: vec![(0, 0); rows],
            caps,
            groups,
        }
    }

    /// The grid rows in groups, as half-open row ranges in order: a group holds, along every
    /// axis above 0, either all the mirror layers at one end of a bilateral wall or none of
    /// them (for fixed indices along the higher axes), so it is closed under the ghost/mirror
    /// maps and [`loam_core::Boundary::fold_ghosts_in`] and
    /// [`loam_core::Boundary::reflect_ghosts_in`] can act on it alone. Every other row is a
    /// group of its own.
    #[inline]
    pub fn groups(&self) -> &[Span] {
        &self.groups
    }

    /// `grid` (one entry per node) cut into the node ranges of the [groups](Blocks::groups).
    pub fn split_groups<'a, X>(&self, mut grid: &'a mut [X]) -> Vec<&'a mut [X]> {
        let n = self.row_len();
        let mut out = Vec::with_capacity(self.groups.len());
        for &(r0, r1) in &self.groups {
            let (group, rest) = grid.split_at_mut((r1 - r0) * n);
            out.push(group);
            grid = rest;
        }
        out
    }

    /// Sort key of a particle whose stencil starts at node `base`: its block, or [`OFF_GRID`]
    /// when the stencil leaves the grid.
    #[inline]
    pub fn key(&self, base: [isize; D]) -> u32 {
        let mut f = 0;
        for a in (0..D).rev() {
            if base[a] < 0 || base[a] as usize + self.b > self.nodes[a] {
                return OFF_GRID;
            }
            f = f * self.dims[a] + base[a] as usize / BLOCK;
        }
        f as u32
    }

    /// Sorted position of particle `p` (valid after [`Blocks::sort`]).
    #[inline]
    pub fn rank(&self, p: usize) -> usize {
        self.rank[p] as usize
    }

    /// Sorts particles by their keys (none may be [`OFF_GRID`]), then finds the span of every
    /// grid row the buffers reach.
    pub fn sort(&mut self, keys: &[u32]) {
        let total = self.slot.len();
        self.counts.clear();
        self.counts.resize(total + 1, 0);
        // By runs of equal keys (consecutive particles mostly share a block): a counter is
        // loaded and stored once per run, not once per particle through memory.
        for run in keys.chunk_by(|a, b| a == b) {
            self.counts[run[0] as usize + 1] += run.len() as u32;
        }
        for i in 1..self.counts.len() {
            self.counts[i] += self.counts[i - 1];
        }
        self.occupied.clear();
        for k in 0..total {
            let (s, e) = (self.counts[k] as usize, self.counts[k + 1] as usize);
            if e > s {
                self.slot[k] = self.occupied.len() as u32;
                self.occupied.push((k, s, e));
            } else {
                self.slot[k] = EMPTY;
            }
        }
        self.order.resize(keys.len(), 0);
        self.rank.resize(keys.len(), 0);
        self.cursor.clone_from(&self.counts);
        let (order, rank) = (&mut self.order, &mut self.rank);
        let mut p = 0;
        for run in keys.chunk_by(|a, b| a == b) {
            let cursor = &mut self.cursor[run[0] as usize];
            let s = *cursor as usize;
            for (i, (o, r)) in order[s..s + run.len()]
                .iter_mut()
                .zip(&mut rank[p..p + run.len()])
                .enumerate()
            {
                (*o, *r) = ((p + i) as u32, (s + i) as u32);
            }
            *cursor += run.len() as u32;
            p += run.len();
        }
        let len = self.width.pow(D as u32);
        if self.buffers.len() < self.occupied.len() {
            self.buffers.resize_with(self.occupied.len(), Vec::new);
        }
        for b in &mut self.buffers[..self.occupied.len()] {
            b.resize(len, NodeSums::zero());
        }
        self.find_spans();
    }

    /// The span of every node row reached by the buffers of the occupied blocks (the hull of
    /// the buffers of the block rows that cover it).
    fn find_spans(&mut self) {
        std::mem::swap(&mut self.span, &mut self.prev_span);
        self.block_span
            .iter_mut()
            .for_each(|s| *s = (usize::MAX, 0));
        for &(k, _, _) in &self.occupied {
            let (bx, row) = (k % self.dims[0], k / self.dims[0]);
            let s = &mut self.block_span[row];
            *s = (s.0.min(bx), s.1.max(bx + 1));
        }
        for r in 0..self.span.len() {
            let (mut lo, mut hi) = (usize::MAX, 0);
            for src in self.sources(r).iter().flatten() {
                let (b0, b1) = self.block_span[src.block / self.dims[0]];
                if b0 < b1 {
                    lo = lo.min(b0 * BLOCK);
                    hi = hi.max((b1 - 1) * BLOCK + self.width);
                }
            }
            self.span[r] = if lo < hi {
                (lo, hi.min(self.nodes[0]))
            } else {
                (0, 0)
            };
        }
    }

    /// Node multi-index of the first node of row `r` (its axis-0 index is 0).
    #[inline]
    pub fn row_node(&self, r: usize) -> [usize; D] {
        let mut rest = r;
        std::array::from_fn(|a| {
            if a == 0 {
                0
            } else {
                let i = rest % self.nodes[a];
                rest /= self.nodes[a];
                i
            }
        })
    }

    /// Nodes per row (the grid's node count along axis 0).
    #[inline]
    pub fn row_len(&self) -> usize {
        self.nodes[0]
    }

    /// The block rows covering node row `r`, in the fixed summation order (by the shift along
    /// y, then z); `None` where a shift does not cover the row.
    #[inline]
    fn sources(&self, r: usize) -> [Option<Source>; 4] {
        let node = self.row_node(r);
        let mut out = [None; 4];
        let combos = 1usize << (D - 1);
        'combo: for combo in 0..combos {
            let (mut block, mut local) = (0, 0);
            let (mut bstride, mut lstride) = (self.dims[0], self.width);
            for a in 1..D {
                let shift = (combo >> (a - 1)) & 1;
                let k = node[a] / BLOCK;
                if k < shift {
                    continue 'combo;
                }
                let k = k - shift;
                let off = node[a] - k * BLOCK;
                if off >= self.width {
                    continue 'combo;
                }
                block += k * bstride;
                local += off * lstride;
                bstride *= self.dims[a];
                lstride *= self.width;
            }
            out[combo] = Some(Source { block, local });
        }
        out
    }

    /// Calls `f(entry)` for the buffer entries of node `i` of the row with block-row sources
    /// `sources`, in the fixed order (shift along x fastest, as the blocks' flat order).
    #[inline(always)]
    fn each_entry(
        &self,
        sources: &[Option<Source>; 4],
        i: usize,
        mut f: impl FnMut(&NodeSums<T, D>),
    ) {
        let (kx, off) = (i / BLOCK, i % BLOCK);
        // The block holding the node, and the one before it along x when its buffer reaches
        // this far (`off + BLOCK < width`).
        let lower = kx > 0 && off + BLOCK < self.width;
        for src in sources.iter().flatten() {
            let s = self.slot[src.block + kx];
            if s != EMPTY {
                f(&self.buffers[s as usize][src.local + off]);
            }
            if lower {
                let s = self.slot[src.block + kx - 1];
                if s != EMPTY {
                    f(&self.buffers[s as usize][src.local + off + BLOCK]);
                }
            }
        }
    }

    /// Calls `f(i)` for the nodes `i` of row `r` visited this step, in ascending order: the
    /// whole row where it lies in a mirror layer across axes 1.., else the span the buffers
    /// reach plus the mirror layers at both ends.
    #[inline]
    pub fn for_each_visited(&self, r: usize, mut f: impl FnMut(usize)) {
        let n = self.nodes[0];
        let node = self.row_node(r);
        let in_layer =
            (1..D).any(|a| node[a] < self.caps[a][0] || node[a] + self.caps[a][1] >= self.nodes[a]);
        if in_layer {
            (0..n).for_each(f);
            return;
        }
        let mut spans = [(0, self.caps[0][0]), self.span[r], (n - self.caps[0][1], n)];
        spans.sort_unstable_by_key(|s| s.0);
        let mut next = 0;
        for (lo, hi) in spans {
            for i in lo.max(next)..hi {
                f(i);
            }
            next = next.max(hi);
        }
    }

    /// Zeroes what the previous step left in row `r` and sums the block buffers into its
    /// visited nodes: mass, momentum and force (the grid arrays are zero elsewhere). The
    /// slices are the row's entries.
    pub fn gather_row(
        &self,
        r: usize,
        m: &mut [T],
        p: &mut [Vector<T, D>],
        f: &mut [Vector<T, D>],
    ) {
        let (lo, hi) = self.prev_span[r];
        m[lo..hi].fill(T::zero());
        p[lo..hi].fill(Vector::zeros());
        f[lo..hi].fill(Vector::zeros());
        let sources = self.sources(r);
        self.for_each_visited(r, |i| {
            let mut acc = NodeSums::zero();
            self.each_entry(&sources, i, |e| {
                acc.m += e.m;
                acc.p += e.p;
                acc.f += e.f;
            });
            (m[i], p[i], f[i]) = (acc.m, acc.p, acc.f);
        });
    }

    /// Sums the momentum of the block buffers into the visited nodes of row `r` (MUSL's
    /// second transfer, after [`Blocks::gather_row`] in the same step).
    pub fn gather_momentum_row(&self, r: usize, p: &mut [Vector<T, D>]) {
        let sources = self.sources(r);
        self.for_each_visited(r, |i| {
            let mut acc = Vector::zeros();
            self.each_entry(&sources, i, |e| acc += e.p);
            p[i] = acc;
        });
    }

    /// Runs `contribute(particle, layout, buffer, out)` for every particle, block by block in
    /// parallel and in sorted order within a block, after `reset` on every buffer entry.
    /// `layout` maps grid nodes to `buffer` entries; `out` is the particle's entry of
    /// `scratch` (indexed by sorted position, so each block owns a contiguous piece).
    pub fn for_each_block<X: Send>(
        &mut self,
        scratch: &mut [X],
        reset: impl Fn(&mut NodeSums<T, D>) + Sync,
        contribute: impl Fn(usize, &Layout<D>, &mut [NodeSums<T, D>], &mut X) + Sync,
    ) {
        let mut pieces = Vec::with_capacity(self.occupied.len());
        let mut rest = scratch;
        for &(_, start, end) in &self.occupied {
            let (piece, tail) = rest.split_at_mut(end - start);
            pieces.push(piece);
            rest = tail;
        }
        let (dims, width, order) = (self.dims, self.width, &self.order);
        let used = self.occupied.len();
        self.buffers[..used]
            .par_iter_mut()
            .zip(self.occupied.par_iter())
            .zip(pieces)
            .with_min_len(MIN_BLOCKS_PER_TASK)
            .for_each(|((buf, &(block, start, end)), piece)| {
                buf.iter_mut().for_each(&reset);
                let mut rest = block;
                let origin = std::array::from_fn(|a| {
                    let k = rest % dims[a];
                    rest /= dims[a];
                    k * BLOCK
                });
                let layout = Layout::cube(origin, width);
                for (&p, out) in order[start..end].iter().zip(piece) {
                    contribute(p as usize, &layout, buf, out);
                }
            });
    }
}

/// Appends to `out` the row groups (see [`Blocks::groups`]) of the rows whose indices along
/// the axes above `axis` are fixed and whose first row is `first`: along `axis`, the mirror
/// layers at each end make one group (all of them, when the two ends meet), and every index
/// between them recurses to the axis below (a single row at axis 1).
fn row_groups<const D: usize>(
    nodes: &[usize; D],
    caps: &[[usize; 2]; D],
    axis: usize,
    first: usize,
    out: &mut Vec<Span>,
) {
    if axis == 0 {
        out.push((first, first + 1));
        return;
    }
    // Rows per unit step along `axis`.
    let stride: usize = nodes[1..axis].iter().product();
    let n = nodes[axis];
    let [lo, hi] = caps[axis];
    if lo + hi >= n {
        out.push((first, first + n * stride));
        return;
    }
    if lo > 0 {
        out.push((first, first + lo * stride));
    }
    for i in lo..n - hi {
        row_groups(nodes, caps, axis - 1, first + i * stride, out);
    }
    if hi > 0 {
        out.push((first + (n - hi) * stride, first + n * stride));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use loam_core::{Wall, WallKind};

    /// Deterministic pseudo-random numbers in [0, 1).
    fn rng(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Particles at random stencil bases inside `[lo, hi)` (node indices per axis) deposit
    /// mass 1 and momentum `(p, 0, ..)` on every node of a `b^D` stencil; the visited-row
    /// gather must equal a dense sum over the whole grid, also after the particles have moved
    /// elsewhere (what the previous step left is cleared).
    fn check_gather<const D: usize>(b: usize) {
        let grid = Grid::<D>::new([0.0; D], [13; D], 1.0, 2);
        let mut boundary = Boundary::all(Wall::new(WallKind::Slip));
        boundary.walls[0][1] = Wall::new(WallKind::Free);
        let mut blocks = Blocks::<f64, D>::new(&grid, b, &boundary);
        let nodes = grid.nodes();
        let n = grid.num_nodes();
        let (mut mass, mut mom, mut force) = (
            vec![0.0; n],
            vec![Vector::<f64, D>::zeros(); n],
            vec![Vector::<f64, D>::zeros(); n],
        );
        // The nodes of the stencil at `base`, by local index `l < b^D` (axis 0 fastest).
        let node = |base: &[isize; D], l: usize| -> [usize; D] {
            let mut rest = l;
            std::array::from_fn(|a| {
                let k = rest % b;
                rest /= b;
                base[a] as usize + k
            })
        };
        let mut seed = 7 + D as u64;
        for (lo, hi) in [(0usize, 9usize), (7, nodes[0] - b + 1), (3, 6)] {
            let bases: Vec<[isize; D]> = (0..60)
                .map(|_| {
                    std::array::from_fn(|_| {
                        (lo + (rng(&mut seed) * (hi - lo) as f64) as usize) as isize
                    })
                })
                .collect();
            let keys: Vec<u32> = bases.iter().map(|&base| blocks.key(base)).collect();
            assert!(keys.iter().all(|&k| k != OFF_GRID));
            blocks.sort(&keys);
            let mut none = vec![(); bases.len()];
            blocks.for_each_block(
                &mut none,
                |e| *e = NodeSums::zero(),
                |p, layout, buf, _| {
                    for l in 0..b.pow(D as u32) {
                        let at = node(&bases[p], l);
                        let i = layout.index(at);
                        buf[i].m += 1.0;
                        buf[i].p[0] += p as f64;
                    }
                },
            );
            let row = grid.nodes()[0];
            for (r, ((m, p), f)) in mass
                .chunks_mut(row)
                .zip(mom.chunks_mut(row))
                .zip(force.chunks_mut(row))
                .enumerate()
            {
                blocks.gather_row(r, m, p, f);
            }
            let mut dense = vec![(0.0, 0.0); n];
            for (p, base) in bases.iter().enumerate() {
                for l in 0..b.pow(D as u32) {
                    let f = grid.flat(node(base, l));
                    dense[f].0 += 1.0;
                    dense[f].1 += p as f64;
                }
            }
            for f in 0..n {
                assert_eq!(mass[f], dense[f].0, "mass at node {:?}", grid.multi(f));
                assert_eq!(
                    mom[f][0],
                    dense[f].1,
                    "momentum at node {:?}",
                    grid.multi(f)
                );
            }
        }
    }

    /// Folding and reflecting group by group gives the bits of the whole-grid fold and
    /// reflection, and the groups cover every row once, in order.
    fn check_groups<const D: usize>(cells: [usize; D], walls: [[Wall; 2]; D]) {
        let grid = Grid::<D>::new([0.0; D], cells, 1.0, 2);
        let boundary = Boundary { walls };
        let blocks = Blocks::<f64, D>::new(&grid, 3, &boundary);
        let n = grid.num_nodes();
        let row = grid.nodes()[0];
        let mut next = 0;
        for &(r0, r1) in blocks.groups() {
            assert!(r0 == next && r1 > r0, "groups {:?}", blocks.groups());
            next = r1;
        }
        assert_eq!(next * row, n);
        let mut seed = 11 + D as u64;
        let mut random = |_| Vector::<f64, D>::from_fn(|_, _| rng(&mut seed) - 0.5);
        let p0: Vec<Vector<f64, D>> = (0..n).map(&mut random).collect();
        let f0: Vec<Vector<f64, D>> = (0..n).map(&mut random).collect();
        let m0: Vec<f64> = (0..n).map(|i| (i % 7) as f64 + 0.25).collect();
        let (mut m1, mut p1, mut f1) = (m0.clone(), p0.clone(), f0.clone());
        boundary.fold_ghosts(&grid, Some(&mut m1), &mut p1, Some(&mut f1));
        boundary.reflect_ghosts(&grid, &mut p1);
        let (mut m2, mut p2, mut f2) = (m0, p0, f0);
        for (((m, p), f), &(r0, r1)) in blocks
            .split_groups(&mut m2)
            .into_iter()
            .zip(blocks.split_groups(&mut p2))
            .zip(blocks.split_groups(&mut f2))
            .zip(blocks.groups())
        {
            let nodes = r0 * row..r1 * row;
            boundary.fold_ghosts_in(&grid, nodes.clone(), Some(m), p, Some(f));
            boundary.reflect_ghosts_in(&grid, nodes, p);
        }
        assert_eq!((m1, p1, f1), (m2, p2, f2));
    }

    #[test]
    fn group_by_group_folds_give_the_whole_grid_bits() {
        let (slip, fixed, free) = (
            Wall::new(WallKind::Slip),
            Wall::new(WallKind::Fixed),
            Wall::new(WallKind::Free),
        );
        let separable = Wall {
            kind: WallKind::Slip,
            separable: true,
        };
        check_groups::<2>([9, 7], [[slip, fixed], [separable, slip]]);
        check_groups::<2>([9, 7], [[free, slip], [slip, free]]);
        // Mirror layers that meet (2·(2·pad + 1) ≥ nodes): one group along that axis.
        check_groups::<2>([3, 3], [[slip, slip], [fixed, slip]]);
        check_groups::<3>([6, 7, 8], [[slip, fixed], [slip, separable], [fixed, slip]]);
        check_groups::<3>([5, 6, 4], [[free, slip], [slip, slip], [free, free]]);
    }

    #[test]
    fn visited_rows_gather_what_a_dense_sum_gives() {
        for b in 2..=4 {
            check_gather::<2>(b);
            check_gather::<3>(b);
        }
    }
}
