//! The reverse of one explicit USL step: the exact adjoint of the discrete map
//! `(particles at tⁿ, θ) → particles at tⁿ⁺¹` of `loam_explicit::Solver::step`.
//!
//! The forward step, stage by stage (`loam_core::step`), and what the reverse does for each,
//! in the opposite order:
//!
//! | forward | reverse |
//! |---|---|
//! | 1. P2G: `m_i, P_i, f_i = Σ_p φ(x_p, v_p, C_p, F_p, σ_p, m_p, V⁰_p; i)` | a gather per particle: `x̄_p, v̄_p, C̄_p, F̄_p, σ̄_p, m̄_p, V̄⁰_p += Σ_i (∂φ/∂·)ᵀ (m̄_i, P̄_i, f̄_i)` |
//! | 1b. fold of the ghosts across bilateral walls (linear) | its transpose ([`Boundary::fold_ghosts_adjoint`]) |
//! | 2. node update `(vⁿ_i, v̂_i) = ψ(m_i, P_i, f_i; g, μ, …)` | a local VJP per node, by duals ([`crate::lanes`]) |
//! | 2b. reflection of the ghost velocities (linear) | its transpose ([`Boundary::reflect_ghosts_adjoint`]) |
//! | 3. G2P gather `G_p = Σ_i (w v̂_i, w (v̂_i − vⁿ_i), v̂_i ⊗ ∇w, w v̂_i ⊗ (x_i − x_p))` | a scatter per particle: `v̂̄_i += (∂G/∂v̂_i)ᵀ Ḡ`, written for the stencil; `x̄_p` through the weights by `D` dual evaluations |
//! | 3b + 4. particle end `(x, v, C, F, σ, h)ⁿ⁺¹ = χ(G_p, x_p, v_p, F_p, σ_p, h_p; θ)` (velocity update, position, wall projection, `F ← (I + Δt L) F`, stress update) | a local VJP per particle, by duals |
//!
//! The grid of the step is recomputed from the start-of-step particles (serially, in particle
//! order). Branches (stick/slip, separable walls, the projection of shallow wall crossings,
//! yield and return region) are taken on real parts, so every local derivative is that of the
//! branch the recomputed step takes, which is the forward pass's: the same real arithmetic on
//! the same inputs, except that the nodal sums add in another order (the forward sums block by
//! block) and may differ from the forward's in the last bit. A node whose contact state sits
//! exactly on a switch could then take the other branch; `tests/adjoint.rs` checks that the
//! recorded and the recomputed branches agree on its scenes.
//!
//! Sums over particles into nodes (the scatter) run serially in particle order, and the
//! parameters' shares are summed per fixed chunk of particles or nodes and then in chunk
//! order: the gradient has the same bits at any thread count.

use crate::adjoint_state::ParticleAdjoint;
use crate::error::AdjointError;
use crate::lanes::{Packed, Unpack, constants, dot_eps, vjp};
use crate::params::{Acts, Param};
use loam_core::constitutive::{Material, MaterialState, Model};
use loam_core::stencil::{Layout, particle_half_width};
use loam_core::step::{EndOfStep, NodeLaw, NodeSums, P2g, momentum_update, particle_end};
use loam_core::tensor::{Tensor, Vector, det, from3, inverse};
use loam_core::transfer::{Gathered, g2p};
use loam_core::{Particles, Scalar, Scheme, Shape, ShapeFunction, Stencil, Transfer};
use loam_explicit::{Config, MASS_EPS};
use nalgebra::Matrix3;
use num_dual::Dual64;
use rayon::prelude::*;

/// Particles or nodes per parallel task (a fixed split, so that sums have a fixed order).
const CHUNK: usize = 256;

/// The reverse of one step, for one configuration and parameter list: the lifted
/// configurations (one constant, one per parameter with that parameter seeded) and the grid
/// scratch, reused from step to step.
pub struct ReverseStep<const D: usize> {
    config: Config<f64, D>,
    /// The configuration as `Dual64` constants (for the input lanes).
    base: Config<Dual64, D>,
    /// Per parameter acting on the nodes: its index in the gradient and the seeded
    /// configuration.
    node_params: Vec<(usize, Param, Config<Dual64, D>)>,
    /// Per parameter acting on particles of one material: its index in the gradient, the
    /// material and that material seeded.
    particle_params: Vec<(usize, usize, Material<Dual64>)>,
    /// Per material, the input lanes of its particle end (see [`EndLayout`]).
    end_lanes: Vec<Vec<usize>>,
    grid: GridScratch<D>,
}

/// The grid of one step, recomputed, and the adjoints of its fields.
struct GridScratch<const D: usize> {
    /// P2G sums, folded: the node update's inputs.
    sums: Vec<NodeSums<f64, D>>,
    /// Start-of-step grid velocity `vⁿ_i` (reflected; FLIP reads it).
    v_old: Vec<Vector<f64, D>>,
    /// Updated grid velocity `v̂_i` (after contact, walls and the reflection).
    v_hat: Vec<Vector<f64, D>>,
    /// Whether a node took part (`m_i` above the floor).
    live: Vec<bool>,
    /// Whether a unilateral contact constraint acted at the node.
    touched: Vec<bool>,
    /// Adjoints `m̄_i`, `P̄_i`, `f̄_i`, `v̂̄_i`, `v̄ⁿ_i`.
    adj_m: Vec<f64>,
    adj_p: Vec<Vector<f64, D>>,
    adj_f: Vec<Vector<f64, D>>,
    adj_v_hat: Vec<Vector<f64, D>>,
    adj_v_old: Vec<Vector<f64, D>>,
}

/// The order of a particle end's inputs and outputs in the flat lists of [`crate::lanes`].
///
/// Inputs: the gathered `G.v`, `G.dv` (D each), `G.grad_v`, `G.affine` (D² each), the
/// start-of-step `x`, `v` (D each), `F` (D²), `σ` (9), plastic strain (1), history tensor
/// (9). Outputs: `x, v` (D each), `C, F` (D² each), `σ` (9), plastic strain (1), tensor (9).
#[derive(Clone, Copy, Debug)]
struct EndLayout<const D: usize>;

impl<const D: usize> EndLayout<D> {
    const G_V: usize = 0;
    const G_DV: usize = D;
    const G_GRAD: usize = 2 * D;
    const G_AFF: usize = 2 * D + D * D;
    const X: usize = 2 * D + 2 * D * D;
    const V: usize = 3 * D + 2 * D * D;
    const F: usize = 4 * D + 2 * D * D;
    const S: usize = 4 * D + 3 * D * D;
    const H: usize = 4 * D + 3 * D * D + 9;
    const INPUTS: usize = 4 * D + 3 * D * D + 19;

    /// The inputs whose adjoint can be non-zero for `transfer` and `model`: the gathered sums
    /// the transfer forms, the velocity only for FLIP, the stress only for the rate model that
    /// integrates from it, the history only for the plastic models.
    fn lanes(transfer: Transfer, model: &Model<f64>) -> Vec<usize> {
        let mut lanes: Vec<usize> = (Self::G_V..Self::G_V + D).collect();
        if transfer.needs_old_grid_velocity() {
            lanes.extend(Self::G_DV..Self::G_DV + D);
            lanes.extend(Self::V..Self::V + D);
        }
        if !transfer.is_mls() {
            lanes.extend(Self::G_GRAD..Self::G_GRAD + D * D);
        }
        if transfer.is_affine() {
            lanes.extend(Self::G_AFF..Self::G_AFF + D * D);
        }
        lanes.extend(Self::X..Self::X + D);
        lanes.extend(Self::F..Self::F + D * D);
        let (stress, history) = match model {
            Model::DruckerPrager(_) => (true, true),
            Model::J2(_) => (false, true),
            _ => (false, false),
        };
        if stress {
            lanes.extend(Self::S..Self::S + 9);
        }
        if history {
            lanes.extend(Self::H..Self::INPUTS);
        }
        lanes
    }
}

/// One particle's G2P and end of step, `χ` of the module table: the new velocity and affine
/// matrix by the transfer, `x ← x + Δt G.v`, then [`particle_end`] (projection, `F`, stress)
/// with `L = G.grad_v` (MLS-MPM: `G.affine`), exactly as `loam_explicit::Solver::step`
/// composes them. Reads the inputs and writes the outputs in the order of [`EndLayout`].
fn particle_map<T: Scalar, const D: usize>(
    transfer: Transfer,
    dt: T,
    end: &EndOfStep<'_, T, D>,
    material: &Material<T>,
    input: &[T],
    out: &mut Packed<T>,
) {
    let mut u = Unpack::new(input);
    let g = Gathered {
        v: u.vector::<D>(),
        dv: u.vector::<D>(),
        grad_v: u.tensor::<D>(),
        affine: u.tensor::<D>(),
    };
    let x = u.vector::<D>();
    let v = u.vector::<D>();
    let mut f = u.tensor::<D>();
    let mut stress = u.matrix3();
    let mut state = MaterialState {
        plastic_strain: u.scalar(),
        tensor: u.matrix3(),
    };
    let (mut v, c) = transfer.particle_velocity(&v, &g);
    let mut x = x + g.v * dt;
    let l = if transfer.is_mls() {
        g.affine
    } else {
        g.grad_v
    };
    particle_end(
        end,
        material,
        &l,
        dt,
        &mut x,
        &mut v,
        &mut f,
        &mut stress,
        &mut state,
    );
    out.vector(&x);
    out.vector(&v);
    out.tensor(&c);
    out.tensor(&f);
    out.matrix3(&stress);
    out.push(state.plastic_strain);
    out.matrix3(&state.tensor);
}

/// One node's update, `ψ` of the module table: `(vⁿ_i, v̂_i)` from `(m_i, P_i, f_i)` by
/// [`momentum_update`] and the contact and wall law; inputs `[m, P, f]`, outputs `[vⁿ, v̂]`.
fn node_map<T: Scalar, const D: usize>(
    law: &NodeLaw<'_, T, D>,
    gravity: &Vector<T, D>,
    dt: T,
    node: [usize; D],
    input: &[T],
    out: &mut Packed<T>,
) {
    let mut u = Unpack::new(input);
    let m = u.scalar();
    let p = u.vector::<D>();
    let f = u.vector::<D>();
    let (v_old, mut v) = momentum_update(m, &p, &f, gravity, dt);
    law.apply(node, &mut v);
    out.vector(&v_old);
    out.vector(&v);
}

/// What the particle pass of the reverse step leaves per particle.
#[derive(Clone, Copy)]
struct ParticleShare<const D: usize> {
    /// The adjoint of the start-of-step state through the particle end (`C̄` is zero there:
    /// the old affine matrix reaches the step only through P2G).
    x: Vector<f64, D>,
    v: Vector<f64, D>,
    f: Tensor<f64, D>,
    stress: Matrix3<f64>,
    plastic_strain: f64,
    tensor: Matrix3<f64>,
}

impl<const D: usize> ReverseStep<D> {
    /// The reverse step of `config` for the gradient with respect to `params` (in that order).
    ///
    /// # Errors
    /// [`AdjointError::Unsupported`] for MUSL and cpGIMP (not covered yet: the adjoint of the
    /// second P2G, and weights that depend on `F`); [`AdjointError::Parameter`] for a
    /// parameter the configuration does not have.
    pub fn new(config: &Config<f64, D>, params: &[Param]) -> Result<Self, AdjointError> {
        if config.scheme == Scheme::Musl {
            return Err(AdjointError::Unsupported {
                what: "solver.scheme = \"musl\"".into(),
                why: "the reverse pass covers USL steps so far; use scheme = \"usl\"".into(),
            });
        }
        if config.shape == Shape::Cpgimp {
            return Err(AdjointError::Unsupported {
                what: "grid.shape_function = \"cpgimp\"".into(),
                why: "its weights depend on F; use ugimp or a B-spline".into(),
            });
        }
        let mut node_params = Vec::new();
        let mut particle_params = Vec::new();
        for (k, &param) in params.iter().enumerate() {
            let seeded = param.seeded(config)?;
            match param.acts() {
                Acts::Nodes => node_params.push((k, param, seeded)),
                Acts::Particles(m) => particle_params.push((k, m, seeded.materials[m].clone())),
                Acts::Initial => {}
            }
        }
        let n = config.grid.num_nodes();
        Ok(Self {
            base: config.lift(),
            node_params,
            particle_params,
            end_lanes: config
                .materials
                .iter()
                .map(|m| EndLayout::<D>::lanes(config.transfer, &m.model))
                .collect(),
            grid: GridScratch {
                sums: vec![NodeSums::zero(); n],
                v_old: vec![Vector::zeros(); n],
                v_hat: vec![Vector::zeros(); n],
                live: vec![false; n],
                touched: vec![false; n],
                adj_m: vec![0.0; n],
                adj_p: vec![Vector::zeros(); n],
                adj_f: vec![Vector::zeros(); n],
                adj_v_hat: vec![Vector::zeros(); n],
                adj_v_old: vec![Vector::zeros(); n],
            },
            config: config.clone(),
        })
    }

    /// Maps the adjoint of the state after a step of size `dt` from time `time`, started from
    /// the particles `start`, to the adjoint of the state before it (in place), and adds the
    /// parameters' shares of the step to `gradient` (indexed as the `params` of
    /// [`ReverseStep::new`]).
    pub fn reverse(
        &mut self,
        start: &Particles<f64, D>,
        time: f64,
        dt: f64,
        adjoint: &mut ParticleAdjoint<D>,
        gradient: &mut [f64],
    ) {
        self.recompute_grid(start, time, dt);
        let shares = self.reverse_particle_end(start, time, dt, adjoint, gradient);
        self.reverse_nodes(time, dt, gradient);
        self.reverse_p2g(start, dt, &shares, adjoint);
    }

    /// Stages 1 and 2 of the forward step from the start-of-step particles: P2G (serially, in
    /// particle order), the fold of the ghosts, the node update, the reflection.
    fn recompute_grid(&mut self, p: &Particles<f64, D>, time: f64, dt: f64) {
        let cfg = &self.config;
        let g = &mut self.grid;
        g.sums.fill(NodeSums::zero());
        let layout = Layout::grid(&cfg.grid);
        let stage = P2g::new(&cfg.grid, cfg.shape, cfg.transfer, dt);
        let mut stencil = Stencil::new(cfg.shape, &cfg.grid, &p.x[0], &p.half_width0[0]);
        for i in 0..p.len() {
            stage.particle(p, i, &mut stencil, &layout, &mut g.sums);
        }
        let mut mass: Vec<f64> = g.sums.iter().map(|s| s.m).collect();
        let mut mom: Vec<Vector<f64, D>> = g.sums.iter().map(|s| s.p).collect();
        let mut force: Vec<Vector<f64, D>> = g.sums.iter().map(|s| s.f).collect();
        cfg.boundary
            .fold_ghosts(&cfg.grid, Some(&mut mass), &mut mom, Some(&mut force));
        let max_mass = p.mass.iter().fold(0.0f64, |a, &m| a.max(m));
        let floor = MASS_EPS * max_mass;
        let law = NodeLaw::new(&cfg.grid, &cfg.boundary, &cfg.contact, time + dt);
        for n in 0..mass.len() {
            g.sums[n] = NodeSums {
                m: mass[n],
                p: mom[n],
                f: force[n],
            };
            g.live[n] = mass[n] > floor;
            if g.live[n] {
                let (v_old, mut v) = momentum_update(mass[n], &mom[n], &force[n], &cfg.gravity, dt);
                let state = law.apply(cfg.grid.multi(n), &mut v);
                g.touched[n] = state.contact.active != 0;
                (g.v_old[n], g.v_hat[n]) = (v_old, v);
            } else {
                g.touched[n] = false;
                (g.v_old[n], g.v_hat[n]) = (Vector::zeros(), Vector::zeros());
            }
        }
        cfg.boundary.reflect_ghosts(&cfg.grid, &mut g.v_hat);
        if cfg.transfer.needs_old_grid_velocity() {
            cfg.boundary.reflect_ghosts(&cfg.grid, &mut g.v_old);
        }
    }

    /// Stages 3 and 4 in reverse: per particle, the local VJP of the particle end and the
    /// scatter of the gathered sums' adjoints to the nodes (`v̂̄`, `v̄ⁿ`), then the transpose of
    /// the reflection. Returns each particle's share of the start-of-step adjoint.
    fn reverse_particle_end(
        &mut self,
        p: &Particles<f64, D>,
        time: f64,
        dt: f64,
        adjoint: &ParticleAdjoint<D>,
        gradient: &mut [f64],
    ) -> Vec<ParticleShare<D>> {
        let cfg = &self.config;
        let base = &self.base;
        let end = EndOfStep::new(&cfg.grid, &cfg.boundary, &base.contact, time + dt);
        let dtd = Dual64::from_re(dt);
        let b = cfg.shape.support_width();
        let stencil_len = b.pow(D as u32);
        let (grid, transfer, shape) = (&cfg.grid, cfg.transfer, cfg.shape);
        let layout = Layout::grid(grid);
        let scale = gather_scale(cfg);
        let (v_hat, v_old) = (&self.grid.v_hat, &self.grid.v_old);
        let old: &[Vector<f64, D>] = if transfer.needs_old_grid_velocity() {
            v_old
        } else {
            &[]
        };
        let n = p.len();
        let zero_share = ParticleShare {
            x: Vector::zeros(),
            v: Vector::zeros(),
            f: Tensor::zeros(),
            stress: Matrix3::zeros(),
            plastic_strain: 0.0,
            tensor: Matrix3::zeros(),
        };
        let mut shares = vec![zero_share; n];
        let mut scatter = vec![(0usize, Vector::zeros(), Vector::zeros()); n * stencil_len];
        let (end_lanes, particle_params) = (&self.end_lanes, &self.particle_params);
        let nparams = gradient.len();
        let partial: Vec<Vec<f64>> = shares
            .par_chunks_mut(CHUNK)
            .zip(scatter.par_chunks_mut(CHUNK * stencil_len))
            .enumerate()
            .map(|(chunk, (shares, scatter))| {
                let mut grad = vec![0.0; nparams];
                for (k, share) in shares.iter_mut().enumerate() {
                    let i = chunk * CHUNK + k;
                    let mat = p.material[i] as usize;
                    let hw = particle_half_width(shape, grid.h, &p.half_width0[i], &p.f[i]);
                    let st = Stencil::new(shape, grid, &p.x[i], &hw);
                    let gathered = g2p(
                        &st,
                        &layout,
                        grid,
                        shape,
                        transfer,
                        !transfer.is_mls(),
                        v_hat,
                        old,
                    );
                    let mut input = Packed::<f64>::default();
                    input.vector(&gathered.v);
                    input.vector(&gathered.dv);
                    input.tensor(&gathered.grad_v);
                    input.tensor(&gathered.affine);
                    input.vector(&p.x[i]);
                    input.vector(&p.v[i]);
                    input.tensor(&p.f[i]);
                    input.matrix3(&p.stress[i]);
                    input.push(p.state[i].plastic_strain);
                    input.matrix3(&p.state[i].tensor);
                    let mut y_bar = Packed::<f64>::default();
                    y_bar.vector(&adjoint.x[i]);
                    y_bar.vector(&adjoint.v[i]);
                    y_bar.tensor(&adjoint.c[i]);
                    y_bar.tensor(&adjoint.f[i]);
                    y_bar.matrix3(&adjoint.stress[i]);
                    y_bar.push(adjoint.plastic_strain[i]);
                    y_bar.matrix3(&adjoint.tensor[i]);
                    let mut x_bar = [0.0; crate::lanes::MAX_LANES];
                    let material = &base.materials[mat];
                    vjp(
                        input.as_slice(),
                        end_lanes[mat].iter().copied(),
                        y_bar.as_slice(),
                        &mut x_bar,
                        |i, out| particle_map(transfer, dtd, &end, material, i, out),
                    );
                    let constant = constants(input.as_slice());
                    for (k, m, seeded) in particle_params {
                        if *m == mat {
                            let mut out = Packed::default();
                            particle_map(
                                transfer,
                                dtd,
                                &end,
                                seeded,
                                constant.as_slice(),
                                &mut out,
                            );
                            grad[*k] += dot_eps(out.as_slice(), y_bar.as_slice());
                        }
                    }
                    let mut u = Unpack::new(&x_bar[..EndLayout::<D>::INPUTS]);
                    let g_bar = Gathered {
                        v: u.vector::<D>(),
                        dv: u.vector::<D>(),
                        grad_v: u.tensor::<D>(),
                        affine: u.tensor::<D>(),
                    };
                    *share = ParticleShare {
                        x: u.vector::<D>(),
                        v: u.vector::<D>(),
                        f: u.tensor::<D>(),
                        stress: u.matrix3(),
                        plastic_strain: u.scalar(),
                        tensor: u.matrix3(),
                    };
                    let out = &mut scatter[k * stencil_len..(k + 1) * stencil_len];
                    share.x +=
                        gather_adjoint(&st, &g_bar, scale, v_hat, old, &p.x[i], &hw, cfg, out);
                }
                grad
            })
            .collect();
        for part in partial {
            for (g, x) in gradient.iter_mut().zip(part) {
                *g += x;
            }
        }
        let g = &mut self.grid;
        g.adj_v_hat.fill(Vector::zeros());
        g.adj_v_old.fill(Vector::zeros());
        for &(node, a_hat, a_old) in &scatter {
            g.adj_v_hat[node] += a_hat;
            g.adj_v_old[node] += a_old;
        }
        cfg.boundary.reflect_ghosts_adjoint(grid, &mut g.adj_v_hat);
        if transfer.needs_old_grid_velocity() {
            cfg.boundary.reflect_ghosts_adjoint(grid, &mut g.adj_v_old);
        }
        shares
    }

    /// Stage 2 in reverse: per live node, the local VJP of the node update (and the
    /// parameters' shares: gravity everywhere, contact where a contact constraint acted),
    /// then the transpose of the fold.
    fn reverse_nodes(&mut self, time: f64, dt: f64, gradient: &mut [f64]) {
        let cfg = &self.config;
        let grid = &cfg.grid;
        let dtd = Dual64::from_re(dt);
        let base_law = NodeLaw::new(grid, &cfg.boundary, &self.base.contact, time + dt);
        let seeded: Vec<(usize, Param, NodeLaw<'_, Dual64, D>, Vector<Dual64, D>)> = self
            .node_params
            .iter()
            .map(|(k, param, c)| {
                let law = NodeLaw::new(grid, &cfg.boundary, &c.contact, time + dt);
                (*k, *param, law, c.gravity)
            })
            .collect();
        let g = &mut self.grid;
        let (sums, live, touched) = (&g.sums, &g.live, &g.touched);
        let (adj_v_hat, adj_v_old) = (&g.adj_v_hat, &g.adj_v_old);
        let nparams = gradient.len();
        let gravity = self.base.gravity;
        let partial: Vec<Vec<f64>> = g
            .adj_m
            .par_chunks_mut(CHUNK)
            .zip(g.adj_p.par_chunks_mut(CHUNK))
            .zip(g.adj_f.par_chunks_mut(CHUNK))
            .enumerate()
            .map(|(chunk, ((am, ap), af))| {
                let mut grad = vec![0.0; nparams];
                for k in 0..am.len() {
                    let n = chunk * CHUNK + k;
                    (am[k], ap[k], af[k]) = (0.0, Vector::zeros(), Vector::zeros());
                    if !live[n] {
                        continue;
                    }
                    let mut y_bar = Packed::<f64>::default();
                    y_bar.vector(&adj_v_old[n]);
                    y_bar.vector(&adj_v_hat[n]);
                    if y_bar.as_slice().iter().all(|&y| y == 0.0) {
                        continue;
                    }
                    let mut input = Packed::<f64>::default();
                    input.push(sums[n].m);
                    input.vector(&sums[n].p);
                    input.vector(&sums[n].f);
                    let node = grid.multi(n);
                    let mut x_bar = [0.0; 1 + 2 * 3];
                    vjp(
                        input.as_slice(),
                        0..1 + 2 * D,
                        y_bar.as_slice(),
                        &mut x_bar,
                        |i, out| node_map(&base_law, &gravity, dtd, node, i, out),
                    );
                    let mut u = Unpack::new(&x_bar[..1 + 2 * D]);
                    (am[k], ap[k], af[k]) = (u.scalar(), u.vector::<D>(), u.vector::<D>());
                    let constant = constants(input.as_slice());
                    for (index, param, law, grav) in &seeded {
                        if matches!(param, Param::Gravity(_)) || touched[n] {
                            let mut out = Packed::default();
                            node_map(law, grav, dtd, node, constant.as_slice(), &mut out);
                            grad[*index] += dot_eps(out.as_slice(), y_bar.as_slice());
                        }
                    }
                }
                grad
            })
            .collect();
        for part in partial {
            for (g, x) in gradient.iter_mut().zip(part) {
                *g += x;
            }
        }
        cfg.boundary
            .fold_ghosts_adjoint(grid, &mut g.adj_m, &mut g.adj_p, &mut g.adj_f);
    }

    /// Stage 1 in reverse: per particle, the gather of the node adjoints through its P2G
    /// contributions, added to its share from the particle end; the result replaces the
    /// adjoint (mass and reference volume accumulate).
    fn reverse_p2g(
        &self,
        p: &Particles<f64, D>,
        dt: f64,
        shares: &[ParticleShare<D>],
        adjoint: &mut ParticleAdjoint<D>,
    ) {
        let cfg = &self.config;
        let g = &self.grid;
        let (adj_m, adj_p, adj_f) = (&g.adj_m, &g.adj_p, &g.adj_f);
        let (grid, shape, transfer) = (&cfg.grid, cfg.shape, cfg.transfer);
        // MLS-MPM: A = m C − Δt V σ D⁻¹ with D⁻¹ = (1/κ)/h² I.
        let mls = transfer
            .is_mls()
            .then(|| dt * shape.apic_inverse_inertia().unwrap_or(0.0) / (grid.h * grid.h));
        let affine = transfer.is_affine();
        let ParticleAdjoint {
            x,
            v,
            c,
            f,
            stress,
            plastic_strain,
            tensor,
            mass,
            volume0,
        } = adjoint;
        (x, v, c, f, stress, plastic_strain, tensor, mass, volume0)
            .into_par_iter()
            .zip(shares.par_iter())
            .enumerate()
            .with_min_len(CHUNK)
            .for_each(
                |(i, ((x, v, c, f, stress, ps, tensor, mass, volume0), share))| {
                    let hw = particle_half_width(shape, grid.h, &p.half_width0[i], &p.f[i]);
                    let st = Stencil::new(shape, grid, &p.x[i], &hw);
                    let (m, vp, cp, fp) = (p.mass[i], p.v[i], p.c[i], p.f[i]);
                    let j = det(&fp);
                    let vol = p.volume0[i] * j;
                    let sigma = from3::<f64, D>(&p.stress[i]);
                    let sv = sigma * vol;
                    let a = match mls {
                        Some(k) => cp * m - sv * k,
                        None if affine => cp * m,
                        None => Tensor::zeros(),
                    };
                    // Moments of the node adjoints over the stencil.
                    let (mut s0, mut s1) = (0.0, Vector::<f64, D>::zeros());
                    let (mut s2, mut s3) = (Tensor::<f64, D>::zeros(), Tensor::<f64, D>::zeros());
                    st.for_each(|node| {
                        let n = node.flat;
                        s0 += node.weight * adj_m[n];
                        s1 += adj_p[n] * node.weight;
                        s2 += adj_p[n] * node.offset.transpose() * node.weight;
                        s3 += adj_f[n] * node.gradient.transpose();
                    });
                    // J = m s0 + m v·s1 + A:s2 − (V σ):s3 (no force term for MLS-MPM).
                    let mut sv_bar = -s3;
                    if let Some(k) = mls {
                        sv_bar = -s2 * k;
                    }
                    let x_bar =
                        share.x + p2g_position_adjoint(cfg, &p.x[i], &hw, m, &vp, &a, &sv, g);
                    *x = x_bar;
                    *v = share.v + s1 * m;
                    *c = if affine { s2 * m } else { Tensor::zeros() };
                    let vol_bar = sv_bar.component_mul(&sigma).sum();
                    let mut s_bar = share.stress;
                    for r in 0..D {
                        for col in 0..D {
                            s_bar[(r, col)] += sv_bar[(r, col)] * vol;
                        }
                    }
                    *stress = s_bar;
                    // V = V⁰ det F: ∂V/∂F = V⁰ det F F⁻ᵀ.
                    let cof = inverse(&fp).map_or_else(Tensor::zeros, |inv| inv.transpose() * j);
                    *f = share.f + cof * (p.volume0[i] * vol_bar);
                    *ps = share.plastic_strain;
                    *tensor = share.tensor;
                    *mass += s0
                        + vp.dot(&s1)
                        + if affine {
                            cp.component_mul(&s2).sum()
                        } else {
                            0.0
                        };
                    *volume0 += j * vol_bar;
                },
            );
    }
}

/// `k/h²` of the APIC / MLS-MPM affine sum `C = (k/h²) Σ w v (x_i − x_p)ᵀ` when the transfer
/// forms it that way (B-splines), `None` when its affine matrix is the velocity gradient
/// (TPIC, APIC with the hat and GIMP) or it has none.
fn gather_scale<const D: usize>(cfg: &Config<f64, D>) -> Option<f64> {
    match cfg.transfer {
        Transfer::Apic | Transfer::Mls => cfg
            .shape
            .apic_inverse_inertia()
            .map(|k| k / (cfg.grid.h * cfg.grid.h)),
        _ => None,
    }
}

/// The adjoint of the G2P gather for one particle with stencil `st`: writes
/// `(node, v̂̄ share, v̄ⁿ share)` per stencil node into `out`,
/// `v̂̄_i = w Ḡ.v + w Ḡ.dv + Ḡ.grad ∇w + (k/h²) w Ḡ.aff (x_i − x_p)`, `v̄ⁿ_i = −w Ḡ.dv`, and
/// returns `x̄_p` through the weights, gradients and offsets: `∂/∂x_p (Ḡ · G)` with the nodal
/// velocities held, by `D` evaluations with a dual position.
#[allow(clippy::too_many_arguments)]
fn gather_adjoint<const D: usize>(
    st: &Stencil<f64, D>,
    g_bar: &Gathered<f64, D>,
    scale: Option<f64>,
    v_hat: &[Vector<f64, D>],
    old: &[Vector<f64, D>],
    x: &Vector<f64, D>,
    hw: &Vector<f64, D>,
    cfg: &Config<f64, D>,
    out: &mut [(usize, Vector<f64, D>, Vector<f64, D>)],
) -> Vector<f64, D> {
    let affine_is_gradient = cfg.transfer.is_affine() && scale.is_none();
    let grad_bar = if affine_is_gradient {
        g_bar.grad_v + g_bar.affine
    } else {
        g_bar.grad_v
    };
    let aff_bar = scale.map(|k| g_bar.affine * k);
    let mut k = 0;
    st.for_each(|node| {
        let w = node.weight;
        let mut a = (g_bar.v + g_bar.dv) * w + grad_bar * node.gradient;
        if let Some(aff) = aff_bar {
            a += aff * node.offset * w;
        }
        out[k] = (node.flat, a, -g_bar.dv * w);
        k += 1;
    });
    let mut x_bar = Vector::zeros();
    let lift = |t: &Tensor<f64, D>| t.map(Dual64::from_re);
    let (gv, gdv) = (g_bar.v.map(Dual64::from_re), g_bar.dv.map(Dual64::from_re));
    let grad_d = lift(&grad_bar);
    let aff_d = aff_bar.map(|a| lift(&a));
    let hw_d = hw.map(Dual64::from_re);
    for a in 0..D {
        let mut xd = x.map(Dual64::from_re);
        xd[a].eps = 1.0;
        let std = Stencil::new(cfg.shape, &cfg.grid, &xd, &hw_d);
        let mut j = Dual64::from_re(0.0);
        std.for_each(|node| {
            let vi = v_hat[node.flat].map(Dual64::from_re);
            let w = node.weight;
            let mut s = gv.dot(&vi) * w + vi.dot(&(grad_d * node.gradient));
            if !old.is_empty() {
                let dv = vi - old[node.flat].map(Dual64::from_re);
                s += gdv.dot(&dv) * w;
            }
            if let Some(aff) = &aff_d {
                s += vi.dot(&(aff * node.offset)) * w;
            }
            j += s;
        });
        x_bar[a] = j.eps;
    }
    x_bar
}

/// `x̄_p` through P2G's weights, gradients and offsets:
/// `∂/∂x_p Σ_i [m̄_i m w + P̄_i · w (m v + A (x_i − x_p)) − f̄_i · (V σ) ∇w]` with the particle's
/// other fields held, by `D` evaluations with a dual position.
#[allow(clippy::too_many_arguments)]
fn p2g_position_adjoint<const D: usize>(
    cfg: &Config<f64, D>,
    x: &Vector<f64, D>,
    hw: &Vector<f64, D>,
    m: f64,
    v: &Vector<f64, D>,
    a: &Tensor<f64, D>,
    sv: &Tensor<f64, D>,
    g: &GridScratch<D>,
) -> Vector<f64, D> {
    let mut x_bar = Vector::zeros();
    let hw_d = hw.map(Dual64::from_re);
    let mv = (v * m).map(Dual64::from_re);
    let a_d = a.map(Dual64::from_re);
    let sv_d = sv.map(Dual64::from_re);
    let md = Dual64::from_re(m);
    let force = !cfg.transfer.is_mls();
    for axis in 0..D {
        let mut xd = x.map(Dual64::from_re);
        xd[axis].eps = 1.0;
        let st = Stencil::new(cfg.shape, &cfg.grid, &xd, &hw_d);
        let mut j = Dual64::from_re(0.0);
        st.for_each(|node| {
            let n = node.flat;
            let w = node.weight;
            let pb = g.adj_p[n].map(Dual64::from_re);
            let mut s = md * w * g.adj_m[n] + pb.dot(&(mv + a_d * node.offset)) * w;
            if force {
                let fb = g.adj_f[n].map(Dual64::from_re);
                s -= fb.dot(&(sv_d * node.gradient));
            }
            j += s;
        });
        x_bar[axis] = j.eps;
    }
    x_bar
}
