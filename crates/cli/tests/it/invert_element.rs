//! End-to-end tests of `loam gradient`, `loam invert` and `loam check` on inversion files of
//! element tests (`[[tests]]`: material constants fitted to laboratory curves).

use crate::common::{assert_refused, loam, repo, text};
use std::path::Path;

/// A drained triaxial test of the example's clay (Modified Cam-Clay λ = 0.2, κ = 0.04,
/// M = 1) in 20 increments, as `drained.toml` in `dir`.
fn drained(dir: &Path) {
    let text = std::fs::read_to_string(repo("examples/element/triaxial_mcc_drained.toml"))
        .unwrap()
        .replace("increments = 100", "increments = 20");
    std::fs::write(dir.join("drained.toml"), text).unwrap();
}

/// A drained triaxial test of Mohr–Coulomb sand (φ = 30°, c = 10 kPa), as `sand.toml`.
fn sand(dir: &Path) {
    let text = r#"[material]
name = "sand"
model = "mohr_coulomb"
density = 1900.0
youngs_modulus = 20.0e6
poisson_ratio = 0.3
friction_angle = 30.0
cohesion = 10.0e3

[initial]
p = 100.0e3

[[stages]]
type = "drained_triaxial"
axial_strain = 0.05
increments = 20
"#;
    std::fs::write(dir.join("sand.toml"), text).unwrap();
}

/// `loam check` and `loam gradient --check` on the example: the forward-mode gradient agrees
/// with the loss evaluated in `Dual64` to 1e-8 and with a converged central difference to
/// 1e-5 (the command exits 1 otherwise); the report has the identifiability table.
#[test]
fn gradient_check_on_the_example_agrees_with_central_differences() {
    let file = repo("examples/inverse/triaxial_mcc.toml");
    let out = loam(&["check", file.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out)
            .contains("valid inversion of 2 element test(s): 3 parameter(s), 80 observation(s)"),
        "{}",
        text(&out)
    );
    let out = loam(&["gradient", file.to_str().unwrap(), "--check"]);
    let all = text(&out);
    assert!(out.status.success(), "{all}");
    for p in [
        "over 80 observations of 2 element test(s)",
        "material.lambda",
        "material.kappa",
        "material.critical_state_slope",
        "condition number",
        "central diff.",
    ] {
        assert!(all.contains(p), "{p} missing in {all}");
    }
}

/// The value of `name` recovered, from the report line `  name: value (truth …`.
fn recovered(report: &str, name: &str) -> f64 {
    let line = (report.lines())
        .find(|l| l.trim_start().starts_with(&format!("{name}: ")))
        .unwrap_or_else(|| panic!("no line for {name} in {report}"));
    line.split_whitespace().nth(1).unwrap().parse().unwrap()
}

/// The example recovers λ, κ and M within 1 % (the issue's goal; with synthetic data the
/// minimum is the truth, reached to far better) and writes the history, the synthetic
/// observations, the recovered element files and the fitted curves. The observations it
/// wrote, read back as measured data, are fitted as well from the same first guesses.
#[test]
fn the_example_recovers_lambda_kappa_and_m_and_its_data_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let file = repo("examples/inverse/triaxial_mcc.toml");
    let out = loam(&[
        "invert",
        file.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let report = text(&out);
    assert!(out.status.success(), "{report}");
    for (name, truth) in [
        ("material.lambda", 0.2),
        ("material.kappa", 0.04),
        ("material.critical_state_slope", 1.0),
    ] {
        let v = recovered(&report, name);
        assert!((v / truth - 1.0).abs() < 1e-2, "{name} = {v}: {report}");
    }
    for f in [
        "history.csv",
        "history_parameters.png",
        "observed_triaxial_mcc_drained.csv",
        "observed_triaxial_mcc.csv",
        "recovered_triaxial_mcc_drained.toml",
        "fit_triaxial_mcc_drained.csv",
        "fit_triaxial_mcc_drained_q.png",
        "fit_triaxial_mcc_drained_volumetric_strain.png",
        "fit_triaxial_mcc_p.png",
    ] {
        assert!(out_dir.join(f).exists(), "{f} missing: {report}");
    }
    // The recovered element file runs with `loam material`.
    let rec = out_dir.join("recovered_triaxial_mcc.toml");
    let run = loam(&[
        "material",
        rec.to_str().unwrap(),
        "--out",
        dir.path().join("rec").to_str().unwrap(),
        "--quiet",
    ]);
    assert!(run.status.success(), "{}", text(&run));
    // The synthetic observations as measured data.
    let examples = repo("examples/element");
    let body = std::fs::read_to_string(&file)
        .unwrap()
        .replace(
            "element = \"../element/triaxial_mcc_drained.toml\"",
            &format!(
                "element = \"{}\"\ndata = \"{}\"",
                examples.join("triaxial_mcc_drained.toml").display(),
                out_dir.join("observed_triaxial_mcc_drained.csv").display()
            ),
        )
        .replace(
            "element = \"../element/triaxial_mcc.toml\"",
            &format!(
                "element = \"{}\"\ndata = \"{}\"",
                examples.join("triaxial_mcc.toml").display(),
                out_dir.join("observed_triaxial_mcc.csv").display()
            ),
        )
        .replace("[synthetic]\nevery = 5", "");
    let measured = dir.path().join("measured.toml");
    std::fs::write(&measured, body).unwrap();
    let out = loam(&[
        "invert",
        measured.to_str().unwrap(),
        "--out",
        dir.path().join("measured").to_str().unwrap(),
    ]);
    let report = text(&out);
    assert!(out.status.success(), "{report}");
    for (name, truth) in [
        ("material.lambda", 0.2),
        ("material.kappa", 0.04),
        ("material.critical_state_slope", 1.0),
    ] {
        let v = recovered(&report, name);
        assert!((v / truth - 1.0).abs() < 1e-2, "{name} = {v}: {report}");
    }
}

/// The measured-data example (the truth curves with noise of 0.5 kPa on q and p′ and 1e-4 on
/// ε_v, rounded as a laboratory writes them, the last point at the test's final strain):
/// λ, κ and M within 1 % of the values the data were made with (the issue's goal). The
/// Gauss–Newton table puts one standard deviation of the noise's effect at 0.42 % for κ and
/// below 0.09 % for λ and M, so 1 % is 2.4 of them for κ (these data give 0.27 %) and more
/// than ten for the others; the data are fixed, so the outcome is too.
#[test]
fn the_measured_example_recovers_lambda_kappa_and_m_within_its_noise() {
    let dir = tempfile::tempdir().unwrap();
    let file = repo("examples/inverse/triaxial_mcc_measured.toml");
    let out = loam(&[
        "invert",
        file.to_str().unwrap(),
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    let report = text(&out);
    assert!(out.status.success(), "{report}");
    for (name, truth) in [
        ("material.lambda", 0.2),
        ("material.kappa", 0.04),
        ("material.critical_state_slope", 1.0),
    ] {
        let v = recovered(&report, name);
        assert!((v / truth - 1.0).abs() < 1e-2, "{name} = {v}: {report}");
    }
}

/// Bad input is refused before anything runs, exit 2, naming the field (and for a data file
/// its line).
#[test]
fn bad_element_inversions_are_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    drained(d);
    sand(d);
    let csv = |name: &str, body: &str| {
        std::fs::write(d.join(name), body).unwrap();
        d.join(name).display().to_string()
    };
    let good = csv(
        "good.csv",
        "# q in kPa\naxial_strain,q\n0.01,40\n0.05,90\n0.10,120\n",
    );
    let no_q = csv("no_q.csv", "axial_strain,p\n0.01,200\n");
    let back = csv("back.csv", "axial_strain,q\n0.01,40\n0.05,90\n0.04,95\n");
    let far = csv("far.csv", "axial_strain,q\n0.01,40\n0.5,90\n");
    let pascal = csv("pascal.csv", "axial_strain,q\n0.01,4.0e7\n");
    let test = |element: &str, data: &str, sigma: &str| {
        format!(
            "[[tests]]\nelement = \"{}\"\ndata = \"{data}\"\nsigma = {sigma}\n",
            d.join(element).display()
        )
    };
    let param = |name: &str, initial: f64| {
        format!("\n[[parameters]]\nname = \"{name}\"\ninitial = {initial}\n")
    };
    let clay = |data: &str| test("drained.toml", data, "{ q = 1.0 }");
    let lambda = param("material.lambda", 0.25);
    let cases: Vec<(String, &str, &str)> = vec![
        (
            clay(&good) + &lambda + "\n[stop]\nmax_iteration = 3\n",
            "stop.max_iteration",
            "unknown field",
        ),
        (clay(&no_q) + &lambda, "tests[0].data", "no column `q`"),
        (clay(&back) + &lambda, "tests[0].data", "line 4"),
        (
            clay(&far) + &lambda,
            "tests[0].data",
            "outside the test's path",
        ),
        (clay(&pascal) + &lambda, "tests[0].data", "kPa"),
        (
            clay(&good) + &param("material.friction_angle", 0.5),
            "parameters[0].name",
            "no constant `friction_angle`",
        ),
        (
            clay(&good) + &param("materials[0].lambda", 0.25),
            "parameters[0].name",
            "write `material.lambda`",
        ),
        (
            test("drained.toml", &good, "{}") + &lambda,
            "tests[0].sigma",
            "at least one quantity",
        ),
        (
            test("sand.toml", &good, "{ q = 1.0, void_ratio = 0.01 }")
                + &param("material.cohesion", 8e3),
            "tests[0].sigma.void_ratio",
            "no initial void ratio",
        ),
        (
            clay(&good) + &lambda + "\n[synthetic]\nevery = 2\n",
            "tests[0].data",
            "not with [synthetic]",
        ),
        (
            test("missing.toml", &good, "{ q = 1.0 }") + &lambda,
            "tests[0].element",
            "cannot read",
        ),
    ];
    assert_refused(d, &cases);
}
