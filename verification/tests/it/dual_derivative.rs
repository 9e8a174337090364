//! The scalar contract end to end: the explicit solver runs with `T = Dual64`, and the
//! derivative it carries, d v_cm(t) / dE of the axial bar, matches a central finite difference.

use loam_verification::axial_bar::{Setup, YOUNG};
use num_dual::Dual64;

#[test]
fn dual_run_gives_the_derivative_of_the_trajectory_with_respect_to_e() {
    let setup = Setup::new(20);
    // 300 steps: t_end = 300 Δt.
    let t_end = 300.0 * setup.dt();
    let dual = setup
        .vcm_history(Dual64::new(YOUNG, 1.0), t_end)
        .expect("dual run");
    let run = |e: f64| setup.vcm_history(e, t_end).expect("real run");
    // Central difference with δ = 1e-4 E: truncation ~ (δ/E)² |v''| ≈ 1e-8 relative,
    // round-off ~ 1e-16 / 1e-4 = 1e-12 relative; 1e-6 leaves a wide margin.
    let delta = 1e-4 * YOUNG;
    let (plus, minus) = (run(YOUNG + delta), run(YOUNG - delta));
    assert_eq!(dual.len(), plus.len());
    assert_eq!(dual.len(), 301, "fixed Δt must give exactly 300 steps");
    let (t, d) = *dual.last().expect("history");
    let fd = (plus.last().expect("history").1 - minus.last().expect("history").1) / (2.0 * delta);
    let rel = (d.eps - fd).abs() / fd.abs();
    println!(
        "t = {t:.4}: dual {:.10e}, finite difference {fd:.10e}, relative {rel:.2e}",
        d.eps
    );
    assert!(fd.abs() > 1e-8, "derivative too small to compare: {fd}");
    assert!(
        rel <= 1e-6,
        "dual {} vs fd {fd}: relative difference {rel:.3e}",
        d.eps
    );
    // The real part of the dual run is the plain f64 run (num-dual orders a few operations
    // differently, so equality holds to round-off accumulated over 300 steps, not bitwise).
    let real = run(YOUNG).last().expect("history").1;
    assert!(
        (d.re - real).abs() <= 1e-10 * real.abs(),
        "real part {} vs f64 run {real}",
        d.re
    );
}

/// Back-analysis from a scene file: the friction dam-break of `examples/dambreak_friction.toml`
/// (MLS-MPM, USL, fixed Δt = 3e-5 s) with a dual friction coefficient on the floor segment
/// under the column (`[[friction]]` 1, x ∈ [0, 0.4] m), set to μ = 0.05 (the file's μ = 0
/// would need a negative μ for the backward difference). After 500 steps the derivative of the
/// front position (the largest x of any particle) with respect to that μ equals a central
/// finite difference taken where the map is smooth.
///
/// The forward map is only piecewise smooth: a floor node switches between stick and slip
/// where its tangential speed meets `μ Δv_n`, and the dual number differentiates the branches
/// the run took. The step record shows the runs at μ ± δ taking the same branches in every
/// step only for δ ≤ 3e-6 (at δ = 1e-5 one or two steps differ, at 1e-4 up to 14), so the
/// difference is taken at δ = 3e-6 after checking the records. There the round-off of the
/// front, about 1e-15 m after 500 steps, contributes 1e-15 / (2δ) ≈ 2e-10 m to a derivative of
/// 5.5e-5 m, i.e. ≈ 3e-6 relative: the tolerance is 1e-5, not the 1e-6 that a smooth map
/// with a larger derivative allows (the axial-bar test above).
#[test]
fn dual_friction_gives_the_derivative_of_the_front() {
    use loam_core::step::StepRecord;
    use loam_explicit::Solver;
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/dambreak_friction.toml");
    let scene = loam_scene::Scene::from_path(&path).expect("the example is valid");
    let built: loam_scene::Built<2> = scene.build().expect("the example builds");
    let mut config = built.explicit_config().expect("an explicit scene");
    const SEGMENT: usize = 0;
    const MU: f64 = 0.05;
    const STEPS: usize = 500;
    config.contact.segments[SEGMENT].mu = MU;
    // The front after STEPS steps, and the branches every step took.
    fn front<T: loam_core::Scalar>(
        config: loam_explicit::Config<T, 2>,
        mut p: loam_core::Particles<T, 2>,
    ) -> (T, Vec<StepRecord>) {
        let mut solver = Solver::new(config, &p).expect("valid configuration");
        let mut records = vec![StepRecord::default(); STEPS];
        for r in &mut records {
            solver
                .step_recorded(&mut p, f64::INFINITY, r)
                .expect("stable step");
        }
        let lead = (0..p.len())
            .max_by(|&a, &b| p.x[a][0].re().total_cmp(&p.x[b][0].re()))
            .expect("particles");
        (p.x[lead][0], records)
    }
    let mut dual = config.lift::<Dual64>();
    dual.contact.segments[SEGMENT].mu = Dual64::new(MU, 1.0);
    let (d, branches) = front(dual, built.particles.lift());
    let run = |m: f64| {
        let mut c = config.clone();
        c.contact.segments[SEGMENT].mu = m;
        front(c, built.particles.clone())
    };
    let delta = 3e-6;
    let ((plus, rp), (minus, rm)) = (run(MU + delta), run(MU - delta));
    for (side, records) in [("+δ", &rp), ("−δ", &rm)] {
        for (k, (a, b)) in records.iter().zip(&branches).enumerate() {
            assert!(
                a.nodes == b.nodes && a.particles == b.particles,
                "μ {side}: step {} took other branches than the dual run",
                k + 1
            );
        }
    }
    let fd = (plus - minus) / (2.0 * delta);
    let rel = (d.eps - fd).abs() / fd.abs();
    println!(
        "dx_front/dμ after {STEPS} steps: dual {:.10e}, central difference {fd:.10e} \
         (δ = {delta}), relative {rel:.2e}",
        d.eps
    );
    assert!(fd.abs() > 1e-6, "derivative too small to compare: {fd}");
    assert!(rel <= 1e-5, "dual {} vs fd {fd}: {rel:.3e}", d.eps);
    assert!(
        (d.re - run(MU).0).abs() <= 1e-12,
        "real part of the dual run"
    );
}
