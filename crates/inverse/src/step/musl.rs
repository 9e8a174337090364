//! MUSL in reverse: the particle end with the velocity gradient of the re-projected grid
//! velocity, the gather of `L` from that field, the second projection, MUSL's second P2G of
//! momentum and the G2P motion, each by its adjoint, last to first.

use super::kernels::{self, End, Motion, musl_end_start};
use super::transfers::{GatherForm, NodeAdjoints, gather_adjoint};
use super::{CHUNK, ParticleShare, ReverseStep, add_parts, pack_end, pack_end_adjoint};
use crate::adjoint_state::ParticleAdjoint;
use crate::lanes::{MAX_LANES, Packed, Unpack, constants, dot_eps, vjp};
use loam_core::stencil::Layout;
use loam_core::step::{EndOfStep, G2p, NodeLaw, NodeSums, momentum_to_grid};
use loam_core::tensor::{Tensor, Vector};
use loam_core::transfer::{Gathered, g2p};
use loam_core::{Particles, ShapeFunction};
use num_dual::Dual64;
use rayon::prelude::*;

/// The motion of one particle in the forward step: its position, velocity and affine matrix
/// after G2P.
type Moved<const D: usize> = (Vector<f64, D>, Vector<f64, D>, Tensor<f64, D>);

impl<const D: usize> ReverseStep<D> {
    /// The stages of a MUSL step after the first grid update, in reverse; leaves `v̂̄` and `v̄ⁿ`
    /// on the grid and returns each particle's share of the start-of-step adjoint and, per
    /// node, the adjoint of the nodal mass from the second projection.
    pub(super) fn musl_particles(
        &mut self,
        p: &Particles<f64, D>,
        time: f64,
        dt: f64,
        adjoint: &ParticleAdjoint<D>,
        gradient: &mut [f64],
    ) -> (Vec<ParticleShare<D>>, Vec<f64>) {
        let mut shares = self.take_shares(p.len());
        let cfg = &self.config;
        let (grid, transfer, shape) = (&cfg.grid, cfg.transfer, cfg.shape);
        let n_nodes = grid.num_nodes();
        let stencil_len = shape.support_width().pow(D as u32);
        let layout = Layout::grid(grid);
        let flip = transfer.needs_old_grid_velocity();
        let affine = transfer.is_affine();
        let stage = G2p::new(grid, shape, transfer, dt);
        let (v_hat, v_old) = (&self.grid.v_hat, &self.grid.v_old);
        let old: &[Vector<f64, D>] = if flip { v_old } else { &[] };

        // Forward: the motion, the second P2G, its fold, the second projection, reflection.
        let moved: Vec<Moved<D>> = (0..p.len())
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|i| stage.motion(self.site(p, i).stencil(), v_hat, old, &p.x[i], &p.v[i]))
            .collect();
        let mut sums = vec![NodeSums::zero(); n_nodes];
        for (i, (_, v1, c1)) in moved.iter().enumerate() {
            let site = self.site(p, i);
            momentum_to_grid(
                site.stencil(),
                &layout,
                p.mass[i],
                v1,
                c1,
                affine,
                &mut sums,
            );
        }
        let mut p2: Vec<Vector<f64, D>> = sums.iter().map(|s| s.p).collect();
        cfg.boundary.fold_ghosts(grid, None, &mut p2, None);
        let law = NodeLaw::new(grid, &cfg.boundary, &cfg.contact, time + dt);
        let (live, states, mass) = (&self.grid.live, &self.grid.states, &self.grid.sums);
        let mut v2: Vec<Vector<f64, D>> = (0..n_nodes)
            .map(|n| {
                if live[n] {
                    let mut v = p2[n] / mass[n].m;
                    law.enforce(grid.multi(n), &mut v, states[n]);
                    v
                } else {
                    Vector::zeros()
                }
            })
            .collect();
        cfg.boundary.reflect_ghosts(grid, &mut v2);

        // Reverse of the particle end and of the gather of L from the second field.
        let end = EndOfStep::new(grid, &cfg.boundary, &self.base.contact, time + dt);
        let dtd = Dual64::from_re(dt);
        let form = self.gather_form();
        // L is Σ v ⊗ ∇w, or MLS-MPM's affine sum of the second field.
        let l_form = GatherForm {
            scale: if transfer.is_mls() { form.scale } else { None },
            affine_is_gradient: false,
        };
        let start = musl_end_start(D);
        let end_lanes: Vec<Vec<usize>> = cfg
            .materials
            .iter()
            .map(|m| {
                let mut l: Vec<usize> = (0..start).collect();
                l.extend(End::lanes::<D>(start, &m.model));
                l
            })
            .collect();
        let mut moved_bar = vec![(Vector::zeros(), Vector::zeros()); p.len()];
        let mut scatter = std::mem::take(&mut self.scatter);
        scatter.resize(p.len() * stencil_len, (0, Vector::zeros(), Vector::zeros()));
        let nparams = gradient.len();
        let parts: Vec<Vec<f64>> = shares
            .par_chunks_mut(CHUNK)
            .zip(moved_bar.par_chunks_mut(CHUNK))
            .zip(scatter.par_chunks_mut(CHUNK * stencil_len))
            .enumerate()
            .map(|(chunk, ((shares, moved_bar), scatter))| {
                let mut grad = vec![0.0; nparams];
                for (k, share) in shares.iter_mut().enumerate() {
                    let i = chunk * CHUNK + k;
                    let mat = p.material[i] as usize;
                    let site = self.site(p, i);
                    let l = stage.velocity_gradient(site.stencil(), &v2);
                    let (x1, v1, _) = moved[i];
                    let mut input = Packed::<f64>::default();
                    input.tensor(&l);
                    input.vector(&x1);
                    input.vector(&v1);
                    pack_end(p, i, &mut input);
                    let mut y_bar = Packed::<f64>::default();
                    y_bar.vector(&adjoint.x[i]);
                    y_bar.vector(&adjoint.v[i]);
                    pack_end_adjoint(adjoint, i, &mut y_bar);
                    let x_bar = self.particle_vjp(
                        mat,
                        &input,
                        &end_lanes[mat],
                        &y_bar,
                        &mut grad,
                        |m, i, out| kernels::musl_end(dtd, &end, m, i, out),
                    );
                    let mut u = Unpack::new(&x_bar[..start + End::len(D)]);
                    let l_bar = u.tensor::<D>();
                    moved_bar[k] = (u.vector::<D>(), u.vector::<D>());
                    share.read_end(&mut u);
                    let zero = Tensor::zeros();
                    let g_bar = Gathered {
                        v: Vector::zeros(),
                        dv: Vector::zeros(),
                        grad_v: if transfer.is_mls() { zero } else { l_bar },
                        affine: if transfer.is_mls() { l_bar } else { zero },
                    };
                    let out = &mut scatter[k * stencil_len..(k + 1) * stencil_len];
                    share.x = gather_adjoint(&site, l_form, &g_bar, &v2, &[], out);
                }
                grad
            })
            .collect();
        add_parts(gradient, parts);
        let mut adj_v2 = vec![Vector::zeros(); n_nodes];
        let mut half = vec![Vector::zeros(); n_nodes];
        Self::add_scatter(&scatter, &mut adj_v2, None, &mut half, &mut []);
        cfg.boundary.reflect_ghosts_adjoint(grid, &mut adj_v2);

        // Reverse of the second projection, per live node.
        let base_law = NodeLaw::new(grid, &cfg.boundary, &self.base.contact, time + dt);
        let seeded: Vec<_> = self
            .node_params
            .iter()
            .map(|(k, _, c)| (*k, NodeLaw::new(grid, &cfg.boundary, &c.contact, time + dt)))
            .collect();
        let mut adj_m2 = vec![0.0; n_nodes];
        let mut adj_p2 = vec![Vector::zeros(); n_nodes];
        let parts: Vec<Vec<f64>> = adj_m2
            .par_chunks_mut(CHUNK)
            .zip(adj_p2.par_chunks_mut(CHUNK))
            .enumerate()
            .map(|(chunk, (am, ap))| {
                let mut grad = vec![0.0; nparams];
                for k in 0..am.len() {
                    let n = chunk * CHUNK + k;
                    if !live[n] || adj_v2[n] == Vector::<f64, D>::zeros() {
                        continue;
                    }
                    let mut input = Packed::<f64>::default();
                    input.push(mass[n].m);
                    input.vector(&p2[n]);
                    let mut y_bar = Packed::<f64>::default();
                    y_bar.vector(&adj_v2[n]);
                    let (node, state) = (grid.multi(n), states[n]);
                    let mut x_bar = [0.0; 4];
                    vjp(
                        input.as_slice(),
                        0..1 + D,
                        y_bar.as_slice(),
                        &mut x_bar,
                        |i, out| kernels::node_enforce(&base_law, node, state, i, out),
                    );
                    am[k] = x_bar[0];
                    ap[k] = Vector::from_fn(|a, _| x_bar[1 + a]);
                    if state.contact.active != 0 {
                        let constant = constants(input.as_slice());
                        for (index, law) in &seeded {
                            let mut out = Packed::default();
                            kernels::node_enforce(law, node, state, constant.as_slice(), &mut out);
                            grad[*index] += dot_eps(out.as_slice(), y_bar.as_slice());
                        }
                    }
                }
                grad
            })
            .collect();
        add_parts(gradient, parts);
        cfg.boundary
            .fold_ghosts_adjoint(grid, None, &mut adj_p2, None);

        // Reverse of the second P2G and of the motion, per particle.
        let second = NodeAdjoints {
            mass: None,
            momentum: &adj_p2,
            force: None,
        };
        let motion_lanes = Motion::<D>::lanes(transfer, false);
        shares
            .par_chunks_mut(CHUNK)
            .zip(scatter.par_chunks_mut(CHUNK * stencil_len))
            .enumerate()
            .for_each(|(chunk, (shares, scatter))| {
                for (k, share) in shares.iter_mut().enumerate() {
                    let i = chunk * CHUNK + k;
                    let site = self.site(p, i);
                    let (_, v1, c1) = moved[i];
                    let m = p.mass[i];
                    let a = if affine { c1 * m } else { Tensor::zeros() };
                    let (s, x_bar) =
                        second.moments_and_position(&site, m, &v1, &a, &Tensor::zeros());
                    let (x1_bar, mut v1_bar) = moved_bar[i];
                    v1_bar += s.s1 * m;
                    let mut c1_bar = adjoint.c[i];
                    share.mass = v1.dot(&s.s1);
                    if affine {
                        c1_bar += s.s2 * m;
                        share.mass += c1.component_mul(&s.s2).sum();
                    }
                    share.x += x_bar;
                    // The motion: (x1, v1, C1) from the gathered sums and (x, v).
                    let g = g2p(
                        site.stencil(),
                        &layout,
                        grid,
                        shape,
                        transfer,
                        false,
                        v_hat,
                        old,
                    );
                    let mut input = Packed::<f64>::default();
                    input.vector(&g.v);
                    input.vector(&g.dv);
                    input.tensor(&g.grad_v);
                    input.tensor(&g.affine);
                    input.vector(&p.x[i]);
                    input.vector(&p.v[i]);
                    let mut y_bar = Packed::<f64>::default();
                    y_bar.vector(&x1_bar);
                    y_bar.vector(&v1_bar);
                    y_bar.tensor(&c1_bar);
                    let mut x_bar = [0.0; MAX_LANES];
                    vjp(
                        input.as_slice(),
                        motion_lanes.iter().copied(),
                        y_bar.as_slice(),
                        &mut x_bar,
                        |i, out| kernels::musl_motion::<_, D>(transfer, dtd, i, out),
                    );
                    let mut u = Unpack::new(&x_bar[..Motion::<D>::END]);
                    let g_bar = Gathered {
                        v: u.vector::<D>(),
                        dv: u.vector::<D>(),
                        grad_v: u.tensor::<D>(),
                        affine: u.tensor::<D>(),
                    };
                    share.x += u.vector::<D>();
                    share.v = u.vector::<D>();
                    let out = &mut scatter[k * stencil_len..(k + 1) * stencil_len];
                    share.x += gather_adjoint(&site, form, &g_bar, v_hat, old, out);
                }
            });
        self.scatter_to_first_grid(&scatter);
        self.scatter = scatter;
        (shares, adj_m2)
    }
}
