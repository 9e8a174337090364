//! Physics checks of the constitutive models.

use super::*;
use num_dual::Dual64;

fn models<T: Scalar>() -> Vec<(&'static str, Box<dyn Hyperelastic<T>>)> {
    let lame = Lame::from_young_poisson(T::cst(1.0e6), T::cst(0.3));
    vec![
        ("linear", Box::new(LinearElastic { lame })),
        ("neo-hookean", Box::new(NeoHookean { lame })),
        ("hencky", Box::new(Hencky { lame })),
    ]
}

fn sample_f() -> Matrix3<f64> {
    nalgebra::matrix![1.10, 0.15, -0.05; -0.08, 0.93, 0.12; 0.04, -0.02, 1.05]
}

/// P = ∂ψ/∂F entry by entry: seed F_ij with a Dual64 and compare the energy's derivative to the
/// model's first Piola–Kirchhoff stress. Both are exact up to round-off (~1e-16 relative to
/// |P| ~ 1e5 Pa), hence the 1e-9 relative tolerance.
#[test]
fn stress_is_the_energy_derivative_for_every_hyperelastic_model() {
    for f in [
        sample_f(),
        Matrix3::identity(),
        Matrix3::from_diagonal(&nalgebra::vector![1.2, 1.2, 0.9]),
    ] {
        for ((name, m), (_, md)) in models::<f64>().into_iter().zip(models::<Dual64>()) {
            let p = m.first_piola(&f);
            let scale = p.norm().max(1.0e3);
            for i in 0..3 {
                for j in 0..3 {
                    let fd = Matrix3::from_fn(|a, b| {
                        Dual64::new(f[(a, b)], if (a, b) == (i, j) { 1.0 } else { 0.0 })
                    });
                    let dpsi = md.energy_density(&fd).eps;
                    assert!(
                        (dpsi - p[(i, j)]).abs() < 1e-9 * scale,
                        "{name}: ∂ψ/∂F[{i}{j}] = {dpsi}, P = {}",
                        p[(i, j)]
                    );
                }
            }
        }
    }
}

#[test]
fn zero_stress_and_energy_in_the_reference_state() {
    for (name, m) in models::<f64>() {
        let i = Matrix3::identity();
        assert!(m.cauchy_stress(&i).norm() < 1e-9, "{name}");
        assert!(m.energy_density(&i).abs() < 1e-9, "{name}");
    }
}

/// Objectivity: σ(R F) = R σ(F) Rᵀ for any rotation R (finite-strain models only; linear
/// elasticity is not objective by construction).
#[test]
fn finite_strain_models_are_objective() {
    let r = nalgebra::Rotation3::from_euler_angles(0.7, -0.4, 1.9).into_inner();
    let f = sample_f();
    for (name, m) in models::<f64>().into_iter().skip(1) {
        let s = m.cauchy_stress(&f);
        let sr = m.cauchy_stress(&(r * f));
        let err = (sr - r * s * r.transpose()).norm() / s.norm();
        assert!(err < 1e-12, "{name}: objectivity error {err}");
    }
}

/// Hencky stress derivatives through the dual eigen path are finite and match central finite
/// differences at F = I, at a repeated stretch pair and at distinct stretches.
/// ε = 1e-6 gives truncation ~1e-12·|∂²σ| and round-off ~1e-10·|σ|/ε; with E = 1e6 the
/// derivatives are ~1e6, so an absolute 1e-2 (relative 1e-8) tolerance is justified.
#[test]
fn hencky_dual_tangent_is_finite_and_exact_at_repeated_stretches() {
    let lame = Lame::from_young_poisson(1.0e6, 0.3);
    let m = Hencky { lame };
    let md = Hencky {
        lame: Lame::from_young_poisson(Dual64::from_re(1.0e6), Dual64::from_re(0.3)),
    };
    let rot = nalgebra::Rotation3::from_euler_angles(0.3, 0.2, -0.5).into_inner();
    let cases = [
        Matrix3::identity(),
        rot * Matrix3::from_diagonal(&nalgebra::vector![1.1, 1.1, 0.95]),
        Matrix3::from_diagonal(&nalgebra::vector![1.0, 1.0, 1.0]) * 1.05,
        sample_f(),
    ];
    let eps = 1e-6;
    for f in cases {
        for i in 0..3 {
            for j in 0..3 {
                let df = Matrix3::from_fn(|a, b| if (a, b) == (i, j) { 1.0 } else { 0.0 });
                let fdual = Matrix3::from_fn(|a, b| Dual64::new(f[(a, b)], df[(a, b)]));
                let dtau = md.kirchhoff_stress(&fdual).map(|x| x.eps);
                assert!(dtau.iter().all(|x| x.is_finite()), "NaN tangent at F = {f}");
                let fdiff = (m.kirchhoff_stress(&(f + df * eps))
                    - m.kirchhoff_stress(&(f - df * eps)))
                    / (2.0 * eps);
                assert!(
                    (dtau - fdiff).norm() < 1e-2,
                    "F = {f}, seed ({i},{j}): dual {dtau} vs fd {fdiff}"
                );
            }
        }
    }
}

#[test]
fn small_strain_limit_matches_linear_elasticity() {
    // At strain 1e-6 all three models agree to O(strain²) relative ⇒ 1e-5 relative tolerance.
    let mut f = Matrix3::identity();
    f[(0, 0)] += 1e-6;
    f[(0, 1)] += 0.5e-6;
    f[(1, 0)] += 0.5e-6;
    let all = models::<f64>();
    let s0 = all[0].1.cauchy_stress(&f);
    for (name, m) in &all[1..] {
        let s = m.cauchy_stress(&f);
        assert!((s - s0).norm() < 1e-5 * s0.norm(), "{name}: {s} vs {s0}");
    }
}

#[test]
fn material_wave_speed() {
    // E = 1e6, ν = 0 ⇒ M = E, c = √(E/ρ) = √(1e6/1e3).
    let m = Material::elastic(ModelKind::Hencky, 1.0e6, 0.0, 1.0e3);
    assert!((m.wave_speed() - 1000.0f64.sqrt()).abs() < 1e-12);
}
