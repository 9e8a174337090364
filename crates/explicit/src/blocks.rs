//! Deterministic, lock-free particle-to-grid accumulation.
//!
//! Particles are sorted (counting sort, stable) into blocks of `BLOCK^D` cells by the first
//! node of their stencil. Each occupied block accumulates its particles, in sorted order, into
//! a private buffer covering the `(BLOCK + b − 1)^D` nodes its stencils can reach; blocks run in
//! parallel without sharing anything. A node then sums the (at most `2^D`) buffers that cover
//! it in a fixed block order. Every floating-point sum therefore happens in an order that does
//! not depend on the thread count, so P2G gives the same bits with 1 or N threads.

use loam_core::Scalar;
use loam_core::tensor::Vector;
use rayon::prelude::*;

/// Block edge in cells. Must be at least `b − 1` so a node is covered by at most two blocks
/// per axis (true for every shape: b ≤ 4).
pub(crate) const BLOCK: usize = 4;

const EMPTY: u32 = u32::MAX;

/// What a node accumulates: mass, momentum, force.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Accum<T: Scalar, const D: usize> {
    pub m: T,
    pub p: Vector<T, D>,
    pub f: Vector<T, D>,
}

impl<T: Scalar, const D: usize> Accum<T, D> {
    fn zero() -> Self {
        Self {
            m: T::zero(),
            p: Vector::zeros(),
            f: Vector::zeros(),
        }
    }
}

/// The private buffer of one block, handed to the per-particle contribution closure.
pub(crate) struct BlockSink<'a, T: Scalar, const D: usize> {
    origin: [usize; D],
    width: usize,
    data: &'a mut [Accum<T, D>],
}

impl<T: Scalar, const D: usize> BlockSink<'_, T, D> {
    #[inline(always)]
    fn local(&self, node: [usize; D]) -> usize {
        let mut l = 0;
        for a in (0..D).rev() {
            l = l * self.width + (node[a] - self.origin[a]);
        }
        l
    }

    /// Adds mass, momentum and force to a node of this block's reach.
    #[inline(always)]
    pub fn add(&mut self, node: [usize; D], m: T, p: Vector<T, D>, f: Vector<T, D>) {
        let e = &mut self.data[self.local(node)];
        e.m += m;
        e.p += p;
        e.f += f;
    }

    /// Adds momentum only (MUSL's second transfer).
    #[inline(always)]
    pub fn add_momentum(&mut self, node: [usize; D], p: Vector<T, D>) {
        let l = self.local(node);
        self.data[l].p += p;
    }
}

/// Sorted particle order, occupied blocks and their buffers.
pub(crate) struct Blocks<T: Scalar, const D: usize> {
    dims: [usize; D],
    width: usize,
    order: Vec<u32>,
    occupied: Vec<(usize, usize, usize)>,
    slot: Vec<u32>,
    buffers: Vec<Vec<Accum<T, D>>>,
    counts: Vec<u32>,
}

impl<T: Scalar, const D: usize> Blocks<T, D> {
    /// Blocks for a grid with `nodes` nodes per axis and stencils of width `b`.
    pub fn new(nodes: [usize; D], b: usize) -> Self {
        let dims = std::array::from_fn(|a| nodes[a].div_ceil(BLOCK));
        let total: usize = dims.iter().product();
        Self {
            dims,
            width: BLOCK + b - 1,
            order: Vec::new(),
            occupied: Vec::new(),
            slot: vec![EMPTY; total],
            buffers: Vec::new(),
            counts: vec![0; total + 1],
        }
    }

    fn block_of(&self, base: &[isize; D]) -> usize {
        let mut f = 0;
        for a in (0..D).rev() {
            f = f * self.dims[a] + base[a] as usize / BLOCK;
        }
        f
    }

    /// Sorts particles by the block of their stencil base (all bases must be on the grid).
    pub fn sort(&mut self, bases: &[[isize; D]]) {
        self.counts.iter_mut().for_each(|c| *c = 0);
        let keys: Vec<usize> = bases.iter().map(|b| self.block_of(b)).collect();
        for &k in &keys {
            self.counts[k + 1] += 1;
        }
        for i in 1..self.counts.len() {
            self.counts[i] += self.counts[i - 1];
        }
        self.occupied.clear();
        self.slot.iter_mut().for_each(|s| *s = EMPTY);
        for k in 0..self.counts.len() - 1 {
            let (s, e) = (self.counts[k] as usize, self.counts[k + 1] as usize);
            if e > s {
                self.slot[k] = self.occupied.len() as u32;
                self.occupied.push((k, s, e));
            }
        }
        self.order.resize(bases.len(), 0);
        let mut next = self.counts.clone();
        for (p, &k) in keys.iter().enumerate() {
            self.order[next[k] as usize] = p as u32;
            next[k] += 1;
        }
        let len = self.width.pow(D as u32);
        self.buffers.resize_with(self.occupied.len(), Vec::new);
        for b in &mut self.buffers {
            b.resize(len, Accum::zero());
        }
    }

    /// Runs `contribute(particle, sink)` for every particle, block by block in parallel,
    /// into zeroed block buffers.
    pub fn accumulate<F>(&mut self, contribute: F)
    where
        F: Fn(usize, &mut BlockSink<'_, T, D>) + Sync,
    {
        let (dims, width, order) = (self.dims, self.width, &self.order);
        self.buffers
            .par_iter_mut()
            .zip(self.occupied.par_iter())
            .for_each(|(buf, &(block, start, end))| {
                buf.iter_mut().for_each(|e| *e = Accum::zero());
                let mut rest = block;
                let origin = std::array::from_fn(|a| {
                    let k = rest % dims[a];
                    rest /= dims[a];
                    k * BLOCK
                });
                let mut sink = BlockSink {
                    origin,
                    width,
                    data: buf,
                };
                for &p in &order[start..end] {
                    contribute(p as usize, &mut sink);
                }
            });
    }

    /// Sum, over the blocks covering `node` (in a fixed order), of their buffer entries.
    #[inline]
    pub fn gather(&self, node: [usize; D]) -> Accum<T, D> {
        let mut acc = Accum::zero();
        for combo in 0..(1usize << D) {
            let mut flat = 0;
            let mut local = 0;
            let mut ok = true;
            for a in (0..D).rev() {
                let shift = (combo >> a) & 1;
                let k = node[a] / BLOCK;
                if k < shift {
                    ok = false;
                    break;
                }
                let k = k - shift;
                let off = node[a] - k * BLOCK;
                if off >= self.width || k >= self.dims[a] {
                    ok = false;
                    break;
                }
                flat = flat * self.dims[a] + k;
                local = local * self.width + off;
            }
            if !ok {
                continue;
            }
            let s = self.slot[flat];
            if s != EMPTY {
                let e = &self.buffers[s as usize][local];
                acc.m += e.m;
                acc.p += e.p;
                acc.f += e.f;
            }
        }
        acc
    }
}
