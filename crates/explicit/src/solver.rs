//! The explicit USL / MUSL step.

use crate::blocks::{Blocks, MIN_ROWS_PER_TASK, OFF_GRID};
use crate::config::Config;
use crate::error::{ConfigError, StepError};
use crate::trace::{GroupTrace, StepTrace};
use loam_core::energy::{Energy, energy};
use loam_core::stencil::Frame;
use loam_core::step::{
    EndOfStep, G2p, NodeLaw, NodeState, NodeSums, P2g, ParticleBranch, StepRecord,
    momentum_to_grid, momentum_update, particle_end,
};
use loam_core::tensor::{Tensor, Vector, det};
use loam_core::{Particles, Scalar, Scheme, ShapeFunction, Stencil, TimeStep};
use rayon::prelude::*;

/// What one completed step did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepInfo {
    /// Number of steps completed so far (this one included).
    pub step: usize,
    /// Simulated time at the end of the step.
    pub time: f64,
    /// The step size used.
    pub dt: f64,
}

/// An explicit MPM solver: the configuration plus scratch space (grid and block buffers).
/// [`Solver::step`] is a function of the particle state and the configuration only; the
/// scratch is rebuilt every step.
pub struct Solver<T: Scalar, const D: usize> {
    config: Config<T, D>,
    blocks: Blocks<T, D>,
    /// Block of every particle (the sort key), from [`Solver::locate`].
    keys: Vec<u32>,
    mass: Vec<T>,
    velocity: Vec<Vector<T, D>>,
    velocity_old: Vec<Vector<T, D>>,
    /// Per node, the unilateral constraints that acted in the grid update
    /// ([`NodeLaw::apply`]), which MUSL's second projection enforces again.
    active: Vec<NodeState>,
    /// Per particle, by sorted position: its stencil of the step (computed once, in P2G) and,
    /// for MUSL, its new position, velocity and affine matrix until the stress update writes
    /// them back.
    kernels: Vec<Kernel<T, D>>,
    /// Per node, the folded P2G sums of a traced step ([`Solver::step_traced`]; empty until
    /// one is taken).
    sums: Vec<NodeSums<T, D>>,
    /// Per material, its elastic wave speed, or `None` where it depends on the particle's
    /// state
    /// ([`loam_core::constitutive::Constitutive::stiffness_depends_on_state`]).
    wave_speed: Vec<Option<f64>>,
    mass_floor: f64,
    steps: usize,
    time: f64,
    /// Per obstacle, the impulse it has given the material since the solver was made or its
    /// clock set ([`Solver::obstacle_impulse`]).
    obstacle_impulse: Vec<[f64; D]>,
    /// Per row group and obstacle, the group's part of one step's impulse (scratch: summed
    /// in group order, so the total does not depend on the thread count).
    group_impulse: Vec<Vec<[f64; D]>>,
}

/// Minimum nodal mass (relative to the largest particle mass) below which a node is treated
/// as empty, so `p/m` never divides by round-off: a node takes part in a step when
/// `m_i > MASS_EPS · max_p m_p`.
pub const MASS_EPS: f64 = 1e-14;

/// Particles handed to one rayon task at least.
const MIN_PARTICLES_PER_TASK: usize = 256;

/// A particle's stencil of the step and (MUSL) its new position, velocity and affine matrix.
#[derive(Clone, Copy, Debug)]
struct Kernel<T: Scalar, const D: usize> {
    stencil: Stencil<T, D>,
    x: Vector<T, D>,
    v: Vector<T, D>,
    c: Tensor<T, D>,
}

/// What [`Solver::locate`] finds: the largest `c_p + |v_p|` (wave speed plus speed; the
/// stability bound is `h` over it), the largest particle mass and whether a stencil leaves
/// the grid.
#[derive(Clone, Copy, Debug)]
struct Located {
    max_rate: f64,
    max_mass: f64,
    off_grid: bool,
}

impl Located {
    const NONE: Self = Self {
        max_rate: 0.0,
        max_mass: 0.0,
        off_grid: false,
    };

    /// Both parts together (associative and commutative, so any split gives the same result;
    /// `f64::max` passes over a NaN).
    #[inline(always)]
    fn join(a: Self, b: Self) -> Self {
        Self {
            max_rate: a.max_rate.max(b.max_rate),
            max_mass: a.max_mass.max(b.max_mass),
            off_grid: a.off_grid || b.off_grid,
        }
    }
}

/// The smaller of two stability bounds; ties go to the lower particle id. A total order (a NaN
/// bound, from a NaN velocity, counts as the largest), so the reduction gives the same result
/// however it is split.
#[inline(always)]
fn lower_limit(a: (f64, usize, f64, f64), b: (f64, usize, f64, f64)) -> (f64, usize, f64, f64) {
    match b.0.total_cmp(&a.0).then(b.1.cmp(&a.1)) {
        std::cmp::Ordering::Less => b,
        _ => a,
    }
}

impl<T: Scalar, const D: usize> Solver<T, D> {
    /// A solver for `config` and the particles it will advance.
    pub fn new(config: Config<T, D>, particles: &Particles<T, D>) -> Result<Self, ConfigError> {
        config.validate()?;
        let count = config.materials.len();
        if let Some(p) = particles.material.iter().position(|&m| m as usize >= count) {
            return Err(ConfigError::UnknownMaterial {
                particle: p,
                material: particles.material[p],
                count,
            });
        }
        let n = config.grid.num_nodes();
        let wave_speed = (config.materials.iter())
            .map(|m| {
                let state_dependent = m.constitutive().stiffness_depends_on_state();
                (!state_dependent).then(|| m.wave_speed())
            })
            .collect();
        Ok(Self {
            blocks: Blocks::new(&config.grid, config.shape.support_width(), &config.boundary),
            keys: Vec::new(),
            mass: vec![T::zero(); n],
            velocity: vec![Vector::zeros(); n],
            velocity_old: vec![Vector::zeros(); n],
            active: vec![NodeState::default(); n],
            kernels: Vec::new(),
            sums: Vec::new(),
            wave_speed,
            mass_floor: 0.0,
            obstacle_impulse: vec![[0.0; D]; config.contact.obstacles.len()],
            group_impulse: Vec::new(),
            config,
            steps: 0,
            time: 0.0,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &Config<T, D> {
        &self.config
    }

    /// Simulated time.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps completed.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Sets the simulated time and the count of steps completed, to continue a run from a
    /// saved state. A step reads nothing else from earlier steps (the grid and block buffers
    /// are scratch, an adaptive `Δt` depends on the particles only), so the particles, the
    /// time and the step count are the whole state: a solver built for the saved particles and
    /// set to the saved clock takes the same steps, bit for bit, as the run that saved them.
    pub fn set_clock(&mut self, time: f64, steps: usize) {
        self.time = time;
        self.steps = steps;
        self.obstacle_impulse.fill([0.0; D]);
    }

    /// Per obstacle (in the order of the configuration's contact), the impulse it has given
    /// the material since the solver was made or its clock set: `I_k = Σ_steps Σ_i m_i Δv_ik`,
    /// the sum over the nodes where obstacle `k` acted in the grid update of the change of
    /// velocity it made there ([`loam_core::contact::Contact::apply_measured`]), so that
    /// `(I_k(t₂) − I_k(t₁)) / (t₂ − t₁)` is the mean force the obstacle exerted on the
    /// material over `[t₁, t₂]` (N·s and N; per metre of thickness in 2D; a footing pushed
    /// down has a negative vertical force, as the reactions of implicit runs). With APIC or
    /// PIC transfers, momentum balances exactly: `P(t₂) − P(t₁) = M g (t₂ − t₁) + I(t₂) −
    /// I(t₁)` plus the walls' impulses, `P` the particles' total momentum.
    pub fn obstacle_impulse(&self) -> &[[f64; D]] {
        &self.obstacle_impulse
    }

    /// Nodal masses of the last step (scratch, for inspection and tests).
    pub fn grid_mass(&self) -> &[T] {
        &self.mass
    }

    /// Energy of a particle state under this configuration.
    pub fn energy(&self, particles: &Particles<T, D>) -> Energy {
        energy(particles, &self.config.materials, &self.config.gravity)
    }

    /// The elastic wave speed `c_p` of particle `i`: its material's, or from its own state
    /// where the stiffness depends on it ([`loam_core::Material::wave_speed_in`]).
    #[inline]
    fn particle_wave_speed(&self, p: &Particles<T, D>, i: usize) -> f64 {
        let m = p.material[i] as usize;
        self.wave_speed[m].unwrap_or_else(|| self.config.materials[m].wave_speed_in(&p.state[i]))
    }

    /// The stability bound `h / (c_p + |v_p|)` of particle `i`, with its wave speed and speed.
    #[inline]
    fn particle_limit(&self, p: &Particles<T, D>, i: usize) -> (f64, usize, f64, f64) {
        let c = self.particle_wave_speed(p, i);
        let s = p.v[i].map(|x| x.re()).norm();
        (self.config.grid.h / (c + s), i, c, s)
    }

    /// The stability bound `min_p h / (c_p + |v_p|)` and the particle that sets it, with its
    /// wave speed and speed. Ties go to the lowest id, so the result is deterministic.
    pub fn stability_limit(&self, particles: &Particles<T, D>) -> (f64, usize, f64, f64) {
        (0..particles.len())
            .into_par_iter()
            .map(|i| self.particle_limit(particles, i))
            .reduce(|| (f64::INFINITY, usize::MAX, 0.0, 0.0), lower_limit)
    }

    /// The step size under the stability bound `limit` and the cap. The bound is
    /// `h / max_p (c_p + |v_p|)`, which is `min_p h / (c_p + |v_p|)` exactly (a division by a
    /// positive number does not increase as the divisor grows, also after rounding); the
    /// particle that sets it is looked up only for the error.
    fn choose_dt(
        &self,
        limit: f64,
        cap: f64,
        particles: &Particles<T, D>,
    ) -> Result<f64, StepError> {
        let dt = match self.config.time_step {
            TimeStep::Fixed { dt } => {
                if dt > limit {
                    let (limit, particle, wave_speed, speed) = self.stability_limit(particles);
                    return Err(StepError::TimeStepTooLarge {
                        step: self.steps + 1,
                        time: self.time,
                        dt,
                        limit,
                        particle,
                        wave_speed,
                        speed,
                    });
                }
                dt
            }
            TimeStep::Adaptive { cfl, max_dt } => (cfl * limit).min(max_dt),
        };
        Ok(dt.min(cap))
    }

    /// Advances the particles by one step of the configured size, capped at `max_dt` (use
    /// `f64::INFINITY` for no cap). The cap shortens a fixed step too: that is the explicit way
    /// to land on a given time ([`Solver::advance_exactly_to`]); plain runs never cap a fixed
    /// step ([`Solver::advance_to`]).
    ///
    /// The step runs on a thread of the current rayon pool (one hand-over per step), so its
    /// parallel phases do not each wake the pool from outside.
    pub fn step(
        &mut self,
        particles: &mut Particles<T, D>,
        max_dt: f64,
    ) -> Result<StepInfo, StepError> {
        let (mut none, mut trace) = (StepRecord::default(), StepTrace::default());
        rayon::scope(|_| {
            self.step_in_pool::<false, false>(None, particles, max_dt, &mut none, &mut trace)
        })
    }

    /// [`Solver::step`], recording into `record` the branches the step took (its `Δt`, the
    /// nodes where a unilateral constraint acted, each particle's wall projection and stress
    /// branch) for a reverse pass. The step itself is the same, bit for bit; a plain
    /// [`Solver::step`] records nothing and pays nothing for it (the recording is chosen at
    /// compile time).
    pub fn step_recorded(
        &mut self,
        particles: &mut Particles<T, D>,
        max_dt: f64,
        record: &mut StepRecord,
    ) -> Result<StepInfo, StepError> {
        let mut trace = StepTrace::default();
        rayon::scope(|_| {
            self.step_in_pool::<true, false>(None, particles, max_dt, record, &mut trace)
        })
    }

    /// [`Solver::step`], keeping in `trace` the grid of its first projection (the folded P2G
    /// sums, `vⁿ` and `v̂` at every node where they are not zero, and the nodes where a
    /// unilateral constraint acted), for a reverse pass that reads it instead of forming the
    /// step's grid again. The step itself is the same, bit for bit; `trace`'s buffers are
    /// reused from call to call.
    pub fn step_traced(
        &mut self,
        particles: &mut Particles<T, D>,
        max_dt: f64,
        trace: &mut StepTrace<T, D>,
    ) -> Result<StepInfo, StepError> {
        let mut none = StepRecord::default();
        rayon::scope(|_| {
            self.step_in_pool::<false, true>(None, particles, max_dt, &mut none, trace)
        })
    }

    /// [`Solver::step_traced`] from the particles `start` into `out`, which receives the state
    /// after the step (the same bits as stepping a copy of `start` in place), without copying
    /// the state first: each particle's fields are read from `start` where the step reads them
    /// and written into `out` once. `out`'s buffers are reused (a state of the same particles
    /// keeps its allocations; its mass, reference volume, half-width, material and
    /// acceleration are copied from `start`).
    pub fn step_traced_from(
        &mut self,
        start: &Particles<T, D>,
        out: &mut Particles<T, D>,
        max_dt: f64,
        trace: &mut StepTrace<T, D>,
    ) -> Result<StepInfo, StepError> {
        let mut none = StepRecord::default();
        rayon::scope(|_| {
            self.step_in_pool::<false, true>(Some(start), out, max_dt, &mut none, trace)
        })
    }

    /// [`Solver::step`], on a pool thread; fills `record` when `RECORD` and `trace` when
    /// `TRACE`. With `start`, the step reads the state before it from `start` and writes the
    /// state after it into `particles` ([`Solver::step_traced_from`]); without, it advances
    /// `particles` in place.
    fn step_in_pool<const RECORD: bool, const TRACE: bool>(
        &mut self,
        start: Option<&Particles<T, D>>,
        particles: &mut Particles<T, D>,
        max_dt: f64,
        record: &mut StepRecord,
        trace: &mut StepTrace<T, D>,
    ) -> Result<StepInfo, StepError> {
        let dt = {
            let before = start.unwrap_or(&*particles);
            let located = self.locate(before);
            let limit = self.config.grid.h / located.max_rate;
            let dt = self.choose_dt(limit, max_dt, before)?;
            if located.off_grid {
                return Err(self.left_grid(before));
            }
            self.blocks.sort(&self.keys);
            self.mass_floor = MASS_EPS * located.max_mass;
            self.transfer_to_grid::<TRACE>(before, dt, &mut trace.groups);
            dt
        };
        if TRACE {
            trace.dt = dt;
            trace.mass_floor = self.mass_floor;
            trace.flip = self.config.transfer.needs_old_grid_velocity();
        }
        if RECORD {
            self.record_nodes(record, dt);
        }
        if let Some(start) = start {
            constants_from(start, particles);
        }
        let branches = &mut record.particles;
        let flagged = match self.config.scheme {
            Scheme::Usl => self.update_particles_usl::<RECORD>(start, particles, dt, branches),
            Scheme::Musl => self.update_particles_musl::<RECORD>(start, particles, dt, branches),
        };
        self.steps += 1;
        self.time += dt;
        if flagged {
            check_particles(particles, self.steps, self.time)?;
            check_containment(&self.config, particles, self.steps, self.time)?;
        }
        Ok(StepInfo {
            step: self.steps,
            time: self.time,
            dt,
        })
    }

    /// Steps until the simulated time reaches `t_end`, calling `on_step` after every step (the
    /// steps run on the rayon pool with its other workers awake: [`crate::pool::hold`]).
    ///
    /// - Fixed step: every step keeps its size Δt; the run stops after the first step that
    ///   reaches or passes `t_end`, so it may end up to one step past it (see
    ///   [`Solver::next_step_cap`] for the round-off allowance).
    /// - Adaptive step: the last step is shortened to end on `t_end`.
    ///
    /// [`Solver::advance_exactly_to`] shortens the last fixed step too, for a caller that must
    /// sample the state at `t_end` itself.
    pub fn advance_to(
        &mut self,
        particles: &mut Particles<T, D>,
        t_end: f64,
        on_step: impl FnMut(&StepInfo, &Particles<T, D>) + Send,
    ) -> Result<(), StepError> {
        self.advance_while(particles, |s| s.next_step_cap(t_end), on_step)
    }

    /// Steps until the simulated time is `t_end` exactly, shortening the last step (fixed or
    /// adaptive) to end on it, and calling `on_step` after every step.
    pub fn advance_exactly_to(
        &mut self,
        particles: &mut Particles<T, D>,
        t_end: f64,
        on_step: impl FnMut(&StepInfo, &Particles<T, D>) + Send,
    ) -> Result<(), StepError> {
        self.advance_while(particles, |s| s.landing_cap(t_end), on_step)
    }

    /// The cap (`max_dt` of [`Solver::step`]) on the next step of [`Solver::advance_to`]
    /// towards `t_end`, or `None` once `t_end` is reached. A front end that steps on its own
    /// (to check for an interruption between steps, say) loops on it.
    ///
    /// - Fixed step Δt: `f64::INFINITY` (no shortening) while the time is short of `t_end`. A
    ///   time short by at most `1e-9 · t_end` (and by less than Δt/2) counts as reached: the
    ///   round-off of summing Δt over the steps, below `n ε t` after `n` steps, stays under
    ///   that up to ten million steps.
    /// - Adaptive step: `t_end − t`, so that the last step ends on `t_end`, while more than
    ///   `1e-12 · t_end` remains (shorter steps would be the round-off of that last sum).
    pub fn next_step_cap(&self, t_end: f64) -> Option<f64> {
        match self.config.time_step {
            TimeStep::Fixed { dt } => {
                let allowance = (1e-9 * t_end.abs()).min(0.5 * dt);
                (t_end - self.time > allowance).then_some(f64::INFINITY)
            }
            TimeStep::Adaptive { .. } => self.landing_cap(t_end),
        }
    }

    /// The cap that makes the next step end on `t_end` (see [`Solver::next_step_cap`]), or
    /// `None` when less than `1e-12 · t_end` remains.
    fn landing_cap(&self, t_end: f64) -> Option<f64> {
        let left = t_end - self.time;
        (left > 1e-12 * t_end.abs().max(1e-300)).then_some(left)
    }

    /// Steps with the caps `cap(self)` until it gives `None`, calling `on_step` after every
    /// step, on the rayon pool with its other workers awake ([`crate::pool::hold`]).
    fn advance_while(
        &mut self,
        particles: &mut Particles<T, D>,
        cap: impl Fn(&Self) -> Option<f64> + Sync,
        mut on_step: impl FnMut(&StepInfo, &Particles<T, D>) + Send,
    ) -> Result<(), StepError> {
        crate::pool::hold(|| {
            while let Some(max_dt) = cap(self) {
                let info = self.step(particles, max_dt)?;
                on_step(&info, particles);
            }
            Ok(())
        })
    }

    /// One pass over the particles: the block of every stencil (the sort key), the stability
    /// bound, the largest mass, and whether a stencil leaves the grid.
    fn locate(&mut self, p: &Particles<T, D>) -> Located {
        let mut keys = std::mem::take(&mut self.keys);
        keys.resize(p.len(), 0);
        let (cfg, blocks) = (&self.config, &self.blocks);
        let frame = Frame::new(&cfg.grid);
        // By chunks of particles with a plain loop inside: per particle the work is a few
        // dozen instructions, less than what a zip of parallel iterators costs per item.
        let located = keys
            .par_chunks_mut(MIN_PARTICLES_PER_TASK)
            .enumerate()
            .map(|(c, keys)| {
                let first = c * MIN_PARTICLES_PER_TASK;
                let mut acc = Located::NONE;
                for (k, key) in keys.iter_mut().enumerate() {
                    let i = first + k;
                    *key = blocks.key(Stencil::first_node_in(cfg.shape, &frame, &p.x[i]));
                    let speed = p.v[i].map(|x| x.re()).norm();
                    acc = Located::join(
                        acc,
                        Located {
                            max_rate: self.particle_wave_speed(p, i) + speed,
                            max_mass: p.mass[i].re(),
                            off_grid: *key == OFF_GRID,
                        },
                    );
                }
                acc
            })
            .reduce(|| Located::NONE, Located::join);
        self.keys = keys;
        located
    }

    /// The error for particles whose stencil left the grid (all of them, by id).
    fn left_grid(&self, p: &Particles<T, D>) -> StepError {
        let ids: Vec<usize> = (0..p.len()).filter(|&i| self.keys[i] == OFF_GRID).collect();
        StepError::LeftGrid {
            step: self.steps + 1,
            time: self.time,
            positions: ids
                .iter()
                .take(3)
                .map(|&i| p.x[i].iter().map(|v| v.re()).collect())
                .collect(),
            ids,
        }
    }

    /// The nodes where a unilateral constraint acted in this step's grid update, into
    /// `record` with the step's time and `Δt`.
    fn record_nodes(&self, record: &mut StepRecord, dt: f64) {
        record.step = self.steps + 1;
        record.time = self.time;
        record.dt = dt;
        record.nodes.clear();
        record.nodes.extend(self.acted_nodes());
    }

    /// The nodes of this step where a unilateral constraint acted, with what acted, in
    /// increasing node order.
    fn acted_nodes(&self) -> impl Iterator<Item = (usize, NodeState)> + '_ {
        let floor = self.mass_floor;
        self.active
            .iter()
            .zip(&self.mass)
            .enumerate()
            .filter(move |(_, (a, m))| m.re() > floor && !a.is_free())
            .map(|(i, (&a, _))| (i, a))
    }

    /// Stage 1, P2G of mass, momentum and internal force ([`P2g`]), then stage 2, the grid
    /// update ([`momentum_update`], [`NodeLaw::apply`]): `v_i = p_i/m_i`,
    /// `v_i ← v_i + Δt (f_i/m_i + g)`, contact and walls. With `TRACE`, each row group keeps
    /// its nodes of the step's grid into its entry of `trace` as its update ends
    /// ([`GroupTrace::keep`]; the folded P2G sums, the update's inputs, wait in `self.sums`).
    fn transfer_to_grid<const TRACE: bool>(
        &mut self,
        p: &Particles<T, D>,
        dt: f64,
        trace: &mut Vec<GroupTrace<T, D>>,
    ) {
        let cfg = &self.config;
        let dtt = T::cst(dt);
        if self.kernels.len() != p.len() {
            let (zero, grid) = (Vector::zeros(), &cfg.grid);
            let placeholder = Kernel {
                stencil: Stencil::new(cfg.shape, grid, &grid.node_position([0; D]), &zero),
                x: zero,
                v: zero,
                c: Tensor::zeros(),
            };
            self.kernels.resize(p.len(), placeholder);
        }
        let stage = P2g::new(&cfg.grid, cfg.shape, cfg.transfer, dt);
        self.blocks.for_each_block(
            &mut self.kernels,
            |e| *e = NodeSums::zero(),
            #[inline(always)]
            |i, layout, buf, kernel| stage.particle(p, i, &mut kernel.stencil, layout, buf),
        );
        let floor = self.mass_floor;
        let (grid, boundary, gravity) = (&cfg.grid, &cfg.boundary, cfg.gravity);
        // Contact acts at the end of the step, when the grid velocity is reached.
        let law = NodeLaw::new(grid, boundary, &cfg.contact, self.time + dt);
        let flip = cfg.transfer.needs_old_grid_velocity();
        let (blocks, n) = (&self.blocks, self.blocks.row_len());
        let obstacles = cfg.contact.obstacles.len();
        self.group_impulse
            .resize_with(blocks.groups().len(), Vec::new);
        for g in &mut self.group_impulse {
            g.clear();
            g.resize(obstacles, [0.0; D]);
        }
        // With `TRACE`, per row group: its part of `self.sums` and its entry of `trace`.
        let kept: Vec<Option<Kept<'_, T, D>>> = if TRACE {
            self.sums.resize(grid.num_nodes(), NodeSums::zero());
            trace.resize_with(blocks.groups().len(), GroupTrace::default);
            (blocks.split_groups(&mut self.sums).into_iter())
                .zip(trace.iter_mut())
                .map(Some)
                .collect()
        } else {
            blocks.groups().iter().map(|_| None).collect()
        };
        // One pass over the row groups (closed under the wall mirrors): gather the block
        // buffers (momentum into `velocity_old`, force into `velocity` until the velocities
        // are formed), fold the ghosts, (`TRACE`) keep the sums, update the velocities,
        // reflect them into the ghosts.
        blocks
            .split_groups(&mut self.mass)
            .into_par_iter()
            .zip(blocks.split_groups(&mut self.velocity_old))
            .zip(blocks.split_groups(&mut self.velocity))
            .zip(blocks.split_groups(&mut self.active))
            .zip(kept)
            .zip(self.group_impulse.par_iter_mut())
            .zip(blocks.groups().par_iter())
            .with_min_len(MIN_ROWS_PER_TASK)
            .for_each(
                |((((((m, v_old), v), active), mut kept), impulse), &(r0, r1))| {
                    let rows = |r: usize| (r - r0) * n..(r - r0 + 1) * n;
                    for r in r0..r1 {
                        let at = rows(r);
                        blocks.gather_row(
                            r,
                            &mut m[at.clone()],
                            &mut v_old[at.clone()],
                            &mut v[at],
                        );
                    }
                    let nodes = r0 * n..r1 * n;
                    boundary.fold_ghosts_in(grid, nodes.clone(), Some(m), v_old, Some(v));
                    if let Some((sums, _)) = &mut kept {
                        for (k, s) in sums.iter_mut().enumerate() {
                            *s = NodeSums {
                                m: m[k],
                                p: v_old[k],
                                f: v[k],
                            };
                        }
                    }
                    for r in r0..r1 {
                        let at = rows(r);
                        let (m, v_old, v) =
                            (&m[at.clone()], &mut v_old[at.clone()], &mut v[at.clone()]);
                        let active = &mut active[at];
                        let mut node = blocks.row_node(r);
                        blocks.for_each_visited(r, |i| {
                            let (m, v_old, v) = (m[i], &mut v_old[i], &mut v[i]);
                            if m.re() > floor {
                                // `v_old` holds the momentum and `v` the force until here.
                                (*v_old, *v) = momentum_update(m, v_old, v, &gravity, dtt);
                                node[0] = i;
                                active[i] = law.apply_measured(node, v, |k, dv| {
                                    // The obstacle's impulse on the node, `m Δv`.
                                    for (a, c) in impulse[k].iter_mut().enumerate() {
                                        *c += m.re() * dv[a].re();
                                    }
                                });
                            } else {
                                *v_old = Vector::zeros();
                                *v = Vector::zeros();
                            }
                        });
                    }
                    boundary.reflect_ghosts_in(grid, nodes.clone(), v);
                    if flip {
                        boundary.reflect_ghosts_in(grid, nodes.clone(), v_old);
                    }
                    if let Some((sums, trace)) = kept {
                        let span = (nodes.start, nodes.end);
                        trace.keep(span, sums, v, v_old, active, floor, flip);
                    }
                },
            );
        for group in &self.group_impulse {
            for (total, part) in self.obstacle_impulse.iter_mut().zip(group) {
                for (t, p) in total.iter_mut().zip(part) {
                    *t += p;
                }
            }
        }
    }

    /// USL: stage 3, G2P ([`G2p::particle`]), then stage 4 with the velocity gradient of the
    /// updated grid velocity ([`particle_end`]). Returns whether a particle needs a closer
    /// look by the checks ([`EndOfStep::flag`]); records the particles' branches into
    /// `branches` when `RECORD`. With `start`, the state before the step is read from it.
    fn update_particles_usl<const RECORD: bool>(
        &self,
        start: Option<&Particles<T, D>>,
        p: &mut Particles<T, D>,
        dt: f64,
        branches: &mut Vec<ParticleBranch>,
    ) -> bool {
        let cfg = &self.config;
        let stage = G2p::new(&cfg.grid, cfg.shape, cfg.transfer, dt);
        let (vel, vel_old) = (&self.velocity, &self.velocity_old);
        let (blocks, kernels) = (&self.blocks, &self.kernels);
        // G2P in a function of its own: inlined into the particle pass, the stages of a
        // particle need about 30 more instructions (register pressure).
        finish_particles::<RECORD, T, D>(
            start,
            p,
            cfg,
            self.time + dt,
            dt,
            branches,
            #[inline(never)]
            |i, x, v, c| {
                let st = &kernels[blocks.rank(i)].stencil;
                stage.particle(st, vel, vel_old, x, v, c)
            },
        )
    }

    /// MUSL: G2P velocity and position ([`G2p::motion`]); map the new particle momentum back
    /// to the grid with the same stencils ([`momentum_to_grid`]), enforce the first
    /// projection's constraints ([`NodeLaw::enforce`]), and take `L` from that grid velocity
    /// ([`G2p::velocity_gradient`]) for stage 4. G2P and the second P2G run in one pass over
    /// the blocks (the new state waits in `kernels`); stage 4 writes it back. Returns whether
    /// a particle needs a closer look by the checks; records the particles' branches into
    /// `branches` when `RECORD`. With `start`, the state before the step is read from it.
    fn update_particles_musl<const RECORD: bool>(
        &mut self,
        start: Option<&Particles<T, D>>,
        p: &mut Particles<T, D>,
        dt: f64,
        branches: &mut Vec<ParticleBranch>,
    ) -> bool {
        let cfg = &self.config;
        let stage = G2p::new(&cfg.grid, cfg.shape, cfg.transfer, dt);
        let affine = cfg.transfer.is_affine();
        {
            let pr = start.unwrap_or(&*p);
            let (vel, vel_old) = (&self.velocity, &self.velocity_old);
            self.blocks.for_each_block(
                &mut self.kernels,
                |e| e.p = Vector::zeros(),
                |i, block, buf, kernel| {
                    let st = &kernel.stencil;
                    let (x, v, c) = stage.motion(st, vel, vel_old, &pr.x[i], &pr.v[i]);
                    // Second P2G: momentum of the updated particle velocities at the
                    // start-of-step positions.
                    momentum_to_grid(st, block, pr.mass[i], &v, &c, affine, buf);
                    (kernel.x, kernel.v, kernel.c) = (x, v, c);
                },
            );
        }
        {
            let (grid, boundary, blocks) = (&cfg.grid, &cfg.boundary, &self.blocks);
            let law = NodeLaw::new(grid, boundary, &cfg.contact, self.time + dt);
            let (floor, n) = (self.mass_floor, blocks.row_len());
            let (mass, active) = (&self.mass, &self.active);
            // As in the first transfer: gather, fold, update and reflect, group by group.
            blocks
                .split_groups(&mut self.velocity)
                .into_par_iter()
                .zip(blocks.groups().par_iter())
                .with_min_len(MIN_ROWS_PER_TASK)
                .for_each(|(v, &(r0, r1))| {
                    let rows = |r: usize| (r - r0) * n..(r - r0 + 1) * n;
                    for r in r0..r1 {
                        blocks.gather_momentum_row(r, &mut v[rows(r)]);
                    }
                    let nodes = r0 * n..r1 * n;
                    boundary.fold_ghosts_in(grid, nodes.clone(), None, v, None);
                    for r in r0..r1 {
                        let at = r * n..(r + 1) * n;
                        let (v, m, active) = (&mut v[rows(r)], &mass[at.clone()], &active[at]);
                        let mut node = blocks.row_node(r);
                        blocks.for_each_visited(r, |i| {
                            let v = &mut v[i];
                            if m[i].re() > floor {
                                *v /= m[i];
                                node[0] = i;
                                law.enforce(node, v, active[i]);
                            } else {
                                *v = Vector::zeros();
                            }
                        });
                    }
                    boundary.reflect_ghosts_in(grid, nodes, v);
                });
        }
        let (vel, blocks, kernels) = (&self.velocity, &self.blocks, &self.kernels);
        finish_particles::<RECORD, T, D>(
            start,
            p,
            cfg,
            self.time + dt,
            dt,
            branches,
            |i, x, v, c| {
                let k = &kernels[blocks.rank(i)];
                (*x, *v, *c) = (k.x, k.v, k.c);
                stage.velocity_gradient(&k.stencil, vel)
            },
        )
    }
}

/// The end of a step for every particle, in parallel: `motion(i, x, v, c)` sets particle `i`'s
/// new position, velocity and affine matrix and returns its velocity gradient `L`; then stage
/// 4 ([`particle_end`]: wall projection, `F ← (I + Δt L) F`, stress update, check flag) at the
/// end-of-step time `time`. Returns whether a particle needs a closer look by the checks
/// ([`EndOfStep::flag`]). With `RECORD`, `branches` receives every particle's branches, by
/// id; without, nothing of them is kept (the choice is made at compile time). With `start`,
/// each particle's fields are first taken from it (the step from `start` into `p`).
#[inline(always)]
fn finish_particles<const RECORD: bool, T: Scalar, const D: usize>(
    start: Option<&Particles<T, D>>,
    p: &mut Particles<T, D>,
    cfg: &Config<T, D>,
    time: f64,
    dt: f64,
    branches: &mut Vec<ParticleBranch>,
    motion: impl Fn(usize, &mut Vector<T, D>, &mut Vector<T, D>, &mut Tensor<T, D>) -> Tensor<T, D>
    + Sync
    + Send,
) -> bool {
    let end = EndOfStep::new(&cfg.grid, &cfg.boundary, &cfg.contact, time);
    let dt = T::cst(dt);
    let Particles {
        x,
        v,
        f,
        c,
        stress,
        material,
        state,
        ..
    } = p;
    let each = (x, v, f, c, stress, state)
        .into_par_iter()
        .zip(material.par_iter())
        .enumerate()
        .with_min_len(MIN_PARTICLES_PER_TASK)
        .map(
            #[inline(always)]
            |(i, ((x, v, f, c, stress, state), &mat))| {
                if let Some(s) = start {
                    (*x, *v, *f, *c) = (s.x[i], s.v[i], s.f[i], s.c[i]);
                    (*stress, *state) = (s.stress[i], s.state[i]);
                }
                let l = motion(i, x, v, c);
                let material = &cfg.materials[mat as usize];
                particle_end(&end, material, &l, dt, x, v, f, stress, state)
            },
        );
    if RECORD {
        let mut flags = Vec::new();
        each.unzip_into_vecs(&mut flags, branches);
        flags.contains(&true)
    } else {
        each.map(|(flag, _)| flag).reduce(|| false, |a, b| a || b)
    }
}

/// Makes `out` a state of the particles of `start` for a step from `start` into it: the fields
/// a step does not change (mass, reference volume and half-width, material, acceleration) are
/// copied, the others sized (the step writes them); the buffers keep their allocations.
fn constants_from<T: Scalar, const D: usize>(start: &Particles<T, D>, out: &mut Particles<T, D>) {
    if out.len() != start.len() {
        out.clone_from(start);
        return;
    }
    // Two halves of about the same bytes, copied at the same time.
    rayon::join(
        || {
            out.a.clone_from(&start.a);
            out.mass.clone_from(&start.mass);
        },
        || {
            out.volume0.clone_from(&start.volume0);
            out.half_width0.clone_from(&start.half_width0);
            out.material.clone_from(&start.material);
        },
    );
}

/// A row group's part of the folded P2G sums and its entry of a step's trace.
type Kept<'a, T, const D: usize> = (&'a mut [NodeSums<T, D>], &'a mut GroupTrace<T, D>);

/// Stops the run on NaN/Inf in any particle field or an inverted particle.
fn check_particles<T: Scalar, const D: usize>(
    p: &Particles<T, D>,
    step: usize,
    time: f64,
) -> Result<(), StepError> {
    fn bad<X: Sync>(v: &[X], pred: impl Fn(&X) -> bool + Sync) -> Vec<usize> {
        v.par_iter()
            .enumerate()
            .filter(|(_, x)| pred(x))
            .map(|(i, _)| i)
            .collect()
    }
    let fin_v = |x: &Vector<T, D>| !x.iter().all(|s| s.is_finite_all());
    let fin_t = |x: &Tensor<T, D>| !x.iter().all(|s| s.is_finite_all());
    let checks: [(&'static str, Vec<usize>); 4] = [
        ("position", bad(&p.x, fin_v)),
        ("velocity", bad(&p.v, fin_v)),
        ("deformation gradient", bad(&p.f, fin_t)),
        (
            "stress",
            bad(&p.stress, |s| !s.iter().all(|s| s.is_finite_all())),
        ),
    ];
    for (field, ids) in checks {
        if !ids.is_empty() {
            return Err(StepError::NonFinite {
                step,
                time,
                field,
                ids,
            });
        }
    }
    let inverted = bad(&p.f, |f| det(f).re() <= 0.0);
    if !inverted.is_empty() {
        return Err(StepError::Inverted {
            step,
            time,
            ids: inverted,
        });
    }
    Ok(())
}

/// Stops the run when a particle has crossed a wall (any face whose condition is not `free`)
/// or lies inside an obstacle; the ids are those of the offending particles.
fn check_containment<T: Scalar, const D: usize>(
    cfg: &Config<T, D>,
    p: &Particles<T, D>,
    step: usize,
    time: f64,
) -> Result<(), StepError> {
    const AXES: [&str; 3] = ["x", "y", "z"];
    let (lo, hi) = (cfg.grid.lo, cfg.grid.hi());
    let escaped = |what: String, ids: Vec<usize>| StepError::Escaped {
        step,
        time,
        what,
        positions: ids
            .iter()
            .take(3)
            .map(|&i| p.x[i].iter().map(|v| v.re()).collect())
            .collect(),
        ids,
    };
    for axis in 0..D {
        for side in 0..2 {
            if cfg.boundary.walls[axis][side].kind == loam_core::WallKind::Free {
                continue;
            }
            let ids: Vec<usize> =
                p.x.par_iter()
                    .enumerate()
                    .filter(|(_, x)| {
                        let c = x[axis].re();
                        if side == 0 {
                            c < lo[axis]
                        } else {
                            c > hi[axis]
                        }
                    })
                    .map(|(i, _)| i)
                    .collect();
            if !ids.is_empty() {
                let face = format!("the {}_{} wall", AXES[axis], ["min", "max"][side]);
                return Err(escaped(face, ids));
            }
        }
    }
    if cfg.contact.is_empty() {
        return Ok(());
    }
    let hits: Vec<(usize, usize)> =
        p.x.par_iter()
            .enumerate()
            .filter_map(|(i, x)| {
                let xr: [f64; D] = std::array::from_fn(|a| x[a].re());
                cfg.contact.penetrated(&xr, time).map(|o| (i, o))
            })
            .collect();
    if let Some(&(_, obstacle)) = hits.first() {
        let ids = hits.iter().map(|&(i, _)| i).collect();
        return Err(escaped(format!("into obstacles[{obstacle}]"), ids));
    }
    Ok(())
}
