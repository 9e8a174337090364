//! Force-controlled rigid groups of nodes (`NodeConstraint::force`): a loading plate on a
//! confined column against the exact uniaxial compression, and the tangent with the shared
//! unknown against differences of the residual.

use loam_core::tensor::Vector;
use loam_core::{
    Boundary, Grid, Material, ModelKind, NodeConstraint, Particles, Shape, Wall, WallKind,
};
use loam_implicit::{ImplicitConfig, ImplicitError, ImplicitSolver, NewtonSettings, TangentMethod};

const WIDTH: f64 = 1.0;
const HEIGHT: f64 = 2.0;
const H: f64 = 0.25;
const E: f64 = 1e7;
const NU: f64 = 0.3;

/// A weightless column `[0, 1] × [0, 2]` (cells of 0.25 m, 2 × 2 particles per cell) between
/// slip walls on a fixed base, under a rigid plate on its top face carrying `force` (N/m)
/// downwards: the nodes of the box `y ∈ [2, top]` share one vertical unknown.
fn column(shape: Shape, material: Material<f64>, top: f64, force: f64) -> ImplicitConfig<2> {
    let grid = Grid::<2>::new([0.0, 0.0], [4, 10], H, shape.ghost_cells());
    let mut boundary = Boundary::all(Wall::new(WallKind::Slip));
    boundary.walls[1][0] = Wall::new(WallKind::Fixed);
    boundary.walls[1][1] = Wall::new(WallKind::Free);
    ImplicitConfig {
        grid,
        shape,
        boundary,
        materials: vec![material],
        gravity: Vector::zeros(),
        constraints: vec![NodeConstraint {
            lo: [0.0, HEIGHT],
            hi: [WIDTH, top],
            displacement: [None, None],
            force: [None, Some(-force)],
        }],
        point_loads: Vec::new(),
        load_steps: 2,
        newton: NewtonSettings::default(),
        dynamics: None,
        gravity_in_full: false,
        min_node_support: ImplicitConfig::<2>::DEFAULT_MIN_NODE_SUPPORT,
        balance: Vec::new(),
        pore_fluid: None,
    }
}

fn particles() -> Particles<f64, 2> {
    let mut p = Particles::<f64, 2>::default();
    let s = H / 2.0;
    for j in 0..(HEIGHT / s).round() as usize {
        for i in 0..(WIDTH / s).round() as usize {
            let x = Vector::<f64, 2>::new((i as f64 + 0.5) * s, (j as f64 + 0.5) * s);
            p.push(x, Vector::zeros(), 1000.0, Vector::repeat(s / 2.0), 0);
        }
    }
    p
}

#[test]
fn a_loaded_plate_compresses_a_confined_column_uniformly() {
    // q = 10 kPa over the 1 m plate; the constrained modulus M = E(1−ν)/((1+ν)(1−2ν)).
    let q = 1e4;
    let m = E * (1.0 - NU) / ((1.0 + NU) * (1.0 - 2.0 * NU));
    let elastic = Material::elastic(ModelKind::LinearElastic, E, NU, 1000.0);
    let config = column(Shape::Linear, elastic, HEIGHT, q * WIDTH);
    let mut p = particles();
    let y0 = p.x.clone();
    let mut solver = ImplicitSolver::new(config, &p).expect("valid");
    let mut report = None;
    while !solver.finished() {
        report = Some(solver.step(&mut p).expect("converges"));
    }
    let report = report.expect("two steps");
    // Uniaxial strain ε = q/M everywhere: the plate settles by q H / M, every particle by
    // ε y, and the stress is −q. Linear shape functions represent the uniform strain exactly;
    // the model's small-strain update over the moved configuration leaves an error of the
    // order of the strain, q/M = 7.4e-4, so 2e-3 relative.
    let settlement = q * HEIGHT / m;
    let plate = report.constraint_displacements[0][1];
    assert!(
        (plate / -settlement - 1.0).abs() < 2e-3,
        "plate {plate:e} vs −{settlement:e}"
    );
    assert_eq!(report.constraint_displacements[0][0], 0.0);
    // The group carries the applied force.
    let reaction = report.constraint_forces[0][1];
    assert!(
        (reaction / -(q * WIDTH) - 1.0).abs() < 1e-6,
        "reaction {reaction}"
    );
    for (i, x) in p.x.iter().enumerate() {
        let uy = x[1] - y0[i][1];
        let exact = -q / m * y0[i][1];
        assert!(
            (uy - exact).abs() < 2e-3 * settlement,
            "particle {i}: {uy:e} vs {exact:e}"
        );
        let syy = p.stress[i][(1, 1)];
        assert!((syy / -q - 1.0).abs() < 2e-3, "particle {i}: σ_yy {syy}");
    }
}

/// A plate pushed down and sideways: each force-controlled component has its own shared
/// unknown, and in equilibrium the internal force of the group on each equals the force it
/// carries. The sideways force shears the column, so the plate moves with it.
#[test]
fn an_inclined_force_is_carried_by_both_shared_unknowns() {
    let (q, s) = (1e4, 2e3);
    let elastic = Material::elastic(ModelKind::LinearElastic, E, NU, 1000.0);
    let mut config = column(Shape::Linear, elastic, HEIGHT, q * WIDTH);
    config.constraints[0].force[0] = Some(s * WIDTH);
    let mut p = particles();
    let mut solver = ImplicitSolver::new(config, &p).expect("valid");
    let mut report = None;
    while !solver.finished() {
        report = Some(solver.step(&mut p).expect("converges"));
    }
    let report = report.expect("two steps");
    // Newton converges to ‖R‖ ≤ 1e-8 of the load, so the reactions hold to 1e-6.
    let reaction = report.constraint_forces[0];
    assert!(
        (reaction[0] / (s * WIDTH) - 1.0).abs() < 1e-6,
        "{reaction:?}"
    );
    assert!(
        (reaction[1] / -(q * WIDTH) - 1.0).abs() < 1e-6,
        "{reaction:?}"
    );
    let plate = report.constraint_displacements[0];
    assert!(plate[0] > 0.0 && plate[1] < 0.0, "plate moved by {plate:?}");
}

#[test]
fn the_tangent_with_a_shared_unknown_is_the_derivative_of_the_residual() {
    // Quadratic B-splines: the plate's box holds the surface row and the row above it, so
    // the shared unknown is reached by ghost and weakly supported nodes too.
    let hencky = Material::elastic(ModelKind::Hencky, E, NU, 1000.0);
    let config = column(Shape::QuadraticBspline, hencky, HEIGHT + H, 1e5);
    let p = particles();
    let solver = ImplicitSolver::new(config, &p).expect("valid");
    let system = solver.system(&p, 0.0, 0.5).expect("system");
    let tie = system
        .dofs
        .ties()
        .first()
        .expect("one shared unknown")
        .clone();
    assert!(
        tie.nodes.len() >= 10,
        "{} nodes in the group",
        tie.nodes.len()
    );
    let mats = solver.materials();
    let n = system.len();
    // A smooth trial state of ~0.1 % strain: a uniform compression and a shear wave.
    let x: Vec<f64> = (0..n)
        .map(|d| {
            let (node, c) = system.dofs.owner_of(d);
            let pos: Vector<f64, 2> = system.grid().node_position(system.grid().multi(node));
            if c == 1 {
                -1e-3 * pos[1]
            } else {
                5e-4 * (3.0 * pos[1]).sin()
            }
        })
        .collect();
    let k = system.tangent_local(&x, mats).expect("tangent");
    let at = |i: usize, j: usize| k.pattern.position(i, j).map_or(0.0, |q| k.values[q]);
    let mut kmax = 0.0f64;
    let mut worst = 0.0f64;
    let mut worst_shared = 0.0f64;
    crate::central_differences(&system, mats, &x, |i, j, fd| {
        let e = (at(i, j) - fd).abs();
        kmax = kmax.max(at(i, j).abs());
        worst = worst.max(e);
        if i == tie.dof || j == tie.dof {
            worst_shared = worst_shared.max(e);
        }
    });
    assert!(at(tie.dof, tie.dof) > 0.0, "the plate's own stiffness");
    assert!(worst <= 1e-6 * kmax, "{worst:e} vs {kmax:e}");
    assert!(worst_shared <= 1e-6 * kmax, "shared {worst_shared:e}");
}

#[test]
fn force_control_is_refused_where_it_cannot_work() {
    let elastic = Material::elastic(ModelKind::LinearElastic, E, NU, 1000.0);
    let p = particles();
    let mut config = column(Shape::Linear, elastic, HEIGHT, 1e4);
    config.newton.tangent = TangentMethod::Colour;
    let err = ImplicitSolver::new(config.clone(), &p)
        .err()
        .expect("refused");
    assert!(
        matches!(&err, ImplicitError::Config { field, .. } if field == "constraints[0].force"),
        "{err}"
    );
    config.newton.tangent = TangentMethod::Local;
    config.constraints[0].displacement[1] = Some(-0.01);
    let err = ImplicitSolver::new(config.clone(), &p)
        .err()
        .expect("refused");
    assert!(err.to_string().contains("both"), "{err}");
    // A box that no particle reaches.
    config.constraints[0].displacement[1] = None;
    config.constraints[0].lo = [0.0, 2.4];
    config.constraints[0].hi = [1.0, 2.4];
    let mut p2 = p.clone();
    let mut solver = ImplicitSolver::new(config, &p2).expect("valid");
    let err = solver.step(&mut p2).expect_err("no group");
    assert!(err.to_string().contains("constraints[0].force"), "{err}");
}
