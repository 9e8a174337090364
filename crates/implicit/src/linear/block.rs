//! Block preconditioner of the coupled displacement–pressure (u–p) systems:
//! [`Preconditioner::Block`](super::Preconditioner::Block).
//!
//! With the unknowns split into displacements `u` and pore pressures `p`, the tangent of a
//! coupled step is the 2 × 2 block matrix
//!
//! ```text
//! A = [ A_uu  A_up ]
//!     [ A_pu  A_pp ]
//! ```
//!
//! (`A_uu` the skeleton's stiffness, `A_up = −α Bᵀ`-like and `A_pu = α B`-like the Biot
//! couplings, `A_pp` the storage, the Darcy flow over the step and the pressure
//! stabilisation; see [`crate::flow`]). It is not symmetric, and near the undrained limit
//! (`Δt κ → 0`, no storage) `A_pp` is only the small stabilisation term. Preconditioners of
//! the whole matrix do not scale: on the Q1–Q1 systems of `block_tests` (3D, 6³ → 12³
//! elements) GMRES with ILU(0) needs 24 → 47 iterations, and with the AMG, which coarsens
//! displacements and pressures as one field, 57 → 893 in the undrained limit; with this
//! preconditioner 27 → 30.
//!
//! # The preconditioner
//!
//! Block upper-triangular,
//!
//! ```text
//! M = [ Ã_uu  A_up ]        M⁻¹ r:  z_p = S̃⁻¹ r_p,   z_u = Ã_uu⁻¹ (r_u − A_up z_p),
//!     [  0     S̃   ]
//! ```
//!
//! with `Ã_uu⁻¹` one V(2,2)-cycle of the smoothed-aggregation AMG ([`super::amg`]) of `A_uu`,
//! built with the rigid-body modes of the displacement unknowns, and `S̃⁻¹` one V(3,3)-cycle
//! ([`SCHUR_SWEEPS`], "Smoothing" below) of the same AMG with the constant near-nullspace and a
//! lower strength threshold ([`SCHUR_STRENGTH_THRESHOLD`], below) of the approximate Schur
//! complement
//!
//! ```text
//! S̃ = A_pp + D^½ M̂ D^½,    D = −diag(A_pu D_uu⁻¹ A_up),   D_uu = diag(A_uu),
//!                          M̂ = diag(M)^−½ M diag(M)^−½,
//! ```
//!
//! `M` the pressure mass matrix of the step ([`BlockSplit::with_pressure_mass`]; `S̃ = A_pp + D`
//! without one).
//!
//! With exact blocks (`Ã_uu = A_uu`, `S̃ = S = A_pp − A_pu A_uu⁻¹ A_up`) the right-preconditioned
//! operator is `A M⁻¹ = [[I, 0], [A_pu A_uu⁻¹, I]]`, whose minimal polynomial is `(λ − 1)²`:
//! GMRES converges in two iterations (Murphy, Golub & Wathen 2000; Ipsen 2001), and with
//! spectrally equivalent approximations in a number of iterations independent of the mesh
//! (Elman, Silvester & Wathen, *Finite Elements and Fast Iterative Solvers*, 2nd ed. 2014,
//! ch. 9). The upper-triangular form is the one that goes with right preconditioning (the lower
//! one with left preconditioning: `M_L⁻¹ A` is then the block-triangular product), and the
//! Krylov solvers here are right-preconditioned so that they monitor the true residual. For
//! coupled poromechanics the same block-triangular structure with an AMG on the mechanics and
//! a fixed-stress Schur approximation is the method of White, Castelletto & Tchelepi,
//! *Block-partitioned solvers for coupled poromechanics: a unified framework*, CMAME 303
//! (2016).
//!
//! **The Schur approximation.** The fixed-stress split adds to the pressure block the
//! (lumped) storage `α²/K_dr` that the skeleton's volume change contributes when the mean
//! stress is held fixed. `D = −diag(A_pu D_uu⁻¹ A_up)` is its algebraic counterpart: the coupling
//! of each pressure with itself through the skeleton, with the stiffness lumped to its
//! diagonal; it needs no material parameters, keeps the pattern of `A_pp`, and costs one pass
//! over the coupling blocks. The exact formula is used, so the sign convention of the fluid
//! rows does not matter: in loam `A_pu ≈ −A_upᵀ` and the term is added, making `S̃` a positive
//! augmentation of `A_pp` that dominates it in the undrained limit (where `S ≈ B A_uu⁻¹ Bᵀ`
//! is spectrally a mass matrix) and leaves it in the drained one (a Laplacian). The full sparse
//! product `A_pu D_uu⁻¹ A_up` was not chosen: with quadratic B-splines it couples pressures
//! four nodes apart (9³ neighbours in 3D against the 7³ of `A_pp`), and its storage and setup
//! would exceed the rest of the preconditioner.
//!
//! **Its shape.** `D` alone is a lumped approximation of the undrained `S`: it drops the
//! couplings of neighbouring pressures, which in a mass matrix are as large as the diagonal
//! (a row of the trilinear mass matrix sums to `(3/2)³` times its diagonal, of the quadratic
//! B-splines' to `(120/66)³`). `D^½ M̂ D^½` keeps `D` on the diagonal and gives the
//! off-diagonal entries the mass matrix's shape, `√(d_q d_r) M_qr / √(M_qq M_rr)`; it is
//! positive definite like `M`, needs no material parameter (the mass is weighted by the
//! stabilisation's `Vⁿ/G`, and only its ratios are used), and stays inside the pattern of
//! `A_pp` (`M` couples the nodes of one particle's stencil). In the drained limit the Darcy
//! Laplacian dominates `S̃` and the shape changes nothing. GMRES iterations per Newton
//! iteration in the undrained step, with `D` alone → with the shape (`docs/performance.md`,
//! *The Schur approximation's shape*): the 3D footing at 20³ cells 55 → 28; the 1 m cube at
//! 8³ cells 39 → 23 (linear shapes) and 91 → 41 (quadratic B-splines), and in its later
//! steps at `κ` = 1e-12 m²/(Pa·s) 38 → 23 and 85 → 40; Terzaghi's column (2D, quadratic
//! B-splines) 27 → 12, and 15.5 → 8 in the consolidation steps; the Q1–Q1 systems of
//! `block_tests` 27 → 19 (2D) and 33 → 18 (3D). Scaling the whole augmentation by 0.5 … 2 moved the counts by at most 15 %
//! (its optimum is near 1), and replacing `D` by one multiple of the mass diagonal changed
//! nothing. The approximation is close: on the undrained tangent of that quadratic cube at
//! 8³ cells (648 pressures, dense matrices) the eigenvalues of `S̃⁻¹ S` are real and lie in
//! [0.45, 1.0], and with both blocks solved exactly GMRES needs 14 iterations (5 in a step of
//! 5 s at `κ` = 1e-7). What the count loses beyond that is in the two V-cycles ("Smoothing").
//!
//! An AMG V-cycle with the constant near-nullspace rather than ILU(0) solves with `S̃`: on the
//! Q1–Q1 test systems of this module (`block_tests`) GMRES with ILU(0) on `S̃` needed 19 → 34
//! iterations from 16² to 32² elements in 2D at mobilities of 1e-8 … 1e-4 m²/(Pa·s), where the
//! pressure block is a Laplacian whose ILU(0) is not mesh-independent, and with the AMG 11 → 13;
//! in 3D (6³ → 12³ elements) 15 → 22 against 13 → 17 (13 → 13 with the threshold below). In
//! the undrained limit both are alike (`S̃` is then dominated by its augmentation).
//!
//! # The AMG of the Schur block
//!
//! The AMG drops the couplings weaker than `θ √(a_ii a_jj)` before it aggregates
//! ([`super::amg`], step 1). The displacement block keeps the elasticity value
//! `θ` = [`STRENGTH_THRESHOLD`] = 0.08; `S̃` uses [`SCHUR_STRENGTH_THRESHOLD`] = 0.02. In the
//! flow-dominated steps `S̃` is the Darcy Laplacian `Δt κ L`, and with linear shape
//! functions `L` is the trilinear stencil, whose couplings are all below 0.08 of the diagonal
//! away from the faces: edge neighbours 1/16, corners 1/32 and face neighbours 0 with exact
//! integration; 0.070, 0.045 and 0.033 with 2³ particles per cell at the quarter points. At
//! 0.08 every node two cells or more from the faces is left out of the aggregates, the V-cycle
//! is a Gauss–Seidel sweep there, and the GMRES count grew in proportion to the number of
//! cells per side. 0.02 is below every coupling of that stencil, so the fine level is cut
//! into the usual 3 × 3 × 3 aggregates, and it still drops the couplings across a mobility
//! contrast beyond about 20 (an edge coupling from a node in the less permeable material
//! `κ₁` to one on the interface with `κ₂ ≫ κ₁` is about `√(2 κ₁/κ₂)/16` of their
//! diagonals). Quadratic B-splines were hardly affected (their wider stencil has strong
//! couplings at 0.08): their counts moved by at most half an iteration per Newton
//! iteration.
//!
//! What was measured before the change, on the 1 m cube of
//! `benches/scenes/consolidation_block_3d_16.toml` with linear shape functions and steps of
//! 1,000 s (GMRES iterations per Newton iteration in the flow-dominated steps), with one
//! part of `M` made exact at a time: with `Ã_uu⁻¹` a sparse LU of `A_uu`, 12–13 (8³ cells) and
//! 26 (16³), no better than the V-cycle; with `S̃⁻¹` a sparse LU of `S̃`, 12–13 at both
//! sizes; with the exact Schur complement (`z_p` from an LU of the whole matrix), 12–13 at
//! both. So neither the displacement AMG nor the diagonal Schur approximation was the cause,
//! but the V-cycle of `S̃`; with the threshold at 0.02 (0 to 0.06 gave the same) the counts are
//! 12.5–15 at 8³, 16³, 24³ and 32³ cells, against 13.5–15, 25.5–26, 39–40 and 56.5–58.5
//! before (`docs/performance.md`). The undrained step, where `S̃` is the stabilisation and
//! its diagonal augmentation, takes about as many iterations as before (0–4 % more).
//!
//! # Smoothing
//!
//! Both cycles smooth more than the AMG's single sweep before and after each coarse
//! correction: `Ã_uu⁻¹` with [`SWEEPS`] = 2 Gauss–Seidel sweeps each way (as every
//! displacement hierarchy, [`super::amg`]), `S̃⁻¹` with [`SCHUR_SWEEPS`] = 3. In the undrained
//! limit `S̃` is mass-like: the constant near-nullspace holds its largest modes, not its
//! smallest, so its coarse correction does little and the sweeps carry the cycle. GMRES
//! iterations per Newton iteration on the quadratic cube of
//! `benches/scenes/consolidation_block_3d_16.toml` (16³ cells; the undrained step, then the
//! four steps of 5 s), and the wall time of `loam run` (2-core Intel Xeon,
//! `docs/performance.md`, *Two and three smoothing sweeps in the block preconditioner*):
//!
//! | sweeps `A_uu`, `S̃` | `κ` = 1e-12 m²/(Pa·s) | `κ` = 1e-4 | wall, 1e-12 / 1e-4 |
//! |---|---|---|---|
//! | 1, 1 (before) | 42.3; 42, 38.5, 38.5, 38.5 | 42.3; 24.5, 27, 32, 33 | 45.0 / 35.2 s |
//! | 2, 2 | 27; 27, 25, 25, 25 | 27; 17, 18.5, 22, 23 | 40.3 / 32.3 s |
//! | 2, 3 (now) | 23.3; 23, 21.5, 22, 22 | 23.3; 16, 18, 22, 23 | 38.9 / 32.2 s |
//! | 3, 3 | 22; 21.5, 20.5, 20.5, 20.5 | 22; 13.5, 15, 18, 19 | 42.3 / 32.1 s |
//!
//! With 2 and 3 the count spans 16–23.3 across the eight decades of mobility from 1e-12 to
//! 1e-4 (1.46×; it was 24.5–42.3, 1.73×), and the runs are 9–14 % faster: the sweeps cost
//! less than the iterations they save (a sweep of `S̃` costs about a quarter of one of
//! `A_uu`). A third sweep of `A_uu` lowers the drained count more than the undrained one
//! (1.63×) and costs about what it saves.
//!
//! # The transposed solve
//!
//! The adjoint systems `Aᵀ x = b` are preconditioned by `Mᵀ`, block lower-triangular:
//! `z_u = Ã_uu⁻ᵀ r_u`, `z_p = S̃⁻ᵀ (r_p − A_upᵀ z_u)`, with the transposed V-cycles
//! ([`super::amg`]). `Aᵀ M⁻ᵀ = (M⁻¹ A)ᵀ` is similar to `(A M⁻¹)ᵀ`, so it has the same
//! eigenvalues and minimal polynomial and the transposed solves converge like the plain ones.
//!
//! Everything is sequential and in a fixed order: the result has the same bits for any
//! thread count.

use std::sync::Arc;

use super::amg::{Amg, NearNullspace, STRENGTH_THRESHOLD, SWEEPS};
use super::{LinearError, Orientation, SparseMatrix, SparsePattern};

/// Name used in errors.
const NAME: &str = "block";

/// Strength threshold `θ` of the finest level of the AMG of `S̃` (module documentation, "The
/// AMG of the Schur block"); the displacement block keeps [`STRENGTH_THRESHOLD`].
pub const SCHUR_STRENGTH_THRESHOLD: f64 = 0.02;

/// Gauss–Seidel sweeps before and after each coarse correction of the V-cycle of `S̃`
/// (module documentation, "Smoothing"); the displacement block uses [`SWEEPS`].
pub const SCHUR_SWEEPS: usize = 3;

/// Which unknowns of a coupled system are displacements and which are pore pressures, and the
/// rigid-body modes of the displacements: what
/// [`Preconditioner::Block`](super::Preconditioner::Block) needs besides the
/// matrix, handed over by
/// [`LinearSolver::set_block_split`](super::LinearSolver::set_block_split).
#[derive(Clone, Debug, PartialEq)]
pub struct BlockSplit {
    /// Per unknown, `true` for a pressure.
    pressure: Vec<bool>,
    /// The rigid-body modes of the displacement unknowns, numbered in increasing order of
    /// their global index.
    displacement_modes: NearNullspace,
    /// The nonzero entries `(row, column, M_rc)` of the pressure mass matrix
    /// ([`BlockSplit::with_pressure_mass`]), numbered like the pressure unknowns (in
    /// increasing order of their global index); empty without one.
    pressure_mass: Vec<(usize, usize, f64)>,
}

impl BlockSplit {
    /// The split of the unknowns `unknowns[i] = (node, component)` of a `D`-dimensional coupled
    /// system: component `< D` a displacement, `== D` the pore pressure. `position(node)`
    /// gives the node's coordinates, for the rigid-body modes
    /// ([`NearNullspace::rigid_body`]) of the displacement unknowns.
    ///
    /// # Panics
    /// If a component is `> D`.
    pub fn new<const D: usize>(
        unknowns: &[(usize, usize)],
        position: impl Fn(usize) -> [f64; D],
    ) -> Self {
        let pressure: Vec<bool> = unknowns
            .iter()
            .map(|&(_, c)| {
                assert!(c <= D, "component {c} of a {D}-dimensional u–p system");
                c == D
            })
            .collect();
        let displacements: Vec<(usize, usize)> =
            unknowns.iter().copied().filter(|&(_, c)| c < D).collect();
        Self {
            pressure,
            displacement_modes: NearNullspace::rigid_body::<D>(&displacements, position),
            pressure_mass: Vec::new(),
        }
    }

    /// The split with the pressure mass matrix `M_qr = Σ_p w_p N_q(x_p) N_r(x_p)` of the
    /// system's pressure unknowns (its pressure–pressure entries are read, the rest of `mass`
    /// is ignored), which shapes the Schur approximation (module documentation, "The Schur
    /// approximation"): only its sparsity and the ratios `M_qr / √(M_qq M_rr)` are used, so the
    /// weights `w_p` need only be right relative to each other.
    ///
    /// # Panics
    /// If `mass` does not have one row per unknown of the split.
    pub fn with_pressure_mass(mut self, mass: &SparseMatrix) -> Self {
        let pattern = &*mass.pattern;
        assert_eq!(pattern.n(), self.len(), "pressure mass vs split unknowns");
        let mut local = vec![usize::MAX; self.len()];
        let mut count = 0;
        for (i, l) in local.iter_mut().enumerate() {
            if self.pressure[i] {
                *l = count;
                count += 1;
            }
        }
        self.pressure_mass = (0..pattern.n())
            .filter(|&j| self.pressure[j])
            .flat_map(|j| pattern.col_range(j).map(move |k| (j, k)))
            .filter_map(|(j, k)| {
                let i = pattern.row_idx()[k];
                let v = mass.values[k];
                (self.pressure[i] && v != 0.0).then_some((local[i], local[j], v))
            })
            .collect();
        self
    }

    /// Number of unknowns.
    pub fn len(&self) -> usize {
        self.pressure.len()
    }

    /// `true` when there is no unknown.
    pub fn is_empty(&self) -> bool {
        self.pressure.is_empty()
    }

    /// Whether unknown `i` is a pore pressure.
    pub fn is_pressure(&self, i: usize) -> bool {
        self.pressure[i]
    }
}

/// One diagonal block, `A_uu` or `S̃`, as a matrix of its own: its pattern, where each of its
/// entries is in `A` (`None` for a diagonal entry added to the pattern), and its AMG.
#[derive(Debug)]
struct DiagonalBlock {
    /// The block's values (the pattern is the restriction of `A`'s, with the diagonal).
    matrix: SparseMatrix,
    /// Per entry of `matrix`, its position in `A`'s values.
    source: Vec<Option<usize>>,
    /// `Ã⁻¹`: the AMG hierarchy (built by [`DiagonalBlock::factorize`]).
    inverse: Option<Amg>,
}

impl DiagonalBlock {
    /// The block of `a` on the unknowns `members` (increasing global indices), with its
    /// values copied from `a`; `local[i]` is the index of unknown `i` in its block.
    fn new(
        a: &SparseMatrix,
        members: &[usize],
        local: &[usize],
        in_block: impl Fn(usize) -> bool,
    ) -> Self {
        let p = &*a.pattern;
        let mut entries = Vec::new();
        for (lj, &j) in members.iter().enumerate() {
            entries.push((lj, lj));
            for k in p.col_range(j) {
                let i = p.row_idx()[k];
                if in_block(i) {
                    entries.push((local[i], lj));
                }
            }
        }
        let pattern = Arc::new(SparsePattern::new(members.len(), entries));
        let mut source = vec![None; pattern.nnz()];
        for (lj, &j) in members.iter().enumerate() {
            for k in p.col_range(j) {
                let i = p.row_idx()[k];
                if in_block(i) {
                    let position = pattern
                        .position(local[i], lj)
                        .expect("the block's pattern holds its entries");
                    source[position] = Some(k);
                }
            }
        }
        Self {
            matrix: SparseMatrix::zeros(pattern),
            source,
            inverse: None,
        }
    }

    /// Copies the block's values from `a`.
    fn fill(&mut self, a: &SparseMatrix) {
        for (v, s) in self.matrix.values.iter_mut().zip(&self.source) {
            *v = s.map_or(0.0, |k| a.values[k]);
        }
    }

    /// Adds the Schur approximation's augmentation `D^½ M̂ D^½` to the block (module
    /// documentation, "The Schur approximation"): `d` on the diagonal, and where the mass
    /// entries `mass` (block numbering) are given and `d_q, d_r, M_qq, M_rr > 0`,
    /// `√(d_q d_r) M_qr / √(M_qq M_rr)` off it (entries outside the block's pattern are
    /// dropped).
    fn augment(&mut self, d: &[f64], mass: &[(usize, usize, f64)]) {
        let pattern = &*self.matrix.pattern;
        for (j, d_j) in d.iter().enumerate() {
            let k = pattern
                .diagonal_position(j)
                .expect("the block's pattern holds its diagonal");
            self.matrix.values[k] += d_j;
        }
        let mut diagonal = vec![0.0; d.len()];
        for &(i, j, m) in mass {
            if i == j {
                diagonal[i] = m;
            }
        }
        for &(i, j, m) in mass {
            let (mi, mj) = (diagonal[i], diagonal[j]);
            if i == j || mi <= 0.0 || mj <= 0.0 || d[i] <= 0.0 || d[j] <= 0.0 {
                continue;
            }
            if let Some(k) = pattern.position(i, j) {
                self.matrix.values[k] += (d[i] * d[j]).sqrt() * m / (mi * mj).sqrt();
            }
        }
    }

    /// Builds the AMG of the block's values with `near_nullspace` (the constant vector when
    /// `None`), the strength threshold `theta` and `sweeps` smoothing sweeps.
    fn factorize(
        &mut self,
        near_nullspace: Option<&NearNullspace>,
        theta: f64,
        sweeps: usize,
    ) -> Result<(), LinearError> {
        self.inverse = None;
        self.inverse = Some(Amg::new(&self.matrix, near_nullspace, theta, sweeps)?);
        Ok(())
    }

    /// `z ← Ã⁻¹ z` (or `Ã⁻ᵀ z`).
    fn solve_in_place(&self, orientation: Orientation, z: &mut [f64]) {
        self.inverse
            .as_ref()
            .expect("the hierarchy is built by `factorize`")
            .apply(orientation, z);
    }
}

/// The block preconditioner of one matrix (module documentation).
#[derive(Debug)]
pub(super) struct Block {
    /// Global indices of the displacement unknowns, increasing.
    u: Vec<usize>,
    /// Global indices of the pressure unknowns, increasing.
    p: Vec<usize>,
    /// `A_uu` and its AMG (rigid-body near-nullspace).
    uu: DiagonalBlock,
    /// `S̃` and its AMG (constant near-nullspace).
    schur: DiagonalBlock,
    /// `A_up` by columns: per pressure unknown (local index), the local indices of the
    /// displacement rows coupled with it and the entries.
    up: Vec<Vec<(usize, f64)>>,
}

impl Block {
    /// Builds the preconditioner of `a` for the unknowns split by `split`.
    ///
    /// # Panics
    /// If `split` does not have the size of `a`.
    pub(super) fn new(a: &SparseMatrix, split: &BlockSplit) -> Result<Self, LinearError> {
        let n = a.pattern.n();
        assert_eq!(split.len(), n, "block split vs matrix unknowns");
        let (p, u): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| split.is_pressure(i));
        let mut local = vec![0; n];
        for block in [&u, &p] {
            for (l, &i) in block.iter().enumerate() {
                local[i] = l;
            }
        }
        let is_u = |i: usize| !split.is_pressure(i);
        let is_p = |i: usize| split.is_pressure(i);
        let mut uu = DiagonalBlock::new(a, &u, &local, is_u);
        let mut schur = DiagonalBlock::new(a, &p, &local, is_p);
        let pat = &*a.pattern;
        let up: Vec<Vec<(usize, f64)>> = (p.iter())
            .map(|&j| {
                (pat.col_range(j))
                    .filter(|&k| is_u(pat.row_idx()[k]))
                    .map(|k| (local[pat.row_idx()[k]], a.values[k]))
                    .collect()
            })
            .collect();

        uu.fill(a);
        let diag_uu = uu.matrix.diagonal();
        if let Some(row) = diag_uu.iter().position(|&d| d == 0.0) {
            return Err(LinearError::ZeroPivot {
                preconditioner: NAME,
                row: u[row],
            });
        }
        // The augmentation's diagonal d = −diag(A_pu D_uu⁻¹ A_up):
        // (A_pu D⁻¹ A_up)_jj = Σ_k a_jk a_kj / a_kk over the displacements k coupled with j.
        let augmentation: Vec<f64> = (p.iter().zip(&up))
            .map(|(&j, column)| {
                -(column.iter())
                    .filter_map(|&(lk, a_kj)| {
                        pat.position(j, u[lk])
                            .map(|jk| a.values[jk] * a_kj / diag_uu[lk])
                    })
                    .sum::<f64>()
            })
            .collect();
        schur.fill(a);
        schur.augment(&augmentation, &split.pressure_mass);
        uu.factorize(Some(&split.displacement_modes), STRENGTH_THRESHOLD, SWEEPS)?;
        schur.factorize(None, SCHUR_STRENGTH_THRESHOLD, SCHUR_SWEEPS)?;
        Ok(Self {
            u,
            p,
            uu,
            schur,
            up,
        })
    }

    /// `z ← M⁻¹ z` (or `M⁻ᵀ z`; module documentation).
    pub(super) fn apply(&self, orientation: Orientation, z: &mut [f64]) {
        let mut zu: Vec<f64> = self.u.iter().map(|&i| z[i]).collect();
        let mut zp: Vec<f64> = self.p.iter().map(|&i| z[i]).collect();
        match orientation {
            Orientation::Plain => {
                self.schur.solve_in_place(orientation, &mut zp);
                // z_u ← r_u − A_up z_p, column by column of A_up.
                for (entries, &x) in self.up.iter().zip(&zp) {
                    for &(l, a_lj) in entries {
                        zu[l] -= a_lj * x;
                    }
                }
                self.uu.solve_in_place(orientation, &mut zu);
            }
            Orientation::Transposed => {
                self.uu.solve_in_place(orientation, &mut zu);
                // z_p ← r_p − A_upᵀ z_u: row j of A_upᵀ is column j of A_up.
                for (entries, zp) in self.up.iter().zip(zp.iter_mut()) {
                    *zp -= (entries.iter()).map(|&(l, a_lj)| a_lj * zu[l]).sum::<f64>();
                }
                self.schur.solve_in_place(orientation, &mut zp);
            }
        }
        for (&i, v) in self.u.iter().zip(zu) {
            z[i] = v;
        }
        for (&i, v) in self.p.iter().zip(zp) {
            z[i] = v;
        }
    }
}
