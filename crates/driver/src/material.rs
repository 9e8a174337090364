//! `loam material FILE`: an element test (one material point through laboratory paths) with
//! the solver's own constitutive kernels; writes `element.csv` and plots in soil mechanics'
//! conventions (compression positive, kPa).

use crate::Outcome;
use loam_implicit::element::{self, PointState};
use loam_scene::element::ElementTest;
use loam_verification::{Series, write_csv, write_plot};
use std::path::{Path, PathBuf};

/// Runs the element test in `path`, writing into `out` (default: the file's `output_dir`, or
/// `out/<file stem>`).
pub fn material(path: &Path, out: Option<&Path>, quiet: bool) -> Outcome {
    let test = match ElementTest::from_path(path) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::BadInput;
        }
    };
    let dir = out.map(Path::to_path_buf).unwrap_or_else(|| {
        test.output_dir
            .clone()
            .unwrap_or_else(|| PathBuf::from("out").join(path.file_stem().unwrap_or_default()))
    });
    if let Err(e) = std::fs::create_dir_all(&dir) {
        eprintln!("error: output folder {}: {e}", dir.display());
        return Outcome::BadInput;
    }
    let material = test.material();
    let path_run = element::run_test(&material, &material, test.start(&material), &test.stages());
    let (states, stage_of) = (path_run.states, path_run.stage_of);
    let failure = (path_run.failure).map(|e| {
        format!(
            "stages[{}] ({}): {e}",
            e.stage(),
            test.stages[e.stage()].name()
        )
    });
    if let Err(msg) = write(&dir, &test, &states, &stage_of) {
        eprintln!("error: {msg}");
        return Outcome::Failed;
    }
    let end = states.last().expect("start").measures();
    if !quiet {
        let peak = states
            .iter()
            .map(|s| s.measures().q)
            .fold(f64::NEG_INFINITY, f64::max);
        println!(
            "{}: {} increments; at the end p′ = {:.4} kPa, q = {:.4} kPa, ε_a = {:.5}, ε_v = {:.5} \
             (compression positive); peak q = {:.4} kPa",
            path.display(),
            states.len() - 1,
            end.p / 1e3,
            end.q / 1e3,
            end.axial_strain,
            end.volumetric_strain,
            peak / 1e3,
        );
        println!("  wrote {}", dir.join("element.csv").display());
    }
    match failure {
        Some(msg) => {
            eprintln!(
                "error: {}: {msg} (the states up to it are written)",
                path.display()
            );
            Outcome::Failed
        }
        None => Outcome::Ok,
    }
}

/// `element.csv` and the plots q–ε_a, q–p′, ε_v–ε_a and (with an initial void ratio) e–log p′.
fn write(
    dir: &Path,
    test: &ElementTest,
    states: &[PointState],
    stage_of: &[usize],
) -> Result<(), String> {
    let e0 = test.void_ratio();
    let rows: Vec<Vec<f64>> = states
        .iter()
        .zip(stage_of)
        .enumerate()
        .map(|(i, (s, &k))| {
            let m = s.measures();
            let j = 1.0 - m.volumetric_strain;
            vec![
                i as f64,
                k as f64,
                m.axial_strain,
                m.volumetric_strain,
                s.f[(0, 2)],
                m.p / 1e3,
                m.q / 1e3,
                -s.stress[(2, 2)] / 1e3,
                -0.5 * (s.stress[(0, 0)] + s.stress[(1, 1)]) / 1e3,
                -s.stress[(0, 2)] / 1e3,
                s.history.plastic_strain,
                e0.map_or(f64::NAN, |e0| (1.0 + e0) * j - 1.0),
            ]
        })
        .collect();
    write_csv(
        &dir.join("element.csv"),
        &[
            "increment",
            "stage",
            "axial_strain",
            "volumetric_strain",
            "shear_strain",
            "p_kPa",
            "q_kPa",
            "sigma_axial_kPa",
            "sigma_radial_kPa",
            "tau_xz_kPa",
            "plastic_strain",
            "void_ratio",
        ],
        &rows,
    )
    .map_err(|e| e.to_string())?;
    let name = &test.material.name;
    let column =
        |x: usize, y: usize| -> Vec<(f64, f64)> { rows.iter().map(|r| (r[x], r[y])).collect() };
    let plots: [(&str, &str, &str, usize, usize); 3] = [
        (
            "q_axial_strain.png",
            "axial strain ε_a (compression +)",
            "q = σ′_a − σ′_r (kPa)",
            2,
            6,
        ),
        ("q_p.png", "p′ (kPa, compression +)", "q (kPa)", 5, 6),
        (
            "volumetric_axial_strain.png",
            "axial strain ε_a",
            "volumetric strain ε_v (compression +)",
            2,
            3,
        ),
    ];
    for (file, x, y, cx, cy) in plots {
        write_plot(
            &dir.join(file),
            &format!("{name}: element test"),
            x,
            y,
            &[Series {
                name: test.material.model.name().into(),
                points: column(cx, cy),
                markers: false,
            }],
        )
        .map_err(|e| e.to_string())?;
    }
    if e0.is_some() {
        let points: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r[5] > 0.0)
            .map(|r| (r[5].log10(), r[11]))
            .collect();
        write_plot(
            &dir.join("e_log_p.png"),
            &format!("{name}: compression curve"),
            "log₁₀ p′ (p′ in kPa)",
            "void ratio e",
            &[Series {
                name: test.material.model.name().into(),
                points,
                markers: false,
            }],
        )
        .map_err(|e| e.to_string())?;
    }
    Ok(())
}
