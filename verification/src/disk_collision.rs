//! Sulsky, Chen & Schreyer (1994): two elastic disks collide and rebound.
//!
//! Unit square, disks of radius 0.2 centred at (0.2, 0.2) and (0.8, 0.8) moving at
//! ±(0.1, 0.1) m/s, E = 1000 Pa, ν = 0.3, ρ = 1000 kg/m³. There is no closed form; the check is
//! energy: with no dissipation in the continuum, kinetic + strain energy is constant, so the
//! drift of the total measures the scheme's numerical dissipation through the impact.

use crate::device::ExplicitRun;
use crate::{CaseReport, Device, Metric, Series, Size, VerifyError, scenes, write_csv, write_plot};
use loam_core::{Particles, Transfer};
use loam_explicit::Config;
use std::path::Path;

/// Builds the two-disk problem with `cells` cells per side and `ppc` particles per cell per
/// axis: `verification/scenes/disk_collision.toml` with that cell size, particle density and
/// transfer.
pub fn build(cells: usize, ppc: usize, transfer: Transfer) -> (Config<f64, 2>, Particles<f64, 2>) {
    let mut scene = scenes::scene("disk_collision");
    scene.grid.cell_size = 1.0 / cells as f64;
    for body in &mut scene.bodies {
        body.particles_per_cell = ppc as u32;
    }
    scene.solver.transfer = Some(transfer);
    let built = scenes::build::<2>(&scene);
    let config = built
        .explicit_config()
        .expect("the disk collision is an explicit scene");
    (config, built.particles)
}

/// Runs the case on `device`: energy history to t = 4 s (contact ≈ 1.6–2.6 s).
pub fn run(size: Size, device: &Device, out: &Path) -> Result<CaseReport, VerifyError> {
    const CASE: &str = "disk-collision";
    let cells = match size {
        Size::Reduced => 20,
        Size::Full => 50,
    };
    let (config, mut particles) = build(cells, 2, Transfer::Apic);
    let mut solver = ExplicitRun::new(CASE, config, &particles, device)?;
    let e0 = solver.energy(&particles);
    let mut rows = vec![vec![0.0, e0.kinetic, e0.strain, e0.total()]];
    let t_end = 4.0;
    let frames = 200;
    for k in 1..=frames {
        let t = t_end * k as f64 / frames as f64;
        solver.advance(&mut particles, t)?;
        let e = solver.energy(&particles);
        rows.push(vec![t, e.kinetic, e.strain, e.total()]);
    }
    let csv = out.join("disk_collision.csv");
    write_csv(&csv, &["t", "kinetic", "strain", "total"], &rows)?;
    let png = out.join("disk_collision.png");
    let series = |name: &str, col: usize| Series {
        name: name.into(),
        points: rows.iter().map(|r| (r[0], r[col])).collect(),
        markers: false,
    };
    write_plot(
        &png,
        &format!("Two-disk collision, {cells}×{cells} cells, APIC/MUSL"),
        "t (s)",
        "energy (J per m)",
        &[
            series("kinetic", 1),
            series("strain", 2),
            series("total", 3),
        ],
    )?;
    let total0 = e0.total();
    // Free flight before contact: the disks touch at t ≈ 1.59 s, and their grid supports
    // (≈ 3 cells each) meet some 0.5 s earlier on the coarse grid, so t < 0.9 s is free flight
    // at both sizes. APIC carries a rigid translation exactly: the energy may change by
    // round-off only. In f64, 1e-9 relative leaves room for ~10³ steps of 1e-16 errors. On
    // the GPU, in f32, one rounding of ε₃₂ = 1.2e-7 per step over the at most 200 free-flight
    // steps (adaptive Δt ≈ 4.4e-3 s at 50 cells, 1e-2 s at 20) drifts the energy by up to
    // 2.4e-5; 1e-4 bounds that with margin (measured on lavapipe: 9.3e-7 at 20 cells, 3.6e-6
    // at 50, growing with the steps).
    let drift_tolerance = match device {
        Device::Cpu => 1e-9,
        Device::Gpu(_) => 1e-4,
    };
    let before = rows
        .iter()
        .filter(|r| r[0] < 0.9)
        .map(|r| (r[3] - total0).abs())
        .fold(0.0, f64::max)
        / total0;
    let loss = (total0 - rows.last().map_or(total0, |r| r[3])) / total0;
    // The impact dissipates: a single-velocity grid makes the contact inelastic while the
    // disks overlap in the grid, and the transfer damps the short waves the impact excites.
    // Measured: 29 % at 20 cells, 11 % at 50 cells (docs/verification.md); the tolerance bounds
    // that loss at each size with margin, so a regression in the transfers or the contact
    // shows up.
    let loss_tol = match size {
        Size::Reduced => 0.35,
        Size::Full => 0.15,
    };
    Ok(CaseReport {
        metrics: vec![
            Metric::at_most(CASE, "energy_drift_before_contact", before, drift_tolerance),
            Metric::at_most(CASE, "energy_loss_through_impact", loss, loss_tol),
        ],
        files: vec![csv, png],
    })
}
