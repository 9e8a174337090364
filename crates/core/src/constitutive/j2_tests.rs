//! Physics checks of the J2 (von Mises) model in Hencky strain space.

use super::*;
use crate::spectral::{Log, symmetric_fn};
use nalgebra::{matrix, vector};
use num_dual::Dual64;

/// E = 10 MPa, ν = 0.3 (μ ≈ 3.85 MPa, λ ≈ 5.77 MPa), σ_y = 100 kPa: yield at a deviatoric
/// strain of order σ_y/(2μ) ≈ 1.3 %.
const YOUNG: f64 = 1.0e7;
const POISSON: f64 = 0.3;
const YIELD: f64 = 1.0e5;

fn j2(hardening: f64) -> J2<f64> {
    J2 {
        lame: Lame::from_young_poisson(YOUNG, POISSON),
        yield_stress: YIELD,
        hardening,
    }
}

fn dual_model(m: &J2<f64>) -> J2<Dual64> {
    J2 {
        lame: m.lame.lift(),
        yield_stress: Dual64::from_re(m.yield_stress),
        hardening: Dual64::from_re(m.hardening),
    }
}

fn dual_state(s: &MaterialState<f64>) -> MaterialState<Dual64> {
    s.lift()
}

fn deviator(t: &Matrix3<f64>) -> Matrix3<f64> {
    t - Matrix3::identity() * (t.trace() / 3.0)
}

/// A general 3D relative deformation gradient, about 10 % strain: far beyond yield.
fn delta_f_3d() -> Matrix3<f64> {
    matrix![1.08, 0.06, -0.03; -0.02, 0.95, 0.07; 0.04, -0.05, 1.03]
}

/// A plane-strain one (in-plane block, `ΔF_zz = 1`, no out-of-plane shear).
fn delta_f_2d() -> Matrix3<f64> {
    matrix![1.06, 0.09, 0.0; -0.03, 0.93, 0.0; 0.0, 0.0, 1.0]
}

/// A state left by a previous plastic step (non-identity `bₑ`, `ε̄ᵖ > 0`).
fn plastic_history(m: &J2<f64>) -> MaterialState<f64> {
    let first = matrix![0.96, -0.04, 0.02; 0.05, 1.07, -0.03; -0.01, 0.03, 0.98];
    let (_, state) = m.kirchhoff_update(&first, &MaterialState::default());
    assert!(state.plastic_strain > 0.0);
    state
}

/// Below yield the model is Hencky elasticity, with `bₑ = F Fᵀ` the total left
/// Cauchy–Green tensor and no plastic strain. One step from the reference state runs the same
/// arithmetic as [`Hencky`] (`ΔF I ΔFᵀ = F Fᵀ`), so the stresses agree to round-off (1e-15
/// relative); ten increments along a straight path reach the same `F` through
/// `bₑ = ΔF bₑⁿ ΔFᵀ` and agree to accumulated round-off (1e-12).
#[test]
fn elastic_range_is_hencky() {
    let m = j2(1.0e6);
    let hencky = Hencky { lame: m.lame };
    // 0.2 % strain: ‖dev τ‖ ≈ 2μ·0.003 ≈ 2e4 Pa < √(2/3) σ_y ≈ 8.2e4 Pa.
    let f = Matrix3::identity() + (delta_f_3d() - Matrix3::identity()) * 0.02;
    let (tau, state) = m.kirchhoff_update(&f, &MaterialState::default());
    let tau_h = hencky.kirchhoff_stress(&f);
    assert!(deviator(&tau).norm() < 0.5 * (2.0f64 / 3.0).sqrt() * YIELD);
    assert!(
        (tau - tau_h).norm() <= 1e-15 * tau_h.norm(),
        "{tau} vs {tau_h}"
    );
    assert_eq!(state.plastic_strain, 0.0);

    let mut state = MaterialState::default();
    let mut f_prev = Matrix3::identity();
    let mut tau = Matrix3::zeros();
    for k in 1..=10 {
        let fk = Matrix3::identity() + (f - Matrix3::identity()) * (k as f64 / 10.0);
        let delta = fk * f_prev.try_inverse().expect("F is invertible");
        let (t, s) = m.kirchhoff_update(&delta, &state);
        (tau, state, f_prev) = (t, s, fk);
    }
    assert!((tau - tau_h).norm() <= 1e-12 * tau_h.norm());
    assert!((state.tensor - f * f.transpose()).norm() <= 1e-14);
    assert_eq!(state.plastic_strain, 0.0);
    let mat = Material::j2(YOUNG, POISSON, YIELD, 1.0e6, 2000.0);
    let psi = mat.energy_density(&f, &state);
    let psi_h = hencky.energy_density(&f);
    assert!((psi - psi_h).abs() <= 1e-12 * psi_h, "ψ = {psi} vs {psi_h}");

    // `Material::elastic(ModelKind::J2, ..)` never yields: Hencky even at 10 % strain.
    let never = Material::elastic(ModelKind::J2, YOUNG, POISSON, 2000.0);
    let big = delta_f_3d();
    let (tau, state) = never.kirchhoff_update(&big, &big, &MaterialState::default());
    let tau_h = hencky.kirchhoff_stress(&big);
    assert!((tau - tau_h).norm() <= 1e-15 * tau_h.norm());
    assert_eq!(state.plastic_strain, 0.0);
    // The infinite yield stress leaves no NaN in the dual (tangent) path.
    let big_d = Matrix3::from_fn(|a, b| Dual64::new(big[(a, b)], if a == b { 1.0 } else { 0.0 }));
    let (tau_d, state_d) =
        never
            .lift::<Dual64>()
            .kirchhoff_update(&big_d, &big_d, &MaterialState::default());
    assert!(
        tau_d
            .iter()
            .chain(&state_d.tensor)
            .all(|x| x.is_finite_all())
    );
}

/// The first Newton iterate of an implicit step evaluates `ΔF = I` from the reference state,
/// where `dev τ = 0` and `‖s‖` has no derivative: the dual tangent must still be finite and
/// be the Hencky (small-strain) one, `∂τ/∂ΔF_ij = μ(e_i e_jᵀ + e_j e_iᵀ) + λ δ_ij I`, exact.
#[test]
fn tangent_at_the_reference_state_is_the_elastic_one() {
    let m = dual_model(&j2(0.0));
    let (mu, lambda) = (m.lame.mu.re, m.lame.lambda.re);
    for i in 0..3 {
        for j in 0..3 {
            let seed = Matrix3::from_fn(|a, b| if (a, b) == (i, j) { 1.0 } else { 0.0 });
            let df =
                Matrix3::from_fn(|a, b| Dual64::new(if a == b { 1.0 } else { 0.0 }, seed[(a, b)]));
            let (tau, state) = m.kirchhoff_update(&df, &MaterialState::default());
            let expected =
                (seed + seed.transpose()) * mu + Matrix3::identity() * (lambda * seed.trace());
            let got = tau.map(|x| x.eps);
            assert!(tau.iter().chain(&state.tensor).all(|x| x.is_finite_all()));
            assert!(
                (got - expected).norm() <= 1e-15 * expected.norm(),
                "({i},{j}): {got}"
            );
            assert_eq!(state.plastic_strain.re, 0.0);
        }
    }
}

/// A plastic case of the return-mapping tests: (name, model, ΔF, state at the start).
type Case = (&'static str, J2<f64>, Matrix3<f64>, MaterialState<f64>);

/// Plastic steps in 3D and plane strain, from the reference state and after plastic flow,
/// for H = 0 and H > 0.
fn plastic_cases() -> Vec<Case> {
    let mut cases = Vec::new();
    for h in [0.0, 2.0e6] {
        let m = j2(h);
        let history = plastic_history(&m);
        // Uniaxial stretch: the trial strain has a repeated principal pair.
        let uniaxial = Matrix3::from_diagonal(&vector![1.0, 1.0, 0.92]);
        cases.push(("3D from I", m, delta_f_3d(), MaterialState::default()));
        cases.push(("3D after a plastic step", m, delta_f_3d(), history));
        cases.push(("3D uniaxial", m, uniaxial, MaterialState::default()));
        cases.push((
            "plane strain from I",
            m,
            delta_f_2d(),
            MaterialState::default(),
        ));
        cases.push((
            "plane strain after a plastic step",
            m,
            delta_f_2d(),
            history,
        ));
    }
    cases
}

/// After a plastic step the stress lies on the updated yield surface,
/// `‖dev τ‖ = √(2/3)(σ_y + H ε̄ᵖ)`: with `Δγ = f/(2μ + ⅔H)` the residual is
/// `f − (2μ + ⅔H)Δγ = 0` exactly, so only round-off of `‖τ‖ ≈ 1e6 Pa` remains (1e-9 Pa, i.e.
/// 1e-14 relative to σ_y). The returned `τ` is also the Hencky stress of the stored `bₑ`
/// (through `exp` then `ln`: 1e-12 relative).
#[test]
fn plastic_step_ends_on_the_yield_surface() {
    for (name, m, df, state) in plastic_cases() {
        let (tau, new) = m.kirchhoff_update(&df, &state);
        assert!(
            new.plastic_strain > state.plastic_strain,
            "{name}: no yield"
        );
        let radius = (2.0f64 / 3.0).sqrt() * (m.yield_stress + m.hardening * new.plastic_strain);
        let s = deviator(&tau).norm();
        assert!(
            (s - radius).abs() <= 1e-9,
            "{name}, H = {}: ‖dev τ‖ = {s}, radius {radius}",
            m.hardening
        );
        let tau_of_be = m.lame.stress(&(symmetric_fn(&new.tensor, &Log) * 0.5));
        assert!((tau - tau_of_be).norm() <= 1e-12 * tau.norm(), "{name}");
    }
}

/// The return is deviatoric (`tr n = 0`), so `det bₑ = exp(2 tr ε)` and the pressure are
/// those of the trial state: plastic flow is isochoric. Round-off of the eigen-decomposition
/// and of `exp` (a few 1e-15 relative, observed ≤ 3e-15): 1e-13 relative.
#[test]
fn plastic_return_is_isochoric() {
    for (name, m, df, state) in plastic_cases() {
        let (tau, new) = m.kirchhoff_update(&df, &state);
        let b_trial = df * state.tensor * df.transpose();
        let (det_new, det_trial) = (new.tensor.determinant(), b_trial.determinant());
        assert!(
            (det_new - det_trial).abs() <= 1e-13 * det_trial,
            "{name}: det bₑ = {det_new}, det bₑᵗʳ = {det_trial}"
        );
        let tau_trial = m.lame.stress(&(symmetric_fn(&b_trial, &Log) * 0.5));
        assert!((tau.trace() - tau_trial.trace()).abs() <= 1e-13 * tau.norm());
    }
}

/// Every output of one step (τ, `bₑ`, `ε̄ᵖ`) as one vector, for derivative checks.
fn outputs(tau: &Matrix3<f64>, s: &MaterialState<f64>) -> Vec<f64> {
    let mut v: Vec<f64> = tau.iter().copied().collect();
    v.extend(s.tensor.iter());
    v.push(s.plastic_strain);
    v
}

/// The consistent tangent: seeding `ΔF_ij` with a Dual64 gives `∂τ/∂ΔF_ij`, `∂bₑ/∂ΔF_ij` and
/// `∂ε̄ᵖ/∂ΔF_ij` of the algorithm, to compare with central differences of the `f64` update.
/// Step 1e-6 on entries of order 1: truncation `h²/6 · ∂³τ ≈ 1e-12 · 1e8 Pa` and the
/// round-off of the eigen-solver `≈ 1e-14 · |τ| / h ≈ 1e-2 Pa`, against tangent entries of
/// order 1e7 Pa: about 1e-9 relative (observed ≤ 6e-9), so 1e-6 relative to the largest
/// entry of each output block leaves two orders of margin. Every case is
/// plastic with the trial state well outside the surface (`f ≈ σ_y ≫ h · ∂f/∂ΔF`), so the
/// differences do not straddle the yield kink. Plane-strain cases seed the in-plane entries
/// only (`ΔF_zz = 1`, no out-of-plane shear).
#[test]
fn consistent_tangent_matches_finite_differences() {
    let h = 1e-6;
    for (name, m, df, state) in plastic_cases() {
        let md = dual_model(&m);
        let sd = dual_state(&state);
        let plane = name.starts_with("plane");
        let n = if plane { 2 } else { 3 };
        for i in 0..n {
            for j in 0..n {
                let seed = Matrix3::from_fn(|a, b| if (a, b) == (i, j) { 1.0 } else { 0.0 });
                let dfd = Matrix3::from_fn(|a, b| Dual64::new(df[(a, b)], seed[(a, b)]));
                let (tau_d, state_d) = md.kirchhoff_update(&dfd, &sd);
                let dual: Vec<f64> = {
                    let mut v: Vec<f64> = tau_d.iter().map(|x| x.eps).collect();
                    v.extend(state_d.tensor.iter().map(|x| x.eps));
                    v.push(state_d.plastic_strain.eps);
                    v
                };
                let (tp, sp) = m.kirchhoff_update(&(df + seed * h), &state);
                let (tm, sm) = m.kirchhoff_update(&(df - seed * h), &state);
                assert!(sp.plastic_strain > state.plastic_strain);
                assert!(sm.plastic_strain > state.plastic_strain);
                let fd: Vec<f64> = outputs(&tp, &sp)
                    .iter()
                    .zip(outputs(&tm, &sm))
                    .map(|(p, q)| (p - q) / (2.0 * h))
                    .collect();
                // Blocks: τ (9), bₑ (9), ε̄ᵖ (1), each against its own scale.
                for range in [0..9, 9..18, 18..19] {
                    let scale = dual[range.clone()]
                        .iter()
                        .chain(&fd[range.clone()])
                        .fold(0.0f64, |a, x| a.max(x.abs()));
                    for k in range {
                        assert!(dual[k].is_finite(), "{name}: NaN tangent");
                        assert!(
                            (dual[k] - fd[k]).abs() <= 1e-6 * scale,
                            "{name}, H = {}, seed ({i},{j}), output {k}: dual {} vs fd {}",
                            m.hardening,
                            dual[k],
                            fd[k]
                        );
                    }
                }
            }
        }
    }
}

/// Parameters are differentiable too: with `Δγ = (‖s‖ − √(2/3)(σ_y + H ε̄ᵖⁿ))/(2μ + ⅔H)`,
/// `∂τ/∂σ_y = 2μ √(2/3) n / (2μ + ⅔H)` (`n` fixed by the trial state), exact to round-off
/// (1e-12 relative).
#[test]
fn yield_stress_derivative_is_the_flow_direction() {
    for (name, m, df, state) in plastic_cases() {
        let mut md = dual_model(&m);
        md.yield_stress = Dual64::new(m.yield_stress, 1.0);
        let dfd = df.map(Dual64::from_re);
        let (tau_d, _) = md.kirchhoff_update(&dfd, &dual_state(&state));
        let b_trial = df * state.tensor * df.transpose();
        let s = deviator(&m.lame.stress(&(symmetric_fn(&b_trial, &Log) * 0.5)));
        let two_mu = 2.0 * m.lame.mu;
        let expected =
            s / s.norm() * (two_mu * (2.0f64 / 3.0).sqrt()) / (two_mu + 2.0 / 3.0 * m.hardening);
        let got = tau_d.map(|x| x.eps);
        assert!(
            (got - expected).norm() <= 1e-12 * expected.norm(),
            "{name}: {got} vs {expected}"
        );
    }
}

/// Uniaxial strain (oedometric compression), `ΔF = diag(1, e^{Δε}, 1)` in small increments,
/// ν = 0 (λ = 0), so the axes are fixed and every log strain is additive: ε = diag(0, ε, 0).
///
/// - Elastic: `τ = 2μ ε`, so `τ_yy = 2μ ε`, `τ_xx = τ_zz = 0`; `dev ε = ε/3 diag(−1, 2, −1)`
///   gives `‖dev τ‖ = 2μ|ε|√(2/3)`, and yield starts at `‖dev τ‖ = √(2/3)σ_y`, i.e.
///   `|τ_yy − τ_xx| = 2μ|ε| = σ_y`, `|ε_Y| = σ_y/(2μ)`.
/// - Plastic: the flow direction is `n = ∓diag(−1, 2, −1)/√6` (the sign of ε), fixed, so the
///   radial return is exact for any increment size. The flow is deviatoric, hence
///   `tr εᵉ = tr ε = ε` and `tr τ = (3λ + 2μ) ε = 2μ ε`. On the surface
///   `‖dev τ‖ = √(2/3)(σ_y + H ε̄ᵖ)` with `dev τ ∥ n`, so `|τ_yy − τ_xx| = σ_y + H ε̄ᵖ`.
///   With `εᵖ = ε̄ᵖ diag(−½, 1, −½)` (sign of ε), `τ_yy − τ_xx = 2μ(εᵉ_yy − εᵉ_xx) =
///   2μ(|ε| − (3/2)ε̄ᵖ)` in magnitude; equating gives `ε̄ᵖ = (2μ|ε| − σ_y)/(3μ + H)` (for
///   H = 0, `ε̄ᵖ = ⅔(|ε| − ε_Y)`). Then `τ_xx = τ_zz = (tr τ − |τ_yy − τ_xx| sgn ε)/3`.
///
/// 170 increments of −3e-4 reach ε = −5.1 % (yield at −1 %, step 34 is the first plastic
/// one); the closed forms hold to the round-off accumulated over the steps (observed
/// ≤ 5e-13 relative to σ_y; asserted 1e-11, i.e. 1e-6 Pa).
#[test]
fn uniaxial_strain_follows_the_closed_form() {
    let (young, de, steps) = (1.0e7, -3.0e-4f64, 170);
    for hardening in [0.0, 2.0e6] {
        let m = J2 {
            lame: Lame::from_young_poisson(young, 0.0),
            yield_stress: YIELD,
            hardening,
        };
        let mu = m.lame.mu;
        let eps_y = YIELD / (2.0 * mu);
        let df = Matrix3::from_diagonal(&vector![1.0, de.exp(), 1.0]);
        let mut state = MaterialState::default();
        let mut first_plastic = None;
        let tol = 1e-11 * YIELD;
        for k in 1..=steps {
            let eps = k as f64 * de;
            let (tau, new) = m.kirchhoff_update(&df, &state);
            state = new;
            let off_diagonal = tau.norm_squared() - tau.diagonal().norm_squared();
            assert!(off_diagonal.abs() <= tol * tol);
            assert!((tau[(0, 0)] - tau[(2, 2)]).abs() <= tol);
            assert!(
                (tau.trace() - 2.0 * mu * eps).abs() <= tol,
                "step {k}: tr τ"
            );
            if state.plastic_strain > 0.0 && first_plastic.is_none() {
                first_plastic = Some(k);
            }
            if eps.abs() < eps_y {
                assert_eq!(state.plastic_strain, 0.0, "step {k}: early yield");
                assert!((tau[(1, 1)] - 2.0 * mu * eps).abs() <= tol);
                assert!(tau[(0, 0)].abs() <= tol);
            } else {
                let ep = (2.0 * mu * eps.abs() - YIELD) / (3.0 * mu + hardening);
                assert!(
                    (state.plastic_strain - ep).abs() <= 1e-11 * ep.max(eps_y),
                    "step {k}: ε̄ᵖ = {} vs {ep}",
                    state.plastic_strain
                );
                let diff = tau[(1, 1)] - tau[(0, 0)];
                let strength = YIELD + hardening * ep;
                assert!(
                    (diff + strength).abs() <= tol,
                    "step {k}, H = {hardening}: τ_yy − τ_xx = {diff}, expected −{strength}"
                );
            }
        }
        assert_eq!(first_plastic, Some(34));
    }
}

/// Objectivity of the update: a rotation superposed on the step, `ΔF → R ΔF`, rotates the
/// trial `bₑ` and hence `τ` and `bₑ` (`R · Rᵀ`) and leaves `ε̄ᵖ` unchanged; the Cauchy stress
/// too, since `det(R F) = det F`. Round-off: 1e-12 relative.
#[test]
fn plastic_update_is_objective() {
    let r = nalgebra::Rotation3::from_euler_angles(0.7, -0.4, 1.9).into_inner();
    for (name, m, df, state) in plastic_cases() {
        let (tau, new) = m.kirchhoff_update(&df, &state);
        let (tau_r, new_r) = m.kirchhoff_update(&(r * df), &state);
        assert!(new.plastic_strain > state.plastic_strain, "{name}");
        assert!(
            (tau_r - r * tau * r.transpose()).norm() <= 1e-12 * tau.norm(),
            "{name}"
        );
        let be = r * new.tensor * r.transpose();
        assert!((new_r.tensor - be).norm() <= 1e-12 * be.norm(), "{name}");
        assert!((new_r.plastic_strain - new.plastic_strain).abs() <= 1e-12 * new.plastic_strain);

        let f = df * 1.01;
        let stress = |delta_f: &Matrix3<f64>, f: &Matrix3<f64>| {
            let mut s = state;
            let kin = Kinematics {
                f,
                delta_f,
                velocity_gradient: &Matrix3::zeros(),
                dt: 1.0,
                stress: &Matrix3::zeros(),
            };
            m.update(&kin, &mut s)
        };
        let sigma = stress(&df, &f);
        let sigma_r = stress(&(r * df), &(r * f));
        assert!((sigma_r - r * sigma * r.transpose()).norm() <= 1e-12 * sigma.norm());
    }
}

/// `Material` dispatch: `update` commits what `kirchhoff_update` returns and gives
/// `σ = τ / det F`; hyperelastic models take `τ(F)` of the total `F` and keep the state; the
/// J2 wave speed uses the elastic `λ + 2μ`. Same arithmetic on both paths (1e-15 relative).
#[test]
fn material_dispatch_of_j2() {
    let mat = Material::j2(YOUNG, POISSON, YIELD, 0.0, 2000.0);
    let df = delta_f_3d();
    let f = df * matrix![1.01, 0.0, 0.0; 0.02, 0.99, 0.0; 0.0, 0.0, 1.0];
    let start = MaterialState::default();
    let (tau, pure) = mat.kirchhoff_update(&df, &f, &start);
    let mut state = start;
    let kin = Kinematics {
        f: &f,
        delta_f: &df,
        velocity_gradient: &Matrix3::zeros(),
        dt: 1.0,
        stress: &Matrix3::zeros(),
    };
    let sigma = mat.update(&kin, &mut state);
    assert_eq!(state, pure);
    assert!(state.plastic_strain > 0.0);
    assert!((sigma * f.determinant() - tau).norm() <= 1e-15 * tau.norm());
    let lame = Lame::from_young_poisson(YOUNG, POISSON);
    assert!((mat.wave_speed() - (lame.p_wave_modulus() / 2000.0).sqrt()).abs() <= 1e-12);

    let elastic = Material::elastic(ModelKind::Hencky, YOUNG, POISSON, 2000.0);
    let (tau_h, kept) = elastic.kirchhoff_update(&df, &f, &pure);
    assert_eq!(kept, pure);
    assert_eq!(tau_h, Hencky { lame }.kirchhoff_stress(&f));
    assert_eq!(
        elastic.energy_density(&f, &pure),
        Hencky { lame }.energy_density(&f)
    );
}

/// The state rebuilt from the stress is the state the return mapping left, after an elastic
/// and after a plastic step: `bₑ = exp(2 C⁻¹:τ)` inverts `τ = C:(½ ln bₑ)`. Tolerance: the
/// round trip through two eigen-decompositions (`ln`, then `exp`) in f64, 1e-12 of ‖bₑ‖.
#[test]
fn the_state_rebuilt_from_the_stress_is_the_returned_state() {
    let m = j2(2.0e5);
    for (delta_f, what) in [(delta_f_3d(), "3D"), (delta_f_2d(), "2D")] {
        for (start, region) in [
            (MaterialState::default(), "from rest"),
            (plastic_history(&m), "plastic history"),
        ] {
            let (tau, state, _) = m.return_map(&delta_f, &start);
            let rebuilt = m.elastic_left_cauchy_green(&tau);
            let err = (rebuilt - state.tensor).norm() / state.tensor.norm();
            assert!(err < 1e-12, "{what}, {region}: relative error {err:e}");
        }
    }
    // The stress of the rebuilt state is the stress it was rebuilt from.
    let tau = m
        .lame
        .stress(&matrix![0.01, 0.002, 0.0; 0.002, -0.004, 0.001; 0.0, 0.001, 0.003]);
    let eps = symmetric_fn(&m.elastic_left_cauchy_green(&tau), &Log) * 0.5;
    assert!((m.lame.stress(&eps) - tau).norm() < 1e-9 * tau.norm());
}
