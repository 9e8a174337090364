//! The `bui-collapse` and `column-runout` cases at any cell size, for the refinement columns
//! of docs/verification.md (the cases themselves run h = 10 mm in the tests and 5 mm in
//! `loam verify`).
//!
//! `cargo run --release -p loam-verification --example granular_refine -- [H]` with `H` the
//! cell size in metres (a divisor of 0.01; default 0.0025).

use loam_verification::granular::simulate;
use loam_verification::{Device, bui, runout};

fn main() {
    let h: f64 = std::env::args()
        .nth(1)
        .map_or(0.0025, |s| s.parse().expect("H is a cell size in metres"));
    println!(
        "| case | a | toe L∞ (m) | (L∞ − L₀)/L₀ | film toe (m) | farthest particle (m) \
         | height at the wall (m) | particles | steps | wall (s) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let bui = bui::collapse(h);
    let columns = runout::COLUMNS.map(|(l0, h0)| ("column-runout", runout::collapse(l0, h0, h)));
    for (case, c) in std::iter::once(("bui-collapse", bui)).chain(columns) {
        let o = simulate(case, &c, &Device::Cpu, 50).expect("the collapse runs to its end");
        let last = o.last();
        println!(
            "| {case} | {:.2} | {:.4} | {:.3} | {:.4} | {:.4} | {:.4} | {} | {} | {:.0} |",
            c.aspect(),
            o.runout(),
            o.normalised_runout(),
            last.film_toe,
            o.max_x,
            last.wall_height,
            o.particles,
            o.steps,
            o.wall
        );
    }
}
