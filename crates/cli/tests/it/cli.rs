//! End-to-end tests of the `loam` binary: exit codes, messages and files.

use crate::common::loam;
#[cfg(unix)]
use crate::common::{interrupt_when, spawn_loam};
use std::path::{Path, PathBuf};

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
    let files = |dir: PathBuf| {
        std::fs::read_dir(dir)
            .expect("examples")
            .map(|e| e.expect("entry").path())
            .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "toml" || e == "json"))
            .collect::<Vec<_>>()
    };
    let examples = workspace().join("examples");
    // The scenes, and the inversion files with their scene (`loam check` validates both);
    // data files beside them (a velocity CSV) are checked through the scenes that read them.
    let mut all = files(examples.clone());
    all.extend(files(examples.join("inverse")));
    all.extend(files(examples.join("consolidation")));
    for path in all {
        let out = loam(&["check", path.to_str().expect("utf-8 path")]);
        assert!(
            out.status.success(),
            "{}: {}",
            path.display(),
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

/// The reference scenes of the verification cases are scenes like any other: `loam check`
/// accepts each of them (velocity files included).
#[test]
fn check_accepts_the_verification_scenes() {
    let mut n = 0;
    for entry in std::fs::read_dir(workspace().join("verification/scenes")).expect("scenes") {
        let path = entry.expect("entry").path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        n += 1;
        let out = loam(&["check", path.to_str().expect("utf-8 path")]);
        assert!(
            out.status.success(),
            "{}: {}",
            path.display(),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    assert!(n >= 12, "expected the 12 reference scenes, found {n}");
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

/// Writes `text` as `name` in `dir` and returns its path as a string.
fn scene_file(dir: &Path, name: &str, text: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write scene");
    path.to_str().expect("utf-8 path").to_owned()
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).expect("summary"))
        .expect("json")
}

/// The frame files the `.pvd` of `dir` lists.
fn listed_frames(dir: &Path) -> Vec<String> {
    let pvd = std::fs::read_to_string(dir.join("particles.pvd")).expect("pvd");
    pvd.split("file=\"")
        .skip(1)
        .map(|rest| rest.split('"').next().expect("closing quote").to_owned())
        .collect()
}

/// A series is valid when every frame the `.pvd` lists exists, the summary lists the same
/// frames, and no temporary file is left over.
fn assert_valid_series(dir: &Path) {
    let listed = listed_frames(dir);
    for f in &listed {
        assert!(dir.join(f).exists(), "{f} listed but missing");
    }
    let in_summary = summary(dir)["frames"].as_array().expect("frames").len();
    assert_eq!(in_summary, listed.len());
    for entry in std::fs::read_dir(dir).expect("dir") {
        let name = entry.expect("entry").file_name();
        let name = name.to_string_lossy();
        assert!(!name.ends_with(".tmp"), "left over: {name}");
    }
}

/// The README's minimal scene with a given Young's modulus, end time and frame count.
fn readme_scene(youngs_modulus: f64, end_time: f64, frames: usize) -> String {
    format!(
        r#"
[grid]
lo = [0.0, 0.0]
hi = [1.0, 1.0]
cell_size = 0.02
shape_function = "quadratic_bspline"

[[materials]]
name = "rubber"
model = "neo_hookean"
density = 1000.0
youngs_modulus = {youngs_modulus:e}
poisson_ratio = 0.3

[[bodies]]
material = "rubber"
shape = {{ type = "disk", centre = [0.5, 0.5], radius = 0.2 }}

[boundaries]
y_min = "slip"

[loads]
gravity = [0.0, -9.81]

[solver]
time_step = {{ type = "adaptive", cfl = 0.4, max_dt = 1e-3 }}
end_time = {end_time:e}

[output]
frames = {frames}
"#
    )
}

/// A steel block at rest, h = 0.05 m, with a fixed step: `h / c` is 8.6e-6 s for steel
/// (c = √(M/ρ) ≈ 5.8 km/s), so 1e-3 s is far above it.
const STEEL_FIXED_1E3: &str = r#"
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
"#;

#[test]
fn a_fixed_dt_above_the_initial_stability_limit_is_refused_before_the_run() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = scene_file(dir.path(), "unstable.toml", STEEL_FIXED_1E3);
    let out = loam(&["check", &scene]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    for want in [
        "solver.time_step.dt",
        "stability limit",
        "particle 0 of material \"steel\"",
    ] {
        assert!(stderr.contains(want), "{want} missing from {stderr}");
    }
    // `run` refuses it the same way, before it writes anything.
    let out_dir = dir.path().join("out");
    let out = loam(&["run", &scene, "--out", out_dir.to_str().expect("path")]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("solver.time_step.dt"), "{stderr}");
    assert!(!out_dir.exists());
}

#[test]
fn an_unstable_run_stops_with_the_step_and_keeps_its_frames() {
    // A soft block (c = √(M/ρ) = 3.67 m/s with M = E(1−ν)/((1+ν)(1−2ν)) = 13,462 Pa) at
    // rest: h/c = 0.05/3.669 = 0.013628 s, so a fixed dt = 0.0136 s passes the check of the
    // initial state. Gravity of 100 m/s² gives it |v| = 1.36 m/s in the first step, after
    // which h/(c + |v|) = 0.0099 s: step 2 must be refused.
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = scene_file(
        dir.path(),
        "unstable.toml",
        r#"
[grid]
lo = [0.0, 0.0]
hi = [1.0, 1.0]
cell_size = 0.05

[[materials]]
name = "foam"
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e4
poisson_ratio = 0.3

[[bodies]]
material = "foam"
shape = { type = "box", lo = [0.4, 0.4], hi = [0.6, 0.6] }

[loads]
gravity = [0.0, -100.0]

[solver]
time_step = { type = "fixed", dt = 0.0136 }
end_time = 0.0544

[output]
frames = 4
"#,
    );
    let out_dir = dir.path().join("out");
    let out = loam(&[
        "run",
        &scene,
        "--out",
        out_dir.to_str().expect("path"),
        "--quiet",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("step 2") && stderr.contains("stability limit"),
        "{stderr}"
    );
    // The frames of t = 0 and of step 1 stay a valid series, and the summary says what
    // happened.
    assert_eq!(listed_frames(&out_dir).len(), 2);
    assert_valid_series(&out_dir);
    let summary = summary(&out_dir);
    assert_eq!(summary["status"], "failed");
    assert_eq!(summary["steps"], 1);
    assert!(
        summary["error"]
            .as_str()
            .expect("error")
            .contains("stability limit")
    );
}

#[test]
fn a_fixed_step_run_makes_round_end_time_over_dt_steps() {
    // end_time / dt = 0.01 / 3e-4 = 33.3: 33 steps, none shortened (stepping to the end
    // time would take 34, the last one shortened). Frames after steps ⌈33 k / 4⌉.
    let dir = tempfile::tempdir().expect("tempdir");
    let text = readme_scene(1.0e6, 0.01, 4).replace(
        r#"time_step = { type = "adaptive", cfl = 0.4, max_dt = 1e-3 }"#,
        r#"time_step = { type = "fixed", dt = 3e-4 }"#,
    );
    let scene = scene_file(dir.path(), "fixed.toml", &text);
    let out = loam(&["run", &scene, "--out", dir.path().to_str().expect("path")]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("33 steps"), "{stdout}");
    let s = summary(dir.path());
    assert_eq!(s["steps"], 33);
    assert_eq!(
        (s["dt_min"].as_f64(), s["dt_max"].as_f64()),
        (Some(3e-4), Some(3e-4))
    );
    let steps: Vec<u64> = s["energy"]
        .as_array()
        .expect("energy")
        .iter()
        .map(|e| e["step"].as_u64().expect("step"))
        .collect();
    assert_eq!(steps, [0, 9, 17, 25, 33]);
    let reached = s["time_reached"].as_f64().expect("time");
    assert!((reached - 33.0 * 3e-4).abs() < 1e-15, "{reached}");
}

#[test]
fn a_run_whose_strain_turns_non_finite_stops_with_the_step_the_field_and_the_ids() {
    // The README's scene with E = 1 Pa: the disk cannot carry its weight (ρ g R = 2 kPa ≫
    // E), collapses and crushes; det F falls below 1e-8 by t ≈ 0.35 s, where ½ ln(F Fᵀ) is no
    // longer computable (the smallest eigenvalue of F Fᵀ is lost in the round-off of the
    // largest) although F is finite with det F > 0.
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = scene_file(dir.path(), "soft.toml", &readme_scene(1.0, 1.0, 20));
    let out = loam(&[
        "run",
        &scene,
        "--out",
        dir.path().to_str().expect("path"),
        "--quiet",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    for want in ["non-finite strain", "first ids [", "det F is down to"] {
        assert!(stderr.contains(want), "{want} missing from {stderr}");
    }
    let error = summary(dir.path())["error"]
        .as_str()
        .expect("error")
        .to_owned();
    assert_eq!(summary(dir.path())["status"], "failed");
    assert!(
        error.starts_with("step ") && error.contains("strain"),
        "{error}"
    );
    // Every frame written is finite, and the series is valid.
    assert!(listed_frames(dir.path()).len() < 21);
    assert_valid_series(dir.path());
}

#[test]
fn a_scene_too_large_for_memory_is_refused_before_anything_is_built() {
    let dir = tempfile::tempdir().expect("tempdir");
    // cell_size = 1e-4 on the README's 1 m square: 1e8 cells and 5e7 particles, about
    // 70 GiB.
    let fine = scene_file(
        dir.path(),
        "fine.toml",
        &readme_scene(1.0e6, 1.0, 20).replace("cell_size = 0.02", "cell_size = 1e-4"),
    );
    // 1000³ cells in 3D: 1e9 grid nodes, some 250 GiB before a particle.
    let cube = scene_file(
        dir.path(),
        "cube.toml",
        r#"
[grid]
lo = [0.0, 0.0, 0.0]
hi = [1.0, 1.0, 1.0]
cell_size = 0.001

[[materials]]
name = "m"
model = "linear_elastic"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3

[[bodies]]
material = "m"
shape = { type = "box", lo = [0.4, 0.4, 0.4], hi = [0.41, 0.41, 0.41] }

[solver]
time_step = { type = "adaptive", cfl = 0.4, max_dt = 1e-3 }
end_time = 1.0
"#,
    );
    for (scene, field) in [(&fine, "grid.cell_size"), (&cube, "grid.cell_size")] {
        for command in ["check", "run"] {
            let out_dir = dir.path().join("out");
            let mut args = vec!["--memory-limit", "16", command, scene];
            if command == "run" {
                args.extend(["--out", out_dir.to_str().expect("path")]);
            }
            let out = loam(&args);
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{command} {scene}: {stderr}");
            for want in [
                field,
                "particles",
                "grid nodes",
                "GiB of memory",
                "16.0 GiB",
            ] {
                assert!(stderr.contains(want), "{want} missing from {stderr}");
            }
            assert!(!out_dir.exists());
        }
    }
    // A scene that fits: check reports its estimates.
    let ok = scene_file(dir.path(), "ok.toml", &readme_scene(1.0e6, 1.0, 20));
    let out = loam(&["check", &ok]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("MiB of memory"),
        "{stdout}"
    );
    assert!(stdout.contains("steps"), "{stdout}");
}

#[test]
fn runs_that_cannot_finish_are_refused_and_long_ones_warned_about() {
    // A stable fixed step of 1e-6 s to 1000 s: 1e9 steps, above the 1e8 a run may take; and
    // 200,000 frames.
    let dir = tempfile::tempdir().expect("tempdir");
    let text = readme_scene(1.0e6, 1000.0, 200_000).replace(
        r#"time_step = { type = "adaptive", cfl = 0.4, max_dt = 1e-3 }"#,
        r#"time_step = { type = "fixed", dt = 1e-6 }"#,
    );
    let scene = scene_file(dir.path(), "long.toml", &text);
    let out_dir = dir.path().join("out");
    for command in ["check", "run"] {
        let mut args = vec![command, scene.as_str()];
        if command == "run" {
            args.extend(["--out", out_dir.to_str().expect("path")]);
        }
        let out = loam(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{command}: {stderr}");
        for want in [
            "solver.end_time: about 1.00e9 steps",
            "solver.time_step.dt",
            "--max-steps",
        ] {
            assert!(stderr.contains(want), "{want} missing from {stderr}");
        }
    }
    assert!(!out_dir.exists());
    // `--max-steps` allows it; then 1.26e12 particle-steps and the frames are warned about.
    let out = loam(&["--max-steps", "2000000000", "check", &scene]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning:") && stderr.contains("particle-steps: this run may take days"),
        "{stderr}"
    );
    assert!(stderr.contains("output.frames: 200000 frames"), "{stderr}");
}

/// Values in the wrong unit that would make a run last for ever or abort: a Young's modulus
/// of 1e300 Pa (its stability limit, h/c ≈ 5e-151 s, is 5e150 steps per second of run), an
/// end time of 1e12 s, a fixed step of 1e-300 s, a billion frames (8 GB of frame times alone;
/// with an adaptive step a step each) and 1e12 load steps of an implicit run. Each is refused
/// by `check` and `run` (exit 2, nothing written), naming the field.
#[test]
fn runs_of_values_in_the_wrong_unit_are_refused_naming_the_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let implicit = std::fs::read_to_string(
        workspace().join("crates/scene/tests/fixtures/good/implicit_2d.toml"),
    )
    .expect("fixture")
    .replace("load_steps = 20", "load_steps = 1000000000000");
    let cases = [
        (
            readme_scene(1.0e300, 1.0, 20),
            "solver.end_time",
            "stability limit",
            None,
        ),
        (
            readme_scene(1.0e6, 1.0e12, 20),
            "solver.end_time",
            "4.59e15 steps",
            None,
        ),
        (
            readme_scene(1.0e6, 1.0, 20).replace(
                r#"time_step = { type = "adaptive", cfl = 0.4, max_dt = 1e-3 }"#,
                r#"time_step = { type = "fixed", dt = 1e-300 }"#,
            ),
            "solver.end_time",
            "1.00e300 steps",
            None,
        ),
        // The frames' bookkeeping, about 600 bytes a frame: 560 GiB.
        (
            readme_scene(1.0e6, 1.0, 1_000_000_000),
            "output.frames",
            "GiB of memory",
            Some("4"),
        ),
        // Where the memory allows it: a step at least per frame.
        (
            readme_scene(1.0e6, 1.0, 1_000_000_000),
            "output.frames",
            "about 1.00e9 steps",
            Some("1000"),
        ),
        (implicit, "solver.load_steps", "1.00e12 steps", None),
    ];
    for (k, (text, field, words, memory)) in cases.iter().enumerate() {
        let scene = scene_file(dir.path(), &format!("case{k}.toml"), text);
        let out_dir = dir.path().join(format!("out{k}"));
        for command in ["check", "run"] {
            let mut args = Vec::new();
            if let Some(gib) = memory {
                args.extend(["--memory-limit", gib]);
            }
            args.extend([command, scene.as_str()]);
            if command == "run" {
                args.extend(["--out", out_dir.to_str().expect("path")]);
            }
            let out = loam(&args);
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "case {k} {command}: {stderr}");
            assert!(
                stderr.contains(&format!("{field}: ")) && stderr.contains(words),
                "case {k} {command}: {stderr}"
            );
        }
        assert!(!out_dir.exists(), "case {k}");
    }
}

/// An output folder that cannot be written (here, a path through a file: refused even to
/// root) is invalid input: `run` and `invert` exit 2 naming the folder, before a step.
#[test]
fn an_unwritable_output_folder_is_invalid_input() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = scene_file(dir.path(), "ok.toml", &readme_scene(1.0e6, 0.01, 2));
    let inversion = workspace().join("examples/inverse/friction.toml");
    let file = dir.path().join("a_file");
    std::fs::write(&file, "").expect("a file");
    let blocked = file.join("out");
    let blocked = blocked.to_str().expect("path");
    let runs = [
        vec!["run", scene.as_str(), "--quiet", "--out", blocked],
        vec![
            "invert",
            inversion.to_str().expect("path"),
            "--out",
            blocked,
        ],
    ];
    for args in runs {
        let out = loam(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains("cannot write to the output folder") && stderr.contains(blocked),
            "{args:?}: {stderr}"
        );
    }
}

#[test]
fn a_second_run_into_a_folder_replaces_the_first_runs_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out_dir = dir.path().join("out");
    let out_arg = out_dir.to_str().expect("path");
    let six = scene_file(dir.path(), "six.toml", &readme_scene(1.0e6, 0.01, 6));
    let two = scene_file(dir.path(), "two.toml", &readme_scene(1.0e6, 0.01, 2));
    assert!(
        loam(&["run", &six, "--out", out_arg, "--quiet"])
            .status
            .success()
    );
    assert!(out_dir.join("frame_0006.vtu").exists());
    std::fs::write(out_dir.join("notes.txt"), "mine").expect("write");
    assert!(
        loam(&["run", &two, "--out", out_arg, "--quiet"])
            .status
            .success()
    );
    for k in 3..=6 {
        assert!(!out_dir.join(format!("frame_{k:04}.vtu")).exists());
    }
    assert_eq!(listed_frames(&out_dir).len(), 3);
    assert_valid_series(&out_dir);
    assert!(
        out_dir.join("notes.txt").exists(),
        "a file the run did not write was removed"
    );
}

#[test]
fn progress_is_printed_as_lines_when_stderr_is_not_a_terminal() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = scene_file(dir.path(), "s.toml", &readme_scene(1.0e6, 0.01, 2));
    let out_arg = dir.path().join("out");
    let out_arg = out_arg.to_str().expect("path");
    let out = loam(&["run", &scene, "--out", out_arg, "--progress-every", "0"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    // At 0 s, a line after every step.
    let steps = summary(Path::new(out_arg))["steps"]
        .as_u64()
        .expect("steps");
    assert_eq!(
        stderr.matches("progress: ").count() as u64,
        steps,
        "{stderr}"
    );
    assert!(stderr.contains(&format!("step {steps},")), "{stderr}");
    let quiet = loam(&["run", &scene, "--out", out_arg, "--quiet"]);
    assert!(!String::from_utf8_lossy(&quiet.stderr).contains("progress: "));
    let bad = loam(&["run", &scene, "--out", out_arg, "--progress-every", "inf"]);
    assert_eq!(bad.status.code(), Some(2));
}

#[test]
fn frames_carry_the_particle_ids() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = workspace().join("crates/scene/tests/fixtures/good/box_2d.toml");
    let out = loam(&[
        "run",
        scene.to_str().expect("path"),
        "--out",
        dir.path().to_str().expect("path"),
        "--quiet",
    ]);
    assert!(out.status.success());
    let frame = std::fs::read_to_string(dir.path().join("frame_0000.vtu")).expect("frame");
    assert!(frame.contains(r#"type="UInt64" Name="id""#), "no id array");
}

#[test]
fn too_many_threads_are_refused() {
    let scene = workspace().join("examples/disk_collision.toml");
    let out = loam(&["--threads", "20000", "check", scene.to_str().expect("path")]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--threads 20000: at most 1024"), "{stderr}");
}

/// Ctrl-C: a real SIGINT to the running process ends the run after a step, with the summary
/// written (`interrupted`), a valid series, and the exit code 130.
#[cfg(unix)]
#[test]
fn sigint_ends_a_run_cleanly() {
    let dir = tempfile::tempdir().expect("tempdir");
    // 1000 s at 1e-3 s a step: a run of minutes, with a frame every 10 steps.
    let scene = scene_file(
        dir.path(),
        "long.toml",
        &readme_scene(1.0e6, 1000.0, 100_000),
    );
    let out_dir = dir.path().join("out");
    let child = spawn_loam(&[
        "run",
        &scene,
        "--quiet",
        "--out",
        out_dir.to_str().expect("path"),
    ]);
    // Wait for a few frames, then interrupt.
    let (code, stderr) = interrupt_when(child, 60, || out_dir.join("frame_0003.vtu").exists());
    assert_eq!(code, Some(130), "{stderr}");
    assert!(stderr.contains("interrupted after"), "{stderr}");
    let s = summary(&out_dir);
    assert_eq!(s["status"], "interrupted");
    assert!(s["steps"].as_u64().expect("steps") >= 30);
    assert_valid_series(&out_dir);
}

/// The `.pvd` times of `dir`, in order.
fn listed_times(dir: &Path) -> Vec<f64> {
    let pvd = std::fs::read_to_string(dir.join("particles.pvd")).expect("pvd");
    pvd.split("timestep=\"")
        .skip(1)
        .map(|rest| {
            let t = rest.split('"').next().expect("closing quote");
            t.parse().expect("a time")
        })
        .collect()
}

/// Ctrl-C with checkpoints: the interrupted run keeps its latest checkpoint and names the
/// command that continues it; the continued run (interrupted in turn) keeps the frames up to
/// the checkpoint, writes the later ones again with the same bytes and numbers on, so the
/// series lists every frame once, in time order.
#[cfg(unix)]
#[test]
fn an_interrupted_run_keeps_its_checkpoint_and_continues_without_duplicate_frames() {
    use loam_scene::checkpoint::CheckpointHeader;
    let dir = tempfile::tempdir().expect("tempdir");
    // A fixed step of 1e-4 s (a fifth of the initial h / c) to 100 s: 10⁶ steps, a frame
    // every 10 steps, a checkpoint every 20.
    let text = readme_scene(1.0e6, 100.0, 100_000).replace(
        "{ type = \"adaptive\", cfl = 0.4, max_dt = 1e-3 }",
        "{ type = \"fixed\", dt = 1e-4 }",
    );
    let scene = scene_file(dir.path(), "long.toml", &text);
    let out_dir = dir.path().join("out");
    let out_arg = out_dir.to_str().expect("path");
    let state = out_dir.join("checkpoint/state.ckpt");
    let saved_step = || CheckpointHeader::peek(&state).map_or(0, |h| h.step);
    let child = spawn_loam(&[
        "run",
        &scene,
        "--quiet",
        "--out",
        out_arg,
        "--checkpoint-every",
        "20",
    ]);
    let (code, stderr) = interrupt_when(child, 60, || saved_step() >= 40);
    assert_eq!(code, Some(130), "{stderr}");
    assert!(
        stderr.contains(&format!("loam run --resume {out_arg}")),
        "{stderr}"
    );
    let first = summary(&out_dir);
    assert_eq!(first["status"], "interrupted");
    let saved = first["checkpoint"]["step"]
        .as_u64()
        .expect("checkpoint step");
    let saved_time = first["checkpoint"]["time"]
        .as_f64()
        .expect("checkpoint time");
    assert!(saved >= 40 && saved.is_multiple_of(20), "{saved}");
    assert!(saved <= first["steps"].as_u64().expect("steps"));
    assert_eq!(
        saved_step(),
        saved,
        "the checkpoint the summary names is kept"
    );
    let before = listed_frames(&out_dir);
    let kept = listed_times(&out_dir)
        .iter()
        .filter(|&&t| t <= saved_time)
        .count();
    // Frames at steps 0, 10, …, up to the checkpoint.
    assert_eq!(kept as u64, saved / 10 + 1);
    let rewritten = before.get(kept).map(|f| {
        (
            f.clone(),
            std::fs::read(out_dir.join(f)).expect("a frame after the checkpoint"),
        )
    });

    let child = spawn_loam(&[
        "run",
        "--resume",
        out_arg,
        "--quiet",
        "--checkpoint-every",
        "20",
    ]);
    let (code, stderr) = interrupt_when(child, 60, || saved_step() >= saved + 40);
    assert_eq!(code, Some(130), "{stderr}");
    let second = summary(&out_dir);
    assert_eq!(second["status"], "interrupted");
    assert_eq!(second["resumed_from"]["step"].as_u64(), Some(saved));
    assert!(second["steps"].as_u64().expect("steps") >= saved + 40);
    let after = listed_frames(&out_dir);
    let numbered: Vec<String> = (0..after.len())
        .map(|k| format!("frame_{k:04}.vtu"))
        .collect();
    assert_eq!(after, numbered, "every frame once, numbered on");
    assert!(after.len() > kept + 1, "{} frames", after.len());
    assert_eq!(after[..kept], before[..kept]);
    let times = listed_times(&out_dir);
    assert!(times.windows(2).all(|w| w[0] < w[1]), "{times:?}");
    if let Some((name, bytes)) = rewritten {
        assert!(
            std::fs::read(out_dir.join(&name)).expect("rewritten frame") == bytes,
            "{name} differs from the first run's"
        );
    }
    assert_valid_series(&out_dir);
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
    // A CPU-only case asked for the GPU: exit 2 before any adapter is opened.
    let cpu_only = loam(&["verify", "cantilever", "--device", "gpu"]);
    let stderr = String::from_utf8_lossy(&cpu_only.stderr);
    assert_eq!(cpu_only.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("cantilever runs on the CPU only"),
        "{stderr}"
    );
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
    // `--memory` is the gradient bench's; a budget below its least is refused.
    for (args, words) in [
        (
            &["bench", "--memory", "1GB", "dambreak"][..],
            "name `gradient`",
        ),
        (
            &["bench", "--memory", "1kB", "--steps", "20", "gradient"][..],
            "is too small",
        ),
        (
            &["bench", "--memory", "lots", "gradient"][..],
            "expected a size such as 512MB",
        ),
    ] {
        let out = loam(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(words), "{args:?}: {stderr}");
    }
    let out = loam(&["bench", "dambreak-2m"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("unknown bench `dambreak-2m`") && stderr.contains("dambreak-1m"),
        "{stderr}"
    );
    // `--profile` times GPU kernels: refused on the CPU, and for zero steps.
    for (args, words) in [
        (
            &["bench", "--profile", "5", "dambreak"][..],
            "use it with --device gpu",
        ),
        (
            &[
                "bench",
                "--device",
                "gpu",
                "--profile",
                "0",
                "dambreak-3d-125k",
            ][..],
            "--profile must be at least 1 step",
        ),
        (
            &["bench", "--p2g", "gather", "dambreak"][..],
            "--p2g chooses the GPU's transfer; use it with --device gpu",
        ),
        (
            &["bench", "--device", "gpu", "--p2g", "atomics"][..],
            "invalid value 'atomics' for '--p2g <P2G>'",
        ),
    ] {
        let out = loam(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(words), "{args:?}: {stderr}");
    }
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
    // and the series lists every frame once. The scene file was edited in between: the run
    // says so and continues with the recorded copy (the frames are those of the first run).
    std::fs::write(&scene, SAND.replace("mu = 0.4", "mu = 0.1")).expect("edit the scene");
    let resumed = loam(&["run", "--resume", out.to_str().expect("path"), "--quiet"]);
    let stderr = String::from_utf8_lossy(&resumed.stderr);
    assert!(resumed.status.success(), "{stderr}");
    assert!(
        stderr.contains("note: ")
            && stderr.contains("sand.toml has changed since the run started")
            && stderr.contains("checkpoint/scene.toml"),
        "{stderr}"
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

/// A reader that goes away (`loam verify --list | head -0`) ends loam quietly by SIGPIPE, as
/// for other Unix tools, instead of a panic about a failed print: stdout is a pipe whose read
/// end is closed before loam starts, so its first line meets a broken pipe.
#[cfg(unix)]
#[test]
fn a_closed_stdout_pipe_ends_loam_by_sigpipe_without_a_panic() {
    use std::os::unix::process::ExitStatusExt;
    let (reader, writer) = std::io::pipe().expect("a pipe");
    drop(reader);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_loam"))
        .args(["verify", "--list"])
        .stdout(writer)
        .output()
        .expect("the loam binary runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(out.status.signal(), Some(13), "{:?}: {stderr}", out.status);
}
