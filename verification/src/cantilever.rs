//! Large-deflection plane-strain cantilever under a tip load, against the elastica.
//!
//! The reference set-up of the implicit benchmark: a 15 × 15 m grid of 0.25 m cells, a beam
//! x ∈ [0.25, 10.25] m, y ∈ [9, 10] m with 6 × 6 particles per cell (5,760 particles), Hencky
//! elasticity E = 12 MPa, ν = 0.2, ρ = 1, no gravity. The root is held by the nodes of the
//! first two grid columns: x-displacement fixed on both columns, y-displacement fixed on them
//! at the neutral axis y = 9.5 m. The tip load, 100 kN in total, goes to the two particles
//! nearest the tip's neutral axis (−50 kN each), ramped over 50 load steps.
//!
//! At full load `PL²/EI = 10` with `I = d³/12`. In plane strain the bending stiffness is
//! `E′I` with `E′ = E/(1 − ν²)`, so the consistent reference is the elastica at
//! `α′ = PL²/(E′I) = 9.6`; both are reported.

use crate::elastica::{tip_displacement, tip_displacement_reissner};
use crate::fe_beam::{FeBeam, FeError, LoadDistribution, Support};
use crate::{CaseReport, Metric, Series, Size, VerifyError, write_csv, write_plot, write_text};
use loam_core::tensor::Vector;
use loam_core::{Boundary, Grid, Material, ModelKind, Particles, Shape, Wall, WallKind};
use loam_implicit::{
    ImplicitConfig, ImplicitError, ImplicitSolver, NewtonSettings, NodeConstraint, PointLoad,
    StepReport,
};
use std::path::Path;

/// Beam length (m).
pub const LENGTH: f64 = 10.0;
/// Beam depth (m).
pub const DEPTH: f64 = 1.0;
/// Young's modulus (Pa).
pub const YOUNG: f64 = 12.0e6;
/// Poisson's ratio.
pub const POISSON: f64 = 0.2;
/// Total tip load (N per m of thickness).
pub const LOAD: f64 = 100.0e3;

/// How the root is held.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Root {
    /// The reference: x fixed on the nodes of the first two grid columns (x = 0 and 0.25 m),
    /// y fixed on them at the neutral axis. With shape functions wider than the hat the
    /// displacement at x = 0.25 m is not zero (`u(0.25) = N(0.5) u_0.5 = u_0.5/8` for quadratic
    /// B-splines), so the root is slightly compliant.
    Reference,
    /// The grid starts at the root, x = 0.25 m, with a slip wall there: the wall is a symmetry
    /// plane (mirror images of the ghost nodes), which clamps the rotation exactly at the root
    /// while leaving the Poisson expansion free; y is pinned at the neutral axis.
    Symmetry,
}

/// Discretisation of the cantilever.
#[derive(Clone, Copy, Debug)]
pub struct Setup {
    /// Root condition.
    pub root: Root,
    /// Cell size (m); the reference uses 0.25.
    pub cell: f64,
    /// Particles per cell per axis; the reference uses 6.
    pub ppc: usize,
    /// Shape functions.
    pub shape: Shape,
    /// Load steps; the reference uses 50.
    pub steps: usize,
    /// Newton settings.
    pub newton: NewtonSettings,
}

impl Setup {
    /// The reference set-up with the given shape functions.
    pub fn reference(shape: Shape) -> Self {
        Self {
            root: Root::Reference,
            cell: 0.25,
            ppc: 6,
            shape,
            steps: 50,
            newton: NewtonSettings::default(),
        }
    }

    /// Configuration, particles and the ids of the two loaded tip particles.
    pub fn build(&self) -> (ImplicitConfig<2>, Particles<f64, 2>, [usize; 2]) {
        let h = self.cell;
        let cells = (15.0 / h).round() as usize;
        let (x0, y0) = (0.25, 9.0);
        let grid_lo = match self.root {
            Root::Reference => 0.0,
            Root::Symmetry => x0,
        };
        let grid = Grid::new([grid_lo, 0.0], [cells, cells], h, self.shape.ghost_cells());
        let mut particles = Particles::default();
        let dp = h / self.ppc as f64;
        let nx = (LENGTH / dp).round() as usize;
        let ny = (DEPTH / dp).round() as usize;
        let hw = Vector::<f64, 2>::repeat(dp / 2.0);
        for i in 0..nx {
            for j in 0..ny {
                let x =
                    Vector::<f64, 2>::new(x0 + (i as f64 + 0.5) * dp, y0 + (j as f64 + 0.5) * dp);
                particles.push(x, Vector::zeros(), 1.0, hw, 0);
            }
        }
        // The two particles nearest the tip's neutral axis (x0 + L, y0 + d/2).
        let tip = Vector::<f64, 2>::new(x0 + LENGTH, y0 + DEPTH / 2.0);
        let mut ids: Vec<usize> = (0..particles.len()).collect();
        ids.sort_by(|&a, &b| {
            (particles.x[a] - tip)
                .norm()
                .total_cmp(&(particles.x[b] - tip).norm())
                .then(a.cmp(&b))
        });
        let loaded = [ids[0], ids[1]];
        let neutral = y0 + DEPTH / 2.0;
        let (boundary, constraints) = match self.root {
            Root::Reference => (
                Boundary::all(Wall::new(WallKind::Free)),
                vec![
                    // x fixed on the first two grid columns …
                    NodeConstraint {
                        lo: [0.0, f64::NEG_INFINITY],
                        hi: [0.25, f64::INFINITY],
                        displacement: [Some(0.0), None],
                    },
                    // … and y fixed on them at the neutral axis.
                    NodeConstraint {
                        lo: [0.0, neutral],
                        hi: [0.25, neutral],
                        displacement: [None, Some(0.0)],
                    },
                ],
            ),
            Root::Symmetry => {
                let mut b = Boundary::all(Wall::new(WallKind::Free));
                b.walls[0][0] = Wall::new(WallKind::Slip);
                (
                    b,
                    vec![NodeConstraint {
                        lo: [x0, neutral],
                        hi: [x0, neutral],
                        displacement: [None, Some(0.0)],
                    }],
                )
            }
        };
        let config = ImplicitConfig {
            grid,
            shape: self.shape,
            boundary,
            materials: vec![Material::elastic(ModelKind::Hencky, YOUNG, POISSON, 1.0)],
            gravity: Vector::zeros(),
            constraints,
            point_loads: loaded
                .iter()
                .map(|&p| PointLoad {
                    particle: p,
                    force: [0.0, -LOAD / 2.0],
                })
                .collect(),
            load_steps: self.steps,
            newton: self.newton,
            dynamics: None,
            min_node_support: ImplicitConfig::<2>::DEFAULT_MIN_NODE_SUPPORT,
        };
        (config, particles, loaded)
    }

    /// Runs all load steps; returns the tip displacement (mean of the loaded particles,
    /// `(u_x, u_y)`) after each step and the step reports.
    pub fn run(&self) -> Result<(Vec<[f64; 2]>, Vec<StepReport<2>>), ImplicitError> {
        let (config, mut particles, loaded) = self.build();
        let start: Vec<Vector<f64, 2>> = loaded.iter().map(|&p| particles.x[p]).collect();
        let mut solver = ImplicitSolver::new(config, &particles)?;
        let mut tips = Vec::new();
        let mut reports = Vec::new();
        while !solver.finished() {
            reports.push(solver.step(&mut particles)?);
            let d = loaded
                .iter()
                .zip(&start)
                .fold(Vector::<f64, 2>::zeros(), |s, (&p, x0)| {
                    s + (particles.x[p] - x0) * 0.5
                });
            tips.push([d[0], d[1]]);
        }
        Ok((tips, reports))
    }
}

/// Which beam theory the reference tip displacement comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Beam {
    /// The classic elastica with `EI` (the benchmark's quoted numbers).
    Elastica,
    /// Reissner's beam with the plane-strain moduli: bending and axial stiffness with
    /// `E′ = E/(1 − ν²)`, shear stiffness `κGA` with κ = 5/6. The consistent reference for a
    /// plane-strain continuum beam of finite depth.
    Reissner,
}

/// The reference tip displacement `(inward u, downward v)` in metres at load fraction `λ`.
pub fn reference_tip(lambda: f64, beam: Beam) -> (f64, f64) {
    let i = DEPTH.powi(3) / 12.0;
    let (v, u) = match beam {
        Beam::Elastica => tip_displacement(lambda * LOAD * LENGTH * LENGTH / (YOUNG * i)),
        Beam::Reissner => {
            let ep = YOUNG / (1.0 - POISSON * POISSON);
            let g = YOUNG / (2.0 * (1.0 + POISSON));
            let ei = ep * i;
            let e = ei / (ep * DEPTH * LENGTH * LENGTH);
            let gs = ei / (5.0 / 6.0 * g * DEPTH * LENGTH * LENGTH);
            tip_displacement_reissner(lambda * LOAD * LENGTH * LENGTH / ei, e, gs)
        }
    };
    (u * LENGTH, v * LENGTH)
}

/// The converged continuum: the tip history (inward `u`, downward `v`, m) of the
/// finite-element reference ([`crate::fe_beam`]) with a clamped root and the parabolic tip
/// shear, `steps` load steps on an `nx × ny` mesh of Q9 elements. At 80 × 8 it is within
/// 2·10⁻⁵ of its mesh limit, 8.2557 m.
pub fn continuum_tip(nx: usize, ny: usize, steps: usize) -> Result<Vec<(f64, f64)>, FeError> {
    let beam = FeBeam {
        steps,
        distribution: LoadDistribution::TipShear,
        ..FeBeam::new(nx, ny, Support::Clamped)
    };
    Ok(beam
        .tip_history()?
        .into_iter()
        .map(|[ux, uy]| (-ux, -uy))
        .collect())
}

fn implicit_err(source: ImplicitError) -> VerifyError {
    VerifyError::Implicit {
        case: "cantilever".into(),
        source,
    }
}

/// One run's tip displacement at full load and its cost.
struct Outcome {
    v: f64,
    u: f64,
    iterations: usize,
    wall: f64,
}

fn solve(setup: &Setup) -> Result<(Outcome, Vec<[f64; 2]>), VerifyError> {
    let start = std::time::Instant::now();
    let (tips, reports) = setup.run().map_err(implicit_err)?;
    let last = tips.last().copied().unwrap_or([0.0, 0.0]);
    Ok((
        Outcome {
            v: -last[1],
            u: -last[0],
            iterations: reports.iter().map(StepReport::<2>::iterations).sum(),
            wall: start.elapsed().as_secs_f64(),
        },
        tips,
    ))
}

/// Runs the case: the reference set-up (cpGIMP) with its tip history against
/// both beam theories, and a refinement table for both root conditions.
pub fn run(size: Size, out: &Path) -> Result<CaseReport, VerifyError> {
    const CASE: &str = "cantilever";
    let reference = Setup::reference(Shape::Cpgimp);
    let main = match size {
        // The reference root is defined by the grid columns of the 0.25 m grid; the coarse
        // reduced run holds the root by the symmetry wall instead.
        Size::Reduced => Setup {
            root: Root::Symmetry,
            cell: 0.5,
            ppc: 4,
            steps: 10,
            ..reference
        },
        Size::Full => reference,
    };
    let (outcome, tips) = solve(&main)?;
    // The continuum reference on the same load steps: 80 × 8 Q9 elements at full size
    // (2–3 s), 40 × 4 at reduced size (within 1e-4 of the mesh limit either way).
    let (nx, ny) = match size {
        Size::Full => (80, 8),
        Size::Reduced => (40, 4),
    };
    let continuum = continuum_tip(nx, ny, main.steps).map_err(|e| VerifyError::Reference {
        case: "cantilever".into(),
        msg: e.to_string(),
    })?;
    let mut rows = Vec::new();
    for (k, (tip, &(u_c, v_c))) in tips.iter().zip(&continuum).enumerate() {
        let lambda = (k + 1) as f64 / main.steps as f64;
        let (u_r, v_r) = reference_tip(lambda, Beam::Reissner);
        let (u_e, v_e) = reference_tip(lambda, Beam::Elastica);
        rows.push(vec![
            lambda * LOAD / 1e3,
            -tip[1],
            -tip[0],
            v_c,
            u_c,
            v_r,
            u_r,
            v_e,
            u_e,
        ]);
    }
    let csv = out.join("cantilever.csv");
    write_csv(
        &csv,
        &[
            "load_kN",
            "v_mpm",
            "u_mpm",
            "v_continuum_fe",
            "u_continuum_fe",
            "v_reissner",
            "u_reissner",
            "v_elastica",
            "u_elastica",
        ],
        &rows,
    )?;
    let png = out.join("cantilever.png");
    let col = |name: &str, c: usize, markers: bool| Series {
        name: name.into(),
        points: rows.iter().map(|r| (r[0], r[c])).collect(),
        markers,
    };
    write_plot(
        &png,
        &format!(
            "Cantilever tip, h = {} m, {} load steps",
            main.cell, main.steps
        ),
        "tip load (kN)",
        "tip displacement (m)",
        &[
            col("v continuum (FE)", 3, false),
            col("u continuum (FE)", 4, false),
            col("v Reissner (plane strain)", 5, false),
            col("u Reissner (plane strain)", 6, false),
            col("v elastica (EI)", 7, false),
            col("u elastica (EI)", 8, false),
            col("v loam", 1, true),
            col("u loam", 2, true),
        ],
    )?;
    let (_, v_reissner) = reference_tip(1.0, Beam::Reissner);
    let (_, v_elastica) = reference_tip(1.0, Beam::Elastica);
    let v_continuum = continuum.last().map_or(f64::NAN, |&(_, v)| v);
    let rel = |v: f64, r: f64| (v - r) / r;
    let mut table = format!(
        "Tip deflection at full load; continuum (FE, clamped, {nx} × {ny} Q9) v = {v_continuum:.4} m, Reissner (plane strain, shear and extension) v = {v_reissner:.4} m, elastica (EI) v = {v_elastica:.4} m.\n\n| root | h (m) | particles/cell | v (m) | u (m) | error vs continuum | error vs Reissner | error vs elastica | Newton iterations | wall (s) |\n|---|---|---|---|---|---|---|---|---|---|\n"
    );
    let mut line = |root: Root, s: &Setup, o: &Outcome| {
        table.push_str(&format!(
            "| {root:?} | {} | {}×{} | {:.4} | {:.4} | {:+.2} % | {:+.2} % | {:+.2} % | {} | {:.2} |\n",
            s.cell,
            s.ppc,
            s.ppc,
            o.v,
            o.u,
            100.0 * rel(o.v, v_continuum),
            100.0 * rel(o.v, v_reissner),
            100.0 * rel(o.v, v_elastica),
            o.iterations,
            o.wall
        ));
    };
    line(main.root, &main, &outcome);
    if size == Size::Full {
        for (root, cell, ppc) in [
            (Root::Symmetry, 0.5, 4),
            (Root::Symmetry, 0.25, 6),
            (Root::Symmetry, 0.125, 4),
        ] {
            let s = Setup {
                root,
                cell,
                ppc,
                ..reference
            };
            let (o, _) = solve(&s)?;
            line(root, &s, &o);
        }
    }
    let md = out.join("cantilever.md");
    write_text(&md, &table)?;
    Ok(CaseReport {
        metrics: vec![
            // The discretisation error: the tip against the converged plane-strain Hencky
            // continuum of the same problem (fe_beam; mesh limit 8.2557 m, known to 1e-5).
            // Full size: the benchmark's 0.5 % (measured −0.08 %). Reduced (h = 0.5 m, two
            // cells through the depth, 10 load steps): measured −1.10 %, the coarse grid's
            // stiffness; 1.5 % bounds it with margin, while a small-rotation (linear)
            // response, PL³/3EI = 33 m, would be off by a factor of four.
            Metric::at_most(
                CASE,
                "tip_rel_error_vs_continuum",
                rel(outcome.v, v_continuum).abs(),
                match size {
                    Size::Full => 0.005,
                    Size::Reduced => 0.015,
                },
            ),
            // The benchmark's stated goal: within 0.5 % of the elastica (EI). Not met: the
            // converged continuum itself lies 1.85 % above the elastica (it has shear and
            // axial flexibility, plane-strain moduli and finite-strain section behaviour), so
            // a correct solver cannot meet it (docs/verification.md). At reduced size 5 %
            // checks that the large-deflection path is right.
            Metric::at_most(
                CASE,
                "tip_rel_error_vs_elastica",
                rel(outcome.v, v_elastica).abs(),
                match size {
                    Size::Full => 0.005,
                    Size::Reduced => 0.05,
                },
            ),
        ],
        files: vec![csv, png, md],
    })
}
