//! The verification cases at reduced size: each must meet its tolerance.

use loam_verification::{Size, case};

fn check(name: &str) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let report =
        (case(name).expect("case exists").run)(Size::Reduced, dir.path()).expect("case runs");
    for m in &report.metrics {
        match m.tolerance {
            Some(t) => println!(
                "{} {} = {:.4e} (tolerance {t:.1e})",
                m.case, m.metric, m.value
            ),
            None => println!("{} {} = {:.4e} (information)", m.case, m.metric, m.value),
        }
    }
    for f in &report.files {
        assert!(f.exists(), "{} was not written", f.display());
    }
    for m in &report.metrics {
        assert!(
            m.passed,
            "{}: {} = {} outside its tolerance {:?}",
            m.case, m.metric, m.value, m.tolerance
        );
    }
}

#[test]
fn axial_bar() {
    check("axial-bar");
}

#[test]
fn disk_collision() {
    check("disk-collision");
}

#[test]
fn tangent_fd() {
    check("tangent-fd");
}

#[test]
fn newton_quadratic() {
    check("newton-quadratic");
}

#[test]
fn cantilever() {
    check("cantilever");
}

#[test]
fn column_compaction() {
    check("column-compaction");
}

#[test]
fn footing_prandtl() {
    check("footing-prandtl");
}

#[test]
fn axial_bar_newmark() {
    check("axial-bar-newmark");
}

#[test]
fn newmark_energy() {
    check("newmark-energy");
}

#[test]
fn dambreak_2d() {
    check("dambreak-2d");
}

#[test]
fn incline_friction() {
    check("incline-friction");
}

#[test]
fn dambreak_obstacles_3d() {
    check("dambreak-obstacles-3d");
}

#[test]
fn bui_collapse() {
    check("bui-collapse");
}

#[test]
fn column_runout() {
    check("column-runout");
}

#[test]
fn adjoint_fd() {
    check("adjoint-fd");
}

#[test]
fn implicit_adjoint_fd() {
    check("implicit-adjoint-fd");
}

#[test]
fn inverse_cantilever() {
    check("inverse-cantilever");
}

#[test]
fn inverse_footing() {
    check("inverse-footing");
}

#[test]
fn inverse_v0() {
    check("inverse-v0");
}

#[test]
fn inverse_friction() {
    check("inverse-friction");
}

#[test]
fn inverse_mlp() {
    check("inverse-mlp");
}
