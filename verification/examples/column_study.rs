//! The column-compaction error at 64 cells for each shape function and quadrature density,
//! the study behind the choice in `loam_verification::column::Setup::new`.
//!
//! `cargo run --release -p loam-verification --example column_study [CELLS]`

use loam_core::Shape;
use loam_verification::column::{Setup, Soil, error_norm, exact_stress};

fn main() {
    let cells = std::env::args()
        .nth(1)
        .map_or(64, |s| s.parse().expect("CELLS is a whole number"));
    println!(
        "| shape | particles per cell | error at {cells} cells | Newton iterations | wall (s) |"
    );
    println!("|---|---|---|---|---|");
    for shape in [
        Shape::Ugimp,
        Shape::Cpgimp,
        Shape::QuadraticBspline,
        Shape::CubicBspline,
    ] {
        for ppc in [2, 4] {
            let setup = Setup {
                ppc,
                shape,
                ..Setup::new(cells)
            };
            let t = std::time::Instant::now();
            let (stress, its) = setup.run(Soil::Elastic).expect("the column converges");
            let e = error_norm(stress.iter().map(|&(y0, s, _)| (s, exact_stress(y0))));
            println!(
                "| {shape:?} | {ppc} × {ppc} | {e:.3e} | {its} | {:.1} |",
                t.elapsed().as_secs_f64()
            );
        }
    }
}
