//! The forward pass of an implicit run, keeping what the reverse pass needs.

use super::kernel::{Loads, ParticleState, Setting};
use crate::error::AdjointError;
use loam_core::Particles;
use loam_core::constitutive::MaterialState;
use loam_core::tensor::{Tensor, Vector};
use loam_implicit::linear::{Factorisation, LinearError, SparseMatrix, SparsePattern};
use loam_implicit::system::StepSystem;
use loam_implicit::{FluidHistory, ImplicitConfig, ImplicitSolver};
use std::sync::Arc;

/// One accepted (sub-)step: the particle state at its start, its load factors and its
/// converged unknowns. A load step cut into halves is the sequence of its accepted sub-steps.
#[derive(Clone, Debug)]
pub struct SubStep<const D: usize> {
    /// The load step it belongs to (1-based).
    pub step: usize,
    /// Load factor at its start.
    pub from: f64,
    /// Load factor at its end.
    pub to: f64,
    /// Positions at its start.
    pub x: Vec<Vector<f64, D>>,
    /// Deformation gradients at its start.
    pub f: Vec<Tensor<f64, D>>,
    /// Histories at its start.
    pub history: Vec<MaterialState<f64>>,
    /// Velocities at its start (constant in a quasi-static run).
    pub v: Vec<Vector<f64, D>>,
    /// Pore pressures at its start (a coupled run's; empty otherwise).
    pub pore_pressure: Vec<f64>,
    /// Converged unknowns `Δu`.
    pub solution: Vec<f64>,
    /// What it read of the sub-step before it as a BDF2 step (`None` for every other step).
    pub fluid_history: Option<FluidHistory>,
    /// The LU factors of its last Newton tangent, kept by [`run_for_gradient`] to
    /// precondition its adjoint solve ([`SubStep::solve_adjoint_near`]); `None` otherwise.
    pub factorisation: Option<Factorisation>,
    /// The values of its stabilisation tangent, kept with the factors (a constant of the
    /// step that its replay would otherwise assemble again); `None` otherwise.
    pub stabilisation: Option<Vec<f64>>,
}

/// A recorded implicit run (quasi-static or Newmark): per accepted sub-step what its reverse needs, and the
/// quantities observations read.
#[derive(Clone, Debug)]
pub struct Trajectory<const D: usize> {
    /// The accepted sub-steps in order.
    pub substeps: Vec<SubStep<D>>,
    /// Particle positions after each load step (entry 0: the initial positions).
    pub positions: Vec<Vec<Vector<f64, D>>>,
    /// Particle velocities after each load step (entry 0: the initial velocities).
    pub velocities: Vec<Vec<Vector<f64, D>>>,
    /// Particle pore pressures after each load step (entry 0: the initial ones; zeros in a
    /// run without a pore fluid).
    pub pore_pressures: Vec<Vec<f64>>,
    /// Per load step (entry `k − 1` for step `k`), the reaction of every constraint.
    pub reactions: Vec<Vec<Vector<f64, D>>>,
    /// Cut sub-steps taken (accepted sub-steps minus load steps).
    pub cuts: usize,
    /// Newton iterations of the converged solves.
    pub iterations: usize,
}

impl<const D: usize> SubStep<D> {
    /// The particles at the start of the sub-step: `initial` with this sub-step's positions,
    /// deformation gradients, histories and velocities.
    pub fn particles(&self, initial: &Particles<f64, D>) -> Particles<f64, D> {
        let mut p = initial.clone();
        p.x.clone_from(&self.x);
        p.f.clone_from(&self.f);
        p.state.clone_from(&self.history);
        p.v.clone_from(&self.v);
        p.pore_pressure.clone_from(&self.pore_pressure);
        p
    }

    /// The start state of particle `p` (`mass` from the run's constants).
    pub fn state(&self, p: usize, mass: f64) -> ParticleState<f64, D> {
        ParticleState {
            x: self.x[p],
            f: self.f[p],
            history: self.history[p],
            v: self.v[p],
            mass,
        }
    }

    /// Solves its adjoint system `Kᵀλ = rhs` (`K` its tangent at the converged unknowns, on
    /// `pattern`, given by the product `apply_transpose(v, out)`: `out = Kᵀ v`) by GMRES
    /// preconditioned with the kept factors of its last Newton tangent
    /// ([`Factorisation::solve_transpose`]): the two differ by the last correction, so a few
    /// products replace a factorisation. Returns whether it did; `false` (`lambda`
    /// unspecified) without kept factors, or where GMRES does not converge: the caller then
    /// solves `K` itself.
    ///
    /// # Errors
    /// A right-hand side that is not finite.
    pub fn solve_adjoint_near(
        &self,
        pattern: &Arc<SparsePattern>,
        apply_transpose: impl Fn(&[f64], &mut [f64]),
        rhs: &[f64],
        lambda: &mut [f64],
    ) -> Result<bool, LinearError> {
        match &self.factorisation {
            Some(near) => Ok(near
                .solve_transpose(pattern, apply_transpose, rhs, lambda)?
                .is_some()),
            None => Ok(false),
        }
    }

    /// Whether this is the last sub-step of its load step within `substeps` at index `i`.
    pub fn ends_step(substeps: &[SubStep<D>], i: usize) -> bool {
        substeps
            .get(i + 1)
            .is_none_or(|n| n.step != substeps[i].step)
    }
}

/// Per load step, the load factors at which its accepted sub-steps ended (one entry for a
/// step taken whole).
pub type Schedule = Vec<Vec<f64>>;

impl<const D: usize> Trajectory<D> {
    /// The sub-steps this run took, as a [`Schedule`] another run can replay.
    pub fn schedule(&self) -> Schedule {
        let mut out: Schedule = Vec::new();
        for (i, s) in self.substeps.iter().enumerate() {
            if i == 0 || self.substeps[i - 1].step != s.step {
                out.push(Vec::new());
            }
            if let Some(ends) = out.last_mut() {
                ends.push(s.to);
            }
        }
        out
    }
}

/// Newton iterations a replayed sub-step may take (at least).
pub const REPLAY_ITERATIONS: usize = 100;

/// Unknowns, summed over the sub-steps, whose LU factors [`run_for_gradient`] keeps; the
/// sub-steps beyond it factorise their adjoint systems afresh. The consolidation example's
/// factors (2D, 346 unknowns a sub-step) take 1.9 kB per unknown, so this is ~200 MB of
/// such factors; larger and 3D systems fill more per unknown, hence also
/// [`KEPT_PER_SUBSTEP`].
pub const KEPT_UNKNOWNS: usize = 100_000;

/// The largest sub-step (in unknowns) whose factors [`run_for_gradient`] keeps: the fill of
/// a sparse LU grows faster than its size (in 3D as `n^{4/3}` at best), so a large system's
/// factors are not copied once per sub-step.
pub const KEPT_PER_SUBSTEP: usize = 10_000;

/// [`run_recorded`] without a schedule, also keeping in each sub-step the LU factors of its
/// last Newton tangent (sub-steps of at most [`KEPT_PER_SUBSTEP`] unknowns, while their
/// unknowns sum to at most [`KEPT_UNKNOWNS`]) for the
/// reverse pass's solves ([`SubStep::solve_adjoint_near`]). A run whose linear solver is not LU
/// keeps none.
///
/// # Errors
/// As [`run_recorded`].
pub fn run_for_gradient<const D: usize>(
    config: &ImplicitConfig<D>,
    initial: &Particles<f64, D>,
) -> Result<Trajectory<D>, AdjointError> {
    record(config, initial, None, KEPT_UNKNOWNS)
}

/// Runs the loading (quasi-static or Newmark) of `config` from `initial`, recording every accepted
/// sub-step. With a `schedule` the load steps are taken as its sub-steps, without cutting
/// (`ImplicitSolver::step_planned`): the gradient is that of the run with the step sizes
/// taken, so finite differences and Taylor tests compare runs with the same sub-steps (a
/// perturbed run whose Newton needs one more iteration would otherwise cut a step the
/// reference run did not, a different discrete map).
///
/// # Errors
/// A schedule for another number of load steps, or a run that is refused or stops.
pub fn run_recorded<const D: usize>(
    config: &ImplicitConfig<D>,
    initial: &Particles<f64, D>,
    schedule: Option<&Schedule>,
) -> Result<Trajectory<D>, AdjointError> {
    record(config, initial, schedule, 0)
}

/// [`run_recorded`], keeping the last tangent's factors of the sub-steps while their
/// unknowns sum to at most `keep`.
fn record<const D: usize>(
    config: &ImplicitConfig<D>,
    initial: &Particles<f64, D>,
    schedule: Option<&Schedule>,
    mut keep: usize,
) -> Result<Trajectory<D>, AdjointError> {
    if let Some(s) = schedule.filter(|s| s.len() != config.load_steps) {
        return Err(AdjointError::Unsupported {
            what: format!("a schedule of {} load steps", s.len()),
            why: format!("the scene has {} load steps", config.load_steps),
        });
    }
    // A replayed sub-step is not cut, so its Newton may take more iterations than the
    // reference's: the map is the sub-step's root, not the iteration that finds it.
    let mut config = config.clone();
    if schedule.is_some() {
        config.newton.max_iterations = config.newton.max_iterations.max(REPLAY_ITERATIONS);
    }
    let mut solver = ImplicitSolver::new(config, initial)?;
    let mut particles = initial.clone();
    let mut out = Trajectory {
        substeps: Vec::new(),
        positions: vec![initial.x.clone()],
        velocities: vec![initial.v.clone()],
        pore_pressures: vec![initial.pore_pressure.clone()],
        reactions: Vec::new(),
        cuts: 0,
        iterations: 0,
    };
    while !solver.finished() {
        let substeps = &mut out.substeps;
        let keep = &mut keep;
        let record = |a: loam_implicit::AcceptedStep<'_, D>| {
            let factorisation = (a.solution.len() <= (*keep).min(KEPT_PER_SUBSTEP))
                .then(|| a.linear.factorisation())
                .flatten();
            *keep -= factorisation.as_ref().map_or(0, Factorisation::n);
            let stabilisation = (factorisation.is_some())
                .then(|| a.stabilisation.map(|m| m.values.clone()))
                .flatten();
            substeps.push(SubStep {
                step: a.step,
                from: a.from,
                to: a.to,
                x: a.start.x.clone(),
                f: a.start.f.clone(),
                history: a.start.state.clone(),
                v: a.start.v.clone(),
                pore_pressure: a.start.pore_pressure.clone(),
                solution: a.solution.to_vec(),
                fluid_history: a.history.cloned(),
                factorisation,
                stabilisation,
            });
        };
        let report = match schedule {
            Some(s) => solver.step_planned(&mut particles, &s[solver.steps()], record)?,
            None => solver.step_observed(&mut particles, record)?,
        };
        out.iterations += report.iterations();
        out.positions.push(particles.x.clone());
        out.velocities.push(particles.v.clone());
        out.pore_pressures.push(particles.pore_pressure.clone());
        out.reactions.push(report.constraint_forces);
    }
    out.cuts = out.substeps.len() - solver.config().load_steps;
    Ok(out)
}

/// What the reverse and the tangent pass rebuild of one sub-step: its system and, per
/// particle, the setting and loads of [`super::kernel::particle_step`].
pub struct Replay<'a, const D: usize> {
    /// The sub-step.
    pub sub: &'a SubStep<D>,
    /// Its system, rebuilt from the recorded start state.
    pub system: StepSystem<D>,
    config: &'a ImplicitConfig<D>,
    initial: &'a Particles<f64, D>,
    point: Vec<Vector<f64, D>>,
}

impl<'a, const D: usize> Replay<'a, D> {
    /// Rebuilds sub-step `sub` of a run of `solver` from `initial`.
    ///
    /// # Errors
    /// A system that cannot be rebuilt (it was built in the forward pass, so only a changed
    /// configuration gets here).
    pub fn new(
        solver: &'a ImplicitSolver<D>,
        initial: &'a Particles<f64, D>,
        sub: &'a SubStep<D>,
    ) -> Result<Self, AdjointError> {
        let config = solver.config();
        let system = solver.system_after(
            &sub.particles(initial),
            sub.from,
            sub.to,
            sub.fluid_history.as_ref(),
        )?;
        // The stabilisation tangent the forward run assembled on the same structure.
        if let (Some(flow), Some(values)) = (&system.flow, &sub.stabilisation)
            && values.len() == system.pattern.nnz()
        {
            let kept = SparseMatrix {
                pattern: system.pattern.clone(),
                values: values.clone(),
            };
            flow.stabilisation
                .set(kept)
                .expect("a fresh system's stabilisation is unset");
        }
        let mut point = vec![Vector::<f64, D>::zeros(); initial.len()];
        for l in &config.point_loads {
            point[l.particle] += Vector::<f64, D>::from(l.force);
        }
        Ok(Self {
            sub,
            system,
            config,
            initial,
            point,
        })
    }

    /// The setting of particle `p`.
    pub fn setting(&self, p: usize) -> Setting<'a, D> {
        Setting {
            grid: &self.config.grid,
            shape: self.config.shape,
            half_width0: self.initial.half_width0[p],
            volume0: self.initial.volume0[p],
            load_factor: if self.config.dynamics.is_some() {
                1.0
            } else {
                self.load_factor()
            },
            gravity_factor: if self.config.dynamics.is_some() || self.config.gravity_in_full {
                1.0
            } else {
                self.load_factor()
            },
        }
    }

    /// The load factor at the end of the sub-step: its progress, or in a coupled run the
    /// schedule's load factor there.
    fn load_factor(&self) -> f64 {
        match &self.config.pore_fluid {
            Some(fluid) => fluid.schedule.at(self.sub.to).1,
            None => self.sub.to,
        }
    }

    /// The loads on particle `p`.
    pub fn loads(&self, p: usize) -> Loads<f64, D> {
        Loads {
            gravity: self.config.gravity,
            point: self.point[p],
            balance: (self.config.balance.get(p).copied()).unwrap_or_else(Vector::zeros),
        }
    }

    /// The start state of particle `p`.
    pub fn state(&self, p: usize) -> ParticleState<f64, D> {
        self.sub.state(p, self.initial.mass[p])
    }

    /// The converged `Δu` of node component `(flat, a)`.
    pub fn du(&self, flat: usize, a: usize) -> f64 {
        self.system.dofs.value(flat, a, &self.sub.solution)
    }

    /// `Δu` of node component `(flat, a)` with the unknowns at zero: the prescribed increment
    /// or zero, the state at which a Newmark step evaluates its start force
    /// `rₙ = f_ext − f_int(0)`.
    pub fn du_start(&self, flat: usize, a: usize) -> f64 {
        match self.system.dofs.get(flat, a) {
            loam_implicit::NodeDof::Prescribed { value } => value,
            _ => 0.0,
        }
    }

    /// Per parameter, [`Replay::prescribed_rate`] of a constraint's displacement (`None` for
    /// every other kind).
    ///
    /// # Errors
    /// As [`Replay::new`].
    pub fn prescribed_rates(
        &self,
        params: &[super::ImplicitParam],
    ) -> Result<Vec<Option<Vec<Vector<f64, D>>>>, AdjointError> {
        params
            .iter()
            .map(|q| match *q {
                super::ImplicitParam::Displacement(k, a) => self.prescribed_rate(k, a).map(Some),
                _ => Ok(None),
            })
            .collect()
    }

    /// Per grid node and component, `d(prescribed Δu)/dθ` for `θ` the displacement of
    /// component `a` of constraint `k` (zero on every other node component): the prescribed
    /// increments are linear in the constraints' displacements, so they are those of a
    /// system whose constraint `k` prescribes 1 along `a` and every other one 0.
    ///
    /// # Errors
    /// As [`Replay::new`].
    pub fn prescribed_rate(&self, k: usize, a: usize) -> Result<Vec<Vector<f64, D>>, AdjointError> {
        let mut unit = self.config.clone();
        for (j, c) in unit.constraints.iter_mut().enumerate() {
            for (b, d) in c.displacement.iter_mut().enumerate() {
                if d.is_some() {
                    *d = Some(if (j, b) == (k, a) { 1.0 } else { 0.0 });
                }
            }
        }
        let particles = self.sub.particles(self.initial);
        let solver = ImplicitSolver::new(unit, &particles)?;
        let system = solver.system(&particles, self.sub.from, self.sub.to)?;
        let nodes = self.config.grid.num_nodes();
        Ok((0..nodes)
            .map(|n| {
                Vector::<f64, D>::from_fn(|c, _| match system.dofs.get(n, c) {
                    loam_implicit::NodeDof::Prescribed { value } => value,
                    _ => 0.0,
                })
            })
            .collect())
    }
}
