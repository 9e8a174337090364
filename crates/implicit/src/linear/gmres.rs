//! Restarted, right-preconditioned GMRES (Saad & Schultz 1986; Saad, *Iterative Methods for
//! Sparse Linear Systems*, 2nd ed. 2003, algorithms 6.9 and 9.5), written here because faer
//! 0.24 ships conjugate gradient, BiCGSTAB and LSMR but no GMRES.
//!
//! GMRES suits the non-symmetric block preconditioner of the coupled systems
//! ([`super::block`]): it minimises the residual over the Krylov space, so its residual never
//! grows, and with a preconditioned operator whose eigenvalues cluster around one (the
//! block-triangular ones) the count is governed by the cluster, where BiCGSTAB's irregular
//! convergence can stall.
//!
//! # The method
//!
//! From `x₀` (zero on the first cycle), with `r₀ = b − A x₀`, `β = ‖r₀‖` and `v₁ = r₀/β`,
//! the Arnoldi process on `A M⁻¹` builds the orthonormal basis `V_{k+1} = [v₁ … v_{k+1}]` of
//! the Krylov space and the Hessenberg matrix `H̄_k` with `A M⁻¹ V_k = V_{k+1} H̄_k`
//! (modified Gram–Schmidt). The iterate `x_k = x₀ + M⁻¹ V_k y_k` minimises
//! `‖b − A x_k‖ = ‖β e₁ − H̄_k y‖`; Givens rotations reduce `H̄_k` to triangular form column by
//! column, and the last entry of the rotated `β e₁` is the residual norm, so the stopping test
//! costs nothing. After [`RESTART`] steps (or on convergence) `y_k` is solved from the
//! triangle, `x` updated with one more application of `M⁻¹` (to `V_k y_k`, so that the
//! preconditioned vectors need not be stored) and the true residual recomputed: the solve
//! stops when it is below `rel_tol ‖b‖` and restarts from `x` otherwise.
//!
//! Right preconditioning makes the minimised residual the true one, `b − A x`, so the
//! stopping rule is the same as the other solvers'.

use super::krylov::KrylovParams;
use super::{LinearError, residual_norm};

/// Krylov steps per restart cycle: the basis takes `(RESTART + 1) n` numbers, 51 vectors
/// (64 MB at 157,000 unknowns). The block-preconditioned coupled systems of drained steps
/// converge within one cycle (15–35 iterations); undrained steps take two or three.
pub const RESTART: usize = 50;

/// Solves `A x = b` with GMRES(`RESTART`) right-preconditioned by `precondition`
/// (`z ← M⁻¹ z`), `A` given by its product `apply(v, out)`: `out = A v` (for a transposed
/// system, the transposed matrix's product and preconditioner). Returns the iteration count
/// (the number of products with `A M⁻¹`).
pub(super) fn solve(
    apply: impl Fn(&[f64], &mut [f64]),
    precondition: impl Fn(&mut [f64]) -> Result<(), LinearError>,
    b: &[f64],
    x: &mut [f64],
    params: KrylovParams,
) -> Result<usize, LinearError> {
    let n = b.len();
    let target = params.rel_tol * norm(b);
    x.fill(0.0);
    let mut iterations = 0;
    let mut r = b.to_vec();
    let mut w = vec![0.0; n];
    loop {
        let beta = norm(&r);
        if beta <= target || beta == 0.0 {
            return Ok(iterations);
        }
        if iterations >= params.max_iter {
            return Err(LinearError::NotConverged {
                method: params.method,
                iterations: params.max_iter,
                relative_residual: residual_norm(&apply, b, x) / norm(b),
                target: params.rel_tol,
            });
        }
        // Arnoldi on A M⁻¹ from v₁ = r/β, with the Givens rotations (c_i, s_i) applied to each
        // new column of H̄ and to g = β e₁ as they come.
        let mut basis: Vec<Vec<f64>> = vec![r.iter().map(|r| r / beta).collect()];
        let mut h: Vec<Vec<f64>> = Vec::new();
        let mut rotations: Vec<(f64, f64)> = Vec::new();
        let mut g = vec![beta];
        while h.len() < RESTART && iterations < params.max_iter {
            let mut z = basis[h.len()].clone();
            precondition(&mut z)?;
            apply(&z, &mut w);
            iterations += 1;
            let mut column: Vec<f64> = Vec::with_capacity(basis.len() + 1);
            for v in &basis {
                let hij = dot(&w, v);
                w.iter_mut().zip(v).for_each(|(w, v)| *w -= hij * v);
                column.push(hij);
            }
            let next = norm(&w);
            column.push(next);
            for (i, &(c, s)) in rotations.iter().enumerate() {
                let (p, q) = (column[i], column[i + 1]);
                column[i] = c * p + s * q;
                column[i + 1] = -s * p + c * q;
            }
            let k = column.len() - 2;
            let (p, q) = (column[k], column[k + 1]);
            let rho = p.hypot(q);
            let (c, s) = if rho == 0.0 {
                (1.0, 0.0)
            } else {
                (p / rho, q / rho)
            };
            column[k] = rho;
            column.pop();
            rotations.push((c, s));
            g.push(-s * g[k]);
            g[k] *= c;
            h.push(column);
            // A zero `next` is a lucky breakdown: the space holds the solution.
            if g[k + 1].abs() <= target || next == 0.0 {
                break;
            }
            basis.push(w.iter().map(|w| w / next).collect());
        }
        // y from the triangle R y = g (R's column j is h[j]), then x ← x + M⁻¹ V y.
        let k = h.len();
        let mut y = g[..k].to_vec();
        for j in (0..k).rev() {
            y[j] /= h[j][j];
            for i in 0..j {
                y[i] -= h[j][i] * y[j];
            }
        }
        let mut update = vec![0.0; n];
        for (v, yj) in basis.iter().zip(&y) {
            update.iter_mut().zip(v).for_each(|(u, v)| *u += yj * v);
        }
        precondition(&mut update)?;
        x.iter_mut().zip(&update).for_each(|(x, u)| *x += u);
        apply(x, &mut w);
        r.iter_mut()
            .zip(b.iter().zip(&w))
            .for_each(|(r, (b, ax))| *r = b - ax);
    }
}

fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(x, y)| x * y).sum()
}

fn norm(v: &[f64]) -> f64 {
    dot(v, v).sqrt()
}
