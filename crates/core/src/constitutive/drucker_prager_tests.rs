//! Checks of the Drucker–Prager model: elasticity, consistency of the return mapping in all
//! its regions, the flow rule, objectivity of the Jaumann update, triaxial and plane-strain
//! closed forms, and the derivative with respect to the friction angle.

use super::*;
use nalgebra::{matrix, vector};
use num_dual::Dual64;

/// E = 10 MPa, ν = 0.3 (μ ≈ 3.85 MPa, K ≈ 8.33 MPa): a loose-to-medium sand. With
/// c = 5 kPa and confinements of ~100 kPa, yield is reached at strains of order 1e-2.
const YOUNG: f64 = 1.0e7;
const POISSON: f64 = 0.3;
const COHESION: f64 = 5.0e3;

fn dp(phi_deg: f64, psi_deg: f64, cohesion: f64, cutoff: Option<f64>) -> DruckerPrager<f64> {
    DruckerPrager {
        lame: Lame::from_young_poisson(YOUNG, POISSON),
        friction_angle: phi_deg.to_radians(),
        dilation_angle: psi_deg.to_radians(),
        cohesion,
        tension_cutoff: cutoff,
        cone: Cone::PlaneStrain,
        elasticity: Elasticity::Jaumann,
    }
}

/// Deterministic pseudo-random numbers in [0, 1) (a tiny LCG keeps the test self-contained).
fn rng(seed: &mut u64) -> f64 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

/// A random velocity-gradient increment `Δt L` with entries in `±scale` plus `bias · I`; in
/// plane strain (`dim = 2`) the out-of-plane row and column are zero.
fn random_dl(seed: &mut u64, dim: usize, scale: f64, bias: f64) -> Matrix3<f64> {
    let mut dl = Matrix3::from_fn(|_, _| 0.0);
    for i in 0..dim {
        for j in 0..dim {
            dl[(i, j)] = scale * (2.0 * rng(seed) - 1.0);
        }
        dl[(i, i)] += bias;
    }
    dl
}

fn state_of(m: &DruckerPrager<f64>, sigma: &Matrix3<f64>) -> MaterialState<f64> {
    MaterialState {
        plastic_strain: 0.0,
        tensor: Matrix3::identity() + m.compliance(sigma) * 2.0,
        hardening: 0.0,
    }
}

fn mean(s: &Matrix3<f64>) -> f64 {
    s.trace() / 3.0
}

fn deviator(s: &Matrix3<f64>) -> Matrix3<f64> {
    s - Matrix3::identity() * mean(s)
}

/// The invariants `I₁`, `J₂`, `J₃ = det s`.
fn invariants(s: &Matrix3<f64>) -> [f64; 3] {
    let d = deviator(s);
    [s.trace(), 0.5 * d.norm_squared(), d.determinant()]
}

/// (1) Below yield one step is the linear law `σ = λ tr(ε) I + 2μ ε` on `ε = Δt D` (the spin
/// of the first step rotates a zero stress), several steps without spin add up linearly, and
/// the state carries `I + 2ε` with the energy `½ σ:ε` per current volume. The stresses here
/// are ~10 Pa, far below `c = 5 kPa`; the comparisons are round-off (1e-12 relative).
#[test]
fn small_strains_follow_the_linear_law() {
    let m = dp(30.0, 10.0, COHESION, None);
    let lin = LinearElastic { lame: m.lame };
    let mut seed = 7;
    for dim in [2, 3] {
        let dl = random_dl(&mut seed, dim, 1e-6, 0.0);
        let eps = (dl + dl.transpose()) * 0.5;
        let expected = m.lame.stress(&eps);
        let (sigma, state, region) = m.stress_update(&Matrix3::zeros(), &dl, &Default::default());
        assert_eq!(region, Region::Elastic);
        assert!(
            (sigma - expected).norm() < 1e-12 * expected.norm(),
            "{dim}D"
        );
        // The same as `LinearElastic` on F = I + Δt L, whose ε = sym(F) − I loses ~6 digits
        // to cancellation at strains of 1e-6 (hence 1e-8 relative).
        let linear = lin.small_strain_stress(&(Matrix3::identity() + dl));
        assert!((sigma - linear).norm() < 1e-8 * linear.norm(), "{dim}D");
        if dim == 2 {
            // Plane strain: σ_zz = λ tr ε, no out-of-plane shear.
            assert!((sigma[(2, 2)] - m.lame.lambda * eps.trace()).abs() < 1e-12 * sigma.norm());
            assert_eq!((sigma[(0, 2)], sigma[(1, 2)]), (0.0, 0.0));
        }
        assert_eq!(state.plastic_strain, 0.0);
        assert!((state.tensor - (Matrix3::identity() + eps * 2.0)).norm() < 1e-18);
        let f = Matrix3::identity() + dl;
        let energy = 0.5 * sigma.component_mul(&eps).sum() * f.determinant();
        // The state stores I + 2ε, so ε ~ 1e-6 comes back with an absolute round-off of
        // ~1e-16, i.e. 1e-10 relative: 1e-9.
        assert!((m.stored_energy(&f, &state) - energy).abs() < 1e-9 * energy);

        // Ten symmetric increments: hypoelasticity without spin is linear in the strain.
        let d = (dl + dl.transpose()) * 0.5;
        let mut s = Matrix3::zeros();
        let mut st = MaterialState::default();
        for _ in 0..10 {
            let (s1, st1, r) = m.stress_update(&s, &d, &st);
            assert_eq!(r, Region::Elastic);
            (s, st) = (s1, st1);
        }
        let expected = m.lame.stress(&(d * 10.0));
        assert!((s - expected).norm() < 1e-12 * expected.norm());
        assert_eq!(st.plastic_strain, 0.0);
    }
}

/// The Hughes–Winget rotation is the forward-Euler Jaumann trial of the brief,
/// `σₙ + Δt (Wσₙ − σₙW) + Δt C:D`, up to `O(Δt²)`: halving `Δt L` quarters the difference.
#[test]
fn trial_stress_is_the_jaumann_rate_to_first_order() {
    let m = dp(30.0, 0.0, COHESION, None);
    let sigma = matrix![-1.2e5, 2.0e4, -1.0e4; 2.0e4, -0.8e5, 5.0e3; -1.0e4, 5.0e3, -1.0e5];
    let l = matrix![0.3, 1.0, -0.4; -0.7, 0.1, 0.9; 0.5, -0.6, -0.2];
    let diff = |dt: f64| {
        let dl = l * dt;
        let w = (dl - dl.transpose()) * 0.5;
        let d = (dl + dl.transpose()) * 0.5;
        let euler = sigma + (w * sigma - sigma * w) + m.lame.stress(&d);
        (m.trial_stress(&sigma, &dl) - euler).norm()
    };
    let (e1, e2) = (diff(1e-3), diff(5e-4));
    // |σ| |W|² Δt² ~ 1e5 · 1 · 1e-6 = 0.1 Pa at Δt = 1e-3.
    assert!(e1 < 1.0, "{e1}");
    let ratio = e1 / e2;
    assert!(
        (ratio - 4.0).abs() < 0.05,
        "second-order difference: ratio {ratio}"
    );
}

/// Checks one update against the consistency conditions; returns the region.
fn check_step(
    m: &DruckerPrager<f64>,
    sigma_n: &Matrix3<f64>,
    dl: &Matrix3<f64>,
    state: &MaterialState<f64>,
) -> (Matrix3<f64>, MaterialState<f64>, Region) {
    let (sigma, new_state, region) = m.stress_update(sigma_n, dl, state);
    let trial = m.trial_stress(sigma_n, dl);
    let (alpha, k) = (m.alpha(), m.k());
    let (sigma_t, _) = m.corner();
    let f = m.yield_function(&sigma);
    let p = mean(&sigma);
    // Round-off scale of f: its three terms (|σ| ~ 1e5 Pa, so 1e-10 of it is 1e-5 Pa, far
    // above the ~1e-11 Pa round-off of the closed-form return and far below any real error).
    let scale = k + alpha * sigma.trace().abs() + deviator(&sigma).norm() + sigma_t.abs();
    let tol = 1e-10 * scale.max(1.0);
    assert!(f <= tol, "{region:?}: f = {f:e} > 0");
    assert!(
        p - sigma_t <= tol,
        "{region:?}: p = {p:e} > σ_t = {sigma_t:e}"
    );
    match region {
        Region::Elastic => {
            assert_eq!(sigma, trial);
            assert_eq!(new_state.plastic_strain, state.plastic_strain);
        }
        Region::Shear => assert!(f.abs() <= tol, "shear: |f| = {f:e}"),
        Region::Tension => assert!((p - sigma_t).abs() <= tol, "tension: p − σ_t"),
        Region::Corner => {
            assert!(f.abs() <= tol, "corner: |f| = {f:e}");
            assert!((p - sigma_t).abs() <= tol, "corner: p − σ_t");
        }
        Region::Edge | Region::Apex => panic!("{region:?} is a Mohr–Coulomb region"),
    }
    if region != Region::Elastic {
        // The trial was outside: f(σᵗʳ) > 0 or pᵗʳ > σ_t.
        assert!(m.yield_function(&trial) > 0.0 || mean(&trial) > sigma_t);
        let deps_p = m.compliance(&(trial - sigma));
        let inc = new_state.plastic_strain - state.plastic_strain;
        assert!((inc - (2.0f64 / 3.0).sqrt() * deps_p.norm()).abs() <= 1e-12 * inc);
        assert!(inc > 0.0);
    }
    assert!((sigma - sigma.transpose()).norm() <= 1e-12 * sigma.norm());
    assert!((new_state.tensor - (Matrix3::identity() + m.compliance(&sigma) * 2.0)).norm() < 1e-15);
    (sigma, new_state, region)
}

/// (2) Random walks of strain increments, 2D and 3D, with and without cohesion, with the
/// cutoff at the apex and below it, associated and not: after every plastic step the stress
/// is on the yield surface (|f| ≤ 1e-10 of the size of its terms) and within the cutoff, and
/// every region of the return is visited.
#[test]
fn plastic_steps_end_on_the_yield_surface_and_within_the_cutoff() {
    let models = [
        dp(30.0, 0.0, COHESION, None),
        dp(30.0, 30.0, COHESION, None),
        dp(35.0, 10.0, COHESION, Some(2.0e3)),
        dp(25.0, 25.0, COHESION, Some(0.0)),
        dp(40.0, 5.0, 0.0, None),
        dp(20.0, 20.0, 2.0e4, Some(1.0e6)), // cutoff above the apex acts as the apex
    ];
    let mut seed = 12345;
    let mut visits = [0usize; 4];
    for m in &models {
        for dim in [2, 3] {
            for walk in 0..20 {
                // Some walks drift into compression, some into extension (the apex / cutoff).
                let (scale, bias) =
                    [(2e-3, -2e-4), (2e-3, 0.0), (2e-3, 3e-4), (2e-4, 1e-3)][walk % 4];
                let mut sigma = Matrix3::identity() * -5.0e4;
                let mut state = state_of(m, &sigma);
                for _ in 0..60 {
                    let dl = random_dl(&mut seed, dim, scale, bias);
                    let (s, st, region) = check_step(m, &sigma, &dl, &state);
                    visits[region as usize] += 1;
                    if dim == 2 {
                        assert_eq!((s[(0, 2)], s[(1, 2)]), (0.0, 0.0), "plane strain");
                    }
                    (sigma, state) = (s, st);
                }
            }
        }
    }
    assert!(
        visits.iter().all(|&n| n > 100),
        "elastic, shear, tension, corner visits: {visits:?}"
    );
}

/// The regions of the return meet continuously: trial states on either side of each region
/// boundary return to nearby stresses (the split of the module docs is exhaustive and
/// consistent). Checked along a line of trials sweeping the mean stress at fixed deviator.
#[test]
fn return_is_continuous_across_regions() {
    let m = dp(30.0, 15.0, COHESION, Some(3.0e3));
    let n = matrix![1.0, 0.3, 0.0; 0.3, -0.5, 0.2; 0.0, 0.2, -0.5];
    let n = deviator(&n) / deviator(&n).norm();
    for q_scale in [1.0e3, 5.0e3, 2.0e4] {
        let mut last: Option<(Matrix3<f64>, Region)> = None;
        let mut seen = Vec::new();
        for i in 0..=4000 {
            let p = -8.0e4 + 40.0 * i as f64;
            let trial = n * q_scale + Matrix3::identity() * p;
            let (s, _, region) = m.return_map(&trial, &state_of(&m, &Matrix3::zeros()));
            if let Some((s0, _)) = last {
                // The trial moved by 40 Pa; a continuous (Lipschitz) return moves less than a
                // few times that.
                assert!((s - s0).norm() < 200.0, "jump at p = {p}: {region:?}");
            }
            if !seen.contains(&region) {
                seen.push(region);
            }
            last = Some((s, region));
        }
        assert!(seen.len() >= 2, "{seen:?}");
    }
}

/// (3) The flow rule: in the shear region `Δεₚ = C⁻¹:(σᵗʳ − σ) = Δγ (n/√2 + α_ψ I)`, so
/// `ψ = 0` gives no plastic volume change, `ψ = φ` the normal of the yield surface, and in
/// general `tr Δεₚ / ‖dev Δεₚ‖ = 3√2 α_ψ`; in the tension region the flow is volumetric.
/// Tolerances: `Δεₚ` (~1e-3) is a difference of elastic strains of ~1e-2 with round-off
/// ~1e-18, so 1e-10 relative is ample.
#[test]
fn plastic_flow_follows_the_potential() {
    let mut seed = 99;
    for (phi, psi) in [(30.0, 0.0), (30.0, 30.0), (35.0, 12.0), (25.0, 25.0)] {
        let m = dp(phi, psi, COHESION, Some(1.0e3));
        let (alpha, alpha_psi) = (m.alpha(), m.alpha_psi());
        let mut shear_steps = 0;
        let mut tension_steps = 0;
        for dim in [2, 3] {
            for walk in 0..30 {
                // Every third walk is a near-isotropic extension (tension region).
                let (scale, bias) = if walk % 3 == 2 {
                    (1e-4, 1e-3)
                } else {
                    (2e-3, -1e-4)
                };
                let mut sigma = Matrix3::identity() * -3.0e4;
                let mut state = state_of(&m, &sigma);
                for _ in 0..30 {
                    let dl = random_dl(&mut seed, dim, scale, bias);
                    let trial = m.trial_stress(&sigma, &dl);
                    let (s, st, region) = m.stress_update(&sigma, &dl, &state);
                    let deps = m.compliance(&(trial - s));
                    let norm = deps.norm();
                    match region {
                        Region::Shear => {
                            shear_steps += 1;
                            let dev = deviator(&deps);
                            let ratio = deps.trace() / dev.norm();
                            assert!(
                                (ratio - 3.0 * 2f64.sqrt() * alpha_psi).abs() < 1e-9,
                                "ψ = {psi}: tr/‖dev‖ = {ratio}"
                            );
                            if psi == 0.0 {
                                assert!(deps.trace().abs() < 1e-10 * norm, "isochoric");
                            }
                            // The direction n of the deviator is that of the stress.
                            let ns = deviator(&s) / deviator(&s).norm();
                            assert!((dev / dev.norm() - ns).norm() < 1e-9);
                            if psi == phi {
                                let normal = ns / 2f64.sqrt() + Matrix3::identity() * alpha;
                                let gap = (deps / norm - normal / normal.norm()).norm();
                                assert!(gap < 1e-9, "associated: {gap:e}");
                            }
                        }
                        Region::Tension => {
                            tension_steps += 1;
                            assert!(deviator(&deps).norm() < 1e-10 * norm, "volumetric");
                            assert!(deps.trace() > 0.0, "the cutoff flow expands");
                        }
                        _ => {}
                    }
                    (sigma, state) = (s, st);
                }
            }
        }
        assert!(
            shear_steps > 50 && tension_steps > 5,
            "{shear_steps} {tension_steps}"
        );
    }
}

/// (4) Objectivity: a pure spin `L = W` leaves the invariants `I₁`, `J₂`, `J₃` of the stress
/// unchanged over 5000 steps (5 rad), 2D and 3D, for a stress inside the cone and for one
/// on it, while the stress does rotate. The Cayley rotation is orthogonal to round-off, so
/// the invariants drift by a random walk of ~√5000 · 1e-16; 1e-12 relative bounds it (the
/// forward-Euler rotation would drift by ~5000 · (ωΔt)² = 5e-3).
#[test]
fn a_pure_spin_leaves_the_invariants_unchanged() {
    let m = dp(30.0, 0.0, COHESION, None);
    let inside = matrix![-1.0e5, 1.5e4, -5.0e3; 1.5e4, -6.0e4, 8.0e3; -5.0e3, 8.0e3, -8.0e4];
    // On the cone: scale the deviator of `inside` onto f = 0.
    let p = mean(&inside);
    let s = deviator(&inside);
    let q = (m.k() - 3.0 * m.alpha() * p) * 2f64.sqrt();
    let on = s * (q / s.norm()) + Matrix3::identity() * p;
    assert!(m.yield_function(&on).abs() < 1e-9);
    let dt = 1e-3;
    for dim in [2, 3] {
        let axis = if dim == 2 {
            vector![0.0, 0.0, 1.0]
        } else {
            vector![1.0, 2.0, -2.0] / 3.0
        };
        let w = axis.cross_matrix(); // ω = 1 rad/s about `axis`
        for start in [inside, on] {
            // In 2D only an in-plane stress (no xz, yz shear) is meaningful.
            let mut sigma = start;
            if dim == 2 {
                sigma[(0, 2)] = 0.0;
                sigma[(1, 2)] = 0.0;
                sigma[(2, 0)] = 0.0;
                sigma[(2, 1)] = 0.0;
            }
            let inv0 = invariants(&sigma);
            let s0 = sigma;
            let mut state = state_of(&m, &sigma);
            for _ in 0..5000 {
                let (s1, st1, _) = m.stress_update(&sigma, &(w * dt), &state);
                (sigma, state) = (s1, st1);
            }
            let inv = invariants(&sigma);
            for (a, (x, x0)) in inv.iter().zip(inv0).enumerate() {
                let scale = [1e5, 1e10, 1e15][a];
                assert!(
                    (x - x0).abs() < 1e-12 * scale,
                    "{dim}D invariant {a}: {x} vs {x0}"
                );
            }
            assert!((sigma - s0).norm() > 1e3, "the stress rotated");
            assert!(state.plastic_strain < 1e-12, "no plastic flow from a spin");
            if dim == 2 {
                assert_eq!((sigma[(0, 2)], sigma[(1, 2)]), (0.0, 0.0));
            }
        }
    }
}

/// Advances one step with axial increment `d_axial` on axis 0 and finds, by the secant method,
/// the lateral increment (the same on `lateral` axes) that keeps the normal stress on axis 1
/// at `target`. Returns the step's result.
fn controlled_step(
    m: &DruckerPrager<f64>,
    sigma: &Matrix3<f64>,
    state: &MaterialState<f64>,
    d_axial: f64,
    lateral: &[usize],
    target: f64,
) -> (Matrix3<f64>, MaterialState<f64>, Region) {
    let run = |x: f64| {
        let mut dl = Matrix3::zeros();
        dl[(0, 0)] = d_axial;
        for &a in lateral {
            dl[(a, a)] = x;
        }
        m.stress_update(sigma, &dl, state)
    };
    let g = |x: f64| run(x).0[(1, 1)] - target;
    let (lambda, mu) = (m.lame.lambda, m.lame.mu);
    let mut x0 = -lambda * d_axial / (2.0 * (lambda + mu));
    let mut x1 = x0 + 1e-6;
    let (mut g0, mut g1) = (g(x0), g(x1));
    for _ in 0..100 {
        if g1.abs() < 1e-11 * target.abs() {
            break;
        }
        let x2 = x1 - g1 * (x1 - x0) / (g1 - g0);
        (x0, g0) = (x1, g1);
        x1 = x2;
        g1 = g(x1);
    }
    assert!(
        g1.abs() < 1e-11 * target.abs(),
        "lateral control failed: {g1}"
    );
    run(x1)
}

/// (5) Triaxial compression (3D, axisymmetric): confinement `σ₂ = σ₃ = −p_c` held, axial
/// strain increased. The deviatoric stress `q = σ₃ − σ₁` rises and then stays at the closed
/// form `q = (k + 3α p_c)/(1/√3 − α)` (from `f = q/√3 + α(−3p_c − q) − k = 0`), whatever ψ.
/// Every plastic step lands on the yield surface with the lateral stress controlled to 1e-11,
/// so the plateau matches to 1e-9.
#[test]
fn triaxial_compression_reaches_the_closed_form_peak() {
    for (phi, psi, c) in [(30.0, 5.0, COHESION), (35.0, 0.0, 0.0), (25.0, 25.0, 2.0e4)] {
        let m = dp(phi, psi, c, None);
        let p_c = 1.0e5;
        let q_peak = (m.k() + 3.0 * m.alpha() * p_c) / (1.0 / 3f64.sqrt() - m.alpha());
        let mut sigma = Matrix3::identity() * -p_c;
        let mut state = state_of(&m, &sigma);
        let mut q_last = 0.0;
        let mut first_plastic = None;
        for step in 0..400 {
            let (s, st, region) = controlled_step(&m, &sigma, &state, -1e-4, &[1, 2], -p_c);
            (sigma, state) = (s, st);
            let q = sigma[(1, 1)] - sigma[(0, 0)];
            assert!(q >= q_last - 1e-9 * q_peak, "q decreased at step {step}");
            assert!(
                q <= q_peak * (1.0 + 1e-9),
                "q = {q} above the peak {q_peak}"
            );
            if region == Region::Shear && first_plastic.is_none() {
                first_plastic = Some(step);
            }
            q_last = q;
        }
        let first = first_plastic.expect("the sample yields");
        assert!(first > 20 && first < 300, "first plastic step {first}");
        assert!(
            (q_last - q_peak).abs() < 1e-9 * q_peak,
            "{q_last} vs {q_peak}"
        );
        assert!((sigma[(2, 2)] + p_c).abs() < 1e-9 * p_c, "axisymmetric");
        assert!(state.plastic_strain > 0.0);
    }
}

/// The Mohr–Coulomb major principal stress at failure for a minor one `σ₃ = −p_c`
/// (compression negative): `σ₁ = −(p_c N_φ + 2c √N_φ)`, `N_φ = (1 + sin φ)/(1 − sin φ)`.
fn mohr_coulomb_peak(phi: f64, c: f64, p_c: f64) -> f64 {
    let n = (1.0 + phi.sin()) / (1.0 - phi.sin());
    -(p_c * n + 2.0 * c * n.sqrt())
}

/// (6a) The cone coefficients: `α = tan φ/√(9 + 12 tan²φ)` and `k = 3c/√(9 + 12 tan²φ)` are
/// the plane-strain forms `α = sin φ/√(3(3 + sin²φ))`, `k = √3 c cos φ/√(3 + sin²φ)`, lie
/// between the inner and outer cones, and give `α = 1/(√3 √13)`, `k = 3c/√13` at φ = 30°;
/// the apex is at `c cot φ`.
#[test]
fn cone_coefficients_are_the_plane_strain_match() {
    for phi_deg in [5.0, 20.0, 30.0, 45.0, 60.0, 85.0] {
        let m = dp(phi_deg, phi_deg, COHESION, None);
        let phi: f64 = phi_deg.to_radians();
        let (s, c) = (phi.sin(), phi.cos());
        let alpha = s / (3.0 * (3.0 + s * s)).sqrt();
        let k = 3f64.sqrt() * COHESION * c / (3.0 + s * s).sqrt();
        assert!((m.alpha() - alpha).abs() < 1e-14 * alpha);
        assert!((m.k() - k).abs() < 1e-12 * k);
        assert_eq!(m.alpha_psi(), m.alpha());
        // Inside the cones through the compression and the extension corners of MC.
        let outer = 2.0 * s / (3f64.sqrt() * (3.0 - s));
        let inner = 2.0 * s / (3f64.sqrt() * (3.0 + s));
        assert!(m.alpha() < inner && inner < outer, "φ = {phi_deg}");
        // In the deviatoric plane at mean stress p, the DP radius ‖s‖ = √2 (k − 3αp) is the
        // smallest MC radius over the Lode angle: the cone is inscribed in the MC pyramid,
        // tangent to its faces. MC (tension positive, σ₁ ≥ σ₂ ≥ σ₃):
        // (σ₁ − σ₃)/2 + (σ₁ + σ₃)/2 sin φ = c cos φ; along σ = pI + ρn, n the unit deviator of
        // Lode angle θ, it is affine in ρ. 1e-6 relative: the sampling of θ (1e-4 rad steps
        // near a smooth minimum gives ~1e-8).
        for p in [-1.0e5, -1.0e4, 0.0] {
            let rho_dp = 2f64.sqrt() * (m.k() - 3.0 * m.alpha() * p);
            let mut rho_min = f64::INFINITY;
            for i in 0..=10_472 {
                let theta = i as f64 * 1e-4; // [0, π/3]
                let n: Vec<f64> = (0..3)
                    .map(|j| {
                        (2.0f64 / 3.0).sqrt()
                            * (theta - 2.0 * std::f64::consts::PI * j as f64 / 3.0).cos()
                    })
                    .collect();
                let (n1, n3) = (n[0], n[2]);
                let rho = (COHESION * c - p * s) / ((n1 - n3) / 2.0 + (n1 + n3) / 2.0 * s);
                assert!(
                    rho >= rho_dp * (1.0 - 1e-12),
                    "DP outside MC at θ = {theta}"
                );
                rho_min = rho_min.min(rho);
            }
            assert!(
                (rho_min - rho_dp).abs() < 1e-6 * rho_dp,
                "{rho_min} vs {rho_dp}"
            );
        }
        assert!((m.apex() - COHESION / phi.tan()).abs() < 1e-9 * m.apex());
        assert!((m.k() / (3.0 * m.alpha()) - m.apex()).abs() < 1e-9 * m.apex());
        assert_eq!(m.tension_limit(), m.apex());
        assert_eq!(m.corner(), (m.apex(), 0.0));
    }
    let m = dp(30.0, 0.0, COHESION, None);
    assert!((m.alpha() - 1.0 / (3f64.sqrt() * 13f64.sqrt())).abs() < 1e-15);
    assert!((m.k() - 3.0 * COHESION / 13f64.sqrt()).abs() < 1e-11);
    assert_eq!(m.alpha_psi(), 0.0);
    assert_eq!(dp(30.0, 0.0, 0.0, None).apex(), 0.0);
    // A cutoff below the apex is kept, one above it is the apex.
    let below = dp(30.0, 0.0, COHESION, Some(1.0e3));
    assert_eq!(below.tension_limit(), 1.0e3);
    assert!((below.corner().1 - (below.k() - 3.0 * below.alpha() * 1.0e3)).abs() < 1e-12);
    assert_eq!(
        dp(30.0, 0.0, COHESION, Some(1.0e9)).tension_limit(),
        m.apex()
    );
}

/// (6b) Plane-strain biaxial compression (`ε_zz = 0`, `σ_yy = −p_c` held, `ε_xx` increased).
/// At the limit state the stress is stationary, so `Δεₚ = Δt D` and `Δεₚ_zz = 0`, i.e.
/// `∂g/∂σ_zz = 0`: `s_zz = −2α_ψ √J₂`. With the in-plane centre `m` and radius `r` of Mohr's
/// circle this gives `r (1 − 3αα_ψ)/√(1 − 3α_ψ²) = k − 3αm`; for `ψ = φ` it is exactly
/// Mohr–Coulomb, `r = c cos φ − m sin φ` (the plane-strain match), so `σ_xx` tends to the MC
/// value `−(p_c N_φ + 2c√N_φ)`. The limit is approached geometrically as `σ_zz` settles;
/// after 2000 steps of 1e-3 the gap is below round-off, and 1e-9 is asserted.
#[test]
fn plane_strain_biaxial_matches_mohr_coulomb() {
    let p_c = 1.0e5;
    for (phi, psi, c) in [
        (30.0, 30.0, COHESION),
        (40.0, 40.0, 0.0),
        (20.0, 20.0, 3.0e4),
        (30.0, 0.0, COHESION),
        (35.0, 10.0, COHESION),
    ] {
        let m = dp(phi, psi, c, None);
        let (alpha, alpha_psi) = (m.alpha(), m.alpha_psi());
        let a = (1.0 - 3.0 * alpha * alpha_psi) / (1.0 - 3.0 * alpha_psi * alpha_psi).sqrt();
        let r = (m.k() + 3.0 * alpha * p_c) / (a - 3.0 * alpha);
        let closed_form = -p_c - 2.0 * r;
        if psi == phi {
            let mc = mohr_coulomb_peak(m.friction_angle, c, p_c);
            assert!(
                (closed_form - mc).abs() < 1e-12 * mc.abs(),
                "{closed_form} vs {mc}"
            );
        }
        let mut sigma = Matrix3::identity() * -p_c;
        let mut state = state_of(&m, &sigma);
        for _ in 0..2000 {
            let (s, st, _) = controlled_step(&m, &sigma, &state, -1e-3, &[1], -p_c);
            (sigma, state) = (s, st);
        }
        let sxx = sigma[(0, 0)];
        assert!(
            (sxx - closed_form).abs() < 1e-9 * closed_form.abs(),
            "φ = {phi}, ψ = {psi}: σ_xx = {sxx} vs {closed_form}"
        );
        // The out-of-plane stress is the one the limit state predicts: s_zz = −2α_ψ √J₂.
        let s = deviator(&sigma);
        let sqrt_j2 = s.norm() / 2f64.sqrt();
        assert!((s[(2, 2)] + 2.0 * alpha_psi * sqrt_j2).abs() < 1e-8 * sqrt_j2);
    }
}

/// A 3D path that mixes compression, shear and spin (shear returns), and one that extends
/// into the corner/apex: the per-step increments.
fn paths() -> Vec<(Matrix3<f64>, Vec<Matrix3<f64>>)> {
    let start = matrix![-8.0e4, 1.0e4, 0.0; 1.0e4, -6.0e4, 5.0e3; 0.0, 5.0e3, -7.0e4];
    let shear: Vec<_> = (0..40)
        .map(|i| {
            let t = i as f64 * 0.15;
            matrix![-4e-4, 6e-4 * t.cos(), 2e-4; -1e-4, 3e-4, 1e-4 * t.sin(); 1e-4, -2e-4, 1e-4]
        })
        .collect();
    let extension: Vec<_> = (0..40)
        .map(|i| {
            let t = i as f64 * 0.2;
            matrix![1.5e-3, 2e-4 * t.sin(), 0.0; 0.0, 1.2e-3, 1e-4; 0.0, -1e-4, 1.0e-3]
        })
        .collect();
    vec![(start, shear), (start, extension)]
}

/// (7) `∂σ/∂φ` with a dual friction angle equals a central difference. The return is closed
/// form, so the dual derivative is exact; the difference with `h = 1e-6` rad has truncation
/// `~|∂³σ/∂φ³| h²/6 ~ 1e5 · 1e-12` and round-off `~1e-16 · 1e5 / 1e-6 = 1e-5` Pa, against
/// derivatives of ~1e4–1e5 Pa/rad: 1e-6 relative is a safe bound. The region sequence is
/// checked to be the same in the three runs (no branch switch inside the difference). The
/// same holds for `ψ` and `c`.
#[test]
fn friction_angle_derivative_matches_central_differences() {
    let h = 1e-6;
    for (phi_deg, psi_deg, cutoff) in [(30.0, 10.0, None), (35.0, 35.0, Some(2.0e3))] {
        let base = dp(phi_deg, psi_deg, COHESION, cutoff);
        for (start, path) in paths() {
            // Which parameter is seeded: 0 = φ, 1 = ψ, 2 = c.
            for which in 0..3 {
                let run_f64 = |delta: f64| {
                    let mut m = base;
                    match which {
                        0 => m.friction_angle += delta,
                        1 => m.dilation_angle += delta,
                        _ => m.cohesion += delta * 1e4,
                    }
                    let mut sigma = start;
                    let mut state = state_of(&m, &start);
                    let mut regions = Vec::new();
                    for dl in &path {
                        let (s, st, r) = m.stress_update(&sigma, dl, &state);
                        (sigma, state) = (s, st);
                        regions.push(r);
                    }
                    (sigma, state.plastic_strain, regions)
                };
                let mut md = base.lift::<Dual64>();
                match which {
                    0 => md.friction_angle.eps = 1.0,
                    1 => md.dilation_angle.eps = 1.0,
                    _ => md.cohesion.eps = 1e4,
                }
                let mut sigma = start.map(Dual64::from_re);
                let mut state = MaterialState {
                    plastic_strain: Dual64::from_re(0.0),
                    tensor: (Matrix3::identity() + base.compliance(&start) * 2.0)
                        .map(Dual64::from_re),
                    hardening: Dual64::from_re(0.0),
                };
                let mut regions = Vec::new();
                for dl in &path {
                    let (s, st, r) = md.stress_update(&sigma, &dl.map(Dual64::from_re), &state);
                    (sigma, state) = (s, st);
                    regions.push(r);
                }
                let (sp, ep, rp) = run_f64(h);
                let (sm, em, rm) = run_f64(-h);
                let (s0, _, r0) = run_f64(0.0);
                assert_eq!(rp, r0);
                assert_eq!(rm, r0);
                assert_eq!(regions, r0);
                let plastic = r0.iter().filter(|&&r| r != Region::Elastic).count();
                assert!(plastic > 10, "{r0:?}");
                let fd = (sp - sm) / (2.0 * h);
                let dual = sigma.map(|x| x.eps);
                assert!((sigma.map(|x| x.re) - s0).norm() < 1e-9 * s0.norm());
                let shear = r0.iter().filter(|&&r| r == Region::Shear).count();
                // Corner and tension returns do not depend on ψ: its derivative vanishes on
                // the extension path, which has a single shear step at its start.
                if which != 1 || shear > 10 {
                    assert!(dual.norm() > 1.0, "a non-trivial derivative");
                }
                assert!(
                    (dual - fd).norm() < 1e-6 * dual.norm().max(1.0),
                    "param {which}: dual {dual} vs fd {fd}"
                );
                let fd_e = (ep - em) / (2.0 * h);
                assert!((state.plastic_strain.eps - fd_e).abs() < 1e-6 * fd_e.abs().max(1e-6));
            }
        }
    }
}

/// The `Material` dispatch: `update` through `Kinematics` (with `Δt L`), `kirchhoff_update`
/// from the stress the state stands for, the energy, `lift`, the wave speed and the model
/// name all agree with the direct calls.
#[test]
fn material_dispatch_matches_the_direct_calls() {
    let phi = 30f64.to_radians();
    let psi = 5f64.to_radians();
    let mat = Material::drucker_prager(YOUNG, POISSON, phi, psi, COHESION, Some(1.0e3), 1800.0);
    let Model::DruckerPrager(m) = mat.model else {
        panic!("{:?}", mat.model)
    };
    assert_eq!(m, dp(30.0, 5.0, COHESION, Some(1.0e3)));
    let sigma_n = matrix![-5.0e4, 4.0e3, 0.0; 4.0e3, -3.0e4, 0.0; 0.0, 0.0, -4.0e4];
    let state = state_of(&m, &sigma_n);
    let l = matrix![-2.0, 30.0, 0.0; -10.0, 1.0, 0.0; 0.0, 0.0, 0.0];
    let dt = 1e-3;
    let f = matrix![0.99, 0.02, 0.0; -0.01, 1.0, 0.0; 0.0, 0.0, 1.0];
    let delta_f = Matrix3::identity() + l * dt;
    let kin = Kinematics {
        f: &f,
        delta_f: &delta_f,
        velocity_gradient: &l,
        dt,
        stress: &sigma_n,
    };
    let (direct, direct_state, region) = m.stress_update(&sigma_n, &(l * dt), &state);
    assert_ne!(region, Region::Elastic, "a plastic step");
    let mut s1 = state;
    assert_eq!(mat.update(&kin, &mut s1), direct);
    assert_eq!(s1, direct_state);
    let mut s2 = state;
    assert_eq!(mat.constitutive().update(&kin, &mut s2), direct);
    let (tau, s3) = mat.kirchhoff_update(&delta_f, &f, &state);
    // The state gives σₙ back to round-off (C:C⁻¹), so τ = J σ to ~1e-12.
    assert!((tau - direct * f.determinant()).norm() < 1e-10 * direct.norm());
    assert!((s3.plastic_strain - direct_state.plastic_strain).abs() < 1e-12);
    assert!((m.stress_of_state(&state) - sigma_n).norm() < 1e-10 * sigma_n.norm());
    assert_eq!(mat.energy_density(&f, &s1), m.stored_energy(&f, &s1));
    let eps = m.compliance(&direct);
    let psi_e = 0.5 * direct.component_mul(&eps).sum() * f.determinant();
    assert!((mat.energy_density(&f, &s1) - psi_e).abs() < 1e-12 * psi_e);
    assert_eq!(mat.constitutive().p_wave_modulus(), m.lame.p_wave_modulus());
    assert!((mat.wave_speed() - (m.lame.p_wave_modulus() / 1800.0).sqrt()).abs() < 1e-12);

    let lifted = mat.lift::<Dual64>();
    let Model::DruckerPrager(ml) = lifted.model else {
        panic!("lift changed the model")
    };
    assert_eq!(ml.friction_angle.re, phi);
    assert_eq!(ml.dilation_angle.re, psi);
    assert_eq!(ml.cohesion.re, COHESION);
    assert_eq!(ml.tension_cutoff.map(|t| t.re), Some(1.0e3));
    assert_eq!(ml.friction_angle.eps, 0.0);

    assert_eq!(ModelKind::DruckerPrager.name(), "drucker_prager");
}

/// `Material::elastic` with `ModelKind::DruckerPrager` is hypoelastic and never yields, even
/// far beyond any finite strength, in compression, extension and shear.
#[test]
fn elastic_drucker_prager_never_yields() {
    let mat = Material::elastic(ModelKind::DruckerPrager, YOUNG, POISSON, 1000.0);
    let Model::DruckerPrager(m) = mat.model else {
        panic!("{:?}", mat.model)
    };
    let mut seed = 3;
    let mut sigma = Matrix3::zeros();
    let mut state = MaterialState::default();
    for bias in [-1e-2, 0.0, 1e-2] {
        for _ in 0..20 {
            let dl = random_dl(&mut seed, 3, 1e-2, bias);
            let (s, st, region) = m.stress_update(&sigma, &dl, &state);
            assert_eq!(region, Region::Elastic);
            assert!(s.iter().all(|x| x.is_finite()));
            (sigma, state) = (s, st);
        }
    }
    assert_eq!(state.plastic_strain, 0.0);
}

/// Purely isotropic extension (`s = 0` exactly) of a cohesive material returns to the apex
/// without NaN, also in dual numbers (where `√J₂` has no derivative at `s = 0`), and the
/// cohesionless material cannot carry any tension.
#[test]
fn isotropic_extension_returns_to_the_apex_without_nan() {
    for c in [COHESION, 0.0] {
        let m = dp(30.0, 10.0, c, None);
        let dl = Matrix3::identity() * 1e-3;
        let (s, st, region) = m.stress_update(&Matrix3::zeros(), &dl, &MaterialState::default());
        assert_eq!(region, Region::Tension);
        assert!((s - Matrix3::identity() * m.apex()).norm() <= 1e-12 * COHESION);
        assert!(st.plastic_strain > 0.0);
        let mut md = m.lift::<Dual64>();
        md.friction_angle.eps = 1.0;
        let (sd, std, _) = md.stress_update(
            &Matrix3::zeros(),
            &dl.map(Dual64::from_re),
            &MaterialState::default(),
        );
        assert!(sd.iter().all(|x| x.is_finite_all()), "{sd}");
        assert!(std.plastic_strain.is_finite_all());
        // d(c cot φ)/dφ = −c / sin²φ.
        let expected = -c / (30f64.to_radians().sin().powi(2));
        assert!((sd[(0, 0)].eps - expected).abs() < 1e-9 * COHESION);
    }
}

/// The model runs in `f32` (the scalar contract) and agrees with `f64` to single precision.
#[test]
fn runs_in_single_precision() {
    let m = dp(30.0, 10.0, COHESION, None);
    let m32 = DruckerPrager::<f32> {
        lame: Lame {
            mu: m.lame.mu as f32,
            lambda: m.lame.lambda as f32,
        },
        friction_angle: m.friction_angle as f32,
        dilation_angle: m.dilation_angle as f32,
        cohesion: m.cohesion as f32,
        tension_cutoff: None,
        cone: Cone::PlaneStrain,
        elasticity: Elasticity::Jaumann,
    };
    let (start, path) = paths().remove(0);
    let mut s64 = start;
    let mut st64 = state_of(&m, &start);
    let mut s32 = start.map(|x| x as f32);
    let mut st32 = MaterialState {
        plastic_strain: 0.0f32,
        tensor: st64.tensor.map(|x| x as f32),
        hardening: 0.0f32,
    };
    for dl in &path {
        (s64, st64, _) = m.stress_update(&s64, dl, &st64);
        (s32, st32, _) = m32.stress_update(&s32, &dl.map(|x| x as f32), &st32);
    }
    let diff = (s32.map(|x| x as f64) - s64).norm();
    assert!(diff < 1e-4 * s64.norm(), "{diff}");
    assert!((st32.plastic_strain as f64 - st64.plastic_strain).abs() < 1e-4 * st64.plastic_strain);
}
