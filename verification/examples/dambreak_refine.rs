//! The `dambreak-2d` case at any cell size and particle density, for the refinement table of
//! docs/verification.md (the case itself runs h = 0.01 m in the tests and 0.004 m in
//! `loam verify`).
//!
//! `cargo run --release -p loam-verification --example dambreak_refine -- [H] [PPC]` with `H`
//! the cell size in metres (it must divide 0.1, 0.12 and 2 m; default 0.0025) and `PPC` the
//! particles per cell per axis (default 2). APIC, MUSL, Δt = 1e-5 s · H / 0.004 m (the
//! case's CFL number), window T_W = 0.5 s. Prints one row of the table.

use loam_core::Transfer;
use loam_verification::dambreak::{
    L0, Setup, late_error, late_speed, relative_error, ritter_front, simulate,
};

fn main() {
    let mut args = std::env::args().skip(1);
    let h: f64 = args
        .next()
        .map_or(0.0025, |s| s.parse().expect("H is a cell size in metres"));
    let ppc: usize = args
        .next()
        .map_or(2, |s| s.parse().expect("PPC is a whole number"));
    let t_w = 0.5;
    let setup = Setup {
        h,
        ppc,
        dt: 1e-5 * h / 0.004,
        transfer: Transfer::Apic,
    };
    let run = simulate(&setup, t_w, 120, &[]).expect("the dam break runs to the window's end");
    let &(t, x) = run.front.last().expect("the history holds t = 0");
    let travel = (x - L0) / (ritter_front(t) - L0) - 1.0;
    println!(
        "| h (m) | ppc | particles | steps | mean \\|e\\| over ⅔T_W–T_W | e(T_W) | travel error | \
         front speed (m/s) | wall (s) |"
    );
    println!(
        "| {h} | {ppc} | {} | {} | {:.2} % | {:.2} % | {:.1} % | {:.3} | {:.0} |",
        run.particles,
        run.steps,
        100.0 * late_error(&run.front, t_w),
        100.0 * relative_error(t, x),
        100.0 * travel,
        late_speed(&run.front, t_w),
        run.wall
    );
}
