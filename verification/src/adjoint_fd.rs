//! `adjoint-fd`: the discrete adjoint's gradient against forward-mode duals, central finite
//! differences and the Taylor test, on short runs of four scenes with USL and MUSL.
//!
//! Scenes (`verification/scenes/adjoint_*.toml`, ≤ 200 steps at full size):
//!
//! - `adjoint_fluid`: a water dam break (MLS-MPM) over three Coulomb floor segments; the
//!   unknowns are the three μ, the viscosity, the sound speed, gravity and the initial
//!   horizontal velocity; the loss tracks particles and two velocity monitors;
//! - `adjoint_block`: a Neo-Hookean block (APIC, uGIMP) between slip walls thrown at a moving
//!   obstacle; E, ν, gravity, the initial horizontal velocity;
//! - `adjoint_column`: a Drucker–Prager column (FLIP, cubic B-splines) collapsing on a Coulomb
//!   floor; φ, c, E, gravity and the floor's μ;
//! - `adjoint_block_3d`: a 3D Neo-Hookean block (TPIC) thrown along a floor; E, ν, the density,
//!   gravity, the initial horizontal velocity.
//!
//! The loss is that of an inversion ([`Observations`]): the positions of every third particle
//! and (fluid) the mean velocity in two boxes, every tenth step, recorded from a run at the
//! scene's values; the gradient is taken at values 5 % away from them, so the loss and its
//! gradient are not zero.
//!
//! Metrics per scene and scheme:
//!
//! - the largest relative difference between the adjoint gradient and the forward-mode dual
//!   derivative (`Problem::dual_derivative`), **≤ 1e-10**: both are the exact derivative of
//!   the same discrete map and differ only by the order of nodal sums (the adjoint recomputes
//!   the grid serially), so anything above round-off is a bug;
//! - the largest relative difference between the dual derivative and a central difference
//!   (`loam_inverse::check::central_difference`: Richardson-extrapolated, at the largest step
//!   δ ≤ 10⁻⁴ |θ| whose perturbed runs take the same branches in every step), **≤ 1e-6**: the
//!   truncation error O(δ⁴) is below 1e-12 relative and the round-off of a loss of order one
//!   over δ ≈ 10⁻⁴ |θ| about 1e-10, so 1e-6 leaves room for losses that move little with a
//!   parameter while catching a derivative that is wrong in any digit that matters;
//! - the Taylor test along a direction `d` over the smooth unknowns (material constants,
//!   gravity, initial velocity; `d_k = ±max(|θ_k|, 10⁻³)`): the remainder
//!   `r(h) = |L(θ + h d) − L(θ) − h ∇L·d|` at `h₀, h₀/2, h₀/4, h₀/8`, at the largest `h₀` of
//!   1e-2, 1e-3, …, 1e-6 whose runs keep the branches; its observed order
//!   `log₂(r(h₀)/r(h₀/8))/3` must be **≥ 1.8** (2 for a correct gradient; a wrong one gives 1);
//! - the same along the friction coefficients at `h₀ = 10⁻²` without regard to branches, as
//!   information: the loss is piecewise smooth in μ (nodes switch between stick and slip
//!   within the step), so the order shows the kinks.

use crate::{CaseReport, Metric, Size, VerifyError, scenes, write_csv, write_text};
use loam_core::Scheme;
use loam_core::tensor::Vector;
use loam_inverse::{
    AdjointError, Checkpoints, Control, MaterialField, MonitorBox, Observations, Param, Problem,
    check,
};
use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::Path;

const CASE: &str = "adjoint-fd";

/// One scene of the case.
struct Spec {
    /// Short label in the metric names.
    label: &'static str,
    /// The stem of its file in `verification/scenes/`.
    file: &'static str,
    /// Steps at reduced and at full size.
    steps: (usize, usize),
    /// Parameters over which the loss is smooth where the branches are kept.
    smooth: &'static [Param],
    /// Friction coefficients: the Taylor test along them is information.
    friction: &'static [Param],
    /// Whether the initial horizontal velocity is an unknown (a smooth one).
    velocity: bool,
    /// Velocity monitor boxes `(lo, hi)` of the loss (2D only).
    monitors: &'static [([f64; 2], [f64; 2])],
}

const SPECS_2D: [Spec; 3] = [
    Spec {
        label: "fluid",
        file: "adjoint_fluid",
        steps: (60, 200),
        smooth: &[
            Param::Material(0, MaterialField::Viscosity),
            Param::Material(0, MaterialField::SoundSpeed),
            Param::Gravity(1),
        ],
        friction: &[Param::Friction(0), Param::Friction(1), Param::Friction(2)],
        velocity: true,
        monitors: &[([0.04, 0.0], [0.1, 0.04]), ([0.1, 0.0], [0.2, 0.06])],
    },
    Spec {
        label: "block",
        file: "adjoint_block",
        steps: (40, 100),
        smooth: &[
            Param::Material(0, MaterialField::Young),
            Param::Material(0, MaterialField::Poisson),
            Param::Gravity(1),
        ],
        friction: &[],
        velocity: true,
        monitors: &[],
    },
    Spec {
        label: "column",
        file: "adjoint_column",
        steps: (60, 200),
        smooth: &[
            Param::Material(0, MaterialField::FrictionAngle),
            Param::Material(0, MaterialField::Cohesion),
            Param::Material(0, MaterialField::Young),
            Param::Gravity(1),
        ],
        friction: &[Param::Friction(0)],
        velocity: false,
        monitors: &[],
    },
];

const SPEC_3D: Spec = Spec {
    label: "block-3d",
    file: "adjoint_block_3d",
    steps: (30, 100),
    smooth: &[
        Param::Material(0, MaterialField::Young),
        Param::Material(0, MaterialField::Poisson),
        Param::Material(0, MaterialField::Density),
        Param::Gravity(1),
    ],
    friction: &[],
    velocity: true,
    monitors: &[],
};

/// The first steps of the Taylor test over the smooth unknowns, relative, largest first.
const TAYLOR_STEPS: [f64; 5] = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6];
/// Remainders per Taylor test (`h₀` halved three times).
const TAYLOR_COUNT: usize = 4;

/// One unknown's row of the table.
struct Row {
    name: String,
    adjoint: f64,
    dual: f64,
    difference: Option<check::Difference>,
    /// The scale of relative differences, `max(|dual|, 10⁻¹² L)`.
    scale: f64,
}

/// What one scene with one scheme gave.
struct Outcome {
    label: String,
    steps: usize,
    particles: usize,
    loss: f64,
    rows: Vec<Row>,
    smooth: check::Taylor,
    friction: Option<check::Taylor>,
    wall: f64,
}

fn adjoint_error(e: AdjointError) -> VerifyError {
    VerifyError::Adjoint {
        case: CASE.into(),
        source: e,
    }
}

/// Runs the checks of `spec` with `scheme`.
fn check_scene<const D: usize>(
    spec: &Spec,
    scheme: Scheme,
    size: Size,
) -> Result<Outcome, VerifyError> {
    let start = std::time::Instant::now();
    let mut scene = scenes::scene(spec.file);
    scene.solver.scheme = Some(scheme);
    let built = scenes::build::<D>(&scene);
    let config = built.explicit_config().expect("an explicit scene");
    let particles = built.particles;
    let steps = match size {
        Size::Reduced => spec.steps.0,
        Size::Full => spec.steps.1,
    };
    let boxes = (spec.monitors.iter())
        .map(|(lo, hi)| MonitorBox {
            lo: Vector::from_fn(|a, _| lo[a]),
            hi: Vector::from_fn(|a, _| hi[a]),
            edge: scene.grid.cell_size,
        })
        .collect();
    let observed: BTreeSet<usize> = (10..=steps).step_by(10).collect();
    let ids: Vec<usize> = (0..particles.len()).step_by(3).collect();
    let objective = Observations::record(
        &config,
        &particles,
        steps,
        &observed,
        &ids,
        Observations::with_monitors(boxes),
    )
    .map_err(adjoint_error)?;
    let mut controls: Vec<Control> = (spec.smooth.iter().chain(spec.friction))
        .map(|&p| Control::Param(p))
        .collect();
    if spec.velocity {
        let mut direction = vec![0.0; D];
        direction[0] = 1.0;
        controls.push(Control::InitialVelocity {
            material: None,
            direction,
        });
    }
    let problem = Problem {
        config,
        initial: particles,
        steps,
        controls,
        objective,
        checkpoints: Checkpoints::Least,
    };
    let truth = problem.values().map_err(adjoint_error)?;
    // 5 % away from the observed run, alternately above and below.
    let theta: Vec<f64> = (truth.iter().enumerate())
        .map(|(k, t)| t * if k % 2 == 0 { 1.05 } else { 0.95 })
        .collect();
    let (loss, grad) = problem.gradient(&theta).map_err(adjoint_error)?;
    let mut rows = Vec::new();
    for (k, control) in problem.controls.iter().enumerate() {
        let dual = problem.dual_derivative(&theta, k).map_err(adjoint_error)?;
        let difference = check::central_difference(&problem, &theta, k).map_err(adjoint_error)?;
        rows.push(Row {
            name: match control {
                Control::Param(p) => p.to_string(),
                Control::InitialVelocity { .. } => "velocity[0]".into(),
                Control::K0 { material } => format!("materials[{material}].k0"),
                Control::VelocityField(_) => {
                    unreachable!("the adjoint-fd scenes have one unknown per control")
                }
            },
            adjoint: grad[k],
            dual,
            difference,
            scale: dual.abs().max(1e-12 * loss.abs()),
        });
    }
    // A direction over a subset of the unknowns, ±max(|θ_k|, 10⁻³) on it.
    let direction = |on: &dyn Fn(usize) -> bool| -> Vec<f64> {
        (theta.iter().enumerate())
            .map(|(k, t)| {
                let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
                if on(k) { sign * t.abs().max(1e-3) } else { 0.0 }
            })
            .collect()
    };
    let slope = |d: &[f64]| d.iter().zip(&grad).map(|(d, g)| d * g).sum::<f64>();
    let n_smooth = spec.smooth.len();
    let n_friction = spec.friction.len();
    let is_friction = |k: usize| (n_smooth..n_smooth + n_friction).contains(&k);
    let d_smooth = direction(&|k| !is_friction(k));
    let smooth = check::taylor_test(
        &problem,
        &theta,
        loss,
        slope(&d_smooth),
        &d_smooth,
        &TAYLOR_STEPS,
        TAYLOR_COUNT,
    )
    .map_err(adjoint_error)?;
    let friction = if n_friction > 0 {
        let d = direction(&is_friction);
        let h0 = TAYLOR_STEPS[0];
        let remainders =
            check::taylor_remainders(&problem, &theta, loss, slope(&d), &d, h0, TAYLOR_COUNT)
                .map_err(adjoint_error)?;
        Some(check::Taylor {
            h0,
            remainders,
            same_branches: false,
        })
    } else {
        None
    };
    let scheme_name = match scheme {
        Scheme::Usl => "USL",
        Scheme::Musl => "MUSL",
    };
    Ok(Outcome {
        label: format!("{} {scheme_name}", spec.label),
        steps,
        particles: problem.initial.len(),
        loss,
        rows,
        smooth,
        friction,
        wall: start.elapsed().as_secs_f64(),
    })
}

/// Runs the case.
pub fn run(size: Size, dir: &Path) -> Result<CaseReport, VerifyError> {
    let mut outcomes = Vec::new();
    for scheme in [Scheme::Usl, Scheme::Musl] {
        for spec in &SPECS_2D {
            outcomes.push(check_scene::<2>(spec, scheme, size)?);
        }
        outcomes.push(check_scene::<3>(&SPEC_3D, scheme, size)?);
    }
    let mut metrics = Vec::new();
    let mut md = String::from(
        "| scene | steps | particles | L | unknown | adjoint | dual | rel. diff | central diff. (δ/|θ|) | rel. diff |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut csv_rows = Vec::new();
    for (i, o) in outcomes.iter().enumerate() {
        let rel_dual = (o.rows.iter())
            .map(|r| (r.adjoint - r.dual).abs() / r.scale)
            .fold(0.0, f64::max);
        let rel_fd = (o.rows.iter())
            .filter_map(|r| r.difference.map(|d| (d.value - r.dual).abs() / r.scale))
            .fold(0.0, f64::max);
        let missing = o.rows.iter().filter(|r| r.difference.is_none()).count();
        metrics.push(Metric::at_most(
            CASE,
            &format!("{}: max rel |adjoint − dual|", o.label),
            rel_dual,
            1e-10,
        ));
        metrics.push(Metric::at_most(
            CASE,
            &format!("{}: max rel |dual − central diff.|", o.label),
            rel_fd,
            1e-6,
        ));
        // Every unknown must have a step that keeps the branches, or the difference
        // check would silently skip it.
        metrics.push(Metric::at_most(
            CASE,
            &format!("{}: unknowns without a difference", o.label),
            missing as f64,
            0.0,
        ));
        metrics.push(Metric::at_least(
            CASE,
            &format!("{}: Taylor order, smooth unknowns", o.label),
            o.smooth.order(),
            1.8,
        ));
        if let Some(f) = &o.friction {
            metrics.push(Metric::info(
                CASE,
                &format!("{}: Taylor order, friction (h₀ = 1e-2)", o.label),
                f.order(),
            ));
        }
        for r in &o.rows {
            let (fd, step, rel) = match r.difference {
                Some(d) => (
                    format!("{:.10e} ({:.0e})", d.value, d.relative_step),
                    d.relative_step,
                    format!("{:.1e}", (d.value - r.dual).abs() / r.scale),
                ),
                None => (
                    "— (every step switches a branch)".into(),
                    f64::NAN,
                    "—".into(),
                ),
            };
            writeln!(
                md,
                "| {} | {} | {} | {:.4e} | {} | {:.10e} | {:.10e} | {:.1e} | {fd} | {rel} |",
                o.label,
                o.steps,
                o.particles,
                o.loss,
                r.name,
                r.adjoint,
                r.dual,
                (r.adjoint - r.dual).abs() / r.scale,
            )
            .expect("writing to a String");
            csv_rows.push(vec![
                i as f64,
                r.adjoint,
                r.dual,
                r.difference.map_or(f64::NAN, |d| d.value),
                step,
            ]);
        }
    }
    md.push_str(
        "\nTaylor remainders r(h) = |L(θ + h d) − L(θ) − h ∇L·d| at h₀, h₀/2, h₀/4, h₀/8 (h relative to |θ|):\n\n| scene | direction | h₀ | same branches | r(h₀) | r(h₀/2) | r(h₀/4) | r(h₀/8) | order | wall (s) |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for o in &outcomes {
        let tests = [
            ("smooth", Some(&o.smooth)),
            ("friction", o.friction.as_ref()),
        ];
        for (name, t) in tests {
            let Some(t) = t else { continue };
            let r: Vec<String> = t.remainders.iter().map(|r| format!("{r:.3e}")).collect();
            writeln!(
                md,
                "| {} | {name} | {:.0e} | {} | {} | {:.2} | {:.1} |",
                o.label,
                t.h0,
                if t.same_branches {
                    "yes"
                } else {
                    "not required"
                },
                r.join(" | "),
                t.order(),
                o.wall
            )
            .expect("writing to a String");
        }
    }
    let table = dir.join("adjoint_fd.md");
    write_text(&table, &md)?;
    let csv = dir.join("adjoint_fd.csv");
    write_csv(
        &csv,
        &[
            "run",
            "adjoint",
            "dual",
            "central_difference",
            "relative_step",
        ],
        &csv_rows,
    )?;
    Ok(CaseReport {
        metrics,
        files: vec![table, csv],
    })
}
