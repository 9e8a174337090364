//! The reverse of one explicit step: the exact adjoint of the discrete map
//! `(particles at tⁿ, θ) → particles at tⁿ⁺¹` of `loam_explicit::Solver::step`, USL and MUSL.
//!
//! The forward step, stage by stage (`loam_core::step`), and what the reverse does for each,
//! in the opposite order:
//!
//! | forward | reverse |
//! |---|---|
//! | 1. P2G: `m_i, P_i, f_i = Σ_p φ(x_p, v_p, C_p, F_p, σ_p, m_p, V⁰_p; i)` | a gather per particle: `x̄_p, v̄_p, C̄_p, F̄_p, σ̄_p, m̄_p, V̄⁰_p += Σ_i (∂φ/∂·)ᵀ (m̄_i, P̄_i, f̄_i)` ([`transfers`]) |
//! | 1b. fold of the ghosts across bilateral walls (linear) | its transpose (`Boundary::fold_ghosts_adjoint`) |
//! | 2. node update `(vⁿ_i, v̂_i) = ψ(m_i, P_i, f_i; g, μ, …)` | a local VJP per node, by duals ([`crate::lanes`]) |
//! | 2b. reflection of the ghost velocities (linear) | its transpose (`Boundary::reflect_ghosts_adjoint`) |
//! | 3. G2P gather `G_p = Σ_i (w v̂_i, w (v̂_i − vⁿ_i), v̂_i ⊗ ∇w, w v̂_i ⊗ (x_i − x_p))` | a scatter per particle, `v̂̄_i += (∂G/∂v̂_i)ᵀ Ḡ`; `x̄_p` through the weights |
//! | 3b. G2P motion and (USL) the particle end: velocity, affine matrix, position, wall projection, `F ← (I + Δt L) F`, stress update | a local VJP per particle, by duals |
//!
//! MUSL inserts, between 3b's motion and the particle end, a second P2G of momentum at the
//! start-of-step stencils, its fold, `v_i = P₂_i/m_i` with the first projection's active set
//! enforced, its reflection, and the gather of `L` from that field; the reverse runs their
//! adjoints in between (`musl.rs`).
//!
//! The grid of the step's first projection (the folded P2G sums, `vⁿ`, `v̂`, what the node law
//! did) is read from the forward step's [`StepTrace`] (`Solver::step_traced`), not formed
//! again: the local derivatives are taken at the forward pass's own values. Branches
//! (stick/slip, separable walls, the projection of shallow wall crossings, yield and return
//! region) are taken on real parts of the same inputs, so every local derivative is that of
//! the branch the forward pass took. The G2P sums (except those of USL with MLS-MPM and the
//! fluid, read from the state after the step) and MUSL's second P2G are formed again here
//! from the traced grid (MUSL's second P2G serially, in particle order: the forward sums block
//! by block, so those sums may differ from the forward's in the last bit, and a node whose
//! second projection sits exactly on a switch could take the other branch);
//! `tests/adjoint.rs` checks the gradient against forward-mode duals on scenes with stick,
//! slip and yield.
//!
//! Sums over particles into nodes (the scatters) run in particle order over two fixed halves of
//! the particles, whose sums are then added per node, and the parameters' shares are summed per fixed chunk of particles or nodes and then in chunk
//! order: the gradient has the same bits at any thread count.

mod fluid_mls;
mod kernels;
mod musl;
mod transfers;
mod usl;

use crate::adjoint_state::ParticleAdjoint;
use crate::error::AdjointError;
use crate::lanes::{MAX_LANES, Packed, Unpack, constants, dot_eps, vjp};
use crate::params::{Acts, Param};
use kernels::node_update;
use loam_core::constitutive::{Material, MaterialState};
use loam_core::stencil::{Frame, particle_half_width};
use loam_core::step::{NodeLaw, NodeState, NodeSums, on_a_face};
use loam_core::tensor::{Tensor, Vector, cofactor, det, from3};
use loam_core::{Particles, Scheme, Shape, Stencil, Transfer};
use loam_explicit::{Config, GridFields, StepTrace};
use nalgebra::Matrix3;
use num_dual::Dual64;
use rayon::prelude::*;
use transfers::{GatherForm, NodeAdjoints, Site};

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
    grid: GridScratch<D>,
    /// Every particle's stencil at the start of the step being reversed, formed once and
    /// shared by the reverse passes.
    stencils: Vec<Stencil<f64, D>>,
    /// The G2P adjoint's scatter before its sum, kept from step to step (every entry is
    /// written before it is read).
    scatter: Scatter<D>,
    /// Each particle's [`ParticleShare`], kept from step to step (every field of every entry
    /// is written before it is read).
    shares: Vec<ParticleShare<D>>,
}

/// The grid of one step, from its trace, and the adjoints of its fields.
struct GridScratch<const D: usize> {
    /// P2G sums, folded: the node update's inputs.
    sums: Vec<NodeSums<f64, D>>,
    /// Start-of-step grid velocity `vⁿ_i` (reflected; FLIP reads it).
    v_old: Vec<Vector<f64, D>>,
    /// Updated grid velocity `v̂_i` (after contact, walls and the reflection).
    v_hat: Vec<Vector<f64, D>>,
    /// What the node law did (MUSL's second projection enforces it again).
    states: Vec<NodeState>,
    /// Whether a node took part (`m_i` above the floor).
    live: Vec<bool>,
    /// Adjoints `m̄_i`, `P̄_i`, `f̄_i`, `v̂̄_i`, `v̄ⁿ_i`.
    adj_m: Vec<f64>,
    adj_p: Vec<Vector<f64, D>>,
    adj_f: Vec<Vector<f64, D>>,
    adj_v_hat: Vec<Vector<f64, D>>,
    adj_v_old: Vec<Vector<f64, D>>,
    /// The second half of a scatter's sums ([`ReverseStep::add_scatter`]).
    half: Vec<Vector<f64, D>>,
    half_old: Vec<Vector<f64, D>>,
}

/// One particle's share of the adjoint of the start-of-step state from the stages after P2G
/// (the old affine matrix reaches the step only through P2G).
#[derive(Clone, Copy)]
struct ParticleShare<const D: usize> {
    x: Vector<f64, D>,
    v: Vector<f64, D>,
    f: Tensor<f64, D>,
    stress: Matrix3<f64>,
    history: MaterialState<f64>,
    /// `m̄_p` from MUSL's second P2G.
    mass: f64,
}

impl<const D: usize> ParticleShare<D> {
    fn zero() -> Self {
        Self {
            x: Vector::zeros(),
            v: Vector::zeros(),
            f: Tensor::zeros(),
            stress: Matrix3::zeros(),
            history: MaterialState::zeros(),
            mass: 0.0,
        }
    }

    /// Reads `F̄, σ̄` and the history's adjoints (the [`kernels::End`] block).
    fn read_end(&mut self, u: &mut Unpack<'_, f64>) {
        self.f = u.tensor::<D>();
        self.stress = u.matrix3();
        self.history = u.history();
    }
}

/// A scatter to the nodes: `(node, v̄ share, v̄ⁿ share)` per stencil node of every particle.
type Scatter<const D: usize> = Vec<(usize, Vector<f64, D>, Vector<f64, D>)>;

/// Packs the particle's end-of-step state fields `F, σ` and history (the [`kernels::End`]
/// block).
fn pack_end<const D: usize>(p: &Particles<f64, D>, i: usize, out: &mut Packed<f64>) {
    out.tensor(&p.f[i]);
    out.matrix3(&p.stress[i]);
    out.history(&p.state[i]);
}

/// Packs the adjoints of `F, σ` and the history.
fn pack_end_adjoint<const D: usize>(a: &ParticleAdjoint<D>, i: usize, out: &mut Packed<f64>) {
    out.tensor(&a.f[i]);
    out.matrix3(&a.stress[i]);
    out.history(&a.history[i]);
}

/// Sums the entries of a scatter, in their order, into `adj` (and their `vⁿ` shares into
/// `old`) after zeroing them: `adj_i = Σ_{entries at i} v̂̄ share`.
fn sum_scatter<const D: usize>(
    entries: &[(usize, Vector<f64, D>, Vector<f64, D>)],
    adj: &mut [Vector<f64, D>],
    old: Option<&mut [Vector<f64, D>]>,
) {
    adj.fill(Vector::zeros());
    match old {
        Some(old) => {
            old.fill(Vector::zeros());
            for &(node, a, a_old) in entries {
                adj[node] += a;
                old[node] += a_old;
            }
        }
        None => {
            for &(node, a, _) in entries {
                adj[node] += a;
            }
        }
    }
}

/// `a_i += b_i` on every node, in parallel.
fn add_nodes<const D: usize>(a: &mut [Vector<f64, D>], b: &[Vector<f64, D>]) {
    a.par_chunks_mut(CHUNK)
        .zip(b.par_chunks(CHUNK))
        .for_each(|(a, b)| a.iter_mut().zip(b).for_each(|(a, b)| *a += b));
}

/// Adds per-chunk parameter shares to the gradient, in chunk order.
fn add_parts(gradient: &mut [f64], parts: Vec<Vec<f64>>) {
    for part in parts {
        for (g, x) in gradient.iter_mut().zip(part) {
            *g += x;
        }
    }
}

impl<const D: usize> ReverseStep<D> {
    /// The reverse step of `config` for the gradient with respect to `params` (in that order).
    ///
    /// # Errors
    /// [`AdjointError::Unsupported`] for cpGIMP (its weights depend on `F`, which the
    /// transfers' adjoints do not follow yet); [`AdjointError::Parameter`] for a parameter
    /// the configuration does not have.
    pub fn new(config: &Config<f64, D>, params: &[Param]) -> Result<Self, AdjointError> {
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
            grid: GridScratch {
                sums: vec![NodeSums::zero(); n],
                v_old: vec![Vector::zeros(); n],
                v_hat: vec![Vector::zeros(); n],
                states: vec![NodeState::default(); n],
                live: vec![false; n],
                adj_m: vec![0.0; n],
                adj_p: vec![Vector::zeros(); n],
                adj_f: vec![Vector::zeros(); n],
                adj_v_hat: vec![Vector::zeros(); n],
                adj_v_old: vec![Vector::zeros(); n],
                half: vec![Vector::zeros(); n],
                half_old: vec![Vector::zeros(); n],
            },
            stencils: Vec::new(),
            scatter: Vec::new(),
            shares: Vec::new(),
            config: config.clone(),
        })
    }

    /// Maps the adjoint of the state after a step from time `time`, started from the
    /// particles `start`, ended on the particles `after` and traced into `trace`
    /// ([`loam_explicit::Solver::step_traced`]), to the adjoint of the state before it (in
    /// place), and adds the parameters' shares of the step to `gradient` (indexed as the
    /// `params` of [`ReverseStep::new`]).
    pub fn reverse(
        &mut self,
        start: &Particles<f64, D>,
        after: &Particles<f64, D>,
        trace: &StepTrace<f64, D>,
        time: f64,
        adjoint: &mut ParticleAdjoint<D>,
        gradient: &mut [f64],
    ) {
        let dt = trace.dt;
        self.locate(start);
        self.load_grid(trace);
        let (shares, extra_mass) = match self.config.scheme {
            Scheme::Usl => {
                let shares = self.usl_particles(start, after, time, dt, adjoint, gradient);
                (shares, None)
            }
            Scheme::Musl => {
                let (shares, m) = self.musl_particles(start, time, dt, adjoint, gradient);
                (shares, Some(m))
            }
        };
        self.reverse_nodes(time, dt, extra_mass.as_deref(), gradient);
        self.reverse_p2g(start, dt, &shares, adjoint);
        self.shares = shares;
    }

    /// The shares' buffer for `n` particles, taken from the previous step (its entries are
    /// stale: the caller writes every field of each).
    fn take_shares(&mut self, n: usize) -> Vec<ParticleShare<D>> {
        let mut shares = std::mem::take(&mut self.shares);
        shares.resize(n, ParticleShare::zero());
        shares
    }

    /// The local VJP of a particle kernel `f(material, inputs, outputs)` at `input` for a
    /// particle of material `mat`, seeding `lanes`, against the output adjoints `y_bar`; adds
    /// the shares of the parameters of that material to `grad` (one evaluation each with the
    /// seeded material and constant inputs). Returns the input adjoints.
    fn particle_vjp(
        &self,
        mat: usize,
        input: &Packed<f64>,
        lanes: &[usize],
        y_bar: &Packed<f64>,
        grad: &mut [f64],
        f: impl Fn(&Material<Dual64>, &[Dual64], &mut Packed<Dual64>),
    ) -> [f64; MAX_LANES] {
        let mut x_bar = [0.0; MAX_LANES];
        let material = &self.base.materials[mat];
        vjp(
            input.as_slice(),
            lanes.iter().copied(),
            y_bar.as_slice(),
            &mut x_bar,
            |i, out| f(material, i, out),
        );
        let constant = constants(input.as_slice());
        for (index, m, seeded) in &self.particle_params {
            if *m == mat {
                let mut out = Packed::default();
                f(seeded, constant.as_slice(), &mut out);
                grad[*index] += dot_eps(out.as_slice(), y_bar.as_slice());
            }
        }
        x_bar
    }

    /// The half-width of particle `i`'s shape function.
    fn half_width(&self, p: &Particles<f64, D>, i: usize) -> Vector<f64, D> {
        let cfg = &self.config;
        particle_half_width(cfg.shape, cfg.grid.h, &p.half_width0[i], &p.f[i])
    }

    /// Forms every particle's stencil at the start of the step (in parallel), in place in the
    /// stencils kept from the step before ([`Stencil::set_in`]: nothing built and copied).
    fn locate(&mut self, p: &Particles<f64, D>) {
        let mut stencils = std::mem::take(&mut self.stencils);
        let cfg = &self.config;
        let frame = Frame::new(&cfg.grid);
        stencils.truncate(p.len());
        for i in stencils.len()..p.len() {
            stencils.push(Stencil::new(
                cfg.shape,
                &cfg.grid,
                &p.x[i],
                &self.half_width(p, i),
            ));
        }
        stencils
            .par_iter_mut()
            .with_min_len(CHUNK)
            .enumerate()
            .for_each(|(i, s)| s.set_in(cfg.shape, &frame, &p.x[i], &self.half_width(p, i)));
        self.stencils = stencils;
    }

    /// The stencil site of particle `i` (its stencil from [`ReverseStep::locate`]).
    fn site(&self, p: &Particles<f64, D>, i: usize) -> Site<'_, D> {
        let cfg = &self.config;
        Site::new(
            &cfg.grid,
            cfg.shape,
            p.x[i],
            self.half_width(p, i),
            &self.stencils[i],
        )
    }

    /// How the transfer's G2P forms its sums.
    fn gather_form(&self) -> GatherForm {
        let cfg = &self.config;
        let scale = match cfg.transfer {
            Transfer::Apic | Transfer::Mls => cfg
                .shape
                .apic_inverse_inertia()
                .map(|k| k / (cfg.grid.h * cfg.grid.h)),
            _ => None,
        };
        GatherForm {
            scale,
            affine_is_gradient: cfg.transfer.is_affine() && scale.is_none(),
        }
    }

    /// Stages 1 and 2 of the forward step, as the step kept them: the folded P2G sums, the
    /// node states and the velocities on every node, and which nodes took part.
    fn load_grid(&mut self, trace: &StepTrace<f64, D>) {
        let g = &mut self.grid;
        trace.expand(GridFields {
            sums: &mut g.sums,
            velocity: &mut g.v_hat,
            velocity_old: &mut g.v_old,
            states: &mut g.states,
        });
        let floor = trace.mass_floor;
        g.live
            .par_iter_mut()
            .zip(g.sums.par_iter())
            .with_min_len(CHUNK)
            .for_each(|(live, s)| *live = s.m > floor);
    }

    /// Adds a scatter into `adj` after zeroing it, and the `vⁿ` shares into `adj_old` when
    /// given. The scatter is cut into two fixed halves (by entry count, so the cut does not
    /// depend on the thread count); each half is summed in particle order into an array of its
    /// own (the second into `half`, `half_old`) at the same time, then `adj = first + second`
    /// per node: the same bits at any thread count, with both halves' sums running at once.
    fn add_scatter(
        scatter: &Scatter<D>,
        adj: &mut [Vector<f64, D>],
        adj_old: Option<&mut [Vector<f64, D>]>,
        half: &mut [Vector<f64, D>],
        half_old: &mut [Vector<f64, D>],
    ) {
        let (first, second) = scatter.split_at(scatter.len() / 2);
        match adj_old {
            Some(old) => {
                rayon::join(
                    || sum_scatter(first, adj, Some(&mut *old)),
                    || sum_scatter(second, half, Some(&mut *half_old)),
                );
                add_nodes(adj, half);
                add_nodes(old, half_old);
            }
            None => {
                rayon::join(
                    || sum_scatter(first, adj, None),
                    || sum_scatter(second, half, None),
                );
                add_nodes(adj, half);
            }
        }
    }

    /// The adjoint of the first grid's velocities from the G2P scatter: `v̂̄` (and `v̄ⁿ` for
    /// FLIP) summed in particle order, then the transpose of their reflection.
    fn scatter_to_first_grid(&mut self, scatter: &Scatter<D>) {
        let cfg = &self.config;
        let flip = cfg.transfer.needs_old_grid_velocity();
        let g = &mut self.grid;
        Self::add_scatter(
            scatter,
            &mut g.adj_v_hat,
            flip.then_some(&mut g.adj_v_old[..]),
            &mut g.half,
            &mut g.half_old,
        );
        cfg.boundary
            .reflect_ghosts_adjoint(&cfg.grid, &mut g.adj_v_hat);
        if flip {
            cfg.boundary
                .reflect_ghosts_adjoint(&cfg.grid, &mut g.adj_v_old);
        }
    }

    /// Stage 2 in reverse: per live node, the local VJP of the node update (and the
    /// parameters' shares: gravity everywhere, contact where a contact constraint acted),
    /// then the transpose of the fold. `extra_mass` adds MUSL's `m̄_i` from the second
    /// projection before the fold.
    fn reverse_nodes(
        &mut self,
        time: f64,
        dt: f64,
        extra_mass: Option<&[f64]>,
        gradient: &mut [f64],
    ) {
        let cfg = &self.config;
        let grid = &cfg.grid;
        let dtd = Dual64::from_re(dt);
        let base_law = NodeLaw::new(grid, &cfg.boundary, &self.base.contact, time + dt);
        let seeded: Vec<_> = self
            .node_params
            .iter()
            .map(|(k, param, c)| {
                let law = NodeLaw::new(grid, &cfg.boundary, &c.contact, time + dt);
                let axis = match param {
                    Param::Gravity(a) => Some(*a),
                    _ => None,
                };
                (*k, axis, law, c.gravity)
            })
            .collect();
        let g = &mut self.grid;
        let (sums, live, states) = (&g.sums, &g.live, &g.states);
        let (adj_v_hat, adj_v_old) = (&g.adj_v_hat, &g.adj_v_old);
        let nparams = gradient.len();
        let gravity = self.base.gravity;
        let parts: Vec<Vec<f64>> = g
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
                    if let Some(extra) = extra_mass {
                        am[k] = extra[n];
                    }
                    let (yo, yh) = (adj_v_old[n], adj_v_hat[n]);
                    if yo.iter().chain(yh.iter()).all(|&y| y == 0.0) {
                        continue;
                    }
                    let node = grid.multi(n);
                    let touched = states[n].contact.active != 0;
                    if !touched && !on_a_face(grid, node) {
                        // Nothing acted on an interior node: vⁿ = P/m, v̂ = vⁿ + Δt (f/m + g),
                        // whose transpose is m̄ = −(P·(v̄ⁿ + v̂̄) + Δt f·v̂̄)/m², P̄ = (v̄ⁿ + v̂̄)/m,
                        // f̄ = Δt v̂̄/m, ḡ = Δt v̂̄.
                        let (m, p, f) = (sums[n].m, sums[n].p, sums[n].f);
                        am[k] -= (p.dot(&(yo + yh)) + dt * f.dot(&yh)) / (m * m);
                        (ap[k], af[k]) = ((yo + yh) / m, yh * (dt / m));
                        for (index, axis, ..) in &seeded {
                            if let Some(a) = axis {
                                grad[*index] += dt * yh[*a];
                            }
                        }
                        continue;
                    }
                    let mut y_bar = Packed::<f64>::default();
                    y_bar.vector(&yo);
                    y_bar.vector(&yh);
                    let mut input = Packed::<f64>::default();
                    input.push(sums[n].m);
                    input.vector(&sums[n].p);
                    input.vector(&sums[n].f);
                    let mut x_bar = [0.0; 1 + 2 * 3];
                    vjp(
                        input.as_slice(),
                        0..1 + 2 * D,
                        y_bar.as_slice(),
                        &mut x_bar,
                        |i, out| node_update(&base_law, &gravity, dtd, node, i, out),
                    );
                    let mut u = Unpack::new(&x_bar[..1 + 2 * D]);
                    am[k] += u.scalar();
                    (ap[k], af[k]) = (u.vector::<D>(), u.vector::<D>());
                    let constant = constants(input.as_slice());
                    for (index, axis, law, grav) in &seeded {
                        if axis.is_some() || touched {
                            let mut out = Packed::default();
                            node_update(law, grav, dtd, node, constant.as_slice(), &mut out);
                            grad[*index] += dot_eps(out.as_slice(), y_bar.as_slice());
                        }
                    }
                }
                grad
            })
            .collect();
        add_parts(gradient, parts);
        cfg.boundary.fold_ghosts_adjoint(
            grid,
            Some(&mut g.adj_m),
            &mut g.adj_p,
            Some(&mut g.adj_f),
        );
    }

    /// Stage 1 in reverse: per particle, the gather of the node adjoints through its P2G
    /// contributions, added to its share from the later stages; the result replaces the
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
        let nodes = NodeAdjoints {
            mass: Some(&g.adj_m[..]),
            momentum: &g.adj_p,
            force: (!cfg.transfer.is_mls()).then_some(&g.adj_f[..]),
        };
        // MLS-MPM: A = m C − Δt V σ D⁻¹ with D⁻¹ = (1/κ)/h² I, and no force term.
        let mls = cfg.transfer.is_mls().then(|| {
            dt * cfg.shape.apic_inverse_inertia().unwrap_or(0.0) / (cfg.grid.h * cfg.grid.h)
        });
        let affine = cfg.transfer.is_affine();
        let ParticleAdjoint {
            x,
            v,
            c,
            f,
            stress,
            history,
            mass,
            volume0,
        } = adjoint;
        (x, v, c, f, stress, history, mass, volume0)
            .into_par_iter()
            .zip(shares.par_iter())
            .enumerate()
            .with_min_len(CHUNK)
            .for_each(
                |(i, ((x, v, c, f, stress, history, mass, volume0), share))| {
                    let site = self.site(p, i);
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
                    // J = m S₀ + m v·S₁ + A:S₂ − (V σ):S₃ (MLS-MPM: the force is in A).
                    let (s, x_bar) = nodes.moments_and_position(&site, m, &vp, &a, &sv);
                    let sv_bar = match mls {
                        Some(k) => -s.s2 * k,
                        None => -s.s3,
                    };
                    *x = share.x + x_bar;
                    *v = share.v + s.s1 * m;
                    *c = if affine { s.s2 * m } else { Tensor::zeros() };
                    let vol_bar = sv_bar.component_mul(&sigma).sum();
                    let mut s_bar = share.stress;
                    for r in 0..D {
                        for col in 0..D {
                            s_bar[(r, col)] += sv_bar[(r, col)] * vol;
                        }
                    }
                    *stress = s_bar;
                    // V = V⁰ det F: ∂V/∂F = V⁰ det F F⁻ᵀ.
                    *f = share.f + cofactor(&fp) * (p.volume0[i] * vol_bar);
                    *history = share.history;
                    let affine_part = if affine {
                        cp.component_mul(&s.s2).sum()
                    } else {
                        0.0
                    };
                    *mass += share.mass + s.s0 + vp.dot(&s.s1) + affine_part;
                    *volume0 += j * vol_bar;
                },
            );
    }
}
