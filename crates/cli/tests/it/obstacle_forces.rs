//! `loam run` reports the force of each rigid obstacle on the material in explicit runs:
//! `summary.json` (`obstacle_forces`) and `obstacle_forces.csv`.

use crate::common::loam;

/// A 0.1 m square elastic block (ρ = 1000 kg/m³: M = 10 kg per metre run) falls 4 cm onto a
/// fixed box and rests on it; the walls are far away and the transfer is APIC, so the
/// material's momentum changes only by gravity and the box: `P(T) = −M g T e_y + I(T)`,
/// `I` the box's impulse, the sum of the reported mean forces times their intervals. The
/// block's momentum at the end is bounded by its kinetic energy, `|P(T)| ≤ √(2 M K(T))`
/// (Cauchy–Schwarz over the particles), so the reported forces must satisfy
/// `|I_y − M g T| ≤ √(2 M K(T))` and `|I_x| ≤ √(2 M K(T))`, to round-off.
#[test]
fn an_explicit_run_reports_the_force_of_each_obstacle() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("drop.toml");
    let out = dir.path().join("out");
    std::fs::write(
        &scene,
        format!(
            r#"[grid]
lo = [0.0, 0.0]
hi = [0.6, 0.6]
cell_size = 0.02

[[materials]]
name = "rubber"
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3

[[bodies]]
material = "rubber"
shape = {{ type = "box", lo = [0.25, 0.25], hi = [0.35, 0.35] }}
particles_per_cell = 2

[[obstacles]]
shape = "box"
lo = [0.1, 0.1]
hi = [0.5, 0.18]

[boundaries]
x_min = "slip"
x_max = "slip"
y_min = "slip"
y_max = "slip"

[loads]
gravity = [0.0, -9.81]

[solver]
type = "explicit"
scheme = "musl"
transfer = "apic"
time_step = {{ type = "fixed", dt = 2.0e-4 }}
end_time = 0.4

[output]
dir = "{}"
frames = 9
"#,
            out.display()
        ),
    )
    .unwrap();
    let run = loam(&["run", "--quiet", scene.to_str().unwrap()]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let samples = summary["obstacle_forces"]
        .as_array()
        .expect("obstacle_forces");
    // One sample per interval between the 10 frames (`frames = 9` after the initial one).
    assert_eq!(samples.len(), 9);
    let (mut impulse, mut end) = ([0.0; 2], 0.0f64);
    for s in samples {
        let span = s["time"].as_f64().unwrap() - s["since"].as_f64().unwrap();
        for (a, total) in impulse.iter_mut().enumerate() {
            *total += s["forces"][0][a].as_f64().unwrap() * span;
        }
        end = end.max(s["time"].as_f64().unwrap());
    }
    let (mass, g) = (10.0, 9.81);
    let kinetic = summary["energy"].as_array().unwrap().last().unwrap()["kinetic"]
        .as_f64()
        .unwrap();
    let bound = (2.0 * mass * kinetic).sqrt();
    let last = samples.last().unwrap()["forces"][0][1].as_f64().unwrap();
    println!(
        "I = ({:.5}, {:.5}) N·s/m, M g T = {:.5}, |P(T)| ≤ {bound:.5}; last mean force F_y = \
         {last:.3} N/m (M g = {:.3})",
        impulse[0],
        impulse[1],
        mass * g * end,
        mass * g
    );
    // Round-off: the sums of a few thousand steps, far below 1e-9 of M g T.
    let slack = 1e-9 * mass * g * end;
    assert!((impulse[1] - mass * g * end).abs() <= bound + slack);
    assert!(impulse[0].abs() <= bound + slack);
    // The box holds the block up: a positive vertical force on the material.
    assert!(last > 0.0, "{last}");
    // The CSV has the same samples, one row each after the header.
    let csv = std::fs::read_to_string(out.join("obstacle_forces.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "step,time,since,obstacles[0].fx,obstacles[0].fy,obstacles[0].ux,obstacles[0].uy"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), samples.len());
    assert_eq!(rows.last().unwrap()[4], last);
}
