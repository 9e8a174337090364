//! Checks of the weakly compressible fluid.

use super::*;
use num_dual::Dual64;

const K: f64 = 2.0e6;
const ETA: f64 = 1.0e-3;

fn water(gamma: f64) -> Fluid<f64> {
    Fluid {
        bulk_modulus: K,
        gamma,
        viscosity: ETA,
    }
}

/// One step of Δt = 1e-4 s from `F` (also the increment) with velocity gradient `L`.
fn kin<'a, T: Scalar>(
    f: &'a Matrix3<T>,
    l: &'a Matrix3<T>,
    zero: &'a Matrix3<T>,
) -> Kinematics<'a, T> {
    Kinematics {
        f,
        delta_f: f,
        velocity_gradient: l,
        dt: T::cst(1e-4),
        stress: zero,
    }
}

#[test]
fn no_pressure_or_energy_at_the_reference_volume() {
    for gamma in [1.0, 1.4, 7.0] {
        let m = water(gamma);
        assert_eq!(m.pressure(1.0), 0.0);
        assert_eq!(m.energy_of_volume_ratio(1.0), 0.0);
        assert_eq!(m.energy_density(&Matrix3::identity()), 0.0);
        assert_eq!(m.kirchhoff_stress(&Matrix3::identity()), Matrix3::zeros());
    }
}

/// `dp/dJ = −K` at `J = 1` for every γ, i.e. `p ≈ K(1 − J)` for small compression. The dual
/// derivative is exact to round-off (1e-9 relative); the central difference with
/// `δ = 1e-6` has truncation `|p'''| δ²/6 ~ K γ² δ² ~ 1e-10 K` and round-off
/// `~1e-16 · K / δ = 1e-10 K`, hence 1e-6 relative.
#[test]
fn bulk_modulus_is_the_reference_stiffness() {
    for gamma in [1.0, 2.0, 7.0] {
        let m = water(gamma);
        let md = m.lift::<Dual64>();
        let dual = md.pressure(Dual64::new(1.0, 1.0)).eps;
        assert!((dual + K).abs() < 1e-9 * K, "γ = {gamma}: dp/dJ = {dual}");
        let d = 1e-6;
        let fd = (m.pressure(1.0 + d) - m.pressure(1.0 - d)) / (2.0 * d);
        assert!((fd + K).abs() < 1e-6 * K, "γ = {gamma}: fd dp/dJ = {fd}");
        // Small compression: p = K (1 − J) + O((1 − J)²), here 1e-5 relative.
        let j = 1.0 - 1e-5;
        assert!((m.pressure(j) - K * (1.0 - j)).abs() < 1e-4 * K * (1.0 - j));
        assert!(m.pressure(j) > 0.0, "compression gives positive pressure");
    }
    // γ = 1 is p = K (1/J − 1) exactly.
    let m = water(1.0);
    for j in [0.5, 0.9, 1.3] {
        assert!((m.pressure(j) - K * (1.0 / j - 1.0)).abs() < 1e-12 * K);
    }
}

#[test]
fn sound_speed_gives_the_bulk_modulus() {
    let m = Fluid::from_sound_speed(20.0, 1000.0, 7.0, 0.0);
    assert_eq!(m.bulk_modulus, 4.0e5);
    let mat = Material {
        density: 1000.0,
        model: Model::Fluid(m),
    };
    assert!((mat.wave_speed() - 20.0).abs() < 1e-12);
    assert_eq!(mat.constitutive().p_wave_modulus(), 4.0e5);
}

/// At rest (`L = 0`) the stress is the hydrostatic `−p I`, whatever the shear in `F`.
#[test]
fn stress_at_rest_is_hydrostatic() {
    let m = water(7.0);
    let zero = Matrix3::zeros();
    let f = nalgebra::matrix![0.98, 0.3, 0.0; 0.01, 0.99, 0.0; 0.0, 0.0, 1.0];
    let j = f.determinant();
    let s = m.update(&kin(&f, &zero, &zero), &mut MaterialState::default());
    let expected = Matrix3::identity() * -m.pressure(j);
    assert!((s - expected).norm() < 1e-12 * K, "{s} vs {expected}");
    assert!(m.pressure(j) > 0.0);
}

/// Simple shear `L = [[0, γ̇], [0, 0]]` (plane strain): `σ_xy = η γ̇`, no normal viscous
/// stress; a uniaxial stretching rate gives a traceless (deviatoric) viscous stress.
#[test]
fn viscous_stress_is_deviatoric_and_newtonian() {
    let m = water(7.0);
    let (i, zero) = (Matrix3::identity(), Matrix3::zeros());
    let rate = 40.0;
    let l = nalgebra::matrix![0.0, rate, 0.0; 0.0, 0.0, 0.0; 0.0, 0.0, 0.0];
    let s = m.update(&kin(&i, &l, &zero), &mut MaterialState::default());
    assert!((s[(0, 1)] - ETA * rate).abs() < 1e-15);
    assert!((s[(1, 0)] - ETA * rate).abs() < 1e-15);
    for a in 0..3 {
        assert!(s[(a, a)].abs() < 1e-15, "normal stress {}", s[(a, a)]);
    }
    // A stretching rate with a volumetric part: the viscous stress is 2η dev D, traceless.
    let l = nalgebra::matrix![3.0, 1.0, 0.0; -2.0, 0.5, 0.0; 0.0, 0.0, 0.0];
    let v = m.viscous_stress(&l);
    assert!(v.trace().abs() < 1e-15);
    let d = (l + l.transpose()) * 0.5;
    let expected = (d - i * (d.trace() / 3.0)) * (2.0 * ETA);
    assert!((v - expected).norm() < 1e-15);
    let s = m.update(&kin(&i, &l, &zero), &mut MaterialState::default());
    assert!((s - expected).norm() < 1e-15, "no pressure at J = 1");
}

/// `dψ/dJ = −p` by dual numbers (exact up to round-off: 1e-9 relative to K), across γ,
/// including γ = 1 (the logarithmic case) and γ within 1e-9 of it (the expm1 form, which
/// must not cancel), and `P = ∂ψ/∂F` gives the Kirchhoff stress `−J p I`.
#[test]
fn energy_derivative_is_minus_the_pressure() {
    for gamma in [1.0, 1.0 + 1e-9, 1.5, 7.0] {
        let m = water(gamma);
        let md = m.lift::<Dual64>();
        for j in [0.8, 0.97, 1.0, 1.02, 1.4] {
            let dpsi = md.energy_of_volume_ratio(Dual64::new(j, 1.0)).eps;
            let p = m.pressure(j);
            assert!(
                (dpsi + p).abs() < 1e-9 * K,
                "γ = {gamma}, J = {j}: {dpsi} vs {p}"
            );
            let psi = m.energy_of_volume_ratio(j);
            assert!(psi >= 0.0, "ψ is non-negative (convex, minimum at J = 1)");
        }
    }
    // Closed forms: γ = 1 is K (J − 1 − ln J); γ = 2 is (K/2)(J − 1 + 1/J − 1).
    let j: f64 = 0.9;
    let psi1 = water(1.0).energy_of_volume_ratio(j);
    assert!((psi1 - K * (j - 1.0 - j.ln())).abs() < 1e-12 * K);
    let psi2 = water(2.0).energy_of_volume_ratio(j);
    assert!((psi2 - 0.5 * K * (j - 1.0 + 1.0 / j - 1.0)).abs() < 1e-12 * K);

    // Through F: ∂ψ/∂F Fᵀ = τ = −J p I.
    let m = water(7.0);
    let md = m.lift::<Dual64>();
    let f = nalgebra::matrix![0.97, 0.05, 0.0; -0.02, 1.01, 0.0; 0.0, 0.0, 1.0];
    let mut dpsi = Matrix3::zeros();
    for a in 0..3 {
        for b in 0..3 {
            let fd = Matrix3::from_fn(|r, c| {
                Dual64::new(f[(r, c)], if (r, c) == (a, b) { 1.0 } else { 0.0 })
            });
            dpsi[(a, b)] = md.energy_density(&fd).eps;
        }
    }
    let tau = dpsi * f.transpose();
    assert!((tau - m.kirchhoff_stress(&f)).norm() < 1e-9 * K);
}

/// The `Material` dispatch (update, energy, Kirchhoff update, trait object) agrees with the
/// direct calls, and `lift` carries the parameters over.
#[test]
fn material_dispatch_matches_the_direct_calls() {
    let mat = Material::fluid(K, 7.0, ETA, 1000.0);
    let Model::Fluid(m) = mat.model else {
        panic!("{:?}", mat.model)
    };
    assert_eq!(m, water(7.0));
    let zero = Matrix3::zeros();
    let f = nalgebra::matrix![0.99, 0.02, 0.0; 0.0, 0.98, 0.0; 0.0, 0.0, 1.0];
    let l = nalgebra::matrix![0.5, 2.0, 0.0; -1.0, -0.3, 0.0; 0.0, 0.0, 0.0];
    let k = kin(&f, &l, &zero);
    let state = MaterialState::default();
    let direct = m.update(&k, &mut state.clone());
    let mut s1 = state;
    assert_eq!(mat.update(&k, &mut s1), direct);
    assert_eq!(s1, state, "no history");
    assert_eq!(mat.constitutive().update(&k, &mut s1.clone()), direct);
    assert_eq!(mat.energy_density(&f, &state), m.energy_density(&f));
    let (tau, s2) = mat.kirchhoff_update(&f, &f, &state);
    assert_eq!(tau, m.kirchhoff_stress(&f));
    assert_eq!(s2, state);
    // The implicit path is inviscid: τ/J is the pressure part of the explicit stress.
    let j = f.determinant();
    assert!((tau / j - (direct - m.viscous_stress(&l))).norm() < 1e-9);

    let lifted = mat.lift::<Dual64>();
    assert_eq!(lifted.density, 1000.0);
    let Model::Fluid(ml) = lifted.model else {
        panic!("lift changed the model")
    };
    assert_eq!(ml.bulk_modulus.re, K);
    assert_eq!(ml.gamma.re, 7.0);
    assert_eq!(ml.viscosity.re, ETA);
    assert_eq!(ml.bulk_modulus.eps, 0.0);
    // The lifted stress with a dual J seed: d(σ_xx)/dF_xx = −dp/dJ · dJ/dF_xx.
    let fd =
        Matrix3::from_fn(|r, c| Dual64::new(f[(r, c)], if (r, c) == (0, 0) { 1.0 } else { 0.0 }));
    let ld = l.map(Dual64::from_re);
    let zd = Matrix3::zeros();
    let kd = kin(&fd, &ld, &zd);
    let sd = lifted.update(&kd, &mut MaterialState::default());
    assert!((sd[(0, 1)].re - direct[(0, 1)]).abs() < 1e-12);
    let dj = f[(1, 1)] * f[(2, 2)] - f[(1, 2)] * f[(2, 1)];
    let dp = lifted.energy_density(&fd, &MaterialState::default()).eps;
    // ψ'(J) dJ/dF_xx = −p dJ/dF_xx.
    assert!((dp + m.pressure(j) * dj).abs() < 1e-9 * K);
    assert!(sd[(0, 0)].eps > 0.0, "stretching F_xx lowers the pressure");
}

#[test]
#[should_panic(expected = "use Material::fluid")]
fn elastic_constructor_refuses_a_fluid() {
    let _ = Material::elastic(ModelKind::Fluid, 1.0e6, 0.3, 1000.0);
}

#[test]
fn integer_exponents_agree_with_the_general_power() {
    // γ = 1 and 7 take the integer power, γ = 7 + 1e-12 the general `exp(−γ ln J)`: the
    // pressures agree to round-off, and so do the J-derivatives.
    for (gamma, near) in [(1.0, 1.0 + 1e-12), (7.0, 7.0 + 1e-12)] {
        let (m, g) = (water(gamma), water(near));
        for j in [0.97, 0.999, 1.0, 1.004, 1.05] {
            let (p, q) = (m.pressure(j), g.pressure(j));
            assert!(
                (p - q).abs() <= 1e-9 * K * (j - 1.0f64).abs() + 1e-6,
                "{p} vs {q}"
            );
            let dp = m.lift::<Dual64>().pressure(Dual64::new(j, 1.0)).eps;
            let dq = g.lift::<Dual64>().pressure(Dual64::new(j, 1.0)).eps;
            assert!(
                (dp - dq).abs() < 1e-9 * K,
                "γ = {gamma}, J = {j}: {dp} vs {dq}"
            );
        }
    }
    // A γ with a derivative part keeps ∂p/∂γ, although its real part is whole:
    // ∂p/∂γ = −p/γ − (K/γ) ln J · J^{−γ}.
    let j = 0.98f64;
    let m = water(7.0);
    let md = Fluid {
        bulk_modulus: Dual64::from_re(K),
        gamma: Dual64::new(7.0, 1.0),
        viscosity: Dual64::from_re(ETA),
    };
    let exact = -m.pressure(j) / 7.0 - K / 7.0 * j.ln() * j.powf(-7.0);
    let dual = md.pressure(Dual64::from_re(j));
    assert!((dual.re - m.pressure(j)).abs() < 1e-9 * K);
    assert!(
        (dual.eps - exact).abs() < 1e-9 * exact.abs(),
        "{} vs {exact}",
        dual.eps
    );
}

#[test]
fn an_inviscid_fluid_has_only_pressure_but_keeps_the_viscosity_derivative() {
    let f = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.99, 1.0, 1.0));
    let l = Matrix3::new(0.1, 0.3, 0.0, -0.2, 0.05, 0.0, 0.0, 0.0, 0.0);
    let zero = Matrix3::zeros();
    let inviscid = Fluid {
        viscosity: 0.0,
        ..water(7.0)
    };
    let s = inviscid.update(&kin(&f, &l, &zero), &mut MaterialState::default());
    assert_eq!(s, Matrix3::identity() * -inviscid.pressure(0.99));
    // η = 0 with a derivative lane: ∂σ/∂η = 2 dev sym L.
    let md = Fluid {
        bulk_modulus: Dual64::from_re(K),
        gamma: Dual64::from_re(7.0),
        viscosity: Dual64::new(0.0, 1.0),
    };
    let (fd, ld, zd) = (
        f.map(Dual64::from_re),
        l.map(Dual64::from_re),
        Matrix3::zeros(),
    );
    let kd = kin(&fd, &ld, &zd);
    let sd = md.update(&kd, &mut MaterialState::default());
    let expected = water(7.0).viscous_stress(&l) / ETA;
    for r in 0..3 {
        for c in 0..3 {
            assert!((sd[(r, c)].re - s[(r, c)]).abs() < 1e-12 * K);
            assert!((sd[(r, c)].eps - expected[(r, c)]).abs() < 1e-12);
        }
    }
}
