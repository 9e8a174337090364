//! End-to-end tests of `loam gradient`, `loam invert` and `loam check` on inversion files.

use crate::common::{assert_refused, loam, repo, text};
use std::path::{Path, PathBuf};
use std::process::Output;

/// A file of `examples/inverse/`.
fn example(name: &str) -> PathBuf {
    repo("examples/inverse").join(name)
}

/// A small inversion of the example scene: the initial horizontal velocity (truth 2.0, first
/// guess 0.5) from 10 particles every 20 steps of a 200-step run.
fn tiny(dir: &Path, max_iterations: usize, initial: f64) -> String {
    let scene = example("dambreak_small.toml");
    let body = format!(
        r#"scene = "{}"
steps = 200

[[parameters]]
name = "velocity"
direction = [1.0, 0.0]
initial = {initial}
truth = 2.0

[synthetic]
particles = 10
every = 20

[stop]
max_iterations = {max_iterations}
gradient = 1e-11
"#,
        scene.display()
    );
    let path = dir.join("tiny.toml");
    std::fs::write(&path, body).expect("write");
    path.to_str().expect("utf-8").to_owned()
}

fn history(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("history.json")).expect("history"))
        .expect("json")
}

/// `--check` passes; `--json` holds the printed loss and gradient to the last bit: the
/// table prints 11 significant digits, so each printed value is within 5e-11 relative of
/// the file's.
#[test]
fn gradient_check_agrees_with_the_dual_run() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("gradient.json");
    let out = loam(&[
        "gradient",
        example("friction.toml").to_str().unwrap(),
        "--check",
        "--json",
        json.to_str().unwrap(),
    ]);
    let all = text(&out);
    // The command fails when the adjoint and the dual derivative differ by more than 1e-8.
    assert!(out.status.success(), "{all}");
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("--json wrote")).unwrap();
    let close = |printed: &str, exact: &serde_json::Value| {
        let (p, e) = (printed.parse::<f64>().unwrap(), exact.as_f64().unwrap());
        assert!((p - e).abs() <= 5e-11 * e.abs(), "printed {p}, json {e}");
    };
    let loss = all.split("L = ").nth(1).and_then(|l| l.split(' ').next());
    close(loss.expect("the loss line"), &doc["loss"]);
    for (k, p) in doc["parameters"].as_array().unwrap().iter().enumerate() {
        assert_eq!(p["name"], format!("friction[{k}]"));
        assert_eq!(p["gradient"], doc["gradient"][k]);
        let row = all
            .lines()
            .find(|l| l.trim_start().starts_with(&format!("friction[{k}] ")));
        let printed = row
            .and_then(|r| r.split_whitespace().nth(2))
            .expect("the table row");
        close(printed, &p["gradient"]);
    }
    for p in [
        "friction[0]",
        "friction[1]",
        "friction[2]",
        "central diff.",
        "r(h/8)",
    ] {
        assert!(all.contains(p), "{p} missing in {all}");
    }
}

/// The explicit adjoint through Modified Cam-Clay: λ, κ, M, the OCR (through `p_c₀` of the
/// initial state) and K0 (through the initial stress and history) of a coarse, short version
/// of `examples/footing_explicit_clay.toml` (288 particles, 100 fixed steps, the footing
/// moving at 0.5 m/s) from 40 synthetic particles. `--check` fails (exit 1) when the adjoint differs
/// from the forward-mode dual run or both from converged central differences; the table names
/// the five parameters.
#[test]
fn gradient_check_through_modified_cam_clay_in_an_explicit_scene() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = std::fs::read_to_string(repo("examples/footing_explicit_clay.toml")).unwrap();
    for (from, to) in [
        ("cell_size = 0.01", "cell_size = 0.05"),
        ("lo = [0.0, 0.32]", "lo = [0.0, 0.3]"),
        ("hi = [0.05, 0.38]", "hi = [0.1, 0.4]"),
        ("velocity = [0.0, -0.1]", "velocity = [0.0, -0.5]"),
        (
            "time_step = { type = \"adaptive\", cfl = 0.4, max_dt = 1e-3 }",
            "time_step = { type = \"fixed\", dt = 5e-4 }",
        ),
        ("end_time = 0.35", "end_time = 0.05"),
    ] {
        assert!(scene.contains(from), "{from} not in the example");
        scene = scene.replacen(from, to, 1);
    }
    std::fs::write(dir.path().join("scene.toml"), scene).unwrap();
    let inversion = dir.path().join("clay.toml");
    std::fs::write(
        &inversion,
        r#"scene = "scene.toml"

[[parameters]]
name = "materials[0].lambda"
initial = 0.22
truth = 0.2

[[parameters]]
name = "materials[0].kappa"
initial = 0.036
truth = 0.04

[[parameters]]
name = "materials[0].critical_state_slope"
initial = 1.1
truth = 1.0

[[parameters]]
name = "materials[0].ocr"
initial = 1.6
truth = 1.5

[[parameters]]
name = "materials[0].k0"
initial = 0.9
truth = 1.0

[synthetic]
particles = 40
seed = 1
every = 10
"#,
    )
    .unwrap();
    let out = loam(&["gradient", inversion.to_str().unwrap(), "--check"]);
    let all = text(&out);
    assert!(out.status.success(), "{all}");
    for p in [
        "materials[0].lambda",
        "materials[0].kappa",
        "materials[0].critical_state_slope",
        "materials[0].ocr",
        "materials[0].k0",
        "central diff.",
    ] {
        assert!(all.contains(p), "{p} missing in {all}");
    }
}

#[test]
fn invert_recovers_the_initial_velocity_and_writes_its_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let file = tiny(dir.path(), 20, 0.5);
    let out_dir = dir.path().join("out");
    let out = loam(&["invert", &file, "--out", out_dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out));
    let h = history(&out_dir);
    let last = h["entries"].as_array().unwrap().last().unwrap().clone();
    let v0 = last["parameters"][0].as_f64().unwrap();
    // Synthetic data from the same discrete model: the minimum is the truth, and L-BFGS on
    // this one-dimensional smooth loss reaches it to round-off (1e-6 leaves a wide margin).
    assert!((v0 - 2.0).abs() < 1e-6, "{v0}\n{}", text(&out));
    for f in [
        "history.csv",
        "history_loss.png",
        "history_parameters.png",
        "tracked.csv",
        "checkpoint.json",
        "recovered_dambreak_small.toml",
    ] {
        assert!(out_dir.join(f).exists(), "{f} not written");
    }
    // The recovered scene is a valid scene holding the recovered velocity.
    let recovered = out_dir.join("recovered_dambreak_small.toml");
    let check = loam(&["check", recovered.to_str().unwrap()]);
    assert!(check.status.success(), "{}", text(&check));
    let table: toml::Table = std::fs::read_to_string(&recovered)
        .unwrap()
        .parse()
        .unwrap();
    let written = table["bodies"][0]["velocity"][0].as_float().unwrap();
    assert_eq!(written, v0);
    // The synthetic observations can be read back as real ones: at the truth the loss is 0.
    let real = format!(
        "scene = \"{}\"\nsteps = 200\n[[parameters]]\nname = \"velocity\"\ndirection = [1.0, 0.0]\ninitial = 2.0\n[observations]\ntracked = \"{}\"\n",
        example("dambreak_small.toml").display(),
        out_dir.join("tracked.csv").display()
    );
    let real_path = dir.path().join("real.toml");
    std::fs::write(&real_path, real).unwrap();
    let g = loam(&["gradient", real_path.to_str().unwrap()]);
    assert!(text(&g).contains("L = 0.0000000000e0"), "{}", text(&g));
}

#[test]
fn resume_continues_exactly_where_the_run_stopped() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    std::fs::create_dir_all(&a).unwrap();
    std::fs::create_dir_all(&b).unwrap();
    // Straight through 6 iterations, and 2 then resumed to 6 (only [stop] changed).
    let whole = tiny(&a, 6, 0.5);
    assert!(
        loam(&["invert", &whole, "--out", a.to_str().unwrap()])
            .status
            .success()
    );
    let part = tiny(&b, 2, 0.5);
    assert!(
        loam(&["invert", &part, "--out", b.to_str().unwrap()])
            .status
            .success()
    );
    assert_eq!(history(&b)["entries"].as_array().unwrap().len(), 3);
    let part = tiny(&b, 6, 0.5);
    let out = loam(&["invert", &part, "--out", b.to_str().unwrap(), "--resume"]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains("resuming from iteration 2"),
        "{}",
        text(&out)
    );
    // The optimiser's state is saved exactly: the same iterates to the last bit.
    let (ha, hb) = (
        history(&a)["entries"].clone(),
        history(&b)["entries"].clone(),
    );
    let params = |h: &serde_json::Value| -> Vec<String> {
        h.as_array()
            .unwrap()
            .iter()
            .map(|e| e["parameters"].to_string())
            .collect()
    };
    assert_eq!(params(&ha), params(&hb));
    // Another inversion (a different first guess) is not resumed.
    let other = tiny(&b, 6, 0.7);
    let out = loam(&["invert", &other, "--out", b.to_str().unwrap(), "--resume"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(text(&out).contains("differs"), "{}", text(&out));
}

#[test]
fn invert_recovers_a_velocity_field_and_reports_its_error() {
    // The velocity-field example made tiny: 80 steps, 50 tracked particles every 20 steps, a
    // 2 → 8 → 8 → 1 network, 8 L-BFGS iterations.
    let dir = tempfile::tempdir().unwrap();
    let body = format!(
        "scene = \"{}\"\nsteps = 80\n[[velocity_field]]\ndirection = [1.0, 0.0]\nhidden = [8, 8]\nseed = 3\n\
         [synthetic]\nscene = \"{}\"\nparticles = 50\nevery = 20\n[stop]\nmax_iterations = 8\n",
        example("mlp_column.toml").display(),
        example("mlp_column_truth.toml").display()
    );
    let file = dir.path().join("field.toml");
    std::fs::write(&file, body).unwrap();
    let out_dir = dir.path().join("out");
    let out = loam(&[
        "invert",
        file.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let all = text(&out);
    assert!(out.status.success(), "{all}");
    assert!(all.contains("relative L2 error against the truth"), "{all}");
    let h = history(&out_dir);
    let entries = h["entries"].as_array().unwrap();
    let error = |e: &serde_json::Value| e["field_errors"][0].as_f64().unwrap();
    let (first, last) = (error(&entries[0]), error(entries.last().unwrap()));
    // The Glorot start is far from the truth (vx of order 1 everywhere against a random
    // field); eight quasi-Newton steps on the positions must at least halve the error.
    assert!(first > 0.5 && last < 0.5 * first, "{first} → {last}\n{all}");
    let loss = |e: &serde_json::Value| e["loss"].as_f64().unwrap();
    assert!(
        loss(entries.last().unwrap()) < 1e-2 * loss(&entries[0]),
        "{all}"
    );
    for f in [
        "history.csv",
        "history_loss.png",
        "history_field_error.png",
        "recovered_velocity.csv",
    ] {
        assert!(out_dir.join(f).exists(), "{f} not written");
    }
    // The recovered scene reads the recovered velocities as its body's velocity file.
    let recovered = out_dir.join("recovered_mlp_column.toml");
    let check = loam(&["check", recovered.to_str().unwrap()]);
    assert!(check.status.success(), "{}", text(&check));
    let g = loam(&["gradient", file.to_str().unwrap(), "--check"]);
    assert!(g.status.success(), "{}", text(&g));
    assert!(
        text(&g).contains("velocity_field[0].w[104]"),
        "{}",
        text(&g)
    );
}

#[test]
fn deposit_observations_round_trip_through_their_csv_file() {
    // The synthetic final deposit written by `loam invert` and read back as data gives the
    // same loss (the CSV holds every digit), and the gradient of the deposit loss agrees with
    // the dual run (`--check` exits 1 otherwise).
    let dir = tempfile::tempdir().unwrap();
    let scene = example("dambreak_small.toml");
    let stations = "[[observations.stations]]\nname = \"a\"\nat = [0.3]\n\
                    [[observations.stations]]\nname = \"b\"\nat = [0.45]\nwidth = 0.05\n";
    let body = |observations: &str| {
        format!(
            "scene = \"{}\"\nsteps = 200\n[[parameters]]\nname = \"friction[1]\"\n\
             initial = 0.5\ntruth = 0.1\ntransform = \"softplus\"\n{observations}",
            scene.display()
        )
    };
    let synthetic = dir.path().join("synthetic.toml");
    std::fs::write(
        &synthetic,
        body(&format!(
            "[observations]\ndeposit_weight = 10.0\n{stations}[synthetic]\n[stop]\n\
             max_iterations = 1\n"
        )),
    )
    .unwrap();
    let out = dir.path().join("out");
    let run = loam(&[
        "invert",
        synthetic.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(run.status.success(), "{}", text(&run));
    let csv = std::fs::read_to_string(out.join("deposit.csv")).expect("deposit.csv");
    assert!(csv.starts_with("step,station,depth\n200,a,"), "{csv}");
    let data = dir.path().join("data.toml");
    std::fs::write(
        &data,
        body(&format!(
            "[observations]\ndeposit = \"{}\"\ndeposit_weight = 10.0\n{stations}",
            out.join("deposit.csv").display()
        )),
    )
    .unwrap();
    let first_loss = |o: &Output| {
        let t = text(o);
        let at = t.find("L = ").expect("a loss") + 4;
        t[at..].split_whitespace().next().unwrap().to_owned()
    };
    let g1 = loam(&["gradient", synthetic.to_str().unwrap()]);
    let g2 = loam(&["gradient", data.to_str().unwrap(), "--check"]);
    assert!(g2.status.success(), "{}", text(&g2));
    assert_eq!(
        first_loss(&g1),
        first_loss(&g2),
        "{}\n{}",
        text(&g1),
        text(&g2)
    );
    assert_ne!(first_loss(&g1), "0.0000000000e0");
}

#[test]
fn malformed_inversion_files_exit_2_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let scene = example("dambreak_small.toml");
    let head = format!("scene = \"{}\"\nsteps = 20\n", scene.display());
    let param = "[[parameters]]\nname = \"friction[1]\"\ninitial = 0.5\ntruth = 0.1\n";
    let synth = "[synthetic]\nparticles = 5\nevery = 10\n";
    let cases = [
        // (body, expected field path, expected words)
        (
            format!(
                "{head}{synth}[[parameters]]\nname = \"friction[7]\"\ninitial = 0.5\ntruth = 0.1\n"
            ),
            "parameters[0].name",
            "friction segments",
        ),
        (
            format!("{head}{synth}[[parameters]]\nname = \"mu\"\ninitial = 0.5\ntruth = 0.1\n"),
            "parameters[0].name",
            "expected",
        ),
        (
            format!("{head}{synth}[[parameters]]\nname = \"friction[1]\"\ninitial = 0.5\n"),
            "parameters[0].truth",
            "[synthetic]",
        ),
        (
            format!("{head}{synth}{param}[optimizer]\nmethod = \"adam\"\nlearning_rate = -1.0\n"),
            "optimizer.learning_rate",
            "positive",
        ),
        (
            format!(
                "{head}{synth}{param}[optimizer]\nmethod = \"levenberg_marquardt\"\ndamping = 0.0\n"
            ),
            "optimizer.damping",
            "positive",
        ),
        (
            format!(
                "{head}{synth}[[velocity_field]]\ndirection = [1.0, 0.0]\n[optimizer]\nmethod = \"levenberg_marquardt\"\n"
            ),
            "optimizer.method",
            "at most 16",
        ),
        (
            format!("{head}{synth}{param}[stop]\nmax_iteration = 3\n"),
            "stop.max_iteration",
            "unknown field",
        ),
        (
            format!("{head}{synth}{param}transform = \"softplus\"\nbounds = [0.2, 1.0]\n"),
            "parameters[0].truth",
            "outside the bounds",
        ),
        (
            format!(
                "{head}{synth}[[parameters]]\nname = \"friction[1]\"\ninitial = 0.0\ntruth = 0.0\ntransform = \"softplus\"\n"
            ),
            "parameters[0].initial",
            "starts positive",
        ),
        (
            format!("{head}{param}"),
            "observations",
            "expected `tracked`",
        ),
        (
            format!("{head}{param}[observations]\ntracked = \"obs.csv\"\n"),
            "observations.tracked",
            "line 2",
        ),
        (
            format!(
                "{head}{synth}[[parameters]]\nname = \"velocity\"\ninitial = 1.0\ntruth = 2.0\ndirection = [1.0]\n"
            ),
            "parameters[0].direction",
            "2 components",
        ),
        (
            format!("{head}{synth}[[velocity_field]]\ndirection = [1.0, 0.0]\nhidden = []\n"),
            "velocity_field[0].hidden",
            "hidden layer",
        ),
        (
            format!(
                "{head}{synth}[[velocity_field]]\ndirection = [1.0, 0.0]\nmaterial = \"sand\"\n"
            ),
            "velocity_field[0].material",
            "unknown material",
        ),
        (
            format!("{head}{synth}[[velocity_field]]\ndirection = [1.0, 0.0]\n"),
            "synthetic.scene",
            "truth scene",
        ),
        (
            format!(
                "{head}{synth}scene = \"{}\"\n[[velocity_field]]\ndirection = [1.0, 0.0]\n",
                example("mlp_column_truth.toml").display()
            ),
            "synthetic.scene",
            "240 particles",
        ),
        (
            format!(
                "{head}{synth}{param}[[observations.stations]]\nname = \"s\"\nat = [0.1, 0.2]\n"
            ),
            "observations.stations[0].at",
            "1 finite horizontal coordinate",
        ),
        (
            format!("{head}{param}[observations]\ndeposit = \"obs.csv\"\n"),
            "observations.stations",
            "needs deposit stations",
        ),
        (
            format!(
                "{head}{synth}{param}[[observations.monitors]]\nname = \"g\"\nlo = [0.1, 0.0]\n\
                 hi = [0.2, 0.1]\nedge = -0.01\n"
            ),
            "observations.monitors[0].edge",
            "expected a width ≥ 0",
        ),
    ];
    std::fs::write(dir.path().join("obs.csv"), "step,id,x,y\n10,3,0.1\n").unwrap();
    assert_refused(dir.path(), &cases);
}

/// Inversions that cannot mean what they say: a run of 10⁸ steps (memory grew without a
/// word), observations that do not fit the scene (millimetres for metres, a position of
/// 1e300 m, a particle given twice at one step, the initial state only, a header and no rows)
/// or observe nothing (`every` past the last step), and a friction coefficient of 1e308. Each
/// is refused by `gradient` and `check`, naming the field (and the file and line).
#[test]
fn implausible_inversions_exit_2_naming_the_field_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let scene = example("dambreak_small.toml");
    let head = format!("scene = \"{}\"\nsteps = 20\n", scene.display());
    let param = "[[parameters]]\nname = \"friction[1]\"\ninitial = 0.5\ntruth = 0.1\n";
    let synth = "[synthetic]\nparticles = 5\nevery = 10\n";
    let data = |name: &str, text: &str| {
        std::fs::write(dir.path().join(name), text).unwrap();
        format!("{head}{param}[observations]\ntracked = \"{name}\"\n")
    };
    let cases = [
        (
            format!(
                "{}{param}{synth}",
                head.replace("steps = 20", "steps = 100000000")
            ),
            "steps",
            "more than the 1e6 steps",
        ),
        (
            data("mm.csv", "step,id,x,y\n10,3,0.05,0.01\n20,3,56.25,12.5\n"),
            "observations.tracked",
            "mm.csv line 3: position 56.25, 12.5 m is outside the grid",
        ),
        (
            data("huge.csv", "step,id,x,y\n10,3,1e300,0.01\n"),
            "observations.tracked",
            "huge.csv line 2",
        ),
        (
            data("twice.csv", "step,id,x,y\n10,3,0.05,0.01\n10,3,0.06,0.01\n"),
            "observations.tracked",
            "twice.csv line 3: step 10, id `3` is given again (first on line 2)",
        ),
        (
            data("initial.csv", "step,id,x,y\n0,3,0.05,0.01\n0,4,0.06,0.01\n"),
            "observations.tracked",
            "initial.csv line 2: every row is at step 0",
        ),
        (
            data("header.csv", "step,id,x,y\n"),
            "observations.tracked",
            "header.csv line 1: a header and no rows",
        ),
        (
            format!("{head}{param}[synthetic]\nparticles = 5\nevery = 50\n"),
            "synthetic.every",
            "nothing would be observed",
        ),
        (
            format!(
                "{head}{synth}[[parameters]]\nname = \"friction[1]\"\ninitial = 1e308\ntruth = 0.1\n"
            ),
            "parameters[0].initial",
            "physical range of a Coulomb friction coefficient",
        ),
    ];
    assert_refused(dir.path(), &cases);
    // A monitor velocity of 1e200 m/s: the loss at the first guess is infinite.
    std::fs::write(
        dir.path().join("v.csv"),
        "step,monitor,vx,vy\n10,g,1e200,0\n",
    )
    .unwrap();
    let file = dir.path().join("inf.toml");
    std::fs::write(
        &file,
        format!(
            "{head}{param}[observations]\nvelocity = \"v.csv\"\n[[observations.monitors]]\n\
             name = \"g\"\nlo = [0.0, 0.0]\nhi = [0.5, 0.25]\n"
        ),
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let (file, out_dir) = (file.to_str().unwrap(), out_dir.to_str().unwrap());
    for args in [
        vec!["gradient", file],
        vec!["invert", file, "--out", out_dir],
    ] {
        let out = loam(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("inf.toml: the loss at the first guess is inf"),
            "{args:?}: {err}"
        );
    }
}

/// `--memory` chooses the adjoint's segments: a budget the whole run fits in gives the same
/// gradient, bit for bit, as the default; a budget below the least the run needs, a malformed
/// size and a budget beside the file's `segment` exit 2 with what is wrong.
#[test]
fn memory_budget_keeps_the_gradient_and_refuses_what_cannot_fit() {
    let dir = tempfile::tempdir().unwrap();
    let file = tiny(dir.path(), 1, 0.5);
    let values = |o: &Output| -> Vec<String> {
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .filter(|l| l.trim_start().starts_with("velocity"))
            .map(str::to_owned)
            .collect()
    };
    let plain = loam(&["gradient", &file]);
    let roomy = loam(&["gradient", &file, "--memory", "4GB"]);
    assert!(
        plain.status.success() && roomy.status.success(),
        "{}",
        text(&roomy)
    );
    assert!(!values(&plain).is_empty(), "{}", text(&plain));
    assert_eq!(values(&plain), values(&roomy));
    // The report says how: the whole run traced in one segment with the budget, shorter
    // segments (some steps run twice) and less memory kept without it.
    let how = |o: &Output| -> (usize, usize, usize) {
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        let steps = out.split(" over ").nth(1).and_then(|r| r.split(' ').next());
        let segment = out
            .split("segments of ")
            .nth(1)
            .and_then(|r| r.split(' ').next());
        let kept = out
            .split(" steps, ")
            .nth(1)
            .and_then(|r| r.split(' ').next());
        let number = |t: Option<&str>| t.and_then(|t| t.parse().ok()).expect(&out);
        (number(steps), number(segment), number(kept))
    };
    let ((steps, k_plain, mb_plain), (_, k_roomy, mb_roomy)) = (how(&plain), how(&roomy));
    assert_eq!(k_roomy, steps, "{}", text(&roomy));
    assert!(k_plain < steps && mb_plain < mb_roomy, "{}", text(&plain));
    let small = loam(&["gradient", &file, "--memory", "1kB"]);
    let err = String::from_utf8_lossy(&small.stderr);
    assert_eq!(small.status.code(), Some(2), "{err}");
    assert!(err.contains("too small") && err.contains(" MB"), "{err}");
    let bad = loam(&["gradient", &file, "--memory", "lots"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("expected a size"));
    let with_segment = dir.path().join("segment.toml");
    let body = std::fs::read_to_string(&file).unwrap();
    std::fs::write(&with_segment, format!("segment = 10\n{body}")).unwrap();
    let both = loam(&[
        "gradient",
        with_segment.to_str().unwrap(),
        "--memory",
        "1GB",
    ]);
    let err = String::from_utf8_lossy(&both.stderr);
    assert_eq!(both.status.code(), Some(2), "{err}");
    assert!(
        err.contains("segment: ") && err.contains("--memory"),
        "{err}"
    );
}

/// `--check` on a moving obstacle's velocity: the disk of the `obstacle-velocity-fd` case
/// pushed into water. The central differences converge (the `conv.` column names a step), and
/// the command passes only because the adjoint and the dual agree with them: it exits 1 when
/// both miss a converged difference (they once did here, by 1.7×, without the moving surface).
#[test]
fn gradient_check_holds_an_obstacle_velocity_to_a_converged_difference() {
    let dir = tempfile::tempdir().unwrap();
    let scene = repo("verification/scenes/obstacle_velocity.toml");
    let body = format!(
        "scene = \"{}\"\nsteps = 60\n\
         [[parameters]]\nname = \"obstacle[0].velocity[0]\"\ninitial = 0.25\ntruth = 0.2\n\
         [[parameters]]\nname = \"obstacle[0].velocity[1]\"\ninitial = -0.75\ntruth = -0.8\n\
         [synthetic]\nparticles = 20\nevery = 20\n",
        scene.display()
    );
    let file = dir.path().join("obstacle.toml");
    std::fs::write(&file, body).unwrap();
    let out = loam(&["gradient", file.to_str().unwrap(), "--check"]);
    let all = text(&out);
    assert!(out.status.success(), "{all}");
    // The rows of the check table: name, adjoint, dual, rel.diff, central diff., rel.diff,
    // conv., the remainders and their ratios.
    let rows: Vec<Vec<&str>> = all
        .lines()
        .map(|l| l.split_whitespace().collect::<Vec<_>>())
        .filter(|t| t.len() > 10 && t[0].starts_with("obstacle[0].velocity["))
        .collect();
    assert_eq!(rows.len(), 2, "{all}");
    for t in rows {
        assert_ne!(
            t[6], "no",
            "{}: the differences did not converge\n{all}",
            t[0]
        );
        let rel: f64 = t[5].parse().unwrap();
        assert!(rel <= 1e-5, "{}: {rel}\n{all}", t[0]);
    }
}
