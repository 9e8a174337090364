//! USL in reverse: per particle, the local VJP of G2P and the particle end together
//! ([`kernels::usl_particle`]; in closed form for MLS-MPM with the fluid, [`fluid_mls`], whose
//! gathered sums are read from the state after the step) and the scatter of the gathered
//! sums' adjoints to the nodes.

use super::fluid_mls;
use super::kernels::{self, End, Motion};
use super::transfers::gather_adjoint;
use super::{CHUNK, ParticleShare, ReverseStep, add_parts, pack_end, pack_end_adjoint};
use crate::adjoint_state::ParticleAdjoint;
use crate::lanes::{Packed, Unpack};
use loam_core::constitutive::Model;
use loam_core::stencil::Layout;
use loam_core::step::EndOfStep;
use loam_core::tensor::{Tensor, Vector};
use loam_core::transfer::{Gathered, g2p};
use loam_core::{Particles, ShapeFunction};
use num_dual::Dual64;
use rayon::prelude::*;

impl<const D: usize> ReverseStep<D> {
    /// Stages 3 and 4 of a USL step in reverse, then the transpose of the reflection; leaves
    /// `v̂̄` and `v̄ⁿ` on the grid and returns each particle's share of the start-of-step
    /// adjoint.
    pub(super) fn usl_particles(
        &mut self,
        p: &Particles<f64, D>,
        after: &Particles<f64, D>,
        time: f64,
        dt: f64,
        adjoint: &ParticleAdjoint<D>,
        gradient: &mut [f64],
    ) -> Vec<ParticleShare<D>> {
        let mut shares = self.take_shares(p.len());
        let cfg = &self.config;
        let end = EndOfStep::new(&cfg.grid, &cfg.boundary, &self.base.contact, time + dt);
        let end_f64 = EndOfStep::new(&cfg.grid, &cfg.boundary, &cfg.contact, time + dt);
        let dtd = Dual64::from_re(dt);
        let (grid, transfer, shape) = (&cfg.grid, cfg.transfer, cfg.shape);
        let stencil_len = shape.support_width().pow(D as u32);
        let layout = Layout::grid(grid);
        let form = self.gather_form();
        let flip = transfer.needs_old_grid_velocity();
        let (v_hat, v_old) = (&self.grid.v_hat, &self.grid.v_old);
        let old: &[Vector<f64, D>] = if flip { v_old } else { &[] };
        let lanes: Vec<Vec<usize>> = cfg
            .materials
            .iter()
            .map(|m| {
                let mut l = Motion::<D>::lanes(transfer, !transfer.is_mls());
                l.extend(End::lanes::<D>(Motion::<D>::END, &m.model));
                l
            })
            .collect();
        // MLS-MPM with the fluid: the particle end sets `v = G.v`, `C = G.affine` and
        // `x = x + Δt G.v`, and the projection of a shallow wall crossing puts the coordinate
        // exactly on a face of the grid box (`EndOfStep::project`); a particle that ended
        // elsewhere carries its gathered sums in the state after the step, so they are read
        // from it instead of gathered again (a particle on a face is gathered again).
        let (lo, hi) = (grid.lo, grid.hi());
        let on_the_box = |x: &Vector<f64, D>| (0..D).any(|a| x[a] == lo[a] || x[a] == hi[a]);
        let mut scatter = std::mem::take(&mut self.scatter);
        scatter.resize(p.len() * stencil_len, (0, Vector::zeros(), Vector::zeros()));
        let nparams = gradient.len();
        let parts: Vec<Vec<f64>> = shares
            .par_chunks_mut(CHUNK)
            .zip(scatter.par_chunks_mut(CHUNK * stencil_len))
            .enumerate()
            .map(|(chunk, (shares, scatter))| {
                let mut grad = vec![0.0; nparams];
                for (k, share) in shares.iter_mut().enumerate() {
                    let i = chunk * CHUNK + k;
                    let mat = p.material[i] as usize;
                    let site = self.site(p, i);
                    let gather = || {
                        g2p(
                            site.stencil(),
                            &layout,
                            grid,
                            shape,
                            transfer,
                            !transfer.is_mls(),
                            v_hat,
                            old,
                        )
                    };
                    let model = &cfg.materials[mat].model;
                    let g_bar = if let (true, Model::Fluid(fluid)) = (transfer.is_mls(), model) {
                        let g = if on_the_box(&after.x[i]) {
                            gather()
                        } else {
                            Gathered {
                                v: after.v[i],
                                affine: after.c[i],
                                dv: Vector::zeros(),
                                grad_v: Tensor::zeros(),
                            }
                        };
                        let y = (
                            &adjoint.x[i],
                            &adjoint.v[i],
                            &adjoint.c[i],
                            &adjoint.f[i],
                            &adjoint.stress[i],
                        );
                        let with_params = self.particle_params.iter().any(|(_, m, _)| *m == mat);
                        let (x, f) = (&p.x[i], &p.f[i]);
                        let r = fluid_mls::reverse(
                            with_params,
                            fluid,
                            &end_f64,
                            dt,
                            &g,
                            x,
                            f,
                            y,
                            share,
                        );
                        for (index, m, seeded) in &self.particle_params {
                            if let (true, Model::Fluid(s)) = (*m == mat, &seeded.model) {
                                let [k_bar, gamma_bar, eta_bar] = r.params;
                                grad[*index] += k_bar * s.bulk_modulus.eps
                                    + gamma_bar * s.gamma.eps
                                    + eta_bar * s.viscosity.eps;
                            }
                        }
                        r.g_bar
                    } else {
                        let g = gather();
                        let mut input = Packed::<f64>::default();
                        input.vector(&g.v);
                        input.vector(&g.dv);
                        input.tensor(&g.grad_v);
                        input.tensor(&g.affine);
                        input.vector(&p.x[i]);
                        input.vector(&p.v[i]);
                        pack_end(p, i, &mut input);
                        let mut y_bar = Packed::<f64>::default();
                        y_bar.vector(&adjoint.x[i]);
                        y_bar.vector(&adjoint.v[i]);
                        y_bar.tensor(&adjoint.c[i]);
                        pack_end_adjoint(adjoint, i, &mut y_bar);
                        let x_bar = self.particle_vjp(
                            mat,
                            &input,
                            &lanes[mat],
                            &y_bar,
                            &mut grad,
                            |m, i, out| kernels::usl_particle(transfer, dtd, &end, m, i, out),
                        );
                        let mut u = Unpack::new(&x_bar[..Motion::<D>::END + End::len(D)]);
                        let g_bar = Gathered {
                            v: u.vector::<D>(),
                            dv: u.vector::<D>(),
                            grad_v: u.tensor::<D>(),
                            affine: u.tensor::<D>(),
                        };
                        share.x = u.vector::<D>();
                        share.v = u.vector::<D>();
                        share.read_end(&mut u);
                        share.mass = 0.0;
                        g_bar
                    };
                    let out = &mut scatter[k * stencil_len..(k + 1) * stencil_len];
                    share.x += gather_adjoint(&site, form, &g_bar, v_hat, old, out);
                }
                grad
            })
            .collect();
        add_parts(gradient, parts);
        self.scatter_to_first_grid(&scatter);
        self.scatter = scatter;
        shares
    }
}
