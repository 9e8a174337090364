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
