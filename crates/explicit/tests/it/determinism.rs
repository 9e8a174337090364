//! Bitwise determinism of the explicit solver across rayon thread counts.

use loam_core::tensor::Vector;
use loam_core::*;
use loam_explicit::{Config, Solver};

/// An elastic block dropped onto a slip floor next to a fixed wall: gravity, walls, contact of
/// particles through the grid, deformation; 3000+ particles across many P2G blocks.
fn scene<const D: usize>(transfer: Transfer) -> (Config<f64, D>, Particles<f64, D>) {
    let h = 0.05;
    let mut boundary = Boundary::all(Wall::new(WallKind::Slip));
    boundary.walls[0][0] = Wall::new(WallKind::Fixed);
    let mut gravity = Vector::<f64, D>::zeros();
    gravity[1] = -9.81;
    let config = Config {
        grid: Grid::new([0.0; D], [20; D], h, 2),
        shape: Shape::QuadraticBspline,
        transfer,
        scheme: Scheme::Musl,
        boundary,
        contact: Default::default(),
        gravity,
        materials: vec![Material::elastic(ModelKind::NeoHookean, 2.0e5, 0.3, 1000.0)],
        time_step: TimeStep::Adaptive {
            cfl: 0.4,
            max_dt: 1e-3,
        },
    };
    let mut particles = Particles::default();
    let dp = h / 2.0;
    let n: usize = if D == 2 { 32 } else { 12 };
    let hw = Vector::<f64, D>::repeat(dp / 2.0);
    for k in 0..n.pow(D as u32) {
        let mut x = Vector::<f64, D>::zeros();
        let mut r = k;
        for a in 0..D {
            x[a] = 0.1 + (r % n) as f64 * dp + 0.013 * a as f64;
            r /= n;
        }
        let v = Vector::<f64, D>::from_fn(|a, _| 0.3 * (a as f64 + 1.0) * (x[0] - 0.5));
        particles.push(x, v, 1000.0, hw, 0);
    }
    (config, particles)
}

fn run<const D: usize>(threads: usize, transfer: Transfer) -> Particles<f64, D> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    pool.install(|| {
        let (config, mut particles) = scene::<D>(transfer);
        let mut solver = Solver::new(config, &particles).expect("valid scene");
        for _ in 0..100 {
            solver
                .step(&mut particles, f64::INFINITY)
                .expect("stable step");
        }
        particles
    })
}

fn bits<const D: usize>(p: &Particles<f64, D>) -> Vec<u64> {
    let mut out = Vec::new();
    for i in 0..p.len() {
        out.extend(p.x[i].iter().chain(p.v[i].iter()).map(|x| x.to_bits()));
        out.extend(p.f[i].iter().chain(p.c[i].iter()).map(|x| x.to_bits()));
        out.extend(p.stress[i].iter().map(|x| x.to_bits()));
    }
    out
}

#[test]
fn same_bits_with_one_and_two_threads_2d() {
    for transfer in [Transfer::Apic, Transfer::Mls] {
        let (a, b) = (run::<2>(1, transfer), run::<2>(2, transfer));
        assert!(
            bits(&a) == bits(&b),
            "2D particle state differs between 1 and 2 threads ({transfer:?})"
        );
        // The run did something: the block moved and deformed.
        assert!(
            a.x.iter()
                .zip(&scene::<2>(transfer).1.x)
                .any(|(x, x0)| (x - x0).norm() > 1e-3)
        );
    }
}

#[test]
fn same_bits_with_one_and_two_threads_3d() {
    let (a, b) = (run::<3>(1, Transfer::Apic), run::<3>(2, Transfer::Apic));
    assert!(
        bits(&a) == bits(&b),
        "3D particle state differs between 1 and 2 threads"
    );
}

/// The same steps through `Solver::advance_exactly_to` from outside any pool: the run is held on
/// the global pool with its other workers kept awake (`loam_explicit::pool::hold`), which
/// changes the schedule of the parallel phases and nothing else.
fn held_run<const D: usize>(transfer: Transfer) -> Particles<f64, D> {
    let (config, mut particles) = scene::<D>(transfer);
    let mut solver = Solver::new(config, &particles).expect("valid scene");
    let mut steps = 0;
    let mut end = 0.0;
    // The end time of the 100 steps `run` takes (the step is adaptive).
    let (config, mut probe) = scene::<D>(transfer);
    let mut timer = Solver::new(config, &probe).expect("valid scene");
    for _ in 0..100 {
        end = timer
            .step(&mut probe, f64::INFINITY)
            .expect("stable step")
            .time;
    }
    solver
        .advance_exactly_to(&mut particles, end, |_, _| steps += 1)
        .expect("stable run");
    assert_eq!(steps, 100);
    particles
}

#[test]
fn a_held_run_has_the_bits_of_a_one_thread_run() {
    for transfer in [Transfer::Apic, Transfer::Mls] {
        assert!(
            bits(&held_run::<2>(transfer)) == bits(&run::<2>(1, transfer)),
            "2D particle state of the held run differs ({transfer:?})"
        );
    }
}
