//! Preconditioned conjugate gradient and BiCGSTAB: faer's matrix-free solvers over the sparse
//! matrix and the preconditioners of [`super::precond`], wrapped as faer [`LinOp`]s.

use std::borrow::Cow;

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::matrix_free::bicgstab::{BicgError, BicgParams, bicgstab, bicgstab_scratch};
use faer::matrix_free::conjugate_gradient::{
    CgError, CgParams, conjugate_gradient, conjugate_gradient_scratch,
};
use faer::matrix_free::{IdentityPrecond, InitialGuessStatus, LinOp, Precond};
use faer::reborrow::ReborrowMut;
use faer::{MatMut, MatRef, Par};

use super::precond::PrecondState;
use super::{LinearError, Orientation, PAR, SparseMatrix, relative_residual};

/// Stopping rule of a Krylov solve.
#[derive(Clone, Copy, Debug)]
pub(super) struct KrylovParams {
    /// Name used in errors.
    pub method: &'static str,
    /// Converged when `‖b − A x‖ < rel_tol ‖b‖` (faer's recursively updated residual).
    pub rel_tol: f64,
    /// Iteration limit.
    pub max_iter: usize,
}

/// `A` or `Aᵀ` as a faer operator.
#[derive(Debug)]
struct MatrixOp<'a> {
    a: &'a SparseMatrix,
    orientation: Orientation,
}

/// `M⁻¹` or `M⁻ᵀ` as a faer preconditioner.
#[derive(Debug)]
struct PrecondOp<'a> {
    state: &'a PrecondState,
    a: &'a SparseMatrix,
    orientation: Orientation,
}

/// Solves with the preconditioned conjugate gradient (`a` symmetric, checked by the caller);
/// `state` must already hold the preconditioner of `a`. Returns the iteration count.
pub(super) fn solve_cg(
    state: &PrecondState,
    a: &SparseMatrix,
    b: &[f64],
    x: &mut [f64],
    orientation: Orientation,
    params: KrylovParams,
) -> Result<usize, LinearError> {
    let op = MatrixOp { a, orientation };
    let precond = PrecondOp {
        state,
        a,
        orientation,
    };
    let mut buffer = MemBuffer::new(conjugate_gradient_scratch(&precond, &op, 1, PAR));
    let n = b.len();
    // faer 0.24 leaves the residual uninitialised with `InitialGuessStatus::Zero` (it only sets
    // `r = b − A x` for `MaybeNonZero`), so start from a zero guess declared as `MaybeNonZero`.
    x.fill(0.0);
    let result = conjugate_gradient(
        MatMut::from_column_major_slice_mut(x, n, 1),
        &precond,
        &op,
        MatRef::from_column_major_slice(b, n, 1),
        CgParams {
            initial_guess: InitialGuessStatus::MaybeNonZero,
            abs_tolerance: 0.0,
            rel_tolerance: params.rel_tol,
            max_iters: params.max_iter,
            ..Default::default()
        },
        |_| {},
        PAR,
        MemStack::new(&mut buffer),
    );
    match result {
        Ok(info) => Ok(info.iter_count),
        Err(CgError::NonPositiveDefiniteOperator | CgError::NonPositiveDefinitePreconditioner) => {
            Err(LinearError::NotPositiveDefinite {
                method: params.method,
                detail: "a search direction of non-positive curvature (the matrix or the preconditioner is not \
                         positive definite)"
                    .into(),
            })
        }
        Err(CgError::NoConvergence { .. }) => Err(not_converged(a, b, x, orientation, params)),
    }
}

/// Solves with BiCGSTAB, right-preconditioned (so the residual it monitors is the true one);
/// `state` must already hold the preconditioner of `a`. Returns the iteration count.
pub(super) fn solve_bicgstab(
    state: &PrecondState,
    a: &SparseMatrix,
    b: &[f64],
    x: &mut [f64],
    orientation: Orientation,
    params: KrylovParams,
) -> Result<usize, LinearError> {
    let op = MatrixOp { a, orientation };
    let left = IdentityPrecond { dim: b.len() };
    let right = PrecondOp {
        state,
        a,
        orientation,
    };
    let mut buffer = MemBuffer::new(bicgstab_scratch(left, &right, &op, 1, PAR));
    let n = b.len();
    // See `solve_cg` on the initial guess.
    x.fill(0.0);
    let result = bicgstab(
        MatMut::from_column_major_slice_mut(x, n, 1),
        left,
        &right,
        &op,
        MatRef::from_column_major_slice(b, n, 1),
        BicgParams {
            initial_guess: InitialGuessStatus::MaybeNonZero,
            abs_tolerance: 0.0,
            rel_tolerance: params.rel_tol,
            max_iters: params.max_iter,
            ..Default::default()
        },
        |_| {},
        PAR,
        MemStack::new(&mut buffer),
    );
    match result {
        Ok(info) => Ok(info.iter_count),
        Err(BicgError::NoConvergence { .. }) => Err(not_converged(a, b, x, orientation, params)),
    }
}

/// The error of a solve that hit the iteration limit, with the true residual of the last
/// iterate (faer's error carries the initial one).
pub(super) fn not_converged(
    a: &SparseMatrix,
    b: &[f64],
    x: &[f64],
    orientation: Orientation,
    params: KrylovParams,
) -> LinearError {
    LinearError::NotConverged {
        method: params.method,
        iterations: params.max_iter,
        relative_residual: relative_residual(a, b, x, orientation),
        target: params.rel_tol,
    }
}

/// Applies `f(rhs column, out column)` to every column, through contiguous copies where faer
/// passes strided views (its solvers pass contiguous columns; other strides are supported for
/// generality).
fn for_each_column(mut out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, f: impl Fn(&[f64], &mut [f64])) {
    for j in 0..rhs.ncols() {
        let column = rhs.col(j);
        let x = match column.try_as_col_major() {
            Some(x) => Cow::Borrowed(x.as_slice()),
            None => Cow::Owned(column.iter().copied().collect()),
        };
        match out.rb_mut().col_mut(j).try_as_col_major_mut() {
            Some(y) => f(&x, y.as_slice_mut()),
            None => {
                let mut y = vec![0.0; out.nrows()];
                f(&x, &mut y);
                out.rb_mut()
                    .col_mut(j)
                    .iter_mut()
                    .zip(y)
                    .for_each(|(o, v)| *o = v);
            }
        }
    }
}

impl LinOp<f64> for MatrixOp<'_> {
    fn apply_scratch(&self, _rhs_ncols: usize, _par: Par) -> StackReq {
        StackReq::EMPTY
    }

    fn nrows(&self) -> usize {
        self.a.pattern.n()
    }

    fn ncols(&self) -> usize {
        self.a.pattern.n()
    }

    fn apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, _par: Par, _stack: &mut MemStack) {
        for_each_column(out, rhs, |x, y| match self.orientation {
            Orientation::Plain => self.a.mul_vec(x, y),
            Orientation::Transposed => self.a.mul_vec_transpose(x, y),
        });
    }

    fn conj_apply(
        &self,
        out: MatMut<'_, f64>,
        rhs: MatRef<'_, f64>,
        par: Par,
        stack: &mut MemStack,
    ) {
        // Real: the conjugate is the operator itself.
        self.apply(out, rhs, par, stack);
    }
}

impl LinOp<f64> for PrecondOp<'_> {
    fn apply_scratch(&self, _rhs_ncols: usize, _par: Par) -> StackReq {
        StackReq::EMPTY
    }

    fn nrows(&self) -> usize {
        self.a.pattern.n()
    }

    fn ncols(&self) -> usize {
        self.a.pattern.n()
    }

    fn apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, _par: Par, _stack: &mut MemStack) {
        for_each_column(out, rhs, |r, z| {
            z.copy_from_slice(r);
            self.state
                .solve_in_place(&self.a.pattern, self.orientation, z);
        });
    }

    fn conj_apply(
        &self,
        out: MatMut<'_, f64>,
        rhs: MatRef<'_, f64>,
        par: Par,
        stack: &mut MemStack,
    ) {
        self.apply(out, rhs, par, stack);
    }
}

impl Precond<f64> for PrecondOp<'_> {}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use faer::Mat;

    use super::*;
    use crate::linear::SparsePattern;

    /// The operator gives the same result on strided (row-major) views as on contiguous ones.
    #[test]
    fn operator_handles_strided_columns() {
        let pattern = Arc::new(SparsePattern::new(
            3,
            [(0, 0), (1, 0), (1, 1), (2, 1), (0, 2), (2, 2)],
        ));
        let a = SparseMatrix {
            pattern,
            values: vec![2.0, -1.0, 3.0, 0.5, 4.0, 1.0],
        };
        let op = MatrixOp {
            a: &a,
            orientation: Orientation::Plain,
        };
        let x = [1.0, -2.0, 0.25];
        let mut expected = [0.0; 3];
        a.mul_vec(&x, &mut expected);

        // Row-major 3×2 storage: each column has row stride 2.
        let rhs_rows = Mat::<f64>::from_fn(2, 3, |i, j| if i == 0 { x[j] } else { 0.0 });
        let mut out_rows = Mat::<f64>::zeros(2, 3);
        let mut buffer = MemBuffer::new(StackReq::EMPTY);
        op.apply(
            out_rows.as_mut().transpose_mut(),
            rhs_rows.as_ref().transpose(),
            PAR,
            MemStack::new(&mut buffer),
        );
        for i in 0..3 {
            assert_eq!(out_rows[(0, i)], expected[i]);
            assert_eq!(out_rows[(1, i)], 0.0);
        }
    }
}
