//! The explicit USL / MUSL step.

use crate::blocks::{Accum, Blocks, MIN_ROWS_PER_TASK, OFF_GRID};
use crate::config::Config;
use crate::error::{ConfigError, StepError};
use loam_core::constitutive::Kinematics;
use loam_core::energy::{Energy, energy};
use loam_core::stencil::{Frame, Layout, particle_half_width};
use loam_core::tensor::{Tensor, Vector, det, from3, to3};
use loam_core::transfer::{g2p, mls_affine_momentum, p2g, p2g_momentum};
use loam_core::{
    Grid, Particles, Scalar, Scheme, ShapeFunction, Stencil, TimeStep, Transfer, WallKind,
};
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
    /// Per node, the unilateral constraints that acted in the grid update (see
    /// [`NodeConditions::apply`]), which MUSL's second projection enforces again.
    active: Vec<Active>,
    /// Per particle, by sorted position: its stencil of the step (computed once, in P2G) and,
    /// for MUSL, its new position, velocity and affine matrix until the stress update writes
    /// them back.
    kernels: Vec<Kernel<T, D>>,
    wave_speed: Vec<f64>,
    mass_floor: f64,
    steps: usize,
    time: f64,
}

/// Minimum nodal mass (relative to the largest particle mass) below which a node is treated
/// as empty, so `p/m` never divides by round-off.
const MASS_EPS: f64 = 1e-14;

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
        let wave_speed = config.materials.iter().map(|m| m.wave_speed()).collect();
        Ok(Self {
            blocks: Blocks::new(&config.grid, config.shape.support_width(), &config.boundary),
            keys: Vec::new(),
            mass: vec![T::zero(); n],
            velocity: vec![Vector::zeros(); n],
            velocity_old: vec![Vector::zeros(); n],
            active: vec![Active::default(); n],
            kernels: Vec::new(),
            wave_speed,
            mass_floor: 0.0,
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
    }

    /// Nodal masses of the last step (scratch, for inspection and tests).
    pub fn grid_mass(&self) -> &[T] {
        &self.mass
    }

    /// Energy of a particle state under this configuration.
    pub fn energy(&self, particles: &Particles<T, D>) -> Energy {
        energy(particles, &self.config.materials, &self.config.gravity)
    }

    /// The stability bound `h / (c_p + |v_p|)` of one particle, with its wave speed and speed.
    #[inline]
    fn particle_limit(&self, p: usize, v: &Vector<T, D>, material: u32) -> (f64, usize, f64, f64) {
        let c = self.wave_speed[material as usize];
        let s = v.map(|x| x.re()).norm();
        (self.config.grid.h / (c + s), p, c, s)
    }

    /// The stability bound `min_p h / (c_p + |v_p|)` and the particle that sets it, with its
    /// wave speed and speed. Ties go to the lowest id, so the result is deterministic.
    pub fn stability_limit(&self, particles: &Particles<T, D>) -> (f64, usize, f64, f64) {
        particles
            .v
            .par_iter()
            .zip(particles.material.par_iter())
            .enumerate()
            .map(|(p, (v, &m))| self.particle_limit(p, v, m))
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

    /// Advances the particles by one step of at most `max_dt` (use `f64::INFINITY` for no cap).
    ///
    /// The step runs on a thread of the current rayon pool (one hand-over per step), so its
    /// parallel phases do not each wake the pool from outside.
    pub fn step(
        &mut self,
        particles: &mut Particles<T, D>,
        max_dt: f64,
    ) -> Result<StepInfo, StepError> {
        rayon::scope(|_| self.step_in_pool(particles, max_dt))
    }

    /// [`Solver::step`], on a pool thread.
    fn step_in_pool(
        &mut self,
        particles: &mut Particles<T, D>,
        max_dt: f64,
    ) -> Result<StepInfo, StepError> {
        let located = self.locate(particles);
        let limit = self.config.grid.h / located.max_rate;
        let dt = self.choose_dt(limit, max_dt, particles)?;
        if located.off_grid {
            return Err(self.left_grid(particles));
        }
        self.blocks.sort(&self.keys);
        self.mass_floor = MASS_EPS * located.max_mass;
        self.transfer_to_grid(particles, dt);
        let flagged = match self.config.scheme {
            Scheme::Usl => self.update_particles_usl(particles, dt),
            Scheme::Musl => self.update_particles_musl(particles, dt),
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

    /// Steps until the simulated time reaches `t_end` exactly (the last step is shortened),
    /// calling `on_step` after every step.
    pub fn advance_to(
        &mut self,
        particles: &mut Particles<T, D>,
        t_end: f64,
        mut on_step: impl FnMut(&StepInfo, &Particles<T, D>),
    ) -> Result<(), StepError> {
        // Steps shorter than this fraction of the time are round-off from summing dt.
        let tiny = 1e-12 * t_end.abs().max(1e-300);
        while t_end - self.time > tiny {
            let info = self.step(particles, t_end - self.time)?;
            on_step(&info, particles);
        }
        Ok(())
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
                            max_rate: self.wave_speed[p.material[i] as usize] + speed,
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

    /// P2G of mass, momentum and internal force, then the grid momentum update with gravity
    /// and walls: `v_i = p_i/m_i`, `v_i ← v_i + Δt (f_i/m_i + g)`.
    fn transfer_to_grid(&mut self, p: &Particles<T, D>, dt: f64) {
        let cfg = &self.config;
        let affine = cfg.transfer.is_affine();
        // MLS-MPM's `1/κ` (validated: MLS needs a B-spline).
        let mls = cfg.transfer.is_mls().then(|| {
            cfg.shape
                .apic_inverse_inertia()
                .expect("MLS with a B-spline")
        });
        let dtt = T::cst(dt);
        let frame = Frame::new(&cfg.grid);
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
        let h = cfg.grid.h;
        self.blocks.for_each_block(
            &mut self.kernels,
            |e| *e = Accum::zero(),
            #[inline(always)]
            |i, layout, buf, kernel| {
                let hw = particle_half_width(cfg.shape, h, &p.half_width0[i], &p.f[i]);
                kernel.stencil.set_in(cfg.shape, &frame, &p.x[i], &hw);
                let st = &kernel.stencil;
                let volume = p.volume0[i] * det(&p.f[i]);
                let sv = from3::<T, D>(&p.stress[i]) * volume;
                if let Some(inverse_inertia) = mls {
                    // Internal force and affine momentum in one term; `f` stays zero.
                    let m = p.mass[i];
                    let a = mls_affine_momentum(m, &p.c[i], &sv, dtt, inverse_inertia, h);
                    p2g_momentum(
                        st,
                        layout,
                        &p.v[i],
                        &a,
                        m,
                        buf,
                        #[inline(always)]
                        |e, m, mom| {
                            e.m += m;
                            e.p += mom;
                        },
                    );
                } else {
                    p2g(
                        st,
                        layout,
                        &p.v[i],
                        affine.then_some(&p.c[i]),
                        p.mass[i],
                        &sv,
                        buf,
                        #[inline(always)]
                        |e, m, mom, f| {
                            e.m += m;
                            e.p += mom;
                            e.f += f;
                        },
                    );
                }
            },
        );
        let floor = self.mass_floor;
        let (grid, boundary, gravity) = (
            &self.config.grid,
            &self.config.boundary,
            self.config.gravity,
        );
        // Contact acts at the end of the step, when the grid velocity is reached.
        let conditions = NodeConditions::new(&self.config, self.time + dt);
        let flip = self.config.transfer.needs_old_grid_velocity();
        let (blocks, n) = (&self.blocks, self.blocks.row_len());
        // One pass over the row groups (closed under the wall mirrors): gather the block
        // buffers (momentum into `velocity_old`, force into `velocity` until the velocities
        // are formed), fold the ghosts, update the velocities, reflect them into the ghosts.
        blocks
            .split_groups(&mut self.mass)
            .into_par_iter()
            .zip(blocks.split_groups(&mut self.velocity_old))
            .zip(blocks.split_groups(&mut self.velocity))
            .zip(blocks.split_groups(&mut self.active))
            .zip(blocks.groups().par_iter())
            .with_min_len(MIN_ROWS_PER_TASK)
            .for_each(|((((m, v_old), v), active), &(r0, r1))| {
                let rows = |r: usize| (r - r0) * n..(r - r0 + 1) * n;
                for r in r0..r1 {
                    let at = rows(r);
                    blocks.gather_row(r, &mut m[at.clone()], &mut v_old[at.clone()], &mut v[at]);
                }
                let nodes = r0 * n..r1 * n;
                boundary.fold_ghosts_in(grid, nodes.clone(), Some(m), v_old, Some(v));
                for r in r0..r1 {
                    let at = rows(r);
                    let (m, v_old, v) =
                        (&m[at.clone()], &mut v_old[at.clone()], &mut v[at.clone()]);
                    let active = &mut active[at];
                    let mut node = blocks.row_node(r);
                    blocks.for_each_visited(r, |i| {
                        let (m, v_old, v) = (m[i], &mut v_old[i], &mut v[i]);
                        if m.re() > floor {
                            *v_old /= m;
                            *v = *v_old + (*v / m + gravity) * dtt;
                            node[0] = i;
                            active[i] = conditions.apply(node, v);
                        } else {
                            *v_old = Vector::zeros();
                            *v = Vector::zeros();
                        }
                    });
                }
                boundary.reflect_ghosts_in(grid, nodes.clone(), v);
                if flip {
                    boundary.reflect_ghosts_in(grid, nodes, v_old);
                }
            });
    }

    /// USL: G2P velocity, position, then `F ← (I + Δt L) F` and the stress update with the
    /// velocity gradient of the updated grid velocity. Returns whether a particle needs a
    /// closer look by the checks (see [`Checks`]).
    fn update_particles_usl(&self, p: &mut Particles<T, D>, dt: f64) -> bool {
        let cfg = &self.config;
        let dtt = T::cst(dt);
        let layout = Layout::grid(&cfg.grid);
        let (vel, vel_old) = (&self.velocity, &self.velocity_old);
        let checks = Checks::new(cfg, self.time + dt);
        let (blocks, kernels) = (&self.blocks, &self.kernels);
        let mls = cfg.transfer.is_mls();
        finish_particles(p, cfg, &checks, dtt, |i, x, v, c| {
            let st = &kernels[blocks.rank(i)].stencil;
            // MLS takes L = C and needs no gradient sums (a constant flag per call, so
            // each inlines to only its own sums).
            let (g, l) = if mls {
                let g = gather(cfg, st, &layout, false, vel, vel_old);
                (g, g.affine)
            } else {
                let g = gather(cfg, st, &layout, true, vel, vel_old);
                (g, g.grad_v)
            };
            (*v, *c) = cfg.transfer.particle_velocity(v, &g);
            *x += g.v * dtt;
            l
        })
    }

    /// MUSL: G2P velocity and position; map the new particle momentum back to the grid (same
    /// shape functions), apply the walls, and take `L` from that grid velocity. G2P and the
    /// second P2G run in one pass over the blocks (the new state waits in `kernels`); the
    /// stress update writes it back. Returns whether a particle needs a closer look by the checks.
    fn update_particles_musl(&mut self, p: &mut Particles<T, D>, dt: f64) -> bool {
        let dtt = T::cst(dt);
        let layout = Layout::grid(&self.config.grid);
        let affine = self.config.transfer.is_affine();
        {
            let (cfg, pr) = (&self.config, &*p);
            let (vel, vel_old) = (&self.velocity, &self.velocity_old);
            self.blocks.for_each_block(
                &mut self.kernels,
                |e| e.p = Vector::zeros(),
                |i, block, buf, kernel| {
                    let st = &kernel.stencil;
                    let g = gather(cfg, st, &layout, false, vel, vel_old);
                    let (v, c) = cfg.transfer.particle_velocity(&pr.v[i], &g);
                    // Second P2G: momentum of the updated particle velocities at the
                    // start-of-step positions.
                    let mc = if affine {
                        c * pr.mass[i]
                    } else {
                        Tensor::zeros()
                    };
                    p2g_momentum(
                        st,
                        block,
                        &v,
                        &mc,
                        pr.mass[i],
                        buf,
                        #[inline(always)]
                        |e, _, mom| e.p += mom,
                    );
                    (kernel.x, kernel.v, kernel.c) = (pr.x[i] + g.v * dtt, v, c);
                },
            );
        }
        {
            let (grid, boundary, blocks) = (&self.config.grid, &self.config.boundary, &self.blocks);
            let conditions = NodeConditions::new(&self.config, self.time + dt);
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
                                conditions.enforce(node, v, active[i]);
                            } else {
                                *v = Vector::zeros();
                            }
                        });
                    }
                    boundary.reflect_ghosts_in(grid, nodes, v);
                });
        }
        let (cfg, vel, blocks, kernels) =
            (&self.config, &self.velocity, &self.blocks, &self.kernels);
        let checks = Checks::new(cfg, self.time + dt);
        let mls = cfg.transfer.is_mls();
        finish_particles(p, cfg, &checks, dtt, |i, x, v, c| {
            let k = &kernels[blocks.rank(i)];
            (*x, *v, *c) = (k.x, k.v, k.c);
            // L = Σ v_i ⊗ ∇w_ip, or MLS-MPM's C_p of the re-projected velocity (two calls
            // with constant transfers, so each inlines to only its own sums).
            let (st, grid, shape) = (&k.stencil, &cfg.grid, cfg.shape);
            if mls {
                g2p(st, &layout, grid, shape, Transfer::Mls, false, vel, &[]).affine
            } else {
                g2p(st, &layout, grid, shape, Transfer::Pic, true, vel, &[]).grad_v
            }
        })
    }
}

/// The end of a step for every particle, in parallel: `motion(i, x, v, c)` sets particle `i`'s
/// new position, velocity and affine matrix and returns its velocity gradient `L`; then the
/// projection of shallow wall crossings ([`Checks::project`]), `F ← (I + Δt L) F` with the
/// stress update ([`update_stress`]) and the per-particle checks. Returns whether a particle
/// needs a closer look by the checks ([`Checks::flag`]).
#[inline(always)]
fn finish_particles<T: Scalar, const D: usize>(
    p: &mut Particles<T, D>,
    cfg: &Config<T, D>,
    checks: &Checks<'_, T, D>,
    dt: T,
    motion: impl Fn(usize, &mut Vector<T, D>, &mut Vector<T, D>, &mut Tensor<T, D>) -> Tensor<T, D>
    + Sync
    + Send,
) -> bool {
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
    (x, v, f, c, stress, state)
        .into_par_iter()
        .zip(material.par_iter())
        .enumerate()
        .with_min_len(MIN_PARTICLES_PER_TASK)
        .map(
            #[inline(always)]
            |(i, ((x, v, f, c, stress, state), &mat))| {
                let l = motion(i, x, v, c);
                checks.project(x, v);
                update_stress(&cfg.materials[mat as usize], &l, dt, f, stress, state);
                checks.flag(x, v, f, stress)
            },
        )
        .reduce(|| false, |a, b| a || b)
}

/// G2P of the updated grid velocity `vel` (and `old`, for FLIP) at the particle with stencil
/// `st`, with the configuration's transfer; the velocity gradient when `gradient` is set (see
/// [`g2p`]).
#[inline(always)]
fn gather<T: Scalar, const D: usize>(
    cfg: &Config<T, D>,
    st: &Stencil<T, D>,
    layout: &Layout<D>,
    gradient: bool,
    vel: &[Vector<T, D>],
    old: &[Vector<T, D>],
) -> loam_core::transfer::Gathered<T, D> {
    g2p(
        st,
        layout,
        &cfg.grid,
        cfg.shape,
        cfg.transfer,
        gradient,
        vel,
        old,
    )
}

/// The unilateral constraints that acted on a node in the grid update: contact
/// ([`loam_core::Contact::apply`]) and separable walls ([`loam_core::Boundary::apply`]).
#[derive(Clone, Copy, Debug, Default)]
struct Active {
    contact: u64,
    walls: u8,
}

/// The conditions on a nodal velocity after the momentum update: contact (friction segments
/// and obstacles, [`loam_core::Contact::apply`]) at the end-of-step time, then the plain walls
/// ([`loam_core::Boundary::apply`]).
struct NodeConditions<'a, T: Scalar, const D: usize> {
    grid: &'a Grid<D>,
    boundary: &'a loam_core::Boundary<D>,
    contact: &'a loam_core::Contact<T, D>,
    /// Whether there are friction segments (they act on face nodes only) and obstacles
    /// (anywhere).
    segments: bool,
    obstacles: bool,
    time: f64,
}

impl<'a, T: Scalar, const D: usize> NodeConditions<'a, T, D> {
    fn new(cfg: &'a Config<T, D>, time: f64) -> Self {
        Self {
            grid: &cfg.grid,
            boundary: &cfg.boundary,
            contact: &cfg.contact,
            segments: !cfg.contact.segments.is_empty(),
            obstacles: !cfg.contact.obstacles.is_empty(),
            time,
        }
    }

    /// Applies contact and the walls to the trial velocity `v` of `node`; returns the
    /// unilateral constraints that acted.
    #[inline(always)]
    fn apply(&self, node: [usize; D], v: &mut Vector<T, D>) -> Active {
        let face = on_a_face(self.grid, node);
        let mut active = Active::default();
        if face && self.segments || self.obstacles {
            active.contact = self.contact.apply(self.grid, node, self.time, v);
        }
        if face {
            active.walls = self.boundary.apply(self.grid, node, v);
        }
        active
    }

    /// MUSL's second projection: non-penetration on the velocity `v` of `node` for the
    /// constraints that acted in [`NodeConditions::apply`], and the bilateral walls.
    #[inline(always)]
    fn enforce(&self, node: [usize; D], v: &mut Vector<T, D>, active: Active) {
        self.contact
            .enforce(self.grid, node, self.time, v, active.contact);
        if on_a_face(self.grid, node) {
            self.boundary.enforce(self.grid, node, v, active.walls);
        }
    }
}

/// Whether a node lies on (or beyond) a face of the domain, where walls and friction segments
/// act; elsewhere [`loam_core::Boundary::apply`] and the segments of
/// [`loam_core::Contact::apply`] do nothing.
#[inline(always)]
fn on_a_face<const D: usize>(grid: &Grid<D>, node: [usize; D]) -> bool {
    (0..D).any(|a| node[a] <= grid.pad || node[a] >= grid.pad + grid.cells[a])
}

/// How far beyond a unilateral (separable) wall, in cells, a particle centre is still put
/// back onto the face by [`Checks::project`]; a centre deeper than that has escaped.
///
/// A unilateral condition is nodal: it stops the face nodes from moving into the wall, but a
/// particle also interpolates interior nodes, so where a flowing layer thins below about half
/// a particle spacing (the front of a granular or fluid surge) a centre can drift a fraction
/// of a spacing past the face (measured: up to 0.16 spacings in the granular collapses of
/// `docs/verification.md`). Half a cell is a whole particle spacing at 2 particles per cell.
const PROJECTION_DEPTH: f64 = 0.5;

/// The per-particle part of the end-of-step checks, run inside the last particle pass: a
/// particle is flagged when [`check_particles`] or [`check_containment`] would report it, and
/// those (which build the error with every offending id) run only when one is flagged.
struct Checks<'a, T: Scalar, const D: usize> {
    /// Per axis, the positions below / above which a particle has crossed a wall
    /// (±∞ for free faces).
    bounds: [(f64, f64); D],
    /// Per axis and side, whether the wall is unilateral (`separable`, and not free), so that
    /// [`Checks::project`] puts shallow crossings back onto the face.
    unilateral: [[bool; 2]; D],
    /// [`PROJECTION_DEPTH`] in metres.
    depth: f64,
    contact: &'a loam_core::Contact<T, D>,
    time: f64,
}

impl<'a, T: Scalar, const D: usize> Checks<'a, T, D> {
    fn new(cfg: &'a Config<T, D>, time: f64) -> Self {
        let (lo, hi) = (cfg.grid.lo, cfg.grid.hi());
        let walled = |a: usize, side: usize| cfg.boundary.walls[a][side].kind != WallKind::Free;
        Self {
            bounds: std::array::from_fn(|a| {
                (
                    if walled(a, 0) {
                        lo[a]
                    } else {
                        f64::NEG_INFINITY
                    },
                    if walled(a, 1) { hi[a] } else { f64::INFINITY },
                )
            }),
            unilateral: std::array::from_fn(|a| {
                std::array::from_fn(|side| walled(a, side) && cfg.boundary.walls[a][side].separable)
            }),
            depth: PROJECTION_DEPTH * cfg.grid.h,
            contact: &cfg.contact,
            time,
        }
    }

    /// Puts a particle centre that ended the step less than [`PROJECTION_DEPTH`] cells beyond
    /// a unilateral wall back onto the face, `x_a ← lo_a` (or `hi_a`), and removes its
    /// velocity component into the wall, `v_a ← max(v_a, 0)` (or `min`): the position
    /// counterpart of the nodal condition. A deeper centre is left where it is, for
    /// [`check_containment`] to report. Comparisons on real parts; a projected coordinate is
    /// a constant (its sensitivity is zero).
    #[inline(always)]
    fn project(&self, x: &mut Vector<T, D>, v: &mut Vector<T, D>) {
        for a in 0..D {
            let (lo, hi) = self.bounds[a];
            let xa = x[a].re();
            if self.unilateral[a][0] && xa < lo && xa >= lo - self.depth {
                x[a] = T::cst(lo);
                if v[a].re() < 0.0 {
                    v[a] = T::zero();
                }
            } else if self.unilateral[a][1] && xa > hi && xa <= hi + self.depth {
                x[a] = T::cst(hi);
                if v[a].re() > 0.0 {
                    v[a] = T::zero();
                }
            }
        }
    }

    /// Whether the particle has a non-finite field, is inverted, has crossed a wall or lies
    /// in an obstacle.
    #[inline(always)]
    fn flag(
        &self,
        x: &Vector<T, D>,
        v: &Vector<T, D>,
        f: &Tensor<T, D>,
        stress: &nalgebra::Matrix3<T>,
    ) -> bool {
        // One finiteness test of a sum instead of one per entry: a NaN or an infinity in any
        // entry makes the sum non-finite; a finite sum that overflows only flags the particle
        // for the exact checks. Two partial sums and plain indexed loops keep it short.
        let (mut s0, mut s1) = (T::zero(), T::zero());
        for a in 0..D {
            s0 += x[a];
            s1 += v[a];
            for b in 0..D {
                s0 += f[(a, b)];
            }
        }
        for a in 0..3 {
            for b in 0..3 {
                s1 += stress[(a, b)];
            }
        }
        if !(s0 + s1).is_finite_all() || det(f).re() <= 0.0 {
            return true;
        }
        let mut xr = [0.0; D];
        let mut out = false;
        for a in 0..D {
            xr[a] = x[a].re();
            out |= xr[a] < self.bounds[a].0 || xr[a] > self.bounds[a].1;
        }
        out || (!self.contact.is_empty() && self.contact.penetrated(&xr, self.time).is_some())
    }
}

/// `F ← (I + Δt L) F`, then the constitutive update on the 3×3 embedding.
#[inline(always)]
fn update_stress<T: Scalar, const D: usize>(
    material: &loam_core::Material<T>,
    l: &Tensor<T, D>,
    dt: T,
    f: &mut Tensor<T, D>,
    stress: &mut nalgebra::Matrix3<T>,
    state: &mut loam_core::MaterialState<T>,
) {
    let delta_f = Tensor::<T, D>::identity() + l * dt;
    *f = delta_f * *f;
    let f3 = to3(f, T::one());
    let df3 = to3(&delta_f, T::one());
    let l3 = to3(l, T::zero());
    let kin = Kinematics {
        f: &f3,
        delta_f: &df3,
        velocity_gradient: &l3,
        dt,
        stress,
    };
    *stress = material.update(&kin, state);
}

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
