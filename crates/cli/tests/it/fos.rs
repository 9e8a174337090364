//! End-to-end tests of `loam fos`: the search's files and exit codes, bad input naming the
//! field, and Ctrl-C.

use crate::common::loam;
#[cfg(unix)]
use crate::common::{interrupt_when, spawn_loam};
use std::path::Path;

/// A vertical cut 4 m high in undrained clay (J2: Tresca with c_u = 10 kPa; γ = 20 kN/m³),
/// a block `[0, 8] × [0, 4]` m on a fixed base with a slip wall behind it, cells of `h` m,
/// gravity switched on over `steps` load steps, and `fos` as the `[fos]` section (its factor
/// of safety, about 0.45, is checked against limit analysis in `loam-implicit`'s tests).
fn cut_scene(dir: &Path, h: f64, steps: usize, fos: &str) -> String {
    let text = format!(
        r#"[grid]
lo = [0.0, 0.0]
hi = [12.0, {top}]
cell_size = {h}

[[materials]]
name = "clay"
model = "j2"
density = 2000.0
youngs_modulus = 20.0e6
poisson_ratio = 0.3
yield_stress = 17320.508075688773

[[bodies]]
material = "clay"
shape = {{ type = "box", lo = [0.0, 0.0], hi = [8.0, 4.0] }}

[boundaries]
x_min = "slip"
y_min = "fixed"

[loads]
gravity = [0.0, -10.0]

[solver]
type = "implicit"
load_steps = {steps}

{fos}
"#,
        top = 4.0 + 2.0 * h
    );
    let path = dir.join("cut.toml");
    std::fs::write(&path, text).expect("scene written");
    path.to_str().expect("utf-8 path").to_string()
}

fn summary(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("fos.json")).expect("fos.json");
    serde_json::from_str(&text).expect("fos.json is JSON")
}

/// The search brackets the cut's factor of safety to the tolerance, prints a table and the
/// result, and writes every trial (factor, outcome, iterations, largest displacement) and the
/// bracket to fos.json and the plot to fos.png; `--tolerance` overrides `fos.tolerance`.
#[test]
fn fos_brackets_a_vertical_cut_and_writes_its_summary_and_plot() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = cut_scene(dir.path(), 1.0, 8, "[fos]\ntolerance = 0.5\nstart = 0.5");
    let out_dir = dir.path().join("out");
    let out = loam(&[
        "fos",
        &scene,
        "--out",
        out_dir.to_str().expect("path"),
        "--tolerance",
        "0.02",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("factor of safety F ="), "{stdout}");
    assert!(stdout.contains("max|u| (m)"), "{stdout}");
    let s = summary(&out_dir);
    assert_eq!(s["status"], "completed");
    assert_eq!(s["tolerance"], 0.02);
    assert_eq!(s["start"], 0.5);
    assert!(
        s["failure_criterion"]
            .as_str()
            .expect("text")
            .contains("does not converge")
    );
    let (lo, hi) = (
        s["stable_factor"].as_f64().expect("stable"),
        s["failed_factor"].as_f64().expect("failed"),
    );
    assert!(hi > lo && hi - lo <= 0.02, "[{lo}, {hi}]");
    let f = s["factor_of_safety"].as_f64().expect("F");
    assert!((f - 0.5 * (lo + hi)).abs() < 1e-12);
    let trials = s["trials"].as_array().expect("trials");
    assert_eq!(trials[0]["factor"], 0.5);
    for t in trials {
        let stable = t["converged"].as_bool().expect("converged");
        assert_eq!(t["outcome"], if stable { "stable" } else { "failed" });
        assert_eq!(t["reason"].is_null(), stable);
        assert!(t["max_displacement"].as_f64().expect("displacement") > 0.0);
        let steps = t["load_steps"].as_array().expect("load steps");
        assert!(!steps.is_empty());
        let its: u64 = steps
            .iter()
            .map(|s| s["iterations"].as_u64().expect("iterations"))
            .sum();
        assert_eq!(its, t["iterations"].as_u64().expect("iterations"));
        if stable {
            assert_eq!(steps.len(), 8);
            assert_eq!(t["load_factor"], 1.0);
        }
    }
    let png = std::fs::read(out_dir.join("fos.png")).expect("fos.png");
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    // The mechanism: the bracket's stable and failed states as two frames at their factors.
    let pvd = out_dir.join("mechanism").join("particles.pvd");
    assert_eq!(s["mechanism"].as_str(), pvd.to_str());
    let frames = loam_scene::output::read_pvd(&pvd).expect("the mechanism's series");
    let times: Vec<f64> = frames.iter().map(|e| e.time).collect();
    assert_eq!(times, [lo, hi]);
    for e in &frames {
        assert!(
            out_dir.join("mechanism").join(&e.file).is_file(),
            "{}",
            e.file
        );
    }
}

/// Bad input exits 2 naming the field: the option, a `[fos]` key, a scene without a strength
/// to reduce, and an explicit scene.
#[test]
fn fos_refuses_bad_input_with_exit_2_naming_the_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = cut_scene(dir.path(), 1.0, 8, "");
    for (args, want) in [
        (
            vec!["fos", scene.as_str(), "--tolerance=-1"],
            "--tolerance -1",
        ),
        (
            vec!["fos", scene.as_str(), "--tolerance", "-1"],
            "--tolerance -1: expected a positive number",
        ),
        (
            vec!["fos", scene.as_str(), "--tolerance", "0"],
            "--tolerance 0",
        ),
        (
            vec!["fos", scene.as_str(), "--tolerance", "nan"],
            "--tolerance NaN",
        ),
    ] {
        let out = loam(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(want), "{args:?}: {stderr}");
    }
    for (edit, want) in [
        (
            ("[solver]", "[fos]\ntolerance = 0.0\n\n[solver]"),
            "fos.tolerance: must be positive, got 0",
        ),
        (
            ("[solver]", "[fos]\nmax_trials = 0\n\n[solver]"),
            "fos.max_trials: must be at least 1, got 0",
        ),
    ] {
        let text = std::fs::read_to_string(&scene)
            .expect("scene")
            .replacen(edit.0, edit.1, 1);
        let path = dir.path().join("bad.toml");
        std::fs::write(&path, text).expect("written");
        let out = loam(&["fos", path.to_str().expect("path")]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{want}: {stderr}");
        assert!(stderr.contains(want), "{want}: {stderr}");
    }
    // An elastic scene: nothing to reduce.
    let elastic = std::fs::read_to_string(&scene)
        .expect("scene")
        .replacen("model = \"j2\"", "model = \"hencky\"", 1)
        .replacen("yield_stress = 17320.508075688773\n", "", 1);
    let path = dir.path().join("elastic.toml");
    std::fs::write(&path, elastic).expect("written");
    let out = loam(&["fos", path.to_str().expect("path")]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("materials: no material has a strength to reduce"),
        "{stderr}"
    );
    // An explicit scene.
    let explicit = std::fs::read_to_string(&scene).expect("scene").replacen(
        "type = \"implicit\"\nload_steps = 8",
        "time_step = { type = \"fixed\", dt = 1e-4 }\nend_time = 0.01",
        1,
    );
    let path = dir.path().join("explicit.toml");
    std::fs::write(&path, explicit).expect("written");
    let out = loam(&["fos", path.to_str().expect("path")]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("solver.type: the factor of safety"),
        "{stderr}"
    );
}

/// Ctrl-C: a real SIGINT after the first trial ends the search before the next load step,
/// with fos.json written (`interrupted`, the first trial complete, the second, when it had
/// started, recorded as interrupted) and the exit code 130.
#[cfg(unix)]
#[test]
fn sigint_ends_a_search_with_what_was_done_written() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Trials of 400 load steps: seconds each, so the second is still running when asked.
    let scene = cut_scene(dir.path(), 0.5, 400, "[fos]\nstart = 0.1\ntolerance = 1e-6");
    let out_dir = dir.path().join("out");
    let child = spawn_loam(&[
        "fos",
        &scene,
        "--quiet",
        "--out",
        out_dir.to_str().expect("path"),
    ]);
    // The second trial starts as soon as the first is written; half a second into its
    // 400 load steps (seconds in all) it is running, but a slow machine may still be
    // between the trials, where the search stops without starting it.
    let (code, stderr) = interrupt_when(child, 120, || {
        let written = out_dir.join("fos.json").exists();
        if written {
            std::thread::sleep(std::time::Duration::from_millis(500));
        }
        written
    });
    assert_eq!(code, Some(130), "{stderr}");
    assert!(stderr.contains("interrupted after"), "{stderr}");
    let s = summary(&out_dir);
    assert_eq!(s["status"], "interrupted");
    assert!(s["factor_of_safety"].is_null());
    let trials = s["trials"].as_array().expect("trials");
    assert!(matches!(trials.len(), 1 | 2), "{} trials", trials.len());
    assert_eq!(trials[0]["outcome"], "stable");
    assert_eq!(
        trials[0]["load_steps"].as_array().expect("steps").len(),
        400
    );
    if let Some(second) = trials.get(1) {
        assert_eq!(second["outcome"], "interrupted");
        let steps = second["load_steps"].as_array().expect("steps").len();
        assert!(steps < 400, "{steps} load steps");
    }
    assert!(out_dir.join("fos.png").exists());
}
