//! Plane-strain collapse of a column of aluminium bars (Bui et al. 2008).
//!
//! Bui, Fukagawa, Sako & Ohno (2008), "Lagrangian meshfree particles method (SPH) for large
//! deformation and failure flows of geomaterial using elastic–plastic soil constitutive
//! model", Int. J. Numer. Anal. Meth. Geomech. 32:1537–1570: a column of aluminium bars (1 and
//! 1.5 mm in diameter, 50 mm long, stacked as a 2D granular medium) 0.2 m long and 0.1 m high
//! against a wall is released; ρ = 2650 kg/m³, E = 0.84 MPa, ν = 0.3, φ = 19.8°, c = 0, ψ = 0.
//! The set-up is [`crate::granular`]; the floor has Coulomb friction μ = tan φ = 0.36, a floor
//! as rough as the material itself (the interface friction angle equals the internal one, the
//! usual "rough" limit: with ψ = 0 the material shears at τ/σ = 3α ≈ sin φ = 0.33 on a
//! horizontal plane, below μ, so the base would rather shear inside the material than slide).
//!
//! **References.** The paper's measured final profile could not be retrieved for this case, so
//! no number from it is used. Two references instead:
//!
//! - *height at the wall*: H₀ = 0.1 m. For this aspect ratio (a = H₀/L₀ = 0.5) the upper-left
//!   part of the column is not mobilised (the failure surface from the toe of the column
//!   reaches the top surface at x ≈ L₀ − H₀ tan(45° − φ/2) ≈ 0.13 m), as the experiment and
//!   the channel experiments below (a < 0.7–1) show;
//! - *runout*: the band of the granular-collapse scaling laws at a = 0.5, Lube et al. (2005)
//!   `(L∞ − L₀)/L₀ = 1.2a` and Lajeunesse et al. (2005) `1.8a`, i.e. L∞ between 0.32 and
//!   0.38 m (see [`crate::runout`] for the laws). The laws were fitted on sands, rice, sugar and
//!   glass beads (friction angles ≈ 22–37°); the bars' 19.8° is below that range, which favours
//!   a longer runout, so this band is a proxy, not the experiment.

use crate::granular::{self, Collapse, G, Granular, MIN_THICKNESS, Outcome};
use crate::runout::{lajeunesse, lube};
use crate::{CaseReport, Metric, Series, Size, VerifyError, write_plot, write_text};
use std::fmt::Write as _;
use std::path::Path;

/// Column length `L₀` (m).
pub const L0: f64 = 0.2;
/// Column height `H₀` (m).
pub const H0: f64 = 0.1;

/// The aluminium bars and the floor.
pub fn material() -> Granular {
    let friction_deg: f64 = 19.8;
    Granular {
        density: 2650.0,
        young: 0.84e6,
        poisson: 0.3,
        friction_deg,
        dilation_deg: 0.0,
        floor_mu: friction_deg.to_radians().tan(),
    }
}

/// The collapse with cell size `h` (a divisor of 0.01 m): a 0.6 m × 0.12 m box, 2 × 2
/// particles per cell, 1 s (the pile is at rest by about 0.6 s).
pub fn collapse(h: f64) -> Collapse {
    Collapse {
        material: material(),
        l0: L0,
        h0: H0,
        length: 0.6,
        height: 0.12,
        h,
        ppc: 2,
        end_time: 1.0,
    }
}

/// The reference runout band `[L₀(1 + 1.2a), L₀(1 + 1.8a)]` at `a = H₀/L₀` (m).
pub fn runout_band() -> (f64, f64) {
    let a = H0 / L0;
    (L0 * (1.0 + lube(a)), L0 * (1.0 + lajeunesse(a)))
}

/// How far `x` lies outside `[lo, hi]`, relative to the nearer edge (0 inside).
pub fn band_excess(x: f64, (lo, hi): (f64, f64)) -> f64 {
    if x > hi {
        (x - hi) / hi
    } else if x < lo {
        (lo - x) / lo
    } else {
        0.0
    }
}

/// Runs the case: final runout and height at the wall.
pub fn run(size: Size, out: &Path) -> Result<CaseReport, VerifyError> {
    const CASE: &str = "bui-collapse";
    // Reduced: h = 10 mm (10 cells over H₀, 800 particles, ≈ 5,200 steps). Full: h = 5 mm
    // (3,200 particles, ≈ 10,500 steps).
    let h = match size {
        Size::Reduced => 0.01,
        Size::Full => 0.005,
    };
    let c = collapse(h);
    let o = granular::simulate(CASE, &c, 50)?;
    let band = runout_band();
    let last = o.last();

    let mut files = Vec::new();
    let csv = out.join("bui_history.csv");
    granular::write_history(&csv, &o)?;
    files.push(csv);
    let csv = out.join("bui_deposit.csv");
    granular::write_deposit(&csv, &o)?;
    files.push(csv);
    let png = out.join("bui_deposit.png");
    write_plot(
        &png,
        &format!(
            "Bui et al. (2008) collapse, h = {} mm: final deposit",
            h * 1e3
        ),
        "x (m)",
        "y (m)",
        &deposit_series(&o, band),
    )?;
    files.push(png);
    let png = out.join("bui_toe.png");
    write_plot(
        &png,
        &format!("Bui et al. (2008) collapse, h = {} mm: toe", h * 1e3),
        "t (s)",
        "x (m)",
        &toe_series(&o, band),
    )?;
    files.push(png);
    let md = out.join("bui.md");
    write_text(&md, &summary(&o, band))?;
    files.push(md);

    // Height at the wall against H₀. Measured: 0.0980 m (−2.0 %) at h = 10 mm, 0.0990 m
    // (−1.0 %) at 5 mm: the wall column settles by the elastic compression (ρgH₀/M = 0.2 %)
    // and by the slumping of the mobilised region next to it, which reaches the wall at the
    // coarse grid's resolution. 3 % bounds both; a column whose top left were mobilised
    // would lose far more.
    let wall_tol = 0.03;
    // Runout against the Lube–Lajeunesse band [0.32, 0.38] m, as the relative distance
    // outside it. Full size: the goal is to lie inside the band (tolerance 0). Measured:
    // 0.381 m at h = 10 mm (0.3 % beyond the band's upper edge) and 0.415 m at 5 mm (+9.2 %;
    // docs/verification.md): the runout grows with refinement as the front thins into a
    // longer tongue, so the full-size goal is not met. The reduced tolerance, 5 %, admits the
    // coarse-grid value with room for where the front particles settle, and fails a front
    // two cells further out.
    let runout_tol = match size {
        Size::Reduced => 0.05,
        Size::Full => 0.0,
    };
    Ok(CaseReport {
        metrics: vec![
            Metric::at_most(
                CASE,
                "wall_height_rel_error",
                (last.wall_height - H0).abs() / H0,
                wall_tol,
            ),
            Metric::at_most(
                CASE,
                "runout_outside_lube_lajeunesse_band",
                band_excess(o.runout(), band),
                runout_tol,
            ),
            // At rest: K/ΔE_p measured 4e-9 (h = 10 mm) and 2.5e-8 (5 mm) at t = 1 s; 1e-4
            // fails a pile still moving.
            Metric::at_most(CASE, "kinetic_over_released_energy", o.rest_ratio(), 1e-4),
            // The toe over the last 0.3 s: measured below 0.002 mm at both sizes;
            // a quarter cell fails a front still creeping.
            Metric::at_most(
                CASE,
                "late_toe_motion_cells",
                o.late_toe_motion(0.3) / h,
                0.25,
            ),
            Metric::at_least(
                CASE,
                "right_wall_clearance_cells",
                o.right_clearance_cells(),
                2.0,
            ),
        ],
        files,
    })
}

/// Series of the deposit plot: final thickness and surface, the initial column, the band.
fn deposit_series(o: &Outcome, (lo, hi): (f64, f64)) -> Vec<Series> {
    let c = &o.collapse;
    vec![
        granular::thickness_series(o, "solid-equivalent thickness", 1.0),
        Series {
            name: "free surface (top particle)".into(),
            points: o.surface.clone(),
            markers: true,
        },
        Series {
            name: "initial column".into(),
            points: granular::initial_outline(c, 1.0),
            markers: false,
        },
        Series {
            name: format!("runout band {lo:.2}–{hi:.2} m (Lube / Lajeunesse)"),
            points: vec![(lo, 0.0), (lo, 0.02 * H0), (hi, 0.02 * H0), (hi, 0.0)],
            markers: false,
        },
        Series {
            name: format!("toe (t ≥ {} mm)", MIN_THICKNESS * 1e3),
            points: vec![(o.runout(), 0.0), (o.runout(), 0.2 * H0)],
            markers: false,
        },
    ]
}

/// Series of the toe plot: toe and film toe against time, with the band edges.
fn toe_series(o: &Outcome, (lo, hi): (f64, f64)) -> Vec<Series> {
    let t_end = o.collapse.end_time;
    vec![
        Series {
            name: format!("toe (t ≥ {} mm)", MIN_THICKNESS * 1e3),
            points: o.history.iter().map(|s| (s.t, s.toe)).collect(),
            markers: false,
        },
        Series {
            name: "toe of any contiguous material".into(),
            points: o.history.iter().map(|s| (s.t, s.film_toe)).collect(),
            markers: false,
        },
        Series {
            name: "band: Lube 1.2a".into(),
            points: vec![(0.0, lo), (t_end, lo)],
            markers: false,
        },
        Series {
            name: "band: Lajeunesse 1.8a".into(),
            points: vec![(0.0, hi), (t_end, hi)],
            markers: false,
        },
    ]
}

/// A Markdown summary of the run.
fn summary(o: &Outcome, (lo, hi): (f64, f64)) -> String {
    let c = &o.collapse;
    let last = o.last();
    let mut md = format!(
        "Bui et al. (2008) collapse, h = {} mm, {} particles, {} steps, {:.1} s wall\n\n",
        c.h * 1e3,
        o.particles,
        o.steps,
        o.wall
    );
    let mut line = |k: &str, v: String| {
        writeln!(md, "| {k} | {v} |").expect("writing to a String cannot fail");
    };
    line("quantity", "value".into());
    line("---", "---".into());
    line(
        "runout L∞ (toe, t ≥ 4 mm)",
        format!("{:.4} m; band {lo:.2}–{hi:.2} m", o.runout()),
    );
    line(
        "(L∞ − L₀)/L₀",
        format!(
            "{:.3}; band {:.2}–{:.2}",
            o.normalised_runout(),
            lube(0.5),
            lajeunesse(0.5)
        ),
    );
    line(
        "toe of any contiguous material",
        format!("{:.4} m", last.film_toe),
    );
    line("farthest particle", format!("{:.4} m", o.max_x));
    line(
        "height at the wall",
        format!("{:.4} m (H₀ = {H0} m)", last.wall_height),
    );
    line(
        "K/ΔE_p at the end",
        format!("{:.2e} (ΔE_p = {:.3} J/m)", o.rest_ratio(), last.released),
    );
    line(
        "elastic compression ρgH₀/M",
        format!("{:.2e}", c.material.elastic_strain(c.h0)),
    );
    line("g", format!("{G} m/s²"));
    md
}
