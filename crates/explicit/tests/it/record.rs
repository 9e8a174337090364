//! The step record: a recorded step is the same step, bit for bit, and what it records is
//! what the step did (stick or slip on a friction floor, the return region of a yielding
//! material, the wall projection).

use loam_core::constitutive::Region;
use loam_core::step::{NodeState, NodeSums, StepRecord};
use loam_core::tensor::Vector;
use loam_core::*;
use loam_explicit::{Config, GridFields, Solver, StepTrace};

/// A 2D Neo-Hookean block (0.1 × 0.05 m, h = 0.02, 2×2 particles per cell) resting on a
/// separable floor with Coulomb friction `mu`, pushed along the floor at 1 m/s, under gravity.
fn sliding_block(mu: f64, material: Material<f64>) -> (Config<f64, 2>, Particles<f64, 2>) {
    let shape = Shape::QuadraticBspline;
    let h = 0.02;
    let mut boundary = Boundary::all(Wall::new(WallKind::Free));
    boundary.walls[1][0] = Wall {
        kind: WallKind::Slip,
        separable: true,
    };
    let mut contact = Contact::new(shape);
    contact.segments.push(FrictionSegment::whole_face(1, 0, mu));
    let config = Config {
        grid: Grid::new([0.0, 0.0], [30, 10], h, shape.ghost_cells()),
        shape,
        transfer: Transfer::Apic,
        scheme: Scheme::Musl,
        boundary,
        contact,
        gravity: Vector::<f64, 2>::new(0.0, -9.81),
        materials: vec![material],
        time_step: TimeStep::Fixed { dt: 1e-4 },
    };
    let mut p = Particles::default();
    let dp = h / 2.0;
    for i in 0..10 {
        for j in 0..5 {
            let x = Vector::<f64, 2>::new(0.1 + (i as f64 + 0.5) * dp, (j as f64 + 0.5) * dp);
            p.push(
                x,
                Vector::<f64, 2>::new(1.0, 0.0),
                1000.0,
                Vector::repeat(dp / 2.0),
                0,
            );
        }
    }
    (config, p)
}

fn rubber() -> Material<f64> {
    Material::elastic(ModelKind::NeoHookean, 1.0e6, 0.3, 1000.0)
}

/// Runs `steps` steps plainly and recorded from the same state; returns the two final states
/// and the records.
fn both(
    (config, p): (Config<f64, 2>, Particles<f64, 2>),
    steps: usize,
) -> (Particles<f64, 2>, Particles<f64, 2>, Vec<StepRecord>) {
    let (mut plain, mut recorded) = (p.clone(), p);
    let mut a = Solver::new(config.clone(), &plain).expect("valid");
    let mut b = Solver::new(config, &recorded).expect("valid");
    let mut records = Vec::new();
    for _ in 0..steps {
        let ia = a.step(&mut plain, f64::INFINITY).expect("stable");
        let mut r = StepRecord::default();
        let ib = b
            .step_recorded(&mut recorded, f64::INFINITY, &mut r)
            .expect("stable");
        assert_eq!(ia, ib);
        assert_eq!((r.step, r.dt), (ib.step, ib.dt));
        records.push(r);
    }
    (plain, recorded, records)
}

#[test]
fn a_recorded_step_is_the_same_step() {
    let (plain, recorded, _) = both(sliding_block(0.2, rubber()), 50);
    assert_eq!(plain.x, recorded.x);
    assert_eq!(plain.v, recorded.v);
    assert_eq!(plain.c, recorded.c);
    assert_eq!(plain.f, recorded.f);
    assert_eq!(plain.stress, recorded.stress);
}

/// At 1 m/s along the floor, the floor nodes under the block slide when `μ = 0.1` (the
/// friction impulse per step, `μ Δv_n` with `Δv_n ≈ g Δt`, is far below the tangential speed)
/// and stick when `μ = 10⁴` (the cone holds any tangential speed the normal impulse meets).
/// Only floor nodes (bit `2·1 + 0` of the contact set) are recorded: the face row and the
/// ghost rows below it, where a friction segment acts too.
#[test]
fn the_record_tells_stick_from_slip() {
    for (mu, slide) in [(0.1, true), (1e4, false)] {
        let (config, p) = sliding_block(mu, rubber());
        let grid = config.grid.clone();
        let (_, _, records) = both((config, p), 20);
        let last = records.last().expect("steps ran");
        assert!(
            !last.nodes.is_empty(),
            "μ = {mu}: the block presses on the floor"
        );
        for &(node, state) in &last.nodes {
            assert!(
                grid.multi(node)[1] <= grid.pad,
                "μ = {mu}: a face or ghost node"
            );
            assert_eq!(state.contact.active, 1 << 2);
            let slid = state.contact.slip == 1 << 2;
            assert_eq!(slid, slide, "μ = {mu}, node {node}");
        }
        assert_eq!(last.particles.len(), 50);
    }
}

/// A soft J2 block (yield stress 100 Pa) sliding on the floor yields under its own weight
/// (ρ g H ≈ 490 Pa at the base): the record holds radial returns near the floor, and none at
/// the top surface, where the stress is near zero.
#[test]
fn the_record_holds_the_return_region() {
    let soft = Material::j2(1.0e6, 0.3, 100.0, 0.0, 1000.0);
    let (_, p, records) = both(sliding_block(0.2, soft), 100);
    let last = records.last().expect("steps ran");
    let yielded: Vec<usize> = (0..p.len())
        .filter(|&i| last.particles[i].region == Region::Shear)
        .collect();
    assert!(!yielded.is_empty(), "the base yields");
    let lowest = yielded
        .iter()
        .map(|&i| p.x[i][1])
        .fold(f64::INFINITY, f64::min);
    assert!(
        lowest < 0.02,
        "yielding starts at the base: lowest at {lowest}"
    );
}

/// A traced step is the same step, bit for bit, in USL and MUSL, in place or from one state
/// into another (two buffers taking turns, the first one empty); its trace holds the acted
/// nodes of the record and, expanded on every node, the step's nodal masses.
#[test]
fn a_traced_step_is_the_same_step_and_keeps_its_grid() {
    for scheme in [Scheme::Usl, Scheme::Musl] {
        let (mut config, p) = sliding_block(0.2, rubber());
        config.scheme = scheme;
        let n = config.grid.num_nodes();
        let (mut plain, mut traced) = (p.clone(), p.clone());
        let (mut from, mut into) = (p, Particles::default());
        let mut a = Solver::new(config.clone(), &plain).expect("valid");
        let mut b = Solver::new(config.clone(), &traced).expect("valid");
        let mut c = Solver::new(config, &from).expect("valid");
        let mut other = StepTrace::default();
        let mut trace = StepTrace::default();
        let mut sums = vec![NodeSums::zero(); n];
        let (mut velocity, mut velocity_old) = (vec![Vector::zeros(); n], vec![Vector::zeros(); n]);
        let mut states = vec![NodeState::default(); n];
        for _ in 0..20 {
            let mut record = StepRecord::default();
            a.step_recorded(&mut plain, f64::INFINITY, &mut record)
                .expect("stable");
            let info = b
                .step_traced(&mut traced, f64::INFINITY, &mut trace)
                .expect("stable");
            assert_eq!(plain, traced);
            c.step_traced_from(&from, &mut into, f64::INFINITY, &mut other)
                .expect("stable");
            std::mem::swap(&mut from, &mut into);
            assert_eq!(from, traced);
            assert_eq!(other.groups, trace.groups);
            assert_eq!(trace.dt, info.dt);
            assert_eq!(trace.acted().collect::<Vec<_>>(), record.nodes);
            assert!(trace.kept() < n, "only the nodes the block reaches");
            trace.expand(GridFields {
                sums: &mut sums,
                velocity: &mut velocity,
                velocity_old: &mut velocity_old,
                states: &mut states,
            });
            let masses: Vec<f64> = sums.iter().map(|s| s.m).collect();
            assert_eq!(masses, b.grid_mass());
            for &(i, state) in &record.nodes {
                assert_eq!(states[i], state);
            }
        }
    }
}
