//! Preconditioners of the Krylov solvers: identity, Jacobi, ILU(0), smoothed-aggregation
//! AMG and the u–p block preconditioner, with solves by `M` and by `Mᵀ` (for the transposed
//! systems of the adjoints).

use super::amg::{Amg, NearNullspace, STRENGTH_THRESHOLD, SWEEPS};
use super::block::{Block, BlockSplit};
use super::{LinearError, Orientation, SparseMatrix, SparsePattern};

/// Preconditioner of an iterative solver (in a scene file: `"identity"`, `"jacobi"`, `"ilu0"`,
/// the default, `"amg"` or `"block"`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Preconditioner {
    /// No preconditioning.
    Identity,
    /// Inverse of the diagonal (fails on a zero diagonal entry).
    Jacobi,
    /// Incomplete LU factorisation without fill-in: `L U` equals `A` on the pattern of `A`
    /// (needs every diagonal entry in the pattern; fails on a zero pivot).
    #[default]
    Ilu0,
    /// One V-cycle of smoothed-aggregation algebraic multigrid (see [`super::amg`]), with the
    /// rigid-body near-nullspace handed over by
    /// [`LinearSolver::set_near_nullspace`](super::LinearSolver::set_near_nullspace): an
    /// iteration count nearly independent of the mesh for elasticity-like systems.
    Amg,
    /// The block upper-triangular preconditioner of a coupled displacement–pressure system
    /// (see [`super::block`]): `M = [[Ã_uu, A_up], [0, S̃]]` with one AMG V-cycle for
    /// `Ã_uu⁻¹` and one for `S̃⁻¹`, `S̃ = A_pp + D^½ M̂ D^½` with `D = −diag(A_pu diag(A_uu)⁻¹ A_up)`
    /// and `M̂` the shape of the pressure mass matrix, the split handed
    /// over by [`LinearSolver::set_block_split`](super::LinearSolver::set_block_split). Not
    /// symmetric: for BiCGSTAB and GMRES.
    Block,
}

/// Marks a row that is not in the column currently being eliminated.
const UNSET: usize = usize::MAX;

/// Numeric data of a preconditioner, allocated once per pattern and refilled by
/// [`PrecondState::factorize`] for every matrix.
#[derive(Debug)]
pub(super) enum PrecondState {
    /// Nothing to store.
    Identity,
    /// `1 / a_ii`.
    Jacobi { inv_diag: Vec<f64> },
    /// The factors in the layout of `A`: the lower triangle with the diagonal is the lower
    /// factor `L`, the strict upper triangle is the unit upper factor `U` (`A ≈ L U`).
    Ilu0 {
        /// Position of each diagonal entry.
        diag: Vec<usize>,
        /// `L` and `U` (see above).
        factor: Vec<f64>,
        /// Row → position in the column being eliminated, or [`UNSET`].
        marker: Vec<usize>,
    },
    /// The multigrid hierarchy (built by [`PrecondState::factorize`]).
    Amg(Option<Amg>),
    /// The blocks and their preconditioners (built by [`PrecondState::factorize`]).
    Block(Option<Box<Block>>),
}

impl PrecondState {
    /// Allocates the storage for matrices on `pattern` (for ILU(0), checks that the diagonal
    /// is in the pattern).
    pub(super) fn new(kind: Preconditioner, pattern: &SparsePattern) -> Result<Self, LinearError> {
        let n = pattern.n();
        Ok(match kind {
            Preconditioner::Identity => Self::Identity,
            Preconditioner::Jacobi => Self::Jacobi {
                inv_diag: vec![0.0; n],
            },
            Preconditioner::Ilu0 => Self::Ilu0 {
                diag: (0..n)
                    .map(|i| {
                        pattern
                            .diagonal_position(i)
                            .ok_or(LinearError::MissingDiagonal { row: i })
                    })
                    .collect::<Result<_, _>>()?,
                factor: vec![0.0; pattern.nnz()],
                marker: vec![UNSET; n],
            },
            Preconditioner::Amg => Self::Amg(None),
            Preconditioner::Block => Self::Block(None),
        })
    }

    /// Computes the preconditioner of `a` (whose pattern is the one given to [`Self::new`]);
    /// only the AMG uses `near_nullspace`, and only the block preconditioner `block_split`
    /// (without which it fails with [`LinearError::NoBlockSplit`]).
    pub(super) fn factorize(
        &mut self,
        a: &SparseMatrix,
        near_nullspace: Option<&NearNullspace>,
        block_split: Option<&BlockSplit>,
    ) -> Result<(), LinearError> {
        match self {
            Self::Identity => Ok(()),
            Self::Jacobi { inv_diag } => {
                for (row, (inv, d)) in inv_diag.iter_mut().zip(a.diagonal()).enumerate() {
                    if d == 0.0 {
                        return Err(LinearError::ZeroPivot {
                            preconditioner: "Jacobi",
                            row,
                        });
                    }
                    *inv = d.recip();
                }
                Ok(())
            }
            Self::Ilu0 {
                diag,
                factor,
                marker,
            } => ilu0(a, diag, factor, marker),
            Self::Amg(hierarchy) => {
                // Free the old hierarchy before building the new one.
                *hierarchy = None;
                *hierarchy = Some(Amg::new(a, near_nullspace, STRENGTH_THRESHOLD, SWEEPS)?);
                Ok(())
            }
            Self::Block(blocks) => {
                *blocks = None;
                let split = block_split.ok_or(LinearError::NoBlockSplit)?;
                *blocks = Some(Box::new(Block::new(a, split)?));
                Ok(())
            }
        }
    }

    /// `z ← M⁻¹ z` (or `M⁻ᵀ z`).
    pub(super) fn solve_in_place(
        &self,
        pattern: &SparsePattern,
        orientation: Orientation,
        z: &mut [f64],
    ) {
        match self {
            Self::Identity => {}
            Self::Jacobi { inv_diag } => z.iter_mut().zip(inv_diag).for_each(|(z, d)| *z *= d),
            Self::Ilu0 { diag, factor, .. } => match orientation {
                Orientation::Plain => ilu_solve(pattern, diag, factor, z),
                Orientation::Transposed => ilu_solve_transpose(pattern, diag, factor, z),
            },
            Self::Amg(hierarchy) => hierarchy
                .as_ref()
                .expect("the hierarchy is built by `factorize`")
                .apply(orientation, z),
            Self::Block(blocks) => blocks
                .as_ref()
                .expect("the blocks are built by `factorize`")
                .apply(orientation, z),
        }
    }
}

/// ILU(0) in the compressed-column layout of `A`.
///
/// The classical row-oriented (IKJ) elimination, run on the columns of `A`, i.e. on the rows
/// of `B = Aᵀ`: it gives `B ≈ L̃ Ũ` (`L̃` unit lower, `Ũ` upper), hence `A ≈ Ũᵀ L̃ᵀ`, where `Ũᵀ`
/// is the lower triangle (with the diagonal) of the result in the layout of `A` and `L̃ᵀ` its
/// unit strict upper triangle. The ILU(0) conditions (`(L U)_ij = a_ij` on the pattern) are
/// invariant under transposition and determine the product uniquely, so this is the usual
/// ILU(0) with the diagonal carried by `L` instead of `U`.
fn ilu0(
    a: &SparseMatrix,
    diag: &[usize],
    factor: &mut [f64],
    marker: &mut [usize],
) -> Result<(), LinearError> {
    let p = &*a.pattern;
    let rows = p.row_idx();
    factor.copy_from_slice(&a.values);
    // Reset in case a previous factorisation stopped half-way on a zero pivot.
    marker.fill(UNSET);
    for j in 0..p.n() {
        let col = p.col_range(j);
        for k in col.clone() {
            marker[rows[k]] = k;
        }
        // Entries (i, j), i < j, in increasing i: b_ji ← b_ji / b_ii, then
        // b_jm ← b_jm − b_ji b_im for m > i where (m, j) is in the pattern.
        for k in col.start..diag[j] {
            let i = rows[k];
            let l = factor[k] / factor[diag[i]];
            factor[k] = l;
            for q in diag[i] + 1..p.col_ptr()[i + 1] {
                let target = marker[rows[q]];
                if target != UNSET {
                    factor[target] -= l * factor[q];
                }
            }
        }
        let pivot = factor[diag[j]];
        if pivot == 0.0 || !pivot.is_finite() {
            return Err(LinearError::ZeroPivot {
                preconditioner: "ILU(0)",
                row: j,
            });
        }
        for k in col {
            marker[rows[k]] = UNSET;
        }
    }
    Ok(())
}

/// `z ← U⁻¹ L⁻¹ z` (column-oriented forward and back substitution).
fn ilu_solve(p: &SparsePattern, diag: &[usize], factor: &[f64], z: &mut [f64]) {
    let rows = p.row_idx();
    for j in 0..p.n() {
        let zj = z[j] / factor[diag[j]];
        z[j] = zj;
        for k in diag[j] + 1..p.col_ptr()[j + 1] {
            z[rows[k]] -= factor[k] * zj;
        }
    }
    for j in (0..p.n()).rev() {
        let zj = z[j];
        for k in p.col_ptr()[j]..diag[j] {
            z[rows[k]] -= factor[k] * zj;
        }
    }
}

/// `z ← L⁻ᵀ U⁻ᵀ z` (row-oriented substitutions on the transposed factors).
fn ilu_solve_transpose(p: &SparsePattern, diag: &[usize], factor: &[f64], z: &mut [f64]) {
    let rows = p.row_idx();
    for j in 0..p.n() {
        let s: f64 = (p.col_ptr()[j]..diag[j])
            .map(|k| factor[k] * z[rows[k]])
            .sum();
        z[j] -= s;
    }
    for j in (0..p.n()).rev() {
        let s: f64 = (diag[j] + 1..p.col_ptr()[j + 1])
            .map(|k| factor[k] * z[rows[k]])
            .sum();
        z[j] = (z[j] - s) / factor[diag[j]];
    }
}
