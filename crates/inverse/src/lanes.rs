//! Local vector–Jacobian products of the step's per-particle and per-node kernels, by
//! forward-mode duals.
//!
//! A local kernel `y = f(x)` (a few dozen inputs and outputs: one particle's end of step, one
//! node's update) is written once, generic over the scalar, in `loam-core`. Its adjoint
//! `x̄ = (∂f/∂x)ᵀ ȳ` is assembled lane by lane: seeding input `k` with a unit derivative gives
//! column `k` of the Jacobian in the outputs' derivative parts, and `x̄_k = ȳ · ∂f/∂x_k`. This
//! costs one evaluation of the kernel per seeded input, with `Dual64` (about twice an `f64`
//! evaluation), and is exact: the derivative of the branch the real parts take, which is the
//! branch the forward pass took (the same real arithmetic on the same inputs).
//!
//! Inputs and outputs travel as flat lists of at most [`MAX_LANES`] values; [`Packed`] writes
//! and [`Unpack`] reads the typed fields in a fixed order.

use loam_core::Scalar;
use loam_core::constitutive::{HISTORY_LEN, MaterialState};
use loam_core::tensor::{Tensor, Vector};
use nalgebra::Matrix3;
use num_dual::Dual64;

/// The most values a local kernel packs: the 3D particle end has 59 inputs.
pub const MAX_LANES: usize = 64;

/// A flat list of at most [`MAX_LANES`] values, written field by field.
#[derive(Clone, Copy, Debug)]
pub struct Packed<X: Copy> {
    values: [X; MAX_LANES],
    len: usize,
}

impl<X: Scalar> Default for Packed<X> {
    fn default() -> Self {
        Self {
            values: [X::zero(); MAX_LANES],
            len: 0,
        }
    }
}

impl<X: Copy> Packed<X> {
    /// The values written so far.
    #[inline]
    pub fn as_slice(&self) -> &[X] {
        &self.values[..self.len]
    }

    /// The values written so far, mutable.
    #[inline]
    pub fn as_mut_slice(&mut self) -> &mut [X] {
        &mut self.values[..self.len]
    }

    /// Number of values written.
    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether nothing was written.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Appends one value.
    ///
    /// # Panics
    /// Past [`MAX_LANES`] values (a fixed bound of the kernels packed here).
    #[inline]
    pub fn push(&mut self, x: X) {
        self.values[self.len] = x;
        self.len += 1;
    }

    /// Appends the components of a vector.
    #[inline]
    pub fn vector<const D: usize>(&mut self, v: &Vector<X, D>)
    where
        X: nalgebra::Scalar,
    {
        for a in 0..D {
            self.push(v[a]);
        }
    }

    /// Appends the entries of a `D × D` tensor, row by row.
    #[inline]
    pub fn tensor<const D: usize>(&mut self, t: &Tensor<X, D>)
    where
        X: nalgebra::Scalar,
    {
        for r in 0..D {
            for c in 0..D {
                self.push(t[(r, c)]);
            }
        }
    }

    /// Appends the entries of a 3×3 matrix, row by row.
    #[inline]
    pub fn matrix3(&mut self, t: &Matrix3<X>)
    where
        X: nalgebra::Scalar,
    {
        self.tensor::<3>(t);
    }

    /// Appends a history state's components ([`MaterialState::components`]).
    #[inline]
    pub fn history(&mut self, h: &MaterialState<X>)
    where
        X: nalgebra::Scalar,
    {
        for x in h.components() {
            self.push(x);
        }
    }
}

/// Reads typed fields back from a flat list, in the order [`Packed`] wrote them.
#[derive(Debug)]
pub struct Unpack<'a, X> {
    values: &'a [X],
    at: usize,
}

impl<'a, X: Copy + nalgebra::Scalar> Unpack<'a, X> {
    /// A reader from the start of `values`.
    #[inline]
    pub fn new(values: &'a [X]) -> Self {
        Self { values, at: 0 }
    }

    /// The next value.
    #[inline]
    pub fn scalar(&mut self) -> X {
        self.at += 1;
        self.values[self.at - 1]
    }

    /// The next `D` values as a vector.
    #[inline]
    pub fn vector<const D: usize>(&mut self) -> Vector<X, D> {
        Vector::from_fn(|_, _| self.scalar())
    }

    /// The next `D²` values as a tensor, row by row.
    #[inline]
    pub fn tensor<const D: usize>(&mut self) -> Tensor<X, D> {
        let mut t = Tensor::from_element(self.values[self.at]);
        for r in 0..D {
            for c in 0..D {
                t[(r, c)] = self.scalar();
            }
        }
        t
    }

    /// The next 9 values as a 3×3 matrix, row by row.
    #[inline]
    pub fn matrix3(&mut self) -> Matrix3<X> {
        self.tensor::<3>()
    }

    /// The next [`HISTORY_LEN`] values as a history state.
    #[inline]
    pub fn history(&mut self) -> MaterialState<X> {
        let start = self.at;
        self.at += HISTORY_LEN;
        MaterialState::from_components(|k| self.values[start + k])
    }
}

/// `x̄ += (∂f/∂x)ᵀ ȳ` for the inputs listed in `lanes` (the others have no adjoint here: inputs
/// the kernel does not read, or whose adjoint is zero), one `Dual64` evaluation of `f` per
/// lane. `f` reads its inputs from the slice and writes its outputs, in the order of `ȳ`.
#[inline]
pub fn vjp(
    x: &[f64],
    lanes: impl IntoIterator<Item = usize>,
    y_bar: &[f64],
    x_bar: &mut [f64],
    mut f: impl FnMut(&[Dual64], &mut Packed<Dual64>),
) {
    let mut input = Packed::<Dual64>::default();
    for &v in x {
        input.push(Dual64::from_re(v));
    }
    for k in lanes {
        input.values[k].eps = 1.0;
        let mut out = Packed::default();
        f(input.as_slice(), &mut out);
        x_bar[k] += dot_eps(out.as_slice(), y_bar);
        input.values[k].eps = 0.0;
    }
}

/// `ȳ · ẏ`: the derivative part of the outputs `y` (one evaluation with a seeded parameter)
/// against their adjoints: that parameter's share of the gradient.
#[inline]
pub fn dot_eps(y: &[Dual64], y_bar: &[f64]) -> f64 {
    debug_assert_eq!(y.len(), y_bar.len());
    y.iter().zip(y_bar).map(|(y, b)| y.eps * b).sum()
}

/// The inputs `x` as constants (zero derivative parts).
#[inline]
pub fn constants(x: &[f64]) -> Packed<Dual64> {
    let mut input = Packed::default();
    for &v in x {
        input.push(Dual64::from_re(v));
    }
    input
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::DualNum;

    #[test]
    fn vjp_is_the_transposed_jacobian() {
        // f(x, y) = (x y, sin x + y²): J = [[y, x], [cos x, 2y]], Jᵀ ȳ.
        let x = [0.3, -1.2];
        let y_bar = [0.7, 2.0];
        let mut x_bar = [0.0; 2];
        vjp(&x, 0..2, &y_bar, &mut x_bar, |i, out| {
            out.push(i[0] * i[1]);
            out.push(i[0].sin() + i[1] * i[1]);
        });
        let expect = [0.7 * x[1] + 2.0 * x[0].cos(), 0.7 * x[0] + 2.0 * 2.0 * x[1]];
        for k in 0..2 {
            assert!(
                (x_bar[k] - expect[k]).abs() < 1e-15,
                "{x_bar:?} vs {expect:?}"
            );
        }
    }

    #[test]
    fn packing_round_trips_typed_fields() {
        let mut p = Packed::<f64>::default();
        let v = Vector::<f64, 2>::new(1.0, 2.0);
        let t = Tensor::<f64, 2>::new(3.0, 4.0, 5.0, 6.0);
        let m = Matrix3::from_fn(|r, c| (10 * r + c) as f64);
        p.vector(&v);
        p.tensor(&t);
        p.matrix3(&m);
        p.push(7.0);
        assert_eq!(p.len(), 2 + 4 + 9 + 1);
        let mut u = Unpack::new(p.as_slice());
        assert_eq!(u.vector::<2>(), v);
        assert_eq!(u.tensor::<2>(), t);
        assert_eq!(u.matrix3(), m);
        assert_eq!(u.scalar(), 7.0);
    }
}
