//! The derivative with respect to a moving obstacle's velocity against a converged central
//! difference.
//!
//! A moving obstacle's surface at time `t` is its shape at `x − v_o t`: its velocity enters
//! the contact law as the velocity the material is pushed to, and through the position of the
//! surface, whose normal at a node turns as a curved obstacle moves by `v_o t`. The adjoint
//! and the forward-mode dual run must carry both; when the second is dropped they still agree
//! with each other (they differentiate the same incomplete map) but not with the loss: here
//! the horizontal component was 1.68× the difference in 2D and 1.63× in 3D. The reference is
//! therefore a central difference of the loss itself, branch-aware and Richardson-extrapolated
//! (`check::converged_difference`), and converged: the estimates at two steps a decade apart
//! agree to 1e-6. The loss (squared displacements of every particle after the run) is smooth
//! over those steps: the perturbed runs keep every contact branch of the run at the point.
//!
//! Tolerances: adjoint = dual to 1e-10 relative (the same exact derivative, summed in another
//! order); dual = central difference to 1e-6 relative, the convergence of the difference
//! itself (measured spreads 5e-12 to 7e-9: truncation O(δ⁴) and the round-off of the loss
//! over δ), far below the error of a derivative that misses the obstacle's motion.

use crate::common::scene;
use loam_core::Particles;
use loam_core::tensor::Vector;
use loam_inverse::{Checkpoints, Control, Param, Problem, TrackedPositions, check};
use std::collections::BTreeMap;

/// Water at rest in a slip-walled tank, a disk of radius 0.04 m coming down into it at
/// (0.2, −0.8) m/s from 1 cm above the surface, with friction.
const POOL_2D: &str = r#"
[grid]
lo = [0.0, 0.0]
hi = [0.4, 0.3]
cell_size = 0.02
shape_function = "quadratic_bspline"

[[materials]]
name = "water"
model = "fluid"
density = 1000.0
sound_speed = 10.0
gamma = 7.0
viscosity = 0.05

[[bodies]]
material = "water"
shape = { type = "box", lo = [0.0, 0.0], hi = [0.4, 0.1] }
particles_per_cell = 2

[[obstacles]]
shape = "cylinder"
centre = [0.2, 0.15]
radius = 0.04
velocity = [0.2, -0.8]
friction = 0.1

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
transfer = "mls"
time_step = { type = "fixed", dt = 5e-4 }
end_time = 0.03
"#;

/// The same in 3D: a cylinder along z, as long as the tank is deep, pushed sideways and down
/// into the water.
const POOL_3D: &str = r#"
[grid]
lo = [0.0, 0.0, 0.0]
hi = [0.2, 0.2, 0.1]
cell_size = 0.025
shape_function = "quadratic_bspline"

[[materials]]
name = "water"
model = "fluid"
density = 1000.0
sound_speed = 10.0
gamma = 7.0
viscosity = 0.05

[[bodies]]
material = "water"
shape = { type = "box", lo = [0.0, 0.0, 0.0], hi = [0.2, 0.075, 0.1] }
particles_per_cell = 2

[[obstacles]]
shape = "cylinder"
centre = [0.1, 0.12, 0.05]
radius = 0.03
axis = "z"
length = 0.1
velocity = [0.3, -1.0, 0.0]
friction = 0.0

[boundaries]
x_min = "slip"
x_max = "slip"
y_min = "slip"
y_max = "slip"
z_min = "slip"
z_max = "slip"

[loads]
gravity = [0.0, -9.81, 0.0]

[solver]
type = "explicit"
scheme = "usl"
transfer = "mls"
time_step = { type = "fixed", dt = 5e-4 }
end_time = 0.02
"#;

/// `Σ_p ‖x_p − x_p(0)‖²` after `steps` steps: every particle's squared displacement.
fn displacements<const D: usize>(
    particles: &Particles<f64, D>,
    steps: usize,
) -> TrackedPositions<D> {
    let ids: Vec<(usize, Vector<f64, D>)> = particles.x.iter().copied().enumerate().collect();
    TrackedPositions {
        targets: BTreeMap::from([(steps, ids)]),
        weight: 1.0,
    }
}

/// Checks the derivatives with respect to `params` by the adjoint, the dual run and the
/// converged central difference, with USL and MUSL.
fn check_scene<const D: usize>(toml: &str, steps: usize, params: &[Param]) {
    for musl in [false, true] {
        let text = if musl {
            toml.replace("scheme = \"usl\"", "scheme = \"musl\"")
        } else {
            toml.to_owned()
        };
        let (config, particles) = scene::<D>(&text);
        let objective = displacements(&particles, steps);
        let problem = Problem {
            config,
            initial: particles,
            steps,
            controls: params.iter().map(|&p| Control::Param(p)).collect(),
            objective,
            checkpoints: Checkpoints::Least,
        };
        let theta = problem.values().expect("values");
        let (loss, grad) = problem.gradient(&theta).expect("gradient");
        assert!(loss > 0.0);
        for (k, param) in params.iter().enumerate() {
            let dual = problem.dual_derivative(&theta, k).expect("dual");
            let c = check::converged_difference(&problem, &theta, k).expect("difference");
            println!(
                "{D}D {} {param}: adjoint {:.12e}, dual {dual:.12e}, central differences {:?} \
                 (spread {:.1e})",
                if musl { "MUSL" } else { "USL" },
                grad[k],
                c.estimates
                    .iter()
                    .map(|e| e.map(|d| format!("{:.12e} ({:.0e})", d.value, d.relative_step)))
                    .collect::<Vec<_>>(),
                c.spread
            );
            let fd = c
                .value
                .unwrap_or_else(|| panic!("{param}: the central differences did not converge"));
            assert!(
                (grad[k] - dual).abs() <= 1e-10 * dual.abs(),
                "{param}: adjoint {:e} vs dual {dual:e}",
                grad[k]
            );
            assert!(
                (fd.value - dual).abs() <= 1e-6 * dual.abs(),
                "{param}: central difference {:e} vs dual {dual:e} (ratio {:.4})",
                fd.value,
                dual / fd.value
            );
        }
    }
}

#[test]
fn disk_pushed_into_water_2d() {
    check_scene::<2>(
        POOL_2D,
        60,
        &[Param::ObstacleVelocity(0, 0), Param::ObstacleVelocity(0, 1)],
    );
}

#[test]
fn cylinder_pushed_into_water_3d() {
    check_scene::<3>(
        POOL_3D,
        40,
        &[Param::ObstacleVelocity(0, 0), Param::ObstacleVelocity(0, 1)],
    );
}
