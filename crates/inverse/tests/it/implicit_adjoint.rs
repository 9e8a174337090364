//! The adjoint of implicit runs against the forward-mode dual derivative, central finite
//! differences and the Taylor test: a Hencky cantilever (E, ν, the tip load, the density under
//! gravity) and a J2 footing pushed by a prescribed settlement (σ_y, E, the hardening, the
//! settlement), over several load steps with active plasticity and a cut step; and the
//! cantilever under a sudden tip load in Newmark dynamics, Hencky (E, ν, the tip load, the
//! density) and J2 with plastic hinging at the clamp (σ_y, E, the hardening, the density),
//! observed through the tip's displacement and velocity.

use loam_core::Particles;
use loam_core::constitutive::{J2, Lame, Model};
use loam_implicit::ImplicitConfig;
use loam_inverse::MaterialField;
use loam_inverse::implicit::{
    ImplicitObservations, ImplicitParam, ImplicitProblem, Observation, Quantity, Schedule, check,
    run_recorded,
};
use loam_scene::Scene;

/// The scene of `verification/scenes/implicit_cantilever.toml` (described there).
const CANTILEVER: &str = include_str!("../../../../verification/scenes/implicit_cantilever.toml");

/// The scene of `verification/scenes/implicit_cantilever_newmark.toml` (described there).
const CANTILEVER_NEWMARK: &str =
    include_str!("../../../../verification/scenes/implicit_cantilever_newmark.toml");

/// The scene of `verification/scenes/implicit_clay_footing.toml` (described there).
const CLAY_FOOTING: &str =
    include_str!("../../../../verification/scenes/implicit_clay_footing.toml");

/// The scene of `verification/scenes/implicit_footing.toml` (described there).
const FOOTING: &str = include_str!("../../../../verification/scenes/implicit_footing.toml");

fn scene(toml: &str) -> (ImplicitConfig<2>, Particles<f64, 2>) {
    let built = Scene::from_toml_str(toml)
        .and_then(|s| s.build::<2>())
        .unwrap_or_else(|e| panic!("{e}"));
    (built.implicit_config().expect("implicit"), built.particles)
}

/// `quantity` after load or time step `step`, measured as `value` with standard deviation
/// `sigma`.
fn observe(step: usize, quantity: Quantity, value: f64, sigma: f64) -> Observation {
    Observation {
        step,
        quantity,
        value,
        sigma,
    }
}

/// The largest relative difference `max_j |a_j − b_j| / |b_j|`.
fn relative_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a - b).abs() / b.abs())
        .fold(0.0, f64::max)
}

/// The Taylor remainders of `problem` at `θ` along `v` for `h = 10⁻³ / 2ⁱ`, `i < 4`, and
/// the ratios of consecutive ones. The step is small enough that no particle's position
/// crosses a knot of the quadratic B-splines (whose second derivative jumps there) between
/// the perturbed runs, and the smallest remainder (~1e-6 of the loss) stays far above its
/// round-off.
fn taylor_ratios(
    problem: &ImplicitProblem<2>,
    theta: &[f64],
    schedule: &Schedule,
    v: &[f64],
) -> Vec<f64> {
    let g = problem.gradient(theta).expect("gradient");
    let slope: f64 = g.gradient.iter().zip(v).map(|(g, v)| g * v).sum();
    let remainders = check::taylor_remainders(problem, theta, schedule, g.loss, slope, v, 1e-3, 4)
        .expect("Taylor runs");
    println!("Taylor remainders {remainders:?}");
    remainders.windows(2).map(|w| w[0] / w[1]).collect()
}

/// Checks the adjoint of the problem of `config`, `initial`, `params` and `items` against the dual derivative (1e-10), central differences
/// (1e-6) and the Taylor test (remainder ratios within [3.5, 4.5], second order).
fn check(
    name: &str,
    config: ImplicitConfig<2>,
    initial: Particles<f64, 2>,
    params: &[ImplicitParam],
    items: Vec<Observation>,
) {
    check_with(name, config, initial, params, items, 1e-4, true);
}

/// [`check`] with the central differences' relative step `fd_step`, and the Taylor test only
/// when `taylor` (whose steps, from 1e-3, must not cross a kink of the loss).
fn check_with(
    name: &str,
    config: ImplicitConfig<2>,
    initial: Particles<f64, 2>,
    params: &[ImplicitParam],
    items: Vec<Observation>,
    fd_step: f64,
    taylor: bool,
) {
    let problem = &ImplicitProblem {
        config,
        initial,
        params: params.to_vec(),
        observations: ImplicitObservations { items },
    };
    let theta = problem.values().expect("values");
    let schedule = problem.schedule(&theta).expect("run");
    let adjoint = problem.gradient(&theta).expect("adjoint");
    let dual = problem.dual_gradient(&theta).expect("dual");
    // Richardson-extrapolated at δ = 10⁻⁴ |θ_k|: truncation O(δ⁴) ~1e-16 relative, round-off
    // ε_L / δ with ε_L the loss's round-off and solver error (Newton converged to 1e-12 of
    // the load): ~1e-9 relative. The perturbed runs replay the sub-steps of the run at θ
    // (the footing's third step converges in exactly its 5 allowed iterations; a perturbed
    // Newton needing a sixth would cut it, a different discrete map).
    let fd: Vec<f64> = (0..theta.len())
        .map(|k| check::central_difference(problem, &theta, &schedule, k, fd_step).expect("runs"))
        .collect();
    for (k, p) in problem.params.iter().enumerate() {
        println!(
            "{name} {p}: adjoint {:.15e} dual {:.15e} fd {:.15e}",
            adjoint.gradient[k], dual[k], fd[k]
        );
    }
    let vs_dual = relative_difference(&adjoint.gradient, &dual);
    let vs_fd = relative_difference(&adjoint.gradient, &fd);
    println!(
        "{name}: loss {:.6e}, adjoint vs dual {vs_dual:.2e}, adjoint vs FD {vs_fd:.2e}, \
         forward {:.3} s, reverse {:.3} s",
        adjoint.loss, adjoint.forward_seconds, adjoint.reverse_seconds
    );
    // Both are exact derivatives of the same discrete map at the same converged solutions;
    // they differ by the round-off of different summation orders and of solving with J and
    // with Jᵀ (backward error ~1e-16 times the condition number of the tangents, ≲ 1e6 here).
    assert!(vs_dual < 1e-10, "{name}: adjoint vs dual {vs_dual:.2e}");
    // The difference quotient's own error is ~1e-9 (see `central_difference`).
    assert!(vs_fd < 1e-6, "{name}: adjoint vs FD {vs_fd:.2e}");
    if !taylor {
        return;
    }
    // Relative direction (each θ_k scaled by its own size), mixed signs.
    let direction: Vec<f64> = (0..theta.len())
        .map(|k| [1.0, -0.6, 0.8, -0.4][k % 4] * theta[k])
        .collect();
    let ratios = taylor_ratios(problem, &theta, &schedule, &direction);
    println!("{name}: Taylor ratios {ratios:.3?}");
    // A remainder that is O(h²) falls 4× per halving; a wrong gradient leaves O(h), 2×.
    assert!(
        ratios.iter().all(|r| (3.5..4.5).contains(r)),
        "{name}: Taylor ratios {ratios:?}"
    );
}

#[test]
fn cantilever_adjoint_matches_dual_and_differences() {
    let (config, initial) = scene(CANTILEVER);
    // The tip particle (the point load's) and one at mid-span on the lower face.
    let tip = config.point_loads[0].particle;
    let mid = (0..initial.len())
        .min_by(|&a, &b| {
            let d = |p: usize| (initial.x[p][0] - 1.25).abs() + (initial.x[p][1] - 2.0).abs();
            d(a).total_cmp(&d(b))
        })
        .expect("particles");
    let displacement = |step, particle, component, value| Observation {
        step,
        quantity: Quantity::Displacement {
            particle,
            component,
        },
        value,
        sigma: 0.01,
    };
    let observations = ImplicitObservations {
        items: vec![
            displacement(2, tip, 1, -0.15),
            displacement(4, tip, 1, -0.3),
            displacement(4, tip, 0, 0.0),
            displacement(3, mid, 1, -0.05),
            Observation {
                step: 4,
                quantity: Quantity::Reaction {
                    constraint: 0,
                    component: 1,
                },
                value: 2000.0,
                sigma: 100.0,
            },
        ],
    };
    let params = [
        ImplicitParam::Material(0, MaterialField::Young),
        ImplicitParam::Material(0, MaterialField::Poisson),
        ImplicitParam::PointLoad(0, 1),
        ImplicitParam::Material(0, MaterialField::Density),
    ];
    check("cantilever", config, initial, &params, observations.items);
}

#[test]
fn footing_adjoint_matches_dual_and_differences() {
    let (config, initial) = scene(FOOTING);
    let run = run_recorded(&config, &initial, None).expect("runs");
    // A step was cut (a failed attempt replaced by two accepted halves), and plasticity is
    // active and growing through the later steps.
    assert!(
        run.cuts >= 1,
        "no cut step: {} sub-steps",
        run.substeps.len()
    );
    let peak = |s: &loam_inverse::implicit::record::SubStep<2>| {
        s.history
            .iter()
            .map(|h| h.plastic_strain)
            .fold(0.0, f64::max)
    };
    let last = run.substeps.last().expect("sub-steps");
    assert!(peak(last) > 0.01 && peak(last) > peak(&run.substeps[1]));
    // A surface particle beside the footing.
    let side = (0..initial.len())
        .min_by(|&a, &b| {
            let d = |p: usize| (initial.x[p][0] - 0.8).abs() + (initial.x[p][1] - 1.0).abs();
            d(a).total_cmp(&d(b))
        })
        .expect("particles");
    let mut items: Vec<Observation> = (1..=4)
        .map(|step| Observation {
            step,
            quantity: Quantity::Reaction {
                constraint: 0,
                component: 1,
            },
            value: -30e3 - 5e3 * step as f64,
            sigma: 1e3,
        })
        .collect();
    items.push(Observation {
        step: 4,
        quantity: Quantity::displacement(side, 1),
        value: 0.0,
        sigma: 1e-3,
    });
    println!(
        "footing: {} sub-steps for 4 load steps ({} cut)",
        run.substeps.len(),
        run.cuts
    );
    let params = [
        ImplicitParam::Material(0, MaterialField::YieldStress),
        ImplicitParam::Material(0, MaterialField::Young),
        ImplicitParam::Material(0, MaterialField::Hardening),
        ImplicitParam::Displacement(0, 1),
    ];
    check("footing", config, initial, &params, items);
}

/// The footing of `implicit_footing.toml` on frictional soil: the J2 clay replaced by
/// Mohr–Coulomb (c = 10 kPa, φ = 30°, ψ = 10°) or Drucker–Prager with Hencky elasticity (the
/// implicit default; same c, φ, ψ, plane-strain cone), with Newton allowed enough iterations
/// that no step is cut. Gradients with respect to φ, c, ψ and E through the plastic history
/// of four load steps, against the dual derivative, central differences and the Taylor test.
fn frictional_footing(model: &str) -> (ImplicitConfig<2>, Particles<f64, 2>) {
    scene(&frictional_footing_text(model))
}

/// The text of [`frictional_footing`]'s scene.
fn frictional_footing_text(model: &str) -> String {
    let material = format!(
        "[[materials]]\nname = \"clay\"\nmodel = \"{model}\"\ndensity = 1800.0\n\
         youngs_modulus = 5.0e6\npoisson_ratio = 0.3\nfriction_angle = 30.0\n\
         dilation_angle = 10.0\ncohesion = 1.0e4\n"
    );
    let text = FOOTING
        .replace(
            "[[materials]]\nname = \"clay\"\nmodel = \"j2\"\ndensity = 1800.0\n\
             youngs_modulus = 5.0e6\npoisson_ratio = 0.3\nyield_stress = 3.0e4\n\
             hardening = 2.0e5\n",
            &material,
        )
        .replace("max_iterations = 5", "max_iterations = 30");
    assert!(
        text.contains(model),
        "the footing's material was not replaced"
    );
    text
}

/// The footing's vertical reaction after each of its 4 load steps, "measured" as
/// `first − 5 kN/m` per step (σ = 1 kN/m).
fn footing_reactions(first: f64) -> Vec<Observation> {
    (1..=4)
        .map(|step| Observation {
            step,
            quantity: Quantity::Reaction {
                constraint: 0,
                component: 1,
            },
            value: first - 5e3 * (step - 1) as f64,
            sigma: 1e3,
        })
        .collect()
}

fn frictional_footing_check(model: &str, fd_step: f64, taylor: bool) {
    let (config, initial) = frictional_footing(model);
    let run = run_recorded(&config, &initial, None).expect("runs");
    let last = run.substeps.last().expect("sub-steps");
    let yielded = last
        .history
        .iter()
        .filter(|h| h.plastic_strain > 0.0)
        .count();
    println!(
        "{model} footing: {yielded} of {} particles yielded",
        initial.len()
    );
    assert!(yielded > 10, "{model}: only {yielded} particles yielded");
    let items = footing_reactions(-25e3);
    let params = [
        ImplicitParam::Material(0, MaterialField::FrictionAngle),
        ImplicitParam::Material(0, MaterialField::Cohesion),
        ImplicitParam::Material(0, MaterialField::DilationAngle),
        ImplicitParam::Material(0, MaterialField::Young),
    ];
    check_with(model, config, initial, &params, items, fd_step, taylor);
}

#[test]
fn mohr_coulomb_footing_adjoint_matches_dual_and_differences() {
    frictional_footing_check("mohr_coulomb", 1e-4, true);
}

/// The Mohr–Coulomb footing with a tension cutoff of 1 kPa (the apex c cot φ is 17.3 kPa):
/// the soil beside the footing, lifted and stretched as the footing settles, reaches the
/// cutoff, so the reactions depend on σ_t; its gradient and c's against the dual derivative,
/// central differences and the Taylor test.
#[test]
fn tension_cutoff_gradient_matches_dual_and_differences() {
    let text = frictional_footing_text("mohr_coulomb").replace(
        "cohesion = 1.0e4\n",
        "cohesion = 1.0e4\ntension_cutoff = 1.0e3\n",
    );
    assert!(text.contains("tension_cutoff"));
    let (config, initial) = scene(&text);
    let params = [
        ImplicitParam::Material(0, MaterialField::TensionCutoff),
        ImplicitParam::Material(0, MaterialField::Cohesion),
    ];
    let problem = ImplicitProblem {
        config: config.clone(),
        initial: initial.clone(),
        params: params.to_vec(),
        observations: ImplicitObservations {
            items: footing_reactions(-25e3),
        },
    };
    let theta = problem.values().expect("values");
    let gradient = problem.gradient(&theta).expect("adjoint").gradient;
    // A cutoff no particle reaches would leave ∂L/∂σ_t exactly 0.
    assert!(
        gradient[0].abs() > 1e-3 * gradient[1].abs() * theta[1] / theta[0],
        "the cutoff is not reached: {gradient:?}"
    );
    check(
        "mohr_coulomb with a tension cutoff",
        config,
        initial,
        &params,
        footing_reactions(-25e3),
    );
}

/// The Drucker–Prager footing's loss has kinks close to its parameters: surface particles at
/// low confinement switch between the cone and the apex within relative changes of 1e-5 of
/// c or E. Central differences of ∂L/∂c at relative steps 1e-3, 1e-4, 1e-5, 1e-6, 1e-7 gave
/// 0.159861, 0.159872, 0.159989, 0.16002990546, 0.1600298826 against the adjoint's
/// 0.16002990594 (of E: 1.04292e-3, 1.04290e-3, 1.04267e-3, 1.042470179e-3, 1.04247002e-3
/// against 1.042470175e-3): the steps above 1e-6 straddle a kink, so the differences are
/// taken at 1e-6 (round-off ~1e-13/1e-6 ~1e-7 relative, within the 1e-6 bound) and the Taylor
/// test, whose steps start at 1e-3, is left out.
#[test]
fn drucker_prager_footing_adjoint_matches_dual_and_differences() {
    frictional_footing_check("drucker_prager", 1e-6, false);
}

/// The Mohr–Coulomb footing of [`frictional_footing`] on ground at rest under a geostatic
/// stress of K0 = 0.6 (`balance` = whether the scene balances it on the grid).
fn prestressed_footing(balance: bool) -> (ImplicitConfig<2>, Particles<f64, 2>) {
    scene(&prestressed_text(balance))
}

/// The text of [`prestressed_footing`]'s scene.
fn prestressed_text(balance: bool) -> String {
    let text = frictional_footing_text("mohr_coulomb")
        .replace(
            "particles_per_cell = 2\n",
            "particles_per_cell = 2\ninitial_stress = { type = \"geostatic\", k0 = 0.6 }\n",
        )
        .replace(
            "load_steps = 4\n",
            &format!("load_steps = 4\nbalance_initial_stress = {balance}\n"),
        );
    assert!(text.contains("k0 = 0.6") && text.contains("balance_initial_stress"));
    text
}

/// The scene `text` with its K0 0.6 set to `k0` by the parameter, and the scene built with
/// `k0`: their histories' largest difference, the scale `max |bₑ − I|`, and the largest
/// difference of their balancing forces relative to the largest.
fn k0_set_and_built(text: &str, k0: f64) -> (f64, f64, f64) {
    let param = ImplicitParam::K0(0);
    let (mut config, mut initial) = scene(text);
    assert!((param.value(&config, &initial).expect("K0") - 0.6).abs() < 1e-9);
    param.set(&mut config, &mut initial, k0).expect("set");
    assert!((param.value(&config, &initial).expect("K0") - k0).abs() < 1e-9);
    let (want_config, want) = scene(&text.replace("k0 = 0.6", &format!("k0 = {k0}")));
    let history = |h: &loam_core::constitutive::MaterialState<f64>| {
        nalgebra::Vector4::new(
            h.tensor[(0, 0)],
            h.tensor[(1, 1)],
            h.tensor[(2, 2)],
            h.hardening,
        )
    };
    let d = (0..initial.len())
        .map(|p| (history(&initial.state[p]) - history(&want.state[p])).amax())
        .fold(0.0, f64::max);
    let scale = (want.state.iter())
        .map(|h| (h.tensor - nalgebra::Matrix3::identity()).amax())
        .fold(0.0, f64::max);
    let largest =
        |b: &[loam_core::tensor::Vector<f64, 2>]| b.iter().map(|f| f.amax()).fold(0.0, f64::max);
    let balance = (config.balance.iter().zip(&want_config.balance))
        .map(|(f, g)| (f - g).amax())
        .fold(0.0, f64::max)
        / largest(&want_config.balance);
    println!(
        "K0 0.6 → {k0}: history differs by {d:.3e} (scale {scale:.3e}), balance by {balance:.3e}"
    );
    (d, scale, balance)
}

/// K0 as a parameter: setting it moves the particles' initial stress, the history that
/// carries it and the balancing forces to those of the scene built with the new K0. Modified
/// Cam-Clay carries its state at `F = I` (`τ_zz = K0 τ_v`, `p_c₀` from the OCR): the same
/// state to the scene's round-off. The Mohr–Coulomb state at rest is stretched
/// (`ε_zz = 0`, so `τ_zz = ν(τ_xx + τ_yy)`): the parameter holds `F` and the Kirchhoff
/// `τ_v = J σ_v` where the scene holds the Cauchy `σ_v`, so `bₑ − I` differs by `O(ε)` of
/// itself (bound: `max |bₑ − I|²`, ~30× the difference seen); a wrong `τ_zz` would move it
/// by ~(1 − ν) ΔK0 of itself, 100× more.
#[test]
fn setting_k0_gives_the_state_the_scene_builds() {
    // Absolute: the history's entries are ~5e-2 (elastic strains) and ~1e4 Pa (p_c).
    let (d, _, balance) = k0_set_and_built(CLAY_FOOTING, 0.55);
    assert!(
        d < 1e-9 && balance < 1e-9,
        "clay: {d:.2e}, balance {balance:.2e}"
    );
    let (d, scale, balance) = k0_set_and_built(&prestressed_text(true), 0.5);
    assert!(d < scale * scale, "Mohr–Coulomb: bₑ differs by {d:.2e}");
    assert!(
        balance < 1e-2,
        "Mohr–Coulomb: balance differs by {balance:.2e}"
    );
    // An elastic model carries its K0 in F: refused by name.
    let hencky = FOOTING
        .replace("model = \"j2\"", "model = \"hencky\"")
        .replace("yield_stress = 3.0e4\nhardening = 2.0e5\n", "")
        .replace(
            "particles_per_cell = 2\n",
            "particles_per_cell = 2\ninitial_stress = { type = \"geostatic\", k0 = 0.6 }\n",
        );
    let (config, initial) = scene(&hencky);
    let err = ImplicitParam::K0(0)
        .value(&config, &initial)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("materials[0].k0") && err.contains("deformation gradient"),
        "{err}"
    );
}

/// `∂L/∂K0` (and `∂L/∂φ` beside it) on the prestressed Mohr–Coulomb footing, unbalanced and
/// balanced: K0 moves the initial history (and the balancing forces, whose derivative is
/// the balance of `∂τ₀/∂K0`), against the dual derivative, central differences and the
/// Taylor test.
#[test]
fn k0_gradient_matches_dual_and_differences() {
    for balance in [false, true] {
        let (config, initial) = prestressed_footing(balance);
        let items = footing_reactions(-35e3);
        let params = [
            ImplicitParam::K0(0),
            ImplicitParam::Material(0, MaterialField::FrictionAngle),
        ];
        let name = format!("K0, balance {balance}");
        check_with(&name, config, initial, &params, items, 1e-4, true);
    }
}

/// The cantilever under its sudden tip load in Newmark dynamics
/// (`implicit_cantilever_newmark.toml`: 5 time steps of 0.04 s, together less than half its
/// first period of ≈ 0.49 s, so the tip is still moving down), and a loss over the tip's
/// deflection after steps 2 to 5, its velocity after steps 3 and 5, and the clamp's reaction.
fn newmark_cantilever() -> (ImplicitConfig<2>, Particles<f64, 2>, Vec<Observation>) {
    let (config, initial) = scene(CANTILEVER_NEWMARK);
    let tip = config.point_loads[0].particle;
    let deflection = Quantity::displacement(tip, 1);
    let velocity = Quantity::velocity(tip, 1);
    let reaction = Quantity::Reaction {
        constraint: 0,
        component: 1,
    };
    let mut items: Vec<Observation> = (2..=5)
        .map(|step| observe(step, deflection, -0.02 * step as f64, 0.01))
        .collect();
    items.push(observe(3, velocity, -0.5, 0.1));
    items.push(observe(5, velocity, -1.0, 0.1));
    items.push(observe(5, reaction, 1500.0, 100.0));
    (config, initial, items)
}

/// The run of a Newmark scene, after checking that its tip moves down faster over the first
/// steps (the dynamics is exercised, not a quasi-static balance).
fn dynamic_run(
    config: &ImplicitConfig<2>,
    initial: &Particles<f64, 2>,
) -> loam_inverse::implicit::Trajectory<2> {
    let run = run_recorded(config, initial, None).expect("runs");
    let tip = config.point_loads[0].particle;
    let v: Vec<f64> = run.velocities.iter().map(|v| v[tip][1]).collect();
    println!(
        "{} sub-steps for {} time steps ({} cut), tip velocity per step {v:?}",
        run.substeps.len(),
        config.load_steps,
        run.cuts
    );
    assert!(
        v[0] == 0.0 && v[1] < 0.0 && v[2] < v[1],
        "tip velocities {v:?}"
    );
    run
}

/// A rigid plate over the top of the Newmark cantilever's free half, carrying 100 N/m down
/// (force-controlled: its nodes share one vertical unknown), beside the tip load. The plate's
/// force enters a Newmark step's residual twice (directly and through the start force `rₙ`),
/// and the shared unknown carries the plate's share of the consistent mass.
#[test]
fn newmark_force_controlled_plate_adjoint_matches_dual_and_differences() {
    let (mut config, initial, items) = newmark_cantilever();
    config.constraints.push(loam_core::NodeConstraint {
        lo: [1.5, 2.5],
        hi: [2.25, 2.5],
        displacement: [None, None],
        force: [None, Some(-100.0)],
    });
    let params = [
        ImplicitParam::Material(0, MaterialField::Young),
        ImplicitParam::ConstraintForce(1, 1),
    ];
    check("newmark plate", config, initial, &params, items);
}

#[test]
fn newmark_cantilever_adjoint_matches_dual_and_differences() {
    let (config, initial, items) = newmark_cantilever();
    dynamic_run(&config, &initial);
    let params = [
        ImplicitParam::Material(0, MaterialField::Young),
        ImplicitParam::Material(0, MaterialField::Poisson),
        ImplicitParam::PointLoad(0, 1),
        ImplicitParam::Material(0, MaterialField::Density),
    ];
    check("newmark cantilever", config, initial, &params, items);
}

#[test]
fn newmark_j2_cantilever_adjoint_matches_dual_and_differences() {
    let (mut config, initial, items) = newmark_cantilever();
    // The bending stress at the clamp reaches ~6PL/h² ≈ 48 kPa: it yields at 20 kPa.
    let lame = Lame::from_young_poisson(1.0e6, 0.25);
    config.materials[0].model = Model::J2(J2 {
        lame,
        yield_stress: 2.0e4,
        hardening: 1.0e5,
    });
    // A time step whose Newton fails is cut into shorter ones, which the reverse pass and
    // the replays take as recorded.
    let run = dynamic_run(&config, &initial);
    assert!(run.cuts >= 1, "no cut step");
    let last = run.substeps.last().expect("sub-steps");
    let peak = last
        .history
        .iter()
        .map(|h| h.plastic_strain)
        .fold(0.0, f64::max);
    println!("newmark J2: peak plastic strain at the last step's start {peak:.3e}");
    assert!(peak > 1e-3, "no plasticity: {peak:.3e}");
    let params = [
        ImplicitParam::Material(0, MaterialField::YieldStress),
        ImplicitParam::Material(0, MaterialField::Young),
        ImplicitParam::Material(0, MaterialField::Hardening),
        ImplicitParam::Material(0, MaterialField::Density),
    ];
    check("newmark J2 cantilever", config, initial, &params, items);
}

/// The J2 footing of `implicit_footing.toml` in Newmark dynamics: 4 time steps of 0.01 s
/// (half the time a pressure wave takes through the 1 m layer), the soil's weight applied
/// suddenly and the footing pushed down by its prescribed settlement. The slip walls make
/// ghost nodes mirror images (signed entries of the mass matrix), and the settlement enters
/// the start force `f_int(0)` of every step.
#[test]
fn newmark_footing_adjoint_matches_dual_and_differences() {
    let (mut config, initial) = scene(FOOTING);
    config.dynamics = Some(0.01);
    config.newton.max_iterations = 25;
    let side = (0..initial.len())
        .min_by(|&a, &b| {
            let d = |p: usize| (initial.x[p][0] - 0.8).abs() + (initial.x[p][1] - 1.0).abs();
            d(a).total_cmp(&d(b))
        })
        .expect("particles");
    let run = run_recorded(&config, &initial, None).expect("runs");
    let v: Vec<f64> = run.velocities.iter().map(|v| v[side][1]).collect();
    let peak = (run.substeps.last().expect("sub-steps").history.iter())
        .map(|h| h.plastic_strain)
        .fold(0.0, f64::max);
    println!("newmark footing: side velocity per step {v:?}, peak plastic strain {peak:.3e}");
    assert!(
        v[1..].iter().all(|v| v.abs() > 1e-3),
        "side velocities {v:?}"
    );
    let load = Quantity::Reaction {
        constraint: 0,
        component: 1,
    };
    let mut items: Vec<Observation> = (1..=4)
        .map(|step| observe(step, load, -30e3 - 5e3 * step as f64, 1e3))
        .collect();
    let beside = Quantity::displacement(side, 1);
    let velocity = Quantity::velocity(side, 1);
    items.push(observe(4, beside, 0.0, 1e-3));
    items.push(observe(2, velocity, 0.0, 0.01));
    items.push(observe(4, velocity, 0.0, 0.01));
    let params = [
        ImplicitParam::Material(0, MaterialField::YieldStress),
        ImplicitParam::Material(0, MaterialField::Young),
        ImplicitParam::Displacement(0, 1),
        ImplicitParam::Material(0, MaterialField::Density),
    ];
    check("newmark footing", config, initial, &params, items);
}
