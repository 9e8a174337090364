//! Mesh-refinement study of the finite-element reference for the plane-strain Hencky cantilever
//! (`loam_verification::fe_beam`): `P = 100 kN` in 50 load steps, both root supports, the load
//! at the tip `(L, d/2)` and at the MPM's load point `(L − 1/48, d/2)` (the centre of the last
//! particle column: particle spacing `0.25/6 m`).
//!
//! ```text
//! cargo run --release -p loam-verification --example fe_cantilever [-- MESH...]
//! ```
//!
//! `MESH` is `NXxNY` (default: 40x4 80x8 160x16 320x32). Prints one table row per run: the
//! deflection `v = −u_y` and inward displacement `u = −u_x` of the point `(x_load, d/2)` at full
//! load, the same of the end-face mean `(1/d)∫u(L, Y) dY` (`v̄`, `ū`), total Newton iterations
//! (largest per step), free DOFs and wall time; then the beam references and the load–deflection
//! path of the finest clamped tip-shear run against Reissner's beam. Load `point` is the point
//! force at `(x_load, d/2)`; `shear` is the parabolic shear traction on the end face (no
//! load-point singularity; `x_load` = L is then only the reported point).

use loam_verification::elastica::{tip_displacement, tip_displacement_reissner};
use loam_verification::fe_beam::{
    DEPTH, FeBeam, LENGTH, LOAD, LoadDistribution, POISSON, Support, YOUNG,
};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let meshes: Vec<(usize, usize)> = if args.is_empty() {
        vec![(40, 4), (80, 8), (160, 16), (320, 32)]
    } else {
        args.iter()
            .map(|a| {
                let (x, y) = a.split_once('x').expect("mesh as NXxNY");
                (x.parse().expect("NX"), y.parse().expect("NY"))
            })
            .collect()
    };
    let loads = [
        ("point", "L", LENGTH, LoadDistribution::Point),
        (
            "point",
            "L-1/48",
            LENGTH - 0.25 / 6.0 / 2.0,
            LoadDistribution::Point,
        ),
        ("shear", "L", LENGTH, LoadDistribution::TipShear),
    ];
    println!(
        "| mesh | support | load | x_load | v (m) | u (m) | v̄ face (m) | ū face (m) | Newton its (max/step) | DOFs | wall (s) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let mut path = None;
    for support in [Support::Pinned, Support::Clamped] {
        for (load, name, x_load, distribution) in loads {
            for &(nx, ny) in &meshes {
                let beam = FeBeam {
                    x_load,
                    distribution,
                    ..FeBeam::new(nx, ny, support)
                };
                match beam.run() {
                    Ok(run) => {
                        let [ux, uy] = *run.tip.last().expect("at least one step");
                        let [mx, my] = *run.tip_face_mean.last().expect("at least one step");
                        println!(
                            "| {nx}×{ny} | {support:?} | {load} | {name} | {:.5} | {:.5} | {:.5} | {:.5} | {} ({}) | {} | {:.1} |",
                            -uy,
                            -ux,
                            -my,
                            -mx,
                            run.iterations.iter().sum::<usize>(),
                            run.iterations.iter().max().expect("steps"),
                            run.dofs,
                            run.wall
                        );
                        if support == Support::Clamped && distribution == LoadDistribution::TipShear
                        {
                            path = Some((nx, ny, run.tip.clone()));
                        }
                    }
                    Err(e) => {
                        println!("| {nx}×{ny} | {support:?} | {load} | {name} | failed: {e} |")
                    }
                }
            }
        }
    }
    let i = DEPTH.powi(3) / 12.0;
    let ep = YOUNG / (1.0 - POISSON * POISSON);
    let g = YOUNG / (2.0 * (1.0 + POISSON));
    let (v, u) = tip_displacement(LOAD * LENGTH * LENGTH / (YOUNG * i));
    println!(
        "elastica, α = PL²/(EI) = 10:        v = {:.4} m, u = {:.4} m",
        v * LENGTH,
        u * LENGTH
    );
    let (v, u) = tip_displacement(LOAD * LENGTH * LENGTH / (ep * i));
    println!(
        "elastica, α′ = PL²/(E′I) = 9.6:     v = {:.4} m, u = {:.4} m",
        v * LENGTH,
        u * LENGTH
    );
    let ei = ep * i;
    let (v, u) = tip_displacement_reissner(
        LOAD * LENGTH * LENGTH / ei,
        ei / (ep * DEPTH * LENGTH * LENGTH),
        ei / (5.0 / 6.0 * g * DEPTH * LENGTH * LENGTH),
    );
    println!(
        "Reissner (E′A, κ = 5/6 GA, α′ = 9.6): v = {:.4} m, u = {:.4} m",
        v * LENGTH,
        u * LENGTH
    );
    if let Some((nx, ny, tip)) = path {
        println!(
            "\nload path, clamped, tip shear, {nx}×{ny}: λ, v (FE), v (Reissner), v (elastica α′)"
        );
        let steps = tip.len();
        for (k, t) in tip.iter().enumerate() {
            if (k + 1) % (steps / 10).max(1) == 0 {
                let lambda = (k + 1) as f64 / steps as f64;
                let (vr, _) = tip_displacement_reissner(
                    lambda * LOAD * LENGTH * LENGTH / ei,
                    ei / (ep * DEPTH * LENGTH * LENGTH),
                    ei / (5.0 / 6.0 * g * DEPTH * LENGTH * LENGTH),
                );
                let (ve, _) = tip_displacement(lambda * LOAD * LENGTH * LENGTH / ei);
                println!(
                    "  {lambda:.2}  {:.5}  {:.5}  {:.5}  (FE/Reissner − 1 = {:+.3} %)",
                    -t[1],
                    vr * LENGTH,
                    ve * LENGTH,
                    100.0 * (-t[1] / (vr * LENGTH) - 1.0)
                );
            }
        }
    }
}
