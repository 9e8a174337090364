//! Sparse direct solvers: faer's LU (partial pivoting, COLAMD ordering) and LLᵀ (AMD ordering),
//! with the symbolic analysis done once per pattern.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{LltError, LltRegularization};
use faer::sparse::linalg::LuError;
use faer::sparse::linalg::cholesky::{
    SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::linalg::lu::{LuRef, NumericLu, SymbolicLu, factorize_symbolic_lu};
use faer::{Conj, MatMut, Side};

use super::{LinearError, Orientation, PAR, SparseMatrix, SparsePattern};

/// faer's symbolic and numeric LU; the numeric part is refilled by every solve and kept for
/// [`Lu::apply`] until the next one.
#[derive(Clone, Debug)]
pub(super) struct Lu {
    symbolic: SymbolicLu<usize>,
    numeric: NumericLu<usize, f64>,
    /// Whether `numeric` holds the factors of a matrix (none before the first solve).
    factored: bool,
}

impl Lu {
    const METHOD: &'static str = "LU";

    /// Symbolic analysis (column ordering, elimination structure) of `pattern`.
    pub(super) fn analyse(pattern: &SparsePattern) -> Result<Self, LinearError> {
        let symbolic = factorize_symbolic_lu(pattern.symbolic().as_ref(), Default::default())
            .map_err(|e| backend_error(Self::METHOD, e))?;
        Ok(Self {
            symbolic,
            numeric: NumericLu::new(),
            factored: false,
        })
    }

    /// Whether the factors of a matrix are held.
    pub(super) fn factored(&self) -> bool {
        self.factored
    }

    /// Numeric factorisation of `a`, then `x = A⁻¹ b` (or `A⁻ᵀ b`).
    pub(super) fn solve(
        &mut self,
        a: &SparseMatrix,
        b: &[f64],
        x: &mut [f64],
        orientation: Orientation,
    ) -> Result<(), LinearError> {
        let mut buffer = workspace(
            Self::METHOD,
            self.symbolic
                .factorize_numeric_lu_scratch::<f64>(PAR, Default::default()),
        )?;
        self.factored = false;
        self.symbolic
            .factorize_numeric_lu(
                &mut self.numeric,
                a.as_faer(),
                PAR,
                MemStack::new(&mut buffer),
                Default::default(),
            )
            .map_err(|e| match e {
                LuError::SymbolicSingular { index } => LinearError::Singular {
                    method: Self::METHOD,
                    detail: format!("no pivot available at elimination step {index}"),
                },
                LuError::Generic(e) => backend_error(Self::METHOD, e),
            })?;
        self.factored = true;
        x.copy_from_slice(b);
        self.apply(x, orientation)
    }

    /// `z ← A⁻¹ z` (or `A⁻ᵀ z`) with the factors of the last matrix [`Lu::solve`] factorised.
    ///
    /// # Panics
    /// If no matrix was factorised ([`Lu::factored`]).
    pub(super) fn apply(&self, z: &mut [f64], orientation: Orientation) -> Result<(), LinearError> {
        assert!(self.factored, "LU applied before a factorisation");
        let scratch = match orientation {
            Orientation::Plain => self.symbolic.solve_in_place_scratch::<f64>(1, PAR),
            Orientation::Transposed => self
                .symbolic
                .solve_transpose_in_place_scratch::<f64>(1, PAR),
        };
        let mut buffer = workspace(Self::METHOD, scratch)?;
        let stack = MemStack::new(&mut buffer);
        let lu = LuRef::new_unchecked(&self.symbolic, &self.numeric);
        let n = z.len();
        let rhs = MatMut::from_column_major_slice_mut(z, n, 1);
        match orientation {
            Orientation::Plain => lu.solve_in_place_with_conj(Conj::No, rhs, PAR, stack),
            Orientation::Transposed => {
                lu.solve_transpose_in_place_with_conj(Conj::No, rhs, PAR, stack)
            }
        }
        Ok(())
    }
}

/// faer's symbolic LLᵀ (of the lower triangle) and the storage of the numeric factor.
#[derive(Debug)]
pub(super) struct Cholesky {
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
}

impl Cholesky {
    const METHOD: &'static str = "Cholesky";

    /// Symbolic analysis (AMD ordering, elimination tree, supernodes) of `pattern`.
    pub(super) fn analyse(pattern: &SparsePattern) -> Result<Self, LinearError> {
        let symbolic = factorize_symbolic_cholesky(
            pattern.symbolic().as_ref(),
            Side::Lower,
            SymmetricOrdering::Amd,
            Default::default(),
        )
        .map_err(|e| backend_error(Self::METHOD, e))?;
        let l_values = vec![0.0; symbolic.len_val()];
        Ok(Self { symbolic, l_values })
    }

    /// Numeric factorisation of the lower triangle of `a` (symmetric, checked by the caller),
    /// then `x = A⁻¹ b`.
    pub(super) fn solve(
        &mut self,
        a: &SparseMatrix,
        b: &[f64],
        x: &mut [f64],
    ) -> Result<(), LinearError> {
        let mut buffer = workspace(
            Self::METHOD,
            StackReq::any_of(&[
                self.symbolic
                    .factorize_numeric_llt_scratch::<f64>(PAR, Default::default()),
                self.symbolic.solve_in_place_scratch::<f64>(1, PAR),
            ]),
        )?;
        let stack = MemStack::new(&mut buffer);
        let llt = self
            .symbolic
            .factorize_numeric_llt(
                &mut self.l_values,
                a.as_faer(),
                Side::Lower,
                LltRegularization::default(),
                PAR,
                stack,
                Default::default(),
            )
            .map_err(
                |LltError::NonPositivePivot { index }| LinearError::NotPositiveDefinite {
                    method: Self::METHOD,
                    detail: format!("non-positive pivot at elimination step {index}"),
                },
            )?;
        llt.solve_in_place_with_conj(Conj::No, rhs_view(b, x), PAR, stack);
        Ok(())
    }
}

/// Copies `b` into `x` and views `x` as a one-column faer matrix (solved in place).
fn rhs_view<'a>(b: &[f64], x: &'a mut [f64]) -> MatMut<'a, f64> {
    x.copy_from_slice(b);
    let n = x.len();
    MatMut::from_column_major_slice_mut(x, n, 1)
}

/// Allocates faer's scratch memory.
fn workspace(method: &'static str, req: StackReq) -> Result<MemBuffer, LinearError> {
    MemBuffer::try_new(req).map_err(|e| backend_error(method, e))
}

/// An error of faer that is not about the matrix (out of memory, index overflow).
fn backend_error(method: &'static str, e: impl std::fmt::Debug) -> LinearError {
    LinearError::Backend {
        method,
        message: format!("{e:?}"),
    }
}
