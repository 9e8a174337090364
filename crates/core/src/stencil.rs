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

impl<T: Scalar, const D: usize> Stencil<T, D> {
    /// Stencil of a particle at `x`; `half_width` is the particle half-length per axis in
    /// physical units (used by GIMP only).
    #[inline]
    pub fn new(shape: Shape, grid: &Grid<D>, x: &Vector<T, D>, half_width: &Vector<T, D>) -> Self {
        let o = grid.origin();
        let inv_h = T::cst(1.0 / grid.h);
        let h = T::cst(grid.h);
        let b = shape.support_width();
        let mut offsets = [[T::zero(); MAX_SUPPORT]; D];
        let axes: [Weights1D<T>; D] = std::array::from_fn(|a| {
            let xi = (x[a] - T::cst(o[a])) * inv_h;
            let w = shape.weights_1d(xi, half_width[a] * inv_h, inv_h);
            for k in 0..b {
                offsets[a][k] = (T::cst((w.base + k as isize) as f64) - xi) * h;
            }
            w
        });
        Self {
            b,
            base: std::array::from_fn(|a| axes[a].base),
            axes,
            offsets,
            nodes: grid.nodes(),
        }
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
        let mut local = [0usize; D];
        let mut stride = [1usize; D];
        for a in 1..D {
            stride[a] = stride[a - 1] * self.nodes[a - 1];
        }
        let base_flat: usize = (0..D).map(|a| self.base[a] as usize * stride[a]).sum();
        for _ in 0..self.len() {
            let mut weight = T::one();
            let mut flat = base_flat;
            for a in 0..D {
                weight *= self.axes[a].w[local[a]];
                flat += local[a] * stride[a];
            }
            let gradient = Vector::<T, D>::from_fn(|a, _| {
                let mut p = self.axes[a].dw[local[a]];
                for c in 0..D {
                    if c != a {
                        p *= self.axes[c].w[local[c]];
                    }
                }
                p
            });
            f(StencilNode {
                index: std::array::from_fn(|a| (self.base[a] + local[a] as isize) as usize),
                flat,
                weight,
                gradient,
                offset: Vector::<T, D>::from_fn(|a, _| self.offsets[a][local[a]]),
            });
            // Odometer increment of the local multi-index.
            for a in 0..D {
                local[a] += 1;
                if local[a] < self.b {
                    break;
                }
                local[a] = 0;
            }
        }
    }
}

/// Particle half-length per axis for the GIMP family: uGIMP keeps the reference size, cpGIMP
/// stretches it by the diagonal of `F`, clamped to `(0, h/2]` so the support stays `b = 3`.
#[inline]
pub fn particle_half_width<T: Scalar, const D: usize>(
    shape: Shape,
    h: f64,
    hw0: &Vector<T, D>,
    f: &Tensor<T, D>,
) -> Vector<T, D> {
    match shape {
        Shape::Cpgimp => Vector::<T, D>::from_fn(|a, _| {
            let l = hw0[a] * f[(a, a)];
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
