//! Tests of the sparse linear algebra against dense nalgebra solves.
//!
//! Tolerances: for an iterative solve, the error of the solution obeys
//! `‖x − x*‖ / ‖x*‖ ≤ κ(A) ‖b − A x‖ / ‖b‖` exactly, so it is checked against `κ(A)` (from the
//! dense SVD) times the reported true residual, plus `1e-12` for the round-off of the dense
//! reference (`κ ε ≈ 1e-14` here). A direct solve is backward stable: its error is `O(κ ε)`,
//! checked at `1e-10` (κ ≤ ~10³ for the test matrices).

use std::sync::Arc;

use nalgebra::{DMatrix, DVector};

use super::precond::PrecondState;
use super::*;

/// Index of grid point `(i, j)` on a `k × k` grid.
fn idx(k: usize, i: usize, j: usize) -> usize {
    i + k * j
}

/// 5-point stencil on a `k × k` grid with Dirichlet boundaries: `c·u_P − Σ w_nb u_nb`, with the
/// neighbour weights `(west, east, south, north)` and the centre weight `centre`.
fn five_point(k: usize, centre: f64, [west, east, south, north]: [f64; 4]) -> SparseMatrix {
    let mut triplets = Vec::new();
    for j in 0..k {
        for i in 0..k {
            let row = idx(k, i, j);
            triplets.push((row, row, centre));
            let mut neighbour = |cond: bool, col: usize, w: f64| {
                if cond {
                    triplets.push((row, col, -w));
                }
            };
            neighbour(i > 0, idx(k, i.wrapping_sub(1), j), west);
            neighbour(i + 1 < k, idx(k, i + 1, j), east);
            neighbour(j > 0, idx(k, i, j.wrapping_sub(1)), south);
            neighbour(j + 1 < k, idx(k, i, j + 1), north);
        }
    }
    let entries = triplets.iter().map(|&(r, c, _)| (r, c));
    let mut a = SparseMatrix::zeros(Arc::new(SparsePattern::new(k * k, entries)));
    for (r, c, v) in triplets {
        a.add(r, c, v);
    }
    a
}

/// The SPD 2D Poisson matrix (5-point Laplacian, Dirichlet) on a `k × k` grid.
fn poisson(k: usize) -> SparseMatrix {
    five_point(k, 4.0, [1.0; 4])
}

/// Non-symmetric convection–diffusion `−Δu + h c·∇u` with first-order upwinding
/// (`c = (2, 1)`, cell Péclet numbers 2 and 1): an M-matrix, so ILU(0) exists.
fn convection_diffusion(k: usize) -> SparseMatrix {
    let (cx, cy) = (2.0, 1.0);
    five_point(k, 4.0 + cx + cy, [1.0 + cx, 1.0, 1.0 + cy, 1.0])
}

/// A deterministic right-hand side with all modes present.
fn rhs(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| (0.7 * i as f64).sin() + 0.3 * (1.9 * i as f64).cos() + 0.1)
        .collect()
}

fn dense_solve(a: &SparseMatrix, b: &[f64], transpose: bool) -> DVector<f64> {
    let dense = if transpose {
        a.to_dense().transpose()
    } else {
        a.to_dense()
    };
    dense
        .lu()
        .solve(&DVector::from_column_slice(b))
        .expect("test matrices are non-singular")
}

fn condition_number(a: &SparseMatrix) -> f64 {
    let s = a.to_dense().singular_values();
    s.max() / s.min()
}

fn relative_error(x: &[f64], reference: &DVector<f64>) -> f64 {
    (DVector::from_column_slice(x) - reference).norm() / reference.norm()
}

const PRECONDITIONERS: [Preconditioner; 4] = [
    Preconditioner::Identity,
    Preconditioner::Jacobi,
    Preconditioner::Ilu0,
    Preconditioner::Amg,
];

fn cg(preconditioner: Preconditioner) -> LinearSolverKind {
    LinearSolverKind::Cg {
        preconditioner,
        rel_tol: 1e-10,
        max_iter: 1000,
    }
}

fn bicgstab(preconditioner: Preconditioner) -> LinearSolverKind {
    LinearSolverKind::Bicgstab {
        preconditioner,
        rel_tol: 1e-10,
        max_iter: 1000,
    }
}

fn gmres(preconditioner: Preconditioner) -> LinearSolverKind {
    LinearSolverKind::Gmres {
        preconditioner,
        rel_tol: 1e-10,
        max_iter: 1000,
    }
}

/// Solves with `kind` (plain or transposed) and checks the solution against the dense LU solve.
fn check_against_dense(a: &SparseMatrix, kind: LinearSolverKind, transpose: bool) {
    let n = a.pattern.n();
    let b = rhs(n);
    let mut x = vec![f64::NAN; n];
    let mut solver = LinearSolver::new(kind);
    let stats = if transpose {
        solver.solve_transpose(a, &b, &mut x)
    } else {
        solver.solve(a, &b, &mut x)
    }
    .unwrap_or_else(|e| panic!("{}: {e}", kind.name()));
    assert_eq!(stats.method, kind.name());
    let err = relative_error(&x, &dense_solve(a, &b, transpose));
    let bound = match kind {
        LinearSolverKind::Lu | LinearSolverKind::Cholesky => 1e-10,
        LinearSolverKind::Cg { rel_tol, .. }
        | LinearSolverKind::Bicgstab { rel_tol, .. }
        | LinearSolverKind::Gmres { rel_tol, .. } => {
            // faer stops on its recursively updated residual; the true one may differ by
            // round-off only (GMRES stops on the true one).
            assert!(
                stats.relative_residual <= 1.01 * rel_tol,
                "{}: {stats:?}",
                kind.name()
            );
            condition_number(a) * stats.relative_residual + 1e-12
        }
    };
    assert!(
        err <= bound,
        "{} (transpose {transpose}): error {err:.3e} > {bound:.3e} ({stats:?})",
        kind.name()
    );
}

#[test]
fn pattern_sorts_and_deduplicates() {
    let p = SparsePattern::new(3, [(2, 0), (0, 0), (2, 0), (1, 2), (0, 2), (1, 1), (0, 0)]);
    assert_eq!(p.n(), 3);
    assert_eq!(p.nnz(), 5);
    assert_eq!(p.col_ptr(), &[0, 2, 3, 5]);
    assert_eq!(p.row_idx(), &[0, 2, 1, 0, 1]);
    assert_eq!(p.position(2, 0), Some(1));
    assert_eq!(p.position(1, 2), Some(4));
    assert_eq!(p.position(1, 0), None);
    assert_eq!(p.position(0, 3), None);
}

#[test]
fn matrix_products_diagonal_and_symmetry_match_dense() {
    let a = convection_diffusion(4);
    let dense = a.to_dense();
    let x = rhs(16);
    let mut y = vec![0.0; 16];
    a.mul_vec(&x, &mut y);
    let xv = DVector::from_column_slice(&x);
    assert!((DVector::from_column_slice(&y) - &dense * &xv).norm() < 1e-13);
    a.mul_vec_transpose(&x, &mut y);
    assert!((DVector::from_column_slice(&y) - dense.transpose() * &xv).norm() < 1e-13);
    assert_eq!(DVector::from_vec(a.diagonal()), dense.diagonal());
    // Upwind weights 3 and 1 against 1: max |a_ij − a_ji| = 2, max |a_ij| = 7.
    assert!((a.symmetry_error() - 2.0 / 7.0).abs() < 1e-15);
    assert_eq!(poisson(4).symmetry_error(), 0.0);
}

#[test]
#[should_panic(expected = "not in the sparsity pattern")]
fn adding_outside_the_pattern_panics() {
    let mut a = poisson(3);
    a.add(0, 8, 1.0);
}

#[test]
fn every_solver_matches_dense_on_poisson() {
    let a = poisson(12);
    let kinds = [LinearSolverKind::Lu, LinearSolverKind::Cholesky].into_iter();
    for kind in kinds
        .chain(PRECONDITIONERS.map(cg))
        .chain(PRECONDITIONERS.map(bicgstab))
    {
        check_against_dense(&a, kind, false);
    }
}

#[test]
fn nonsymmetric_solvers_match_dense_on_convection_diffusion() {
    let a = convection_diffusion(12);
    for kind in std::iter::once(LinearSolverKind::Lu)
        .chain(PRECONDITIONERS.map(bicgstab))
        .chain(PRECONDITIONERS.map(gmres))
    {
        check_against_dense(&a, kind, false);
    }
}

#[test]
fn transpose_solves_match_dense() {
    let a = convection_diffusion(12);
    for kind in std::iter::once(LinearSolverKind::Lu)
        .chain(PRECONDITIONERS.map(bicgstab))
        .chain(PRECONDITIONERS.map(gmres))
    {
        check_against_dense(&a, kind, true);
    }
    // Symmetric solvers: Aᵀ = A.
    let a = poisson(12);
    for kind in std::iter::once(LinearSolverKind::Cholesky).chain(PRECONDITIONERS.map(cg)) {
        check_against_dense(&a, kind, true);
    }
}

/// Unpreconditioned GMRES on a 900-unknown convection–diffusion system needs several restart
/// cycles of [`gmres::RESTART`] steps; the restarted solves, plain and transposed, still match
/// the dense LU solve within `κ(A)` times the relative residual.
#[test]
fn restarted_gmres_matches_dense() {
    let a = convection_diffusion(30);
    for transpose in [false, true] {
        let n = a.pattern.n();
        let b = rhs(n);
        let mut x = vec![0.0; n];
        let kind = gmres(Preconditioner::Identity);
        let mut solver = LinearSolver::new(kind);
        let stats = if transpose {
            solver.solve_transpose(&a, &b, &mut x)
        } else {
            solver.solve(&a, &b, &mut x)
        }
        .expect("converges");
        assert!(
            stats.iterations > 2 * gmres::RESTART,
            "restarted: {stats:?}"
        );
        assert!(stats.relative_residual <= 1e-10, "{stats:?}");
        let err = relative_error(&x, &dense_solve(&a, &b, transpose));
        let bound = condition_number(&a) * stats.relative_residual + 1e-12;
        assert!(
            err <= bound,
            "transpose {transpose}: {err:.2e} > {bound:.2e}"
        );
    }
}

#[test]
fn symbolic_analysis_is_reused_while_the_pattern_is_the_same() {
    let kinds = [
        LinearSolverKind::Lu,
        LinearSolverKind::Cholesky,
        cg(Preconditioner::Ilu0),
        bicgstab(Preconditioner::Jacobi),
    ];
    for kind in kinds {
        let mut solver = LinearSolver::new(kind);
        let mut a = poisson(10);
        let b = rhs(100);
        let mut x = vec![0.0; 100];
        solver.solve(&a, &b, &mut x).expect("first solve");
        // New values on the same pattern: A ← 2A + diag(1, 2, 3, ...).
        a.values.iter_mut().for_each(|v| *v *= 2.0);
        for i in 0..100 {
            a.add(i, i, (i + 1) as f64);
        }
        let stats = solver.solve(&a, &b, &mut x).expect("second solve");
        assert_eq!(solver.symbolic_analyses(), 1, "{}", kind.name());
        let err = relative_error(&x, &dense_solve(&a, &b, false));
        assert!(err < 1e-8, "{}: error {err:.2e} ({stats:?})", kind.name());
        // Same structure but a different pattern object: analysed again.
        let copy = SparseMatrix {
            pattern: poisson(10).pattern,
            values: a.values,
        };
        solver.solve(&copy, &b, &mut x).expect("third solve");
        assert_eq!(solver.symbolic_analyses(), 2, "{}", kind.name());
    }
}

#[test]
fn cholesky_rejects_indefinite_and_nonsymmetric_matrices() {
    // Laplacian eigenvalues lie in (0, 8): shifting by 4 makes it indefinite.
    let mut a = poisson(8);
    for i in 0..64 {
        a.add(i, i, -4.0);
    }
    let mut x = vec![0.0; 64];
    let err = LinearSolver::new(LinearSolverKind::Cholesky)
        .solve(&a, &rhs(64), &mut x)
        .unwrap_err();
    assert!(
        matches!(
            err,
            LinearError::NotPositiveDefinite {
                method: "Cholesky",
                ..
            }
        ),
        "{err}"
    );

    let a = convection_diffusion(8);
    for kind in [LinearSolverKind::Cholesky, cg(Preconditioner::Identity)] {
        let err = LinearSolver::new(kind)
            .solve(&a, &rhs(64), &mut x)
            .unwrap_err();
        assert!(matches!(err, LinearError::NotSymmetric { .. }), "{err}");
    }
}

#[test]
fn lu_reports_singular_matrices() {
    let mut x = vec![0.0; 64];
    let mut lu = LinearSolver::new(LinearSolverKind::Lu);
    // Pure-Neumann Laplacian (zero row sums; constant null space) with b ∉ range(A).
    let mut a = poisson(8);
    for j in 0..64 {
        let row_sum: f64 = (0..64)
            .filter_map(|i| a.pattern.position(j, i).map(|p| a.values[p]))
            .sum();
        a.add(j, j, -row_sum);
    }
    let err = lu.solve(&a, &rhs(64), &mut x).unwrap_err();
    assert!(
        matches!(err, LinearError::Singular { method: "LU", .. }),
        "{err}"
    );

    // A column of explicit zeros.
    let mut a = poisson(8);
    for p in a.pattern.col_range(5) {
        a.values[p] = 0.0;
    }
    let err = lu.solve(&a, &rhs(64), &mut x).unwrap_err();
    assert!(
        matches!(err, LinearError::Singular { method: "LU", .. }),
        "{err}"
    );

    // A column missing from the pattern (structurally singular).
    let entries = (0..4)
        .map(|i| (i, i))
        .filter(|&(_, j)| j != 2)
        .chain([(2, 1)]);
    let mut a = SparseMatrix::zeros(Arc::new(SparsePattern::new(4, entries)));
    a.values.fill(1.0);
    let err = lu.solve(&a, &[1.0; 4], &mut x[..4]).unwrap_err();
    assert!(
        matches!(err, LinearError::Singular { method: "LU", .. }),
        "{err}"
    );
}

#[test]
fn preconditioner_setup_errors() {
    let mut x = vec![0.0; 9];
    let mut a = poisson(3);
    let p = a.pattern.diagonal_position(4).expect("diagonal");
    a.values[p] = 0.0;
    let err = LinearSolver::new(bicgstab(Preconditioner::Jacobi))
        .solve(&a, &rhs(9), &mut x)
        .unwrap_err();
    assert!(
        matches!(
            err,
            LinearError::ZeroPivot {
                preconditioner: "Jacobi",
                row: 4
            }
        ),
        "{err}"
    );

    let a = SparseMatrix::zeros(Arc::new(SparsePattern::new(2, [(0, 0), (0, 1), (1, 0)])));
    let err = LinearSolver::new(bicgstab(Preconditioner::Ilu0))
        .solve(&a, &[1.0; 2], &mut x[..2])
        .unwrap_err();
    assert!(
        matches!(err, LinearError::MissingDiagonal { row: 1 }),
        "{err}"
    );

    let mut a = poisson(3);
    a.values[3] = f64::NAN;
    let err = LinearSolver::new(LinearSolverKind::Lu)
        .solve(&a, &rhs(9), &mut x)
        .unwrap_err();
    assert!(
        matches!(
            err,
            LinearError::NonFinite {
                what: "matrix",
                index: 3
            }
        ),
        "{err}"
    );
}

/// Tridiagonal matrices (SPD and non-symmetric): ILU(0) has no fill to drop, so it is the exact
/// LU and the preconditioned solvers converge in one iteration.
#[test]
fn ilu0_of_a_tridiagonal_matrix_is_exact() {
    let n: usize = 50;
    let tridiagonal = |lower: f64, upper: f64| {
        let entries =
            (0..n).flat_map(|i| [(i, i), (i, i.saturating_sub(1)), (i, (i + 1).min(n - 1))]);
        let mut a = SparseMatrix::zeros(Arc::new(SparsePattern::new(n, entries)));
        for i in 0..n {
            a.add(i, i, 2.5 + (i as f64 * 0.37).sin());
            if i > 0 {
                a.add(i, i - 1, -lower);
                a.add(i - 1, i, -upper);
            }
        }
        a
    };
    for (a, kind) in [
        (
            tridiagonal(1.0, 1.0),
            LinearSolverKind::Cg {
                preconditioner: Preconditioner::Ilu0,
                rel_tol: 1e-12,
                max_iter: 10,
            },
        ),
        (
            tridiagonal(1.4, 0.6),
            LinearSolverKind::Bicgstab {
                preconditioner: Preconditioner::Ilu0,
                rel_tol: 1e-12,
                max_iter: 10,
            },
        ),
    ] {
        let mut state =
            PrecondState::new(Preconditioner::Ilu0, &a.pattern).expect("diagonal present");
        state.factorize(&a, None, None).expect("non-zero pivots");
        let (l, u) = dense_factors(&a, &state);
        assert!((&l * &u - a.to_dense()).abs().max() < 1e-14);
        let mut x = vec![0.0; n];
        let stats = LinearSolver::new(kind)
            .solve(&a, &rhs(n), &mut x)
            .expect("converges");
        assert_eq!(stats.iterations, 1, "{stats:?}");
    }
}

/// The defining property of ILU(0): `(L U)_ij = a_ij` on the pattern of `A`.
#[test]
fn ilu0_reproduces_the_matrix_on_its_pattern() {
    for a in [poisson(7), convection_diffusion(7)] {
        let mut state =
            PrecondState::new(Preconditioner::Ilu0, &a.pattern).expect("diagonal present");
        state
            .factorize(&a, None, None)
            .expect("M-matrix: positive pivots");
        let (l, u) = dense_factors(&a, &state);
        let lu = &l * &u;
        let dense = a.to_dense();
        let mut max_err = 0.0_f64;
        for j in 0..a.pattern.n() {
            for p in a.pattern.col_range(j) {
                let i = a.pattern.row_idx()[p];
                max_err = max_err.max((lu[(i, j)] - dense[(i, j)]).abs());
            }
        }
        assert!(max_err < 1e-13, "{max_err:e}");
        // And it is not the exact LU (fill was dropped).
        assert!((lu - dense).abs().max() > 1e-3);
    }
}

/// Dense `L` (lower, with the diagonal) and `U` (unit upper) of an ILU(0) state.
fn dense_factors(a: &SparseMatrix, state: &PrecondState) -> (DMatrix<f64>, DMatrix<f64>) {
    let PrecondState::Ilu0 { factor, .. } = state else {
        panic!("not an ILU(0) state")
    };
    let f = SparseMatrix {
        pattern: Arc::clone(&a.pattern),
        values: factor.clone(),
    }
    .to_dense();
    let n = a.pattern.n();
    (
        f.lower_triangle(),
        f.upper_triangle() - DMatrix::from_diagonal(&f.diagonal()) + DMatrix::identity(n, n),
    )
}

/// Bitwise-identical results with 1 and 4 rayon threads.
#[test]
fn results_do_not_depend_on_the_thread_count() {
    let a = convection_diffusion(60);
    let spd = poisson(60);
    let b = rhs(3600);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        pool.install(|| {
            let mut out = Vec::new();
            for (m, kind) in [
                (&a, LinearSolverKind::Lu),
                (&spd, LinearSolverKind::Cholesky),
                (&spd, cg(Preconditioner::Ilu0)),
                (&a, bicgstab(Preconditioner::Ilu0)),
                (&spd, cg(Preconditioner::Amg)),
                (&a, bicgstab(Preconditioner::Amg)),
            ] {
                let mut x = vec![0.0; 3600];
                LinearSolver::new(kind)
                    .solve(m, &b, &mut x)
                    .expect("solves");
                out.push(x);
            }
            out
        })
    };
    let one = run(1);
    let four = run(4);
    for (x1, x4) in one.iter().zip(&four) {
        assert!(x1.iter().zip(x4).all(|(p, q)| p.to_bits() == q.to_bits()));
    }
}

#[test]
fn empty_system() {
    let a = SparseMatrix::zeros(Arc::new(SparsePattern::new(0, [])));
    let kinds = [LinearSolverKind::Lu, LinearSolverKind::Cholesky].into_iter();
    for kind in kinds
        .chain(PRECONDITIONERS.map(cg))
        .chain(PRECONDITIONERS.map(bicgstab))
        .chain(PRECONDITIONERS.map(gmres))
    {
        let stats = LinearSolver::new(kind)
            .solve(&a, &[], &mut [])
            .expect("empty solve");
        assert_eq!(stats.relative_residual, 0.0);
    }
}
