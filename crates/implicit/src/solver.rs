//! Load stepping: freeze the particles, solve the step with Newton, commit, and cut the step
//! in half when Newton fails.

use crate::dofs::{DofMap, NodeDof};
use crate::flow::{Flow, FlowFrozen, PoreFluid, TimeIntegration};
use crate::kernel::Frozen;
use crate::linear::{LinearSolver, LinearSolverKind, SparseMatrix};
use crate::newton::{NewtonReport, NewtonSettings, solve};
use crate::system::{Controlled, Inverted, Materials, ParticleUpdate, StepSystem, Structure};
use loam_core::stencil::particle_half_width;
use loam_core::tensor::Vector;
use loam_core::{Boundary, Grid, Material, NodeConstraint, Particles, PointLoad, Shape, Stencil};
use std::sync::{Arc, Mutex};
use thiserror::Error;

/// Everything a quasi-static implicit run needs besides the particles.
#[derive(Clone, Debug)]
pub struct ImplicitConfig<const D: usize> {
    /// Background grid (reset every load step).
    pub grid: Grid<D>,
    /// Shape functions.
    pub shape: Shape,
    /// Walls on the grid faces.
    pub boundary: Boundary<D>,
    /// Material table.
    pub materials: Vec<Material<f64>>,
    /// Gravity, ramped with the load factor (in full from the first step with
    /// [`ImplicitConfig::gravity_in_full`] or in dynamics).
    pub gravity: Vector<f64, D>,
    /// Prescribed displacements and force-controlled rigid groups of grid nodes (ramped).
    pub constraints: Vec<NodeConstraint<D>>,
    /// Point loads on particles (ramped).
    pub point_loads: Vec<PointLoad<D>>,
    /// Number of equal load steps from load factor 0 to 1.
    pub load_steps: usize,
    /// Newton settings.
    pub newton: NewtonSettings,
    /// Newmark dynamics (β = ¼, γ = ½) with this time step: each load step is a time step
    /// of `dt` (cut steps are shorter), gravity and point loads act in full from the start and
    /// prescribed displacements ramp over the steps. `None`: quasi-static.
    pub dynamics: Option<f64>,
    /// Quasi-static runs: gravity acts in full from the first load step instead of ramping
    /// with the load factor, for particles that start from a stress at rest under it (a
    /// geostatic / K0 state); point loads and prescribed displacements still ramp.
    pub gravity_in_full: bool,
    /// A node takes part in a load step when its particle support `Σ_p w_ip V_p` exceeds
    /// this fraction of a cell volume (1e-4 by default; see `ImplicitConfig::DEFAULT_MIN_NODE_SUPPORT`).
    /// A node below it keeps `Δu = 0` in a quasi-static step and follows an active neighbour
    /// in a dynamic one.
    pub min_node_support: f64,
    /// Per particle, a force that acts in full at every step (N; N per m in 2D): the balance
    /// of a prestressed body's initial stress against gravity on the grid
    /// ([`crate::balance`]). Empty: none.
    pub balance: Vec<Vector<f64, D>>,
    /// The pore fluid of a coupled (u–p) run: every step then solves for the excess pore
    /// pressure too, over the time its schedule gives, with the loads following the
    /// schedule's load factor. `None`: the solid alone.
    pub pore_fluid: Option<PoreFluid<D>>,
}

impl<const D: usize> ImplicitConfig<D> {
    /// Default of [`ImplicitConfig::min_node_support`]: a quadratic B-spline weight of 1e-4
    /// is a particle 0.014 h inside the edge of the support.
    pub const DEFAULT_MIN_NODE_SUPPORT: f64 = 1e-4;
}

/// Why a load step could not be completed.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ImplicitError {
    /// Invalid configuration.
    #[error("{field}: {msg}")]
    Config {
        /// Offending field.
        field: String,
        /// What was expected.
        msg: String,
    },
    /// Newton failed even after cutting the step `cuts` times.
    #[error(
        "load step {step} (load factor {from:.6} → {to:.6}) failed after {cuts} cut(s): {reason}"
    )]
    NoConvergence {
        /// Load step.
        step: usize,
        /// Load factor at the start of the failed attempt.
        from: f64,
        /// Target load factor of the failed attempt.
        to: f64,
        /// Cuts tried.
        cuts: usize,
        /// Newton iterations of every attempt of the step, failed ones included.
        iterations: usize,
        /// The last failure.
        reason: String,
    },
    /// A particle's start-of-step state has no stress (its deformation gradient is not
    /// invertible).
    #[error(
        "load step {step}: particle {particle} starts the step with a deformation gradient that is not invertible"
    )]
    InvalidState {
        /// Load step.
        step: usize,
        /// Particle id.
        particle: usize,
    },
    /// A particle's support left the grid.
    #[error("load step {step}: particle {particle} left the grid at {position:?}")]
    LeftGrid {
        /// Load step.
        step: usize,
        /// Particle id.
        particle: usize,
        /// Its position.
        position: Vec<f64>,
    },
}

/// What one load step did.
#[derive(Clone, Debug, PartialEq)]
pub struct StepReport<const D: usize> {
    /// Load step number (1-based).
    pub step: usize,
    /// Load factor reached.
    pub load_factor: f64,
    /// Unknowns of the (last) system.
    pub unknowns: usize,
    /// Newton solves of the step in order: one per sub-step, failed attempts included.
    pub solves: Vec<NewtonReport>,
    /// Times the step was cut.
    pub cuts: usize,
    /// Per entry of `ImplicitConfig::constraints`, the total force the prescribed components
    /// exert on the material at the end of the step (the reaction; N per m in 2D); for a
    /// force-controlled component, the applied force it balances.
    pub constraint_forces: Vec<Vector<f64, D>>,
    /// Per entry of `ImplicitConfig::constraints`, the total displacement (m) of its
    /// force-controlled components since the start of the run, the motion of the rigid
    /// group; zero for the other components.
    pub constraint_displacements: Vec<Vector<f64, D>>,
}

impl<const D: usize> StepReport<D> {
    /// Newton iterations of the converged solves.
    pub fn iterations(&self) -> usize {
        self.solves
            .iter()
            .filter(|s| s.converged)
            .map(|s| s.iterations())
            .sum()
    }

    /// Newton iterations of every solve, failed attempts included.
    pub fn attempted_iterations(&self) -> usize {
        self.solves.iter().map(|s| s.iterations()).sum()
    }
}

/// A converged (sub-)step from load factor `from` to `to`, as [`ImplicitSolver::step_observed`]
/// accepts it.
#[derive(Clone, Copy, Debug)]
pub struct AcceptedStep<'a, const D: usize> {
    /// The load step it belongs to (1-based).
    pub step: usize,
    /// Load factor at its start.
    pub from: f64,
    /// Load factor at its end.
    pub to: f64,
    /// The particles at its start.
    pub start: &'a Particles<f64, D>,
    /// The converged unknowns `Δu` of
    /// [`ImplicitSolver::system_after`]`(start, from, to, history)`.
    pub solution: &'a [f64],
    /// What a BDF2 step read of the step before it (`None` for every other step).
    pub history: Option<&'a FluidHistory>,
    /// The linear solver of its Newton iterations, holding (for LU) the factors of the last
    /// tangent ([`LinearSolver::factorisation`]).
    pub linear: &'a LinearSolver,
    /// A coupled step's stabilisation tangent, a constant of the step
    /// ([`crate::flow::Flow::stabilisation`]), once a tangent has assembled it.
    pub stabilisation: Option<&'a SparseMatrix>,
}

/// Lets every node that particles reach but that is too weakly supported to take part in the
/// step follow an active node instead of staying put. With `Δu_j = 0`, a particle whose stencil
/// reaches node `j` with weight `w` is strained by `Δu ⊗ ∇N_j` (`|∇N_j| ≈ √(2w)/h` for quadratic
/// B-splines) by any translation of the step, which does work and breaks rigid motion. The
/// node follows the best-supported active node inside every stencil that reaches it (the
/// intersection of the stencil boxes), so the sparsity pattern is unchanged; if there is none,
/// it stays at `Δu = 0`.
fn follow_weak_nodes<const D: usize>(
    grid: &Grid<D>,
    frozen: &[Frozen<D>],
    support: &[f64],
    active: &[bool],
    dofs: &mut DofMap<D>,
) {
    // Per inactive node, the intersection [lo, hi) of the stencil boxes holding it.
    let mut boxes: Vec<Option<([isize; D], [isize; D])>> = vec![None; support.len()];
    for fr in frozen {
        let st = &fr.stencil;
        st.for_each(|n| {
            // Every stencil box that holds the node counts, zero weights included: the assembly
            // couples all the nodes of a box.
            if active[n.flat] {
                return;
            }
            let hi_p: [isize; D] = std::array::from_fn(|a| st.base[a] + st.b as isize);
            boxes[n.flat] = Some(match boxes[n.flat] {
                None => (st.base, hi_p),
                Some((lo, hi)) => (
                    std::array::from_fn(|a| lo[a].max(st.base[a])),
                    std::array::from_fn(|a| hi[a].min(hi_p[a])),
                ),
            });
        });
    }
    for (node, b) in boxes.iter().enumerate() {
        let Some((lo, hi)) = *b else { continue };
        let extent: [usize; D] = std::array::from_fn(|a| (hi[a] - lo[a]).max(0) as usize);
        let count: usize = extent.iter().product();
        let mut best: Option<usize> = None;
        for k in 0..count {
            let mut r = k;
            let idx: [usize; D] = std::array::from_fn(|a| {
                let i = lo[a] as usize + r % extent[a];
                r /= extent[a];
                i
            });
            let f = grid.flat(idx);
            if active[f] && best.is_none_or(|b| support[f] > support[b]) {
                best = Some(f);
            }
        }
        if let Some(target) = best {
            dofs.follow(node, target);
        }
    }
}

/// The quasi-static implicit solver.
pub struct ImplicitSolver<const D: usize> {
    config: ImplicitConfig<D>,
    materials: Materials,
    linear: LinearSolver,
    /// Cholesky of the regularised consistent mass for the end of Newmark steps.
    mass_solver: LinearSolver,
    load_factor: f64,
    steps: usize,
    /// The sparsity of the last step built, for the next one with the same unknowns.
    structure: Mutex<Option<Arc<Structure>>>,
    /// Total displacement of the force-controlled components of each constraint.
    constraint_displacements: Vec<Vector<f64, D>>,
    /// A coupled run with BDF2: the last accepted (sub-)step's time step and each particle's
    /// fluid-content change over it ([`crate::flow::TimeIntegration::Bdf2`]).
    fluid_history: Option<FluidHistory>,
}

/// What a BDF2 step needs of the (sub-)step before it
/// ([`crate::flow::TimeIntegration::Bdf2`]).
#[derive(Clone, Debug, PartialEq)]
pub struct FluidHistory {
    /// Its time step `Δtⁿ⁻¹` (s; zero for an undrained step).
    pub dt: f64,
    /// Per particle, its fluid-content change `ΔΞⁿ_p` (m³; m² in 2D).
    pub content: Vec<f64>,
    /// Per particle, its excess-pressure increment `Δp_eⁿ_p` (Pa).
    pub increment: Vec<f64>,
}

impl<const D: usize> ImplicitSolver<D> {
    /// A solver for `config` and its particles.
    pub fn new(
        config: ImplicitConfig<D>,
        particles: &Particles<f64, D>,
    ) -> Result<Self, ImplicitError> {
        let bad = |field: &str, msg: String| ImplicitError::Config {
            field: field.into(),
            msg,
        };
        if config.load_steps == 0 {
            return Err(bad("load_steps", "must be at least 1".into()));
        }
        if config.grid.pad < config.shape.ghost_cells() {
            return Err(bad(
                "grid.pad",
                format!(
                    "{:?} needs {} ghost cells",
                    config.shape,
                    config.shape.ghost_cells()
                ),
            ));
        }
        if let Some(p) = particles
            .material
            .iter()
            .position(|&m| m as usize >= config.materials.len())
        {
            return Err(bad(
                "particles.material",
                format!(
                    "particle {p} refers to material {}, but there are {}",
                    particles.material[p],
                    config.materials.len()
                ),
            ));
        }
        if let Some(l) = config
            .point_loads
            .iter()
            .find(|l| l.particle >= particles.len())
        {
            return Err(bad(
                "point_loads.particle",
                format!(
                    "particle {} does not exist ({} particles)",
                    l.particle,
                    particles.len()
                ),
            ));
        }
        if !config.balance.is_empty() && config.balance.len() != particles.len() {
            return Err(bad(
                "balance",
                format!(
                    "{} forces for {} particles",
                    config.balance.len(),
                    particles.len()
                ),
            ));
        }
        if let Some(fluid) = &config.pore_fluid {
            check_pore_fluid(&config, fluid)?;
        }
        check_constraints(&config)?;
        Ok(Self {
            constraint_displacements: vec![Vector::zeros(); config.constraints.len()],
            materials: Materials::new(config.materials.clone()),
            linear: LinearSolver::new(config.newton.linear),
            mass_solver: LinearSolver::new(LinearSolverKind::Cholesky),
            config,
            load_factor: 0.0,
            steps: 0,
            structure: Mutex::new(None),
            fluid_history: None,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &ImplicitConfig<D> {
        &self.config
    }

    /// Load factor reached (0 … 1).
    pub fn load_factor(&self) -> f64 {
        self.load_factor
    }

    /// The load factor the loads have reached: [`ImplicitSolver::load_factor`] for a run of
    /// the solid alone, the schedule's load factor at that progress for a coupled run.
    pub fn applied_load(&self) -> f64 {
        self.load_at(self.load_factor)
    }

    /// Load steps completed.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// `true` when the loading is complete.
    pub fn finished(&self) -> bool {
        self.steps >= self.config.load_steps
    }

    /// The material tables (real and lifted to the dual types of the tangents).
    pub fn materials(&self) -> &Materials {
        &self.materials
    }

    /// Builds the system of a (sub-)step from load factor `from` to `to` for the current
    /// particles: frozen particle data, unknown numbering, sparsity pattern and external force.
    /// [`ImplicitSolver::step`] calls it; it is public for benchmarks and tests.
    pub fn system(
        &self,
        p: &Particles<f64, D>,
        from: f64,
        to: f64,
    ) -> Result<StepSystem<D>, ImplicitError> {
        self.system_after(p, from, to, self.fluid_history.as_ref())
    }

    /// [`ImplicitSolver::system`] of a step that follows one whose BDF2 history is `history`
    /// (`None`: a backward-Euler step): how the adjoint rebuilds a recorded step.
    ///
    /// # Errors
    /// As [`ImplicitSolver::system`].
    pub fn system_after(
        &self,
        p: &Particles<f64, D>,
        from: f64,
        to: f64,
        history: Option<&FluidHistory>,
    ) -> Result<StepSystem<D>, ImplicitError> {
        let cfg = &self.config;
        let grid = &cfg.grid;
        let mut frozen = Vec::with_capacity(p.len());
        let mut support = vec![0.0; grid.num_nodes()];
        for i in 0..p.len() {
            let hw = particle_half_width(cfg.shape, grid.h, &p.half_width0[i], &p.f[i]);
            let st = Stencil::new(cfg.shape, grid, &p.x[i], &hw);
            if !st.on_grid(grid) {
                return Err(ImplicitError::LeftGrid {
                    step: self.steps + 1,
                    particle: i,
                    position: p.x[i].iter().copied().collect(),
                });
            }
            st.for_each(|n| support[n.flat] += n.weight * p.volume0[i]);
            frozen.push(Frozen {
                stencil: st,
                f_n: p.f[i],
                state: p.state[i],
                volume0: p.volume0[i],
                material: p.material[i] as usize,
            });
        }
        // Nodes whose particle support `Σ_p w_ip V_p` is a tiny fraction of a full cell carry
        // a tiny stiffness and make the tangent near-singular (a particle at the very edge of
        // a B-spline support); they are left out as unknowns and follow an active neighbour
        // (`follow_weak_nodes`). Held at Δu = 0 they would pin the particles touching them,
        // and every converged step would freeze that into F (a beam stiffening with the
        // number of load steps, `docs/verification.md`).
        let full = grid.h.powi(D as i32);
        let active: Vec<bool> = support
            .iter()
            .map(|&s| s > cfg.min_node_support * full)
            .collect();
        let (from_load, to_load) = (self.load_at(from), self.load_at(to));
        let dl = to_load - from_load;
        let prescribed = |node: [usize; D], c: usize| {
            let x: Vector<f64, D> = grid.node_position(node);
            let xa: [f64; D] = std::array::from_fn(|a| x[a]);
            cfg.constraints
                .iter()
                .rev()
                .find(|k| k.displacement[c].is_some() && k.contains(&xa, grid.h))
                .and_then(|k| k.displacement[c].map(|u| u * dl))
        };
        let mut dofs = match &cfg.pore_fluid {
            None => DofMap::new(grid, &cfg.boundary, &active, prescribed),
            Some(fluid) => {
                DofMap::coupled(grid, &cfg.boundary, &fluid.drained, &active, |node, c| {
                    if c < D {
                        return prescribed(node, c);
                    }
                    // No excess pressure above the water table.
                    let x: Vector<f64, D> = grid.node_position(node);
                    fluid
                        .water_table
                        .is_some_and(|z| x[D - 1] > z + 1e-9 * grid.h)
                        .then_some(0.0)
                })
            }
        };
        follow_weak_nodes(grid, &frozen, &support, &active, &mut dofs);
        // Force-controlled components: the free components of the nodes in the box share
        // one unknown, which carries the force. Each tie renumbers the unknowns, so a group is
        // remembered by one of its members and its unknown looked up once all are tied.
        let mut shared_forces = Vec::new();
        for (i, k) in cfg.constraints.iter().enumerate() {
            for c in 0..D {
                let Some(force) = k.force[c] else { continue };
                let members: Vec<(usize, usize)> = (0..grid.num_nodes())
                    .filter(|&f| {
                        let x: Vector<f64, D> = grid.node_position(grid.multi(f));
                        k.contains(&std::array::from_fn(|a| x[a]), grid.h)
                    })
                    .map(|f| (f, c))
                    .collect();
                let dof = dofs.tie(&members).ok_or_else(|| ImplicitError::Config {
                    field: format!("constraints[{i}].force"),
                    msg: format!(
                        "no grid node in the box [{:?}, {:?}] moves with the particles in load \
                         step {}: a force-controlled box must hold nodes of the body's surface",
                        k.lo,
                        k.hi,
                        self.steps + 1
                    ),
                })?;
                let member = (members.iter())
                    .find(|&&(f, c)| matches!(dofs.get(f, c), NodeDof::Free { dof: d, .. } if d == dof))
                    .copied()
                    .expect("a member holds the shared unknown");
                shared_forces.push((i, c, member, force));
            }
        }
        // Quasi-static loads ramp with the load factor; dynamic loads act in full, and so do
        // gravity on a prestressed body and its balance.
        let factor = if cfg.dynamics.is_some() { 1.0 } else { to_load };
        let g_factor = if cfg.gravity_in_full { 1.0 } else { factor };
        let mut loads = vec![Vector::<f64, D>::zeros(); p.len()];
        for l in &cfg.point_loads {
            loads[l.particle] += Vector::<f64, D>::from(l.force) * factor;
        }
        let previous = self.structure.lock().map_or(None, |s| s.clone());
        let force = |i: usize| {
            let balance = cfg.balance.get(i).copied().unwrap_or_else(Vector::zeros);
            p.mass[i] * g_factor * cfg.gravity + loads[i] + balance
        };
        let mut system = StepSystem::reusing(grid, frozen, dofs, force, previous.as_ref());
        for (constraint, component, (f, c), force) in shared_forces {
            let NodeDof::Free { dof, .. } = system.dofs.get(f, c) else {
                unreachable!("a tied member stays free")
            };
            system.f_ext[dof] += force * factor;
            system.controlled.push(Controlled {
                constraint,
                component,
                dof,
                factor,
            });
        }
        if let Ok(mut cache) = self.structure.lock() {
            *cache = Some(system.structure().clone());
        }
        if let Some(fluid) = &cfg.pore_fluid {
            system.flow = Some(self.flow(fluid, p, from, to, history));
            system.add_inflow(&fluid.inflow);
        }
        if let Some(dt) = cfg.dynamics {
            let step_dt = dt * cfg.load_steps as f64 * dl;
            system
                .set_dynamic(step_dt, &p.mass, &p.v, &self.materials)
                .map_err(|Inverted { particle }| ImplicitError::InvalidState {
                    step: self.steps + 1,
                    particle,
                })?;
        }
        Ok(system)
    }

    /// The load factor at run progress `s` (the schedule's for a coupled run).
    fn load_at(&self, s: f64) -> f64 {
        match &self.config.pore_fluid {
            Some(fluid) => fluid.schedule.at(s).1,
            None => s,
        }
    }

    /// Time reached (s): the schedule's at the progress made; zero for a run of the solid
    /// alone.
    pub fn time(&self) -> f64 {
        self.config
            .pore_fluid
            .as_ref()
            .map_or(0.0, |f| f.schedule.at(self.load_factor).0)
    }

    /// The pore fluid of the (sub-)step from progress `from` to `to` (module docs of
    /// [`crate::flow`]): the time step, the scale `G_ref/h` with `G_ref` the volume-weighted
    /// mean shear modulus of the particles, and per particle the start-of-step excess and
    /// hydrostatic pressures and the stabilisation weight `Vⁿ/G`; the stabilisation's patches
    /// group the particles by grid cell, in a deterministic order. A BDF2 step carries `c₁`
    /// of each particle's last fluid-content change and weights its flows by `c₂`
    /// ([`crate::flow::TimeIntegration::weights`]).
    fn flow(
        &self,
        fluid: &PoreFluid<D>,
        p: &Particles<f64, D>,
        from: f64,
        to: f64,
        history: Option<&FluidHistory>,
    ) -> Flow {
        let dt = fluid.schedule.at(to).0 - fluid.schedule.at(from).0;
        let history = history.filter(|h| h.content.len() == p.len());
        let (carry, weight) = fluid
            .time_integration
            .weights(dt, history.map_or(0.0, |h| h.dt));
        let shear: Vec<f64> = (0..p.len())
            .map(|i| {
                self.config.materials[p.material[i] as usize]
                    .shear_modulus_in(&p.state[i])
                    .max(f64::MIN_POSITIVE)
            })
            .collect();
        let volume: Vec<f64> = (0..p.len())
            .map(|i| p.volume0[i] * loam_core::tensor::det(&p.f[i]))
            .collect();
        let total: f64 = volume.iter().sum();
        let g_ref = shear.iter().zip(&volume).map(|(g, v)| g * v).sum::<f64>() / total;
        let mut particles: Vec<FlowFrozen> = (0..p.len())
            .map(|i| {
                let hydrostatic = fluid.hydrostatic(&p.x[i]);
                FlowFrozen {
                    excess: p.pore_pressure[i] - hydrostatic,
                    hydrostatic,
                    weight: volume[i] / shear[i],
                    leakage: 0.0,
                    carried: history.map_or(0.0, |h| carry * h.content[i]),
                    carried_increment: history.map_or(0.0, |h| carry * h.increment[i]),
                }
            })
            .collect();
        for d in &fluid.drains {
            let mobility = fluid.hydraulic[p.material[d.particle] as usize].mobility;
            particles[d.particle].leakage = mobility * d.conductance;
        }
        let patches = if fluid.stabilisation {
            let grid = &self.config.grid;
            let origin = grid.origin();
            let mut by_cell = std::collections::BTreeMap::<Vec<i64>, Vec<usize>>::new();
            for (i, x) in p.x.iter().enumerate() {
                let cell = (0..D)
                    .map(|a| ((x[a] - origin[a]) / grid.h).floor() as i64)
                    .collect();
                by_cell.entry(cell).or_default().push(i);
            }
            by_cell.into_values().collect()
        } else {
            Vec::new()
        };
        Flow {
            dt: weight * dt,
            carry: if history.is_some() { carry } else { 0.0 },
            scale: g_ref / self.config.grid.h,
            hydraulic: fluid.hydraulic.clone(),
            particles,
            patches,
            stabilisation: std::sync::OnceLock::new(),
        }
    }

    /// Reaction of every user constraint: on a prescribed component, the internal force on
    /// the grid nodes inside its box; on a force-controlled one, the internal force on the
    /// unknown its group shares, `Σ_{i ↦ w} sign_i f_i` (which balances the applied force;
    /// nodes of the box that a wall holds on that axis push on the wall, not the group).
    fn constraint_forces(&self, system: &StepSystem<D>, x: &[f64]) -> Vec<Vector<f64, D>> {
        let Ok(f) = system.nodal_internal_force(x, &self.materials) else {
            return vec![Vector::zeros(); self.config.constraints.len()];
        };
        let grid = &self.config.grid;
        let mut totals: Vec<Vector<f64, D>> = (self.config.constraints.iter())
            .map(|k| {
                let mut total = Vector::<f64, D>::zeros();
                for (n, fn_) in f.iter().enumerate() {
                    let pos: Vector<f64, D> = grid.node_position(grid.multi(n));
                    if k.contains(&std::array::from_fn(|a| pos[a]), grid.h) {
                        for a in (0..D).filter(|&a| k.displacement[a].is_some()) {
                            total[a] += fn_[a];
                        }
                    }
                }
                total
            })
            .collect();
        for c in &system.controlled {
            for (n, fn_) in f.iter().enumerate() {
                if let NodeDof::Free { dof, sign } = system.dofs.get(n, c.component)
                    && dof == c.dof
                {
                    totals[c.constraint][c.component] += sign * fn_[c.component];
                }
            }
        }
        totals
    }

    /// Adds the converged increment `x` of every force-controlled component to its total:
    /// the value of the shared unknown at any node of the group.
    fn add_constraint_displacements(&mut self, system: &StepSystem<D>, x: &[f64]) {
        let grid = &self.config.grid;
        for (k, total) in self
            .config
            .constraints
            .iter()
            .zip(&mut self.constraint_displacements)
        {
            for c in (0..D).filter(|&c| k.force[c].is_some()) {
                let member = (0..grid.num_nodes()).find(|&f| {
                    let pos: Vector<f64, D> = grid.node_position(grid.multi(f));
                    k.contains(&std::array::from_fn(|a| pos[a]), grid.h)
                        && matches!(system.dofs.get(f, c), NodeDof::Free { .. })
                });
                if let Some(f) = member {
                    total[c] += system.dofs.value(f, c, x);
                }
            }
        }
    }

    /// The particle updates of a converged (sub-)step `x`, with the grid motion of a Newmark
    /// step (see [`crate::system::Inertia`]); `Err` says why the attempt must be cut.
    fn particle_updates(
        &mut self,
        system: &StepSystem<D>,
        x: &[f64],
    ) -> Result<Vec<ParticleUpdate<D>>, String> {
        let motion = match &system.inertia {
            Some(inertia) => Some(
                inertia
                    .grid_motion(x, &mut self.mass_solver)
                    .map_err(|e| format!("mass matrix: {e}"))?,
            ),
            None => None,
        };
        system
            .particle_updates(x, motion.as_ref(), &self.materials)
            .map_err(|Inverted { particle }| {
                format!("the converged state inverts particle {particle}")
            })
    }

    /// Advances one load step (cutting it into halves as needed) and updates the particles.
    pub fn step(
        &mut self,
        particles: &mut Particles<f64, D>,
    ) -> Result<StepReport<D>, ImplicitError> {
        self.step_observed(particles, |_| {})
    }

    /// [`ImplicitSolver::step`], handing every accepted (sub-)step to `accepted` before the
    /// particles take its update: a step cut into halves is the sequence of its accepted
    /// sub-steps, in order. [`ImplicitSolver::system`] on [`AcceptedStep::start`] with its load
    /// factors rebuilds the same system, so a reverse pass needs nothing else.
    pub fn step_observed(
        &mut self,
        particles: &mut Particles<f64, D>,
        mut accepted: impl FnMut(AcceptedStep<'_, D>),
    ) -> Result<StepReport<D>, ImplicitError> {
        let target = self.target();
        let mut report = self.new_report();
        let mut from = self.load_factor;
        let mut size = target - from;
        while target - from > 1e-12 * size.max(1e-300) {
            let to = (from + size).min(target);
            match self.attempt(particles, &mut report, from, to, &mut accepted)? {
                None => from = to,
                Some(reason) => {
                    if report.cuts >= self.config.newton.max_cuts {
                        return Err(ImplicitError::NoConvergence {
                            step: report.step,
                            from,
                            to,
                            cuts: report.cuts,
                            iterations: report.attempted_iterations(),
                            reason,
                        });
                    }
                    report.cuts += 1;
                    size *= 0.5;
                }
            }
        }
        Ok(self.finish(report))
    }

    /// The next load step as the given sequence of sub-steps, ending at the load factors
    /// `ends` (the last one is the step's target, `(steps + 1) / load_steps`), without
    /// cutting: replays the sub-steps of another run, so that a run at perturbed parameters
    /// takes the step sizes a reference run took ([`StepReport::cuts`] counts the sub-steps
    /// beyond the first).
    ///
    /// # Errors
    /// `ends` that do not increase to the step's target (`Config` naming `ends`), or a
    /// sub-step that does not converge (`NoConvergence` with no cut).
    pub fn step_planned(
        &mut self,
        particles: &mut Particles<f64, D>,
        ends: &[f64],
        mut accepted: impl FnMut(AcceptedStep<'_, D>),
    ) -> Result<StepReport<D>, ImplicitError> {
        let target = self.target();
        let increasing = ends
            .iter()
            .try_fold(self.load_factor, |from, &to| (to > from).then_some(to));
        if increasing.is_none_or(|last| (last - target).abs() > 1e-12) {
            return Err(ImplicitError::Config {
                field: "ends".into(),
                msg: format!(
                    "sub-step ends {ends:?} must increase from {} to {target}",
                    self.load_factor
                ),
            });
        }
        let mut report = self.new_report();
        let mut from = self.load_factor;
        for &to in ends {
            if let Some(reason) = self.attempt(particles, &mut report, from, to, &mut accepted)? {
                return Err(ImplicitError::NoConvergence {
                    step: report.step,
                    from,
                    to,
                    cuts: 0,
                    iterations: report.attempted_iterations(),
                    reason,
                });
            }
            from = to;
        }
        report.cuts = ends.len() - 1;
        Ok(self.finish(report))
    }

    /// Load factor at the end of the next load step.
    fn target(&self) -> f64 {
        (self.steps + 1) as f64 / self.config.load_steps as f64
    }

    /// The report of the next load step before any attempt.
    fn new_report(&self) -> StepReport<D> {
        StepReport {
            step: self.steps + 1,
            load_factor: self.load_factor,
            unknowns: 0,
            solves: Vec::new(),
            cuts: 0,
            constraint_forces: vec![Vector::zeros(); self.config.constraints.len()],
            constraint_displacements: self.constraint_displacements.clone(),
        }
    }

    /// Completes the load step of `report`.
    fn finish(&mut self, mut report: StepReport<D>) -> StepReport<D> {
        let target = self.target();
        self.steps += 1;
        self.load_factor = target;
        report.load_factor = target;
        report
    }

    /// One attempt of a sub-step from load factor `from` to `to`: on convergence the
    /// particles take its update (after `accepted` has seen it) and `Ok(None)` is returned;
    /// otherwise the particles are unchanged and `Ok(Some(reason))` says why it failed.
    fn attempt(
        &mut self,
        particles: &mut Particles<f64, D>,
        report: &mut StepReport<D>,
        from: f64,
        to: f64,
        accepted: &mut impl FnMut(AcceptedStep<'_, D>),
    ) -> Result<Option<String>, ImplicitError> {
        let system = self.system(particles, from, to)?;
        report.unknowns = system.len();
        system.prepare(&mut self.linear);
        let (x, newton) = solve(
            &system,
            &self.materials,
            &self.config.newton,
            &mut self.linear,
            self.config.grid.h,
        );
        let converged = newton.converged;
        let failure = newton.failure.clone();
        report.solves.push(newton);
        if !converged {
            return Ok(Some(failure.unwrap_or_default()));
        }
        let update = match self.particle_updates(&system, &x) {
            Ok(u) => u,
            Err(reason) => return Ok(Some(reason)),
        };
        report.constraint_forces = self.constraint_forces(&system, &x);
        self.add_constraint_displacements(&system, &x);
        report.constraint_displacements = self.constraint_displacements.clone();
        accepted(AcceptedStep {
            step: report.step,
            from,
            to,
            start: particles,
            solution: &x,
            history: system
                .flow
                .as_ref()
                .filter(|f| f.carry != 0.0)
                .and(self.fluid_history.as_ref()),
            linear: &self.linear,
            stabilisation: system.flow.as_ref().and_then(|f| f.stabilisation.get()),
        });
        if let Some(fluid) = &self.config.pore_fluid
            && fluid.time_integration == TimeIntegration::Bdf2
        {
            let start = &system.flow.as_ref().expect("a coupled step").particles;
            self.fluid_history = Some(FluidHistory {
                dt: fluid.schedule.at(to).0 - fluid.schedule.at(from).0,
                content: update.iter().map(|u| u.fluid_content).collect(),
                increment: (update.iter().zip(start))
                    .map(|(u, s)| u.excess_pore_pressure - s.excess)
                    .collect(),
            });
        }
        for (i, u) in update.into_iter().enumerate() {
            particles.x[i] += u.displacement;
            particles.v[i] += u.velocity_increment;
            particles.a[i] = u.acceleration;
            particles.f[i] = u.f;
            particles.stress[i] = u.stress;
            particles.state[i] = u.state;
            if let Some(fluid) = &self.config.pore_fluid {
                particles.pore_pressure[i] =
                    fluid.hydrostatic(&particles.x[i]) + u.excess_pore_pressure;
            }
        }
        self.load_factor = to;
        Ok(None)
    }
}

/// Checks the constraints: a component is prescribed or force-controlled, not both, and a
/// force-controlled group needs the per-particle tangent (the colour-seeded one assumes that
/// an unknown moves one node).
fn check_constraints<const D: usize>(config: &ImplicitConfig<D>) -> Result<(), ImplicitError> {
    for (i, k) in config.constraints.iter().enumerate() {
        if let Some(c) = (0..D).find(|&c| k.displacement[c].is_some() && k.force[c].is_some()) {
            return Err(ImplicitError::Config {
                field: format!("constraints[{i}]"),
                msg: format!("component {c} has both a displacement and a force"),
            });
        }
        if k.force.iter().any(Option::is_some)
            && config.newton.tangent == crate::newton::TangentMethod::Colour
        {
            return Err(ImplicitError::Config {
                field: format!("constraints[{i}].force"),
                msg: "a force-controlled group needs tangent = \"local\" (the colour-seeded \
                      tangent assumes each unknown moves one node)"
                    .into(),
            });
        }
    }
    Ok(())
}

/// Checks a coupled run's pore fluid against the rest of its configuration.
fn check_pore_fluid<const D: usize>(
    config: &ImplicitConfig<D>,
    fluid: &PoreFluid<D>,
) -> Result<(), ImplicitError> {
    let bad = |field: &str, msg: String| {
        Err(ImplicitError::Config {
            field: field.into(),
            msg,
        })
    };
    if fluid.hydraulic.len() != config.materials.len() {
        return bad(
            "pore_fluid.hydraulic",
            format!(
                "{} entries for {} materials",
                fluid.hydraulic.len(),
                config.materials.len()
            ),
        );
    }
    if config.dynamics.is_some() {
        return bad(
            "dynamics",
            "a coupled (u–p) run is quasi-static; Newmark dynamics is not available with a pore fluid".into(),
        );
    }
    let schedule = &fluid.schedule;
    if schedule.time.len() != config.load_steps + 1 || schedule.load.len() != schedule.time.len() {
        return bad(
            "pore_fluid.schedule",
            format!(
                "{} times and {} load factors for {} load steps (one more than the steps each)",
                schedule.time.len(),
                schedule.load.len(),
                config.load_steps
            ),
        );
    }
    let ordered = schedule.time.windows(2).all(|w| w[1] >= w[0]);
    if schedule.time[0] != 0.0 || !ordered || schedule.time.iter().any(|t| !t.is_finite()) {
        return bad(
            "pore_fluid.schedule.time",
            "must start at 0 and never decrease".into(),
        );
    }
    Ok(())
}
