//! Checks of [`ModifiedCamClay`]: the normal compression and unloading lines, the undrained
//! stress path against its closed form, returns ending on the ellipse, the initial state, and
//! the consistent tangent (and parameter derivatives) from dual numbers against central
//! differences in the elastic region and on both sides of the critical state, at distinct and
//! repeated trial strains.

use super::soil_tests::{check_tangent, principal, rng};
use super::*;
use nalgebra::matrix;
use num_dual::Dual64;

/// A soft clay: λ = 0.2, κ = 0.04, M = 1, e₀ = 1.
fn clay(shear: Shear<f64>, preconsolidation: Preconsolidation<f64>) -> ModifiedCamClay<f64> {
    ModifiedCamClay {
        lambda: 0.2,
        kappa: 0.04,
        critical_state_slope: 1.0,
        void_ratio: 1.0,
        shear,
        preconsolidation,
    }
}

fn nc_clay() -> ModifiedCamClay<f64> {
    clay(Shear::Poisson(0.3), Preconsolidation::Ratio(1.0))
}

/// `τ = −p I` (tension positive).
fn isotropic(p: f64) -> Matrix3<f64> {
    Matrix3::identity() * -p
}

/// `(p, q)` of a Kirchhoff stress, compression positive.
fn invariants(tau: &Matrix3<f64>) -> (f64, f64) {
    let p = -tau.trace() / 3.0;
    let dev = tau + Matrix3::identity() * p;
    (p, (1.5 * dev.component_mul(&dev).sum()).sqrt())
}

#[test]
fn initial_state_carries_the_given_stress() {
    let m = clay(Shear::Poisson(0.3), Preconsolidation::Ratio(2.0));
    let tau0 = Matrix3::from_diagonal(&nalgebra::vector![-60e3, -60e3, -100e3]);
    let state = m.initial_state(&tau0).expect("compressive");
    let (tau, after, region) = m.return_map(&Matrix3::identity(), &state);
    // A step with ΔF = I returns τ₀: round-off of log/exp of bₑ (1e-12 of the stress).
    assert!(
        (tau - tau0).norm() <= 1e-10 * tau0.norm(),
        "{tau} vs {tau0}"
    );
    assert_eq!(region, Region::Elastic);
    let (p, q) = invariants(&tau0);
    let expected = 2.0 * (p + q * q / p);
    assert!((after.hardening - expected).abs() <= 1e-12 * expected);
    assert!(m.initial_state(&Matrix3::zeros()).is_none());
    assert!(m.initial_state(&(Matrix3::identity() * 1e3)).is_none());
}

/// Isotropic compression from a normally consolidated state: the points follow
/// `ln v = const − λ̃ ln p′` while loading and `− κ̃ ln p′` while unloading, exactly (the
/// return lands on `p = p_c` and both laws are exponential), here to 1e-9 of the slope.
#[test]
fn isotropic_compression_follows_the_ncl_and_unloads_on_kappa() {
    let m = nc_clay();
    let mut state = m.initial_state(&isotropic(100e3)).unwrap();
    let mut ln_j = 0.0;
    let mut previous = (0.0, 100e3f64.ln());
    let stretch = |s: f64| Matrix3::identity() * s;
    for (steps, s, slope) in [(10, 0.99, m.lambda_log()), (5, 1.002, m.kappa_log())] {
        for _ in 0..steps {
            let (tau, next, _) = m.return_map(&stretch(s), &state);
            state = next;
            ln_j += 3.0 * f64::ln(s);
            let ln_p = (-tau.trace() / 3.0).ln();
            let measured = -(ln_j - previous.0) / (ln_p - previous.1);
            assert!(
                (measured - slope).abs() <= 1e-9 * slope,
                "d ln v / d ln p′ = {measured} (expected {slope})"
            );
            previous = (ln_j, ln_p);
        }
    }
}

/// Undrained (isochoric) triaxial compression of normally consolidated clay: at every step the
/// stress lies on `q = M p′ √(p′_c/p′ − 1)` with `p′_c = p′_c0 (p′₀/p′)^(κ/(λ−κ))`, the closed
/// form of the model at constant volume (exact for backward Euler, so to the local Newton's
/// tolerance: 1e-8 of p′₀), and the path ends at the critical state, `p′_f/p′₀ = (½)^((λ−κ)/λ)`
/// = 0.574, `q_f = M p′_f`, within 0.5 % after 40 % axial strain.
#[test]
fn undrained_path_matches_the_closed_form() {
    let m = nc_clay();
    let p0 = 100e3;
    let mut state = m.initial_state(&isotropic(p0)).unwrap();
    let steps = 200;
    let a: f64 = (-0.4f64 / steps as f64).exp();
    let df = Matrix3::from_diagonal(&nalgebra::vector![a.powf(-0.5), a.powf(-0.5), a]);
    let exponent = m.kappa / (m.lambda - m.kappa);
    let mut last = (p0, 0.0);
    for _ in 0..steps {
        let (tau, next, _) = m.return_map(&df, &state);
        state = next;
        let (p, q) = invariants(&tau);
        let p_c = p0 * (p0 / p).powf(exponent);
        let closed = m.critical_state_slope * p * (p_c / p - 1.0).max(0.0).sqrt();
        assert!(
            (q - closed).abs() <= 1e-8 * p0,
            "q = {q}, closed form {closed}"
        );
        assert!((state.hardening - p_c).abs() <= 1e-8 * p0);
        last = (p, q);
    }
    let ratio = 0.5f64.powf((m.lambda - m.kappa) / m.lambda);
    assert!(
        (last.0 / p0 - ratio).abs() <= 5e-3 * ratio,
        "p′/p′₀ = {}",
        last.0 / p0
    );
    assert!(
        (last.1 / last.0 - 1.0).abs() <= 5e-3,
        "q/p′ = {}",
        last.1 / last.0
    );
}

/// Plastic returns from random trial states end on the ellipse (f = 0 to 1e-9 of p_c²),
/// elastic ones inside, on both sides of the critical state.
#[test]
fn returns_end_on_the_ellipse() {
    let mut seed = 11;
    for preconsolidation in [1.0, 4.0] {
        let m = clay(
            Shear::Modulus(3e6),
            Preconsolidation::Ratio(preconsolidation),
        );
        let state = m.initial_state(&isotropic(100e3)).unwrap();
        let (mut wet, mut dry) = (0, 0);
        for _ in 0..500 {
            let df = Matrix3::identity()
                + Matrix3::from_fn(|_, _| 0.03 * (2.0 * rng(&mut seed) - 1.0))
                + Matrix3::identity() * 0.02 * (2.0 * rng(&mut seed) - 1.0);
            let (tau, next, region) = m.return_map(&df, &state);
            let (p, q) = invariants(&tau);
            let f = m.yield_function(p, q, next.hardening);
            let scale = next.hardening * next.hardening;
            match region {
                Region::Elastic => assert!(f <= 1e-9 * scale, "elastic outside: f = {f}"),
                _ => {
                    assert!(f.abs() <= 1e-9 * scale, "f = {f:e}");
                    if p > next.hardening / 2.0 {
                        wet += 1
                    } else {
                        dry += 1
                    }
                }
            }
        }
        assert!(wet + dry > 50, "too few plastic returns");
        if preconsolidation > 2.0 {
            assert!(dry > 10, "no return on the dry side");
        }
    }
}

/// The dual tangent against central differences (tolerances in [`check_tangent`]): elastic,
/// plastic on the wet side (normally consolidated), plastic on the dry side (OCR 4), and at
/// repeated trial strains (isotropic compression, triaxial), for both shear laws.
#[test]
fn tangent_matches_central_differences() {
    let triaxial = matrix![1.0, 0.0, 0.0; 0.0, 1.0, 0.0; 0.0, 0.0, 0.985];
    let general = matrix![1.004, 0.003, -0.002; 0.001, 0.996, 0.004; -0.003, 0.002, 0.985];
    let directions = [
        matrix![0.3, 0.1, -0.2; 0.4, -0.5, 0.2; 0.1, 0.3, 0.6],
        matrix![1.0, 0.0, 0.0; 0.0, 1.0, 0.0; 0.0, 0.0, 1.0],
    ];
    for shear in [Shear::Poisson(0.3), Shear::Modulus(3e6)] {
        for (ocr, df, what) in [
            (1.0, Matrix3::identity() * 1.001, "elastic unloading"),
            (1.0, Matrix3::identity() * 0.995, "isotropic loading"),
            (1.0, triaxial, "wet side, triaxial"),
            (1.0, general, "wet side, general"),
            (4.0, triaxial, "dry side, triaxial"),
            (4.0, general, "dry side, general"),
        ] {
            let m = clay(shear, Preconsolidation::Ratio(ocr));
            let state = m.initial_state(&isotropic(100e3)).unwrap();
            let md = m.lift::<Dual64>();
            let sd = state.lift::<Dual64>();
            for d in &directions {
                check_tangent(
                    |g| md.return_map(g, &sd).0,
                    |g| m.return_map(g, &state).0,
                    &df,
                    d,
                    &format!("{shear:?}, {what}"),
                );
            }
        }
    }
}

/// Derivatives of the returned stress and `p_c` with respect to λ, κ, M, e₀ and the incoming
/// `p_c` by one dual evaluation each, against central differences with a relative step of
/// 1e-6 (truncation ~1e-12, round-off ~1e-10 of the value: tolerance 1e-6 of the derivative
/// plus 1e-9 of the value).
#[test]
fn parameter_derivatives_match_central_differences() {
    let df = matrix![1.004, 0.003, -0.002; 0.001, 0.996, 0.004; -0.003, 0.002, 0.985];
    let m = nc_clay();
    let state = m.initial_state(&isotropic(100e3)).unwrap();
    type Setter = fn(&mut ModifiedCamClay<Dual64>, &mut MaterialState<Dual64>, Dual64);
    let cases: [(&str, Setter, f64); 5] = [
        ("lambda", |m, _, v| m.lambda = v, m.lambda),
        ("kappa", |m, _, v| m.kappa = v, m.kappa),
        (
            "M",
            |m, _, v| m.critical_state_slope = v,
            m.critical_state_slope,
        ),
        ("e0", |m, _, v| m.void_ratio = v, m.void_ratio),
        ("p_c", |_, s, v| s.hardening = v, state.hardening),
    ];
    for (name, set, value) in cases {
        let eval = |x: Dual64| {
            let mut md = m.lift::<Dual64>();
            let mut sd = state.lift::<Dual64>();
            set(&mut md, &mut sd, x);
            let (tau, next, region) = md.return_map(&df.map(Dual64::from_re), &sd);
            assert_eq!(region, Region::Shear, "{name}: the case must be plastic");
            (tau, next.hardening)
        };
        let (tau, p_c) = eval(Dual64::new(value, 1.0));
        let h = 1e-6 * value;
        let (tp, pp) = eval(Dual64::from_re(value + h));
        let (tm, pm) = eval(Dual64::from_re(value - h));
        let fd_tau = (tp - tm).map(|x| x.re) / (2.0 * h);
        let fd_pc = (pp.re - pm.re) / (2.0 * h);
        let ad_tau = tau.map(|x| x.eps);
        let tol = |d: f64, v: f64| 1e-6 * d.abs() + 1e-9 * v.abs() / h;
        assert!(
            (ad_tau - fd_tau).norm() <= tol(fd_tau.norm(), tau.map(|x| x.re).norm()),
            "{name}: dτ dual {ad_tau:.6e} vs central {fd_tau:.6e}"
        );
        assert!(
            (p_c.eps - fd_pc).abs() <= tol(fd_pc, p_c.re),
            "{name}: dp_c dual {} vs central {fd_pc}",
            p_c.eps
        );
    }
}

/// At repeated principal stresses (triaxial) the ordered principal values of the return
/// satisfy τ₁ = τ₂ exactly (the return keeps the trial's symmetry).
#[test]
fn triaxial_return_keeps_the_symmetry() {
    let m = nc_clay();
    let state = m.initial_state(&isotropic(100e3)).unwrap();
    let df = matrix![1.0, 0.0, 0.0; 0.0, 1.0, 0.0; 0.0, 0.0, 0.98];
    let (tau, _, _) = m.return_map(&df, &state);
    let t = principal(&tau);
    assert!((t[0] - t[1]).abs() <= 1e-9 * t[2].abs());
}

/// The wave speed of the explicit time-step bound comes from the state's own stiffness: at an
/// isotropic state `p₀` (inside the ellipse, OCR 2) the constrained modulus `∂τ_zz/∂ε_zz` of a
/// uniaxial Hencky strain, by central differences of the return map (δ = 1e-6: truncation
/// ~δ² and round-off ~1e-10 |τ|/δ, both far below the 1e-6 tolerance), equals
/// `p_wave_modulus_in = p₀/κ̃ + 4G(p₀)/3`, and it grows in proportion to `p₀` (`K` and `G`
/// both ∝ `p` with `G` from ν); at a distorted state it bounds the stiffness along every
/// axis.
#[test]
fn the_wave_speed_follows_the_state_pressure() {
    let m = clay(Shear::Poisson(0.3), Preconsolidation::Ratio(2.0));
    assert!(m.stiffness_depends_on_state());
    let mut moduli = Vec::new();
    for p0 in [50e3, 400e3] {
        let state = m.initial_state(&isotropic(p0)).expect("p₀ > 0");
        let modulus = m.p_wave_modulus_in(&state);
        let h = 1e-6;
        let tau_zz = |e: f64| {
            let df = Matrix3::from_diagonal(&nalgebra::vector![1.0, 1.0, e.exp()]);
            let (tau, _, region) = m.return_map(&df, &state);
            assert_eq!(region, Region::Elastic);
            tau[(2, 2)]
        };
        let fd = (tau_zz(h) - tau_zz(-h)) / (2.0 * h);
        assert!(
            (fd - modulus).abs() <= 1e-6 * modulus,
            "p₀ = {p0}: central difference {fd:.9e} vs {modulus:.9e}"
        );
        let kappa = 0.04 / 2.0;
        let g = 1.5 * (1.0 - 0.6) / 1.3 * p0 / kappa;
        assert!((modulus - (p0 / kappa + 4.0 / 3.0 * g)).abs() <= 1e-9 * modulus);
        moduli.push(modulus);
    }
    assert!((moduli[1] / moduli[0] - 8.0).abs() < 1e-9, "{moduli:?}");
    // At a distorted state (τ = diag(−50, −100, −200) kPa) the bound covers the stiffness
    // along every axis, which the coupling `2 (dG/dε_v) dev εₑ ⊗ 1` raises above K + 4G/3.
    let state = m
        .initial_state(&Matrix3::from_diagonal(&nalgebra::vector![
            -50e3, -100e3, -200e3
        ]))
        .expect("p₀ > 0");
    let bound = m.p_wave_modulus_in(&state);
    for axis in 0..3 {
        let h = 1e-6;
        let tau = |e: f64| {
            let mut d = nalgebra::Vector3::from_element(1.0);
            d[axis] = e.exp();
            let (tau, _, region) = m.return_map(&Matrix3::from_diagonal(&d), &state);
            assert_eq!(region, Region::Elastic);
            tau[(axis, axis)]
        };
        let fd = (tau(h) - tau(-h)) / (2.0 * h);
        assert!(
            fd <= bound,
            "axis {axis}: stiffness {fd:.6e} above the bound {bound:.6e}"
        );
    }
}
