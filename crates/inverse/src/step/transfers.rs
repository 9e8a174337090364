//! The adjoints of the transfers, written for the stencil: P2G's is a gather of the node
//! adjoints, G2P's a scatter to the nodes. The dependence on the particle position goes
//! through the weights, their gradients and the offsets `x_i − x_p`: in closed form where the
//! sums hold no weight gradient (MLS-MPM, MUSL's motion and second P2G), which needs only the
//! weights' first derivatives `∇w`; otherwise (the force `−V σ ∇w` and the velocity gradient
//! `Σ v ∇wᵀ`, whose derivatives need the second derivatives of the weights) by `D`
//! evaluations of the same sums with a dual position. The G2P scatter's closed form runs row
//! by row over the stencil ([`Site::rows`]): a node forms only its axis-0 terms, and the row's
//! factors multiply the row's sums once.

use loam_core::shape::MAX_SUPPORT;
use loam_core::stencil::{Layout, Stencil, StencilRow};
use loam_core::tensor::{Tensor, Vector};
use loam_core::transfer::Gathered;
use loam_core::{Grid, Shape};
use num_dual::Dual64;

/// One particle's place on the grid: grid, shape, position, half-width, and its stencil
/// (formed once and shared by the reverse passes of the step).
#[derive(Clone, Copy)]
pub(super) struct Site<'a, const D: usize> {
    grid: &'a Grid<D>,
    shape: Shape,
    x: Vector<f64, D>,
    half_width: Vector<f64, D>,
    stencil: &'a Stencil<f64, D>,
}

impl<'a, const D: usize> Site<'a, D> {
    /// The site of a particle at `x` with half-width `half_width` and its stencil there.
    pub fn new(
        grid: &'a Grid<D>,
        shape: Shape,
        x: Vector<f64, D>,
        half_width: Vector<f64, D>,
        stencil: &'a Stencil<f64, D>,
    ) -> Self {
        Self {
            grid,
            shape,
            x,
            half_width,
            stencil,
        }
    }

    /// The stencil at the particle.
    pub fn stencil(&self) -> &Stencil<f64, D> {
        self.stencil
    }

    /// Calls `f(node, w, ∇w, x_i − x_p)` for every node of the stencil (`node` the flat grid
    /// index).
    #[inline]
    pub fn each(&self, f: impl FnMut(usize, f64, Vector<f64, D>, Vector<f64, D>)) {
        let mut f = f;
        self.stencil
            .for_each_in(&Layout::grid(self.grid), |n, _, w, g, o| f(n, w, g, o));
    }

    /// Calls `f(row, [N, N', o])` for every row of the stencil ([`Stencil::for_each_row`]),
    /// whose width must be `B`: the row's factors of the axes above 0 (its first node's flat
    /// grid index `row.index`) and the axis-0 factors of its `B` nodes.
    #[inline]
    pub fn rows<const B: usize>(&self, f: impl FnMut(&StencilRow<f64, D>, [&[f64; B]; 3])) {
        let mut f = f;
        debug_assert_eq!(self.stencil.width(), B);
        let [w0, dw0, o0] = self.stencil.axis0();
        let first = |a: &[f64; MAX_SUPPORT]| -> [f64; B] { std::array::from_fn(|i| a[i]) };
        let axis0 = [first(w0), first(dw0), first(o0)];
        self.stencil.for_each_row(&Layout::grid(self.grid), |row| {
            f(&row, [&axis0[0], &axis0[1], &axis0[2]])
        });
    }

    /// `∂J/∂x_p` of `J = Σ_i term(node i)` with everything but the position held, by `D`
    /// evaluations of the stencil with a dual position.
    pub fn position_derivative(
        &self,
        mut term: impl FnMut(usize, Dual64, &Vector<Dual64, D>, &Vector<Dual64, D>) -> Dual64,
    ) -> Vector<f64, D> {
        let hw = self.half_width.map(Dual64::from_re);
        Vector::from_fn(|axis, _| {
            let mut x = self.x.map(Dual64::from_re);
            x[axis].eps = 1.0;
            let st = Stencil::new(self.shape, self.grid, &x, &hw);
            let mut j = Dual64::from_re(0.0);
            st.for_each_in(&Layout::grid(self.grid), |n, _, w, g, o| {
                j += term(n, w, &g, &o)
            });
            j.eps
        })
    }
}

/// How a transfer's gathered sums are formed, for their adjoint.
#[derive(Clone, Copy, Debug)]
pub(super) struct GatherForm {
    /// `k/h²` of the affine sum `C = (k/h²) Σ w v (x_i − x_p)ᵀ` (APIC and MLS-MPM with
    /// B-splines); `None` where the affine matrix is the velocity gradient or absent.
    pub scale: Option<f64>,
    /// Whether the affine matrix is the velocity gradient (TPIC, APIC with the hat and GIMP).
    pub affine_is_gradient: bool,
}

/// The adjoint of a G2P gather `G = Σ_i (w v_i, w (v_i − vⁿ_i), v_i ⊗ ∇w, k/h² w v_i ⊗ o_i)` at
/// one particle: writes `(node, v̄ share, v̄ⁿ share)` per stencil node into `out`,
/// `v̄_i = w Ḡ.v + w Ḡ.dv + Ḡ.grad ∇w + (k/h²) w Ḡ.aff o_i`, `v̄ⁿ_i = −w Ḡ.dv`, and returns
/// `x̄_p = ∂(Ḡ · G)/∂x_p` with the nodal velocities held. `old` is empty unless FLIP.
pub(super) fn gather_adjoint<const D: usize>(
    site: &Site<'_, D>,
    form: GatherForm,
    g_bar: &Gathered<f64, D>,
    velocity: &[Vector<f64, D>],
    old: &[Vector<f64, D>],
    out: &mut [(usize, Vector<f64, D>, Vector<f64, D>)],
) -> Vector<f64, D> {
    let grad_bar = if form.affine_is_gradient {
        g_bar.grad_v + g_bar.affine
    } else {
        g_bar.grad_v
    };
    let aff_bar = form.scale.map(|k| g_bar.affine * k);
    let gvd = g_bar.v + g_bar.dv;
    let flip = !old.is_empty();
    if grad_bar == Tensor::<f64, D>::zeros() {
        return closed_gather_adjoint(site, g_bar, gvd, aff_bar, velocity, old, out);
    }
    let mut k = 0;
    site.each(|n, w, gradient, offset| {
        // t = Ḡ.v + Ḡ.dv + Ā o_i: the node's share is w t plus the ∇w term.
        let t = match &aff_bar {
            Some(aff) => gvd + aff * offset,
            None => gvd,
        };
        let a = t * w + grad_bar * gradient;
        out[k] = (n, a, if flip { -g_bar.dv * w } else { Vector::zeros() });
        k += 1;
    });
    let (gv, gdv) = (g_bar.v.map(Dual64::from_re), g_bar.dv.map(Dual64::from_re));
    let grad_d = grad_bar.map(Dual64::from_re);
    let aff_d = aff_bar.map(|a| a.map(Dual64::from_re));
    site.position_derivative(|n, w, gradient, offset| {
        let vi = velocity[n].map(Dual64::from_re);
        let mut s = gv.dot(&vi) * w + vi.dot(&(grad_d * gradient));
        if !old.is_empty() {
            s += gdv.dot(&(vi - old[n].map(Dual64::from_re))) * w;
        }
        if let Some(aff) = &aff_d {
            s += vi.dot(&(aff * offset)) * w;
        }
        s
    })
}

/// [`gather_adjoint`] without a `∇w` term, row by row ([`Site::rows`]). The position
/// derivative is in closed form: `J = Σ_i w_i a_i` with `a_i = v_i·t_i − vⁿ_i·Ḡ.dv`,
/// `t_i = Ḡ.v + Ḡ.dv + Ā o_i`, so `∂J/∂x_p = Σ_i ∇w_i a_i − Āᵀ Σ_i w_i v_i`
/// (`∂o_i/∂x_p = −I`): the weights' first derivatives only. Along a row `t_i = t_row + Ā e₀ o_i`
/// with `t_row = Ḡ.v + Ḡ.dv + Σ_{a≥1} Ā e_a o_a` (the row's offsets), and `w_i`, `∇w_i` are the
/// row's factors times the node's axis-0 factors, so a node forms only its axis-0 terms. The
/// support width and whether the transfer is FLIP are constants of the loop
/// ([`closed_rows`]).
fn closed_gather_adjoint<const D: usize>(
    site: &Site<'_, D>,
    g_bar: &Gathered<f64, D>,
    gvd: Vector<f64, D>,
    aff_bar: Option<Tensor<f64, D>>,
    velocity: &[Vector<f64, D>],
    old: &[Vector<f64, D>],
    out: &mut [(usize, Vector<f64, D>, Vector<f64, D>)],
) -> Vector<f64, D> {
    let a = (site, g_bar, gvd, aff_bar, velocity, old, out);
    match (site.stencil().width(), old.is_empty()) {
        (2, true) => closed_rows::<D, 2, false>(a),
        (2, false) => closed_rows::<D, 2, true>(a),
        (3, true) => closed_rows::<D, 3, false>(a),
        (3, false) => closed_rows::<D, 3, true>(a),
        (4, true) => closed_rows::<D, 4, false>(a),
        (4, false) => closed_rows::<D, 4, true>(a),
        (b, _) => unreachable!("support width {b}"),
    }
}

/// The arguments of [`closed_gather_adjoint`].
type ClosedArgs<'a, 's, const D: usize> = (
    &'a Site<'s, D>,
    &'a Gathered<f64, D>,
    Vector<f64, D>,
    Option<Tensor<f64, D>>,
    &'a [Vector<f64, D>],
    &'a [Vector<f64, D>],
    &'a mut [(usize, Vector<f64, D>, Vector<f64, D>)],
);

/// [`closed_gather_adjoint`] for support width `B` and FLIP or not.
fn closed_rows<const D: usize, const B: usize, const FLIP: bool>(
    (site, g_bar, gvd, aff_bar, velocity, old, out): ClosedArgs<'_, '_, D>,
) -> Vector<f64, D> {
    let (mut x_bar, mut wv) = (Vector::<f64, D>::zeros(), Vector::<f64, D>::zeros());
    let mut k = 0;
    site.rows::<B>(|row, [w0, dw0, o0]| {
        let (mut t_row, mut a0) = (gvd, Vector::<f64, D>::zeros());
        if let Some(aff) = &aff_bar {
            for c in 1..D {
                t_row += aff.column(c) * row.offset[c];
            }
            a0 = aff.column(0).into_owned();
        }
        let v_row: &[Vector<f64, D>; B] = velocity[row.index..row.index + B].try_into().unwrap();
        let out_row: &mut [_; B] = (&mut out[k..k + B]).try_into().unwrap();
        k += B;
        // Σ N' a, Σ N a and Σ N v over the row.
        let (mut sd, mut sw, mut sv) = (0.0, 0.0, Vector::<f64, D>::zeros());
        for i in 0..B {
            let t = t_row + a0 * o0[i];
            let w = w0[i] * row.weight;
            let shares = if FLIP { -g_bar.dv * w } else { Vector::zeros() };
            out_row[i] = (row.index + i, t * w, shares);
            let vi = v_row[i];
            let mut a = vi.dot(&t);
            if FLIP {
                a -= old[row.index + i].dot(&g_bar.dv);
            }
            sd += dw0[i] * a;
            sw += w0[i] * a;
            sv += vi * w0[i];
        }
        x_bar[0] += sd * row.weight;
        for c in 1..D {
            x_bar[c] += sw * row.gradient[c];
        }
        wv += sv * row.weight;
    });
    if let Some(aff) = &aff_bar {
        x_bar -= aff.transpose() * wv;
    }
    x_bar
}

/// The node adjoints a particle's P2G contributions meet, summed over its stencil:
/// `S₀ = Σ w m̄_i`, `S₁ = Σ w P̄_i`, `S₂ = Σ w P̄_i o_iᵀ`, `S₃ = Σ f̄_i ∇wᵀ` (`o_i = x_i − x_p`).
#[derive(Clone, Copy)]
pub(super) struct Moments<const D: usize> {
    pub s0: f64,
    pub s1: Vector<f64, D>,
    pub s2: Tensor<f64, D>,
    pub s3: Tensor<f64, D>,
}

impl<const D: usize> Moments<D> {
    /// All four sums zero.
    fn zero() -> Self {
        Self {
            s0: 0.0,
            s1: Vector::zeros(),
            s2: Tensor::zeros(),
            s3: Tensor::zeros(),
        }
    }
}

/// The adjoints a P2G of mass, momentum and force reads (mass and force absent for MUSL's
/// second, momentum-only transfer).
#[derive(Clone, Copy)]
pub(super) struct NodeAdjoints<'a, const D: usize> {
    pub mass: Option<&'a [f64]>,
    pub momentum: &'a [Vector<f64, D>],
    pub force: Option<&'a [Vector<f64, D>]>,
}

impl<const D: usize> NodeAdjoints<'_, D> {
    /// [`Moments`] over the stencil of `site`, and `x̄_p` through P2G's weights, gradients
    /// and offsets: `∂/∂x_p Σ_i [m̄_i m w + P̄_i · w (m v + A o_i) − f̄_i · (V σ) ∇w]` with the
    /// particle's other fields held (`A` its affine momentum, `sv = V σ`). Without a force
    /// term (MLS-MPM's P2G, MUSL's second P2G) the derivative is in closed form in the same
    /// loop, `Σ_i ∇w_i b_i − Aᵀ S₁` with `b_i = m m̄_i + P̄_i·(m v + A o_i)`; with one it takes
    /// `D` dual evaluations (the force's derivative needs the weights' second derivatives).
    pub fn moments_and_position(
        &self,
        site: &Site<'_, D>,
        m: f64,
        v: &Vector<f64, D>,
        a: &Tensor<f64, D>,
        sv: &Tensor<f64, D>,
    ) -> (Moments<D>, Vector<f64, D>) {
        let mut s = Moments::zero();
        if self.force.is_none() {
            return match site.stencil().width() {
                2 => self.closed_moments::<2>(site, m, v, a),
                3 => self.closed_moments::<3>(site, m, v, a),
                4 => self.closed_moments::<4>(site, m, v, a),
                b => unreachable!("support width {b}"),
            };
        }
        let mv = v * m;
        site.each(|n, w, gradient, offset| {
            let pw = self.momentum[n] * w;
            s.s1 += pw;
            s.s2 += pw * offset.transpose();
            if let Some(mass) = self.mass {
                s.s0 += w * mass[n];
            }
            if let Some(force) = self.force {
                s.s3 += force[n] * gradient.transpose();
            }
        });
        let mv = mv.map(Dual64::from_re);
        let a = a.map(Dual64::from_re);
        let sv = sv.map(Dual64::from_re);
        let x_bar = site.position_derivative(|n, w, gradient, offset| {
            let pb = self.momentum[n].map(Dual64::from_re);
            let mut j = pb.dot(&(mv + a * offset)) * w;
            if let Some(mass) = self.mass {
                j += w * (m * mass[n]);
            }
            if let Some(force) = self.force {
                j -= force[n].map(Dual64::from_re).dot(&(sv * gradient));
            }
            j
        });
        (s, x_bar)
    }

    /// [`NodeAdjoints::moments_and_position`] without a force term, for support width `B`
    /// (row by row, [`Site::rows`], a node forming the same terms as [`Site::each`] gives):
    /// the moments and `x̄_p = Σ_i ∇w_i b_i − Aᵀ S₁`, `b_i = m m̄_i + P̄_i·(m v + A o_i)`.
    fn closed_moments<const B: usize>(
        &self,
        site: &Site<'_, D>,
        m: f64,
        v: &Vector<f64, D>,
        a: &Tensor<f64, D>,
    ) -> (Moments<D>, Vector<f64, D>) {
        let mut s = Moments::zero();
        let mv = v * m;
        let mut x_bar = Vector::zeros();
        site.rows::<B>(|row, [w0, dw0, o0]| {
            let nodes = row.index..row.index + B;
            let p_row: &[Vector<f64, D>; B] = self.momentum[nodes.clone()].try_into().unwrap();
            let m_row: Option<&[f64; B]> = self.mass.map(|mass| mass[nodes].try_into().unwrap());
            for i in 0..B {
                let w = w0[i] * row.weight;
                let mut gradient = row.gradient * w0[i];
                gradient[0] = dw0[i] * row.weight;
                let mut offset = row.offset;
                offset[0] = o0[i];
                let pb = p_row[i];
                let pw = pb * w;
                s.s1 += pw;
                s.s2 += pw * offset.transpose();
                let mut b = pb.dot(&(mv + a * offset));
                if let Some(mass) = m_row {
                    s.s0 += w * mass[i];
                    b += m * mass[i];
                }
                x_bar += gradient * b;
            }
        });
        (s, x_bar - a.transpose() * s.s1)
    }
}
