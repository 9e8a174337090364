//! The `b^D` tensor-product stencil of one particle.

use crate::grid::Grid;
use crate::scalar::Scalar;
use crate::shape::{MAX_SUPPORT, Shape, ShapeFunction, Weights1D};
use crate::tensor::{Tensor, Vector};

/// One node of a particle's stencil, as handed to [`Stencil::for_each`].
#[derive(Clone, Copy, Debug)]
pub struct StencilNode<T: Scalar, const D: usize> {
    /// Grid multi-index of the node.
    pub index: [usize; D],
    /// Flat grid index `i + nx·(j + ny·k)`.
    pub flat: usize,
    /// Weight `w_ip`.
    pub weight: T,
    /// Gradient `∇w_ip`.
    pub gradient: Vector<T, D>,
    /// Offset from the particle to the node, `x_i − x_p`.
    pub offset: Vector<T, D>,
}

/// How the nodes of a box of the grid map to the entries of an array:
/// `index(node) = Σ_a (node_a − origin_a) · strides[a]`, axis 0 contiguous (stride 1), so a
/// row of a stencil is a run of consecutive entries. The whole grid in flat order is
/// [`Layout::grid`]; a block-local buffer is [`Layout::cube`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout<const D: usize> {
    /// The node stored at index 0.
    origin: [usize; D],
    /// Index step per unit step of the node index along each axis (`strides[0] = 1`).
    strides: [usize; D],
}

impl<const D: usize> Layout<D> {
    /// The grid's own flat numbering, `i + nx·(j + ny·k)` ([`Grid::flat`]).
    #[inline]
    pub fn grid(grid: &Grid<D>) -> Self {
        Self::grid_of_nodes(grid.nodes())
    }

    /// The flat numbering of a grid with `nodes` nodes per axis.
    #[inline]
    fn grid_of_nodes(nodes: [usize; D]) -> Self {
        Self::cube_strides([0; D], |a| nodes[a])
    }

    /// A box from `origin` whose extent along axis `a` is `extent(a)` nodes, axis 0 fastest.
    #[inline]
    fn cube_strides(origin: [usize; D], extent: impl Fn(usize) -> usize) -> Self {
        let mut strides = [1usize; D];
        for a in 1..D {
            strides[a] = strides[a - 1] * extent(a - 1);
        }
        Self { origin, strides }
    }

    /// A cube of `width^D` nodes from `origin`, axis 0 fastest.
    #[inline]
    pub fn cube(origin: [usize; D], width: usize) -> Self {
        Self::cube_strides(origin, |_| width)
    }

    /// Index of `node`, which must lie in the box this layout describes.
    #[inline]
    pub fn index(&self, node: [usize; D]) -> usize {
        let mut index = 0;
        for a in 0..D {
            index += (node[a] - self.origin[a]) * self.strides[a];
        }
        index
    }
}

/// What stencils need of a grid, computed once for a pass over many particles: the position
/// of node 0 ([`Grid::origin`]), `1/h` and `h` as scalars, and the node counts.
#[derive(Clone, Copy, Debug)]
pub struct Frame<T, const D: usize> {
    origin: [f64; D],
    inv_h: T,
    h: T,
    nodes: [usize; D],
}

impl<T: Scalar, const D: usize> Frame<T, D> {
    /// The frame of `grid`.
    #[inline]
    pub fn new(grid: &Grid<D>) -> Self {
        Self {
            origin: grid.origin(),
            inv_h: T::cst(1.0 / grid.h),
            h: T::cst(grid.h),
            nodes: grid.nodes(),
        }
    }
}

/// Weights `w_ip` and gradients `∇w_ip` of one particle on its `b^D` nodes.
#[derive(Clone, Copy, Debug)]
pub struct Stencil<T, const D: usize> {
    /// Support width `b` per axis.
    pub b: usize,
    /// Multi-index of the first node.
    pub base: [isize; D],
    /// Per-axis 1D weights.
    pub axes: [Weights1D<T>; D],
    /// Per-axis offsets `x_{base+k} − x_p` (physical units).
    offsets: [[T; MAX_SUPPORT]; D],
    /// Node counts of the grid per axis (for flat indices).
    nodes: [usize; D],
}

/// The grid coordinate `ξ = (x − x_0)/h` of a particle along one axis (in units of cells
/// from node 0), computed the same way for [`Stencil::new`] and [`Stencil::first_node`].
#[inline(always)]
fn grid_coordinate<T: Scalar>(x: T, origin: f64, inv_h: T) -> T {
    (x - T::cst(origin)) * inv_h
}

impl<T: Scalar, const D: usize> Stencil<T, D> {
    /// Stencil of a particle at `x`; `half_width` is the particle half-length per axis in
    /// physical units (used by GIMP only).
    #[inline(always)]
    pub fn new(shape: Shape, grid: &Grid<D>, x: &Vector<T, D>, half_width: &Vector<T, D>) -> Self {
        let zero = Weights1D {
            base: 0,
            w: [T::zero(); MAX_SUPPORT],
            dw: [T::zero(); MAX_SUPPORT],
        };
        let mut st = Self {
            b: 0,
            base: [0; D],
            axes: [zero; D],
            offsets: [[T::zero(); MAX_SUPPORT]; D],
            nodes: [0; D],
        };
        st.set(shape, grid, x, half_width);
        st
    }

    /// Makes this the stencil of a particle at `x` (the same as [`Stencil::new`], in place: a
    /// solver that keeps one stencil per particle refills it without building and copying a
    /// new value).
    #[inline(always)]
    pub fn set(
        &mut self,
        shape: Shape,
        grid: &Grid<D>,
        x: &Vector<T, D>,
        half_width: &Vector<T, D>,
    ) {
        self.set_in(shape, &Frame::new(grid), x, half_width);
    }

    /// [`Stencil::set`] with the grid's [`Frame`] computed once for many particles.
    #[inline(always)]
    pub fn set_in(
        &mut self,
        shape: Shape,
        frame: &Frame<T, D>,
        x: &Vector<T, D>,
        half_width: &Vector<T, D>,
    ) {
        // One branch on the shape per particle, then a fill specialised for it: with the
        // shape (and so the width) a constant, the weights inline without their own dispatch
        // and the loops have constant length (this runs for every particle in every step).
        let (f, x, hw) = (frame, x, half_width);
        match shape {
            Shape::Linear => {
                self.fill::<2>(f, x, hw, |xi, l| Shape::Linear.weights_1d(xi, l, f.inv_h))
            }
            Shape::Ugimp => {
                self.fill::<3>(f, x, hw, |xi, l| Shape::Ugimp.weights_1d(xi, l, f.inv_h))
            }
            Shape::Cpgimp => {
                self.fill::<3>(f, x, hw, |xi, l| Shape::Cpgimp.weights_1d(xi, l, f.inv_h))
            }
            Shape::QuadraticBspline => self.fill::<3>(f, x, hw, |xi, l| {
                Shape::QuadraticBspline.weights_1d(xi, l, f.inv_h)
            }),
            Shape::CubicBspline => self.fill::<4>(f, x, hw, |xi, l| {
                Shape::CubicBspline.weights_1d(xi, l, f.inv_h)
            }),
        }
    }

    /// [`Stencil::set_in`] for a shape of support width `B` whose 1D weights at the grid
    /// coordinate `ξ` and half-width `l` (in cells) are `weights(ξ, l)`.
    #[inline(always)]
    fn fill<const B: usize>(
        &mut self,
        frame: &Frame<T, D>,
        x: &Vector<T, D>,
        half_width: &Vector<T, D>,
        weights: impl Fn(T, T) -> Weights1D<T>,
    ) {
        let (o, inv_h, h) = (&frame.origin, frame.inv_h, frame.h);
        self.b = B;
        self.nodes = frame.nodes;
        // Field by field, with plain loops (the closures of `array::from_fn` are not always
        // inlined).
        for a in 0..D {
            let xi = grid_coordinate(x[a], o[a], inv_h);
            self.axes[a] = weights(xi, half_width[a] * inv_h);
            let base = self.axes[a].base;
            self.base[a] = base;
            for k in 0..B {
                self.offsets[a][k] = (T::cst((base + k as isize) as f64) - xi) * h;
            }
        }
    }

    /// The first node ([`Stencil::base`]) of the stencil of a particle at `x`, without the
    /// weights: the same value `Stencil::new(shape, grid, x, _).base` has.
    #[inline]
    pub fn first_node(shape: Shape, grid: &Grid<D>, x: &Vector<T, D>) -> [isize; D] {
        Self::first_node_in(shape, &Frame::new(grid), x)
    }

    /// [`Stencil::first_node`] with the grid's [`Frame`] computed once for many particles.
    #[inline(always)]
    pub fn first_node_in(shape: Shape, frame: &Frame<T, D>, x: &Vector<T, D>) -> [isize; D] {
        let mut base = [0; D];
        for a in 0..D {
            base[a] = shape.first_node(grid_coordinate(x[a], frame.origin[a], frame.inv_h));
        }
        base
    }

    /// Number of nodes, `b^D`.
    #[inline]
    pub fn len(&self) -> usize {
        self.b.pow(D as u32)
    }

    /// Always `false`: a stencil has at least 2^D nodes (present for API completeness).
    #[inline]
    pub fn is_empty(&self) -> bool {
        false
    }

    /// `true` when every node of the stencil exists on `grid`.
    #[inline]
    pub fn on_grid(&self, grid: &Grid<D>) -> bool {
        grid.contains_stencil(self.base, self.b)
    }

    /// Calls `f` for every node of the stencil (axis 0 fastest) with its index, weight
    /// `w = Π_a N_a`, gradient `∂w/∂x_a = N'_a Π_{c≠a} N_c` and offset `x_i − x_p`.
    /// The stencil must be [on the grid](Stencil::on_grid).
    #[inline]
    pub fn for_each(&self, mut f: impl FnMut(StencilNode<T, D>)) {
        let layout = Layout::grid_of_nodes(self.nodes);
        self.for_each_in(&layout, |flat, local, weight, gradient, offset| {
            f(StencilNode {
                index: std::array::from_fn(|a| self.base[a] as usize + local[a]),
                flat,
                weight,
                gradient,
                offset,
            })
        });
    }

    /// Calls `f(index, local, w, ∇w, x_i − x_p)` for every node of the stencil (axis 0
    /// fastest), with `index` the node's entry in an array of the given [`Layout`] (the flat
    /// grid, or a block-local buffer) and `local` its offset from [`Stencil::base`]. The whole
    /// stencil must lie in the layout's box.
    #[inline(always)]
    pub fn for_each_in(
        &self,
        layout: &Layout<D>,
        mut f: impl FnMut(usize, [usize; D], T, Vector<T, D>, Vector<T, D>),
    ) {
        let [w0, dw0, o0] = self.axis0();
        self.for_each_row(
            layout,
            #[inline(always)]
            |row| {
                for i in 0..self.width() {
                    let mut gradient = row.gradient * w0[i];
                    gradient[0] = dw0[i] * row.weight;
                    let mut offset = row.offset;
                    offset[0] = o0[i];
                    let mut local = row.local;
                    local[0] = i;
                    f(row.index + i, local, w0[i] * row.weight, gradient, offset);
                }
            },
        );
    }

    /// Support width `b` (at most [`MAX_SUPPORT`]).
    #[inline(always)]
    pub fn width(&self) -> usize {
        self.b.min(MAX_SUPPORT)
    }

    /// The 1D factors along axis 0, `[N_0(i), N'_0(i), x_i − x_p]` for the nodes
    /// `i < b` of a row (entries from `b` on are unused).
    #[inline(always)]
    pub fn axis0(&self) -> [&[T; MAX_SUPPORT]; 3] {
        [&self.axes[0].w, &self.axes[0].dw, &self.offsets[0]]
    }

    /// Calls `f` for every row of the stencil: the `b` nodes `base + (i, j, k)`, `i < b`, at
    /// fixed `(j, k)`, in the order of [`Stencil::for_each`]. A row carries the factors of the
    /// axes above 0, so a kernel forms per node only what depends on axis 0 (see
    /// [`StencilRow`] for how the node's weight, gradient and offset follow).
    #[inline(always)]
    pub fn for_each_row(&self, layout: &Layout<D>, mut f: impl FnMut(StencilRow<T, D>)) {
        assert!((1..=3).contains(&D), "stencils exist for D = 1, 2, 3");
        let first = self.first_index(layout);
        let ax = &self.axes;
        let b = self.width();
        let nj = if D > 1 { b } else { 1 };
        let nk = if D > 2 { b } else { 1 };
        for k in 0..nk {
            for j in 0..nj {
                let mut row = StencilRow {
                    index: first,
                    local: [0; D],
                    weight: T::one(),
                    gradient: Vector::zeros(),
                    offset: Vector::zeros(),
                };
                // w_yz = Π_{a ≥ 1} N_a, and its derivatives along y and z.
                if D == 2 {
                    row.weight = ax[1].w[j];
                    row.gradient[1] = ax[1].dw[j];
                } else if D == 3 {
                    row.weight = ax[1].w[j] * ax[2].w[k];
                    row.gradient[1] = ax[1].dw[j] * ax[2].w[k];
                    row.gradient[2] = ax[1].w[j] * ax[2].dw[k];
                }
                let local = [0, j, k];
                for a in 1..D {
                    row.index += local[a] * layout.strides[a];
                    row.local[a] = local[a];
                    row.offset[a] = self.offsets[a][local[a]];
                }
                f(row);
            }
        }
    }

    /// Index of the stencil's first node in `layout`.
    #[inline(always)]
    fn first_index(&self, layout: &Layout<D>) -> usize {
        let mut first = 0;
        for a in 0..D {
            first += (self.base[a] as usize - layout.origin[a]) * layout.strides[a];
        }
        first
    }
}

/// One row of a stencil (see [`Stencil::for_each_row`]): the nodes `base + (i, j, k)`,
/// `i < b`. With the axis-0 factors `[N, N', o] = `[`Stencil::axis0`]`()[..][i]`, node `i` has
/// index `index + i`, weight `N·weight`, gradient `gradient·N` with component 0
/// replaced by `N'·weight`, and offset `offset` with component 0 replaced by `o`.
#[derive(Clone, Copy, Debug)]
pub struct StencilRow<T: Scalar, const D: usize> {
    /// Index of the row's first node (`i = 0`) in the layout.
    pub index: usize,
    /// Offset of the row's first node from [`Stencil::base`] (component 0 is 0).
    pub local: [usize; D],
    /// `Π_{a ≥ 1} N_a`.
    pub weight: T,
    /// `∂/∂x_a Π_{c ≥ 1} N_c` for `a ≥ 1`; component 0 is zero.
    pub gradient: Vector<T, D>,
    /// `x_i − x_p` along the axes `a ≥ 1`; component 0 is zero.
    pub offset: Vector<T, D>,
}

/// Particle half-length per axis for the GIMP family: uGIMP keeps the reference size, cpGIMP
/// stretches it by the length of the deformed material axis, `l_a = l⁰_a ‖F e_a‖ =
/// l⁰_a √(Σ_b F_ba²)` (Charlton et al. 2017), clamped to `(0, h/2]` so the support stays `b = 3`.
///
/// The column norm is `√C_aa`, the stretch of the fibre along axis `a`: a rigid rotation leaves
/// the domain unchanged, where the diagonal `F_aa` would shrink it by `cos θ` (and invert it
/// past 90°).
#[inline]
pub fn particle_half_width<T: Scalar, const D: usize>(
    shape: Shape,
    h: f64,
    hw0: &Vector<T, D>,
    f: &Tensor<T, D>,
) -> Vector<T, D> {
    match shape {
        Shape::Cpgimp => Vector::<T, D>::from_fn(|a, _| {
            let mut c2 = T::zero();
            for b in 0..D {
                c2 += f[(b, a)] * f[(b, a)];
            }
            let l = hw0[a] * c2.sqrt();
            if l.re() > 0.5 * h {
                T::cst(0.5 * h)
            } else if l.re() < 1e-6 * h {
                T::cst(1e-6 * h)
            } else {
                l
            }
        }),
        _ => *hw0,
    }
}

/// Upper bound on the stencil size of any shape in 3D (`4³`).
pub const MAX_STENCIL: usize = MAX_SUPPORT * MAX_SUPPORT * MAX_SUPPORT;

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::SMatrix;

    fn check_completeness<const D: usize>(shape: Shape, x: Vector<f64, D>) {
        let grid = Grid::<D>::new([0.0; D], [8; D], 0.5, 2);
        // GIMP half-length: 2×2 particles per cell → l_p = h/4.
        let hw = Vector::<f64, D>::repeat(0.125);
        let s = Stencil::new(shape, &grid, &x, &hw);
        assert!(s.on_grid(&grid));
        let (mut sw, mut sg) = (0.0, Vector::<f64, D>::zeros());
        let mut sx = Vector::<f64, D>::zeros();
        let mut sxg = SMatrix::<f64, D, D>::zeros();
        s.for_each(|n| {
            let (w, g) = (n.weight, n.gradient);
            let xi: Vector<f64, D> = grid.node_position(n.index);
            assert_eq!(n.flat, grid.flat(n.index));
            assert!((n.offset - (xi - x)).norm() < 1e-14);
            sw += w;
            sg += g;
            sx += xi * w;
            sxg += xi * g.transpose();
        });
        // Round-off only: sums of ≤ 64 terms of size ≤ 1 (times x ≤ 4) in f64.
        let tol = 1e-13;
        assert!((sw - 1.0).abs() < tol, "{shape:?} D={D}: Σw = {sw}");
        assert!(sg.norm() < tol * 10.0, "{shape:?} D={D}: Σ∇w = {sg}");
        assert!(
            (sx - x).norm() < tol * 10.0,
            "{shape:?} D={D}: Σ x_i w = {sx} vs {x}"
        );
        assert!(
            (sxg - SMatrix::<f64, D, D>::identity()).norm() < tol * 10.0,
            "{shape:?} D={D}: Σ x_i ⊗ ∇w = {sxg}"
        );
    }

    #[test]
    fn partition_of_unity_and_linear_completeness_2d_3d() {
        let pts2 = [[1.13, 2.71], [2.5, 2.5], [1.999, 3.001], [0.77, 0.31]];
        let pts3 = [[1.13, 2.71, 0.58], [2.5, 2.25, 2.0], [3.9, 0.26, 1.49]];
        for shape in Shape::ALL {
            for p in pts2 {
                check_completeness::<2>(shape, Vector::<f64, 2>::from(p));
            }
            for p in pts3 {
                check_completeness::<3>(shape, Vector::<f64, 3>::from(p));
            }
        }
    }

    #[test]
    fn stencil_gradients_match_finite_differences() {
        // Central differences with ε = 1e-6 h; truncation O(ε²) plus round-off ~1e-10.
        let grid = Grid::<3>::new([0.0; 3], [8; 3], 0.5, 2);
        let hw = Vector::<f64, 3>::repeat(0.125);
        let x = Vector::<f64, 3>::new(1.13, 2.21, 0.58);
        let eps = 5e-7;
        for shape in Shape::ALL {
            let s = Stencil::new(shape, &grid, &x, &hw);
            let nodes = |st: &Stencil<f64, 3>| {
                let mut v = Vec::new();
                st.for_each(|n| v.push((n.weight, n.gradient)));
                v
            };
            for (k, &(_, g)) in nodes(&s).iter().enumerate() {
                for a in 0..3 {
                    let mut xp = x;
                    xp[a] += eps;
                    let mut xm = x;
                    xm[a] -= eps;
                    let (sp, sm) = (
                        Stencil::new(shape, &grid, &xp, &hw),
                        Stencil::new(shape, &grid, &xm, &hw),
                    );
                    assert_eq!(sp.base, sm.base);
                    let fd = (nodes(&sp)[k].0 - nodes(&sm)[k].0) / (2.0 * eps);
                    assert!(
                        (fd - g[a]).abs() < 1e-7,
                        "{shape:?} k={k} a={a}: {fd} vs {}",
                        g[a]
                    );
                }
            }
        }
    }
}
