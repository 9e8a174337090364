//! Tests of the block preconditioner on linear Biot consolidation systems of equal-order
//! (Q1–Q1) elements on a structured grid of the unit square or cube, stabilised by the
//! polynomial pressure projection, written in loam's form ([`crate::flow`]):
//!
//! ```text
//! mixture rows:  K u − α Qᵀ p          = f_u,   K_(vi)(wj) = ∫ C ∇N_v ∇N_w,  Q_q(vi) = ∫ N_q ∂_i N_v
//! fluid rows:    α Q u + (Δt κ L + S M + Π/G) p = f_p,   L = ∫ ∇N_q·∇N_r,   M = ∫ N_q N_r,
//! ```
//!
//! `Π_qr = ∫ N_q N_r − ∫N_q ∫N_r / |e|` per element, with the fluid rows scaled by `G/h` and the
//! pressure unknowns by `h/G`, as in a coupled step. The skeleton is clamped at the base
//! (`x_{D−1} = 0`) and the top face (`x_{D−1} = 1`) is drained (`p = 0`); the rest is free and
//! impermeable. Material: `E` = 20 MPa, `ν` = 0.3 (`G` ≈ 7.7 MPa), `α` = 1, incompressible
//! constituents (`S` = 0, the hardest case for the pressure block), `Δt` = 1 s and mobilities
//! `κ` from 1e-12 to 1e-4 m²/(Pa·s), so `Δt κ G / h²` spans 2e-4 … 8e5 on these grids: from
//! undrained steps, where the pressure block is the stabilisation alone, to drained ones,
//! where it is a Laplacian.

use super::amg::{STRENGTH_THRESHOLD, inspect};
use super::amg_tests::{POISSON, YOUNG, assemble, corners, element_stiffness};
use super::block::SCHUR_STRENGTH_THRESHOLD;
use super::*;

const E: f64 = 20e6;
const BIOT: f64 = 1.0;
const DT: f64 = 1.0;

/// A coupled system and its split, with the pressure mass `∫ N_q N_r / G` (the weights of
/// a coupled step's [`StepSystem::pressure_mass`](crate::system::StepSystem::pressure_mass)).
struct Biot {
    a: SparseMatrix,
    split: BlockSplit,
    /// The split without the pressure mass: the Schur augmentation's diagonal alone.
    diagonal_split: BlockSplit,
}

/// Values and physical gradients of the `2^D` Q1 shape functions of a cell of side `h` at the
/// reference point `xi ∈ [0, 1]^D`.
fn q1<const D: usize>(xi: [f64; D], h: f64) -> (Vec<f64>, Vec<[f64; D]>) {
    let corners = corners::<D>();
    let factor = |v: usize, x: f64| if v == 1 { x } else { 1.0 - x };
    let values = (corners.iter())
        .map(|v| (0..D).map(|a| factor(v[a], xi[a])).product())
        .collect();
    let grads = (corners.iter())
        .map(|v| {
            std::array::from_fn(|d| {
                (0..D)
                    .map(|a| match (a == d, v[a]) {
                        (true, 1) => 1.0 / h,
                        (true, _) => -1.0 / h,
                        (false, _) => factor(v[a], xi[a]),
                    })
                    .product()
            })
        })
        .collect();
    (values, grads)
}

impl Biot {
    /// The system of `k^D` elements with mobility `kappa` (m²/(Pa·s)).
    fn new<const D: usize>(k: usize, kappa: f64) -> Self {
        let side = k + 1;
        let h = 1.0 / k as f64;
        let shear = E / (2.0 * (1.0 + POISSON));
        let scale = shear / h;
        let multi = |flat: usize| -> [usize; D] {
            std::array::from_fn(|a| flat / side.pow(a as u32) % side)
        };
        let flat = |idx: [usize; D]| (0..D).map(|a| idx[a] * side.pow(a as u32)).sum::<usize>();
        // Unknowns, node by node, component-fastest (displacements, then the pressure).
        let nodes = side.pow(D as u32);
        let mut dof = vec![None; nodes * (D + 1)];
        let mut unknowns = Vec::new();
        for node in 0..nodes {
            let height = multi(node)[D - 1];
            for c in 0..=D {
                let fixed = if c < D { height == 0 } else { height == k };
                if !fixed {
                    dof[node * (D + 1) + c] = Some(unknowns.len());
                    unknowns.push((node, c));
                }
            }
        }
        // Element matrices in the element's local numbering (corner v, component c) → v (D+1) + c.
        let corners = corners::<D>();
        let m = corners.len();
        let size = m * (D + 1);
        let mut ke = vec![vec![0.0; size]; size];
        let mut me = vec![vec![0.0; size]; size];
        let stiffness = element_stiffness::<D>(h);
        for v in 0..m {
            for w in 0..m {
                for i in 0..D {
                    for j in 0..D {
                        ke[v * (D + 1) + i][w * (D + 1) + j] =
                            E / YOUNG * stiffness[v * D + i][w * D + j];
                    }
                }
            }
        }
        let gauss = [0.5 - 0.5 / 3f64.sqrt(), 0.5 + 0.5 / 3f64.sqrt()];
        let weight = 0.5f64.powi(D as i32) * h.powi(D as i32);
        let volume = h.powi(D as i32);
        let mut integral_n = vec![0.0; m];
        for g in &corners {
            let (n, grad) = q1::<D>(std::array::from_fn(|a| gauss[g[a]]), h);
            for q in 0..m {
                integral_n[q] += weight * n[q];
                for v in 0..m {
                    for i in 0..D {
                        // ∂f_(v,i)/∂p_q = −α ∫ ∂_i N_v N_q; ∂g_q/∂u_(v,i) = α ∫ N_q ∂_i N_v.
                        let coupling = BIOT * weight * n[q] * grad[v][i] * scale;
                        ke[v * (D + 1) + i][q * (D + 1) + D] -= coupling;
                        ke[q * (D + 1) + D][v * (D + 1) + i] += coupling;
                    }
                    let laplace: f64 = (0..D).map(|a| grad[q][a] * grad[v][a]).sum();
                    let mass = n[q] * n[v];
                    ke[q * (D + 1) + D][v * (D + 1) + D] +=
                        scale * scale * weight * (DT * kappa * laplace + mass / shear);
                    me[q * (D + 1) + D][v * (D + 1) + D] += weight * mass / shear;
                }
            }
        }
        for q in 0..m {
            for r in 0..m {
                ke[q * (D + 1) + D][r * (D + 1) + D] -=
                    scale * scale * integral_n[q] * integral_n[r] / (volume * shear);
            }
        }
        let a = assemble(k, D + 1, &ke, &corners, flat, &dof, unknowns.len());
        let mass = assemble(k, D + 1, &me, &corners, flat, &dof, unknowns.len());
        let diagonal_split = BlockSplit::new::<D>(&unknowns, |node| {
            let idx = multi(node);
            std::array::from_fn(|a| idx[a] as f64 * h)
        });
        let split = diagonal_split.clone().with_pressure_mass(&mass);
        Self {
            a,
            split,
            diagonal_split,
        }
    }

    fn n(&self) -> usize {
        self.a.pattern.n()
    }

    /// A solver of `kind` that knows the split.
    fn solver(&self, kind: LinearSolverKind) -> LinearSolver {
        let mut solver = LinearSolver::new(kind);
        solver.set_block_split(Some(self.split.clone()));
        solver
    }

    /// GMRES+block iterations to a relative residual of 1e-8 on `A x = b` (or `Aᵀ x = b`)
    /// with the preconditioner built on `split`.
    fn iterations(&self, split: &BlockSplit, transpose: bool) -> usize {
        let b = load(self.n());
        let mut x = vec![0.0; b.len()];
        let mut solver = LinearSolver::new(gmres(1e-8));
        solver.set_block_split(Some(split.clone()));
        let stats = if transpose {
            solver.solve_transpose(&self.a, &b, &mut x)
        } else {
            solver.solve(&self.a, &b, &mut x)
        };
        stats.expect("GMRES+block converges").iterations
    }

    /// Solves `A x = b` (or `Aᵀ x = b`) with `kind`; panics on failure.
    fn solve(&self, kind: LinearSolverKind, b: &[f64], transpose: bool) -> (Vec<f64>, LinearStats) {
        let mut x = vec![0.0; b.len()];
        let mut solver = self.solver(kind);
        let stats = if transpose {
            solver.solve_transpose(&self.a, b, &mut x)
        } else {
            solver.solve(&self.a, b, &mut x)
        }
        .unwrap_or_else(|e| panic!("{}: {e}", kind.name()));
        (x, stats)
    }
}

/// A deterministic right-hand side with all modes present.
fn load(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| (0.37 * i as f64).sin() + 0.5 * (1.3 * i as f64).cos())
        .collect()
}

fn gmres(rel_tol: f64) -> LinearSolverKind {
    LinearSolverKind::Gmres {
        preconditioner: Preconditioner::Block,
        rel_tol,
        max_iter: 2000,
    }
}

fn bicgstab(rel_tol: f64) -> LinearSolverKind {
    LinearSolverKind::Bicgstab {
        preconditioner: Preconditioner::Block,
        rel_tol,
        max_iter: 2000,
    }
}

fn relative_difference(x: &[f64], y: &[f64]) -> f64 {
    let d: f64 = x.iter().zip(y).map(|(x, y)| (x - y).powi(2)).sum();
    let y2: f64 = y.iter().map(|y| y * y).sum();
    (d / y2).sqrt()
}

/// GMRES and BiCGSTAB with the block preconditioner solve `A x = b` and `Aᵀ x = b` like the
/// sparse LU, in 2D and 3D, undrained and drained. The bound is the exact one,
/// `‖x − x*‖ / ‖x*‖ ≤ κ(A) ‖b − A x‖ / ‖b‖` with `κ = σ_max / σ_min` from the dense singular
/// values, plus `κ ε` for the round-off of the LU reference.
#[test]
fn block_solutions_match_lu() {
    for (system, label) in [
        (Biot::new::<2>(12, 1e-10), "2D undrained"),
        (Biot::new::<2>(12, 1e-5), "2D drained"),
        (Biot::new::<3>(5, 1e-10), "3D undrained"),
        (Biot::new::<3>(5, 1e-5), "3D drained"),
    ] {
        let a = &system.a;
        let sigma = a.to_dense().singular_values();
        let kappa = sigma.max() / sigma.min();
        let b = load(system.n());
        for transpose in [false, true] {
            let (reference, _) = system.solve(LinearSolverKind::Lu, &b, transpose);
            for kind in [gmres(1e-10), bicgstab(1e-10)] {
                let (x, stats) = system.solve(kind, &b, transpose);
                assert_eq!(stats.method, kind.name());
                let bound = kappa * stats.relative_residual + kappa * f64::EPSILON;
                let err = relative_difference(&x, &reference);
                println!(
                    "{label}, transpose {transpose}, n = {}, κ = {kappa:.1e}: {} {} iterations, \
                     error {err:.1e}",
                    system.n(),
                    kind.name(),
                    stats.iterations
                );
                assert!(
                    err <= bound,
                    "{label} transpose {transpose} {}: error {err:.2e} > {bound:.2e} ({stats:?})",
                    kind.name()
                );
            }
        }
    }
}

/// GMRES+block iterations to a relative residual of 1e-8, per grid and mobility.
fn iteration_counts<const D: usize>(sizes: [usize; 2], mobilities: &[f64]) -> Vec<[usize; 2]> {
    mobilities
        .iter()
        .map(|&kappa| {
            sizes.map(|k| {
                let system = Biot::new::<D>(k, kappa);
                let b = load(system.n());
                let (_, stats) = system.solve(gmres(1e-8), &b, false);
                let (_, transposed) = system.solve(gmres(1e-8), &b, true);
                println!(
                    "{D}D {k}^{D} elements, {} unknowns, κ = {kappa:.0e}: GMRES+block {}, \
                     transposed {}",
                    system.n(),
                    stats.iterations,
                    transposed.iterations
                );
                stats.iterations.max(transposed.iterations)
            })
        })
        .collect()
}

/// Mesh and mobility independence: refining the grid twice grows the GMRES+block count by at
/// most a factor 1.5, at every mobility from 1e-12 to 1e-4 m²/(Pa·s), plain and transposed;
/// and across those eight decades, where the pressure block changes from the stabilisation
/// alone to a Laplacian 10⁹ times larger, the count varies by at most a factor 2.2 (measured:
/// 8–16 in 2D, 8–14 in 3D; 10–20 and 12–20 with one smoothing sweep per cycle, and 13–30 with
/// the Schur augmentation's diagonal alone).
#[test]
fn block_iteration_counts_do_not_grow_with_the_mesh_or_the_mobility() {
    let mobilities = [1e-12, 1e-10, 1e-8, 1e-6, 1e-4];
    for counts in [
        iteration_counts::<2>([16, 32], &mobilities),
        iteration_counts::<3>([6, 12], &mobilities),
    ] {
        for (kappa, [coarse, fine]) in mobilities.iter().zip(&counts) {
            assert!(
                *fine as f64 <= 1.5 * *coarse as f64,
                "κ = {kappa:e}: {coarse} → {fine} iterations"
            );
        }
        let all = counts.iter().flatten();
        let (min, max) = (all.clone().min().unwrap(), all.max().unwrap());
        assert!(*max as f64 <= 2.2 * *min as f64, "{counts:?}");
    }
}

/// Near the undrained limit the pressure block is the stabilisation alone and the Schur
/// complement `S ≈ A_pp + B A_uu⁻¹ Bᵀ` is spectrally a pressure mass matrix. The
/// augmentation shaped like that mass (`D^½ M̂ D^½`) keeps the couplings of neighbouring
/// pressures that its diagonal `D` alone drops (a Q1 mass matrix's row sum is `(3/2)^D` times
/// its diagonal), so GMRES needs markedly fewer iterations, plain and transposed; in the flow-dominated limit, where the Darcy Laplacian dominates `S̃`, the
/// shape changes nothing. The thresholds, 0.75 and 1.1 of the diagonal version's count, are
/// loose against the measured ratios (printed), so the test checks the effect, not the digits.
#[test]
fn the_mass_shaped_schur_augmentation_cuts_the_undrained_iterations() {
    let cases = [
        (Biot::new::<2>(32, 1e-12), "2D undrained"),
        (Biot::new::<3>(10, 1e-12), "3D undrained"),
        (Biot::new::<2>(32, 1e-4), "2D drained"),
        (Biot::new::<3>(10, 1e-4), "3D drained"),
    ];
    for (system, label) in cases {
        for transpose in [false, true] {
            let shaped = system.iterations(&system.split, transpose);
            let diagonal = system.iterations(&system.diagonal_split, transpose);
            println!(
                "{label}, transpose {transpose}: {shaped} iterations with the mass shape, \
                 {diagonal} with the diagonal alone"
            );
            let bound = if label.ends_with("undrained") {
                0.75
            } else {
                1.1
            };
            assert!(
                shaped as f64 <= bound * diagonal as f64,
                "{label} transpose {transpose}: {shaped} vs {diagonal}"
            );
        }
    }
}

/// The pressure block `A_pp` of `system` as a matrix of its own.
fn pressure_block(system: &Biot) -> SparseMatrix {
    let a = &system.a;
    let p: Vec<usize> = (0..system.n())
        .filter(|&i| system.split.is_pressure(i))
        .collect();
    let mut local = vec![usize::MAX; system.n()];
    for (l, &i) in p.iter().enumerate() {
        local[i] = l;
    }
    let mut triplets = Vec::new();
    for (lj, &j) in p.iter().enumerate() {
        for k in a.pattern.col_range(j) {
            let i = a.pattern.row_idx()[k];
            if local[i] != usize::MAX {
                triplets.push((local[i], lj, a.values[k]));
            }
        }
    }
    let pattern = SparsePattern::new(p.len(), triplets.iter().map(|&(r, c, _)| (r, c)));
    let mut app = SparseMatrix::zeros(Arc::new(pattern));
    for (r, c, v) in triplets {
        app.add(r, c, v);
    }
    app
}

/// In the flow-dominated limit the pressure block is the trilinear Laplacian, whose couplings
/// are all weak against the displacement systems' threshold away from the faces (at most 1/16
/// of the diagonal, the edge neighbours; a neighbour on a face has half the diagonal and is
/// strong): with it the AMG leaves every node at least two cells from the impermeable faces
/// out of the aggregates, where it is then Gauss–Seidel alone. The Schur block's threshold
/// aggregates them all.
#[test]
fn schur_threshold_aggregates_every_pressure_node() {
    let system = Biot::new::<3>(8, 1e-4);
    let app = pressure_block(&system);
    let constant = NearNullspace::constant(app.pattern.n());
    let (_, _, left_out) = inspect::first_tentative(&app, &constant, SCHUR_STRENGTH_THRESHOLD);
    assert_eq!(left_out, 0);
    let (_, _, left_out) = inspect::first_tentative(&app, &constant, STRENGTH_THRESHOLD);
    // Node layers 2 … 6 across the 9 of each side, 2 … 7 of the 8 below the drained top.
    assert_eq!(left_out, 5 * 5 * 6);
}

/// In the flow-dominated steps (`Δt κ G / h²` from 490 to 2e5 here) the GMRES+block count stays flat
/// from 8³ to 16³ elements in 3D: the AMG of `S̃` coarsens the Laplacian everywhere.
#[test]
fn flow_dominated_iteration_counts_stay_flat_in_3d() {
    for kappa in [1e-6, 1e-4] {
        let counts = iteration_counts::<3>([8, 16], &[kappa]);
        let [coarse, fine] = counts[0];
        assert!(
            fine as f64 <= 1.2 * coarse as f64,
            "κ = {kappa:e}: {coarse} → {fine} iterations"
        );
    }
}

/// Without the split (a solid system) the block preconditioner refuses to run.
#[test]
fn block_needs_the_split() {
    let system = Biot::new::<2>(4, 1e-8);
    let b = load(system.n());
    let mut x = vec![0.0; system.n()];
    let err = LinearSolver::new(gmres(1e-8))
        .solve(&system.a, &b, &mut x)
        .unwrap_err();
    assert!(matches!(err, LinearError::NoBlockSplit), "{err}");
}
