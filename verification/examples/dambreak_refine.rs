//! The `dambreak-2d` case at any cell size, particle density, time step, transfer and sound
//! speed, for the refinement tables of docs/verification.md (the case itself runs h = 0.02 and
//! 0.01 m in the tests, 0.01 and 0.004 m in `loam verify`).
//!
//! `cargo run --release -p loam-verification --example dambreak_refine -- [H] [PPC] [dt=DT]
//! [transfer=T] [c=C]` with `H` the cell size in metres (it must divide 0.1, 0.12 and 2 m;
//! default 0.0025), `PPC` the particles per cell per axis (default 2), `DT` the time step in
//! seconds (default 1e-5 s · H / 0.004 m, CFL ≈ 0.09; the case runs CFL ≈ 0.37), `T` one of `apic` (the
//! default), `tpic`, `flip` (α = 1), `pic` or `mls`, and `C` the sound speed in m/s (default
//! 35). MUSL, window T_W = 0.5 s. Prints one row of the table.

use loam_core::Transfer;
use loam_verification::Device;
use loam_verification::dambreak::{
    L0, SOUND_SPEED, Setup, late_error, late_speed, relative_error, ritter_front, simulate,
};

/// The transfer named `name` on the command line.
fn transfer(name: &str) -> Transfer {
    match name {
        "apic" => Transfer::Apic,
        "tpic" => Transfer::Tpic,
        "flip" => Transfer::Flip { alpha: 1.0 },
        "pic" => Transfer::Pic,
        "mls" => Transfer::Mls,
        other => panic!("transfer={other}: expected apic, tpic, flip, pic or mls"),
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (options, positional): (Vec<&String>, Vec<&String>) =
        args.iter().partition(|a| a.contains('='));
    let h: f64 = positional
        .first()
        .map_or(0.0025, |s| s.parse().expect("H is a cell size in metres"));
    let ppc: usize = positional
        .get(1)
        .map_or(2, |s| s.parse().expect("PPC is a whole number"));
    let mut setup = Setup {
        h,
        ppc,
        dt: 1e-5 * h / 0.004,
        transfer: Transfer::Apic,
        sound_speed: SOUND_SPEED,
    };
    for option in options {
        let (key, value) = option.split_once('=').expect("an option is key=value");
        let number = || -> f64 {
            value
                .parse()
                .unwrap_or_else(|_| panic!("{key}={value}: expected a number"))
        };
        match key {
            "dt" => setup.dt = number(),
            "c" => setup.sound_speed = number(),
            "transfer" => setup.transfer = transfer(value),
            other => panic!("unknown option {other}: expected dt, transfer or c"),
        }
    }
    let t_w = 0.5;
    let run = simulate(&setup, &Device::Cpu, t_w, 120, &[])
        .expect("the dam break runs to the window's end");
    let &(t, x) = run.front.last().expect("the history holds t = 0");
    let travel = (x - L0) / (ritter_front(t) - L0) - 1.0;
    println!(
        "| h (m) | ppc | Δt (s) | transfer | c (m/s) | particles | steps | mean \\|e\\| over \
         ⅔T_W–T_W | e(T_W) | travel error | front speed (m/s) | wall (s) |"
    );
    println!(
        "| {h} | {ppc} | {:e} | {:?} | {} | {} | {} | {:.2} % | {:.2} % | {:.1} % | {:.3} | {:.0} |",
        setup.dt,
        setup.transfer,
        setup.sound_speed,
        run.particles,
        run.steps,
        100.0 * late_error(&run.front, t_w),
        100.0 * relative_error(t, x),
        100.0 * travel,
        late_speed(&run.front, t_w),
        run.wall
    );
}
