//! Checks of the Hencky soil models ([`MohrCoulomb`], [`DruckerPrager`] with
//! [`Elasticity::Hencky`]): returns end on the yield surface, the closed forms of the
//! triaxial edge, and the consistent tangent from dual numbers against central differences in
//! the elastic, main-plane, edge and apex regions, at distinct and repeated trial strains.

use super::*;
use nalgebra::matrix;
use num_dual::Dual64;

/// E = 20 MPa, ν = 0.3: a medium sand; strains of 1e-2 load it to a few hundred kPa.
const YOUNG: f64 = 2.0e7;
const POISSON: f64 = 0.3;

fn mc(phi_deg: f64, psi_deg: f64, cohesion: f64) -> MohrCoulomb<f64> {
    MohrCoulomb {
        lame: Lame::from_young_poisson(YOUNG, POISSON),
        friction_angle: phi_deg.to_radians(),
        dilation_angle: psi_deg.to_radians(),
        cohesion,
        tension_cutoff: None,
    }
}

fn dp_hencky(phi_deg: f64, psi_deg: f64, cohesion: f64, cone: Cone) -> DruckerPrager<f64> {
    DruckerPrager {
        lame: Lame::from_young_poisson(YOUNG, POISSON),
        friction_angle: phi_deg.to_radians(),
        dilation_angle: psi_deg.to_radians(),
        cohesion,
        tension_cutoff: None,
        cone,
        elasticity: Elasticity::Hencky,
    }
}

/// A state of isotropic compression `p` (Pa, compression positive): `bₑ = exp(2εₑ)` with
/// `εₑ = −p/(3K) I`.
fn compressed(lame: &Lame<f64>, p: f64) -> MaterialState<f64> {
    let k = lame.lambda + 2.0 / 3.0 * lame.mu;
    MaterialState {
        plastic_strain: 0.0,
        tensor: Matrix3::identity() * (-2.0 * p / (3.0 * k)).exp(),
        hardening: 0.0,
    }
}

/// The relative deformation gradient (diagonal) that takes [`compressed`]`(p0)` to the
/// triaxial trial stress `τ₁ = τ₂ = −p0 + q/3`, `τ₃ = −p0 − 2q/3` (`q > 0`: compression) or
/// `τ₁ = −p0 + 2|q|/3`, `τ₂ = τ₃ = −p0 − |q|/3` (`q < 0`: extension).
fn triaxial_df(lame: &Lame<f64>, p0: f64, q: f64) -> Matrix3<f64> {
    let t = if q > 0.0 {
        [-p0 + q / 3.0, -p0 + q / 3.0, -p0 - 2.0 * q / 3.0]
    } else {
        [-p0 - 2.0 * q / 3.0, -p0 + q / 3.0, -p0 + q / 3.0]
    };
    let eps = lame.strain(&Matrix3::from_diagonal(&t.into()));
    let k = lame.lambda + 2.0 / 3.0 * lame.mu;
    let eps_n = -p0 / (3.0 * k);
    Matrix3::from_diagonal(&nalgebra::vector![
        (eps[(0, 0)] - eps_n).exp(),
        (eps[(1, 1)] - eps_n).exp(),
        (eps[(2, 2)] - eps_n).exp()
    ])
}

pub(super) fn principal(tau: &Matrix3<f64>) -> [f64; 3] {
    let (l, _) = crate::spectral::symmetric_eigen(tau);
    let mut l = l;
    l.sort_by(|a, b| b.total_cmp(a));
    l
}

/// Deterministic pseudo-random numbers in [0, 1).
pub(super) fn rng(seed: &mut u64) -> f64 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

/// Directional derivative of `τ(ΔF)` along `d` by a dual evaluation against a central
/// difference with step `h = 1e-7`. The return is piecewise smooth (closed form in each
/// region), so away from region boundaries the central difference has truncation `O(h²)`
/// ~1e-12 relative and round-off ~`ε_mach |τ| / h` ~1e-9 |τ|: the tolerance is 1e-6 of the
/// derivative plus 1e-8 |τ| (a tenfold margin on the round-off, which alone sets the floor
/// where the derivative is zero, at the apex).
pub(super) fn check_tangent(
    update: impl Fn(&Matrix3<Dual64>) -> Matrix3<Dual64>,
    real: impl Fn(&Matrix3<f64>) -> Matrix3<f64>,
    df: &Matrix3<f64>,
    d: &Matrix3<f64>,
    what: &str,
) {
    let dual = update(&Matrix3::from_fn(|i, j| Dual64::new(df[(i, j)], d[(i, j)])));
    let h = 1e-7;
    let fd = (real(&(df + d * h)) - real(&(df - d * h))) / (2.0 * h);
    let ad = dual.map(|x| x.eps);
    let scale = fd.norm().max(ad.norm());
    let tau = real(df).norm();
    assert!(
        (ad - fd).norm() <= 1e-6 * scale + 1e-8 * tau,
        "{what}: dual {ad:.6e} vs central difference {fd:.6e}"
    );
    assert!(
        ad.iter().all(|x| x.is_finite()),
        "{what}: non-finite tangent"
    );
}

/// `count` relative deformation gradients `I + a R + b s I` with the entries of `R` and `s`
/// pseudo-random in [−1, 1) from `seed`: distortions of size `a`, volume changes of size `b`.
fn random_df(seed: u64, count: usize, a: f64, b: f64) -> Vec<Matrix3<f64>> {
    let mut seed = seed;
    (0..count)
        .map(|_| {
            Matrix3::identity()
                + Matrix3::from_fn(|_, _| a * (2.0 * rng(&mut seed) - 1.0))
                + Matrix3::identity() * b * (2.0 * rng(&mut seed) - 1.0)
        })
        .collect()
}

#[test]
fn mohr_coulomb_returns_end_on_the_pyramid() {
    let m = mc(30.0, 10.0, 10e3);
    let state = compressed(&m.lame, 100e3);
    let mut regions = std::collections::HashSet::new();
    for df in random_df(7, 2000, 0.04, 0.03) {
        let (tau, _, region) = m.return_map(&df, &state);
        regions.insert(format!("{region:?}"));
        let f = m.yield_function(principal(&tau));
        // 1e-9 of the stress scale: round-off of the closed-form return and the eigenbasis.
        let scale = tau.norm().max(1e3);
        match region {
            Region::Elastic => assert!(f <= 1e-9 * scale, "elastic state outside: f = {f}"),
            Region::Apex => {
                let apex = m.apex();
                assert!((tau - Matrix3::identity() * apex).norm() <= 1e-9 * scale);
            }
            _ => assert!(f.abs() <= 1e-9 * scale, "{region:?}: f = {f}"),
        }
    }
    for r in ["Elastic", "Shear", "Edge", "Apex"] {
        assert!(
            regions.contains(r),
            "no trial state reached {r}: {regions:?}"
        );
    }
}

/// Triaxial compression of a cohesionless material: the trial `εᵗʳ = (a, a, b)` with
/// `a > b` returns to the compression edge `τ₁ = τ₂`, where `f = 0` gives
/// `τ₃/τ₁ = (1 + sin φ)/(1 − sin φ)`; triaxial extension `(a, b, b)` to the extension edge.
#[test]
fn mohr_coulomb_triaxial_edges_have_the_closed_form_ratio() {
    let m = mc(35.0, 5.0, 0.0);
    let ratio = (1.0 + 35f64.to_radians().sin()) / (1.0 - 35f64.to_radians().sin());
    let state = compressed(&m.lame, 150e3);
    for (df, edge) in [
        (
            triaxial_df(&Lame::from_young_poisson(YOUNG, POISSON), 150e3, 400e3),
            "compression",
        ),
        (
            triaxial_df(&Lame::from_young_poisson(YOUNG, POISSON), 150e3, -300e3),
            "extension",
        ),
    ] {
        let (tau, _, region) = m.return_map(&df, &state);
        assert_eq!(region, Region::Edge, "{edge}");
        let t = principal(&tau);
        // Major over minor compressive principal stress: 1e-12 relative (closed form).
        assert!(
            ((t[2] / t[0]) - ratio).abs() < 1e-12 * ratio,
            "{edge}: {t:?}"
        );
        // The two stresses of the edge are equal.
        let pair = if edge == "compression" {
            (t[0], t[1])
        } else {
            (t[1], t[2])
        };
        assert!((pair.0 - pair.1).abs() < 1e-9 * t[2].abs(), "{edge}: {t:?}");
    }
}

#[test]
fn mohr_coulomb_tangent_matches_central_differences_in_every_region() {
    let m = mc(30.0, 10.0, 10e3);
    let md = m.lift::<Dual64>();
    let state = compressed(&m.lame, 100e3);
    let sd = state.lift::<Dual64>();
    let d = matrix![0.3, 0.1, -0.2; 0.05, -0.4, 0.25; -0.1, 0.2, 0.15];
    let cases = [
        // Elastic: a small distortion.
        (
            matrix![1.0005, 0.0002, 0.0; 0.0, 0.9995, 0.0; 0.0, 0.0, 1.0],
            Region::Elastic,
        ),
        // Elastic at three equal trial strains: the divided differences come from the
        // Jacobian of the return (2μ off the diagonal).
        (Matrix3::identity() * 1.0002, Region::Elastic),
        // Main plane: three distinct principal strains.
        (
            matrix![1.01, 0.004, 0.0; 0.004, 1.0, 0.0; 0.0, 0.0, 0.98],
            Region::Shear,
        ),
        // Compression edge at repeated trial strains (a triaxial test, σ₂ = σ₃ exactly).
        (
            triaxial_df(&Lame::from_young_poisson(YOUNG, POISSON), 100e3, 400e3),
            Region::Edge,
        ),
        // Extension edge, also repeated.
        (
            triaxial_df(&Lame::from_young_poisson(YOUNG, POISSON), 100e3, -300e3),
            Region::Edge,
        ),
        // Apex: isotropic extension beyond c cot φ.
        (Matrix3::identity() * 1.02, Region::Apex),
    ];
    for (df, expected) in cases {
        let (_, _, region) = m.return_map(&df, &state);
        assert_eq!(region, expected, "ΔF = {df}");
        for dir in [d, Matrix3::identity(), d.transpose() + d] {
            check_tangent(
                |x| md.return_map(x, &sd).0,
                |x| m.return_map(x, &state).0,
                &df,
                &dir,
                &format!("{expected:?}"),
            );
        }
    }
}

/// `∂τ/∂φ`, `∂τ/∂c`, `∂τ/∂ψ` by a dual parameter against central differences, on the main
/// plane and on an edge (1e-6 relative, as for the tangent).
#[test]
fn mohr_coulomb_parameter_derivatives_match_central_differences() {
    let state = compressed(&Lame::from_young_poisson(YOUNG, POISSON), 100e3);
    for df in [
        matrix![1.01, 0.004, 0.0; 0.004, 1.0, 0.0; 0.0, 0.0, 0.98],
        triaxial_df(&Lame::from_young_poisson(YOUNG, POISSON), 100e3, 400e3),
    ] {
        for which in 0..3 {
            let with = |x: f64| {
                let mut p = [30f64.to_radians(), 10f64.to_radians(), 10e3];
                p[which] = x;
                (p, which)
            };
            let base = [30f64.to_radians(), 10f64.to_radians(), 10e3][which];
            let build = |p: [f64; 3]| MohrCoulomb {
                lame: Lame::from_young_poisson(YOUNG, POISSON),
                friction_angle: p[0],
                dilation_angle: p[1],
                cohesion: p[2],
                tension_cutoff: None,
            };
            let (p0, _) = with(base);
            let mut pd: [Dual64; 3] = p0.map(Dual64::from_re);
            pd[which] = Dual64::new(base, 1.0);
            let md = MohrCoulomb {
                lame: Lame::from_young_poisson(YOUNG, POISSON).lift::<Dual64>(),
                friction_angle: pd[0],
                dilation_angle: pd[1],
                cohesion: pd[2],
                tension_cutoff: None,
            };
            let dual = md
                .return_map(&df.map(Dual64::from_re), &state.lift())
                .0
                .map(|x| x.eps);
            let h = 1e-6 * base;
            let fd = (build(with(base + h).0).return_map(&df, &state).0
                - build(with(base - h).0).return_map(&df, &state).0)
                / (2.0 * h);
            assert!(
                (dual - fd).norm() <= 1e-6 * fd.norm().max(1.0),
                "parameter {which}: {dual} vs {fd}"
            );
        }
    }
}

#[test]
fn hencky_drucker_prager_tangent_matches_central_differences() {
    for cone in [Cone::PlaneStrain, Cone::Compression, Cone::Extension] {
        let m = dp_hencky(30.0, 5.0, 10e3, cone);
        let md = m.lift::<Dual64>();
        let state = compressed(&m.lame, 100e3);
        let sd = state.lift::<Dual64>();
        let d = matrix![0.3, 0.1, -0.2; 0.05, -0.4, 0.25; -0.1, 0.2, 0.15];
        for (df, expected) in [
            (
                matrix![1.0005, 0.0002, 0.0; 0.0, 0.9995, 0.0; 0.0, 0.0, 1.0],
                Region::Elastic,
            ),
            (
                triaxial_df(&Lame::from_young_poisson(YOUNG, POISSON), 100e3, 400e3),
                Region::Shear,
            ),
            (
                matrix![1.01, 0.004, 0.0; 0.004, 1.0, 0.0; 0.0, 0.0, 0.98],
                Region::Shear,
            ),
            (
                matrix![1.02, 0.001, 0.0; 0.0, 1.02, 0.0; 0.0, 0.0, 1.02],
                Region::Corner,
            ),
        ] {
            let (_, _, region) = m.hencky_return(&df, &state);
            assert_eq!(region, expected, "{cone:?}, ΔF = {df}");
            for dir in [d, Matrix3::identity()] {
                check_tangent(
                    |x| md.hencky_return(x, &sd).0,
                    |x| m.hencky_return(x, &state).0,
                    &df,
                    &dir,
                    &format!("{cone:?} {expected:?}"),
                );
            }
        }
    }
}

/// The compression cone is `q = M p′ + …` in triaxial compression with
/// `M = 6 sin φ/(3 − sin φ)`; the extension cone `M_e = 6 sin φ/(3 + sin φ)` in extension:
/// a cohesionless triaxial trial returns onto `q = M p′` (Kirchhoff invariants, 1e-12).
#[test]
fn drucker_prager_cones_touch_mohr_coulomb_on_their_meridians() {
    let phi: f64 = 35f64.to_radians();
    for (cone, df, m_slope) in [
        (
            Cone::Compression,
            triaxial_df(&Lame::from_young_poisson(YOUNG, POISSON), 150e3, 400e3),
            6.0 * phi.sin() / (3.0 - phi.sin()),
        ),
        (
            Cone::Extension,
            triaxial_df(&Lame::from_young_poisson(YOUNG, POISSON), 150e3, -300e3),
            6.0 * phi.sin() / (3.0 + phi.sin()),
        ),
    ] {
        let m = dp_hencky(35.0, 5.0, 0.0, cone);
        let (tau, _, region) = m.hencky_return(&df, &compressed(&m.lame, 150e3));
        assert_eq!(region, Region::Shear);
        let p = -tau.trace() / 3.0;
        let s = tau + Matrix3::identity() * p;
        let q = (1.5 * s.norm_squared()).sqrt();
        assert!(
            (q - m_slope * p).abs() < 1e-12 * q,
            "{cone:?}: q = {q}, M p = {}",
            m_slope * p
        );
        // And the Mohr–Coulomb function of the same (c, φ) is zero there too.
        let f = mc(35.0, 5.0, 0.0).yield_function(principal(&tau));
        assert!(f.abs() < 1e-9 * q, "{cone:?}: MC f = {f}");
    }
}

/// For strains of 1e-4 the Hencky and the Jaumann Drucker–Prager give the same Kirchhoff
/// stress to first order: they differ by terms of relative size `|ε|` ~ 1e-4 (`ln(1 + x)`
/// against `x`, and `J = det F` against 1), so 1e-3 relative is a tenfold margin.
#[test]
fn hencky_and_jaumann_drucker_prager_agree_at_small_strain() {
    let h = dp_hencky(30.0, 5.0, 10e3, Cone::PlaneStrain);
    let j = DruckerPrager {
        elasticity: Elasticity::Jaumann,
        ..h
    };
    let df = matrix![1.0001, 0.00003, 0.0; 0.00002, 0.99995, 0.0; 0.0, 0.0, 1.0];
    let (tau_h, _) = h.kirchhoff_update(&df, &df, &MaterialState::default());
    let (tau_j, _) = j.kirchhoff_update(&df, &df, &MaterialState::default());
    assert!(
        (tau_h - tau_j).norm() < 1e-3 * tau_h.norm(),
        "{tau_h} vs {tau_j}"
    );
}

/// c = 10 kPa, φ = 30°, ψ = 10° (apex c cot φ = 17.3 kPa) cut at σ_t = 5 kPa.
fn mc_cut() -> MohrCoulomb<f64> {
    MohrCoulomb {
        tension_cutoff: Some(5e3),
        ..mc(30.0, 10.0, 10e3)
    }
}

/// `ΔF = diag(exp ε)` from the stress-free state: the trial Hencky strains are `ε`.
fn stretch(eps: [f64; 3]) -> Matrix3<f64> {
    Matrix3::from_diagonal(&nalgebra::vector![eps[0].exp(), eps[1].exp(), eps[2].exp()])
}

/// Over random trial states around a low confinement, the cut pyramid's return never leaves
/// a principal stress above `σ_t` nor outside the pyramid, and every region is reached.
#[test]
fn mohr_coulomb_returns_respect_the_tension_cutoff() {
    let m = mc_cut();
    let cutoff = 5e3;
    let state = compressed(&m.lame, 5e3);
    let mut regions = std::collections::HashSet::new();
    for df in random_df(11, 4000, 0.004, 0.003) {
        let (tau, _, region) = m.return_map(&df, &state);
        regions.insert(format!("{region:?}"));
        let t = principal(&tau);
        // 1e-9 of the stress scale: round-off of the closed-form solves and the eigenbasis.
        let scale = tau.norm().max(1e3);
        assert!(t[0] <= cutoff + 1e-9 * scale, "{region:?}: {t:?}");
        let f = m.yield_function(t);
        assert!(f <= 1e-9 * scale, "{region:?}: f = {f}");
        if matches!(region, Region::Tension | Region::Corner) {
            assert!((t[0] - cutoff).abs() <= 1e-9 * scale, "{region:?}: {t:?}");
        }
        if region == Region::Corner {
            assert!(f.abs() <= 1e-9 * scale, "corner off the pyramid: f = {f}");
        }
    }
    for r in ["Elastic", "Shear", "Edge", "Tension", "Corner"] {
        assert!(
            regions.contains(r),
            "no trial state reached {r}: {regions:?}"
        );
    }
}

/// Uniaxial extension beyond the cutoff returns along `D e₁` to `τ₁ = σ_t`, which leaves the
/// lateral stresses at `λ/(λ + 2μ) σ_t = ν/(1 − ν) σ_t` (closed form, 1e-12 relative); two
/// and three equal stretches end at `τ₁ = τ₂ = σ_t` and at `σ_t I`.
#[test]
fn mohr_coulomb_cutoff_returns_have_the_closed_forms() {
    let m = mc_cut();
    let cutoff = 5e3;
    let state = MaterialState::default();
    let (tau, _, region) = m.return_map(&stretch([1e-3, 0.0, 0.0]), &state);
    assert_eq!(region, Region::Tension);
    let lateral = POISSON / (1.0 - POISSON) * cutoff;
    assert!((tau[(0, 0)] - cutoff).abs() < 1e-12 * cutoff, "{tau}");
    for i in 1..3 {
        assert!((tau[(i, i)] - lateral).abs() < 1e-12 * cutoff, "{tau}");
    }
    let (tau, _, region) = m.return_map(&stretch([1e-3, 0.9e-3, 0.0]), &state);
    assert_eq!(region, Region::Tension);
    assert!((tau[(0, 0)] - cutoff).abs() < 1e-12 * cutoff, "{tau}");
    assert!((tau[(1, 1)] - cutoff).abs() < 1e-12 * cutoff, "{tau}");
    assert!(tau[(2, 2)] < cutoff, "{tau}");
    let (tau, _, region) = m.return_map(&stretch([1e-3; 3]), &state);
    assert_eq!(region, Region::Tension);
    assert!(
        (tau - Matrix3::identity() * cutoff).norm() < 1e-12 * cutoff,
        "{tau}"
    );
    // Without a cutoff the same isotropic extension goes to the apex c cot φ.
    let (tau, _, region) = mc(30.0, 10.0, 10e3).return_map(&stretch([1e-3; 3]), &state);
    assert_eq!(region, Region::Apex);
    let apex = 10e3 / 30f64.to_radians().tan();
    assert!(
        (tau - Matrix3::identity() * apex).norm() < 1e-9 * apex,
        "{tau}"
    );
}

/// The dual tangent against central differences (as [`check_tangent`]) at one, two and three
/// active cutoffs and at a cutoff meeting the pyramid's main plane.
#[test]
fn mohr_coulomb_cutoff_tangent_matches_central_differences() {
    let m = mc_cut();
    let md = m.lift::<Dual64>();
    let state = MaterialState::default();
    let sd = state.lift::<Dual64>();
    let d = matrix![0.3, 0.1, -0.2; 0.05, -0.4, 0.25; -0.1, 0.2, 0.15];
    for (eps, expected) in [
        ([1e-3, 0.0, 0.0], Region::Tension),
        ([1e-3, 0.9e-3, 0.0], Region::Tension),
        ([1e-3; 3], Region::Tension),
        ([2e-3, 0.0, -1e-3], Region::Corner),
    ] {
        let df = stretch(eps);
        let (_, _, region) = m.return_map(&df, &state);
        assert_eq!(region, expected, "ε = {eps:?}");
        for dir in [d, Matrix3::identity(), d.transpose() + d] {
            check_tangent(
                |x| md.return_map(x, &sd).0,
                |x| m.return_map(x, &state).0,
                &df,
                &dir,
                &format!("{expected:?} at ε = {eps:?}"),
            );
        }
    }
}
