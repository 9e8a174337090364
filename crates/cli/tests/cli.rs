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

/// A small explicit scene with plastic flow on a friction floor (see `tests/restart.rs`),
/// fixed Δt = 2e-4 s to 0.012 s: about 60 steps, 4 frames after the initial one.
const SAND: &str = r#"
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

[[bodies]]
material = "sand"
shape = { type = "box", lo = [0.04, 0.0], hi = [0.24, 0.12] }
velocity = [1.5, 0.0]

[boundaries]
x_min = "fixed"
y_min = { kind = "slip", separable = true }

[[friction]]
wall = "y_min"
mu = 0.4

[loads]
gravity = [0.0, -9.81]

[solver]
transfer = "mls"
time_step = { type = "fixed", dt = 2.0e-4 }
end_time = 0.012

[output]
frames = 4
"#;

#[test]
fn a_run_resumed_from_its_checkpoint_rewrites_the_later_frames_with_the_same_bytes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("sand.toml");
    std::fs::write(&scene, SAND).expect("write scene");
    let out = dir.path().join("out");
    let run = loam(&[
        "run",
        scene.to_str().expect("path"),
        "--out",
        out.to_str().expect("path"),
        "--checkpoint-every",
        "25",
        "--quiet",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let summary = |dir: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).expect("summary"))
            .expect("json")
    };
    let first = summary(&out);
    let steps = first["steps"].as_u64().expect("steps");
    let saved = first["checkpoint"]["step"]
        .as_u64()
        .expect("checkpoint step");
    assert_eq!(saved, steps / 25 * 25, "the latest multiple of 25 steps");
    assert!(out.join("checkpoint/state.ckpt").exists());
    assert_eq!(
        std::fs::read_to_string(out.join("checkpoint/scene.toml")).expect("scene copy"),
        SAND
    );
    let pvd = std::fs::read_to_string(out.join("particles.pvd")).expect("pvd");
    let last = std::fs::read(out.join("frame_0004.vtu")).expect("last frame");

    // Continue from the checkpoint: the frames after it are written again, identically,
    // and the series lists every frame once.
    let resumed = loam(&["run", "--resume", out.to_str().expect("path"), "--quiet"]);
    assert!(
        resumed.status.success(),
        "{}",
        String::from_utf8_lossy(&resumed.stderr)
    );
    assert_eq!(
        std::fs::read_to_string(out.join("particles.pvd")).expect("pvd"),
        pvd
    );
    assert!(std::fs::read(out.join("frame_0004.vtu")).expect("last frame") == last);
    let second = summary(&out);
    assert_eq!(second["status"], "completed");
    assert_eq!(second["steps"].as_u64(), Some(steps));
    assert_eq!(second["resumed_from"]["step"].as_u64(), Some(saved));
    assert_eq!(second["frames"].as_array().expect("frames").len(), 5);
    assert_eq!(second["energy"], first["energy"]);

    // A damaged checkpoint, an edited scene copy and a folder without a checkpoint are
    // input errors that name the problem.
    let state = out.join("checkpoint/state.ckpt");
    let bytes = std::fs::read(&state).expect("state");
    let resume = || loam(&["run", "--resume", out.to_str().expect("path"), "--quiet"]);
    let refused = |expected: &str| {
        let r = resume();
        let stderr = String::from_utf8_lossy(&r.stderr).into_owned();
        assert_eq!(r.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains(expected), "{expected}: {stderr}");
    };
    std::fs::write(&state, &bytes[..bytes.len() / 2]).expect("truncate");
    refused("truncated");
    let mut flipped = bytes.clone();
    flipped[bytes.len() / 2] ^= 1;
    std::fs::write(&state, &flipped).expect("flip a bit");
    refused("checksum mismatch");
    std::fs::write(&state, &bytes).expect("restore");
    std::fs::write(
        out.join("checkpoint/scene.toml"),
        SAND.replace("mu = 0.4", "mu = 0.5"),
    )
    .expect("edit the copy");
    refused("has changed since the state was saved");
    let empty = dir.path().join("empty");
    let r = loam(&["run", "--resume", empty.to_str().expect("path")]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("no checkpoint to resume"));

    // A fresh run into the folder removes the old checkpoint with the old frames' run.
    let again = loam(&[
        "run",
        scene.to_str().expect("path"),
        "--out",
        out.to_str().expect("path"),
        "--quiet",
    ]);
    assert!(again.status.success());
    assert!(!state.exists());
}

#[test]
fn checkpoints_are_refused_for_implicit_scenes() {
    let scene = workspace().join("crates/scene/tests/fixtures/good/implicit_2d.toml");
    let dir = tempfile::tempdir().expect("tempdir");
    let out = loam(&[
        "run",
        scene.to_str().expect("path"),
        "--out",
        dir.path().to_str().expect("path"),
        "--checkpoint-every",
        "5",
        "--quiet",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("for explicit runs"));
}
