//! Smoothed-aggregation algebraic multigrid (Vaněk, Mandel & Brezina 1996), used as the
//! preconditioner [`Preconditioner::Amg`](super::Preconditioner::Amg) of CG and BiCGSTAB for
//! the displacement (elasticity) systems of 3D implicit runs, where ILU(0) and Jacobi need a
//! number of iterations that grows with the mesh.
//!
//! It is written here because faer has Krylov solvers and a matrix-free preconditioner
//! interface but no multigrid, and the Rust crates that offer AMG are young 0.x releases that
//! have not been shown to work on these systems.
//!
//! # Setup, one level at a time (`A₀ = A`)
//!
//! 1. **Strength of connection on nodes.** The unknowns come in node blocks (the components of
//!    one grid node that are free; a node on a slip wall has fewer). With `s_IJ = ‖A_IJ‖_F`,
//!    the Frobenius norm of the block coupling nodes `I` and `J` over the components present,
//!    `J` is strongly connected to `I` on level `l` when `s_IJ > θ_l √(s_II s_JJ)`,
//!    symmetrised (`I ~ J` when either direction is strong), with `θ_l = θ 2^(−l)` and
//!    `θ` = [`STRENGTH_THRESHOLD`] = 0.08 (Vaněk, Mandel & Brezina's values). On the finest
//!    level it drops the couplings that are weak against both diagonals (the far corners of wide
//!    MPM stencils, contacts with a much softer material) and keeps the rest. It halves per
//!    level because a Galerkin operator spreads a node's coupling over more neighbours: a
//!    coarse 3D node couples with about 26 others at some 0.06 of the diagonal each, so a
//!    fixed 0.08 leaves most coarse nodes without a strong neighbour and hence without a
//!    coarse correction (measured on a 32³-element cube: 815 of 1,398 second-level nodes,
//!    and CG iterations growing from 12 to 31 between 8³ and 32³ elements; 12 throughout with
//!    the halving). `θ` is a parameter of the setup: the pressure Schur block of the u–p
//!    preconditioner, a scalar Laplacian whose trilinear stencil has no coupling above 0.08
//!    of the diagonal, uses a lower one ([`super::block`]).
//! 2. **Aggregation** (the greedy phases of Vaněk et al.): (1) every node whose strong
//!    neighbours are all unaggregated forms an aggregate with them; (2) every node left joins
//!    the phase-1 aggregate of its strongest aggregated neighbour; (3) the nodes still left
//!    form aggregates with their unaggregated strong neighbours. A node without strong
//!    neighbours stays out of every aggregate: its coupling is weak, and the smoother alone
//!    reduces its error.
//! 3. **Tentative prolongator `T`.** The near-nullspace `B` (`n × m`: the rigid-body modes,
//!    see [`NearNullspace`]) is split by aggregates; each block `B_a = Q_a R_a` is factored by a
//!    modified Gram–Schmidt with re-orthogonalisation that drops the columns dependent on the
//!    previous ones (a single 3D node has three independent modes out of six). `T` holds the
//!    orthonormal `Q_a` as block columns, and the coarse near-nullspace is `B_c = [R_a]`, so
//!    `T B_c = B` on the aggregated unknowns: the coarse space holds the rigid-body modes
//!    exactly.
//! 4. **Smoothed prolongator** `P = (I − ω D⁻¹ A) T` with `D = diag(A)` and
//!    `ω = 4 / (3 ρ(D⁻¹ A))`, where `ρ` is estimated by [`POWER_ITERATIONS`] power iterations
//!    from a fixed pseudo-random start vector (deterministic) in the norm weighted by `|D|`.
//! 5. **Galerkin coarse operator** `A_c = Pᵀ A P` (faer's sparse–sparse products, sequential).
//!
//! Levels are added until the coarse system has at most [`COARSE_SIZE`] = 500 unknowns (its
//! dense LU then costs `(2/3) 500³ ≈ 8·10⁷` flops, a few milliseconds, comparable with one
//! smoothing sweep of a fine 3D level with 10⁵ unknowns), [`MAX_LEVELS`] is reached or the
//! aggregation stops reducing the size. The coarsest system is solved by a dense LU with
//! partial pivoting (faer).
//!
//! # What it buys
//!
//! On the linear-elastic test systems of this module (Q1 elements, a clamped face) CG+AMG
//! needs 8–9 iterations to a relative residual of 1e-8 from 528 to 19,152 unknowns (10–13
//! from 528 to 103,488 with one sweep per cycle), where CG+ILU(0) needs 21–80. On an MPM
//! tangent (quadratic B-splines, 2³ particles per cell, a block under gravity; one sweep per
//! cycle) it needed about 110 at both 3,255 and 18,399 unknowns, against 28 and
//! 51 for ILU(0): the nodes at the free surface whose particle support is a small fraction of
//! a cell ([`ImplicitConfig::min_node_support`](crate::ImplicitConfig::min_node_support))
//! carry low-energy local modes that neither the rigid-body coarse space nor a point smoother
//! reduces (with that threshold at 1e-2 of a cell instead of 1e-4 the count falls to 30).
//! The count does not grow with the mesh, so the AMG overtakes ILU(0) on large 3D runs.
//!
//! # Application: a V-cycle
//!
//! `z = M⁻¹ r` is one V(ν,ν)-cycle from a zero guess: `ν` forward Gauss–Seidel sweeps on each
//! level before the coarse correction `x ← x + P A_c⁻¹ Pᵀ (b − A x)` (recursively) and `ν`
//! backward sweeps after it. For a symmetric positive definite `A` the backward sweep is the
//! adjoint of the forward one and `A_c` is symmetric positive definite, so `M⁻¹` is symmetric
//! positive definite and serves CG. Each sweep is a contraction in the energy norm, so the
//! cycle's error propagator `E_ν` satisfies `‖E_(ν+1)‖_A ≤ ‖E_ν‖_A`: more sweeps never slow
//! the convergence, they only cost more per cycle.
//!
//! The transpose `M⁻ᵀ` (adjoint systems) is the same cycle on the transposed operators
//! `Aᵀ, A_cᵀ, …` with the same `P`: from the error propagator (here with `ν = 1`)
//! `E = (I − (D+U)⁻¹A)(I − P A_c⁻¹ Pᵀ A)(I − (D+L)⁻¹A)` and `M⁻¹ = (I − E) A⁻¹` follows
//! `M⁻ᵀ = (I − E′) A⁻ᵀ` with `E′ = (I − (D+Lᵀ)⁻¹Aᵀ)(I − P A_c⁻ᵀ Pᵀ Aᵀ)(I − (D+Uᵀ)⁻¹Aᵀ)`, and
//! `D + Uᵀ`, `D + Lᵀ` are the lower and upper triangles of `Aᵀ`: forward Gauss–Seidel on `Aᵀ`
//! before, backward after (`ν` of each for a V(ν,ν)-cycle).
//!
//! `ν` is a parameter of the hierarchy. The displacement systems use [`SWEEPS`] = 2: MPM
//! stiffness matrices with quadratic B-splines couple nodes two cells apart (5^D stencils),
//! and one sweep leaves much of the error the coarse space does not hold. CG iterations to
//! 1e-8 and wall time of `loam run` (2-core Intel Xeon; `docs/performance.md`, *Two and
//! three smoothing sweeps in the block preconditioner*), one sweep → two: a 1 m cube under
//! its own weight at 32³ cells, linear shape functions, 12 → 9 (4.20 → 4.16 s); the same at
//! 16³ cells with quadratic B-splines, 23 → 16 (2.62 → 2.56 s); the Hencky block of
//! `benches/scenes/hencky_block_3d_27k.toml` (a free surface, ten load steps) with CG+AMG,
//! 22.5–23.5 → 15.5–16 per Newton iteration (36.4 → 35.6 s). In the u–p block preconditioner
//! ([`super::block`]) the effect is larger, because the displacement cycle's error is
//! amplified there by the Schur block's.
//!
//! Everything runs sequentially in a fixed order (no hash-map iteration, no parallel
//! reduction), so the preconditioner has the same bits for any thread count.

use std::collections::BTreeMap;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting::{factor, solve};
use faer::perm::PermRef;
use faer::sparse::linalg::matmul::sparse_sparse_matmul;
use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat};
use faer::{Mat, MatMut};

use super::{LinearError, Orientation, PAR, SparseMatrix};

/// Strength threshold `θ` of the finest level: node `J` is strongly connected to node `I` on
/// level `l` when `‖A_IJ‖_F > θ 2^(−l) √(‖A_II‖_F ‖A_JJ‖_F)`.
pub const STRENGTH_THRESHOLD: f64 = 0.08;

/// Gauss–Seidel sweeps `ν` before and after each coarse correction of the V-cycle of the
/// displacement (elasticity) systems (module documentation, "Application: a V-cycle").
pub const SWEEPS: usize = 2;

/// Largest number of unknowns of the coarsest level, solved by a dense LU.
pub const COARSE_SIZE: usize = 500;

/// Largest number of levels, the coarsest included.
pub const MAX_LEVELS: usize = 10;

/// Power iterations for the estimate of `ρ(D⁻¹ A)` in the prolongator smoothing weight
/// `ω = 4 / (3 ρ)`. Power iteration approaches `ρ` from below; `ω` only sets how much of the
/// high-frequency part of `T` the smoothing removes, and a few per cent on `ρ` does not change
/// the convergence rate.
pub const POWER_ITERATIONS: usize = 15;

/// A column of the local near-nullspace block whose norm falls below this fraction of its
/// original norm after orthogonalisation against the previous ones is dependent and dropped.
const DROP_TOLERANCE: f64 = 1e-10;

/// An unknown that belongs to no aggregate (or a node without a strong neighbour).
const NONE: usize = usize::MAX;

/// Name used in errors.
const NAME: &str = "AMG";

/// The near-nullspace of a matrix for the AMG preconditioner: which unknowns belong to the
/// same node, and `m` vectors `B = [b₁ … b_m]` (`n × m`) on which the matrix is nearly zero:
/// for elasticity, the rigid-body modes (`A B ≈ 0` away from the supports).
#[derive(Clone, Debug, PartialEq)]
pub struct NearNullspace {
    /// Node of every unknown, numbered `0 .. nodes` in order of first appearance.
    node: Vec<usize>,
    /// Number of vectors `m`.
    modes: usize,
    /// `B`, row-major: `values[i m + k]` is entry `i` of vector `k`.
    values: Vec<f64>,
}

impl NearNullspace {
    /// The rigid-body modes of a displacement field in `D` dimensions: the `D` translations
    /// `t_a(x) = e_a` and the `D (D − 1) / 2` infinitesimal rotations
    /// `r_ab(x) = ((x_a − c_a) e_b − (x_b − c_b) e_a) / ℓ` (`a < b`; in 2D the in-plane rotation,
    /// in 3D the rotations about the three axes), restricted to the unknowns.
    ///
    /// `unknowns[i] = (node, component)` names unknown `i` (any node keys: unknowns with the
    /// same key form a block); `position(node)` gives the node's coordinates. The rotations are
    /// centred at the mean position `c` of the unknowns and divided by the root-mean-square
    /// distance `ℓ` from it, so every mode is of order one whatever the units and the origin.
    ///
    /// # Panics
    /// If a component is `≥ D`.
    pub fn rigid_body<const D: usize>(
        unknowns: &[(usize, usize)],
        position: impl Fn(usize) -> [f64; D],
    ) -> Self {
        let mut ids = BTreeMap::new();
        let node = unknowns
            .iter()
            .map(|&(key, c)| {
                assert!(c < D, "component {c} of a {D}-dimensional displacement");
                let next = ids.len();
                *ids.entry(key).or_insert(next)
            })
            .collect();
        let x: Vec<[f64; D]> = unknowns.iter().map(|&(key, _)| position(key)).collect();
        let count = x.len().max(1) as f64;
        let centre: [f64; D] = std::array::from_fn(|a| x.iter().map(|p| p[a]).sum::<f64>() / count);
        let spread = (x.iter())
            .map(|p| (0..D).map(|a| (p[a] - centre[a]).powi(2)).sum::<f64>())
            .sum::<f64>()
            / count;
        let scale = if spread > 0.0 { spread.sqrt() } else { 1.0 };
        let planes: Vec<(usize, usize)> = (0..D)
            .flat_map(|a| (a + 1..D).map(move |b| (a, b)))
            .collect();
        let modes = D + planes.len();
        let mut values = Vec::with_capacity(unknowns.len() * modes);
        for (&(_, c), p) in unknowns.iter().zip(&x) {
            values.extend((0..D).map(|a| if a == c { 1.0 } else { 0.0 }));
            values.extend(planes.iter().map(|&(a, b)| {
                if c == b {
                    (p[a] - centre[a]) / scale
                } else if c == a {
                    -(p[b] - centre[b]) / scale
                } else {
                    0.0
                }
            }));
        }
        Self {
            node,
            modes,
            values,
        }
    }

    /// The constant vector, every unknown its own node: the near-nullspace of a scalar
    /// problem, used when none is given.
    pub fn constant(n: usize) -> Self {
        Self {
            node: (0..n).collect(),
            modes: 1,
            values: vec![1.0; n],
        }
    }

    /// Number of unknowns `n`.
    pub fn len(&self) -> usize {
        self.node.len()
    }

    /// `true` when there is no unknown.
    pub fn is_empty(&self) -> bool {
        self.node.is_empty()
    }

    /// Number of vectors `m`.
    pub fn modes(&self) -> usize {
        self.modes
    }

    /// Entry `i` of vector `k`.
    pub fn value(&self, i: usize, k: usize) -> f64 {
        self.values[i * self.modes + k]
    }
}

/// One level above the coarsest: its operator (both ways round, for row access in the
/// Gauss–Seidel sweeps of `A` and of `Aᵀ`), the inverse diagonal and the prolongator from the
/// next level.
#[derive(Debug)]
struct Level {
    /// `A` (compressed columns): column `i` is row `i` of `Aᵀ`.
    a: SparseColMat<usize, f64>,
    /// `Aᵀ` (compressed columns): column `i` is row `i` of `A`.
    at: SparseColMat<usize, f64>,
    /// `1 / a_ii`.
    inv_diag: Vec<f64>,
    /// Smoothed prolongator `P` (this level × next level).
    p: SparseColMat<usize, f64>,
}

impl Level {
    /// The row-access form (column `i` = row `i`) of the operator applied: `A` or `Aᵀ`.
    fn rows(&self, orientation: Orientation) -> SparseColMatRef<'_, usize, f64> {
        match orientation {
            Orientation::Plain => self.at.as_ref(),
            Orientation::Transposed => self.a.as_ref(),
        }
    }
}

/// Dense LU with partial pivoting of the coarsest operator, `A_c = Pᵀ L U`.
#[derive(Debug)]
struct CoarseLu {
    /// `L` (unit, strictly lower part) and `U` (upper part) in one matrix.
    lu: Mat<f64>,
    /// Row permutation and its inverse.
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
}

/// A smoothed-aggregation hierarchy of one matrix, applied as a V-cycle (see the module
/// documentation).
#[derive(Debug)]
pub(super) struct Amg {
    levels: Vec<Level>,
    coarse: CoarseLu,
    /// Gauss–Seidel sweeps before and after each coarse correction.
    sweeps: usize,
}

impl Amg {
    /// Builds the hierarchy of `a` with `near_nullspace` (the constant vector, unknown by
    /// unknown, when `None`) and the strength threshold `theta` of the finest level
    /// ([`STRENGTH_THRESHOLD`] for the displacement systems; module documentation, step 1),
    /// to be applied as a V(`sweeps`, `sweeps`)-cycle ([`SWEEPS`] for the displacement
    /// systems; module documentation, "Application: a V-cycle").
    ///
    /// # Panics
    /// If `near_nullspace` does not have the size of `a`, or `sweeps` is zero.
    pub(super) fn new(
        a: &SparseMatrix,
        near_nullspace: Option<&NearNullspace>,
        theta: f64,
        sweeps: usize,
    ) -> Result<Self, LinearError> {
        assert!(sweeps > 0, "a V-cycle needs at least one smoothing sweep");
        let n = a.pattern.n();
        let fallback;
        let near_nullspace = match near_nullspace {
            Some(ns) => ns,
            None => {
                fallback = NearNullspace::constant(n);
                &fallback
            }
        };
        assert_eq!(near_nullspace.len(), n, "near-nullspace vs matrix unknowns");
        let mut op = SparseColMat::new(a.pattern.symbolic().clone(), a.values.clone());
        let mut ns = near_nullspace.clone();
        let mut levels = Vec::new();
        while op.nrows() > COARSE_SIZE && levels.len() + 1 < MAX_LEVELS {
            let at = op.as_ref().transpose().to_col_major().map_err(backend)?;
            let theta_l = theta * 0.5f64.powi(levels.len() as i32);
            let graph = strong_graph(at.as_ref(), &ns.node, theta_l);
            let (agg, count) = aggregate(&graph);
            let (t, coarse_ns) = tentative(&agg, count, &ns);
            if t.ncols() >= op.nrows() {
                break;
            }
            let inv_diag = inverse_diagonal(op.as_ref())?;
            let p = smooth_prolongator(op.as_ref(), at.as_ref(), &inv_diag, t)?;
            let coarse_op = galerkin(op.as_ref(), p.as_ref())?;
            levels.push(Level {
                a: std::mem::replace(&mut op, coarse_op),
                at,
                inv_diag,
                p,
            });
            ns = coarse_ns;
        }
        let coarse = CoarseLu::new(op.as_ref())?;
        Ok(Self {
            levels,
            coarse,
            sweeps,
        })
    }

    /// `z ← M⁻¹ z` (or `M⁻ᵀ z`): one V-cycle from a zero guess.
    pub(super) fn apply(&self, orientation: Orientation, z: &mut [f64]) {
        let x = self.cycle(0, orientation, z);
        z.copy_from_slice(&x);
    }

    /// The V-cycle from level `l` down for the right-hand side `b`.
    fn cycle(&self, l: usize, orientation: Orientation, b: &[f64]) -> Vec<f64> {
        let Some(level) = self.levels.get(l) else {
            return self.coarse.solve(orientation, b);
        };
        let rows = level.rows(orientation);
        let mut x = vec![0.0; b.len()];
        for _ in 0..self.sweeps {
            gauss_seidel(rows, &level.inv_diag, b, &mut x, Sweep::Forward);
        }
        let p = level.p.as_ref();
        let r: Vec<f64> = (0..b.len()).map(|i| b[i] - row_dot(rows, i, &x)).collect();
        let r_c: Vec<f64> = (0..p.ncols()).map(|j| row_dot(p, j, &r)).collect();
        let x_c = self.cycle(l + 1, orientation, &r_c);
        for (j, xj) in x_c.iter().enumerate() {
            for (i, &pij) in p.row_idx_of_col(j).zip(p.val_of_col(j)) {
                x[i] += pij * xj;
            }
        }
        for _ in 0..self.sweeps {
            gauss_seidel(rows, &level.inv_diag, b, &mut x, Sweep::Backward);
        }
        x
    }
}

/// A faer failure unrelated to the values (out of memory, index overflow).
fn backend(e: impl std::fmt::Display) -> LinearError {
    LinearError::Backend {
        method: NAME,
        message: e.to_string(),
    }
}

/// `Σ_k m_ik x_k` for the matrix `M` whose row `i` is column `i` of `rows`.
fn row_dot(rows: SparseColMatRef<'_, usize, f64>, i: usize, x: &[f64]) -> f64 {
    (rows.row_idx_of_col(i).zip(rows.val_of_col(i)))
        .map(|(k, v)| v * x[k])
        .sum()
}

/// Direction of a Gauss–Seidel sweep.
#[derive(Clone, Copy)]
enum Sweep {
    Forward,
    Backward,
}

/// One Gauss–Seidel sweep on `M x = b` (row `i` of `M` is column `i` of `rows`):
/// `x_i ← x_i + (b_i − Σ_k m_ik x_k) / m_ii` for `i` increasing or decreasing.
fn gauss_seidel(
    rows: SparseColMatRef<'_, usize, f64>,
    inv_diag: &[f64],
    b: &[f64],
    x: &mut [f64],
    sweep: Sweep,
) {
    let mut relax = |i: usize| x[i] += (b[i] - row_dot(rows, i, x)) * inv_diag[i];
    match sweep {
        Sweep::Forward => (0..b.len()).for_each(&mut relax),
        Sweep::Backward => (0..b.len()).rev().for_each(&mut relax),
    }
}

/// `1 / a_ii` of every row; a zero (or missing) diagonal entry is a zero pivot.
fn inverse_diagonal(a: SparseColMatRef<'_, usize, f64>) -> Result<Vec<f64>, LinearError> {
    (0..a.ncols())
        .map(|j| {
            let d = (a.row_idx_of_col(j).zip(a.val_of_col(j)))
                .find(|&(i, _)| i == j)
                .map_or(0.0, |(_, &v)| v);
            if d == 0.0 {
                Err(LinearError::ZeroPivot {
                    preconditioner: NAME,
                    row: j,
                })
            } else {
                Ok(d.recip())
            }
        })
        .collect()
}

/// Symmetric graph of the strong node couplings, with a strength per edge.
#[derive(Debug)]
struct StrongGraph {
    /// The neighbours of node `I` are `neighbour[start[I] .. start[I + 1]]`.
    start: Vec<usize>,
    /// `(J, strength)`, sorted by `J`; strength `s_IJ² / (s_II s_JJ)`, the larger of the two
    /// directions.
    neighbour: Vec<(usize, f64)>,
}

impl StrongGraph {
    fn nodes(&self) -> usize {
        self.start.len() - 1
    }

    fn neighbours(&self, i: usize) -> &[(usize, f64)] {
        &self.neighbour[self.start[i]..self.start[i + 1]]
    }
}

/// The unknowns of every node, in increasing order (`nodes` = 1 + the largest node index).
fn node_unknowns(node: &[usize]) -> (Vec<usize>, Vec<usize>) {
    let nodes = node.iter().max().map_or(0, |&m| m + 1);
    let mut start = vec![0; nodes + 1];
    for &k in node {
        start[k + 1] += 1;
    }
    for k in 0..nodes {
        start[k + 1] += start[k];
    }
    let mut next = start.clone();
    let mut unknowns = vec![0; node.len()];
    for (i, &k) in node.iter().enumerate() {
        unknowns[next[k]] = i;
        next[k] += 1;
    }
    (start, unknowns)
}

/// The strong couplings (module documentation, step 1) of the nodes `node[i]` of the
/// unknowns; `rows` is `A` in row-access form.
fn strong_graph(rows: SparseColMatRef<'_, usize, f64>, node: &[usize], theta: f64) -> StrongGraph {
    let (start, unknowns) = node_unknowns(node);
    let nodes = start.len() - 1;
    // Node matrix S² (s_IJ² = Σ a_ij² over i ∈ I, j ∈ J), row by row; `seen[J] = I` once
    // node J is in row I.
    let mut acc = vec![0.0; nodes];
    let mut seen = vec![NONE; nodes];
    let mut touched = Vec::new();
    let mut s2: Vec<Vec<(usize, f64)>> = Vec::with_capacity(nodes);
    let mut diag = vec![0.0; nodes];
    for big_i in 0..nodes {
        for &i in &unknowns[start[big_i]..start[big_i + 1]] {
            for (j, v) in rows.row_idx_of_col(i).zip(rows.val_of_col(i)) {
                let big_j = node[j];
                if seen[big_j] != big_i {
                    seen[big_j] = big_i;
                    touched.push(big_j);
                }
                acc[big_j] += v * v;
            }
        }
        touched.sort_unstable();
        diag[big_i] = acc[big_i];
        s2.push(touched.iter().map(|&j| (j, acc[j])).collect());
        touched.iter().for_each(|&j| acc[j] = 0.0);
        touched.clear();
    }
    // s_IJ > θ √(s_II s_JJ)  ⇔  s_IJ² / √(s_II² s_JJ²) > θ².
    let mut edges = Vec::new();
    for (big_i, row) in s2.iter().enumerate() {
        for &(big_j, v) in row {
            let scale = (diag[big_i] * diag[big_j]).sqrt();
            if big_j != big_i && scale > 0.0 && v > theta * theta * scale {
                let strength = v / scale;
                edges.push((big_i, big_j, strength));
                edges.push((big_j, big_i, strength));
            }
        }
    }
    edges.sort_unstable_by_key(|p| (p.0, p.1));
    edges.dedup_by(|later, kept| {
        let same = (later.0, later.1) == (kept.0, kept.1);
        if same {
            kept.2 = kept.2.max(later.2);
        }
        same
    });
    let mut graph_start = vec![0; nodes + 1];
    for &(big_i, _, _) in &edges {
        graph_start[big_i + 1] += 1;
    }
    for k in 0..nodes {
        graph_start[k + 1] += graph_start[k];
    }
    StrongGraph {
        start: graph_start,
        neighbour: edges.into_iter().map(|(_, j, s)| (j, s)).collect(),
    }
}

/// Aggregate of every node ([`NONE`] for a node without strong neighbours) and the number of
/// aggregates: the three greedy phases of the module documentation, step 2.
fn aggregate(graph: &StrongGraph) -> (Vec<usize>, usize) {
    let nodes = graph.nodes();
    let mut agg = vec![NONE; nodes];
    let mut count = 0;
    // Phase 1: a node whose strong neighbours are all free roots an aggregate of them all.
    for i in 0..nodes {
        let nb = graph.neighbours(i);
        if agg[i] == NONE && !nb.is_empty() && nb.iter().all(|&(j, _)| agg[j] == NONE) {
            agg[i] = count;
            nb.iter().for_each(|&(j, _)| agg[j] = count);
            count += 1;
        }
    }
    // Phase 2: the others join the phase-1 aggregate of their strongest neighbour in one
    // (the first of equally strong ones).
    let phase1 = agg.clone();
    for i in 0..nodes {
        if agg[i] != NONE {
            continue;
        }
        let best = (graph.neighbours(i).iter())
            .filter(|&&(j, _)| phase1[j] != NONE)
            .fold(None, |best: Option<(usize, f64)>, &(j, s)| match best {
                Some((_, b)) if b >= s => best,
                _ => Some((j, s)),
            });
        if let Some((j, _)) = best {
            agg[i] = phase1[j];
        }
    }
    // Phase 3: what is left forms aggregates with its free strong neighbours.
    for i in 0..nodes {
        let nb = graph.neighbours(i);
        if agg[i] == NONE && !nb.is_empty() {
            agg[i] = count;
            for &(j, _) in nb {
                if agg[j] == NONE {
                    agg[j] = count;
                }
            }
            count += 1;
        }
    }
    (agg, count)
}

/// Orthonormal basis `Q` (`rows × k`, column-major) of the columns of `b` (`rows × m`,
/// row-major) and `R` (`k × m`, row-major) with `b = Q R`: modified Gram–Schmidt with one
/// re-orthogonalisation, dropping the dependent columns ([`DROP_TOLERANCE`]).
fn local_qr(rows: usize, m: usize, b: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut q: Vec<f64> = Vec::new();
    let mut r: Vec<Vec<f64>> = Vec::new();
    for col in 0..m {
        let mut v: Vec<f64> = (0..rows).map(|i| b[i * m + col]).collect();
        let norm0 = norm(&v);
        let mut coeff = vec![0.0; r.len()];
        for _ in 0..2 {
            for (k, qk) in q.chunks_exact(rows).enumerate() {
                let c: f64 = qk.iter().zip(&v).map(|(a, b)| a * b).sum();
                v.iter_mut().zip(qk).for_each(|(v, q)| *v -= c * q);
                coeff[k] += c;
            }
        }
        for (rk, c) in r.iter_mut().zip(coeff) {
            rk[col] = c;
        }
        let residual = norm(&v);
        if norm0 > 0.0 && residual > DROP_TOLERANCE * norm0 {
            q.extend(v.iter().map(|v| v / residual));
            let mut rk = vec![0.0; m];
            rk[col] = residual;
            r.push(rk);
        }
    }
    (q, r.concat())
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// The tentative prolongator `T` of `aggregates` and the coarse near-nullspace `B_c`
/// (module documentation, step 3); the coarse unknowns of aggregate `a` form coarse node `a`.
fn tentative(
    agg: &[usize],
    count: usize,
    ns: &NearNullspace,
) -> (SparseColMat<usize, f64>, NearNullspace) {
    let m = ns.modes;
    // Unknowns of every aggregate, increasing.
    let member_agg: Vec<usize> = ns.node.iter().map(|&k| agg[k]).collect();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); count];
    for (i, &a) in member_agg.iter().enumerate() {
        if a != NONE {
            members[a].push(i);
        }
    }
    let mut col_ptr = vec![0];
    let mut row_idx = Vec::new();
    let mut values = Vec::new();
    let mut coarse = NearNullspace {
        node: Vec::new(),
        modes: m,
        values: Vec::new(),
    };
    for (a, rows) in members.iter().enumerate() {
        let block: Vec<f64> = rows
            .iter()
            .flat_map(|&i| &ns.values[i * m..(i + 1) * m])
            .copied()
            .collect();
        let (q, r) = local_qr(rows.len(), m, &block);
        for column in q.chunks_exact(rows.len().max(1)) {
            row_idx.extend_from_slice(rows);
            values.extend_from_slice(column);
            col_ptr.push(row_idx.len());
            coarse.node.push(a);
        }
        coarse.values.extend(r);
    }
    let n_c = col_ptr.len() - 1;
    let symbolic = SymbolicSparseColMat::new_checked(ns.len(), n_c, col_ptr, None, row_idx);
    (SparseColMat::new(symbolic, values), coarse)
}

/// A fixed pseudo-random vector with entries in `[−1, 1)` (a multiplicative hash of the
/// index), the start of the power iteration.
fn start_vector(n: usize) -> Vec<f64> {
    (0..n as u64)
        .map(|i| {
            let h = (i + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            (h >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        })
        .collect()
}

/// Estimate of `ρ(D⁻¹ A)` by [`POWER_ITERATIONS`] power iterations (`rows`: `A` in row-access
/// form): `‖D⁻¹ A v‖_D` for the last iterate `v` normalised in the norm `‖x‖_D² = Σ |a_ii| x_i²`.
///
/// In that norm the iteration is the power method of `|D|^(−1/2) A |D|^(−1/2)`, symmetric for a
/// symmetric `A`: the estimate then grows monotonically towards `ρ` from below, whatever the
/// scaling of the unknowns (on coarse levels translations and rotations have diagonals orders
/// of magnitude apart, and the Euclidean norm ratio of the non-normal `D⁻¹ A` overshoots).
fn spectral_radius(rows: SparseColMatRef<'_, usize, f64>, inv_diag: &[f64]) -> f64 {
    let d_norm = |x: &[f64]| {
        (x.iter().zip(inv_diag))
            .map(|(x, inv)| x * x / inv.abs())
            .sum::<f64>()
            .sqrt()
    };
    let mut v = start_vector(inv_diag.len());
    let mut rho = 0.0;
    for _ in 0..POWER_ITERATIONS {
        let length = d_norm(&v);
        if length == 0.0 {
            break;
        }
        v.iter_mut().for_each(|v| *v /= length);
        let w: Vec<f64> = (0..v.len())
            .map(|i| row_dot(rows, i, &v) * inv_diag[i])
            .collect();
        rho = d_norm(&w);
        v = w;
    }
    rho
}

/// `P = (I − ω D⁻¹ A) T` with `ω = 4 / (3 ρ(D⁻¹ A))`, on the pattern of `A T` (which holds the
/// pattern of `T`: the diagonal of `A` is present).
fn smooth_prolongator(
    a: SparseColMatRef<'_, usize, f64>,
    rows: SparseColMatRef<'_, usize, f64>,
    inv_diag: &[f64],
    t: SparseColMat<usize, f64>,
) -> Result<SparseColMat<usize, f64>, LinearError> {
    let omega = 4.0 / (3.0 * spectral_radius(rows, inv_diag));
    let mut p = sparse_sparse_matmul(a, t.as_ref(), -omega, PAR).map_err(backend)?;
    let (symbolic, values) = p.parts_mut();
    for j in 0..symbolic.ncols() {
        let range = symbolic.col_range(j);
        let col_rows = &symbolic.row_idx()[range.clone()];
        let col_values = &mut values[range];
        for (&i, v) in col_rows.iter().zip(col_values.iter_mut()) {
            *v *= inv_diag[i];
        }
        for (i, &tij) in t.row_idx_of_col(j).zip(t.val_of_col(j)) {
            let k = col_rows
                .binary_search(&i)
                .expect("the pattern of A T holds the pattern of T");
            col_values[k] += tij;
        }
    }
    Ok(p)
}

/// `A_c = Pᵀ (A P)`.
fn galerkin(
    a: SparseColMatRef<'_, usize, f64>,
    p: SparseColMatRef<'_, usize, f64>,
) -> Result<SparseColMat<usize, f64>, LinearError> {
    let ap = sparse_sparse_matmul(a, p, 1.0, PAR).map_err(backend)?;
    let pt = p.transpose().to_col_major().map_err(backend)?;
    sparse_sparse_matmul(pt.as_ref(), ap.as_ref(), 1.0, PAR).map_err(backend)
}

impl CoarseLu {
    /// Dense LU of `a`; a zero or non-finite pivot fails with its row.
    fn new(a: SparseColMatRef<'_, usize, f64>) -> Result<Self, LinearError> {
        let n = a.nrows();
        let mut lu = Mat::<f64>::zeros(n, n);
        for j in 0..n {
            for (i, &v) in a.row_idx_of_col(j).zip(a.val_of_col(j)) {
                lu[(i, j)] = v;
            }
        }
        let mut perm = vec![0; n];
        let mut perm_inv = vec![0; n];
        let params = Default::default();
        let mut buffer =
            MemBuffer::new(factor::lu_in_place_scratch::<usize, f64>(n, n, PAR, params));
        factor::lu_in_place(
            lu.as_mut(),
            &mut perm,
            &mut perm_inv,
            PAR,
            MemStack::new(&mut buffer),
            params,
        );
        if let Some(row) = (0..n).find(|&i| {
            let u = lu[(i, i)];
            u == 0.0 || !u.is_finite()
        }) {
            return Err(LinearError::ZeroPivot {
                preconditioner: NAME,
                row,
            });
        }
        Ok(Self { lu, perm, perm_inv })
    }

    /// `A_c⁻¹ b` or `A_c⁻ᵀ b`.
    fn solve(&self, orientation: Orientation, b: &[f64]) -> Vec<f64> {
        let n = b.len();
        let mut x = b.to_vec();
        if n == 0 {
            return x;
        }
        let perm = PermRef::new_checked(&self.perm, &self.perm_inv, n);
        let lu = self.lu.as_ref();
        let rhs = MatMut::from_column_major_slice_mut(&mut x, n, 1);
        let mut buffer = MemBuffer::new(solve::solve_in_place_scratch::<usize, f64>(n, 1, PAR));
        let stack = MemStack::new(&mut buffer);
        match orientation {
            Orientation::Plain => solve::solve_in_place(lu, lu, perm, rhs, PAR, stack),
            Orientation::Transposed => {
                solve::solve_transpose_in_place(lu, lu, perm, rhs, PAR, stack)
            }
        }
        x
    }
}

#[cfg(test)]
pub(super) mod inspect {
    //! Access to the parts of the setup for the tests.
    use super::*;

    /// Unknowns per level of `amg`, finest first.
    pub(in crate::linear) fn sizes(amg: &Amg) -> Vec<usize> {
        (amg.levels.iter().map(|l| l.a.nrows()))
            .chain([amg.coarse.lu.nrows()])
            .collect()
    }

    /// The tentative prolongator (dense) and coarse near-nullspace of the finest level with
    /// the strength threshold `theta`, and the number of nodes left out of every aggregate.
    pub(in crate::linear) fn first_tentative(
        a: &SparseMatrix,
        ns: &NearNullspace,
        theta: f64,
    ) -> (nalgebra::DMatrix<f64>, NearNullspace, usize) {
        let at = a.as_faer().transpose().to_col_major().expect("transpose");
        let graph = strong_graph(at.as_ref(), &ns.node, theta);
        let (agg, count) = aggregate(&graph);
        let left_out = agg.iter().filter(|&&a| a == NONE).count();
        let (t, coarse) = tentative(&agg, count, ns);
        let dense = nalgebra::DMatrix::from_fn(t.nrows(), t.ncols(), |i, j| {
            (t.row_idx_of_col(j).zip(t.val_of_col(j)))
                .find(|&(r, _)| r == i)
                .map_or(0.0, |(_, &v)| v)
        });
        (dense, coarse, left_out)
    }
}
