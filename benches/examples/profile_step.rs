//! Runs explicit steps of the 2D 100k-particle fluid block (for profilers).
fn main() {
    let (config, mut p) = loam_benches::fluid_block_2d::<f64>(100_000);
    let mut s = loam_explicit::Solver::new(config, &p).unwrap();
    let t = std::time::Instant::now();
    for _ in 0..40 {
        s.step(&mut p, f64::INFINITY).unwrap();
    }
    println!("{:.2} ms/step", t.elapsed().as_secs_f64() * 1e3 / 40.0);
}
