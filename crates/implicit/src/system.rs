//! The nonlinear system of one load step: residual `R(Δu) = f_int(Δu) − f_ext` over the free
//! unknowns, its sparse tangent `K = ∂R/∂Δu`, and the particle update once it converged.

use crate::dofs::{DofMap, NodeDof, Tie};
use crate::flow::Flow;
use crate::kernel::{Frozen, delta_f, particle_stress};
use crate::linear::{
    BlockSplit, LinearError, LinearSolver, NearNullspace, SparseMatrix, SparsePattern,
};
use loam_core::tensor::{Tensor, Vector, det};
use loam_core::{Grid, Material, Stencil};
use nalgebra::Matrix3;
use num_dual::{Dual64, DualSVec64};
use rayon::prelude::*;
use std::sync::Arc;

/// Particles per parallel chunk: local results of a chunk are computed in parallel and then
/// scattered serially in particle order, so the assembly is deterministic.
pub(crate) const CHUNK: usize = 1024;

/// A trial state that inverts a particle (`det ΔF ≤ 0`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Inverted {
    /// The particle.
    pub particle: usize,
}

/// Whether the per-particle tangent of `material` in 3D is taken in one pass with all nine
/// entries of `ΔF` seeded in a 9-lane dual (`DualSVec64<9>`) rather than in nine passes of a
/// one-lane `Dual64`. A lane costs about as much as the real part, so nine single-lane
/// passes do the model's real arithmetic nine times and one wide pass once: the wide pass
/// wins where the real work is large, as in Modified Cam-Clay's local Newton iteration
/// (`loam bench tangent` times both for every model; docs/performance.md). In 2D the four
/// entries always go in one pass.
pub fn tangent_in_one_pass<T: loam_core::Scalar>(material: &Material<T>) -> bool {
    matches!(
        material.model,
        loam_core::constitutive::Model::ModifiedCamClay(_)
    )
}

/// Material tables lifted to the scalar types the tangents use.
pub struct Materials {
    /// Real parameters (residual).
    pub real: Vec<Material<f64>>,
    /// For the per-particle tangent (one `ΔF` entry seeded at a time).
    pub dual: Vec<Material<Dual64>>,
    /// For the colour-seeded tangent with 2 or 3 lanes.
    pub dual2: Vec<Material<DualSVec64<2>>>,
    /// 3-lane version.
    pub dual3: Vec<Material<DualSVec64<3>>>,
    /// For the per-particle tangent in 2D: all 4 entries of `ΔF` seeded in one pass.
    pub dual4: Vec<Material<DualSVec64<4>>>,
    /// For the per-particle tangent in 3D: all 9 entries of `ΔF` seeded in one pass.
    pub dual9: Vec<Material<DualSVec64<9>>>,
    /// For the per-particle tangent of a coupled step in 2D: `ΔF`, `p̂` and `∇p̂` (7 lanes).
    pub dual7: Vec<Material<DualSVec64<7>>>,
    /// The same in 3D (13 lanes).
    pub dual13: Vec<Material<DualSVec64<13>>>,
}

impl Materials {
    /// Lifts a real material table.
    pub fn new(real: Vec<Material<f64>>) -> Self {
        Self {
            dual: real.iter().map(|m| m.lift()).collect(),
            dual2: real.iter().map(|m| m.lift()).collect(),
            dual3: real.iter().map(|m| m.lift()).collect(),
            dual4: real.iter().map(|m| m.lift()).collect(),
            dual9: real.iter().map(|m| m.lift()).collect(),
            dual7: real.iter().map(|m| m.lift()).collect(),
            dual13: real.iter().map(|m| m.lift()).collect(),
            real,
        }
    }
}

/// Relative weight `ε` of the diagonal added to the consistent mass in the end-of-step solves,
/// `(M + ε diag M) x = b` (see [`Inertia`]). `M` is positive semi-definite: it is singular when
/// a step has more unknowns than its particles pin down (one particle per cell with B-splines),
/// and its null space is that of the interpolation `N`, which moves no particle. A right-hand
/// side in the range of `M` has no component along that null space, so `ε` only scales each
/// resolved mode by `λ/(λ + ε)` (`λ` an eigenvalue of `(diag M)⁻¹ M`) and keeps the Cholesky
/// pivots positive. With 10⁻¹⁰ the energy of a linear-elastic beam drifts by ~10⁻⁹ over ten
/// periods (the drift is proportional to `ε`).
pub const MASS_REGULARISATION: f64 = 1e-10;

/// The inertia of a Newmark step (β = ¼, γ = ½, average acceleration / trapezoidal rule) and
/// the particle update it implies.
///
/// On the grid of the step, with the consistent mass `M_ij = Σ_p m_p N_ip N_jp` (through the
/// unknown map), Newmark reads
///
/// ```text
/// Δu      = Δt vₙ + Δt²/4 (aₙ + aₙ₊₁)
/// vₙ₊₁    = vₙ + Δt/2 (aₙ + aₙ₊₁)  =  2 Δu/Δt − vₙ
/// M aₙ₊₁  = f_ext − f_int(Δu)
/// ```
///
/// and the grid state at the start of the step is the one the particles carry:
///
/// - `M vₙ = pₙ := Σ_p m_p N_ip v_p`, the mass-weighted L² projection of the particle
///   velocities onto the grid (never formed: only `M vₙ = pₙ` enters the residual);
/// - `M aₙ = rₙ := f_ext − f_int(0)`, the force balance of the start state on this step's grid.
///
/// The residual is `R(Δu) = (4/Δt²) M Δu − (4/Δt) pₙ − rₙ + f_int(Δu) − f_ext` and the
/// tangent adds `(4/Δt²) M`. Once Newton has converged, the particles take
///
/// ```text
/// M Δv    = (2/Δt) M Δu − 2 pₙ           (Δv = vₙ₊₁ − vₙ on the grid)
/// M aₙ₊₁  = (2/Δt) M Δv − rₙ
/// v_p    ← v_p + Σ_i N_ip Δv_i           (FLIP: the part of v_p the grid cannot hold is kept)
/// a_p    ← Σ_i N_ip aₙ₊₁,i              (output; the next step does not read it)
/// x_p    ← x_p + Σ_i N_ip Δu_i
/// ```
///
/// **Energy.** Because `Σ_p m_p v_p·(N Δv)_p = Δv·pₙ = Δv·M vₙ`, the particles' kinetic energy
/// changes by exactly the grid's, `Δv·M vₙ + ½ Δv·M Δv = ½ (vₙ + vₙ₊₁)·M Δv`, which by the two
/// Newmark relations is `(Δu/Δt)·(Δt/2)(M aₙ + M aₙ₊₁) = ½ Δu·(rₙ + rₙ₊₁)`: the trapezoidal
/// rule for the work of the forces over the step. The stored energy `Σ_p V_p⁰ ψ(ΔF Fⁿ)` is a
/// function of `Δu` whose gradient is `f_int(Δu)`, so for a quadratic `ψ` (linear elasticity)
/// `K + U − f_ext·u` is conserved exactly, step by step, whatever the grid and however the
/// particles move; for a nonlinear `ψ` the error per step is the trapezoidal rule's,
/// `O(|Δu|³ ψ‴)`, which falls as Δt². Three shortcuts break this and did before:
///
/// - projecting with the lumped mass (`vₙ = M_L⁻¹ pₙ`, so `M vₙ ≠ pₙ`) exchanges
///   `Δv·(M_L − M) vₙ` per step with nothing;
/// - carrying `aₙ` on the particles from the last step balances it against the last step's
///   grid: once the particles' stencils change, `M aₙ ≠ rₙ` and the mismatch does work (and a
///   body starting at rest under load starts with `aₙ = 0`, which halves its first step);
/// - holding a weakly supported node at `Δu = 0` strains every particle whose stencil reaches
///   it by `Δu ⊗ ∇N_j` in any translation: a steep, non-quadratic `ψ` along the step, whose
///   trapezoidal error dominated at small amplitude. Dynamic steps let such nodes follow an
///   active neighbour instead (`ImplicitSolver::system`).
///
/// The end-of-step solves use `M + ε diag M` with `ε` = [`MASS_REGULARISATION`].
pub struct Inertia {
    /// Consistent mass matrix on the step's pattern.
    pub mass: SparseMatrix,
    /// Time step Δt.
    pub dt: f64,
    /// Grid momentum at the start of the step, `pₙ = Σ_p m_p N_ip v_p` (= `M vₙ`), per unknown.
    pub momentum: Vec<f64>,
    /// Start-of-step force `rₙ = f_ext − f_int(0)` (= `M aₙ`), per unknown.
    pub force: Vec<f64>,
}

/// The grid fields a converged Newmark step hands to the particles.
#[derive(Clone, Debug, PartialEq)]
pub struct GridMotion {
    /// `Δv = vₙ₊₁ − vₙ` per unknown.
    pub velocity_increment: Vec<f64>,
    /// `aₙ₊₁` per unknown.
    pub acceleration: Vec<f64>,
}

impl Inertia {
    /// The inertia term of the residual for `Δu = x`: `M aₙ₊₁(Δu) = (4/Δt²) M Δu − (4/Δt) pₙ − rₙ`.
    pub fn mass_times_acceleration(&self, x: &[f64]) -> Vec<f64> {
        let mut mx = vec![0.0; x.len()];
        self.mass.mul_vec(x, &mut mx);
        let (c0, c1) = (4.0 / (self.dt * self.dt), 4.0 / self.dt);
        mx.iter()
            .zip(&self.momentum)
            .zip(&self.force)
            .map(|((mx, p), r)| c0 * mx - c1 * p - r)
            .collect()
    }

    /// The matrix of the end-of-step solves, `M + ε diag M` with `ε` = [`MASS_REGULARISATION`].
    pub fn regularised_mass(&self) -> SparseMatrix {
        let mut m = self.mass.clone();
        for (d, md) in self.mass.diagonal().into_iter().enumerate() {
            m.add(d, d, MASS_REGULARISATION * md);
        }
        m
    }

    /// The grid velocity increment and end-of-step acceleration of the converged `Δu = x`,
    /// from `(M + ε diag M) Δv = (2/Δt) M Δu − 2 pₙ` and `(M + ε diag M) aₙ₊₁ = (2/Δt) M Δv − rₙ`.
    pub fn grid_motion(
        &self,
        x: &[f64],
        solver: &mut LinearSolver,
    ) -> Result<GridMotion, LinearError> {
        let n = x.len();
        let m = self.regularised_mass();
        let mut mx = vec![0.0; n];
        self.mass.mul_vec(x, &mut mx);
        let rhs: Vec<f64> = mx
            .iter()
            .zip(&self.momentum)
            .map(|(mx, p)| 2.0 / self.dt * mx - 2.0 * p)
            .collect();
        let mut dv = vec![0.0; n];
        solver.solve(&m, &rhs, &mut dv)?;
        self.mass.mul_vec(&dv, &mut mx);
        let rhs: Vec<f64> = mx
            .iter()
            .zip(&self.force)
            .map(|(mdv, r)| 2.0 / self.dt * mdv - r)
            .collect();
        let mut a = vec![0.0; n];
        solver.solve(&m, &rhs, &mut a)?;
        Ok(GridMotion {
            velocity_increment: dv,
            acceleration: a,
        })
    }
}

/// A force-controlled component of a user constraint in one step: its nodes share the unknown
/// `dof`, and `f_ext[dof] = factor · F` with `F` the constraint's force component
/// (`NodeConstraint::force`) and `factor` the step's load factor, so `∂f_ext[dof]/∂F = factor`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Controlled {
    /// Index of the constraint (`ImplicitConfig::constraints`).
    pub constraint: usize,
    /// The force-controlled component.
    pub component: usize,
    /// The shared unknown.
    pub dof: usize,
    /// The load factor the force carries in this step.
    pub factor: f64,
}

/// One load step's system.
pub struct StepSystem<const D: usize> {
    /// Newmark inertia for dynamic steps (`None`: quasi-static).
    pub inertia: Option<Inertia>,
    /// The pore fluid of a coupled (u–p) step (`None`: the solid alone); the unknown map
    /// then has `D + 1` components per node.
    pub flow: Option<Flow>,
    /// Frozen particle data.
    pub frozen: Vec<Frozen<D>>,
    /// Unknown numbering.
    pub dofs: DofMap<D>,
    /// Tangent sparsity (fixed for the step).
    pub pattern: Arc<SparsePattern>,
    /// External force on the unknowns at the end of the step.
    pub f_ext: Vec<f64>,
    /// The force-controlled components of the user constraints and the shared unknowns that
    /// carry their forces (empty when there is none).
    pub controlled: Vec<Controlled>,
    /// The sparsity pattern and its slot tables, shared with the next step when its unknowns
    /// are the same.
    structure: Arc<Structure>,
    b: usize,
    grid: Grid<D>,
}

/// What the tangent's sparsity depends on: the owners of the unknowns (node, component), the
/// field count and the stencil width. Steps whose particles stay in their cells (every step
/// of a small-strain consolidation) have the same owners and share one `Structure`, so the
/// pattern is built and the direct solver's symbolic analysis is done once for all of them.
#[derive(Debug)]
pub struct Structure {
    /// The unknowns' owners, `DofMap::owner_of` in order.
    owners: Vec<(usize, usize)>,
    fields: usize,
    b: usize,
    /// Tangent sparsity.
    pattern: Arc<SparsePattern>,
    /// Per unknown (column), the value positions of its rows by neighbour offset.
    slots: Vec<u32>,
    /// Per unknown: the key `Σ_a i_a reach^a` of its owner node's multi-index and its
    /// component; the neighbour offset of two unknowns is the difference of their keys.
    owner_key: Vec<(isize, usize)>,
    /// `Σ_a half · reach^a` (`half` = b − 1, or b in a coupled step), the key offset of a
    /// zero neighbour offset.
    key_centre: isize,
    /// Neighbour offsets per node, `reach^D`.
    offsets: usize,
    /// Per unknown, whether it is shared by a group of nodes ([`DofMap::tie`]; empty when
    /// none is): its entries are looked up in the pattern, not through the offset tables.
    tied: Vec<bool>,
    /// The groups of the shared unknowns.
    ties: Vec<Tie>,
}

impl Structure {
    /// The sparsity of a step with unknowns `dofs` and stencils `b` nodes wide: owner nodes
    /// within `b − 1` of each other along every axis couple (the pressures of a coupled step
    /// within `b`).
    fn new<const D: usize>(grid: &Grid<D>, dofs: &DofMap<D>, b: usize) -> Self {
        let n = dofs.len();
        let fields = dofs.fields();
        // Pattern: owner nodes within b − 1 of each other along every axis couple. In a
        // coupled step the pressures of nodes b apart couple too: the stabilisation's
        // projection over a grid cell (`crate::flow`) joins the particles of one cell, whose
        // stencils may start one node apart.
        let half = if fields > D { b } else { b - 1 };
        let reach = 2 * half + 1;
        let nodes = grid.nodes();
        let offsets = reach.pow(D as u32);
        // Whether neighbour offset `k` is in the outer ring that only pressures reach.
        let outer = |k: usize| {
            let mut r = k;
            (0..D).any(|_| {
                let o = (r % reach) as isize - half as isize;
                r /= reach;
                o.unsigned_abs() > b - 1
            })
        };
        let neighbour = |flat: usize, k: usize| -> Option<usize> {
            let idx = grid.multi(flat);
            let mut r = k;
            let mut out = [0usize; D];
            for a in 0..D {
                let o = (r % reach) as isize - half as isize;
                r /= reach;
                let j = idx[a] as isize + o;
                if j < 0 || j as usize >= nodes[a] {
                    return None;
                }
                out[a] = j as usize;
            }
            Some(grid.flat(out))
        };
        let mut tied = vec![false; if dofs.ties().is_empty() { 0 } else { n }];
        for t in dofs.ties() {
            tied[t.dof] = true;
        }
        let is_tied = |d: usize| !tied.is_empty() && tied[d];
        let owner_dof = |flat: usize, c: usize| match dofs.get(flat, c) {
            NodeDof::Free { dof, .. } if !is_tied(dof) && dofs.owner_of(dof).0 == flat => Some(dof),
            _ => None,
        };
        // Every (column unknown, neighbour offset, row component, row unknown) coupling of
        // unknowns that are not shared.
        let couplings = |f: &mut dyn FnMut(usize, usize, usize, usize)| {
            for col in (0..n).filter(|&d| !is_tied(d)) {
                let (node, col_c) = dofs.owner_of(col);
                for k in 0..offsets {
                    let ring = outer(k);
                    if ring && col_c < D {
                        continue;
                    }
                    if let Some(m) = neighbour(node, k) {
                        for c in (0..fields).filter(|&c| !ring || c == D) {
                            if let Some(row) = owner_dof(m, c) {
                                f(col, k, c, row);
                            }
                        }
                    }
                }
            }
        };
        let mut entries = Vec::with_capacity(n * offsets * fields);
        couplings(&mut |col, _, _, row| entries.push((row, col)));
        // A shared unknown couples with every unknown of the nodes within b − 1 of any node
        // of its group (it is a displacement: no outer pressure ring).
        for t in dofs.ties() {
            for &node in &t.nodes {
                for k in (0..offsets).filter(|&k| !outer(k)) {
                    let Some(m) = neighbour(node, k) else {
                        continue;
                    };
                    for c in 0..fields {
                        if let NodeDof::Free { dof, .. } = dofs.get(m, c) {
                            entries.push((dof, t.dof));
                            entries.push((t.dof, dof));
                        }
                    }
                }
            }
        }
        let pattern = Arc::new(SparsePattern::new(n, entries));
        let mut slots = vec![NO_SLOT; n * offsets * fields];
        couplings(&mut |col, k, c, row| {
            let pos = pattern.position(row, col).expect("entry was inserted");
            slots[(col * offsets + k) * fields + c] = pos as u32;
        });
        let key = |idx: [usize; D]| -> isize {
            let mut k = 0isize;
            for a in (0..D).rev() {
                k = k * reach as isize + idx[a] as isize;
            }
            k
        };
        let owner_key = (0..n)
            .map(|d| {
                let (node, c) = dofs.owner_of(d);
                (key(grid.multi(node)), c)
            })
            .collect();
        let key_centre = key([half; D]);
        Self {
            owners: (0..n).map(|d| dofs.owner_of(d)).collect(),
            fields,
            b,
            pattern,
            slots,
            owner_key,
            key_centre,
            offsets,
            tied,
            ties: dofs.ties().to_vec(),
        }
    }

    /// Whether this is the sparsity of a step with unknowns `dofs` and stencils `b` wide.
    fn fits<const D: usize>(&self, dofs: &DofMap<D>, b: usize) -> bool {
        self.b == b
            && self.fields == dofs.fields()
            && self.owners.len() == dofs.len()
            && self.ties == dofs.ties()
            && (0..dofs.len()).all(|d| dofs.owner_of(d) == self.owners[d])
    }
}

const NO_SLOT: u32 = u32::MAX;

/// An unknown placed in a step's sparsity ([`StepSystem::place`]): the position of its
/// entry in column `c` is `slots[c.column + row]`, the offset tables' index split into a
/// row part and a column part.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Placed {
    /// The unknown.
    pub dof: usize,
    /// Its sign at the node component it was placed for.
    pub sign: f64,
    /// Whether it is shared by a group of nodes (its entries are looked up in the pattern).
    tied: bool,
    /// `key · fields + component`, its part of the index as a row.
    row: isize,
    /// `(dof · offsets + key_centre − key) · fields`, its part as a column.
    column: isize,
}

impl<const D: usize> StepSystem<D> {
    /// Builds the system: `frozen` particles, the unknown map and the external force
    /// `f_ext = Σ_p (m_p g + f_p) N_i(x_pⁿ)` (gravity and particle point loads at the end of
    /// the step, scattered through the map).
    pub fn new(
        grid: &Grid<D>,
        frozen: Vec<Frozen<D>>,
        dofs: DofMap<D>,
        particle_force: impl Fn(usize) -> Vector<f64, D>,
    ) -> Self {
        Self::reusing(grid, frozen, dofs, particle_force, None)
    }

    /// [`StepSystem::new`], taking the sparsity `previous` (another step's
    /// [`StepSystem::structure`]) when this step's unknowns have the same owners.
    pub fn reusing(
        grid: &Grid<D>,
        frozen: Vec<Frozen<D>>,
        dofs: DofMap<D>,
        particle_force: impl Fn(usize) -> Vector<f64, D>,
        previous: Option<&Arc<Structure>>,
    ) -> Self {
        let b = frozen.first().map_or(2, |f| f.stencil.b);
        let structure = match previous {
            Some(s) if s.fits(&dofs, b) => s.clone(),
            _ => Arc::new(Structure::new(grid, &dofs, b)),
        };
        let n = dofs.len();
        let mut f_ext = vec![0.0; n];
        for (p, fr) in frozen.iter().enumerate() {
            let fp = particle_force(p);
            fr.stencil.for_each(|node| {
                for a in 0..D {
                    if let NodeDof::Free { dof, sign } = dofs.get(node.flat, a) {
                        f_ext[dof] += sign * node.weight * fp[a];
                    }
                }
            });
        }
        Self {
            inertia: None,
            flow: None,
            frozen,
            dofs,
            pattern: structure.pattern.clone(),
            f_ext,
            controlled: Vec::new(),
            structure,
            b,
            grid: grid.clone(),
        }
    }

    /// The sparsity of this step, for [`StepSystem::reusing`].
    pub fn structure(&self) -> &Arc<Structure> {
        &self.structure
    }

    /// Number of unknowns.
    pub fn len(&self) -> usize {
        self.dofs.len()
    }

    /// `true` when there are no unknowns.
    pub fn is_empty(&self) -> bool {
        self.dofs.is_empty()
    }

    /// The rigid-body modes of the unknowns at their owner nodes' positions (the
    /// near-nullspace of the tangent, for the AMG preconditioner).
    pub fn near_nullspace(&self) -> NearNullspace {
        NearNullspace::rigid_body::<D>(&self.owners(), |flat| self.node_position(flat))
    }

    /// The displacement–pressure split of a coupled step's unknowns (component `D` the pore
    /// pressure), with the rigid-body modes of the displacement unknowns at their owner nodes'
    /// positions and the pressure mass matrix ([`StepSystem::pressure_mass`]): what the block
    /// preconditioner needs besides the tangent.
    ///
    /// # Panics
    /// On a step without pore fluid.
    pub fn block_split(&self) -> BlockSplit {
        BlockSplit::new::<D>(&self.owners(), |flat| self.node_position(flat))
            .with_pressure_mass(&self.pressure_mass())
    }

    /// Hands `linear` what its preconditioner needs besides the tangent: the near-nullspace of
    /// this step's unknowns (the AMG preconditioner of a solid step), or the
    /// displacement–pressure split (the block preconditioner; none in a step without pore
    /// fluid, whose solves then fail with `LinearError::NoBlockSplit`), so that every solve
    /// of the step (Newton's, and the adjoint's transposed ones) uses them.
    pub fn prepare(&self, linear: &mut LinearSolver) {
        let kind = linear.kind();
        if kind.uses_near_nullspace() && self.flow.is_none() {
            linear.set_near_nullspace(Some(self.near_nullspace()));
        }
        if kind.uses_block_split() {
            linear.set_block_split(self.flow.as_ref().map(|_| self.block_split()));
        }
    }

    /// The owner (node, component) of every unknown, in order.
    fn owners(&self) -> Vec<(usize, usize)> {
        (0..self.len()).map(|d| self.dofs.owner_of(d)).collect()
    }

    /// The coordinates of grid node `flat`.
    fn node_position(&self, flat: usize) -> [f64; D] {
        let x: Vector<f64, D> = self.grid.node_position(self.grid.multi(flat));
        std::array::from_fn(|a| x[a])
    }

    /// Position in the value array of entry (row unknown, column unknown); both are owners.
    #[inline]
    pub(crate) fn slot(&self, row: usize, col: usize) -> usize {
        let st = &*self.structure;
        if !st.tied.is_empty() && (st.tied[row] || st.tied[col]) {
            return st
                .pattern
                .position(row, col)
                .expect("a shared unknown's entries are in the pattern");
        }
        let (kr, rc) = st.owner_key[row];
        let (kc, _) = st.owner_key[col];
        let k = (kr - kc + st.key_centre) as usize;
        let s = st.slots[(col * st.offsets + k) * st.fields + rc];
        debug_assert_ne!(s, NO_SLOT, "tangent entry outside the pattern");
        s as usize
    }

    /// Unknown `dof` with what [`StepSystem::slot_placed`] needs to find its entries
    /// without going through the unknown tables again.
    #[inline]
    pub(crate) fn place(&self, dof: usize, sign: f64) -> Placed {
        let st = &*self.structure;
        let tied = !st.tied.is_empty() && st.tied[dof];
        let (key, comp) = st.owner_key[dof];
        let fields = st.fields as isize;
        Placed {
            dof,
            sign,
            tied,
            row: key * fields + comp as isize,
            column: (dof as isize * st.offsets as isize + st.key_centre - key) * fields,
        }
    }

    /// [`StepSystem::slot`] of two placed unknowns: one look-up in the slot table.
    #[inline]
    pub(crate) fn slot_placed(&self, row: &Placed, col: &Placed) -> usize {
        if row.tied || col.tied {
            return self.slot(row.dof, col.dof);
        }
        let s = self.structure.slots[(col.column + row.row) as usize];
        debug_assert_ne!(s, NO_SLOT, "tangent entry outside the pattern");
        s as usize
    }

    /// `ΔF` of particle `p` for the unknowns `x`.
    #[inline]
    pub(crate) fn delta_f_real(&self, p: usize, x: &[f64]) -> Tensor<f64, D> {
        delta_f(&self.frozen[p].stencil, |flat, c| {
            self.dofs.value(flat, c, x)
        })
    }

    /// Evaluates `compute(p)` for every particle, in parallel chunks of [`CHUNK`], and hands
    /// the results to `consume(p, result)` serially in particle order (so every sum it makes
    /// is deterministic). A `None` result is a trial state that inverts particle `p`.
    pub(crate) fn chunked<R: Send>(
        &self,
        compute: impl Fn(usize) -> Option<R> + Sync,
        mut consume: impl FnMut(usize, R),
    ) -> Result<(), Inverted> {
        let mut local: Vec<Option<R>> = Vec::new();
        for start in (0..self.frozen.len()).step_by(CHUNK) {
            let end = (start + CHUNK).min(self.frozen.len());
            (start..end)
                .into_par_iter()
                .map(&compute)
                .collect_into_vec(&mut local);
            for (k, r) in local.drain(..).enumerate() {
                let p = start + k;
                consume(p, r.ok_or(Inverted { particle: p })?);
            }
        }
        Ok(())
    }

    /// Internal force on the unknowns `f_int(x)`; `Err` names a particle the trial state
    /// inverts.
    pub fn internal_force(&self, x: &[f64], materials: &Materials) -> Result<Vec<f64>, Inverted> {
        if self.flow.is_some() {
            return self.coupled_force(x, materials);
        }
        let mut f = vec![0.0; self.len()];
        self.chunked(
            |p| {
                let fr = &self.frozen[p];
                particle_stress(&materials.real[fr.material], fr, &self.delta_f_real(p, x))
                    .map(|s| s.0)
            },
            |p, s| {
                self.frozen[p].stencil.for_each(|node| {
                    let fi = s * node.gradient;
                    for a in 0..D {
                        if let NodeDof::Free { dof, sign } = self.dofs.get(node.flat, a) {
                            f[dof] += sign * fi[a];
                        }
                    }
                });
            },
        )?;
        Ok(f)
    }

    /// The force `f = Σ_p s_p ∇N_i` on the unknowns of the per-particle tensors `s_p` (at
    /// `Δu = 0` the internal force of a stress field is that of `s_p = V⁰_p τ_p`).
    pub fn divergence(&self, s: &[Tensor<f64, D>]) -> Vec<f64> {
        let mut f = vec![0.0; self.len()];
        for (fr, s) in self.frozen.iter().zip(s) {
            fr.stencil.for_each(|node| {
                let fi = s * node.gradient;
                for a in 0..D {
                    if let NodeDof::Free { dof, sign } = self.dofs.get(node.flat, a) {
                        f[dof] += sign * fi[a];
                    }
                }
            });
        }
        f
    }

    /// Internal force `f_i = Σ_p V⁰τΔF⁻ᵀ ∇N_i` on every grid node (flat index), before any
    /// folding of ghost nodes: at prescribed nodes it is the reaction the constraint exerts.
    pub fn nodal_internal_force(
        &self,
        x: &[f64],
        materials: &Materials,
    ) -> Result<Vec<Vector<f64, D>>, Inverted> {
        if self.flow.is_some() {
            return self.coupled_nodal_force(x, materials);
        }
        let mut f = vec![Vector::<f64, D>::zeros(); self.grid.num_nodes()];
        for (p, fr) in self.frozen.iter().enumerate() {
            let (s, _, _) =
                particle_stress(&materials.real[fr.material], fr, &self.delta_f_real(p, x))
                    .ok_or(Inverted { particle: p })?;
            fr.stencil
                .for_each(|node| f[node.flat] += s * node.gradient);
        }
        Ok(f)
    }

    /// Residual `R(x) = f_int(x) − f_ext` (plus `M a_{n+1}(x)` for a dynamic step).
    pub fn residual(&self, x: &[f64], materials: &Materials) -> Result<Vec<f64>, Inverted> {
        let mut r = self.internal_force(x, materials)?;
        r.iter_mut().zip(&self.f_ext).for_each(|(r, f)| *r -= f);
        if let Some(inertia) = &self.inertia {
            let ma = inertia.mass_times_acceleration(x);
            r.iter_mut().zip(&ma).for_each(|(r, m)| *r += m);
        }
        Ok(r)
    }

    /// Adds the dynamic part `(4/Δt²) M` to a tangent (no-op for quasi-static steps).
    fn add_inertia(&self, k: &mut SparseMatrix) {
        if let Some(inertia) = &self.inertia {
            let c0 = 4.0 / (inertia.dt * inertia.dt);
            k.values
                .iter_mut()
                .zip(&inertia.mass.values)
                .for_each(|(k, m)| *k += c0 * m);
        }
    }

    /// The consistent mass `M_ij = Σ_p m_p N_ip N_jp` on the step's unknowns (one block per
    /// component; the pattern of the tangent).
    pub fn consistent_mass(&self, mass: &[f64]) -> SparseMatrix {
        let mut m = SparseMatrix::zeros(self.pattern.clone());
        for (p, fr) in self.frozen.iter().enumerate() {
            let mut nodes = Vec::with_capacity(fr.stencil.len());
            fr.stencil
                .for_each(|node| nodes.push((node.flat, node.weight)));
            for &(fi, wi) in &nodes {
                for c in 0..D {
                    let NodeDof::Free { dof: row, sign: si } = self.dofs.get(fi, c) else {
                        continue;
                    };
                    for &(fj, wj) in &nodes {
                        if let NodeDof::Free { dof: col, sign: sj } = self.dofs.get(fj, c) {
                            m.values[self.slot(row, col)] += si * sj * mass[p] * wi * wj;
                        }
                    }
                }
            }
        }
        m
    }

    /// A field on the unknowns `v` at particle `p`, `Σ_i N_ip v_i` (zero at the components
    /// that are not unknowns).
    pub fn interpolate(&self, p: usize, v: &[f64]) -> Vector<f64, D> {
        let mut out = Vector::<f64, D>::zeros();
        self.frozen[p].stencil.for_each(|n| {
            for a in 0..D {
                out[a] += n.weight * self.dofs.field(n.flat, a, v);
            }
        });
        out
    }

    /// `−∂R[c.dof]/∂F` of the force `F` of the force-controlled component `c`: `ℓ` (its load
    /// factor) in a quasi-static or coupled step, `2ℓ` in a Newmark step, whose residual
    /// `f_int(Δu) + f_int(0) − 2 f_ext + …` holds the external force once directly and once
    /// through the start force `rₙ = f_ext − f_int(0)`.
    pub fn controlled_rate(&self, c: &Controlled) -> f64 {
        match self.inertia {
            Some(_) => 2.0 * c.factor,
            None => c.factor,
        }
    }

    /// Makes this a Newmark step of size `dt` (see [`Inertia`]): assembles the consistent
    /// mass, the grid momentum `pₙ = Σ_p m_p N_ip v_p` and the start-of-step force
    /// `rₙ = f_ext − f_int(0)`. `Err` names a particle whose start state has no stress (a
    /// deformation gradient that is not invertible).
    pub fn set_dynamic(
        &mut self,
        dt: f64,
        mass: &[f64],
        v: &[Vector<f64, D>],
        materials: &Materials,
    ) -> Result<(), Inverted> {
        let n = self.len();
        let m = self.consistent_mass(mass);
        let mut momentum = vec![0.0; n];
        for (p, fr) in self.frozen.iter().enumerate() {
            fr.stencil.for_each(|node| {
                for c in 0..D {
                    if let NodeDof::Free { dof, sign } = self.dofs.get(node.flat, c) {
                        momentum[dof] += sign * mass[p] * node.weight * v[p][c];
                    }
                }
            });
        }
        let f0 = self.internal_force(&vec![0.0; n], materials)?;
        let force = self.f_ext.iter().zip(&f0).map(|(e, i)| e - i).collect();
        self.inertia = Some(Inertia {
            mass: m,
            dt,
            momentum,
            force,
        });
        Ok(())
    }

    /// Tangent by per-particle forward-mode AD: `A = ∂(V⁰ τ ΔF⁻ᵀ)/∂ΔF` from `D²` passes with
    /// one `ΔF` entry seeded as a `Dual64`, then `K_{ia,jc} = Σ_{bd} ∂N_i/∂x_b A_{ab,cd} ∂N_j/∂x_d`
    /// scattered through the unknown map. Exact (no finite differences); the fast path.
    pub fn tangent_local(
        &self,
        x: &[f64],
        materials: &Materials,
    ) -> Result<SparseMatrix, Inverted> {
        if self.flow.is_some() {
            return self.coupled_tangent_local(x, materials);
        }
        self.tangent_from(|p| self.material_tangent(p, x, materials))
    }

    /// The tangent `K_{ia,jc} = Σ_p Σ_{bd} ∂_b N_i A_p[c][d]_{ab} ∂_d N_j` (plus `(4/Δt²) M`
    /// for a dynamic step) from every particle's `A_p = ∂(V⁰ τ ΔF⁻ᵀ)/∂ΔF`, given by
    /// `local(p)` (`None`: particle `p` is inverted).
    pub fn tangent_from(
        &self,
        local: impl Fn(usize) -> Option<[[Tensor<f64, D>; D]; D]> + Sync,
    ) -> Result<SparseMatrix, Inverted> {
        let mut k = SparseMatrix::zeros(self.pattern.clone());
        self.chunked(local, |p, a| {
            self.scatter_local(&self.frozen[p].stencil, &a, &mut k)
        })?;
        self.add_inertia(&mut k);
        Ok(k)
    }

    /// `A[c][d] = ∂(V⁰ τ ΔF⁻ᵀ)/∂ΔF_cd` for particle `p`.
    fn material_tangent(
        &self,
        p: usize,
        x: &[f64],
        materials: &Materials,
    ) -> Option<[[Tensor<f64, D>; D]; D]> {
        let fr = &self.frozen[p];
        let g = self.delta_f_real(p, x);
        if D == 2 {
            return self.material_tangent_lanes::<4>(fr, &g, &materials.dual4[fr.material]);
        }
        if tangent_in_one_pass(&materials.real[fr.material]) {
            return self.material_tangent_lanes::<9>(fr, &g, &materials.dual9[fr.material]);
        }
        let mat = &materials.dual[fr.material];
        let mut out = [[Tensor::<f64, D>::zeros(); D]; D];
        for c in 0..D {
            for d in 0..D {
                let gd = Tensor::<Dual64, D>::from_fn(|i, j| {
                    Dual64::new(g[(i, j)], if (i, j) == (c, d) { 1.0 } else { 0.0 })
                });
                let (s, _, _) = particle_stress(mat, fr, &gd)?;
                out[c][d] = s.map(|v| v.eps);
            }
        }
        Some(out)
    }

    /// `A` with all `L = D²` entries of `ΔF` seeded in one pass (lane `c·D + d`).
    fn material_tangent_lanes<const L: usize>(
        &self,
        fr: &Frozen<D>,
        g: &Tensor<f64, D>,
        mat: &Material<DualSVec64<L>>,
    ) -> Option<[[Tensor<f64, D>; D]; D]> {
        let gd = Tensor::<DualSVec64<L>, D>::from_fn(|i, j| {
            let mut e = nalgebra::SVector::<f64, L>::zeros();
            e[i * D + j] = 1.0;
            DualSVec64::<L>::new(g[(i, j)], num_dual::Derivative::some(e))
        });
        let (s, _, _) = particle_stress(mat, fr, &gd)?;
        Some(std::array::from_fn(|c| {
            std::array::from_fn(|d| s.map(|v| v.eps.0.as_ref().map_or(0.0, |e| e[c * D + d])))
        }))
    }

    /// Adds one particle's `K_{ia,jc} = Σ_{bd} ∂_b N_i A[c][d]_{ab} ∂_d N_j` to the matrix.
    fn scatter_local(
        &self,
        st: &Stencil<f64, D>,
        a: &[[Tensor<f64, D>; D]; D],
        k: &mut SparseMatrix,
    ) {
        let mut nodes = Vec::with_capacity(st.len());
        st.for_each(|n| nodes.push((n.flat, n.gradient)));
        for &(fj, gj) in &nodes {
            // G[c] = Σ_d A[c][d] ∂_d N_j  (a D×D tensor per column component c)
            let gcol: [Tensor<f64, D>; D] = std::array::from_fn(|c| {
                let mut s = Tensor::<f64, D>::zeros();
                for d in 0..D {
                    s += a[c][d] * gj[d];
                }
                s
            });
            for c in 0..D {
                let NodeDof::Free { dof: col, sign: sc } = self.dofs.get(fj, c) else {
                    continue;
                };
                for &(fi, gi) in &nodes {
                    let v = gcol[c] * gi;
                    for r in 0..D {
                        if let NodeDof::Free { dof: row, sign: sr } = self.dofs.get(fi, r) {
                            k.values[self.slot(row, col)] += sr * sc * v[r];
                        }
                    }
                }
            }
        }
    }

    /// Reference tangent by block-colour seeding (see `tangent` module docs): for each of the
    /// `b^D` node colours, seed the `D` components of every unknown owned by a node of that
    /// colour with a `D`-lane dual, evaluate every particle once, and scatter the dual parts
    /// of its nodal forces into the columns of the one seeded node in its stencil.
    pub fn tangent_colour(
        &self,
        x: &[f64],
        materials: &Materials,
    ) -> Result<SparseMatrix, Inverted> {
        if self.flow.is_some() {
            return self.coupled_tangent_colour(x, materials);
        }
        match D {
            2 => self.tangent_colour_lanes::<2>(x, &materials.dual2),
            3 => self.tangent_colour_lanes::<3>(x, &materials.dual3),
            _ => unreachable!("D is 2 or 3"),
        }
    }

    fn tangent_colour_lanes<const L: usize>(
        &self,
        x: &[f64],
        mats: &[Material<DualSVec64<L>>],
    ) -> Result<SparseMatrix, Inverted> {
        let mut k = SparseMatrix::zeros(self.pattern.clone());
        for colour in 0..self.colours() {
            self.chunked(
                |p| {
                    let fr = &self.frozen[p];
                    // The seeded owner node of this colour in the stencil, if any.
                    let mut seeded = None;
                    let g = delta_f::<f64, DualSVec64<L>, D>(&fr.stencil, |flat, c| {
                        let v = self.dofs.value(flat, c, x);
                        match self.dofs.get(flat, c) {
                            NodeDof::Free { dof, sign } if self.colour(dof) == colour => {
                                seeded = Some(self.dofs.owner_of(dof).0);
                                let mut e = nalgebra::SVector::<f64, L>::zeros();
                                e[c] = sign;
                                DualSVec64::<L>::new(v, num_dual::Derivative::some(e))
                            }
                            _ => DualSVec64::<L>::from_re(v),
                        }
                    });
                    particle_stress(&mats[fr.material], fr, &g).map(|s| (seeded, s.0))
                },
                |p, (seeded, s)| {
                    let Some(owner) = seeded else { return };
                    self.frozen[p].stencil.for_each(|node| {
                        let fi = s * node.gradient.map(DualSVec64::<L>::from_re);
                        for r in 0..D {
                            let NodeDof::Free { dof: row, sign: sr } = self.dofs.get(node.flat, r)
                            else {
                                continue;
                            };
                            let Some(eps) = fi[r].eps.0.as_ref() else {
                                continue;
                            };
                            for c in 0..D {
                                if let NodeDof::Free { dof: col, .. } = self.dofs.get(owner, c) {
                                    k.values[self.slot(row, col)] += sr * eps[c];
                                }
                            }
                        }
                    });
                },
            )?;
        }
        self.add_inertia(&mut k);
        Ok(k)
    }

    /// Number of node colours, `b^D`.
    pub(crate) fn colours(&self) -> usize {
        self.b.pow(D as u32)
    }

    /// The background grid of the step.
    pub fn grid(&self) -> &Grid<D> {
        &self.grid
    }

    /// Colour `(i mod b, j mod b, k mod b)` of the owner node of unknown `dof`.
    #[inline]
    pub(crate) fn colour(&self, dof: usize) -> usize {
        let idx = self.grid.multi(self.dofs.owner_of(dof).0);
        let mut c = 0;
        for a in (0..D).rev() {
            c = c * self.b + idx[a] % self.b;
        }
        c
    }

    /// The converged particle update: `F = ΔF Fⁿ`, history, Cauchy stress `σ = τ / J` (the
    /// effective stress of a coupled step) and excess pore pressure, the displacement `Σ_i N_i Δu_i` and, for a dynamic step, the particle velocity increment
    /// `Σ_i N_i Δv_i` and acceleration `Σ_i N_i aₙ₊₁,i` from the step's [`GridMotion`]
    /// (see [`Inertia`]).
    pub fn particle_updates(
        &self,
        x: &[f64],
        motion: Option<&GridMotion>,
        materials: &Materials,
    ) -> Result<Vec<ParticleUpdate<D>>, Inverted> {
        (0..self.frozen.len())
            .into_par_iter()
            .map(|p| {
                let fr = &self.frozen[p];
                let g = self.delta_f_real(p, x);
                let (tau, state, excess, content) = match &self.flow {
                    Some(_) => {
                        let c = self
                            .coupled_real(p, x, materials)
                            .ok_or(Inverted { particle: p })?;
                        (c.tau, c.state, c.excess, c.content)
                    }
                    None => {
                        let (_, tau, state) = particle_stress(&materials.real[fr.material], fr, &g)
                            .ok_or(Inverted { particle: p })?;
                        (tau, state, 0.0, 0.0)
                    }
                };
                let f = g * fr.f_n;
                let j = det(&f);
                let mut u = Vector::<f64, D>::zeros();
                let (mut dv, mut acc) = (Vector::<f64, D>::zeros(), Vector::<f64, D>::zeros());
                fr.stencil.for_each(|n| {
                    for a in 0..D {
                        u[a] += n.weight * self.dofs.value(n.flat, a, x);
                        if let Some(m) = motion {
                            dv[a] += n.weight * self.dofs.field(n.flat, a, &m.velocity_increment);
                            acc[a] += n.weight * self.dofs.field(n.flat, a, &m.acceleration);
                        }
                    }
                });
                Ok(ParticleUpdate {
                    displacement: u,
                    velocity_increment: dv,
                    acceleration: acc,
                    f,
                    stress: tau / j,
                    state,
                    excess_pore_pressure: excess,
                    fluid_content: content,
                })
            })
            .collect()
    }
}

/// What a converged load step changes on a particle.
#[derive(Clone, Debug)]
pub struct ParticleUpdate<const D: usize> {
    /// Displacement over the step.
    pub displacement: Vector<f64, D>,
    /// Change of the particle velocity, `Σ_i N_i Δv_i` (zero when quasi-static).
    pub velocity_increment: Vector<f64, D>,
    /// End-of-step acceleration `Σ_i N_i aₙ₊₁,i` (zero when quasi-static).
    pub acceleration: Vector<f64, D>,
    /// New deformation gradient.
    pub f: Tensor<f64, D>,
    /// New Cauchy stress (3×3).
    pub stress: Matrix3<f64>,
    /// New history.
    pub state: loam_core::MaterialState<f64>,
    /// Excess pore pressure `p_e` at the end of a coupled step (Pa, compression positive;
    /// zero otherwise).
    pub excess_pore_pressure: f64,
    /// Fluid-content change `ΔΞ` over a coupled step, the volume of water the particle
    /// expelled ([`crate::flow::Coupled::content`]; m³, m² in 2D; zero otherwise).
    pub fluid_content: f64,
}
