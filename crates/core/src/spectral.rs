//! Dual-safe isotropic functions of symmetric matrices, `f(A) = Σ_k f(λ_k) n_k n_kᵀ`.
//!
//! The eigen-decomposition `A₀ = Q Λ Qᵀ` is taken on the real part `A₀` only (cyclic Jacobi in
//! `f64`, exact to round-off at repeated eigenvalues). The first-order perturbation
//! `Ȧ = A − A₀` (the dual part) is carried by the Daleckii–Krein formula
//!
//! `ḟ = Q (Φ ∘ (Qᵀ Ȧ Q)) Qᵀ`, `Φ_ij = (f(λ_i) − f(λ_j)) / (λ_i − λ_j)` (`= f'(λ_i)` when
//! `λ_i = λ_j`),
//!
//! evaluated in `T` arithmetic with real `Q`, `Φ`. The divided difference is evaluated without
//! cancellation for close eigenvalues, so derivatives stay finite and exact at `A = I` and at
//! any repeated eigenvalue — where differentiating an eigen-solver (eigenvector derivatives
//! `∝ 1/(λ_i − λ_j)`) gives NaN. For `f32`/`f64` `Ȧ = 0` and only the real path runs. The
//! formula is exact for first-order dual numbers (products of perturbations vanish).

use crate::scalar::Scalar;
use nalgebra::SMatrix;

/// A scalar function applied to the eigenvalues of a symmetric matrix.
pub trait SpectralFn {
    /// `f(λ)`.
    fn value(&self, x: f64) -> f64;
    /// The divided difference `f[x, y] = (f(x) − f(y))/(x − y)`, `= f'(x)` at `x = y`,
    /// accurate when `x ≈ y`.
    fn divided_difference(&self, x: f64, y: f64) -> f64;
}

/// The natural logarithm (Hencky strain `ε = ½ ln(F Fᵀ)`); eigenvalues must be positive.
#[derive(Clone, Copy, Debug)]
pub struct Log;

impl SpectralFn for Log {
    fn value(&self, x: f64) -> f64 {
        x.ln()
    }
    fn divided_difference(&self, x: f64, y: f64) -> f64 {
        // (ln x − ln y)/(x − y) = ln1p(t)/(t·y) with t = (x − y)/y; series for small t.
        let t = (x - y) / y;
        if t.abs() < 1e-4 {
            (1.0 - t / 2.0 + t * t / 3.0 - t * t * t / 4.0) / y
        } else {
            t.ln_1p() / (t * y)
        }
    }
}

/// The exponential (inverse of [`Log`], e.g. `b = exp(2ε)`).
#[derive(Clone, Copy, Debug)]
pub struct Exp;

impl SpectralFn for Exp {
    fn value(&self, x: f64) -> f64 {
        x.exp()
    }
    fn divided_difference(&self, x: f64, y: f64) -> f64 {
        // (eˣ − eʸ)/(x − y) = eʸ·expm1(d)/d, d = x − y.
        let d = x - y;
        if d.abs() < 1e-8 {
            y.exp() * (1.0 + d / 2.0)
        } else {
            y.exp() * d.exp_m1() / d
        }
    }
}

/// Eigenvalues `λ` and orthonormal eigenvectors (columns of `Q`) of a real symmetric matrix,
/// `A = Q diag(λ) Qᵀ`, by cyclic Jacobi rotations.
///
/// Written here rather than using nalgebra's `SymmetricEigen` because the latter needs
/// dimension-arithmetic bounds (`DimSub<U1>`) that would spread to every generic kernel; for
/// 2×2 and 3×3 Jacobi converges quadratically and is accurate to round-off.
pub fn symmetric_eigen<const D: usize>(a: &SMatrix<f64, D, D>) -> ([f64; D], SMatrix<f64, D, D>) {
    let mut m = (a + a.transpose()) * 0.5;
    let mut q = SMatrix::<f64, D, D>::identity();
    let scale = m.norm().max(f64::MIN_POSITIVE);
    for _sweep in 0..50 {
        let mut off = 0.0;
        for i in 0..D {
            for j in i + 1..D {
                off += m[(i, j)] * m[(i, j)];
            }
        }
        if off.sqrt() <= 1e-17 * scale {
            break;
        }
        for p in 0..D {
            for r in p + 1..D {
                let apr = m[(p, r)];
                if apr == 0.0 {
                    continue;
                }
                // Rotation angle that zeroes m[p, r]: tan 2θ = 2 a_pr / (a_rr − a_pp).
                let theta = (m[(r, r)] - m[(p, p)]) / (2.0 * apr);
                // (signum(0.0) = 1, so θ = 0 gives the 45° rotation.)
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let cs = 1.0 / (t * t + 1.0).sqrt();
                let sn = t * cs;
                for k in 0..D {
                    let (mkp, mkr) = (m[(k, p)], m[(k, r)]);
                    m[(k, p)] = cs * mkp - sn * mkr;
                    m[(k, r)] = sn * mkp + cs * mkr;
                }
                for k in 0..D {
                    let (mpk, mrk) = (m[(p, k)], m[(r, k)]);
                    m[(p, k)] = cs * mpk - sn * mrk;
                    m[(r, k)] = sn * mpk + cs * mrk;
                }
                for k in 0..D {
                    let (qkp, qkr) = (q[(k, p)], q[(k, r)]);
                    q[(k, p)] = cs * qkp - sn * qkr;
                    q[(k, r)] = sn * qkp + cs * qkr;
                }
            }
        }
    }
    (std::array::from_fn(|i| m[(i, i)]), q)
}

/// `f(A)` for a symmetric matrix `A` of any first-order scalar type, with exact, finite
/// first derivatives at distinct and repeated eigenvalues (see the module docs).
pub fn symmetric_fn<T: Scalar, const D: usize>(
    a: &SMatrix<T, D, D>,
    f: &impl SpectralFn,
) -> SMatrix<T, D, D> {
    let a0 = a.map(|x| x.re());
    let (lam, q) = symmetric_eigen(&a0);
    let fl: [f64; D] = std::array::from_fn(|i| f.value(lam[i]));
    let real =
        q * SMatrix::<f64, D, D>::from_fn(|i, j| if i == j { fl[i] } else { 0.0 }) * q.transpose();
    // Perturbation part: Ȧ = A − A₀ has zero real part (only derivative lanes).
    let qt = q.map(T::cst);
    let adot = a - a0.map(T::cst);
    let rotated = qt.transpose() * adot * qt;
    let phi = SMatrix::<f64, D, D>::from_fn(|i, j| f.divided_difference(lam[i], lam[j]));
    let hadamard = SMatrix::<T, D, D>::from_fn(|i, j| rotated[(i, j)] * T::cst(phi[(i, j)]));
    real.map(T::cst) + qt * hadamard * qt.transpose()
}

/// Isotropic functions of the principal values of a symmetric 3×3 matrix that need not act on
/// each eigenvalue alone: `g : ℝ³ → (ℝ³)ᴺ` with `g⁽ⁿ⁾(Pλ) = P g⁽ⁿ⁾(λ)` for every permutation
/// `P`. A return mapping in principal space is one (its outputs the principal stresses and
/// the new elastic stretches); [`isotropic_maps`] applies it.
pub trait PrincipalMaps<T: Scalar, const N: usize> {
    /// What the map reports besides its values (e.g. the branch a return mapping took, or
    /// invariants computed from the principal values).
    type Tag;
    /// The outputs `g⁽ⁿ⁾(λ)` in `T` arithmetic (branches on real parts), with the tag.
    fn principal(&self, lambda: [T; 3]) -> ([[T; 3]; N], Self::Tag);
    /// The Jacobians `∂g⁽ⁿ⁾_i/∂λ_j` at a real point, used where two eigenvalues coincide.
    fn jacobian(&self, lambda: [f64; 3]) -> [[[f64; 3]; 3]; N];
}

/// `G⁽ⁿ⁾(A) = Σ_k g⁽ⁿ⁾_k(λ) n_k n_kᵀ` for a symmetric 3×3 `A = Σ_k λ_k n_k n_kᵀ` of any
/// first-order scalar type and each output `n` of `g`, with exact, finite first derivatives
/// at distinct and repeated eigenvalues, from one eigen-decomposition for all outputs.
///
/// As in [`symmetric_fn`], the eigenvectors come from the real part `A₀` and the
/// perturbation `Ȧ = A − A₀` is carried in the eigenbasis, `Â = Qᵀ Ȧ Q`
/// (Miehe 1998; de Souza Neto, Perić & Owen 2008, Appendix A):
///
/// `Ġ = Q (diag(ġ) + Φ ∘ Â_off) Qᵀ`, `ġ_i = Σ_k ∂g_i/∂λ_k Â_kk`,
/// `Φ_ij = (g_i − g_j)/(λ_i − λ_j)`, and where `λ_i = λ_j` its limit
/// `½ (∂g_i/∂λ_i − ∂g_j/∂λ_i + ∂g_j/∂λ_j − ∂g_i/∂λ_j)` from [`PrincipalMaps::jacobian`].
///
/// `ġ` comes from evaluating `g` at `λ_k + Â_kk` in `T` itself, so derivatives with respect
/// to the map's own parameters (dual parameters inside `g`) are carried too, and so is the
/// exact first derivative of an invariant (a symmetric function of the principal values)
/// the tag carries.
pub fn isotropic_maps<T: Scalar, G: PrincipalMaps<T, N>, const N: usize>(
    a: &SMatrix<T, 3, 3>,
    g: &G,
) -> ([SMatrix<T, 3, 3>; N], G::Tag) {
    let a0 = a.map(|x| x.re());
    let (lam, q) = symmetric_eigen(&a0);
    let qt = q.map(T::cst);
    let adot = a - a0.map(T::cst);
    let rotated = qt.transpose() * adot * qt;
    let lam_t: [T; 3] = std::array::from_fn(|i| T::cst(lam[i]) + rotated[(i, i)]);
    let (values, tag) = g.principal(lam_t);
    let mut hats: [SMatrix<T, 3, 3>; N] = std::array::from_fn(|n| {
        SMatrix::<T, 3, 3>::from_fn(|i, j| if i == j { values[n][i] } else { T::zero() })
    });
    if !a.iter().all(|x| x.is_constant()) {
        let scale = lam.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(1e-300);
        let mut jac = None;
        for i in 0..3 {
            for j in 0..3 {
                if i == j {
                    continue;
                }
                let gap = lam[i] - lam[j];
                let close = gap.abs() <= 1e-6 * scale;
                let d = if close {
                    Some(jac.get_or_insert_with(|| g.jacobian(lam)))
                } else {
                    None
                };
                for n in 0..N {
                    let phi = match &d {
                        None => (values[n][i].re() - values[n][j].re()) / gap,
                        Some(d) => {
                            let d = &d[n];
                            0.5 * (d[i][i] - d[j][i] + d[j][j] - d[i][j])
                        }
                    };
                    hats[n][(i, j)] = rotated[(i, j)] * T::cst(phi);
                }
            }
        }
    }
    (hats.map(|h| qt * h * qt.transpose()), tag)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Matrix3, matrix};
    use num_dual::Dual64;

    #[test]
    fn jacobi_reconstructs_the_matrix() {
        let a = matrix![4.0, 1.0, -2.0; 1.0, 2.0, 0.5; -2.0, 0.5, 3.0];
        let (l, q) = symmetric_eigen(&a);
        let rec = q * Matrix3::from_diagonal(&l.into()) * q.transpose();
        assert!((rec - a).norm() < 1e-13);
        assert!((q.transpose() * q - Matrix3::identity()).norm() < 1e-14);
    }

    /// Directional derivative of log at `A` along `dA` by the dual path vs a central
    /// difference of the real path (ε = 1e-6: truncation ~1e-12, round-off ~1e-10).
    fn check_log_derivative(a: Matrix3<f64>, da: Matrix3<f64>) {
        let ad = Matrix3::from_fn(|i, j| Dual64::new(a[(i, j)], da[(i, j)]));
        let ld = symmetric_fn(&ad, &Log);
        let eps = 1e-6;
        let fd = (symmetric_fn(&(a + da * eps), &Log) - symmetric_fn(&(a - da * eps), &Log))
            / (2.0 * eps);
        for i in 0..3 {
            for j in 0..3 {
                assert!(ld[(i, j)].eps.is_finite());
                assert!(
                    (ld[(i, j)].eps - fd[(i, j)]).abs() < 1e-8,
                    "({i},{j}) dual {} vs fd {}",
                    ld[(i, j)].eps,
                    fd[(i, j)]
                );
            }
        }
    }

    #[test]
    fn log_derivative_is_exact_at_identity_and_repeated_eigenvalues() {
        let da = matrix![0.3, 0.1, -0.2; 0.1, -0.4, 0.25; -0.2, 0.25, 0.15];
        check_log_derivative(Matrix3::identity(), da);
        // λ = (2, 2, 0.5): a repeated pair in a rotated frame.
        let (_, q) = symmetric_eigen(&matrix![1.0, 0.4, 0.2; 0.4, 2.0, 0.3; 0.2, 0.3, 3.0]);
        let a = q * Matrix3::from_diagonal(&nalgebra::vector![2.0, 2.0, 0.5]) * q.transpose();
        check_log_derivative(a, da);
        // At the identity, d log(A)[Ȧ] = Ȧ exactly.
        let ad = Matrix3::from_fn(|i, j| Dual64::new(if i == j { 1.0 } else { 0.0 }, da[(i, j)]));
        let ld = symmetric_fn(&ad, &Log);
        assert!((ld.map(|x| x.eps) - da).norm() < 1e-15);
    }

    #[test]
    fn exp_inverts_log_in_2d() {
        let a = Matrix2::new(1.3, 0.2, 0.2, 0.8);
        let back = symmetric_fn(&symmetric_fn(&a, &Log), &Exp);
        assert!((back - a).norm() < 1e-14);
    }
}
