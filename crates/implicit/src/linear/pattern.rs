//! Compressed-sparse-column pattern and the square sparse matrix stored on it.

use std::fmt;
use std::sync::Arc;

use super::Orientation;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use rayon::slice::ParallelSliceMut;

/// Fixed sparsity pattern of a square matrix in compressed-sparse-column form (row indices
/// sorted within each column, no duplicates).
///
/// Built once per load step from the `(row, col)` pairs of the tangent and shared (through an
/// [`Arc`]) by every matrix of the step; the values are refilled at every Newton iteration.
/// [`LinearSolver`](super::LinearSolver) recognises the pattern by pointer identity and reuses
/// its symbolic work while the same `Arc` comes back.
pub struct SparsePattern {
    symbolic: SymbolicSparseColMat<usize>,
    /// Position of the diagonal entry of each column, if it is in the pattern.
    diagonal: Vec<Option<usize>>,
}

impl SparsePattern {
    /// Builds the pattern of an `n × n` matrix from `(row, col)` pairs, in any order and with
    /// any number of repetitions.
    ///
    /// # Panics
    /// If a row or column index is `≥ n`.
    pub fn new(n: usize, entries: impl IntoIterator<Item = (usize, usize)>) -> Self {
        // Sorted by (col, row): the CSC order. Sorting whole tuples gives the same result for
        // any thread count.
        let mut pairs: Vec<(usize, usize)> = entries
            .into_iter()
            .map(|(row, col)| {
                assert!(
                    row < n && col < n,
                    "entry ({row}, {col}) outside a {n}×{n} matrix"
                );
                (col, row)
            })
            .collect();
        pairs.par_sort_unstable();
        pairs.dedup();

        let mut col_ptr = vec![0; n + 1];
        for &(col, _) in &pairs {
            col_ptr[col + 1] += 1;
        }
        for j in 0..n {
            col_ptr[j + 1] += col_ptr[j];
        }
        let row_idx: Vec<usize> = pairs.iter().map(|&(_, row)| row).collect();
        let diagonal = (0..n)
            .map(|j| {
                let range = col_ptr[j]..col_ptr[j + 1];
                row_idx[range.clone()]
                    .binary_search(&j)
                    .ok()
                    .map(|k| range.start + k)
            })
            .collect();
        let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        Self { symbolic, diagonal }
    }

    /// Number of rows (= columns).
    pub fn n(&self) -> usize {
        self.diagonal.len()
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.row_idx().len()
    }

    /// Position of `(row, col)` in the value array, if it is in the pattern (binary search in
    /// the column).
    pub fn position(&self, row: usize, col: usize) -> Option<usize> {
        if col >= self.n() {
            return None;
        }
        let range = self.col_range(col);
        self.row_idx()[range.clone()]
            .binary_search(&row)
            .ok()
            .map(|k| range.start + k)
    }

    /// Column pointers: the entries of column `j` are at positions `col_ptr[j]..col_ptr[j + 1]`.
    pub fn col_ptr(&self) -> &[usize] {
        self.symbolic.col_ptr()
    }

    /// Row index of every stored entry, sorted within each column.
    pub fn row_idx(&self) -> &[usize] {
        self.symbolic.row_idx()
    }

    /// Positions of the entries of column `j`.
    pub(super) fn col_range(&self, j: usize) -> std::ops::Range<usize> {
        self.col_ptr()[j]..self.col_ptr()[j + 1]
    }

    /// Position of the diagonal entry `(i, i)`, if it is in the pattern.
    pub(super) fn diagonal_position(&self, i: usize) -> Option<usize> {
        self.diagonal[i]
    }

    /// The pattern as faer's symbolic matrix.
    pub(super) fn symbolic(&self) -> &SymbolicSparseColMat<usize> {
        &self.symbolic
    }
}

impl fmt::Debug for SparsePattern {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SparsePattern")
            .field("n", &self.n())
            .field("nnz", &self.nnz())
            .finish_non_exhaustive()
    }
}

/// A square sparse matrix on a shared [`SparsePattern`]: `values[k]` is the entry at row
/// `pattern.row_idx()[k]` of the column whose range contains `k`.
#[derive(Clone)]
pub struct SparseMatrix {
    /// The (shared) sparsity pattern.
    pub pattern: Arc<SparsePattern>,
    /// One value per pattern entry, in CSC order.
    pub values: Vec<f64>,
}

impl SparseMatrix {
    /// The zero matrix on `pattern`.
    pub fn zeros(pattern: Arc<SparsePattern>) -> Self {
        let values = vec![0.0; pattern.nnz()];
        Self { pattern, values }
    }

    /// Adds `v` to the entry `(row, col)`.
    ///
    /// # Panics
    /// If `(row, col)` is not in the pattern (an assembly bug: the pattern must contain every
    /// entry the assembly touches).
    pub fn add(&mut self, row: usize, col: usize, v: f64) {
        let Some(k) = self.pattern.position(row, col) else {
            panic!("entry ({row}, {col}) is not in the sparsity pattern");
        };
        self.values[k] += v;
    }

    /// `y = A x` or `y = Aᵀ x`.
    pub(super) fn mul_oriented(&self, x: &[f64], y: &mut [f64], orientation: Orientation) {
        match orientation {
            Orientation::Plain => self.mul_vec(x, y),
            Orientation::Transposed => self.mul_vec_transpose(x, y),
        }
    }

    /// `y = A x`.
    ///
    /// # Panics
    /// If `x` or `y` does not have length `n`.
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) {
        let n = self.check_lengths(x, y);
        y.fill(0.0);
        for j in 0..n {
            let xj = x[j];
            for k in self.pattern.col_range(j) {
                y[self.pattern.row_idx()[k]] += self.values[k] * xj;
            }
        }
    }

    /// `y = Aᵀ x`.
    ///
    /// # Panics
    /// If `x` or `y` does not have length `n`.
    pub fn mul_vec_transpose(&self, x: &[f64], y: &mut [f64]) {
        let n = self.check_lengths(x, y);
        for j in 0..n {
            y[j] = self
                .pattern
                .col_range(j)
                .map(|k| self.values[k] * x[self.pattern.row_idx()[k]])
                .sum();
        }
    }

    /// The diagonal (zero where the pattern has no diagonal entry).
    pub fn diagonal(&self) -> Vec<f64> {
        (0..self.pattern.n())
            .map(|i| {
                self.pattern
                    .diagonal_position(i)
                    .map_or(0.0, |k| self.values[k])
            })
            .collect()
    }

    /// Dense copy, for tests and debugging of small systems.
    pub fn to_dense(&self) -> nalgebra::DMatrix<f64> {
        let n = self.pattern.n();
        let mut dense = nalgebra::DMatrix::zeros(n, n);
        for j in 0..n {
            for k in self.pattern.col_range(j) {
                dense[(self.pattern.row_idx()[k], j)] = self.values[k];
            }
        }
        dense
    }

    /// `max |a_ij − a_ji| / max |a_ij|` (an entry missing from the pattern counts as zero);
    /// zero for the zero matrix.
    pub fn symmetry_error(&self) -> f64 {
        let p = &self.pattern;
        let mut max_entry = 0.0_f64;
        let mut max_diff = 0.0_f64;
        for j in 0..p.n() {
            for k in p.col_range(j) {
                let i = p.row_idx()[k];
                let mirror = p.position(j, i).map_or(0.0, |m| self.values[m]);
                max_entry = max_entry.max(self.values[k].abs());
                max_diff = max_diff.max((self.values[k] - mirror).abs());
            }
        }
        if max_entry > 0.0 {
            max_diff / max_entry
        } else {
            0.0
        }
    }

    /// The matrix as a faer view.
    pub(super) fn as_faer(&self) -> SparseColMatRef<'_, usize, f64> {
        SparseColMatRef::new(self.pattern.symbolic().as_ref(), &self.values)
    }

    /// Asserts that `x` and `y` have the matrix dimension and returns it.
    fn check_lengths(&self, x: &[f64], y: &[f64]) -> usize {
        let n = self.pattern.n();
        assert_eq!(x.len(), n, "input vector length");
        assert_eq!(y.len(), n, "output vector length");
        n
    }
}

impl fmt::Debug for SparseMatrix {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SparseMatrix")
            .field("pattern", &self.pattern)
            .finish_non_exhaustive()
    }
}
