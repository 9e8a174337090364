//! Field-by-field validation of a parsed scene.
//!
//! [`Scene::validate`] collects every problem it finds, each naming the field path and what
//! was expected, so one `loam check` shows them all. Checks run in two stages: the fields
//! (ranges, finiteness, coordinate counts, names, the grid) and then, only when the fields
//! are sound, the particle generation itself (every body must produce particles).

use crate::error::{Issue, SceneError};
use crate::geometry::twice_signed_area;
use crate::schema::{BodyShape, BodySpec, Scene};
use loam_core::{ModelKind, TimeStep, Transfer};
use std::collections::HashSet;

/// Tolerance, relative to the domain size, for a body's bounding box to stick out of the
/// domain and for the domain to be a whole number of cells.
const GEOMETRY_TOLERANCE: f64 = 1e-9;

/// The most grid cells a scene may ask for (keeps index arithmetic far from overflow and
/// catches a cell size typed in the wrong unit).
const MAX_CELLS: f64 = (1u64 << 32) as f64;

/// The most particles per cell along one axis.
const MAX_PARTICLES_PER_CELL: u32 = 8;

impl Scene {
    /// Checks every field and the particle generation; the `from_*` loaders call it.
    pub fn validate(&self) -> Result<(), SceneError> {
        let mut issues = self.field_issues();
        if issues.is_empty() {
            issues = match self.dim() {
                2 => self.seed::<2>(|_, _| {}),
                3 => self.seed::<3>(|_, _| {}),
                _ => Vec::new(),
            };
        }
        self.issues_to_result(issues)
    }

    /// `Ok` when there are no issues, else an invalid-scene error naming the source file.
    pub(crate) fn issues_to_result(&self, issues: Vec<Issue>) -> Result<(), SceneError> {
        if issues.is_empty() {
            return Ok(());
        }
        let err = SceneError::invalid(issues);
        Err(match &self.source {
            Some(path) => err.in_file(path),
            None => err,
        })
    }

    /// The problems with the fields, in file order (empty when all are sound).
    pub(crate) fn field_issues(&self) -> Vec<Issue> {
        let mut c = Checker::default();
        let dim = self.check_grid(&mut c);
        self.check_materials(&mut c);
        let names: Vec<&str> = self.materials.iter().map(|m| m.name.as_str()).collect();
        if self.bodies.is_empty() {
            c.issue("bodies", "a scene needs at least one body");
        }
        for (i, body) in self.bodies.iter().enumerate() {
            self.check_body(&mut c, &format!("bodies[{i}]"), body, dim, &names);
        }
        self.check_boundaries(&mut c, dim);
        if let (Some(g), Some(dim)) = (&self.loads.gravity, dim) {
            c.coords("loads.gravity", g, dim);
        }
        self.check_solver(&mut c);
        self.check_output(&mut c);
        c.issues
    }

    /// Checks `[grid]`; returns the dimension when `lo` gives a usable one.
    fn check_grid(&self, c: &mut Checker) -> Option<usize> {
        let g = &self.grid;
        let dim = g.lo.len();
        if !(2..=3).contains(&dim) {
            c.issue(
                "grid.lo",
                format!("expected 2 or 3 coordinates (2D or 3D), got {dim}"),
            );
            return None;
        }
        let coords_ok = c.coords("grid.lo", &g.lo, dim) & c.coords("grid.hi", &g.hi, dim);
        let h_ok = c.positive("grid.cell_size", g.cell_size);
        if !coords_ok {
            return Some(dim);
        }
        let mut extents_ok = true;
        for a in 0..dim {
            if g.hi[a] <= g.lo[a] {
                c.issue(
                    format!("grid.hi[{a}]"),
                    format!(
                        "must be greater than grid.lo[{a}] = {}, got {}",
                        g.lo[a], g.hi[a]
                    ),
                );
                extents_ok = false;
            }
        }
        if !(h_ok && extents_ok) {
            return Some(dim);
        }
        let mut total = 1.0;
        for a in 0..dim {
            let extent = g.hi[a] - g.lo[a];
            let n = extent / g.cell_size;
            if (n - n.round()).abs() > GEOMETRY_TOLERANCE * n.max(1.0) || n.round() < 1.0 {
                c.issue(
                    "grid.cell_size",
                    format!(
                        "the domain extent {extent} along {} is not a whole number of cells of \
                         size {} ({n:.3} cells)",
                        AXES[a], g.cell_size
                    ),
                );
            }
            total *= n.round();
        }
        if total > MAX_CELLS {
            c.issue(
                "grid.cell_size",
                format!("{total:e} cells is more than loam can index ({MAX_CELLS:e})"),
            );
        }
        Some(dim)
    }

    fn check_materials(&self, c: &mut Checker) {
        if self.materials.is_empty() {
            c.issue("materials", "a scene needs at least one material");
        }
        let mut seen = HashSet::new();
        for (i, m) in self.materials.iter().enumerate() {
            let path = format!("materials[{i}]");
            if m.name.trim().is_empty() {
                c.issue(format!("{path}.name"), "must not be empty");
            } else if !seen.insert(m.name.as_str()) {
                c.issue(
                    format!("{path}.name"),
                    format!("duplicate material name {:?}", m.name),
                );
            }
            c.positive(&format!("{path}.density"), m.density);
            c.positive(&format!("{path}.youngs_modulus"), m.youngs_modulus);
            let nu = m.poisson_ratio;
            if c.finite(&format!("{path}.poisson_ratio"), nu) && !(nu > -1.0 && nu < 0.5) {
                c.issue(
                    format!("{path}.poisson_ratio"),
                    format!("must be in (-1, 0.5), got {nu}"),
                );
            }
            let plastic = m.model == ModelKind::J2;
            match m.yield_stress {
                Some(sy) if plastic => {
                    c.positive(&format!("{path}.yield_stress"), sy);
                }
                None if plastic => c.issue(
                    format!("{path}.yield_stress"),
                    "required for model \"j2\" (the uniaxial yield stress, Pa)",
                ),
                Some(_) => c.issue(
                    format!("{path}.yield_stress"),
                    "only used by model \"j2\"; remove it or change the model",
                ),
                None => {}
            }
            if let Some(hardening) = m.hardening {
                let hpath = format!("{path}.hardening");
                if !plastic {
                    c.issue(
                        hpath,
                        "only used by model \"j2\"; remove it or change the model",
                    );
                } else if c.finite(&hpath, hardening) && hardening < 0.0 {
                    c.issue(hpath, format!("must be zero or positive, got {hardening}"));
                }
            }
        }
    }

    fn check_body(
        &self,
        c: &mut Checker,
        path: &str,
        body: &BodySpec,
        dim: Option<usize>,
        names: &[&str],
    ) {
        if !names.contains(&body.material.as_str()) {
            let mut known: Vec<String> = Vec::new();
            for n in names.iter().map(|n| format!("{n:?}")) {
                if !known.contains(&n) {
                    known.push(n);
                }
            }
            c.issue(
                format!("{path}.material"),
                format!(
                    "unknown material {:?}; expected one of {}",
                    body.material,
                    known.join(", ")
                ),
            );
        }
        let ppc = body.particles_per_cell;
        if !(1..=MAX_PARTICLES_PER_CELL).contains(&ppc) {
            c.issue(
                format!("{path}.particles_per_cell"),
                format!("must be between 1 and {MAX_PARTICLES_PER_CELL}, got {ppc}"),
            );
        }
        let Some(dim) = dim else { return };
        if let Some(v) = &body.velocity {
            c.coords(&format!("{path}.velocity"), v, dim);
        }
        if check_shape(c, &format!("{path}.shape"), &body.shape, dim) {
            self.check_inside_domain(c, path, &body.shape);
        }
    }

    /// A body's bounding box must lie in the domain (walls included).
    fn check_inside_domain(&self, c: &mut Checker, path: &str, shape: &BodyShape) {
        let (lo, hi) = (&self.grid.lo, &self.grid.hi);
        if lo.len() != hi.len() || lo.iter().chain(hi).any(|x| !x.is_finite()) {
            return; // the grid's own issues are reported
        }
        let (blo, bhi) = shape.bounds();
        let inside = (0..lo.len()).all(|a| {
            let tol = GEOMETRY_TOLERANCE * (hi[a] - lo[a]).abs();
            blo[a] >= lo[a] - tol && bhi[a] <= hi[a] + tol
        });
        if !inside {
            c.issue(
                path,
                format!(
                    "body lies outside the grid domain: its bounding box {} is not inside {}",
                    Interval(&blo, &bhi),
                    Interval(lo, hi)
                ),
            );
        }
    }

    fn check_boundaries(&self, c: &mut Checker, dim: Option<usize>) {
        let Some(dim) = dim else { return };
        for (name, axis, _, wall) in self.boundaries.faces() {
            if wall.is_some() && axis >= dim {
                c.issue(
                    format!("boundaries.{name}"),
                    format!("the grid is {dim}D; it has no {} faces", AXES[axis]),
                );
            }
        }
    }

    fn check_solver(&self, c: &mut Checker) {
        let s = &self.solver;
        if let Transfer::Flip { alpha } = s.transfer
            && c.finite("solver.transfer.alpha", alpha)
            && !(0.0..=1.0).contains(&alpha)
        {
            c.issue(
                "solver.transfer.alpha",
                format!("must be in [0, 1], got {alpha}"),
            );
        }
        match s.time_step {
            TimeStep::Fixed { dt } => {
                c.positive("solver.time_step.dt", dt);
            }
            TimeStep::Adaptive { cfl, max_dt } => {
                if c.finite("solver.time_step.cfl", cfl) && !(cfl > 0.0 && cfl <= 1.0) {
                    c.issue(
                        "solver.time_step.cfl",
                        format!("must be in (0, 1], got {cfl}"),
                    );
                }
                c.positive("solver.time_step.max_dt", max_dt);
            }
        }
        c.positive("solver.end_time", s.end_time);
    }

    fn check_output(&self, c: &mut Checker) {
        let o = &self.output;
        if o.dir.as_ref().is_some_and(|d| d.as_os_str().is_empty()) {
            c.issue("output.dir", "must not be empty");
        }
        if o.frames == 0 {
            c.issue("output.frames", "must be at least 1, got 0");
        }
        let mut seen = HashSet::new();
        for (i, field) in o.fields.iter().enumerate() {
            if !seen.insert(field) {
                c.issue(
                    format!("output.fields[{i}]"),
                    format!("`{}` is listed twice", field.name()),
                );
            }
        }
    }
}

/// Checks a body shape's own fields; `true` when they are sound.
fn check_shape(c: &mut Checker, path: &str, shape: &BodyShape, dim: usize) -> bool {
    if let Some(only) = shape.dimension().filter(|&d| d != dim) {
        let alternatives = if dim == 3 {
            "use a sphere, a cylinder or a box"
        } else {
            "use a disk, a polygon or a box"
        };
        c.issue(
            format!("{path}.type"),
            format!(
                "a {} is a {only}D shape but the grid is {dim}D; {alternatives}",
                shape.type_name()
            ),
        );
        return false;
    }
    let before = c.issues.len();
    match shape {
        BodyShape::Box { lo, hi } => {
            if c.coords(&format!("{path}.lo"), lo, dim) & c.coords(&format!("{path}.hi"), hi, dim) {
                for a in 0..dim {
                    if hi[a] <= lo[a] {
                        c.issue(
                            format!("{path}.hi[{a}]"),
                            format!("must be greater than lo[{a}] = {}, got {}", lo[a], hi[a]),
                        );
                    }
                }
            }
        }
        BodyShape::Disk { centre, radius } | BodyShape::Sphere { centre, radius } => {
            c.coords(&format!("{path}.centre"), centre, dim);
            c.positive(&format!("{path}.radius"), *radius);
        }
        BodyShape::Cylinder {
            centre,
            axis,
            radius,
            length,
        } => {
            c.coords(&format!("{path}.centre"), centre, dim);
            if c.coords(&format!("{path}.axis"), axis, dim) && axis.iter().all(|&a| a == 0.0) {
                c.issue(format!("{path}.axis"), "must not be the zero vector");
            }
            c.positive(&format!("{path}.radius"), *radius);
            c.positive(&format!("{path}.length"), *length);
        }
        BodyShape::Polygon { vertices } => {
            let path = format!("{path}.vertices");
            if vertices.len() < 3 {
                c.issue(
                    &path,
                    format!(
                        "a polygon needs at least 3 vertices, got {}",
                        vertices.len()
                    ),
                );
            } else {
                let mut ok = true;
                for (i, v) in vertices.iter().enumerate() {
                    ok &= c.coords(&format!("{path}[{i}]"), v, 2);
                }
                if ok && twice_signed_area(vertices) == 0.0 {
                    c.issue(&path, "the polygon has zero area");
                }
            }
        }
    }
    c.issues.len() == before
}

/// Axis names for messages.
const AXES: [&str; 3] = ["x", "y", "z"];

/// Collects issues; the check helpers return `true` when the value passed.
#[derive(Default)]
struct Checker {
    issues: Vec<Issue>,
}

impl Checker {
    fn issue(&mut self, path: impl Into<String>, message: impl Into<String>) {
        self.issues.push(Issue::new(path, message));
    }

    fn finite(&mut self, path: &str, x: f64) -> bool {
        let ok = x.is_finite();
        if !ok {
            self.issue(path, format!("must be a finite number, got {x}"));
        }
        ok
    }

    fn positive(&mut self, path: &str, x: f64) -> bool {
        if !self.finite(path, x) {
            return false;
        }
        let ok = x > 0.0;
        if !ok {
            self.issue(path, format!("must be positive, got {x}"));
        }
        ok
    }

    /// A point or vector of the scene's dimension with finite components.
    fn coords(&mut self, path: &str, v: &[f64], dim: usize) -> bool {
        if v.len() != dim {
            self.issue(
                path,
                format!(
                    "expected {dim} coordinates (the grid is {dim}D), got {}",
                    v.len()
                ),
            );
            return false;
        }
        v.iter().enumerate().fold(true, |ok, (a, &x)| {
            self.finite(&format!("{path}[{a}]"), x) && ok
        })
    }
}

/// A box written `[x0, x1] × [y0, y1] (× [z0, z1])`.
struct Interval<'a>(&'a [f64], &'a [f64]);

impl std::fmt::Display for Interval<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (a, (lo, hi)) in self.0.iter().zip(self.1).enumerate() {
            if a > 0 {
                f.write_str(" × ")?;
            }
            write!(f, "[{lo}, {hi}]")?;
        }
        Ok(())
    }
}
