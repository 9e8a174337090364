//! Stage tests, written once and run over `f32`, `f64` and `Dual64` (the `f32` path is the
//! CPU twin of the GPU kernels; the dual path carries derivatives with respect to a seeded
//! parameter `s`, checked against the analytical derivative).

use super::*;
use crate::boundary::{Boundary, Wall, WallKind};
use crate::constitutive::{Material, MaterialState, ModelKind, Region};
use crate::contact::{Contact, FrictionSegment};
use crate::grid::Grid;
use crate::particles::Particles;
use crate::scalar::Scalar;
use crate::shape::Shape;
use crate::stencil::{Layout, Stencil};
use crate::tensor::{Tensor, Vector};
use crate::transfer::Transfer;
use nalgebra::Matrix3;
use num_dual::Dual64;

/// A scalar type under test: how to seed the parameter `s` and read `d/ds` back.
trait Probe: Scalar {
    /// Round-off scale of the type: sums of up to 64 stencil terms of unit size stay within
    /// a few hundred ulps of the exact value (`f32`: 6e-8 per operation).
    const TOL: f64;
    /// `s = re` with `ds/ds = 1` (a constant for the real types).
    fn seeded(re: f64) -> Self;
    /// `d/ds` (0 for the real types).
    fn d(&self) -> f64;
}

impl Probe for f32 {
    const TOL: f64 = 2e-5;
    fn seeded(re: f64) -> Self {
        re as f32
    }
    fn d(&self) -> f64 {
        0.0
    }
}

impl Probe for f64 {
    const TOL: f64 = 1e-12;
    fn seeded(re: f64) -> Self {
        re
    }
    fn d(&self) -> f64 {
        0.0
    }
}

impl Probe for Dual64 {
    const TOL: f64 = 1e-12;
    fn seeded(re: f64) -> Self {
        Dual64::new(re, 1.0)
    }
    fn d(&self) -> f64 {
        self.eps
    }
}

/// Whether `T` carries a derivative (then `d/ds` is checked).
fn dual<T: Probe>() -> f64 {
    T::seeded(0.0).d()
}

fn close(a: f64, b: f64, tol: f64, what: &str) {
    assert!(
        (a - b).abs() <= tol * (1.0 + b.abs()),
        "{what}: {a} against {b} (tolerance {tol})"
    );
}

fn cst<T: Scalar, const D: usize>(x: [f64; D]) -> Vector<T, D> {
    Vector::from_fn(|a, _| T::cst(x[a]))
}

/// A free grid of `8^D` cells of 0.1 m with the padding every shape needs.
fn grid<const D: usize>() -> Grid<D> {
    Grid::new([0.0; D], [8; D], 0.1, 2)
}

/// One particle at an off-node position, with velocity, affine matrix and stress, its stress
/// `s σ₀` scaled by the seeded `s = 1`.
fn one_particle<T: Probe, const D: usize>() -> (Particles<T, D>, Matrix3<f64>) {
    let mut p = Particles::default();
    let x: [f64; D] = std::array::from_fn(|a| 0.4137 + 0.0219 * a as f64);
    let v: [f64; D] = std::array::from_fn(|a| 1.5 - 0.7 * a as f64);
    p.push(cst(x), cst(v), T::cst(1200.0), cst([0.025; D]), 0);
    p.c[0] = Tensor::from_fn(|r, c| T::cst(0.3 * r as f64 - 0.2 * c as f64 + 0.1));
    p.f[0] = Tensor::from_fn(|r, c| T::cst(if r == c { 1.02 } else { 0.01 }));
    let sigma0 = Matrix3::new(-2.0e3, 400.0, 0.0, 400.0, -1.0e3, 0.0, 0.0, 0.0, -1.5e3);
    p.stress[0] = sigma0.map(T::cst) * T::seeded(1.0);
    (p, sigma0)
}

/// Stage 1: P2G distributes exactly the particle's mass and momentum (partition of unity,
/// `Σ w (x_i − x_p) = 0`), its internal forces sum to zero, and their first moment is the
/// stress, `Σ_i (x_i − x_p) ⊗ f_i = −V σ` (`Σ_i (x_i − x_p) ⊗ ∇w_ip = I` for every shape
/// that reproduces linear fields) — with its derivative in `s`.
fn p2g_conserves<T: Probe, const D: usize>() {
    let g = grid::<D>();
    let layout = Layout::grid(&g);
    let (p, sigma0) = one_particle::<T, D>();
    let volume = p.volume0[0].re() * crate::tensor::det(&p.f[0]).re();
    for shape in [
        Shape::Linear,
        Shape::Ugimp,
        Shape::QuadraticBspline,
        Shape::CubicBspline,
    ] {
        for transfer in [Transfer::Pic, Transfer::Apic] {
            let stage = P2g::<T, D>::new(&g, shape, transfer, 1e-4);
            let mut st = Stencil::new(shape, &g, &p.x[0], &p.half_width0[0]);
            let mut nodes = vec![NodeSums::<T, D>::zero(); g.num_nodes()];
            stage.particle(&p, 0, &mut st, &layout, &mut nodes);
            let (mut m, mut mom, mut f) = (0.0, [0.0; D], [0.0; D]);
            let mut moment = [[0.0; D]; D];
            let mut d_moment = [[0.0; D]; D];
            st.for_each(|n| {
                let e = &nodes[layout.index(n.index)];
                let xi = g.node_position::<f64>(n.index);
                m += e.m.re();
                for a in 0..D {
                    mom[a] += e.p[a].re();
                    f[a] += e.f[a].re();
                    for b in 0..D {
                        moment[a][b] += e.f[a].re() * (xi[b] - p.x[0][b].re());
                        d_moment[a][b] += e.f[a].d() * (xi[b] - p.x[0][b].re());
                    }
                }
            });
            let what = format!("{shape:?} {transfer:?} D = {D}");
            close(m, p.mass[0].re(), T::TOL, &format!("mass, {what}"));
            let scale = volume * 2.0e3;
            for a in 0..D {
                let mv = (p.mass[0] * p.v[0][a]).re();
                close(mom[a], mv, T::TOL, &format!("momentum, {what}"));
                close(f[a] / scale, 0.0, T::TOL, &format!("force sum, {what}"));
                for b in 0..D {
                    let want = -volume * sigma0[(a, b)];
                    close(moment[a][b] / scale, want / scale, T::TOL, &what);
                    let d_want = want * dual::<T>();
                    close(d_moment[a][b] / scale, d_want / scale, T::TOL, &what);
                }
            }
        }
    }
}

/// Stage 2: the momentum update and the Coulomb law on a friction floor: slip (with its
/// derivative in a seeded `μ`), stick, and a separating node left alone.
fn node_update_on_a_friction_floor<T: Probe>() {
    let g = grid::<2>();
    let mut boundary = Boundary::all(Wall::new(WallKind::Free));
    boundary.walls[1][0] = Wall {
        kind: WallKind::Slip,
        separable: true,
    };
    let mut contact = Contact::<T, 2>::new(Shape::QuadraticBspline);
    contact
        .segments
        .push(FrictionSegment::whole_face(1, 0, T::seeded(0.25)));
    let law = NodeLaw::new(&g, &boundary, &contact, 0.0);
    let floor = [5, g.pad];
    // v_old = p/m = (3, −2); v = v_old + Δt (f/m + g) = (3, −2 + 0.1 (−1 − 10)) = (3, −3.1).
    let (m, p, f) = (T::cst(2.0), cst([6.0, -4.0]), cst([0.0, -2.0]));
    let (v_old, mut v) = momentum_update(m, &p, &f, &cst([0.0, -10.0]), T::cst(0.1));
    close(v_old[0].re(), 3.0, T::TOL, "v_old");
    close(v[1].re(), -3.1, T::TOL, "trial v");
    // Slip: |v_t| = 3 > μ Δv_n = 0.775, so v_t = 3 − 0.775 and dv_t/dμ = −Δv_n = −3.1.
    let state = law.apply(floor, &mut v);
    assert_eq!(state.contact.active, 1 << 2);
    assert_eq!(state.contact.slip, 1 << 2);
    close(v[0].re(), 2.225, T::TOL, "slip speed");
    close(v[0].d(), -3.1 * dual::<T>(), T::TOL, "d v_t / d μ");
    close(v[1].re(), 0.0, T::TOL, "normal speed");
    // Stick: |v_t| = 0.5 ≤ 0.775.
    let mut v = cst([0.5, -3.1]);
    let state = law.apply(floor, &mut v);
    assert_eq!((state.contact.active, state.contact.slip), (1 << 2, 0));
    assert_eq!(v, Vector::<T, 2>::zeros());
    // Separating, and a node off the face: untouched.
    for (node, v0) in [(floor, [1.0, 1.0]), ([5, 5], [1.0, -1.0])] {
        let mut v = cst(v0);
        let state = law.apply(node, &mut v);
        assert!(state.is_free());
        assert_eq!(v, cst(v0));
    }
}

/// Stage 3: G2P of an affine grid velocity `v_i = a + B x_i` (with `a_x = s`) gives, for every
/// transfer, `v_p = a + B x_p`, `L = B` and the position `x + Δt v_p`; the affine transfers
/// carry `C = B`; FLIP adds the change of the field to the old particle velocity.
fn g2p_reproduces_affine_fields<T: Probe, const D: usize>() {
    let g = grid::<D>();
    let b: Tensor<f64, D> = Tensor::from_fn(|r, c| 0.5 + r as f64 - 0.75 * c as f64);
    let a: [f64; D] = std::array::from_fn(|k| 0.2 * k as f64 - 0.1);
    let field = |b: &Tensor<f64, D>, shift: f64| -> Vec<Vector<T, D>> {
        (0..g.num_nodes())
            .map(|i| {
                let x = g.node_position::<f64>(g.multi(i));
                let mut v = cst::<T, D>((b * x).into());
                for k in 0..D {
                    v[k] += T::cst(a[k] + shift);
                }
                v[0] += T::seeded(0.0);
                v
            })
            .collect()
    };
    let (vel, old) = (field(&b, 0.0), field(&(b * 0.5), 0.3));
    let xp: [f64; D] = std::array::from_fn(|k| 0.3877 + 0.031 * k as f64);
    let exact: Vector<f64, D> = b * Vector::from(xp) + Vector::from(a);
    let dt = 1e-3;
    for shape in [Shape::QuadraticBspline, Shape::CubicBspline] {
        let st = Stencil::new(shape, &g, &cst::<T, D>(xp), &cst([0.025; D]));
        for transfer in [
            Transfer::Pic,
            Transfer::Flip { alpha: 1.0 },
            Transfer::Apic,
            Transfer::Tpic,
            Transfer::Mls,
        ] {
            let stage = G2p::<T, D>::new(&g, shape, transfer, dt);
            let v_old = cst::<T, D>([0.7; D]);
            let (mut x, mut v, mut c) = (cst::<T, D>(xp), v_old, Tensor::zeros());
            let l = stage.particle(&st, &vel, &old, &mut x, &mut v, &mut c);
            let what = format!("{shape:?} {transfer:?} D = {D}");
            let want_v: Vector<f64, D> = match transfer {
                // v_p + Σ w (v_i − v_iⁿ) = 0.7 + (B − B/2) x_p − 0.3.
                Transfer::Flip { .. } => (b * 0.5) * Vector::from(xp) + Vector::repeat(0.4),
                _ => exact,
            };
            for r in 0..D {
                close(v[r].re(), want_v[r], T::TOL, &format!("v, {what}"));
                let gathered = exact[r];
                close(
                    x[r].re(),
                    xp[r] + dt * gathered,
                    T::TOL,
                    &format!("x, {what}"),
                );
                for k in 0..D {
                    close(l[(r, k)].re(), b[(r, k)], T::TOL, &format!("L, {what}"));
                    let want_c = if transfer.is_affine() { b[(r, k)] } else { 0.0 };
                    close(c[(r, k)].re(), want_c, T::TOL, &format!("C, {what}"));
                    close(l[(r, k)].d(), 0.0, T::TOL, &format!("dL/ds, {what}"));
                }
            }
            let d_v = if matches!(transfer, Transfer::Flip { .. }) {
                0.0
            } else {
                dual::<T>()
            };
            close(v[0].d(), d_v, T::TOL, &format!("dv/ds, {what}"));
        }
    }
}

/// Stage 4: `F ← (I + Δt L) F` exactly, the stress of the new `F` (Neo-Hookean, with
/// `dF/ds = Δt L₀ F` for `L = s L₀`), the return region of J2 in shear and of
/// Drucker–Prager in tension, and the projection of a shallow wall crossing.
fn particle_end_updates_and_projects<T: Probe>() {
    let dt = T::cst(1e-3);
    let l0 = Tensor::<f64, 2>::new(0.5, 2.0, -1.0, 0.25);
    let l = l0.map(T::cst) * T::seeded(1.0);
    let f0 = Tensor::<f64, 2>::new(1.01, 0.02, 0.0, 0.99);
    let rubber = Material::elastic(
        ModelKind::NeoHookean,
        T::cst(1e6),
        T::cst(0.3),
        T::cst(1000.0),
    );
    let (mut f, mut stress, mut state) = (f0.map(T::cst), Matrix3::zeros(), Default::default());
    let region = update_stress(&rubber, &l, dt, &mut f, &mut stress, &mut state);
    assert_eq!(region, Region::Elastic);
    let want = (Tensor::identity() + l0 * 1e-3) * f0;
    let d_want = l0 * 1e-3 * f0;
    for r in 0..2 {
        for c in 0..2 {
            close(f[(r, c)].re(), want[(r, c)], T::TOL, "F");
            close(f[(r, c)].d(), d_want[(r, c)] * dual::<T>(), T::TOL, "dF/ds");
        }
    }
    let f3 = crate::tensor::to3(&f, T::one());
    let kin_stress = match &rubber.model {
        crate::constitutive::Model::NeoHookean(m) => {
            crate::constitutive::Hyperelastic::cauchy_stress(m, &f3)
        }
        _ => unreachable!(),
    };
    for (s, k) in stress.iter().zip(kin_stress.iter()) {
        close(s.re() / 1e4, k.re() / 1e4, T::TOL, "σ(F)");
    }
    // J2 in simple shear past yield: the radial return.
    let shear = Tensor::<T, 2>::new(T::zero(), T::cst(10.0), T::zero(), T::zero());
    let clay = Material::j2(
        T::cst(1e7),
        T::cst(0.3),
        T::cst(1e4),
        T::zero(),
        T::cst(1800.0),
    );
    let (mut f, mut stress) = (Tensor::identity(), Matrix3::zeros());
    let mut state = MaterialState::default();
    let region = update_stress(&clay, &shear, dt, &mut f, &mut stress, &mut state);
    assert_eq!(region, Region::Shear);
    assert!(state.plastic_strain.re() > 0.0);
    // Drucker–Prager pulled apart past its tension cutoff (zero cohesion: the apex, p ≤ 0).
    let sand = Material::drucker_prager(
        T::cst(1e7),
        T::cst(0.3),
        T::cst(0.5),
        T::zero(),
        T::zero(),
        None,
        T::cst(1800.0),
    );
    let stretch = Tensor::<T, 2>::identity() * T::cst(10.0);
    let (mut f, mut stress) = (Tensor::identity(), Matrix3::zeros());
    let mut state = MaterialState::default();
    let region = update_stress(&sand, &stretch, dt, &mut f, &mut stress, &mut state);
    assert!(
        matches!(region, Region::Tension | Region::Corner),
        "{region:?}"
    );
    // Projection onto a separable floor at y = 0 (h = 0.1): 0.02 below is put back, with its
    // velocity into the floor removed; 0.07 below (more than half a cell) is left and flagged.
    let g = grid::<2>();
    let mut boundary = Boundary::all(Wall::new(WallKind::Free));
    boundary.walls[1][0] = Wall {
        kind: WallKind::Slip,
        separable: true,
    };
    let contact = Contact::<T, 2>::default();
    let end = EndOfStep::new(&g, &boundary, &contact, 0.0);
    let id = Tensor::<T, 2>::identity();
    let calm = Matrix3::zeros();
    let (mut x, mut v) = (cst([0.3, -0.02]), cst([1.0, -2.0]));
    assert_eq!(end.project(&mut x, &mut v), 1 << 2);
    assert_eq!((x, v), (cst([0.3, 0.0]), cst([1.0, 0.0])));
    assert!(!end.flag(&x, &v, &id, &calm));
    let (mut x, mut v) = (cst([0.3, -0.07]), cst([1.0, -2.0]));
    assert_eq!(end.project(&mut x, &mut v), 0);
    assert!(end.flag(&x, &v, &id, &calm), "crossed the floor");
    let nan = Matrix3::from_element(T::cst(f64::NAN));
    assert!(end.flag(&cst([0.3, 0.3]), &v, &id, &nan), "NaN stress");
}

/// Each stage test for one scalar type.
macro_rules! stage_tests {
    ($module:ident, $t:ty) => {
        mod $module {
            #[test]
            fn p2g_conserves_mass_momentum_and_the_stress_moment() {
                super::p2g_conserves::<$t, 2>();
                super::p2g_conserves::<$t, 3>();
            }

            #[test]
            fn node_update_applies_coulomb_on_a_friction_floor() {
                super::node_update_on_a_friction_floor::<$t>();
            }

            #[test]
            fn g2p_reproduces_affine_fields() {
                super::g2p_reproduces_affine_fields::<$t, 2>();
                super::g2p_reproduces_affine_fields::<$t, 3>();
            }

            #[test]
            fn particle_end_updates_and_projects() {
                super::particle_end_updates_and_projects::<$t>();
            }
        }
    };
}

stage_tests!(f32_stages, f32);
stage_tests!(f64_stages, f64);
stage_tests!(dual_stages, num_dual::Dual64);
