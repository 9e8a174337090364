//! The discrete adjoint against forward-mode duals and central finite differences.
//!
//! Each scene is a short run (tens of steps) of a small scene file; the loss is the squared
//! distance of a few tracked particles from fixed points at three steps. For every parameter
//! the adjoint gradient must equal the derivative of the forward-mode dual run
//! (`Solver<Dual64, D>` on the configuration lifted with that parameter seeded): both are the
//! exact derivative of the same discrete map, so they agree to round-off (1e-10 relative; the
//! two differ only in the order of the nodal sums, the adjoint recomputing the grid serially).
//! A central finite difference (`loam_inverse::check::central_difference`:
//! Richardson-extrapolated, truncation O(δ⁴)) checks the dual oracle itself, to 1e-6 relative,
//! at the largest step δ ≤ 10⁻⁴ |θ| whose perturbed runs take the forward run's branches in
//! every step (the map is piecewise smooth: across a stick/slip or yield switch a difference
//! measures the jump). The step is a compromise: a loss of order one that moves by 1e-11 when the viscosity
//! moves by δ = 5e-8 loses its difference in the round-off of the run (plain central
//! difference against the dual on the fluid scene: 5e-11 at δ = 10⁻³ |θ|, 1e-7 at 10⁻⁴, 1e-5
//! at 10⁻⁶, 1e-3 at 10⁻⁸), while ν of the Neo-Hookean block has a large third derivative
//! (3.7e-6 at 10⁻³, 3e-8 at 3·10⁻⁴, 1e-9 at 10⁻⁴).

use loam_core::Particles;
use loam_core::tensor::Vector;
use loam_explicit::Solver;
use loam_inverse::{
    Checkpoints, Control, MaterialField, Objective, Param, Problem, ScalarObjective,
    TrackedPositions, check, gradient, run_collected,
};
use num_dual::Dual64;
use std::collections::BTreeMap;

use crate::common::{FLUID_2D, scene};

/// Tracked particles (every `stride`-th) pulled towards `target` at three steps.
fn objective<const D: usize>(
    n: usize,
    steps: usize,
    stride: usize,
    target: [f64; D],
) -> TrackedPositions<D> {
    let ids: Vec<(usize, Vector<f64, D>)> = (0..n)
        .step_by(stride)
        .map(|p| (p, Vector::from(target)))
        .collect();
    let targets: BTreeMap<usize, Vec<(usize, Vector<f64, D>)>> = [steps / 3, 2 * steps / 3, steps]
        .into_iter()
        .map(|s| (s, ids.clone()))
        .collect();
    TrackedPositions {
        targets,
        weight: 1.0,
    }
}

/// Checks every parameter and the initial velocity (x component, every particle) as the
/// unknowns of a [`Problem`]: adjoint = dual to 1e-10, and dual = central difference
/// ([`check::central_difference`]) to 1e-6 except for those in `no_difference`.
fn check<const D: usize>(
    toml: &str,
    steps: usize,
    stride: usize,
    target: [f64; D],
    params: &[Param],
    no_difference: &[Param],
) -> (Problem<D, TrackedPositions<D>>, Vec<f64>) {
    let (config, particles) = scene::<D>(toml);
    let objective = objective(particles.len(), steps, stride, target);
    let mut direction = [0.0; D];
    direction[0] = 1.0;
    let controls: Vec<Control> = (params.iter().map(|&p| Control::Param(p)))
        .chain([Control::InitialVelocity {
            material: None,
            direction: direction.to_vec(),
        }])
        .collect();
    let mut problem = Problem {
        config,
        initial: particles,
        steps,
        controls,
        objective,
        checkpoints: Checkpoints::Least,
    };
    let theta = problem.values().expect("values");
    let (loss, grad) = problem.gradient(&theta).expect("gradient");
    let plain = problem.loss(&theta).expect("loss");
    assert!(
        (loss - plain).abs() <= 1e-12 * plain.abs(),
        "loss {loss} vs {plain}"
    );
    for (k, control) in problem.controls.iter().enumerate() {
        let dual = problem.dual_derivative(&theta, k).expect("dual");
        let adj = grad[k];
        let scale = dual.abs().max(1e-12 * loss.abs());
        println!("{control:?}: adjoint {adj:.12e}, dual {dual:.12e}");
        assert!(
            (adj - dual).abs() <= 1e-10 * scale,
            "{control:?}: adjoint {adj:e} vs dual {dual:e}"
        );
        let Control::Param(param) = control else {
            continue;
        };
        if !no_difference.contains(param) {
            let fd = check::central_difference(&problem, &theta, k)
                .expect("difference")
                .unwrap_or_else(|| panic!("{param}: every perturbation switches a branch"));
            println!(
                "{param}: central difference {:.12e} (δ = {:e} |θ|)",
                fd.value, fd.relative_step
            );
            assert!(
                (fd.value - dual).abs() <= 1e-6 * scale,
                "{param}: central difference {:e} vs dual {dual:e}",
                fd.value
            );
        }
    }
    gauss_newton(&problem, &theta, loss, &grad);
    // The segment length does not change the result (checkpointing is exact): one step, a
    // length that does not divide the run, the whole run traced in one forward pass (a budget
    // it fits in).
    for checkpoints in [
        Checkpoints::Segment(1),
        Checkpoints::Segment(3),
        Checkpoints::Memory(u64::MAX),
    ] {
        problem.checkpoints = checkpoints;
        assert_eq!(problem.gradient(&theta).expect("gradient").1, grad);
    }
    (problem, theta)
}

/// The Gauss–Newton model from the residuals' dual Jacobian ([`Problem::gauss_newton`]):
/// its `L = Σ r²` is the loss and its `2 Jᵀr` the adjoint's gradient (the same exact
/// derivative, summed in another order: 1e-10 relative).
fn gauss_newton<const D: usize>(
    problem: &Problem<D, TrackedPositions<D>>,
    theta: &[f64],
    loss: f64,
    grad: &[f64],
) {
    let model = problem.gauss_newton(theta).expect("Gauss–Newton model");
    assert!(
        (model.loss - loss).abs() <= 1e-12 * loss,
        "{} vs {loss}",
        model.loss
    );
    let scale = grad.iter().fold(0.0_f64, |m, g| m.max(g.abs()));
    for (k, (a, b)) in model.gradient.iter().zip(grad).enumerate() {
        assert!(
            (a - b).abs() <= 1e-10 * scale,
            "unknown {k}: 2Jᵀr {a:e} vs adjoint {b:e}"
        );
    }
}

/// The diagonal entry `2 ‖J_k‖²` of the Gauss–Newton matrix against the central difference
/// `J_k ≈ (r(θ + δe_k) − r(θ − δe_k)) / 2δ` of the residuals (δ = 10⁻⁴ |θ_k|; truncation
/// O(δ²) ≈ 1e-8 relative on this smooth fluid run, whose perturbed runs keep the forward
/// run's stick/slip branches; 1e-5 leaves room for the round-off of the difference).
fn gauss_newton_diagonal<const D: usize>(
    problem: &Problem<D, TrackedPositions<D>>,
    theta: &[f64],
    k: usize,
) {
    let h = problem
        .gauss_newton(theta)
        .expect("Gauss–Newton model")
        .matrix[k * theta.len() + k];
    let delta = 1e-4 * theta[k].abs();
    let residuals = |step: f64| {
        let mut at = theta.to_vec();
        at[k] += step;
        let (config, particles) = problem.setup(&at).expect("setup");
        run_collected(config, particles, problem.steps, |s, p, out| {
            problem.objective.residuals(s, p, out)
        })
        .expect("run")
    };
    let (plus, minus) = (residuals(delta), residuals(-delta));
    let column: f64 = (plus.iter().zip(&minus))
        .map(|(p, m)| ((p - m) / (2.0 * delta)).powi(2))
        .sum();
    assert!(
        (2.0 * column - h).abs() <= 1e-5 * h,
        "H_kk {h:e} vs difference {:e}",
        2.0 * column
    );
}

#[test]
fn fluid_mls_on_friction_segments() {
    let params = [
        Param::Friction(0),
        Param::Friction(1),
        Param::Gravity(1),
        Param::Material(0, MaterialField::SoundSpeed),
        Param::Material(0, MaterialField::Viscosity),
        Param::Material(0, MaterialField::Gamma),
        Param::Material(0, MaterialField::Density),
    ];
    let (problem, theta) = check::<2>(FLUID_2D, 60, 7, [0.3, 0.02], &params, &[]);
    gauss_newton_diagonal(&problem, &theta, 0);
}

/// A Neo-Hookean block (APIC with uGIMP: the affine matrix is the velocity gradient) thrown
/// at a moving box with friction, between bilateral slip walls.
const BLOCK_2D: &str = r#"
[grid]
lo = [0.0, 0.0]
hi = [0.5, 0.3]
cell_size = 0.025
shape_function = "ugimp"

[[materials]]
name = "rubber"
model = "neo_hookean"
density = 1000.0
youngs_modulus = 2.0e5
poisson_ratio = 0.3

[[bodies]]
material = "rubber"
shape = { type = "box", lo = [0.05, 0.05], hi = [0.15, 0.15] }
particles_per_cell = 2
velocity = [2.0, 0.5]

[[obstacles]]
shape = "box"
lo = [0.22, 0.0]
hi = [0.3, 0.3]
velocity = [-0.5, 0.0]
friction = 0.2

[boundaries]
x_min = "slip"
x_max = "slip"
y_min = "slip"
y_max = "slip"

[loads]
gravity = [0.0, -9.81]

[solver]
type = "explicit"
scheme = "usl"
transfer = "apic"
time_step = { type = "fixed", dt = 1e-3 }
end_time = 0.04
"#;

#[test]
fn neo_hookean_block_against_a_moving_obstacle() {
    let params = [
        Param::Material(0, MaterialField::Young),
        Param::Material(0, MaterialField::Poisson),
        Param::ObstacleVelocity(0, 0),
        Param::ObstacleFriction(0),
        Param::Gravity(1),
    ];
    // The obstacle's velocity also moves its surface, and the contact layer's node set
    // changes with it (a branch switch at any δ here): its derivative, through the pushed
    // velocity and the moving normal, is checked against the dual run only in this scene and
    // against a converged central difference in `tests/obstacle_velocity.rs`.
    let no_difference = [Param::ObstacleVelocity(0, 0)];
    check::<2>(BLOCK_2D, 40, 3, [0.25, 0.2], &params, &no_difference);
}

/// A Drucker–Prager column (FLIP, cubic B-splines) collapsing on a Coulomb floor.
const SAND_2D: &str = r#"
[grid]
lo = [0.0, 0.0]
hi = [0.4, 0.2]
cell_size = 0.02
shape_function = "cubic_bspline"

[[materials]]
name = "sand"
model = "drucker_prager"
density = 1800.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
friction_angle = 30.0
dilation_angle = 5.0
cohesion = 50.0

[[bodies]]
material = "sand"
shape = { type = "box", lo = [0.0, 0.0], hi = [0.08, 0.12] }
particles_per_cell = 2

[boundaries]
x_min = "slip"
x_max = "slip"
y_min = { kind = "slip", separable = true }
y_max = "slip"

[[friction]]
wall = "y_min"
mu = 0.4
from = [0.0]
to = [0.4]

[loads]
gravity = [0.0, -9.81]

[solver]
type = "explicit"
scheme = "usl"
transfer = { type = "flip", alpha = 0.9 }
time_step = { type = "fixed", dt = 5e-4 }
end_time = 0.03
"#;

#[test]
fn drucker_prager_column_with_flip() {
    let params = [
        Param::Material(0, MaterialField::FrictionAngle),
        Param::Material(0, MaterialField::Cohesion),
        Param::Material(0, MaterialField::DilationAngle),
        Param::Material(0, MaterialField::Young),
        Param::Friction(0),
    ];
    check::<2>(SAND_2D, 60, 5, [0.2, 0.0], &params, &[]);
}

/// A 3D Neo-Hookean block (TPIC) falling onto a separable floor.
const BLOCK_3D: &str = r#"
[grid]
lo = [0.0, 0.0, 0.0]
hi = [0.2, 0.2, 0.2]
cell_size = 0.04
shape_function = "quadratic_bspline"

[[materials]]
name = "rubber"
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e5
poisson_ratio = 0.3

[[bodies]]
material = "rubber"
shape = { type = "box", lo = [0.04, 0.0, 0.04], hi = [0.12, 0.08, 0.12] }
particles_per_cell = 2
velocity = [0.5, -0.5, 0.2]

[boundaries]
x_min = "slip"
x_max = "slip"
y_min = { kind = "slip", separable = true }
y_max = "slip"
z_min = "no_slip"
z_max = "slip"

[loads]
gravity = [0.0, -9.81, 0.0]

[solver]
type = "explicit"
scheme = "usl"
transfer = "tpic"
time_step = { type = "fixed", dt = 1e-3 }
end_time = 0.03
"#;

#[test]
fn neo_hookean_block_3d_with_tpic() {
    let params = [
        Param::Material(0, MaterialField::Young),
        Param::Gravity(1),
        Param::Material(0, MaterialField::Density),
    ];
    check::<3>(BLOCK_3D, 30, 5, [0.15, 0.0, 0.1], &params, &[]);
}

/// A loss that is not a position: the objective's own adjoint is what the reverse pass
/// starts from, so any `Objective` works (here the kinetic energy at the last step).
struct Kinetic {
    step: usize,
}

impl<const D: usize> Objective<D> for Kinetic {
    fn term(
        &self,
        step: usize,
        p: &Particles<f64, D>,
        adjoint: Option<&mut loam_inverse::ParticleAdjoint<D>>,
    ) -> f64 {
        if step != self.step {
            return 0.0;
        }
        if let Some(a) = adjoint {
            for i in 0..p.len() {
                a.v[i] += p.v[i] * p.mass[i];
                a.mass[i] += 0.5 * p.v[i].norm_squared();
            }
        }
        p.kinetic_energy()
    }
}

#[test]
fn kinetic_energy_gradient_matches_the_dual_run() {
    let (config, particles) = scene::<2>(FLUID_2D);
    let steps = 40;
    let param = Param::Friction(1);
    let grad = gradient(
        &config,
        &particles,
        steps,
        &[param],
        &Kinetic { step: steps },
        Checkpoints::Least,
    )
    .expect("gradient");
    let mut solver = Solver::new(param.seeded(&config).unwrap(), &particles.lift()).unwrap();
    let mut p: Particles<Dual64, 2> = particles.lift();
    for _ in 0..steps {
        solver.step(&mut p, f64::INFINITY).unwrap();
    }
    let dual = p.kinetic_energy().eps;
    assert!(
        (grad.params[0] - dual).abs() <= 1e-10 * dual.abs(),
        "{} vs {dual}",
        grad.params[0]
    );
}

/// `toml` with MUSL instead of USL.
fn musl(toml: &str) -> String {
    toml.replace("scheme = \"usl\"", "scheme = \"musl\"")
}

#[test]
fn musl_fluid_apic_on_friction_segments() {
    let toml = musl(FLUID_2D).replace("transfer = \"mls\"", "transfer = \"apic\"");
    let params = [
        Param::Friction(0),
        Param::Friction(1),
        Param::Gravity(1),
        Param::Material(0, MaterialField::SoundSpeed),
        Param::Material(0, MaterialField::Viscosity),
    ];
    check::<2>(&toml, 60, 7, [0.3, 0.02], &params, &[]);
}

#[test]
fn musl_fluid_mls() {
    let params = [
        Param::Friction(1),
        Param::Material(0, MaterialField::SoundSpeed),
    ];
    check::<2>(&musl(FLUID_2D), 40, 7, [0.3, 0.02], &params, &[]);
}

#[test]
fn musl_neo_hookean_block_against_a_moving_obstacle() {
    let params = [
        Param::Material(0, MaterialField::Young),
        Param::ObstacleVelocity(0, 0),
        Param::ObstacleFriction(0),
    ];
    let no_difference = [Param::ObstacleVelocity(0, 0)];
    check::<2>(&musl(BLOCK_2D), 40, 3, [0.25, 0.2], &params, &no_difference);
}

#[test]
fn musl_drucker_prager_column_with_flip() {
    let params = [
        Param::Material(0, MaterialField::FrictionAngle),
        Param::Material(0, MaterialField::Cohesion),
        Param::Friction(0),
    ];
    check::<2>(&musl(SAND_2D), 60, 5, [0.2, 0.0], &params, &[]);
}

#[test]
fn musl_neo_hookean_block_3d_with_tpic() {
    let params = [Param::Material(0, MaterialField::Young), Param::Gravity(1)];
    check::<3>(&musl(BLOCK_3D), 30, 5, [0.15, 0.0, 0.1], &params, &[]);
}

/// The gradient has the same bits with one worker thread and with two: the scatters add in
/// particle order and the parameters' shares in chunk order.
#[test]
fn gradient_bits_do_not_depend_on_the_thread_count() {
    let (config, particles) = scene::<2>(&musl(SAND_2D));
    let obj = objective(particles.len(), 20, 5, [0.2, 0.0]);
    let params = [
        Param::Material(0, MaterialField::FrictionAngle),
        Param::Friction(0),
        Param::Gravity(1),
    ];
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                gradient(&config, &particles, 20, &params, &obj, Checkpoints::Least).unwrap()
            })
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one.params, two.params);
    assert_eq!(one.initial, two.initial);
}

/// With an adaptive step the reverse pass holds each step's Δt at the forward's value, as the
/// dual run does (the step size is chosen on real parts): the two agree to round-off. A
/// central difference would also see the step sizes move, so it is not compared here.
#[test]
fn adaptive_steps_are_held_fixed_like_the_dual_run() {
    let toml = BLOCK_2D.replace(
        "time_step = { type = \"fixed\", dt = 1e-3 }",
        "time_step = { type = \"adaptive\", cfl = 0.4, max_dt = 1e-3 }",
    );
    let params = [Param::Material(0, MaterialField::Young), Param::Gravity(1)];
    check::<2>(&toml, 40, 3, [0.25, 0.2], &params, &params);
}
