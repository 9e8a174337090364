//! The checkpoint contract: the explicit state is the particles, the simulated time and the
//! step count. A run stopped after `k` steps, saved to a file and read back (through
//! `loam_scene::checkpoint`, as `loam run --checkpoint-every` / `--resume` do), then
//! continued to step `n`, has the same bits at step `n` as the run that never stopped, with
//! one thread and with two.

use loam_core::Particles;
use loam_explicit::Solver;
use loam_scene::Scene;
use loam_scene::checkpoint::{CheckpointHeader, read_checkpoint, scene_hash, write_checkpoint};
use std::path::Path;

/// Drucker–Prager sand (history: the plastic strain and the elastic-strain state) thrown
/// along a friction floor (μ = 0.4 on a unilateral slip wall) next to a fixed wall, under
/// gravity: contact, friction, plastic flow and (APIC or MLS) the affine matrix in the state.
fn scene(transfer: &str) -> String {
    format!(
        r#"
[grid]
lo = [0.0, 0.0]
hi = [0.6, 0.3]
cell_size = 0.02

[[materials]]
name = "sand"
model = "drucker_prager"
density = 1800.0
youngs_modulus = 2.0e6
poisson_ratio = 0.3
friction_angle = 30.0
dilation_angle = 5.0

[[bodies]]
material = "sand"
shape = {{ type = "box", lo = [0.04, 0.0], hi = [0.24, 0.12] }}
velocity = [1.5, -0.2]

[boundaries]
x_min = "fixed"
x_max = "slip"
y_min = {{ kind = "slip", separable = true }}

[[friction]]
wall = "y_min"
mu = 0.4

[loads]
gravity = [0.0, -9.81]

[solver]
transfer = "{transfer}"
time_step = {{ type = "adaptive", cfl = 0.4, max_dt = 1e-3 }}
end_time = 1.0
"#
    )
}

fn steps(solver: &mut Solver<f64, 2>, p: &mut Particles<f64, 2>, n: usize) {
    for _ in 0..n {
        solver.step(p, f64::INFINITY).expect("a stable step");
    }
}

/// Every field of every particle, and the clock, as bits.
fn bits(p: &Particles<f64, 2>, solver: &Solver<f64, 2>) -> Vec<u64> {
    let mut out = vec![solver.time().to_bits(), solver.steps() as u64];
    for i in 0..p.len() {
        let fields = p.x[i].iter().chain(&p.v[i]).chain(&p.a[i]);
        let fields = fields.chain(&p.f[i]).chain(&p.c[i]).chain(&p.stress[i]);
        let fields = fields.chain(&p.half_width0[i]).chain(&p.state[i].tensor);
        out.extend(fields.map(|x| x.to_bits()));
        out.extend([p.mass[i], p.volume0[i], p.state[i].plastic_strain].map(f64::to_bits));
        out.push(u64::from(p.material[i]));
    }
    out
}

const STOP: usize = 25;
const END: usize = 60;

/// Step `END` of the uninterrupted run.
fn uninterrupted(text: &str) -> Vec<u64> {
    let built = Scene::from_toml_str(text).unwrap().build::<2>().unwrap();
    let mut p = built.particles.clone();
    let mut solver = Solver::new(built.explicit_config().expect("an explicit scene"), &p).unwrap();
    steps(&mut solver, &mut p, END);
    bits(&p, &solver)
}

/// Step `END` of the run saved to `file` after `STOP` steps and continued from the file in
/// a new solver; also whether the saved state had plastic flow and a non-zero affine matrix.
fn continued(text: &str, file: &Path) -> (Vec<u64>, bool, bool) {
    let built = Scene::from_toml_str(text).unwrap().build::<2>().unwrap();
    let hash = scene_hash(text.as_bytes());
    {
        let mut p = built.particles.clone();
        let mut solver =
            Solver::new(built.explicit_config().expect("an explicit scene"), &p).unwrap();
        steps(&mut solver, &mut p, STOP);
        let header = CheckpointHeader {
            dimension: 2,
            particles: p.len(),
            step: solver.steps() as u64,
            time: solver.time(),
            scene_hash: hash,
            source: "sand.toml".into(),
        };
        write_checkpoint(file, &header, &p).unwrap();
    }
    let (header, mut p) = read_checkpoint::<2>(file).unwrap();
    header
        .check_scene(file, 2, built.particles.len(), hash)
        .unwrap();
    let plastic = p.state.iter().any(|s| s.plastic_strain > 0.0);
    let affine = p.c.iter().any(|c| c.norm() > 0.0);
    let mut solver = Solver::new(built.explicit_config().expect("an explicit scene"), &p).unwrap();
    solver.set_clock(header.time, header.step as usize);
    steps(&mut solver, &mut p, END - STOP);
    (bits(&p, &solver), plastic, affine)
}

#[test]
fn a_run_continued_from_a_checkpoint_file_has_the_same_bits_at_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    for transfer in ["apic", "mls"] {
        let text = scene(transfer);
        let mut reference = None;
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let file = dir.path().join(format!("{transfer}_{threads}.ckpt"));
            let (whole, (resumed, plastic, affine)) =
                pool.install(|| (uninterrupted(&text), continued(&text, &file)));
            assert!(
                plastic && affine,
                "{transfer}: the saved state should carry plastic strain and C"
            );
            assert!(
                whole == resumed,
                "{transfer}, {threads} thread(s): the continued run differs from the \
                 uninterrupted one at step {END}"
            );
            // The same bits at any thread count, too.
            match &reference {
                None => reference = Some(whole),
                Some(r) => assert!(*r == whole, "{transfer}: 1 and 2 threads differ"),
            }
        }
    }
}
