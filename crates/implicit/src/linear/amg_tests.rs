//! Tests of the smoothed-aggregation AMG preconditioner on linear elastic stiffness matrices of
//! bilinear (2D, plane strain) and trilinear (3D) elements on a structured grid of the unit
//! square or cube, clamped on the face `x = 0` and on rollers (`u_y = 0`) on the face `y = 0`,
//! so the nodes of that face have one component fewer than the others.

use std::sync::Arc;
use std::time::Instant;

use super::amg::{Amg, STRENGTH_THRESHOLD, SWEEPS, inspect};
use super::precond::PrecondState;
use super::*;

/// Young's modulus and Poisson's ratio of the test material.
pub(super) const YOUNG: f64 = 1.0;
pub(super) const POISSON: f64 = 0.3;

/// Stiffness matrix of the elements of a `k^D` grid (see the module documentation) and the
/// rigid-body modes of its unknowns.
struct Elasticity {
    a: SparseMatrix,
    modes: NearNullspace,
}

/// Assembles the element matrix `ke` of every element of a `k^D`-element grid (its rows and
/// columns `fields` per corner, corners in the order of `corners`) into a matrix over the
/// `n` unknowns `dof[node · fields + c]` (`None`: fixed); `flat` numbers the nodes.
pub(super) fn assemble<const D: usize>(
    k: usize,
    fields: usize,
    ke: &[Vec<f64>],
    corners: &[[usize; D]],
    flat: impl Fn([usize; D]) -> usize,
    dof: &[Option<usize>],
    n: usize,
) -> SparseMatrix {
    let mut triplets = Vec::new();
    for element in 0..k.pow(D as u32) {
        let origin: [usize; D] = std::array::from_fn(|a| element / k.pow(a as u32) % k);
        let element_dofs: Vec<Option<usize>> = (corners.iter())
            .flat_map(|v| {
                let node = flat(std::array::from_fn(|a| origin[a] + v[a]));
                (0..fields).map(move |c| node * fields + c)
            })
            .map(|g| dof[g])
            .collect();
        for (r, row) in element_dofs.iter().enumerate() {
            for (c, col) in element_dofs.iter().enumerate() {
                if let (Some(row), Some(col)) = (row, col) {
                    triplets.push((*row, *col, ke[r][c]));
                }
            }
        }
    }
    let pattern = SparsePattern::new(n, triplets.iter().map(|&(r, c, _)| (r, c)));
    let mut a = SparseMatrix::zeros(Arc::new(pattern));
    for (r, c, v) in triplets {
        a.add(r, c, v);
    }
    a
}

/// The `2^D` corners of the reference cell `[0, 1]^D`, lexicographic.
pub(super) fn corners<const D: usize>() -> Vec<[usize; D]> {
    (0..1 << D)
        .map(|v| std::array::from_fn(|a| (v >> a) & 1))
        .collect()
}

/// Element stiffness of a cube of side `h` (`2^D` corners × `D` components, corner-major):
/// `K_(v,i)(w,j) = Σ_g w_g h^D [λ ∂_i N_v ∂_j N_w + μ (∇N_v·∇N_w δ_ij + ∂_j N_v ∂_i N_w)]` with
/// the tensor-product Q1 shape functions and 2-point Gauss rules per axis (exact here).
pub(super) fn element_stiffness<const D: usize>(h: f64) -> Vec<Vec<f64>> {
    let lambda = YOUNG * POISSON / ((1.0 + POISSON) * (1.0 - 2.0 * POISSON));
    let mu = YOUNG / (2.0 * (1.0 + POISSON));
    let corners = corners::<D>();
    let size = corners.len() * D;
    let mut k = vec![vec![0.0; size]; size];
    let gauss = [0.5 - 0.5 / 3f64.sqrt(), 0.5 + 0.5 / 3f64.sqrt()];
    for g in corners.iter() {
        let xi: [f64; D] = std::array::from_fn(|a| gauss[g[a]]);
        // ∇N_v at ξ (physical gradient: the reference one over h).
        let grad: Vec<[f64; D]> = (corners.iter())
            .map(|v| {
                std::array::from_fn(|d| {
                    (0..D)
                        .map(|a| match (a == d, v[a]) {
                            (true, 1) => 1.0,
                            (true, _) => -1.0,
                            (false, 1) => xi[a],
                            (false, _) => 1.0 - xi[a],
                        })
                        .product::<f64>()
                        / h
                })
            })
            .collect();
        let weight = 0.5f64.powi(D as i32) * h.powi(D as i32);
        for (v, gv) in grad.iter().enumerate() {
            for (w, gw) in grad.iter().enumerate() {
                let dot: f64 = (0..D).map(|a| gv[a] * gw[a]).sum();
                for i in 0..D {
                    for j in 0..D {
                        let shear = if i == j { dot } else { 0.0 } + gv[j] * gw[i];
                        k[v * D + i][w * D + j] += weight * (lambda * gv[i] * gw[j] + mu * shear);
                    }
                }
            }
        }
    }
    k
}

impl Elasticity {
    /// The system of `k^D` elements.
    fn new<const D: usize>(k: usize) -> Self {
        let side = k + 1;
        let h = 1.0 / k as f64;
        let multi = |flat: usize| -> [usize; D] {
            std::array::from_fn(|a| flat / side.pow(a as u32) % side)
        };
        let flat = |idx: [usize; D]| (0..D).map(|a| idx[a] * side.pow(a as u32)).sum::<usize>();
        // Unknowns: clamped at x = 0, u_y = 0 at y = 0.
        let mut dof = vec![None; side.pow(D as u32) * D];
        let mut unknowns = Vec::new();
        for node in 0..side.pow(D as u32) {
            let idx = multi(node);
            for c in 0..D {
                if idx[0] > 0 && !(c == 1 && idx[1] == 0) {
                    dof[node * D + c] = Some(unknowns.len());
                    unknowns.push((node, c));
                }
            }
        }
        let ke = element_stiffness::<D>(h);
        let corners = corners::<D>();
        let a = assemble(k, D, &ke, &corners, flat, &dof, unknowns.len());
        let modes = NearNullspace::rigid_body::<D>(&unknowns, |node| {
            let idx = multi(node);
            std::array::from_fn(|a| idx[a] as f64 * h)
        });
        Self { a, modes }
    }

    fn n(&self) -> usize {
        self.a.pattern.n()
    }

    /// The system with a non-symmetric perturbation on the pattern of `A`:
    /// `a_ij ← (1 + 0.2 sign(j − i)) a_ij`.
    fn nonsymmetric(&self) -> SparseMatrix {
        let mut a = self.a.clone();
        let p = Arc::clone(&a.pattern);
        for j in 0..p.n() {
            for k in p.col_range(j) {
                let i = p.row_idx()[k];
                a.values[k] *= 1.0 + 0.2 * (j as f64 - i as f64).signum();
            }
        }
        a
    }

    /// A solver of `kind` that knows the rigid-body modes.
    fn solver(&self, kind: LinearSolverKind) -> LinearSolver {
        let mut solver = LinearSolver::new(kind);
        solver.set_near_nullspace(Some(self.modes.clone()));
        solver
    }
}

/// A deterministic load with all modes present.
fn load(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| (0.37 * i as f64).sin() + 0.5 * (1.3 * i as f64).cos())
        .collect()
}

fn cg(preconditioner: Preconditioner, rel_tol: f64) -> LinearSolverKind {
    LinearSolverKind::Cg {
        preconditioner,
        rel_tol,
        max_iter: 5000,
    }
}

fn bicgstab(preconditioner: Preconditioner, rel_tol: f64) -> LinearSolverKind {
    LinearSolverKind::Bicgstab {
        preconditioner,
        rel_tol,
        max_iter: 5000,
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|v| v * v).sum::<f64>().sqrt()
}

fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(x, y)| x * y).sum()
}

/// `(‖x − y‖ / ‖y‖)`.
fn relative_difference(x: &[f64], y: &[f64]) -> f64 {
    let d: Vec<f64> = x.iter().zip(y).map(|(x, y)| x - y).collect();
    norm(&d) / norm(y)
}

/// Solves `A x = b` (or `Aᵀ x = b`) with `kind`; panics on failure.
fn solve(
    solver: &mut LinearSolver,
    a: &SparseMatrix,
    b: &[f64],
    transpose: bool,
) -> (Vec<f64>, LinearStats) {
    let mut x = vec![0.0; b.len()];
    let stats = if transpose {
        solver.solve_transpose(a, b, &mut x)
    } else {
        solver.solve(a, b, &mut x)
    }
    .unwrap_or_else(|e| panic!("{}: {e}", solver.kind().name()));
    (x, stats)
}

/// `M⁻¹ v` (or `M⁻ᵀ v`) of the AMG of `a`.
fn precondition(state: &PrecondState, a: &SparseMatrix, v: &[f64], transpose: bool) -> Vec<f64> {
    let mut z = v.to_vec();
    let orientation = if transpose {
        Orientation::Transposed
    } else {
        Orientation::Plain
    };
    state.solve_in_place(&a.pattern, orientation, &mut z);
    z
}

fn amg_state(a: &SparseMatrix, modes: &NearNullspace) -> PrecondState {
    let mut state =
        PrecondState::new(Preconditioner::Amg, &a.pattern).expect("no structural check");
    state.factorize(a, Some(modes), None).expect("AMG setup");
    state
}

/// CG+AMG and BiCGSTAB+AMG agree with the sparse LU solve of the same system. The error
/// bound is the exact one, `‖x − x*‖ / ‖x*‖ ≤ κ(A) ‖b − A x‖ / ‖b‖`, with `κ` from the dense
/// eigenvalues, plus `κ ε` for the round-off of the LU reference (`κ ≤ 10⁴` here).
#[test]
fn amg_solutions_match_lu() {
    for system in [Elasticity::new::<2>(20), Elasticity::new::<3>(6)] {
        let a = &system.a;
        let n = system.n();
        let hierarchy =
            Amg::new(a, Some(&system.modes), STRENGTH_THRESHOLD, SWEEPS).expect("setup");
        assert!(
            inspect::sizes(&hierarchy).len() >= 2,
            "a multilevel hierarchy: {:?}",
            inspect::sizes(&hierarchy)
        );
        let eigen = a.to_dense().symmetric_eigenvalues();
        let kappa = eigen.max() / eigen.min();
        assert!(eigen.min() > 0.0);
        let b = load(n);
        let (reference, _) = solve(&mut LinearSolver::new(LinearSolverKind::Lu), a, &b, false);
        for kind in [
            cg(Preconditioner::Amg, 1e-10),
            bicgstab(Preconditioner::Amg, 1e-10),
        ] {
            let (x, stats) = solve(&mut system.solver(kind), a, &b, false);
            assert_eq!(stats.method, kind.name());
            let bound = kappa * stats.relative_residual + kappa * f64::EPSILON;
            let err = relative_difference(&x, &reference);
            assert!(
                err <= bound,
                "{}: error {err:.2e} > {bound:.2e} ({stats:?})",
                kind.name()
            );
            println!(
                "n = {n}, levels {:?}, κ = {kappa:.1e}: {} {} iterations, error {err:.1e}",
                inspect::sizes(&hierarchy),
                kind.name(),
                stats.iterations
            );
        }
    }
}

/// BiCGSTAB+AMG solves `A x = b` and `Aᵀ x = b` of a non-symmetric matrix like the sparse LU,
/// within the same bound as above with `κ = σ_max / σ_min` from the dense singular values.
#[test]
fn amg_solves_nonsymmetric_and_transposed_systems() {
    let system = Elasticity::new::<2>(20);
    let a = system.nonsymmetric();
    let sigma = a.to_dense().singular_values();
    let kappa = sigma.max() / sigma.min();
    let b = load(system.n());
    for transpose in [false, true] {
        let mut lu = LinearSolver::new(LinearSolverKind::Lu);
        let (reference, _) = solve(&mut lu, &a, &b, transpose);
        let kind = bicgstab(Preconditioner::Amg, 1e-10);
        let (x, stats) = solve(&mut system.solver(kind), &a, &b, transpose);
        let bound = kappa * stats.relative_residual + kappa * f64::EPSILON;
        let err = relative_difference(&x, &reference);
        assert!(
            err <= bound,
            "transpose {transpose}: error {err:.2e} > {bound:.2e} ({stats:?})"
        );
        println!(
            "non-symmetric, transpose {transpose}: κ = {kappa:.1e}, {} iterations, error {err:.1e}",
            stats.iterations
        );
    }
}

/// CG iterations to a relative residual of 1e-8 per grid; the AMG's count stays nearly flat
/// while ILU(0)'s and Jacobi's grow like the square root of the condition number, `O(1/h)`.
fn iteration_counts<const D: usize>(sizes: &[usize]) -> Vec<[usize; 3]> {
    let preconditioners = [
        Preconditioner::Amg,
        Preconditioner::Ilu0,
        Preconditioner::Jacobi,
    ];
    sizes
        .iter()
        .map(|&k| {
            let system = Elasticity::new::<D>(k);
            let b = load(system.n());
            let counts = preconditioners.map(|p| {
                solve(&mut system.solver(cg(p, 1e-8)), &system.a, &b, false)
                    .1
                    .iterations
            });
            println!(
                "{D}D {k}^{D} elements, {} unknowns: CG+AMG {}, CG+ILU(0) {}, CG+Jacobi {}",
                system.n(),
                counts[0],
                counts[1],
                counts[2]
            );
            counts
        })
        .collect()
}

/// Mesh independence: from the coarsest grid to one 4 (2D) or 3 (3D) times finer, the AMG's
/// iteration count grows by at most a factor 1.5, while ILU(0)'s and Jacobi's grow by more
/// than half the mesh ratio (their asymptotic growth is the mesh ratio, `√κ ∝ 1/h`). The
/// grids all have more than [`super::amg::COARSE_SIZE`] unknowns, so every AMG here has at
/// least two levels (a smaller system is solved by the coarse LU alone, in one iteration).
#[test]
fn amg_iteration_counts_do_not_grow_with_the_mesh() {
    for (sizes, counts) in [
        (
            [16, 32, 64].as_slice(),
            iteration_counts::<2>(&[16, 32, 64]),
        ),
        ([6, 12, 18].as_slice(), iteration_counts::<3>(&[6, 12, 18])),
    ] {
        let ratio = sizes[sizes.len() - 1] as f64 / sizes[0] as f64;
        let (first, last) = (counts[0], counts[counts.len() - 1]);
        let amg_max = counts.iter().map(|c| c[0]).max().expect("sizes") as f64;
        let amg_min = counts.iter().map(|c| c[0]).min().expect("sizes") as f64;
        assert!(amg_max <= 1.5 * amg_min, "AMG counts {counts:?}");
        for p in [1, 2] {
            assert!(
                last[p] as f64 > 0.5 * ratio * first[p] as f64,
                "the one-level preconditioners must grow: {counts:?}"
            );
        }
    }
}

/// The tentative prolongator reproduces the rigid-body modes: `T B_c = B` to round-off
/// (`1e-12` relative: a few Gram–Schmidt operations on numbers of order one), its columns are
/// orthonormal (`TᵀT = I`, same tolerance), every node is aggregated, and the coarse space is
/// smaller than the fine one.
#[test]
fn tentative_prolongator_holds_the_rigid_body_modes() {
    for system in [Elasticity::new::<2>(8), Elasticity::new::<3>(4)] {
        let (t, coarse, left_out) =
            inspect::first_tentative(&system.a, &system.modes, STRENGTH_THRESHOLD);
        assert_eq!(left_out, 0);
        let m = system.modes.modes();
        assert!(
            t.ncols() < system.n() && t.ncols() >= m,
            "{} → {}",
            system.n(),
            t.ncols()
        );
        let b = nalgebra::DMatrix::from_fn(system.n(), m, |i, k| system.modes.value(i, k));
        let b_c = nalgebra::DMatrix::from_fn(coarse.len(), m, |i, k| coarse.value(i, k));
        let reproduced = (&t * b_c - &b).abs().max() / b.abs().max();
        assert!(reproduced < 1e-12, "T B_c − B: {reproduced:.1e}");
        let identity = nalgebra::DMatrix::identity(t.ncols(), t.ncols());
        let orthogonality = (t.transpose() * &t - identity).abs().max();
        assert!(orthogonality < 1e-12, "TᵀT − I: {orthogonality:.1e}");
        // The modes are not trivially reproduced: they are not constant.
        assert!((0..system.n()).any(|i| system.modes.value(i, m - 1).abs() > 0.1));
    }
}

/// Random-looking vectors for the bilinear-form checks.
fn probe(n: usize, seed: f64) -> Vec<f64> {
    (0..n).map(|i| (seed * (i as f64 + 1.0)).sin()).collect()
}

/// For a symmetric `A`, `xᵀ M⁻¹ y = yᵀ M⁻¹ x` and `xᵀ M⁻¹ x > 0`; for a non-symmetric one,
/// `xᵀ M⁻¹ y = (M⁻ᵀ x)ᵀ y`, while `M⁻¹` itself is clearly not symmetric. Both sides are the
/// same sums in exact arithmetic; their round-off is relative to `‖x‖ ‖M⁻¹ y‖` times a few
/// hundred operations per entry and the condition of the coarse LU: `1e-11` holds with a
/// margin (the measured differences are printed).
#[test]
fn amg_is_symmetric_and_its_transpose_is_the_adjoint() {
    let system = Elasticity::new::<3>(6);
    let n = system.n();
    let (x, y) = (probe(n, 0.731), probe(n, 1.913));
    let spd = amg_state(&system.a, &system.modes);
    let my = precondition(&spd, &system.a, &y, false);
    let mx = precondition(&spd, &system.a, &x, false);
    let scale = norm(&x) * norm(&my);
    let asymmetry = (dot(&x, &my) - dot(&y, &mx)).abs() / scale;
    assert!(asymmetry < 1e-11, "symmetric A: {asymmetry:.1e}");
    assert!(dot(&x, &mx) > 0.0 && dot(&y, &my) > 0.0);

    let a = system.nonsymmetric();
    let state = amg_state(&a, &system.modes);
    let my = precondition(&state, &a, &y, false);
    let mx = precondition(&state, &a, &x, false);
    let mtx = precondition(&state, &a, &x, true);
    let scale = norm(&x) * norm(&my);
    let adjoint = (dot(&x, &my) - dot(&mtx, &y)).abs() / scale;
    let asymmetry_ns = (dot(&x, &my) - dot(&y, &mx)).abs() / scale;
    println!(
        "symmetric: {asymmetry:.1e}; transpose: {adjoint:.1e} (M⁻¹ asymmetry {asymmetry_ns:.1e})"
    );
    assert!(adjoint < 1e-11, "transpose: {adjoint:.1e}");
    assert!(
        asymmetry_ns > 1e-4,
        "M⁻¹ of a non-symmetric A: {asymmetry_ns:.1e}"
    );
}

/// Two setups and applications give the same bits, with 1 and with 4 rayon threads.
#[test]
fn amg_is_deterministic() {
    let system = Elasticity::new::<3>(6);
    let b = load(system.n());
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        pool.install(|| {
            let state = amg_state(&system.a, &system.modes);
            let z = precondition(&state, &system.a, &b, false);
            let (x, _) = solve(
                &mut system.solver(cg(Preconditioner::Amg, 1e-10)),
                &system.a,
                &b,
                false,
            );
            [z, x]
        })
    };
    let reference = run(1);
    for other in [run(1), run(4)] {
        for (p, q) in reference.iter().zip(&other) {
            assert!(p.iter().zip(q).all(|(p, q)| p.to_bits() == q.to_bits()));
        }
    }
}

/// The spectral radius of the V(ν,ν)-cycle's error propagator `E_ν = I − M_ν⁻¹ A`, from the
/// dense `M_ν⁻¹` (the cycle applied to every unit vector).
fn cycle_contraction(system: &Elasticity, sweeps: usize) -> f64 {
    let a = &system.a;
    let n = system.n();
    let hierarchy = Amg::new(a, Some(&system.modes), STRENGTH_THRESHOLD, sweeps).expect("setup");
    let mut m_inv = nalgebra::DMatrix::zeros(n, n);
    for j in 0..n {
        let mut z = vec![0.0; n];
        z[j] = 1.0;
        hierarchy.apply(Orientation::Plain, &mut z);
        m_inv.column_mut(j).copy_from_slice(&z);
    }
    let e = nalgebra::DMatrix::identity(n, n) - m_inv * a.to_dense();
    e.complex_eigenvalues()
        .iter()
        .map(|l| l.norm())
        .fold(0.0, f64::max)
}

/// Every Gauss–Seidel sweep is a contraction in the energy norm and the backward sweep is the
/// forward one's adjoint, so for a symmetric positive definite `A` the error propagator of the
/// V(ν,ν)-cycle is self-adjoint in that norm, `E_(ν+1) = S_b E_ν S_f` and
/// `ρ(E_(ν+1)) = ‖E_(ν+1)‖_A ≤ ‖E_ν‖_A` (module docs of `amg`). Measured exactly (dense), the
/// contraction falls strictly with each sweep and stays below one.
#[test]
fn more_sweeps_contract_the_cycle_more() {
    for (system, label) in [
        (Elasticity::new::<2>(20), "2D 20²"),
        (Elasticity::new::<3>(6), "3D 6³"),
    ] {
        let rho: Vec<f64> = (1..=3).map(|nu| cycle_contraction(&system, nu)).collect();
        println!("{label}: ρ(E_ν) for ν = 1, 2, 3: {rho:.3?}");
        assert!(rho[0] < 1.0, "{label}: {rho:?}");
        assert!(rho[1] < rho[0] && rho[2] < rho[1], "{label}: {rho:?}");
    }
}

/// Without the rigid-body modes the AMG falls back to the constant vector per unknown, which
/// still converges but needs more iterations than with them.
#[test]
fn rigid_body_modes_pay_off() {
    let system = Elasticity::new::<3>(8);
    let b = load(system.n());
    let kind = cg(Preconditioner::Amg, 1e-8);
    let with = solve(&mut system.solver(kind), &system.a, &b, false).1;
    let without = solve(&mut LinearSolver::new(kind), &system.a, &b, false).1;
    println!(
        "CG+AMG iterations: {} with the rigid-body modes, {} without",
        with.iterations, without.iterations
    );
    assert!(
        with.iterations < without.iterations,
        "{with:?} vs {without:?}"
    );
}

/// Wall times of setup + solve on the largest 3D case (printed only; nothing is asserted about
/// them).
#[test]
fn amg_timing_on_the_largest_3d_case() {
    let start = Instant::now();
    let system = Elasticity::new::<3>(18);
    let assembly = start.elapsed().as_secs_f64();
    let b = load(system.n());
    let start = Instant::now();
    let hierarchy =
        Amg::new(&system.a, Some(&system.modes), STRENGTH_THRESHOLD, SWEEPS).expect("setup");
    let setup = start.elapsed().as_secs_f64();
    println!(
        "3D 18^3 elements: {} unknowns, {} non-zeros, assembly {assembly:.2} s; AMG levels {:?}, setup {setup:.3} s",
        system.n(),
        system.a.pattern.nnz(),
        inspect::sizes(&hierarchy)
    );
    for kind in [
        cg(Preconditioner::Amg, 1e-8),
        cg(Preconditioner::Ilu0, 1e-8),
        LinearSolverKind::Lu,
    ] {
        let start = Instant::now();
        let (_, stats) = solve(&mut system.solver(kind), &system.a, &b, false);
        println!(
            "{}: setup + solve {:.3} s, {} iterations, residual {:.1e}",
            kind.name(),
            start.elapsed().as_secs_f64(),
            stats.iterations,
            stats.relative_residual
        );
    }
}

/// A zero diagonal entry of the finest level is reported as a zero pivot of the AMG.
#[test]
fn amg_reports_a_zero_diagonal() {
    let system = Elasticity::new::<2>(20);
    let mut a = system.a.clone();
    let row = 7;
    let k = a.pattern.diagonal_position(row).expect("diagonal");
    a.values[k] = 0.0;
    let mut x = vec![0.0; system.n()];
    let err = system
        .solver(bicgstab(Preconditioner::Amg, 1e-8))
        .solve(&a, &load(system.n()), &mut x)
        .unwrap_err();
    assert!(
        matches!(
            err,
            LinearError::ZeroPivot {
                preconditioner: "AMG",
                row: 7
            }
        ),
        "{err}"
    );
}
