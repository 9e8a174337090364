//! End-to-end tests of `loam gradient`, `loam invert` and `loam check` on inversion files
//! whose scene is implicit (quasi-static load steps, and Newmark time steps).

use crate::common::{assert_refused, loam, repo, text};
use std::path::Path;

/// The verification cantilever (64 particles) over 3 load steps: E and the tip load from
/// the displacement of the loaded particle.
fn cantilever(dir: &Path) -> String {
    let body = format!(
        r#"scene = "{}"
steps = 3

[[parameters]]
name = "materials[0].young"
initial = 1.2e6
truth = 1.0e6

[[parameters]]
name = "point_loads[0].force[1]"
initial = -900.0
truth = -1000.0

[synthetic]
ids = [31]
"#,
        repo("verification/scenes/implicit_cantilever.toml").display()
    );
    let path = dir.join("cantilever.toml");
    std::fs::write(&path, body).expect("write");
    path.to_str().expect("utf-8").to_owned()
}

/// The loss `L` that `loam gradient` printed (its digits, as printed).
fn printed_loss(s: &str) -> String {
    s.lines()
        .find(|l| l.contains("L = "))
        .and_then(|l| l.split("L = ").nth(1))
        .map(|l| l.split(' ').next().unwrap_or("").to_owned())
        .unwrap_or_default()
}

/// The row of `loam gradient`'s table for parameter `name` (its value and `dL/dθ`).
fn gradient_row(s: &str, name: &str) -> String {
    s.lines()
        .find(|l| l.trim_start().starts_with(name))
        .map(str::to_owned)
        .unwrap_or_default()
}

/// `--check` fails unless the adjoint and the forward-mode dual derivative agree to 1e-8;
/// the report also carries the central differences, the "last load step only" gradient and
/// the Gauss–Newton table.
#[test]
fn gradient_check_on_an_implicit_scene_agrees_with_the_dual_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = loam(&["gradient", &cantilever(dir.path()), "--check"]);
    let all = text(&out);
    assert!(out.status.success(), "{all}");
    for p in [
        "over 3 load steps",
        "materials[0].young",
        "point_loads[0].force[1]",
        "central diff.",
        "last load step only",
        "condition number",
    ] {
        assert!(all.contains(p), "{p} missing in {all}");
    }
}

/// `--check` on the Newmark example (E and ρ of the cantilever from its tip's motion under a
/// sudden load): the adjoint through the mass matrix and the particle velocities agrees with
/// the forward-mode dual derivative to 1e-8 (the command fails otherwise).
#[test]
fn gradient_check_on_a_newmark_scene_agrees_with_the_dual_run() {
    let file = repo("examples/inverse/cantilever_newmark.toml");
    let out = loam(&["gradient", file.to_str().unwrap(), "--check"]);
    let all = text(&out);
    assert!(out.status.success(), "{all}");
    for p in [
        "over 5 time steps of 0.04 s",
        "materials[0].young",
        "materials[0].density",
        "central diff.",
    ] {
        assert!(all.contains(p), "{p} missing in {all}");
    }
}

/// The footing's reactions written by a synthetic run and read back from the CSV file
/// reproduce the synthetic loss: zero at the truth (the values round-trip exactly), and the
/// same loss and gradient as the synthetic file away from it.
#[test]
fn reaction_observations_round_trip_through_their_csv_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene = repo("examples/inverse/footing_clay.toml");
    let head = format!(
        "scene = \"{}\"\nsteps = 3\n[[parameters]]\nname = \"materials[0].yield_stress\"\ninitial = 2.5e4\ntruth = 3.0e4\n",
        scene.display()
    );
    let reactions = "[observations]\nreaction_sigma = 10.0\n[[observations.reactions]]\nname = \"footing\"\nconstraint = 0\naxis = 1\n";
    let synthetic = dir.path().join("synthetic.toml");
    std::fs::write(
        &synthetic,
        format!("{head}{reactions}[synthetic]\n[stop]\nmax_iterations = 0\n"),
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let out = loam(&[
        "invert",
        synthetic.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out));
    let csv = std::fs::read_to_string(out_dir.join("reaction.csv")).unwrap();
    assert!(csv.starts_with("step,reaction,force\n1,footing,"), "{csv}");
    assert_eq!(csv.lines().count(), 4, "{csv}");
    let from_csv = dir.path().join("csv.toml");
    let observed = reactions.replacen(
        "reaction_sigma = 10.0\n",
        &format!(
            "reaction_sigma = 10.0\nreaction = \"{}\"\n",
            out_dir.join("reaction.csv").display()
        ),
        1,
    );
    std::fs::write(&from_csv, format!("{head}{observed}")).unwrap();
    let a = text(&loam(&["gradient", synthetic.to_str().unwrap()]));
    let b = text(&loam(&["gradient", from_csv.to_str().unwrap()]));
    assert_eq!(printed_loss(&a), printed_loss(&b), "{a}\n{b}");
    let grad = "materials[0].yield_stress";
    assert_eq!(gradient_row(&a, grad), gradient_row(&b, grad), "{a}\n{b}");
    std::fs::write(
        &from_csv,
        std::fs::read_to_string(&from_csv)
            .unwrap()
            .replace("initial = 2.5e4", "initial = 3.0e4"),
    )
    .unwrap();
    let at_truth = text(&loam(&["gradient", from_csv.to_str().unwrap()]));
    assert_eq!(printed_loss(&at_truth), "0.0000000000e0", "{at_truth}");
}

/// Fields, parameter names and observation kinds of the other solver's path, and
/// observations that do not fit the scene, exit 2 naming the field and what is accepted.
#[test]
fn malformed_implicit_inversion_files_exit_2_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let beam = repo("verification/scenes/implicit_cantilever.toml");
    let footing = repo("examples/inverse/footing_clay.toml");
    let dam = repo("examples/inverse/dambreak_small.toml");
    let layer = repo("examples/inverse/consolidation_layer.toml");
    let on = |scene: &Path| format!("scene = \"{}\"\n", scene.display());
    let young = "[[parameters]]\nname = \"materials[0].young\"\ninitial = 1.2e6\ntruth = 1.0e6\n";
    let synth = "[synthetic]\nids = [31]\n";
    let reaction = |axis: usize| {
        format!("[[observations.reactions]]\nname = \"r\"\nconstraint = 0\naxis = {axis}\n")
    };
    let cases = [
        (
            format!(
                "{}{synth}[[parameters]]\nname = \"friction[0]\"\ninitial = 0.5\ntruth = 0.1\n",
                on(&beam)
            ),
            "parameters[0].name",
            "applies to explicit scenes",
        ),
        (
            format!(
                "{}{synth}[[parameters]]\nname = \"point_loads[2].force[1]\"\ninitial = 1.0\ntruth = 1.0\n",
                on(&beam)
            ),
            "parameters[0].name",
            "no such point load",
        ),
        (
            format!(
                "{}{synth}[[parameters]]\nname = \"constraints[0].force[0]\"\ninitial = 1.0\ntruth = 1.0\n",
                on(&repo("verification/scenes/implicit_mandel.toml"))
            ),
            "parameters[0].name",
            "not force-controlled",
        ),
        (
            format!("{}{young}[synthetic]\nids = [64]\n", on(&beam)),
            "synthetic.ids[0]",
            "64 particles",
        ),
        (
            format!(
                "{}{young}{synth}[observations]\ntracked = \"obs.csv\"\n",
                on(&beam)
            ),
            "observations.tracked",
            "applies to explicit scenes",
        ),
        (
            format!(
                "{}{young}{synth}[optimizer]\nmethod = \"levenberg_marquardt\"\n",
                on(&beam)
            ),
            "optimizer.method",
            "applies to explicit scenes",
        ),
        (
            format!("{}end_time = 1.0\n{young}{synth}", on(&beam)),
            "end_time",
            "applies to explicit scenes",
        ),
        (
            format!("{}{young}[synthetic]\n{}", on(&footing), reaction(0)),
            "observations.reactions[0].axis",
            "free",
        ),
        (
            format!(
                "{}{young}[synthetic]\n{}",
                on(&footing),
                reaction(1).replace("constraint = 0", "constraint = 3")
            ),
            "observations.reactions[0].constraint",
            "does not exist",
        ),
        (
            format!("{}{young}", on(&footing)),
            "observations",
            "expected `displacement`, `reaction` or `pore_pressure`",
        ),
        (
            format!(
                "{}{young}[observations]\nreaction = \"obs.csv\"\n{}",
                on(&footing),
                reaction(1)
            ),
            "observations.reaction",
            "step 0",
        ),
        (
            format!(
                "{}steps = 20\n[synthetic]\nparticles = 5\nevery = 10\n[[parameters]]\nname = \"point_loads[0].force[1]\"\ninitial = 1.0\ntruth = 1.0\n",
                on(&dam)
            ),
            "parameters[0].name",
            "applies to implicit scenes",
        ),
        (
            format!(
                "{}steps = 20\n[synthetic]\nparticles = 5\nevery = 10\n[[parameters]]\nname = \"friction[1]\"\ninitial = 0.5\ntruth = 0.1\n{}",
                on(&dam),
                reaction(1)
            ),
            "observations.reactions",
            "applies to implicit scenes",
        ),
        // A run of 10⁸ load steps (each kept for the adjoint), a first observed step past
        // the last, and a displacement of a kilometre (in millimetres?) on a 2 m beam.
        (
            format!("{}steps = 100000000\n{young}{synth}", on(&beam)),
            "steps",
            "more than the 1e6 steps",
        ),
        (
            format!(
                "{}steps = 10\n{young}[synthetic]\nids = [31]\nevery = 20\n",
                on(&beam)
            ),
            "synthetic.every",
            "nothing would be observed",
        ),
        (
            format!(
                "{}{young}[observations]\ndisplacement = \"u.csv\"\n",
                on(&beam)
            ),
            "observations.displacement",
            "u.csv line 3: displacement",
        ),
        // Pore-pressure observations and parameters on a scene without a pore fluid, and a
        // coupled scene's malformed piezometers and steps.
        (
            format!(
                "{}{young}{synth}[[observations.piezometers]]\nname = \"p\"\nat = [1.0, 1.0]\n",
                on(&beam)
            ),
            "observations.piezometers",
            "has no [pore_fluid]",
        ),
        (
            format!(
                "{}{synth}[[parameters]]\nname = \"materials[0].hydraulic_conductivity\"\ninitial = 1e-8\ntruth = 1e-8\n",
                on(&beam)
            ),
            "parameters[0].name",
            "has no [pore_fluid]",
        ),
        (
            format!("{}steps = 3\n{young}{synth}", on(&layer)),
            "steps",
            "[solver.consolidation] schedule",
        ),
        (
            format!(
                "{}{young}[observations]\npore_pressure = \"p.csv\"\n",
                on(&layer)
            ),
            "observations.piezometers",
            "needs [[observations.piezometers]]",
        ),
        (
            format!(
                "{}{young}{synth}[[observations.piezometers]]\nname = \"p\"\nat = [0.0]\n",
                on(&layer)
            ),
            "observations.piezometers[0].at",
            "expected 2 finite coordinates",
        ),
    ];
    std::fs::write(
        dir.path().join("obs.csv"),
        "step,reaction,force\n0,r,-1.0\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("u.csv"),
        "step,id,ux,uy\n1,31,0.0,-0.01\n2,31,0.0,-1000.0\n",
    )
    .unwrap();
    assert_refused(dir.path(), &cases);
}

/// A coupled (u–p) scene: the piezometers' pore pressures of a synthetic run, written as
/// `pore_pressure.csv` and read back, give the synthetic loss and gradient (zero loss at the
/// truth), and `--check` confirms the adjoint through the consolidation steps against the
/// forward-mode dual run (the command fails otherwise).
#[test]
fn pore_pressure_observations_round_trip_and_their_gradient_checks() {
    let dir = tempfile::tempdir().unwrap();
    let scene = repo("examples/inverse/consolidation_layer.toml");
    let head = format!(
        "scene = \"{}\"\n[[parameters]]\nname = \"materials[0].hydraulic_conductivity\"\ninitial = 2e-8\ntruth = 1e-8\n",
        scene.display()
    );
    let piezometers = "[observations]\npore_pressure_sigma = 100.0\n[[observations.piezometers]]\nname = \"upper\"\nat = [0.0, 1.5]\n[[observations.piezometers]]\nname = \"lower\"\nat = [0.0, 0.75]\n";
    let synthetic = dir.path().join("synthetic.toml");
    let synthetic_text = format!("{head}{piezometers}[synthetic]\n[stop]\nmax_iterations = 0\n");
    std::fs::write(&synthetic, &synthetic_text).unwrap();
    let out_dir = dir.path().join("out");
    let out = loam(&[
        "invert",
        synthetic.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out));
    let csv = std::fs::read_to_string(out_dir.join("pore_pressure.csv")).unwrap();
    assert!(
        csv.starts_with("step,piezometer,pore_pressure\n1,upper,"),
        "{csv}"
    );
    // Two piezometers after each of the 26 steps.
    assert_eq!(csv.lines().count(), 1 + 2 * 26, "{csv}");
    let from_csv = dir.path().join("csv.toml");
    let observed = piezometers.replacen(
        "pore_pressure_sigma = 100.0\n",
        &format!(
            "pore_pressure_sigma = 100.0\npore_pressure = \"{}\"\n",
            out_dir.join("pore_pressure.csv").display()
        ),
        1,
    );
    std::fs::write(&from_csv, format!("{head}{observed}")).unwrap();
    let a = text(&loam(&["gradient", synthetic.to_str().unwrap()]));
    let b = text(&loam(&["gradient", from_csv.to_str().unwrap()]));
    assert_eq!(printed_loss(&a), printed_loss(&b), "{a}\n{b}");
    let grad = "materials[0].hydraulic_conductivity";
    assert_eq!(gradient_row(&a, grad), gradient_row(&b, grad), "{a}\n{b}");
    std::fs::write(
        &from_csv,
        std::fs::read_to_string(&from_csv)
            .unwrap()
            .replace("initial = 2e-8", "initial = 1e-8"),
    )
    .unwrap();
    let at_truth = text(&loam(&["gradient", from_csv.to_str().unwrap()]));
    assert_eq!(printed_loss(&at_truth), "0.0000000000e0", "{at_truth}");
    let out = loam(&["gradient", synthetic.to_str().unwrap(), "--check"]);
    assert!(out.status.success(), "{}", text(&out));
}

/// The same layer with its fluid balance integrated by BDF2 (`scheme = "bdf2"`): `--check`
/// confirms the adjoint through steps that carry the previous step's fluid-content change
/// against the forward-mode dual run, and the gradient is not backward Euler's (the scheme
/// reaches both the run and its adjoint).
#[test]
fn a_bdf2_consolidation_gradient_checks() {
    let dir = tempfile::tempdir().unwrap();
    let layer = repo("examples/inverse/consolidation_layer.toml");
    let layer_text = std::fs::read_to_string(&layer).unwrap();
    assert!(layer_text.contains("growth = 1.3\n"));
    let layer_bdf2 = dir.path().join("layer_bdf2.toml");
    std::fs::write(
        &layer_bdf2,
        layer_text.replace("growth = 1.3\n", "growth = 1.3\nscheme = \"bdf2\"\n"),
    )
    .unwrap();
    let file = |scene: &Path, name: &str| {
        let path = dir.path().join(name);
        std::fs::write(
            &path,
            format!(
                "scene = \"{}\"\n[[parameters]]\nname = \"materials[0].hydraulic_conductivity\"\ninitial = 2e-8\ntruth = 1e-8\n[observations]\npore_pressure_sigma = 100.0\n[[observations.piezometers]]\nname = \"upper\"\nat = [0.0, 1.5]\n[synthetic]\n",
                scene.display()
            ),
        )
        .unwrap();
        path
    };
    let bdf2 = file(&layer_bdf2, "bdf2.toml");
    let out = loam(&["gradient", bdf2.to_str().unwrap(), "--check"]);
    assert!(out.status.success(), "{}", text(&out));
    let euler = text(&loam(&[
        "gradient",
        file(&layer, "euler.toml").to_str().unwrap(),
    ]));
    let grad = "materials[0].hydraulic_conductivity";
    assert_ne!(
        gradient_row(&text(&out), grad),
        gradient_row(&euler, grad),
        "{euler}"
    );
}

/// `examples/inverse/mandel_plate.toml`: Mandel's specimen under a force-controlled plate
/// (its nodes share one vertical unknown, which carries the force), E and the conductivity
/// from the plate's settlement and the centre's pore pressure, here with the plate's force
/// `constraints[0].force[1]` as a third parameter. `--check` confirms the adjoint through
/// the shared unknown, and by the force on it, against the forward-mode dual run (the
/// command fails otherwise).
#[test]
fn a_force_controlled_plate_gradient_checks() {
    let dir = tempfile::tempdir().unwrap();
    let example = repo("examples/inverse/mandel_plate.toml");
    let scene = repo("verification/scenes/implicit_mandel.toml");
    let text_in = std::fs::read_to_string(&example).unwrap().replace(
        "scene = \"../../verification/scenes/implicit_mandel.toml\"",
        &format!("scene = \"{}\"", scene.display()),
    );
    let file = dir.path().join("mandel_force.toml");
    std::fs::write(
        &file,
        format!(
            "{text_in}\n[[parameters]]\nname = \"constraints[0].force[1]\"\ninitial = -1.2e4\ntruth = -1.0e4\nscale = 1.0e4\n"
        ),
    )
    .unwrap();
    let out = loam(&["gradient", file.to_str().unwrap(), "--check"]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains("constraints[0].force[1]"),
        "{}",
        text(&out)
    );
}

/// An implicit inversion stopped after 2 iterations and resumed to 5 ends where a run of 5
/// iterations ends, bit for bit (the optimiser's state is checkpointed).
#[test]
fn resume_continues_an_implicit_inversion_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let file = cantilever(dir.path());
    let with_stop = |n: usize| {
        let text = std::fs::read_to_string(&file).unwrap();
        let text = match text.split_once("[stop]") {
            Some((head, _)) => head.to_owned(),
            None => text,
        };
        std::fs::write(&file, format!("{text}[stop]\nmax_iterations = {n}\n")).unwrap();
    };
    let run = |out: &Path, resume: bool| {
        let mut args = vec!["invert", file.as_str(), "--out", out.to_str().unwrap()];
        if resume {
            args.push("--resume");
        }
        let o = loam(&args);
        assert!(o.status.success(), "{}", text(&o));
    };
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    with_stop(5);
    run(&a, false);
    with_stop(2);
    run(&b, false);
    with_stop(5);
    run(&b, true);
    let history = |d: &Path| -> serde_json::Value {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("history.json")).unwrap())
                .unwrap();
        (v["entries"].as_array().unwrap().iter())
            .map(|e| serde_json::json!([e["loss"], e["parameters"]]))
            .collect()
    };
    assert_eq!(history(&a), history(&b));
    let scene = std::fs::read_to_string(a.join("recovered_implicit_cantilever.toml")).unwrap();
    assert!(scene.contains("load_steps = 3"), "{scene}");
}
