//! Sparse linear algebra of the Newton solver: a fixed per-step [`SparsePattern`], the
//! [`SparseMatrix`] refilled on it at every iteration, and a [`LinearSolver`] that solves
//! `A x = b` or `Aᵀ x = b` with faer's sparse LU or Cholesky (symbolic analysis reused while the
//! pattern stays the same), with faer's preconditioned CG / BiCGSTAB or with restarted GMRES
//! ([`gmres`]), preconditioned by the identity, Jacobi, ILU(0), smoothed-aggregation AMG or,
//! for the coupled u–p systems, the block preconditioner of [`block`].
//!
//! Everything runs sequentially ([`faer::Par::Seq`]): faer's parallel dense kernels split some
//! reductions by thread count, which would make the results depend on the machine.

pub mod amg;
#[cfg(test)]
mod amg_tests;
pub mod block;
#[cfg(test)]
mod block_tests;
mod direct;
pub mod gmres;
mod krylov;
mod pattern;
mod precond;
#[cfg(test)]
mod tests;

use std::sync::Arc;

use faer::Par;

pub use amg::NearNullspace;
pub use block::BlockSplit;
pub use pattern::{SparseMatrix, SparsePattern};
pub use precond::Preconditioner;

use krylov::KrylovParams;
use precond::PrecondState;

/// Largest relative asymmetry `max |a_ij − a_ji| / max |a_ij|` accepted by the solvers for
/// symmetric matrices (Cholesky, CG); tangents that are symmetric in theory are so to round-off.
pub const SYMMETRY_TOLERANCE: f64 = 1e-8;

/// Largest relative residual `‖b − A x‖ / ‖b‖` of a direct solve; beyond it the matrix is reported
/// [`LinearError::Singular`] (singular or so ill-conditioned that the solution is meaningless).
/// A Newton correction solved to 1e-4 still gives a converging iteration (an inexact Newton
/// step), so ill-conditioned but usable tangents are accepted.
pub const DIRECT_RESIDUAL_LIMIT: f64 = 1e-4;

/// Parallelism of every faer call (see the module documentation).
const PAR: Par = Par::Seq;

/// Which linear solver to use.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LinearSolverKind {
    /// Sparse LU with partial pivoting (faer); any non-singular matrix.
    Lu,
    /// Sparse Cholesky `L Lᵀ` (faer); symmetric positive definite matrices only.
    Cholesky,
    /// Preconditioned conjugate gradient (faer); symmetric positive definite matrices only.
    Cg {
        /// Preconditioner (must be symmetric positive definite for CG).
        preconditioner: Preconditioner,
        /// Stop when `‖b − A x‖ < rel_tol ‖b‖`.
        rel_tol: f64,
        /// Iteration limit.
        max_iter: usize,
    },
    /// Right-preconditioned BiCGSTAB (faer); any non-singular matrix.
    Bicgstab {
        /// Preconditioner.
        preconditioner: Preconditioner,
        /// Stop when `‖b − A x‖ < rel_tol ‖b‖`.
        rel_tol: f64,
        /// Iteration limit.
        max_iter: usize,
    },
    /// Right-preconditioned GMRES restarted every [`gmres::RESTART`] iterations ([`gmres`]);
    /// any non-singular matrix.
    Gmres {
        /// Preconditioner.
        preconditioner: Preconditioner,
        /// Stop when `‖b − A x‖ < rel_tol ‖b‖`.
        rel_tol: f64,
        /// Iteration limit.
        max_iter: usize,
    },
}

/// [`LinearSolverKind::name`] of the Krylov methods: row CG, BiCGSTAB, GMRES; column by
/// preconditioner in the order of [`Preconditioner`]'s variants.
const KRYLOV_NAMES: [[&str; 5]; 3] = [
    ["CG", "CG+Jacobi", "CG+ILU(0)", "CG+AMG", "CG+block"],
    [
        "BiCGSTAB",
        "BiCGSTAB+Jacobi",
        "BiCGSTAB+ILU(0)",
        "BiCGSTAB+AMG",
        "BiCGSTAB+block",
    ],
    [
        "GMRES",
        "GMRES+Jacobi",
        "GMRES+ILU(0)",
        "GMRES+AMG",
        "GMRES+block",
    ],
];

impl LinearSolverKind {
    /// Short name used in reports and errors, e.g. `"CG+ILU(0)"`.
    pub fn name(self) -> &'static str {
        let (method, preconditioner) = match self {
            Self::Lu => return "LU",
            Self::Cholesky => return "Cholesky",
            Self::Cg { preconditioner, .. } => (0, preconditioner),
            Self::Bicgstab { preconditioner, .. } => (1, preconditioner),
            Self::Gmres { preconditioner, .. } => (2, preconditioner),
        };
        let column = match preconditioner {
            Preconditioner::Identity => 0,
            Preconditioner::Jacobi => 1,
            Preconditioner::Ilu0 => 2,
            Preconditioner::Amg => 3,
            Preconditioner::Block => 4,
        };
        KRYLOV_NAMES[method][column]
    }

    /// The preconditioner of an iterative method (`None` for a direct one).
    pub fn preconditioner(self) -> Option<Preconditioner> {
        match self {
            Self::Lu | Self::Cholesky => None,
            Self::Cg { preconditioner, .. }
            | Self::Bicgstab { preconditioner, .. }
            | Self::Gmres { preconditioner, .. } => Some(preconditioner),
        }
    }

    /// Whether the method uses a near-nullspace ([`LinearSolver::set_near_nullspace`]).
    pub fn uses_near_nullspace(self) -> bool {
        self.preconditioner() == Some(Preconditioner::Amg)
    }

    /// Whether the method needs the displacement–pressure split of the unknowns
    /// ([`LinearSolver::set_block_split`]).
    pub fn uses_block_split(self) -> bool {
        self.preconditioner() == Some(Preconditioner::Block)
    }

    /// Whether the method needs a symmetric matrix.
    fn needs_symmetry(self) -> bool {
        matches!(self, Self::Cholesky | Self::Cg { .. })
    }
}

/// Outcome of a successful solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearStats {
    /// [`LinearSolverKind::name`] of the method used.
    pub method: &'static str,
    /// Krylov iterations; 1 for a direct solve.
    pub iterations: usize,
    /// True relative residual `‖b − A x‖ / ‖b‖` of the returned solution (`‖b − A x‖` when
    /// `b = 0`), recomputed after the solve.
    pub relative_residual: f64,
}

/// Why a linear solve failed.
#[derive(Debug, thiserror::Error)]
pub enum LinearError {
    /// The matrix or the right-hand side holds a NaN or an infinity.
    #[error("the {what} holds a non-finite value (NaN or infinity) at index {index}")]
    NonFinite {
        /// `"matrix"` or `"right-hand side"`.
        what: &'static str,
        /// Index into the value array or the vector.
        index: usize,
    },
    /// The matrix is structurally or numerically singular.
    #[error("{method}: the matrix is singular ({detail})")]
    Singular {
        /// Solver name.
        method: &'static str,
        /// What revealed it.
        detail: String,
    },
    /// A solver for symmetric positive definite matrices met a matrix that is not.
    #[error("{method}: the matrix is not positive definite ({detail}); use LU or BiCGSTAB")]
    NotPositiveDefinite {
        /// Solver name.
        method: &'static str,
        /// What revealed it.
        detail: String,
    },
    /// A solver for symmetric matrices met a matrix that is not.
    #[error(
        "{method}: the matrix is not symmetric (relative asymmetry {symmetry_error:.2e} > \
         {tolerance:.0e}); use LU or BiCGSTAB"
    )]
    NotSymmetric {
        /// Solver name.
        method: &'static str,
        /// [`SparseMatrix::symmetry_error`].
        symmetry_error: f64,
        /// [`SYMMETRY_TOLERANCE`].
        tolerance: f64,
    },
    /// An iterative solver reached its iteration limit.
    #[error(
        "{method}: not converged after {iterations} iterations (relative residual \
         {relative_residual:.3e}, target {target:.1e})"
    )]
    NotConverged {
        /// Solver name.
        method: &'static str,
        /// Iterations done.
        iterations: usize,
        /// True relative residual of the last iterate.
        relative_residual: f64,
        /// Requested relative residual.
        target: f64,
    },
    /// ILU(0) needs every diagonal entry in the pattern.
    #[error(
        "ILU(0) needs the diagonal in the sparsity pattern, but row {row} has no diagonal entry"
    )]
    MissingDiagonal {
        /// First row without a diagonal entry.
        row: usize,
    },
    /// The block preconditioner was not given the displacement–pressure split of the unknowns
    /// (a system without pore pressures).
    #[error(
        "the block preconditioner needs a coupled displacement–pressure system (a pore fluid); \
         use another preconditioner for the solid alone"
    )]
    NoBlockSplit,
    /// A preconditioner divides by zero.
    #[error("{preconditioner} preconditioner: zero pivot in row {row}")]
    ZeroPivot {
        /// `"Jacobi"`, `"ILU(0)"`, `"AMG"` or `"block"`.
        preconditioner: &'static str,
        /// Row of the zero diagonal entry or pivot (for the AMG, a row of the level where it
        /// was met: the finest, a coarse one or the coarsest's dense LU).
        row: usize,
    },
    /// faer failed for a reason unrelated to the matrix values (out of memory, index overflow).
    #[error("{method}: {message}")]
    Backend {
        /// Solver name.
        method: &'static str,
        /// faer's error.
        message: String,
    },
}

/// Whether to solve with `A` or with `Aᵀ`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Orientation {
    Plain,
    Transposed,
}

/// Per-pattern state of the selected method.
#[derive(Debug)]
enum Backend {
    Lu(direct::Lu),
    Cholesky(direct::Cholesky),
    Krylov(Krylov, PrecondState, KrylovParams),
}

/// The Krylov methods.
#[derive(Clone, Copy, Debug)]
enum Krylov {
    Cg,
    Bicgstab,
    Gmres,
}

/// The per-pattern state and the pattern it belongs to.
#[derive(Debug)]
struct Analysis {
    pattern: Arc<SparsePattern>,
    backend: Backend,
}

/// Sparse linear solver of one kind, caching its symbolic work (faer's symbolic LU / Cholesky,
/// the ILU(0) structure and the preconditioner storage) for the pattern it last saw; the cache is
/// reused while the matrices come with the same `Arc<SparsePattern>` (pointer identity).
#[derive(Debug)]
pub struct LinearSolver {
    kind: LinearSolverKind,
    analysis: Option<Analysis>,
    symbolic_analyses: usize,
    near_nullspace: Option<Arc<NearNullspace>>,
    block_split: Option<Arc<BlockSplit>>,
}

impl LinearSolver {
    /// A solver of the given kind, with nothing cached yet.
    pub fn new(kind: LinearSolverKind) -> Self {
        Self {
            kind,
            analysis: None,
            symbolic_analyses: 0,
            near_nullspace: None,
            block_split: None,
        }
    }

    /// Gives the near-nullspace of the next matrices (for the AMG preconditioner: the
    /// rigid-body modes of the unknowns, [`NearNullspace::rigid_body`]); `None` falls back to
    /// the constant vector, unknown by unknown. The other methods ignore it.
    ///
    /// The solves that follow panic if its size differs from that of their matrix.
    pub fn set_near_nullspace(&mut self, near_nullspace: Option<NearNullspace>) {
        self.near_nullspace = near_nullspace.map(Arc::new);
    }

    /// Gives the displacement–pressure split of the next matrices, for the block
    /// preconditioner ([`BlockSplit`]); `None` (a system without pore pressures) makes its
    /// solves fail with [`LinearError::NoBlockSplit`]. The other methods ignore it.
    ///
    /// The solves that follow panic if its size differs from that of their matrix.
    pub fn set_block_split(&mut self, block_split: Option<BlockSplit>) {
        self.block_split = block_split.map(Arc::new);
    }

    /// The kind of solver.
    pub fn kind(&self) -> LinearSolverKind {
        self.kind
    }

    /// Number of per-pattern analyses done so far (one per distinct pattern met in a row): the
    /// symbolic factorisation for LU and Cholesky, the preconditioner storage (and the ILU(0)
    /// diagonal positions) for the Krylov methods.
    pub fn symbolic_analyses(&self) -> usize {
        self.symbolic_analyses
    }

    /// Solves `A x = b`; `x` is overwritten (its content is not used as an initial guess).
    ///
    /// # Panics
    /// If `b`, `x` or `a.values` do not match the size of the pattern.
    pub fn solve(
        &mut self,
        a: &SparseMatrix,
        b: &[f64],
        x: &mut [f64],
    ) -> Result<LinearStats, LinearError> {
        self.solve_oriented(a, b, x, Orientation::Plain)
    }

    /// Solves `Aᵀ x = b` (adjoint systems), with the same caching as [`Self::solve`].
    ///
    /// # Panics
    /// If `b`, `x` or `a.values` do not match the size of the pattern.
    pub fn solve_transpose(
        &mut self,
        a: &SparseMatrix,
        b: &[f64],
        x: &mut [f64],
    ) -> Result<LinearStats, LinearError> {
        self.solve_oriented(a, b, x, Orientation::Transposed)
    }

    /// The LU factors of the last matrix this solver factorised, kept past the next
    /// factorisation (`None` unless the method is LU and a matrix was factorised).
    pub fn factorisation(&self) -> Option<Factorisation> {
        match &self.analysis {
            Some(Analysis {
                pattern,
                backend: Backend::Lu(lu),
            }) if lu.factored() => Some(Factorisation {
                pattern: Arc::clone(pattern),
                lu: lu.clone(),
            }),
            _ => None,
        }
    }

    fn solve_oriented(
        &mut self,
        a: &SparseMatrix,
        b: &[f64],
        x: &mut [f64],
        orientation: Orientation,
    ) -> Result<LinearStats, LinearError> {
        let n = a.pattern.n();
        assert_eq!(
            a.values.len(),
            a.pattern.nnz(),
            "matrix values vs pattern entries"
        );
        assert_eq!(b.len(), n, "right-hand side length");
        assert_eq!(x.len(), n, "solution length");
        check_finite("matrix", &a.values)?;
        check_finite("right-hand side", b)?;
        let kind = self.kind;
        let method = kind.name();
        if kind.needs_symmetry() {
            let symmetry_error = a.symmetry_error();
            if symmetry_error > SYMMETRY_TOLERANCE {
                return Err(LinearError::NotSymmetric {
                    method,
                    symmetry_error,
                    tolerance: SYMMETRY_TOLERANCE,
                });
            }
        }

        let near_nullspace = self.near_nullspace.clone();
        let block_split = self.block_split.clone();
        let iterations = match self.backend(&a.pattern)? {
            Backend::Lu(lu) => {
                lu.solve(a, b, x, orientation)?;
                1
            }
            // Symmetric: the transposed system is the same.
            Backend::Cholesky(llt) => {
                llt.solve(a, b, x)?;
                1
            }
            Backend::Krylov(method, state, params) => {
                state.factorize(a, near_nullspace.as_deref(), block_split.as_deref())?;
                match method {
                    Krylov::Cg => krylov::solve_cg(state, a, b, x, orientation, *params)?,
                    Krylov::Bicgstab => {
                        krylov::solve_bicgstab(state, a, b, x, orientation, *params)?
                    }
                    Krylov::Gmres => {
                        let precondition = |z: &mut [f64]| {
                            state.solve_in_place(&a.pattern, orientation, z);
                            Ok(())
                        };
                        let apply =
                            |v: &[f64], out: &mut [f64]| a.mul_oriented(v, out, orientation);
                        gmres::solve(apply, precondition, b, x, *params)?
                    }
                }
            }
        };

        let relative_residual = relative_residual(a, b, x, orientation);
        let direct = matches!(kind, LinearSolverKind::Lu | LinearSolverKind::Cholesky);
        if direct && (relative_residual.is_nan() || relative_residual > DIRECT_RESIDUAL_LIMIT) {
            return Err(LinearError::Singular {
                method,
                detail: format!(
                    "the computed solution has relative residual {relative_residual:.2e} > \
                     {DIRECT_RESIDUAL_LIMIT:.0e}"
                ),
            });
        }
        Ok(LinearStats {
            method,
            iterations,
            relative_residual,
        })
    }

    /// The per-pattern state for `pattern`, analysing it unless it is the cached one.
    fn backend(&mut self, pattern: &Arc<SparsePattern>) -> Result<&mut Backend, LinearError> {
        let analysis = match self.analysis.take() {
            Some(cached) if Arc::ptr_eq(&cached.pattern, pattern) => cached,
            stale => {
                // Free the old factorisation before building the new one.
                drop(stale);
                let method = self.kind.name();
                let iterative = |method_kind, preconditioner, rel_tol, max_iter| {
                    let params = KrylovParams {
                        method,
                        rel_tol,
                        max_iter,
                    };
                    PrecondState::new(preconditioner, pattern)
                        .map(|state| Backend::Krylov(method_kind, state, params))
                };
                let backend = match self.kind {
                    LinearSolverKind::Lu => Backend::Lu(direct::Lu::analyse(pattern)?),
                    LinearSolverKind::Cholesky => {
                        Backend::Cholesky(direct::Cholesky::analyse(pattern)?)
                    }
                    LinearSolverKind::Cg {
                        preconditioner,
                        rel_tol,
                        max_iter,
                    } => iterative(Krylov::Cg, preconditioner, rel_tol, max_iter)?,
                    LinearSolverKind::Bicgstab {
                        preconditioner,
                        rel_tol,
                        max_iter,
                    } => iterative(Krylov::Bicgstab, preconditioner, rel_tol, max_iter)?,
                    LinearSolverKind::Gmres {
                        preconditioner,
                        rel_tol,
                        max_iter,
                    } => iterative(Krylov::Gmres, preconditioner, rel_tol, max_iter)?,
                };
                self.symbolic_analyses += 1;
                Analysis {
                    pattern: Arc::clone(pattern),
                    backend,
                }
            }
        };
        Ok(&mut self.analysis.insert(analysis).backend)
    }
}

/// Relative residual `‖b − Aᵀx‖/‖b‖` at which [`Factorisation::solve_transpose`] stops:
/// near the round-off of the product itself (the coupled examples' solves end at 7e-16 to
/// 4e-15), so that a gradient through it agrees with one through a direct solve to the
/// digits the checks compare (the printed gradients: every digit).
pub const NEAR_REL_TOL: f64 = 1e-14;

/// Iterations [`Factorisation::solve_transpose`] allows: the last Newton tangent of a
/// converged step differs from the converged one by a perturbation of the size of the last
/// correction (or of low rank, where particles changed between elastic and plastic), so
/// GMRES preconditioned by its factors needs a few (1 to 4 on the coupled examples).
pub const NEAR_MAX_ITER: usize = 20;

/// The LU factors of one matrix, kept past its solve ([`LinearSolver::factorisation`]) to
/// precondition solves with nearby matrices of the same sparsity structure
/// ([`Factorisation::solve_transpose`]).
#[derive(Clone, Debug)]
pub struct Factorisation {
    pattern: Arc<SparsePattern>,
    lu: direct::Lu,
}

impl Factorisation {
    /// Number of unknowns.
    pub fn n(&self) -> usize {
        self.pattern.n()
    }

    /// Solves `Aᵀ x = b` by GMRES right-preconditioned with these factors (`M⁻ᵀ`), for an
    /// `A` on `pattern` close to the factorised matrix (the last Newton tangent of a step
    /// whose adjoint takes the tangent at the converged state) and given by its transposed
    /// product `apply_transpose(v, out)`: `out = Aᵀ v`. A few products and solves replace a
    /// factorisation, and `A` need not be assembled. Returns the iteration count, or `None`
    /// (with `x` unspecified) where the factors are of another structure or GMRES does not
    /// reach [`NEAR_REL_TOL`] in [`NEAR_MAX_ITER`] iterations: the caller then solves `A`
    /// itself.
    ///
    /// # Errors
    /// A right-hand side that is not finite.
    pub fn solve_transpose(
        &self,
        pattern: &Arc<SparsePattern>,
        apply_transpose: impl Fn(&[f64], &mut [f64]),
        b: &[f64],
        x: &mut [f64],
    ) -> Result<Option<usize>, LinearError> {
        if !self.fits(pattern) {
            return Ok(None);
        }
        check_finite("right-hand side", b)?;
        let params = KrylovParams {
            method: "GMRES+LU of a nearby matrix",
            rel_tol: NEAR_REL_TOL,
            max_iter: NEAR_MAX_ITER,
        };
        let precondition = |z: &mut [f64]| self.lu.apply(z, Orientation::Transposed);
        match gmres::solve(apply_transpose, precondition, b, x, params) {
            Ok(iterations) => Ok(Some(iterations)),
            Err(LinearError::NotConverged { .. }) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// Whether `pattern` is the structure these factors were computed on.
    fn fits(&self, pattern: &Arc<SparsePattern>) -> bool {
        Arc::ptr_eq(&self.pattern, pattern)
            || (self.pattern.n() == pattern.n()
                && self.pattern.col_ptr() == pattern.col_ptr()
                && self.pattern.row_idx() == pattern.row_idx())
    }
}

/// Fails on the first NaN or infinity of `values`.
fn check_finite(what: &'static str, values: &[f64]) -> Result<(), LinearError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(LinearError::NonFinite { what, index }),
        None => Ok(()),
    }
}

/// `‖b − op(A) x‖ / ‖b‖`, or `‖b − op(A) x‖` when `b = 0`.
fn relative_residual(a: &SparseMatrix, b: &[f64], x: &[f64], orientation: Orientation) -> f64 {
    let residual = residual_norm(|v, out| a.mul_oriented(v, out, orientation), b, x);
    let b_norm = b.iter().map(|b| b * b).sum::<f64>().sqrt();
    if b_norm > 0.0 {
        residual / b_norm
    } else {
        residual
    }
}

/// `‖b − A x‖` for `A` given by its product `apply(v, out)`: `out = A v`.
fn residual_norm(apply: impl Fn(&[f64], &mut [f64]), b: &[f64], x: &[f64]) -> f64 {
    let mut ax = vec![0.0; b.len()];
    apply(x, &mut ax);
    ax.iter()
        .zip(b)
        .map(|(ax, b)| (b - ax).powi(2))
        .sum::<f64>()
        .sqrt()
}
