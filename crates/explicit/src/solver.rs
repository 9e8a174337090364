//! The explicit USL / MUSL step.

use crate::blocks::Blocks;
use crate::config::Config;
use crate::error::{ConfigError, StepError};
use loam_core::constitutive::Kinematics;
use loam_core::energy::{Energy, energy};
use loam_core::stencil::particle_half_width;
use loam_core::tensor::{Tensor, Vector, det, from3, to3};
use loam_core::transfer::{g2p, p2g, p2g_momentum};
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
    mass: Vec<T>,
    velocity: Vec<Vector<T, D>>,
    velocity_old: Vec<Vector<T, D>>,
    x_old: Vec<Vector<T, D>>,
    bases: Vec<[isize; D]>,
    wave_speed: Vec<f64>,
    mass_floor: f64,
    steps: usize,
    time: f64,
}

/// Minimum nodal mass (relative to the largest particle mass) below which a node is treated
/// as empty, so `p/m` never divides by round-off.
const MASS_EPS: f64 = 1e-14;

/// The stencil of a particle at `x` with reference half-width `hw0` and deformation `f`.
#[inline]
fn stencil<T: Scalar, const D: usize>(
    cfg: &Config<T, D>,
    x: &Vector<T, D>,
    hw0: &Vector<T, D>,
    f: &Tensor<T, D>,
) -> Stencil<T, D> {
    let hw = particle_half_width(cfg.shape, cfg.grid.h, hw0, f);
    Stencil::new(cfg.shape, &cfg.grid, x, &hw)
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
            blocks: Blocks::new(config.grid.nodes(), config.shape.support_width()),
            mass: vec![T::zero(); n],
            velocity: vec![Vector::zeros(); n],
            velocity_old: vec![Vector::zeros(); n],
            x_old: Vec::new(),
            bases: Vec::new(),
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

    /// Nodal masses of the last step (scratch, for inspection and tests).
    pub fn grid_mass(&self) -> &[T] {
        &self.mass
    }

    /// Energy of a particle state under this configuration.
    pub fn energy(&self, particles: &Particles<T, D>) -> Energy {
        energy(particles, &self.config.materials, &self.config.gravity)
    }

    /// The stability bound `min_p h / (c_p + |v_p|)` and the particle that sets it, with its
    /// wave speed and speed. Ties go to the lowest id, so the result is deterministic.
    pub fn stability_limit(&self, particles: &Particles<T, D>) -> (f64, usize, f64, f64) {
        let h = self.config.grid.h;
        particles
            .v
            .par_iter()
            .zip(particles.material.par_iter())
            .enumerate()
            .map(|(p, (v, &m))| {
                let c = self.wave_speed[m as usize];
                let s = v.map(|x| x.re()).norm();
                (h / (c + s), p, c, s)
            })
            .reduce(
                || (f64::INFINITY, usize::MAX, 0.0, 0.0),
                |a, b| {
                    if b.0 < a.0 || (b.0 == a.0 && b.1 < a.1) {
                        b
                    } else {
                        a
                    }
                },
            )
    }

    fn choose_dt(&self, particles: &Particles<T, D>, cap: f64) -> Result<f64, StepError> {
        let (limit, particle, wave_speed, speed) = self.stability_limit(particles);
        let dt = match self.config.time_step {
            TimeStep::Fixed { dt } => {
                if dt > limit {
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
    pub fn step(
        &mut self,
        particles: &mut Particles<T, D>,
        max_dt: f64,
    ) -> Result<StepInfo, StepError> {
        let dt = self.choose_dt(particles, max_dt)?;
        self.locate(particles)?;
        self.blocks.sort(&self.bases);
        self.transfer_to_grid(particles, dt);
        match self.config.scheme {
            Scheme::Usl => self.update_particles_usl(particles, dt),
            Scheme::Musl => self.update_particles_musl(particles, dt),
        }
        self.steps += 1;
        self.time += dt;
        check_particles(particles, self.steps, self.time)?;
        check_containment(&self.config, particles, self.steps, self.time)?;
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

    /// Stencil bases of every particle; fails when a support leaves the grid.
    fn locate(&mut self, p: &Particles<T, D>) -> Result<(), StepError> {
        self.bases.resize(p.len(), [0; D]);
        let bases: Vec<[isize; D]> = (0..p.len())
            .into_par_iter()
            .map(|i| stencil(&self.config, &p.x[i], &p.half_width0[i], &p.f[i]).base)
            .collect();
        self.bases = bases;
        let (grid, b) = (&self.config.grid, self.config.shape.support_width());
        let ids: Vec<usize> = self
            .bases
            .par_iter()
            .enumerate()
            .filter(|(_, base)| !grid.contains_stencil(**base, b))
            .map(|(i, _)| i)
            .collect();
        if ids.is_empty() {
            return Ok(());
        }
        Err(StepError::LeftGrid {
            step: self.steps + 1,
            time: self.time,
            positions: ids
                .iter()
                .take(3)
                .map(|&i| p.x[i].iter().map(|v| v.re()).collect())
                .collect(),
            ids,
        })
    }

    /// P2G of mass, momentum and internal force, then the grid momentum update with gravity
    /// and walls: `v_i = p_i/m_i`, `v_i ← v_i + Δt (f_i/m_i + g)`.
    fn transfer_to_grid(&mut self, p: &Particles<T, D>, dt: f64) {
        let cfg = &self.config;
        let affine = cfg.transfer.is_affine();
        let contribute = |i: usize, sink: &mut crate::blocks::BlockSink<'_, T, D>| {
            let st = stencil(cfg, &p.x[i], &p.half_width0[i], &p.f[i]);
            let volume = p.volume0[i] * det(&p.f[i]);
            let sv = from3::<T, D>(&p.stress[i]) * volume;
            let c = affine.then_some(&p.c[i]);
            p2g(&st, &p.v[i], c, p.mass[i], &sv, |n, m, mom, f| {
                sink.add(n, m, mom, f)
            });
        };
        self.blocks.accumulate(contribute);
        self.mass_floor = MASS_EPS * p.mass.iter().fold(0.0f64, |a, m| a.max(m.re()));
        let floor = self.mass_floor;
        let (grid, boundary, contact, gravity) = (
            &self.config.grid,
            &self.config.boundary,
            &self.config.contact,
            self.config.gravity,
        );
        // Contact acts at the end of the step, when the grid velocity is reached.
        let time = self.time + dt;
        // Gather the block buffers: momentum goes to `velocity_old`, force to `velocity`
        // until the velocities are formed below.
        let blocks = &self.blocks;
        self.mass
            .par_iter_mut()
            .zip(self.velocity_old.par_iter_mut())
            .zip(self.velocity.par_iter_mut())
            .enumerate()
            .for_each(|(n, ((m, mom), force))| {
                let acc = blocks.gather(grid.multi(n));
                (*m, *mom, *force) = (acc.m, acc.p, acc.f);
            });
        boundary.fold_ghosts(
            grid,
            Some(&mut self.mass),
            &mut self.velocity_old,
            Some(&mut self.velocity),
        );
        let dtt = T::cst(dt);
        self.mass
            .par_iter()
            .zip(self.velocity_old.par_iter_mut())
            .zip(self.velocity.par_iter_mut())
            .enumerate()
            .for_each(|(n, ((&m, v_old), v))| {
                if m.re() > floor {
                    *v_old /= m;
                    *v = *v_old + (*v / m + gravity) * dtt;
                    let node = grid.multi(n);
                    contact.apply(grid, node, time, v, true);
                    boundary.apply(grid, node, v);
                } else {
                    *v_old = Vector::zeros();
                    *v = Vector::zeros();
                }
            });
        boundary.reflect_ghosts(grid, &mut self.velocity);
        if self.config.transfer.needs_old_grid_velocity() {
            boundary.reflect_ghosts(grid, &mut self.velocity_old);
        }
    }

    /// USL: G2P velocity, position, then `F ← (I + Δt L) F` and the stress update with the
    /// velocity gradient of the updated grid velocity.
    fn update_particles_usl(&self, p: &mut Particles<T, D>, dt: f64) {
        let cfg = &self.config;
        let dtt = T::cst(dt);
        let (vel, vel_old) = (&self.velocity, &self.velocity_old);
        let Particles {
            x,
            v,
            f,
            c,
            stress,
            material,
            half_width0,
            state,
            ..
        } = p;
        (x, v, f, c, stress, state)
            .into_par_iter()
            .zip(material.par_iter().zip(half_width0.par_iter()))
            .for_each(|((x, v, f, c, stress, state), (&mat, hw0))| {
                let st = stencil(cfg, x, hw0, f);
                let g = g2p(
                    &st,
                    &cfg.grid,
                    cfg.shape,
                    cfg.transfer,
                    |n| vel[n],
                    |n| vel_old[n],
                );
                (*v, *c) = cfg.transfer.particle_velocity(v, &g);
                *x += g.v * dtt;
                update_stress(
                    &cfg.materials[mat as usize],
                    &g.grad_v,
                    dtt,
                    f,
                    stress,
                    state,
                );
            });
    }

    /// MUSL: G2P velocity and position; map the new particle momentum back to the grid (same
    /// shape functions), apply the walls, and take `L` from that grid velocity.
    fn update_particles_musl(&mut self, p: &mut Particles<T, D>, dt: f64) {
        let dtt = T::cst(dt);
        self.x_old.clone_from(&p.x);
        {
            let cfg = &self.config;
            let (vel, vel_old) = (&self.velocity, &self.velocity_old);
            let Particles {
                x,
                v,
                f,
                c,
                half_width0,
                ..
            } = &mut *p;
            (x, v, c)
                .into_par_iter()
                .zip(f.par_iter().zip(half_width0.par_iter()))
                .for_each(|((x, v, c), (f, hw0))| {
                    let st = stencil(cfg, x, hw0, f);
                    let g = g2p(
                        &st,
                        &cfg.grid,
                        cfg.shape,
                        cfg.transfer,
                        |n| vel[n],
                        |n| vel_old[n],
                    );
                    (*v, *c) = cfg.transfer.particle_velocity(v, &g);
                    *x += g.v * dtt;
                });
        }
        // Second P2G: momentum of the updated particle velocities at the start-of-step positions.
        let affine = self.config.transfer.is_affine();
        {
            let (cfg, x_old, pr) = (&self.config, &self.x_old, &*p);
            let contribute = |i: usize, sink: &mut crate::blocks::BlockSink<'_, T, D>| {
                let xo = &x_old[i];
                let st = stencil(cfg, xo, &pr.half_width0[i], &pr.f[i]);
                let c = affine.then_some(&pr.c[i]);
                p2g_momentum(&st, &pr.v[i], c, pr.mass[i], |n, _, mom| {
                    sink.add_momentum(n, mom)
                });
            };
            self.blocks.accumulate(contribute);
        }
        {
            let (grid, boundary, contact, blocks) = (
                &self.config.grid,
                &self.config.boundary,
                &self.config.contact,
                &self.blocks,
            );
            let time = self.time + dt;
            self.velocity
                .par_iter_mut()
                .enumerate()
                .for_each(|(n, v)| *v = blocks.gather(grid.multi(n)).p);
            boundary.fold_ghosts(grid, None, &mut self.velocity, None);
            let floor = self.mass_floor;
            self.velocity
                .par_iter_mut()
                .zip(self.mass.par_iter())
                .enumerate()
                .for_each(|(n, (v, &m))| {
                    if m.re() > floor {
                        *v /= m;
                        let node = grid.multi(n);
                        contact.apply(grid, node, time, v, false);
                        boundary.apply(grid, node, v);
                    } else {
                        *v = Vector::zeros();
                    }
                });
            boundary.reflect_ghosts(grid, &mut self.velocity);
        }
        let cfg = &self.config;
        let vel = &self.velocity;
        let x_old = &self.x_old;
        let Particles {
            f,
            stress,
            material,
            half_width0,
            state,
            ..
        } = p;
        (f, stress, state)
            .into_par_iter()
            .zip(
                material
                    .par_iter()
                    .zip(half_width0.par_iter())
                    .zip(x_old.par_iter()),
            )
            .for_each(|((f, stress, state), ((&mat, hw0), xo))| {
                let st = stencil(cfg, xo, hw0, f);
                let mut l = Tensor::<T, D>::zeros();
                st.for_each(|n| l += vel[n.flat] * n.gradient.transpose());
                update_stress(&cfg.materials[mat as usize], &l, dtt, f, stress, state);
            });
    }
}

/// `F ← (I + Δt L) F`, then the constitutive update on the 3×3 embedding.
#[inline]
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
