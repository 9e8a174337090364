//! Round-trip checks of the transfers against exact properties.

use super::*;

/// Deterministic pseudo-random numbers in [0, 1) (a tiny LCG keeps the test self-contained).
fn rng(seed: &mut u64) -> f64 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

struct Cloud<const D: usize> {
    grid: Grid<D>,
    x: Vec<Vector<f64, D>>,
    v: Vec<Vector<f64, D>>,
    c: Vec<Tensor<f64, D>>,
    m: Vec<f64>,
}

fn cloud<const D: usize>(n: usize, seed: u64) -> Cloud<D> {
    let mut s = seed;
    let grid = Grid::<D>::new([0.0; D], [6; D], 0.25, 2);
    let x = (0..n)
        .map(|_| Vector::<f64, D>::from_fn(|_, _| 0.2 + 1.1 * rng(&mut s)))
        .collect();
    let v = (0..n)
        .map(|_| Vector::<f64, D>::from_fn(|_, _| rng(&mut s) - 0.5))
        .collect();
    let c = (0..n)
        .map(|_| Tensor::<f64, D>::from_fn(|_, _| 2.0 * rng(&mut s) - 1.0))
        .collect();
    let m = (0..n).map(|_| 0.5 + rng(&mut s)).collect();
    Cloud { grid, x, v, c, m }
}

/// P2G of mass and momentum on a dense grid; returns (mass, velocity) per node.
fn to_grid<const D: usize>(
    cl: &Cloud<D>,
    shape: Shape,
    affine: bool,
) -> (Vec<f64>, Vec<Vector<f64, D>>) {
    let n = cl.grid.num_nodes();
    let mut mp = vec![(0.0, Vector::<f64, D>::zeros()); n];
    let hw = Vector::<f64, D>::repeat(cl.grid.h / 4.0);
    let layout = Layout::grid(&cl.grid);
    for k in 0..cl.x.len() {
        let st = Stencil::new(shape, &cl.grid, &cl.x[k], &hw);
        let mc = if affine {
            cl.c[k] * cl.m[k]
        } else {
            Tensor::zeros()
        };
        p2g_momentum(
            &st,
            &layout,
            &cl.v[k],
            &mc,
            cl.m[k],
            &mut mp,
            |e, mw, mv| {
                e.0 += mw;
                e.1 += mv;
            },
        );
    }
    let m = mp.iter().map(|e| e.0).collect();
    let v = mp
        .iter()
        .map(|&(mi, pi)| if mi > 0.0 { pi / mi } else { pi })
        .collect();
    (m, v)
}

fn gather<const D: usize>(
    cl: &Cloud<D>,
    shape: Shape,
    vel: &[Vector<f64, D>],
    k: usize,
) -> Gathered<f64, D> {
    let hw = Vector::<f64, D>::repeat(cl.grid.h / 4.0);
    let st = Stencil::new(shape, &cl.grid, &cl.x[k], &hw);
    g2p(
        &st,
        &Layout::grid(&cl.grid),
        &cl.grid,
        shape,
        Transfer::Apic,
        true,
        vel,
        &[],
    )
}

/// Angular momentum `Σ m x × v` as a vector with `D(D−1)/2` components (z only in 2D).
fn cross<const D: usize>(a: &Vector<f64, D>, b: &Vector<f64, D>) -> [f64; 3] {
    if D == 2 {
        [a[0] * b[1] - a[1] * b[0], 0.0, 0.0]
    } else {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }
}

fn add(acc: &mut [f64; 3], s: f64, v: [f64; 3]) {
    for i in 0..3 {
        acc[i] += s * v[i];
    }
}

/// Particle angular momentum including the APIC affine part `Σ_i w_ip r × (C_p r)`,
/// `r = x_i − x_p` (Jiang et al. 2015, eq. for `L_p`).
fn particle_angular_momentum<const D: usize>(
    cl: &Cloud<D>,
    shape: Shape,
    v: &[Vector<f64, D>],
    c: &[Tensor<f64, D>],
) -> [f64; 3] {
    let hw = Vector::<f64, D>::repeat(cl.grid.h / 4.0);
    let mut l = [0.0; 3];
    for k in 0..cl.x.len() {
        add(&mut l, cl.m[k], cross(&cl.x[k], &v[k]));
        let st = Stencil::new(shape, &cl.grid, &cl.x[k], &hw);
        st.for_each(|n| {
            let r = n.offset;
            add(&mut l, cl.m[k] * n.weight, cross(&r, &(c[k] * r)));
        });
    }
    l
}

fn check_apic<const D: usize>(shape: Shape) {
    // 1. An affine field v = A x + b with C_p = A survives P2G → G2P exactly (to round-off).
    let mut cl = cloud::<D>(300, 7 + D as u64);
    let a = cl.c[0];
    let b = cl.v[0];
    for k in 0..cl.x.len() {
        cl.v[k] = a * cl.x[k] + b;
        cl.c[k] = a;
    }
    let (_, vel) = to_grid(&cl, shape, true);
    for k in 0..cl.x.len() {
        let g = gather(&cl, shape, &vel, k);
        assert!(
            (g.v - cl.v[k]).norm() < 1e-12,
            "{shape:?}: affine velocity not reproduced"
        );
        assert!(
            (g.affine - a).norm() < 1e-11,
            "{shape:?}: affine matrix {} vs {a}",
            g.affine
        );
    }
    // 2. Arbitrary v_p, C_p: angular momentum particles → grid → particles is conserved.
    let cl = cloud::<D>(300, 99 + D as u64);
    let l0 = particle_angular_momentum(&cl, shape, &cl.v, &cl.c);
    let (m, vel) = to_grid(&cl, shape, true);
    let mut lg = [0.0; 3];
    for (i, (&mi, vi)) in m.iter().zip(&vel).enumerate() {
        add(
            &mut lg,
            mi,
            cross(&cl.grid.node_position::<f64>(cl.grid.multi(i)), vi),
        );
    }
    let (mut v1, mut c1) = (cl.v.clone(), cl.c.clone());
    for k in 0..cl.x.len() {
        let g = gather(&cl, shape, &vel, k);
        (v1[k], c1[k]) = Transfer::Apic.particle_velocity(&cl.v[k], &g);
    }
    let l1 = particle_angular_momentum(&cl, shape, &v1, &c1);
    let scale = l0.iter().map(|x| x.abs()).sum::<f64>().max(1.0);
    for i in 0..3 {
        // Sums of ~300·27 terms of O(1): round-off well below 1e-12 relative.
        assert!(
            (lg[i] - l0[i]).abs() < 1e-12 * scale,
            "{shape:?}: P2G changed L: {lg:?} vs {l0:?}"
        );
        assert!(
            (l1[i] - l0[i]).abs() < 1e-12 * scale,
            "{shape:?}: G2P changed L: {l1:?} vs {l0:?}"
        );
    }
}

#[test]
fn apic_round_trip_is_exact_for_affine_fields_and_conserves_angular_momentum() {
    for shape in [Shape::QuadraticBspline, Shape::CubicBspline] {
        check_apic::<2>(shape);
        check_apic::<3>(shape);
    }
}

#[test]
fn gradient_form_apic_reproduces_affine_fields_for_hat_and_gimp() {
    for shape in [Shape::Linear, Shape::Ugimp] {
        let mut cl = cloud::<2>(200, 3);
        let a = cl.c[0];
        for k in 0..cl.x.len() {
            cl.v[k] = a * cl.x[k];
            cl.c[k] = a;
        }
        let (_, vel) = to_grid(&cl, shape, true);
        for k in 0..cl.x.len() {
            let g = gather(&cl, shape, &vel, k);
            assert!((g.v - cl.v[k]).norm() < 1e-12, "{shape:?}");
            assert!((g.grad_v - a).norm() < 1e-11, "{shape:?}");
        }
    }
}

#[test]
fn flip_blend_endpoints() {
    let g = Gathered::<f64, 2> {
        v: Vector::<f64, 2>::new(1.0, 2.0),
        dv: Vector::<f64, 2>::new(0.5, -0.5),
        grad_v: Tensor::zeros(),
        affine: Tensor::zeros(),
    };
    let vp = Vector::<f64, 2>::new(3.0, 3.0);
    let (pic, _) = Transfer::Flip { alpha: 0.0 }.particle_velocity(&vp, &g);
    let (flip, _) = Transfer::Flip { alpha: 1.0 }.particle_velocity(&vp, &g);
    assert_eq!(pic, g.v);
    assert_eq!(flip, vp + g.dv);
}

/// TPIC reproduces an affine velocity field exactly for every shape function (its C_p is the
/// gathered velocity gradient, and Σ x_i ⊗ ∇w = I), and conserves linear momentum.
#[test]
fn tpic_round_trip_is_exact_for_affine_fields() {
    for shape in Shape::ALL {
        let mut cl = cloud::<2>(200, 11);
        let a = cl.c[0];
        let b = cl.v[0];
        for k in 0..cl.x.len() {
            cl.v[k] = a * cl.x[k] + b;
            cl.c[k] = a;
        }
        let (m, vel) = to_grid(&cl, shape, true);
        let p_grid: Vector<f64, 2> = m.iter().zip(&vel).map(|(&mi, v)| v * mi).sum();
        let p_particles: Vector<f64, 2> = cl.v.iter().zip(&cl.m).map(|(v, &mi)| v * mi).sum();
        assert!((p_grid - p_particles).norm() < 1e-12 * p_particles.norm().max(1.0));
        let hw = Vector::<f64, 2>::repeat(cl.grid.h / 4.0);
        for k in 0..cl.x.len() {
            let st = Stencil::new(shape, &cl.grid, &cl.x[k], &hw);
            let g = g2p(
                &st,
                &Layout::grid(&cl.grid),
                &cl.grid,
                shape,
                Transfer::Tpic,
                false,
                &vel,
                &[],
            );
            let (v, c) = Transfer::Tpic.particle_velocity(&cl.v[k], &g);
            assert!((v - cl.v[k]).norm() < 1e-12, "{shape:?}: velocity");
            assert!((c - a).norm() < 1e-11, "{shape:?}: gradient {c} vs {a}");
        }
    }
}

/// The nodal forces of MLS-MPM's P2G term for one particle with stress `σ` (volume 1), read
/// off [`p2g_momentum`] with `v = 0`, `C = 0`, `Δt = 1`: `f_i = −σ D⁻¹ (x_i − x_p) w_ip`.
fn mls_forces<const D: usize>(
    cl: &Cloud<D>,
    shape: Shape,
    k: usize,
    sigma: &Tensor<f64, D>,
) -> Vec<Vector<f64, D>> {
    let kappa_inv = shape.apic_inverse_inertia().expect("a B-spline");
    let a = mls_affine_momentum(cl.m[k], &Tensor::zeros(), sigma, 1.0, kappa_inv, cl.grid.h);
    let mut f = vec![Vector::<f64, D>::zeros(); cl.grid.num_nodes()];
    let hw = Vector::<f64, D>::repeat(cl.grid.h / 4.0);
    let st = Stencil::new(shape, &cl.grid, &cl.x[k], &hw);
    let layout = Layout::grid(&cl.grid);
    p2g_momentum(
        &st,
        &layout,
        &Vector::zeros(),
        &a,
        cl.m[k],
        &mut f,
        |e, _, p| *e += p,
    );
    f
}

/// MLS-MPM's internal force is exact in the three senses the method rests on (Hu et al.
/// 2018): the nodal forces of one particle sum to zero (`Σ_i w_ip (x_i − x_p) = 0`), their
/// moment vanishes for a symmetric stress, and their work on any affine grid velocity
/// `v_i = G x_i + b` is the particle's stress power `−V σ : G` (`Σ_i w (x_i − x_p) ⊗
/// (x_i − x_p) = D_p`). All to round-off.
#[test]
fn mls_force_balances_and_does_the_stress_power_on_affine_fields() {
    fn check<const D: usize>(shape: Shape) {
        let cl = cloud::<D>(40, 23 + D as u64);
        for k in 0..cl.x.len() {
            let g = cl.c[(k + 1) % cl.x.len()];
            let b = cl.v[(k + 2) % cl.x.len()];
            // A symmetric stress of order 1.
            let sigma = (cl.c[k] + cl.c[k].transpose()) * 0.5;
            let f = mls_forces(&cl, shape, k, &sigma);
            let (mut sum, mut moment, mut work) = (Vector::<f64, D>::zeros(), [0.0; 3], 0.0);
            for (i, fi) in f.iter().enumerate() {
                let xi = cl.grid.node_position::<f64>(cl.grid.multi(i));
                sum += fi;
                add(&mut moment, 1.0, cross(&xi, fi));
                work += fi.dot(&(g * xi + b));
            }
            // Forces of order 1/h ≈ 4 summed over ≤ 64 nodes: 1e-12 is round-off.
            assert!(sum.norm() < 1e-12, "{shape:?} D={D}: Σ f = {sum}");
            assert!(
                moment.iter().all(|m| m.abs() < 1e-12),
                "{shape:?} D={D}: moment {moment:?}"
            );
            let power = -(sigma.component_mul(&g)).sum();
            assert!(
                (work - power).abs() < 1e-12 * power.abs().max(1.0),
                "{shape:?} D={D}: work {work} vs −σ:G = {power}"
            );
        }
    }
    for shape in [Shape::QuadraticBspline, Shape::CubicBspline] {
        check::<2>(shape);
        check::<3>(shape);
    }
}
