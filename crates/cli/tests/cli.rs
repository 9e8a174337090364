//! End-to-end tests of the `loam` binary: exit codes, messages and files.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn loam(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_loam"))
        .args(args)
        .output()
        .expect("the loam binary runs")
}

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn check_rejects_every_malformed_fixture_with_exit_2_and_a_field_path() {
    let dir = workspace().join("crates/scene/tests/fixtures/bad");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).expect("fixture folder") {
        let path = entry.expect("entry").path();
        let out = loam(&["check", path.to_str().expect("utf-8 path")]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{}: {stderr}", path.display());
        assert!(
            stderr.starts_with("error: "),
            "{}: {stderr}",
            path.display()
        );
        assert!(!stderr.contains("panicked"), "{}: {stderr}", path.display());
        // Every message names the file and a location: a field path (`a.b`, `a[0]`) or a
        // line/column for syntax errors.
        let named = stderr.contains('.') && (stderr.contains(": ") || stderr.contains("line"));
        assert!(named, "{}: no field named in {stderr}", path.display());
        n += 1;
    }
    assert!(
        n >= 10,
        "expected at least 10 malformed fixtures, found {n}"
    );
}

#[test]
fn check_accepts_the_examples() {
    for entry in std::fs::read_dir(workspace().join("examples")).expect("examples") {
        let path = entry.expect("entry").path();
        let out = loam(&["check", path.to_str().expect("utf-8 path")]);
        assert!(
            out.status.success(),
            "{}: {}",
            path.display(),
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

#[test]
fn run_writes_a_paraview_series_and_a_summary() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = workspace().join("crates/scene/tests/fixtures/good/box_2d.toml");
    let out = loam(&[
        "run",
        scene.to_str().expect("path"),
        "--out",
        dir.path().to_str().expect("path"),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let pvd = std::fs::read_to_string(dir.path().join("particles.pvd")).expect("pvd written");
    let frames = pvd.matches("<DataSet").count();
    assert!(frames >= 2, "{pvd}");
    assert!(dir.path().join("frame_0000.vtu").exists());
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("summary.json")).expect("summary"),
    )
    .expect("json");
    assert_eq!(summary["status"], "completed");
    assert!(summary["steps"].as_u64().expect("steps") > 0);
    assert_eq!(summary["frames"].as_array().expect("frames").len(), frames);
}

#[test]
fn an_unstable_run_stops_with_the_step_and_keeps_its_frames() {
    // A stiff block with a fixed time step far above h/c: the first step must be refused.
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("unstable.toml");
    std::fs::write(
        &scene,
        r#"
[grid]
lo = [0.0, 0.0]
hi = [1.0, 1.0]
cell_size = 0.05

[[materials]]
name = "steel"
model = "neo_hookean"
density = 7800.0
youngs_modulus = 2.0e11
poisson_ratio = 0.3

[[bodies]]
material = "steel"
shape = { type = "box", lo = [0.2, 0.2], hi = [0.4, 0.4] }

[solver]
time_step = { type = "fixed", dt = 1.0e-3 }
end_time = 0.01

[output]
frames = 2
"#,
    )
    .expect("write scene");
    let out_dir = dir.path().join("out");
    let out = loam(&[
        "run",
        scene.to_str().expect("path"),
        "--out",
        out_dir.to_str().expect("path"),
        "--quiet",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("step 1") && stderr.contains("stability limit"),
        "{stderr}"
    );
    // The initial frame stays a valid series, and the summary says what happened.
    assert!(out_dir.join("frame_0000.vtu").exists());
    let pvd = std::fs::read_to_string(out_dir.join("particles.pvd")).expect("pvd");
    assert_eq!(pvd.matches("<DataSet").count(), 1);
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out_dir.join("summary.json")).expect("summary"),
    )
    .expect("json");
    assert_eq!(summary["status"], "failed");
    assert!(
        summary["error"]
            .as_str()
            .expect("error")
            .contains("stability limit")
    );
}

#[test]
fn verify_lists_cases_and_writes_json() {
    let out = loam(&["verify", "--list"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("axial-bar") && stdout.contains("disk-collision")
    );
    let bad = loam(&["verify", "no-such-case"]);
    assert_eq!(bad.status.code(), Some(2));
    let dir = tempfile::tempdir().expect("tempdir");
    let json = dir.path().join("out.json");
    let out = loam(&[
        "verify",
        "axial-bar",
        "--reduced",
        "--json",
        json.to_str().expect("path"),
        "--out",
        dir.path().to_str().expect("path"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("json")).expect("parse");
    let first = &v.as_array().expect("array")[0];
    for key in ["case", "metric", "value", "tolerance", "passed"] {
        assert!(first.get(key).is_some(), "missing {key} in {first}");
    }
    assert_eq!(first["case"], "axial-bar");
    assert!(dir.path().join("axial-bar/axial_bar.png").exists());
}

#[test]
fn bench_lists_its_scenes_and_refuses_an_unknown_one() {
    let out = loam(&["bench", "--list"]);
    assert!(out.status.success());
    let list = String::from_utf8_lossy(&out.stdout);
    for name in ["dambreak", "dambreak-1m", "column-3d", "cantilever"] {
        assert!(list.contains(name), "{name} missing from {list}");
    }
    let out = loam(&["bench", "dambreak-2m"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("unknown bench `dambreak-2m`") && stderr.contains("dambreak-1m"),
        "{stderr}"
    );
}

#[test]
fn bench_times_the_dam_break_and_writes_json() {
    let dir = tempfile::tempdir().expect("tempdir");
    let json = dir.path().join("bench.json");
    let out = loam(&[
        "bench",
        "dambreak",
        "--steps",
        "3",
        "--json",
        json.to_str().expect("path"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("json written"))
            .expect("valid json");
    let row = &rows[0];
    assert_eq!(row["bench"], "dambreak");
    // The friction dam-break: a 0.5 m × 0.3 m block at 2 × 2 particles per 0.01 m cell.
    assert_eq!(row["particles"], 6000);
    assert_eq!(row["steps"], 3);
    let (wall, rate) = (
        row["wall_s"].as_f64().expect("wall"),
        row["particle_steps_per_s"].as_f64().expect("rate"),
    );
    assert!(wall > 0.0 && (rate * wall - 18_000.0).abs() < 1e-6 * 18_000.0);
}
