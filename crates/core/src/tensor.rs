//! Small fixed-size tensor helpers generic over the dimension `D` (2 = plane strain, 3).
//!
//! nalgebra's determinant and inverse need dimension-arithmetic trait bounds that would leak
//! into every kernel signature; these closed forms for `D ∈ {2, 3}` keep kernels bound only by
//! `T: Scalar`.

use crate::scalar::Scalar;
use nalgebra::{Matrix3, SMatrix, SVector};

/// A `D`-vector of scalars.
pub type Vector<T, const D: usize> = SVector<T, D>;
/// A `D × D` matrix of scalars.
pub type Tensor<T, const D: usize> = SMatrix<T, D, D>;

/// Determinant of a 2×2 or 3×3 matrix (cofactor expansion).
#[inline]
pub fn det<T: Scalar, const D: usize>(m: &Tensor<T, D>) -> T {
    match D {
        2 => m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)],
        3 => {
            m[(0, 0)] * (m[(1, 1)] * m[(2, 2)] - m[(1, 2)] * m[(2, 1)])
                - m[(0, 1)] * (m[(1, 0)] * m[(2, 2)] - m[(1, 2)] * m[(2, 0)])
                + m[(0, 2)] * (m[(1, 0)] * m[(2, 1)] - m[(1, 1)] * m[(2, 0)])
        }
        _ => panic!("loam supports D = 2 and D = 3 only"),
    }
}

/// The cofactor matrix, `cof(A)_ij = (−1)^(i+j) M_ij` (`M_ij` the minor of entry `(i, j)`),
/// so that `cof(A) = det(A) A⁻ᵀ` where `A` is invertible; it is also `∂ det A / ∂A`, and is
/// defined (and smooth) for singular `A` too.
#[inline]
pub fn cofactor<T: Scalar, const D: usize>(m: &Tensor<T, D>) -> Tensor<T, D> {
    Tensor::from_fn(|i, j| match D {
        2 => {
            let minor = m[(1 - i, 1 - j)];
            if i == j { minor } else { -minor }
        }
        3 => {
            let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
            let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
            m[(r0, c0)] * m[(r1, c1)] - m[(r0, c1)] * m[(r1, c0)]
        }
        _ => panic!("loam supports D = 2 and D = 3 only"),
    })
}

/// Inverse of a 2×2 or 3×3 matrix by the adjugate, `A⁻¹ = adj(A) / det(A)`.
/// Returns `None` when the real part of the determinant is zero.
#[inline]
pub fn inverse<T: Scalar, const D: usize>(m: &Tensor<T, D>) -> Option<Tensor<T, D>> {
    let d = det(m);
    if d.re() == 0.0 {
        return None;
    }
    Some(cofactor(m).transpose() / d)
}

/// Embeds a `D × D` tensor in 3×3: the plane-strain deformation gradient has `F_zz = 1`,
/// so `fill` is the (2, 2) entry used when `D = 2` (1 for F, 0 for a velocity gradient).
#[inline]
pub fn to3<T: Scalar, const D: usize>(m: &Tensor<T, D>, fill: T) -> Matrix3<T> {
    let mut out = Matrix3::<T>::zeros();
    for i in 0..D {
        for j in 0..D {
            out[(i, j)] = m[(i, j)];
        }
    }
    if D == 2 {
        out[(2, 2)] = fill;
    }
    out
}

/// The leading `D × D` block of a 3×3 tensor (the in-plane part in plane strain).
#[inline]
pub fn from3<T: Scalar, const D: usize>(m: &Matrix3<T>) -> Tensor<T, D> {
    Tensor::<T, D>::from_fn(|i, j| m[(i, j)])
}

/// The product `a b`, `(a b)_ij = Σ_k a_ik b_kj`, summed in a plain loop in the order of `k`.
///
/// nalgebra's generic product computes `α a b + β c` and also multiplies by its `α = 1`,
/// which for a many-lane dual is one more full product per term; the sums are the same.
#[inline]
pub fn product<T: Scalar, const R: usize, const K: usize, const C: usize>(
    a: &SMatrix<T, R, K>,
    b: &SMatrix<T, K, C>,
) -> SMatrix<T, R, C> {
    SMatrix::from_fn(|i, j| {
        let mut sum = a[(i, 0)] * b[(0, j)];
        for k in 1..K {
            sum += a[(i, k)] * b[(k, j)];
        }
        sum
    })
}

/// Converts a tensor of one scalar type to another through the real parts (drops derivatives).
#[inline]
pub fn real<T: Scalar, const R: usize, const C: usize>(m: &SMatrix<T, R, C>) -> SMatrix<f64, R, C> {
    m.map(|x| x.re())
}

/// Lifts a real tensor into scalar type `T` (zero derivative part).
#[inline]
pub fn lift<T: Scalar, const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> SMatrix<T, R, C> {
    m.map(T::cst)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, matrix};

    /// cof A = det(A) A⁻ᵀ for invertible A (to round-off, 1e-14 on entries of order 1), and
    /// cof A = ∂ det A / ∂A entry by entry (det is linear in each entry, so a central
    /// difference is exact up to round-off: 1e-12 with step 1e-3); a singular A of rank
    /// D − 1 keeps a non-zero cofactor.
    #[test]
    fn cofactor_is_the_derivative_of_the_determinant() {
        let a = matrix![2.0, 0.3, -0.1; 0.2, 1.5, 0.4; 0.0, -0.7, 3.0];
        let c = cofactor::<f64, 3>(&a);
        let ai = inverse::<f64, 3>(&a).unwrap();
        assert!((c - ai.transpose() * det::<f64, 3>(&a)).norm() < 1e-14);
        let h = 1e-3;
        for i in 0..3 {
            for j in 0..3 {
                let (mut up, mut down) = (a, a);
                up[(i, j)] += h;
                down[(i, j)] -= h;
                let fd = (det::<f64, 3>(&up) - det::<f64, 3>(&down)) / (2.0 * h);
                assert!((fd - c[(i, j)]).abs() < 1e-12, "({i}, {j})");
            }
        }
        let b = Matrix2::new(1.0, 2.0, 3.0, 4.5);
        let cb = cofactor::<f64, 2>(&b);
        assert_eq!(cb, Matrix2::new(4.5, -3.0, -2.0, 1.0));
        let singular = matrix![1.0, 2.0, 3.0; 2.0, 4.0, 6.0; 0.0, 1.0, 1.0];
        assert_eq!(det::<f64, 3>(&singular), 0.0);
        assert!(cofactor::<f64, 3>(&singular).norm() > 1.0);
    }

    #[test]
    fn inverse_times_matrix_is_identity() {
        let a = matrix![2.0, 0.3, -0.1; 0.2, 1.5, 0.4; 0.0, -0.7, 3.0];
        let ai = inverse::<f64, 3>(&a).unwrap();
        assert!((a * ai - Matrix3::identity()).norm() < 1e-14);
        assert!((det::<f64, 3>(&a) - a.determinant()).abs() < 1e-13);
        let b = Matrix2::new(1.0, 2.0, 3.0, 4.5);
        let bi = inverse::<f64, 2>(&b).unwrap();
        assert!((b * bi - Matrix2::identity()).norm() < 1e-14);
        assert!(inverse::<f64, 2>(&Matrix2::new(1.0, 2.0, 2.0, 4.0)).is_none());
    }

    #[test]
    fn plane_strain_embedding_keeps_fzz() {
        let f = Matrix2::new(1.1, 0.2, 0.0, 0.9);
        let f3 = to3::<f64, 2>(&f, 1.0);
        assert_eq!(f3[(2, 2)], 1.0);
        assert_eq!(from3::<f64, 2>(&f3), f);
    }
}
