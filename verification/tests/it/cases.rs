//! The verification cases at reduced size: each must meet its tolerance, on the CPU, and the
//! cases whose explicit runs can step on the GPU also there (in f32, against the same
//! references and tolerances).
//!
//! Under `CI=true` a missing GPU adapter fails the GPU tests; elsewhere they say they are
//! skipped and pass (install `mesa-vulkan-drivers` for a software adapter).

use loam_gpu::Gpu;
use loam_verification::{Device, Size, case};
use std::sync::OnceLock;

fn check(name: &str) {
    check_on(name, &Device::Cpu);
}

fn check_on(name: &str, device: &Device) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let report = case(name)
        .expect("case exists")
        .run(Size::Reduced, device, dir.path())
        .expect("case runs");
    for m in &report.metrics {
        match m.tolerance {
            Some(t) => println!(
                "{} on {}: {} = {:.4e} (tolerance {t:.1e})",
                m.case,
                device.name(),
                m.metric,
                m.value
            ),
            None => println!(
                "{} on {}: {} = {:.4e} (information)",
                m.case,
                device.name(),
                m.metric,
                m.value
            ),
        }
    }
    for f in &report.files {
        assert!(f.exists(), "{} was not written", f.display());
    }
    for m in &report.metrics {
        assert!(
            m.passed,
            "{} on {}: {} = {} outside its tolerance {:?}",
            m.case,
            device.name(),
            m.metric,
            m.value,
            m.tolerance
        );
    }
}

/// The GPU (one device for the binary), or `None` with a note where there is none outside CI.
fn gpu() -> Option<Device> {
    static GPU: OnceLock<Result<Gpu, String>> = OnceLock::new();
    match GPU.get_or_init(|| Gpu::new(false).map_err(|e| e.to_string())) {
        Ok(gpu) => Some(Device::Gpu(Box::new(gpu.clone()))),
        Err(e) if std::env::var("CI").as_deref() == Ok("true") => {
            panic!("CI needs a GPU adapter for the GPU tests: {e}")
        }
        Err(e) => {
            eprintln!("skipped: {e}");
            None
        }
    }
}

fn check_on_gpu(name: &str) {
    if let Some(device) = gpu() {
        check_on(name, &device);
    }
}

#[test]
fn disk_collision_on_the_gpu() {
    check_on_gpu("disk-collision");
}

#[test]
fn dambreak_2d_on_the_gpu() {
    check_on_gpu("dambreak-2d");
}

#[test]
fn bui_collapse_on_the_gpu() {
    check_on_gpu("bui-collapse");
}

#[test]
fn dambreak_obstacles_3d_on_the_gpu() {
    check_on_gpu("dambreak-obstacles-3d");
}

/// A case that runs on the CPU only says so when asked for the GPU, and names those that do.
#[test]
fn a_cpu_only_case_is_refused_on_the_gpu() {
    let cantilever = case("cantilever").expect("case exists");
    let e = cantilever
        .check_device(true)
        .expect_err("the cantilever is implicit");
    let message = e.to_string();
    assert!(
        message.contains("runs on the CPU only") && message.contains("dambreak-2d"),
        "{message}"
    );
    assert!(cantilever.check_device(false).is_ok());
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
fn footing_cphi() {
    check("footing-cphi");
}

#[test]
fn slope_fos() {
    check("slope-fos");
}

#[test]
fn k0_layer() {
    check("k0-layer");
}

#[test]
fn terzaghi() {
    check("terzaghi");
}

#[test]
fn mandel() {
    check("mandel");
}

#[test]
fn consolidation_large() {
    check("consolidation-large");
}

#[test]
fn footing_consolidation_3d() {
    check("footing-consolidation-3d");
}

#[test]
fn triaxial_dp() {
    check("triaxial-dp");
}

#[test]
fn triaxial_mc() {
    check("triaxial-mc");
}

#[test]
fn triaxial_mcc() {
    check("triaxial-mcc");
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
fn obstacle_velocity_fd() {
    check("obstacle-velocity-fd");
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
fn inverse_footing_cphi() {
    check("inverse-footing-cphi");
}

#[test]
fn inverse_triaxial_mcc() {
    check("inverse-triaxial-mcc");
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
