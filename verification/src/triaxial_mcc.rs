//! `triaxial-mcc`: Modified Cam-Clay element tests against the closed forms of critical state
//! soil mechanics, by the element-test driver ([`loam_implicit::element`]) with the solvers'
//! own kernels. λ = 0.2, κ = 0.04, M = 1, e₀ = 1, ν = 0.3, normally consolidated at
//! p′₀ = 200 kPa (isotropic).
//!
//! - Undrained (isochoric) compression: the stress path `q = M p′ √(p′_c/p′ − 1)` with
//!   `p′_c = p′_c0 (p′₀/p′)^(κ/(λ−κ))` all along (the model's closed form at constant volume),
//!   and the critical state `p′_f/p′₀ = (½)^((λ−κ)/λ)` = 0.574, `s_u/p′₀ = M p′_f/(2p′₀)` =
//!   0.287.
//! - Drained compression at constant radial stress: `q_f = 3M p′₀/(3 − M)` (the critical
//!   state on the 3:1 total stress path).
//! - Oedometer loading, unloading and reloading: the slopes of `ln v` against `ln p′_τ`, times
//!   `v₀ = 1 + e₀`, are `λ` on the normal compression line and `κ` on unloading, with
//!   `p′_τ = J p′` the Kirchhoff mean stress in which the model's laws are written (the model
//!   is linear in `ln v–ln p′_τ`; the `e–ln p′` slopes with the Cauchy `p′` of a laboratory
//!   differ by the volume change and are reported too).
//!
//! The critical state is approached asymptotically: the undrained test runs to 40 % axial
//! strain and the drained one to 60 % (where the remaining gap is below 0.1 %), as laboratory
//! tests are run to "ultimate" states. Compression is positive in the reports.

use crate::triaxial::{drained, isotropic_start};
use crate::{CaseReport, Metric, Series, Size, VerifyError, write_csv, write_plot};
use loam_core::constitutive::{Material, Model, ModifiedCamClay, Preconsolidation, Shear};
use loam_implicit::element::{self, PointState};
use loam_scene::element::StageSpec;
use std::path::Path;

const CASE: &str = "triaxial-mcc";
const P0: f64 = 200e3;

fn clay() -> (ModifiedCamClay<f64>, Material<f64>) {
    let m = ModifiedCamClay {
        lambda: 0.2,
        kappa: 0.04,
        critical_state_slope: 1.0,
        void_ratio: 1.0,
        shear: Shear::Poisson(0.3),
        preconsolidation: Preconsolidation::Ratio(1.0),
    };
    let material = Material {
        density: 1800.0,
        model: Model::ModifiedCamClay(m),
    };
    (m, material)
}

fn run_stages(
    material: &Material<f64>,
    start: PointState,
    stages: &[StageSpec],
) -> Result<Vec<PointState>, VerifyError> {
    let stages: Vec<_> = stages.iter().map(StageSpec::lab_stage).collect();
    let run = element::run_test(material, material, start, &stages);
    match run.failure {
        Some(e) => Err(VerifyError::Reference {
            case: CASE.into(),
            msg: e.to_string(),
        }),
        None => Ok(run.states),
    }
}

/// `(λ, κ)` measured as `−v₀ Δln v / Δln p′_τ` over the last increment of the loading stage
/// and the first of the unloading stage, with `p′_τ = J p′` the Kirchhoff mean stress (the
/// model's measure: its laws are in Kirchhoff stress, as Borja & Tamagnini's), and the same
/// in `e–ln p′` with the Cauchy `p′` a laboratory reports.
fn oedometer_slopes(states: &[PointState], split: usize, v0: f64) -> ([f64; 2], [f64; 2]) {
    let ln_v = |s: &PointState| (v0 * s.f.determinant()).ln();
    let ln_p = |s: &PointState| (s.measures().p * s.f.determinant()).ln();
    let ln_p_cauchy = |s: &PointState| s.measures().p.ln();
    let e = |s: &PointState| v0 * s.f.determinant() - 1.0;
    let slope = |a: &PointState, b: &PointState| -v0 * (ln_v(b) - ln_v(a)) / (ln_p(b) - ln_p(a));
    let e_slope =
        |a: &PointState, b: &PointState| -(e(b) - e(a)) / (ln_p_cauchy(b) - ln_p_cauchy(a));
    let (a, b, c) = (&states[split - 1], &states[split], &states[split + 1]);
    ([slope(a, b), slope(b, c)], [e_slope(a, b), e_slope(b, c)])
}

/// Runs `triaxial-mcc`.
pub fn run(size: Size, out: &Path) -> Result<CaseReport, VerifyError> {
    let (m, material) = clay();
    let n = match size {
        Size::Reduced => 100,
        Size::Full => 400,
    };
    let start = isotropic_start(&material, P0);
    let undrained_stages = vec![StageSpec::UndrainedTriaxial {
        axial_strain: 0.4,
        increments: Some(n),
    }];
    let undrained = run_stages(&material, start.clone(), &undrained_stages)?;
    let exponent = m.kappa / (m.lambda - m.kappa);
    let mut path_gap = 0.0f64;
    for s in &undrained {
        let sm = s.measures();
        let p_c = P0 * (P0 / sm.p).powf(exponent);
        let closed = m.critical_state_slope * sm.p * (p_c / sm.p - 1.0).max(0.0).sqrt();
        path_gap = path_gap.max((sm.q - closed).abs() / P0);
    }
    let end = undrained.last().expect("a run has states").measures();
    let ratio = 0.5f64.powf((m.lambda - m.kappa) / m.lambda);
    let su = m.critical_state_slope * ratio / 2.0;

    let drained_states = element::run(&material, start.clone(), &[drained(P0, 0.6, 3 * n)])
        .map_err(|e| VerifyError::Reference {
            case: CASE.into(),
            msg: e.to_string(),
        })?;
    let q_f = 3.0 * m.critical_state_slope * P0 / (3.0 - m.critical_state_slope);
    let q_drained = drained_states.last().map_or(0.0, |s| s.measures().q);

    let oedometer = run_stages(
        &material,
        start,
        &[
            StageSpec::Oedometer {
                axial_strain: 0.2,
                increments: Some(n),
            },
            StageSpec::Oedometer {
                axial_strain: -0.01,
                increments: Some(n / 4),
            },
            StageSpec::Oedometer {
                axial_strain: 0.05,
                increments: Some(n),
            },
        ],
    )?;
    let v0 = 1.0 + m.void_ratio;
    let ([lambda, kappa], [lambda_e, kappa_e]) = oedometer_slopes(&oedometer, n, v0);

    let files = write_outputs(
        out,
        &undrained,
        &drained_states,
        &oedometer,
        (m, ratio, q_f),
    )?;
    Ok(CaseReport {
        metrics: vec![
            // Backward Euler lands on the ellipse and the hardening law is exact at constant
            // volume, so the path holds to the local Newton's tolerance: 1e-8 of p′₀.
            Metric::at_most(CASE, "undrained_path_max_gap_over_p0", path_gap, 1e-8),
            // The goal: 0.5 % at the critical state.
            Metric::at_most(
                CASE,
                "undrained_pf_over_p0_rel_error",
                (end.p / P0 - ratio).abs() / ratio,
                5e-3,
            ),
            Metric::at_most(
                CASE,
                "undrained_su_over_p0_rel_error",
                (end.q / 2.0 / P0 - su).abs() / su,
                5e-3,
            ),
            Metric::at_most(
                CASE,
                "drained_q_f_rel_error",
                (q_drained - q_f).abs() / q_f,
                5e-3,
            ),
            // ln v is linear in ln p′ on both lines: the slopes hold to round-off of the
            // increments (1e-6 relative).
            Metric::at_most(
                CASE,
                "oedometer_lambda_rel_error",
                (lambda - m.lambda).abs() / m.lambda,
                1e-6,
            ),
            Metric::at_most(
                CASE,
                "oedometer_kappa_rel_error",
                (kappa - m.kappa).abs() / m.kappa,
                1e-6,
            ),
            Metric::info(CASE, "oedometer_e_ln_p_slope_loading", lambda_e),
            Metric::info(CASE, "oedometer_e_ln_p_slope_unloading", kappa_e),
        ],
        files,
    })
}

/// The CSV of the three tests and the plots q–p′ (undrained path with its closed form and
/// the critical state line), q–ε_a, and e–ln p′ (oedometer).
fn write_outputs(
    out: &Path,
    undrained: &[PointState],
    drained_states: &[PointState],
    oedometer: &[PointState],
    (m, ratio, q_f): (ModifiedCamClay<f64>, f64, f64),
) -> Result<Vec<std::path::PathBuf>, VerifyError> {
    let v0 = 1.0 + m.void_ratio;
    let row = |test: f64, s: &PointState| {
        let sm = s.measures();
        vec![
            test,
            sm.axial_strain,
            sm.volumetric_strain,
            sm.p / 1e3,
            sm.q / 1e3,
            v0 * s.f.determinant() - 1.0,
        ]
    };
    let rows: Vec<Vec<f64>> = (undrained.iter().map(|s| row(0.0, s)))
        .chain(drained_states.iter().map(|s| row(1.0, s)))
        .chain(oedometer.iter().map(|s| row(2.0, s)))
        .collect();
    let csv = out.join("triaxial_mcc.csv");
    write_csv(
        &csv,
        &[
            "test_0undrained_1drained_2oedometer",
            "axial_strain",
            "volumetric_strain",
            "p_kPa",
            "q_kPa",
            "void_ratio",
        ],
        &rows,
    )?;
    let exponent = m.kappa / (m.lambda - m.kappa);
    let closed: Vec<(f64, f64)> = (0..=100)
        .map(|k| {
            let p = P0 * (ratio + (1.0 - ratio) * k as f64 / 100.0);
            let p_c = P0 * (P0 / p).powf(exponent);
            let q = m.critical_state_slope * p * (p_c / p - 1.0).max(0.0).sqrt();
            (p / 1e3, q / 1e3)
        })
        .collect();
    let pq = |states: &[PointState]| -> Vec<(f64, f64)> {
        (states.iter())
            .map(|s| (s.measures().p / 1e3, s.measures().q / 1e3))
            .collect()
    };
    let csl = vec![(0.0, 0.0), (1.6 * P0 / 1e3, 1.6 * P0 / 1e3)];
    let png_pq = out.join("triaxial_mcc_p_q.png");
    write_plot(
        &png_pq,
        "Modified Cam-Clay, NC p′₀ = 200 kPa: stress paths",
        "p′ (kPa)",
        "q (kPa)",
        &[
            Series {
                name: "critical state line q = M p′".into(),
                points: csl,
                markers: false,
            },
            Series {
                name: "undrained, closed form".into(),
                points: closed,
                markers: false,
            },
            Series {
                name: "undrained, loam".into(),
                points: pq(undrained),
                markers: true,
            },
            Series {
                name: "drained, loam".into(),
                points: pq(drained_states),
                markers: true,
            },
        ],
    )?;
    let png_q = out.join("triaxial_mcc_q_axial.png");
    let q_axial = |states: &[PointState]| -> Vec<(f64, f64)> {
        (states.iter())
            .map(|s| (s.measures().axial_strain, s.measures().q / 1e3))
            .collect()
    };
    write_plot(
        &png_q,
        "Modified Cam-Clay, NC p′₀ = 200 kPa: q against axial strain",
        "axial strain ε_a (compression +)",
        "q (kPa)",
        &[
            Series {
                name: "drained 3Mp′₀/(3 − M)".into(),
                points: vec![(0.0, q_f / 1e3), (0.6, q_f / 1e3)],
                markers: false,
            },
            Series {
                name: "drained, loam".into(),
                points: q_axial(drained_states),
                markers: true,
            },
            Series {
                name: "undrained, loam".into(),
                points: q_axial(undrained),
                markers: true,
            },
        ],
    )?;
    let png_e = out.join("triaxial_mcc_e_ln_p.png");
    let e_ln_p: Vec<(f64, f64)> = (oedometer.iter())
        .map(|s| (s.measures().p.ln(), v0 * s.f.determinant() - 1.0))
        .collect();
    write_plot(
        &png_e,
        "Modified Cam-Clay: oedometer loading, unloading, reloading",
        "ln p′ (p′ in Pa)",
        "void ratio e",
        &[Series {
            name: "loam".into(),
            points: e_ln_p,
            markers: true,
        }],
    )?;
    Ok(vec![csv, png_pq, png_q, png_e])
}
