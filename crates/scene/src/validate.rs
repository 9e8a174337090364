//! Field-by-field validation of a parsed scene.
//!
//! [`Scene::validate`] collects every problem it finds, each naming the field path and what
//! was expected, so one `loam check` shows them all. Checks run in two stages: the fields
//! (ranges, finiteness, coordinate counts, names, the grid, which keys the solver family
//! uses) and then, only when the fields are sound, what depends on the grid and the
//! particles (every body must produce particles, every constraint box must hold a grid node,
//! every point load must find its particles).

use crate::error::{Issue, SceneError};
use crate::geometry::twice_signed_area;
use crate::schema::{
    BodyShape, BodySpec, FosSpec, InitialStressSpec, MaterialSpec, RotationSpec, Scene, SolverKind,
};
use loam_core::constitutive::Elasticity;
use loam_core::{ModelKind, TimeStep, Transfer, WallKind};
use loam_implicit::TangentMethod;
use std::collections::HashSet;

mod contact;
mod material_keys;
mod pore_fluid;

/// Tolerance, relative to the domain size, for a body's bounding box to stick out of the
/// domain and for the domain to be a whole number of cells.
const GEOMETRY_TOLERANCE: f64 = 1e-9;

/// The most grid cells a scene may ask for (keeps index arithmetic far from overflow and
/// catches a cell size typed in the wrong unit).
const MAX_CELLS: f64 = (1u64 << 32) as f64;

/// The most particles per cell along one axis.
const MAX_PARTICLES_PER_CELL: u32 = 8;

/// Tolerance, relative to the cell size, for a grid node to lie in a constraint box (the
/// solver's, [`loam_core::NodeConstraint::contains`]).
const CONSTRAINT_TOLERANCE: f64 = 1e-9;

impl Scene {
    /// Checks every field, without generating particles (the first half of
    /// [`Scene::validate`]).
    pub fn check_fields(&self) -> Result<(), SceneError> {
        self.issues_to_result(self.field_issues())
    }

    /// Checks every field and the particle generation; the `from_*` loaders call it.
    pub fn validate(&self) -> Result<(), SceneError> {
        let mut issues = self.field_issues();
        if issues.is_empty() {
            issues = match self.dim() {
                2 => self.generation_issues::<2>(),
                3 => self.generation_issues::<3>(),
                _ => Vec::new(),
            };
        }
        self.issues_to_result(issues)
    }

    /// The second stage on sound fields of dimension `D`: particle generation, then
    /// [`Scene::placement_issues`].
    fn generation_issues<const D: usize>(&self) -> Vec<Issue> {
        let mut count = 0usize;
        let mut nearest = [f64::INFINITY; 6];
        let (lo, hi) = (&self.grid.lo, &self.grid.hi);
        let mut issues = self.seed::<D>(|_, x| {
            count += 1;
            let d = pore_fluid::face_distances(&x, lo, hi);
            nearest.iter_mut().zip(d).for_each(|(n, d)| *n = n.min(d));
        });
        issues.extend(self.placement_issues::<D>(count));
        issues.extend(self.drained_face_issues(&nearest));
        issues
    }

    /// What depends on the grid nodes and the particles (the fields must be sound and of
    /// dimension `D`; `particles` is the number generated): every constraint box holds a
    /// grid node of the domain, every point load asks for no more particles than there are.
    pub(crate) fn placement_issues<const D: usize>(&self, particles: usize) -> Vec<Issue> {
        let mut c = Checker::default();
        let g = &self.grid;
        let h = g.cell_size;
        for (i, k) in self.constraints.iter().enumerate() {
            // Node indices k·h from grid.lo inside [lo − ε, hi + ε], within the domain.
            let tol = CONSTRAINT_TOLERANCE * h;
            let has_node = (0..D).all(|a| {
                let cells = ((g.hi[a] - g.lo[a]) / h).round();
                let first = ((k.lo[a] - tol - g.lo[a]) / h).ceil().max(0.0);
                let last = ((k.hi[a] + tol - g.lo[a]) / h).floor().min(cells);
                first <= last
            });
            if !has_node {
                c.issue(
                    format!("constraints[{i}]"),
                    format!(
                        "the box contains no grid node; node spacing is h = {h} m from grid.lo"
                    ),
                );
            }
        }
        for (i, l) in self.point_loads.iter().enumerate() {
            if l.count > particles {
                c.issue(
                    format!("point_loads[{i}].count"),
                    format!(
                        "asks for {} particles but the scene has {particles}",
                        l.count
                    ),
                );
            }
        }
        c.issues
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
        self.check_constraints(&mut c, dim);
        self.check_point_loads(&mut c, dim);
        self.check_tractions(&mut c, dim);
        self.check_probes(&mut c, dim);
        self.check_friction(&mut c, dim);
        self.check_obstacles(&mut c, dim);
        self.check_solver(&mut c);
        self.check_pore_fluid(&mut c, dim);
        self.check_output(&mut c);
        if let Some(fos) = &self.fos {
            check_fos_values(&mut c, fos);
            c.issues.extend(self.fos_issues());
        }
        c.issues
    }

    /// Checks that `loam fos` can search this scene's factor of safety (whether or not it has
    /// a `[fos]` section): a quasi-static implicit scene, loaded by gravity or point loads that
    /// ramp over the load steps (no body with an initial stress), with a material whose
    /// strength can be reduced. [`Scene::validate`] makes the same checks when the scene has
    /// a `[fos]` section.
    pub fn check_fos(&self) -> Result<(), SceneError> {
        self.issues_to_result(self.fos_issues())
    }

    /// The problems [`Scene::check_fos`] reports.
    fn fos_issues(&self) -> Vec<Issue> {
        let mut c = Checker::default();
        if self.solver.kind != SolverKind::Implicit {
            c.issue(
                "solver.type",
                "the factor of safety is searched over quasi-static implicit runs; expected \
                 \"implicit\"",
            );
        }
        if self.solver.newmark_dt.is_some() {
            c.issue(
                "solver.newmark_dt",
                "the factor of safety is searched over quasi-static runs; remove it",
            );
        }
        if self.pore_fluid.is_some() {
            c.issue(
                "pore_fluid",
                "the factor of safety is searched over runs of the soil's skeleton (drained, \
                 or undrained through an undrained strength); a coupled run is not searched \
                 yet",
            );
        }
        let gravity = self
            .loads
            .gravity
            .as_ref()
            .is_some_and(|g| g.iter().any(|&x| x != 0.0));
        if !gravity && self.point_loads.is_empty() && self.tractions.is_empty() {
            c.issue(
                "loads.gravity",
                "nothing loads the scene: the search reduces the strength until the loading \
                 fails, so it needs gravity, [[point_loads]] or [[tractions]]",
            );
        }
        for (i, body) in self.bodies.iter().enumerate() {
            if body.initial_stress.is_some() {
                c.issue(
                    format!("bodies[{i}].initial_stress"),
                    "the factor of safety is searched over gravity switch-on, and with an \
                     initial stress gravity acts in full from the first load step (the first \
                     step is the elastic reference of the failure test); remove it",
                );
            }
        }
        if !self.materials.iter().any(|m| {
            matches!(
                m.model,
                ModelKind::MohrCoulomb | ModelKind::DruckerPrager | ModelKind::J2
            )
        }) {
            c.issue(
                "materials",
                "no material has a strength to reduce: expected a \"mohr_coulomb\", \
                 \"drucker_prager\" or \"j2\" material (the elastic models, \"fluid\" and \
                 \"modified_cam_clay\", whose strength comes from its state, have no c, φ or \
                 σ_y to divide)",
            );
        }
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
            check_material(c, &path, m);
        }
    }
}

/// The problems with one material's keys (without its name), under the field path `path`.
pub(crate) fn material_issues(path: &str, m: &MaterialSpec) -> Vec<Issue> {
    let mut c = Checker::default();
    check_material(&mut c, path, m);
    c.issues
}

/// Checks the keys of one material: the density, which keys its model takes and their ranges
/// (declared in [`material_keys`]), and the rules between keys.
fn check_material(c: &mut Checker, path: &str, m: &MaterialSpec) {
    c.positive(&format!("{path}.density"), m.density);
    let sound = material_keys::check_keys(c, path, m);
    let ok = |key: &str| sound.contains(&key);
    // ψ ≤ φ.
    if let Some(psi) = m.dilation_angle.filter(|_| ok("dilation_angle")) {
        let phi = m.friction_angle.filter(|_| ok("friction_angle"));
        let bound = phi.unwrap_or(90.0);
        if !(0.0..=bound).contains(&psi) || (phi.is_none() && psi >= 90.0) {
            let shown = phi.map_or_else(String::new, |phi| format!(" = [0, {phi}]"));
            c.issue(
                format!("{path}.dilation_angle"),
                format!("must be in [0, friction_angle]{shown} degrees, got {psi}"),
            );
        }
    }
    // 0 ≤ σ_t ≤ c cot φ.
    if let Some(t) = m.tension_cutoff.filter(|_| ok("tension_cutoff")) {
        let tpath = format!("{path}.tension_cutoff");
        let phi = m.friction_angle.filter(|_| ok("friction_angle"));
        let cohesion = if m.cohesion.is_none() || ok("cohesion") {
            Some(m.cohesion.unwrap_or(0.0))
        } else {
            None
        };
        match (phi, cohesion) {
            (Some(phi), Some(coh)) => {
                // The apex c cot φ, with room for round-off when it is written out.
                let apex = coh / phi.to_radians().tan();
                if !(t >= 0.0 && t <= apex * (1.0 + 1e-12)) {
                    // Six significant digits: cot 45° is not exactly 1 in floats.
                    let apex = format!("{apex:.5e}").parse().unwrap_or(apex);
                    c.issue(
                        tpath,
                        format!(
                            "must be in [0, c cot φ] = [0, {apex}] Pa (the apex, which is \
                             the default), got {t}"
                        ),
                    );
                }
            }
            _ if t < 0.0 => c.issue(tpath, format!("must be zero or positive, got {t}")),
            _ => {}
        }
    }
    // κ < λ.
    if let (Some(lambda), Some(kappa)) = (m.lambda, m.kappa)
        && ok("lambda")
        && ok("kappa")
        && kappa >= lambda
    {
        c.issue(
            format!("{path}.kappa"),
            format!("must be smaller than lambda = {lambda}, got {kappa}"),
        );
    }
}

impl Scene {
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
        let quasi_static =
            self.solver.kind == SolverKind::Implicit && self.solver.newmark_dt.is_none();
        for (key, given) in [
            ("velocity", body.velocity.is_some()),
            ("rotation", body.rotation.is_some()),
            ("velocity_file", body.velocity_file.is_some()),
        ] {
            if given && quasi_static {
                c.issue(
                    format!("{path}.{key}"),
                    "not used by a quasi-static implicit run (it has no inertia); remove it, or \
                     set solver.newmark_dt for implicit dynamics",
                );
            }
        }
        if let Some(file) = &body.velocity_file {
            if file.as_os_str().is_empty() {
                c.issue(format!("{path}.velocity_file"), "must not be empty");
            }
            if body.velocity.is_some() || body.rotation.is_some() {
                c.issue(
                    format!("{path}.velocity_file"),
                    "gives every particle its velocity, so `velocity` and `rotation` cannot be \
                     added to it; remove them or the file",
                );
            }
        }
        let Some(dim) = dim else { return };
        if let Some(v) = &body.velocity {
            c.coords(&format!("{path}.velocity"), v, dim);
        }
        if let Some(r) = &body.rotation {
            self.check_rotation(c, &format!("{path}.rotation"), r, dim);
        }
        if let Some(stress) = &body.initial_stress {
            self.check_initial_stress(c, &format!("{path}.initial_stress"), body, stress, dim);
        } else if (self.materials.iter())
            .any(|m| m.name == body.material && m.model == ModelKind::ModifiedCamClay)
        {
            c.issue(
                format!("{path}.initial_stress"),
                "required for a body of model \"modified_cam_clay\": it has no stiffness at \
                 zero stress (give type = \"geostatic\" with the body under gravity)",
            );
        }
        if check_shape(c, &format!("{path}.shape"), &body.shape, dim) {
            self.check_inside_domain(c, path, &body.shape);
        }
    }

    /// `rotation`: ω a number in 2D and three components in 3D, the centre a point.
    fn check_rotation(&self, c: &mut Checker, path: &str, r: &RotationSpec, dim: usize) {
        let wpath = format!("{path}.angular_velocity");
        match (dim, r.angular_velocity.len()) {
            (2, 1) | (3, 3) => {
                for (a, &w) in r.angular_velocity.iter().enumerate() {
                    let at = if dim == 2 {
                        wpath.clone()
                    } else {
                        format!("{wpath}[{a}]")
                    };
                    c.finite(&at, w);
                }
            }
            (2, n) => c.issue(
                wpath,
                format!(
                    "expected a number in 2D (rad/s, counter-clockwise positive), got {n} \
                     components"
                ),
            ),
            (_, n) => c.issue(
                wpath,
                format!("expected three components [ωx, ωy, ωz] in 3D (rad/s), got {n}"),
            ),
        }
        if let Some(centre) = &r.centre {
            c.coords(&format!("{path}.centre"), centre, dim);
        }
    }

    /// `initial_stress`: gravity along one axis, `geostatic` not on a fluid, `k0` positive,
    /// `surface` finite.
    fn check_initial_stress(
        &self,
        c: &mut Checker,
        path: &str,
        body: &BodySpec,
        stress: &InitialStressSpec,
        dim: usize,
    ) {
        let g = self.loads.gravity.as_deref().unwrap_or(&[]);
        let along = g.iter().filter(|&&x| x != 0.0).count();
        if g.len() == dim && along != 1 {
            c.issue(
                path,
                format!(
                    "needs gravity along one coordinate axis (depth is measured along it), got \
                     loads.gravity = {}",
                    if g.is_empty() {
                        "none".to_owned()
                    } else {
                        Point(g).to_string()
                    }
                ),
            );
        } else if g.is_empty() {
            c.issue(
                path,
                "needs gravity along one coordinate axis; set loads.gravity",
            );
        }
        let fluid = self
            .materials
            .iter()
            .find(|m| m.name == body.material)
            .is_some_and(|m| m.model == ModelKind::Fluid);
        if let InitialStressSpec::Geostatic { k0, .. } = stress {
            if fluid {
                c.issue(
                    format!("{path}.type"),
                    "a fluid carries no shear stress, so its stress at rest is the same in every \
                     direction: use type = \"hydrostatic\"",
                );
            }
            if let Some(k0) = k0 {
                c.positive(&format!("{path}.k0"), *k0);
            }
        }
        if let Some(level) = stress.surface() {
            c.finite(&format!("{path}.surface"), level);
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
            let Some(wall) = wall else { continue };
            if axis >= dim {
                c.issue(
                    format!("boundaries.{name}"),
                    format!("the grid is {dim}D; it has no {} faces", AXES[axis]),
                );
            } else if wall.separable
                && wall.kind != WallKind::Free
                && self.solver.kind == SolverKind::Implicit
            {
                c.issue(
                    format!("boundaries.{name}"),
                    "the implicit solver has no separable walls (it would leave the face \
                     free); remove `separable` for a wall that holds both ways",
                );
            }
        }
    }

    fn check_constraints(&self, c: &mut Checker, dim: Option<usize>) {
        if self.constraints.is_empty() {
            return;
        }
        if self.solver.kind != SolverKind::Implicit {
            c.issue("constraints", IMPLICIT_ONLY_LOADING);
            return;
        }
        let Some(dim) = dim else { return };
        for (i, k) in self.constraints.iter().enumerate() {
            let path = format!("constraints[{i}]");
            if c.coords(&format!("{path}.lo"), &k.lo, dim)
                & c.coords(&format!("{path}.hi"), &k.hi, dim)
            {
                for a in 0..dim {
                    if k.hi[a] < k.lo[a] {
                        c.issue(
                            format!("{path}.hi[{a}]"),
                            format!("must be at least lo[{a}] = {}, got {}", k.lo[a], k.hi[a]),
                        );
                    }
                }
            }
            let mut sized = true;
            for (key, values, unit) in [
                ("displacement", &k.displacement, "m"),
                ("force", &k.force, "N"),
            ] {
                let kpath = format!("{path}.{key}");
                if !values.is_empty() && values.len() != dim {
                    sized = false;
                    c.issue(
                        &kpath,
                        format!(
                            "expected {dim} components (the grid is {dim}D), each a number \
                             ({unit}) or \"free\", got {}",
                            values.len()
                        ),
                    );
                }
                for (a, u) in values.iter().enumerate() {
                    if let Some(u) = *u {
                        c.finite(&format!("{kpath}[{a}]"), u);
                    }
                }
            }
            let number = |v: &[Option<f64>], a: usize| v.get(a).is_some_and(Option::is_some);
            if !sized {
                continue;
            }
            if (0..dim).all(|a| !number(&k.displacement, a) && !number(&k.force, a)) {
                c.issue(
                    &path,
                    "no component is prescribed: give `displacement` (m) or `force` (N) a \
                     number for at least one axis",
                );
            }
            for a in (0..dim).filter(|&a| number(&k.displacement, a) && number(&k.force, a)) {
                c.issue(
                    format!("{path}.force[{a}]"),
                    format!(
                        "axis {a} also has a displacement; a component is either \
                         displacement- or force-controlled (write \"free\" in one of them)"
                    ),
                );
            }
            if k.force.iter().any(Option::is_some)
                && self
                    .solver
                    .newton
                    .is_some_and(|n| n.tangent == TangentMethod::Colour)
            {
                c.issue(
                    format!("{path}.force"),
                    "a force-controlled group needs solver.newton.tangent = \"local\" (the default): \
                     the colour-seeded tangent assumes each unknown moves one node",
                );
            }
            // Force-controlled boxes must not share nodes on the same axis: each is one group.
            for (j, other) in self.constraints.iter().enumerate().take(i) {
                let overlap = (0..dim).all(|b| {
                    k.lo.get(b)
                        .zip(other.hi.get(b))
                        .is_some_and(|(l, h)| l <= h)
                        && other
                            .lo
                            .get(b)
                            .zip(k.hi.get(b))
                            .is_some_and(|(l, h)| l <= h)
                });
                if let Some(a) = (0..dim).find(|&a| number(&k.force, a) && number(&other.force, a))
                    && overlap
                {
                    c.issue(
                        format!("{path}.force[{a}]"),
                        format!(
                            "the box overlaps constraints[{j}], also force-controlled along \
                             axis {a}: each force-controlled box is one rigid group; merge them \
                             or separate the boxes"
                        ),
                    );
                }
            }
        }
    }

    fn check_point_loads(&self, c: &mut Checker, dim: Option<usize>) {
        if self.point_loads.is_empty() {
            return;
        }
        if self.solver.kind != SolverKind::Implicit {
            c.issue("point_loads", IMPLICIT_ONLY_LOADING);
            return;
        }
        for (i, l) in self.point_loads.iter().enumerate() {
            let path = format!("point_loads[{i}]");
            if l.count == 0 {
                c.issue(format!("{path}.count"), "must be at least 1, got 0");
            }
            let Some(dim) = dim else { continue };
            self.check_point_in_domain(c, &format!("{path}.at"), &l.at, dim);
            c.vector(&format!("{path}.force"), &l.force, dim, "components");
        }
    }

    fn check_tractions(&self, c: &mut Checker, dim: Option<usize>) {
        if self.tractions.is_empty() {
            return;
        }
        if self.solver.kind != SolverKind::Implicit {
            c.issue("tractions", IMPLICIT_ONLY_LOADING);
            return;
        }
        let Some(dim) = dim else { return };
        for (i, t) in self.tractions.iter().enumerate() {
            let path = format!("tractions[{i}]");
            check_surface(c, &path, t.face, (&t.lo, &t.hi), dim);
            c.vector(&format!("{path}.traction"), &t.traction, dim, "components");
        }
    }

    fn check_probes(&self, c: &mut Checker, dim: Option<usize>) {
        if self.probes.is_empty() {
            return;
        }
        if self.solver.kind != SolverKind::Implicit {
            c.issue(
                "probes",
                "only recorded by the implicit solver; set solver.type = \"implicit\" (explicit \
                 runs write every particle's history in their frames)",
            );
            return;
        }
        let mut names = HashSet::new();
        for (i, probe) in self.probes.iter().enumerate() {
            let path = format!("probes[{i}]");
            let name = probe.name.clone().unwrap_or_else(|| format!("probe_{i}"));
            if name.is_empty() || name.contains([',', '"', '\n']) {
                c.issue(
                    format!("{path}.name"),
                    format!("{name:?}: a probe's name must be non-empty, without commas, quotes or line breaks (it heads CSV columns)"),
                );
            } else if !names.insert(name.clone()) {
                c.issue(
                    format!("{path}.name"),
                    format!("{name:?} is the name of an earlier probe; names must be unique"),
                );
            }
            if let Some(dim) = dim {
                self.check_point_in_domain(c, &format!("{path}.at"), &probe.at, dim);
            }
        }
    }

    /// `at` (field `path`) has `dim` finite coordinates and lies in the grid's domain.
    fn check_point_in_domain(&self, c: &mut Checker, path: &str, at: &[f64], dim: usize) {
        if !c.coords(path, at, dim) {
            return;
        }
        let (lo, hi) = (&self.grid.lo, &self.grid.hi);
        let grid_ok =
            lo.len() == dim && hi.len() == dim && lo.iter().chain(hi).all(|x| x.is_finite());
        if grid_ok
            && !(0..dim).all(|a| {
                let tol = GEOMETRY_TOLERANCE * (hi[a] - lo[a]).abs();
                at[a] >= lo[a] - tol && at[a] <= hi[a] + tol
            })
        {
            c.issue(
                path,
                format!(
                    "the point {} lies outside the grid domain {}",
                    Point(at),
                    Interval(lo, hi)
                ),
            );
        }
    }

    fn check_solver(&self, c: &mut Checker) {
        let s = &self.solver;
        match s.kind {
            SolverKind::Explicit => {
                for (key, given) in [
                    ("load_steps", s.load_steps.is_some()),
                    ("newmark_dt", s.newmark_dt.is_some()),
                    ("balance_initial_stress", s.balance_initial_stress.is_some()),
                    ("newton", s.newton.is_some()),
                    ("linear", s.linear.is_some()),
                    ("consolidation", s.consolidation.is_some()),
                ] {
                    if given {
                        c.issue(
                            format!("solver.{key}"),
                            "only used by the implicit solver; remove it or set \
                             solver.type = \"implicit\"",
                        );
                    }
                }
                self.check_explicit(c);
            }
            SolverKind::Implicit => {
                for (key, given) in [
                    ("scheme", s.scheme.is_some()),
                    ("transfer", s.transfer.is_some()),
                    ("time_step", s.time_step.is_some()),
                    ("end_time", s.end_time.is_some()),
                    ("device", s.device.is_some()),
                ] {
                    if given {
                        c.issue(
                            format!("solver.{key}"),
                            "only used by the explicit solver (an implicit run is quasi-static: \
                             it applies the loads over solver.load_steps steps, with no time); \
                             remove it or set solver.type = \"explicit\"",
                        );
                    }
                }
                self.check_implicit(c);
            }
        }
    }

    fn check_explicit(&self, c: &mut Checker) {
        let s = &self.solver;
        let shape = self.grid.shape_function;
        if s.transfer == Some(Transfer::Mls) && shape.apic_inverse_inertia().is_none() {
            c.issue(
                "solver.transfer",
                format!(
                    "MLS-MPM needs a B-spline shape function (grid.shape_function = \
                     \"quadratic_bspline\" or \"cubic_bspline\"), got {shape:?}"
                ),
            );
        }
        if let Some(Transfer::Flip { alpha }) = s.transfer
            && c.finite("solver.transfer.alpha", alpha)
            && !(0.0..=1.0).contains(&alpha)
        {
            c.issue(
                "solver.transfer.alpha",
                format!("must be in [0, 1], got {alpha}"),
            );
        }
        match s.time_step {
            None => c.issue("solver.time_step", "required for the explicit solver"),
            Some(TimeStep::Fixed { dt }) => {
                c.positive("solver.time_step.dt", dt);
            }
            Some(TimeStep::Adaptive { cfl, max_dt }) => {
                if c.finite("solver.time_step.cfl", cfl) && !(cfl > 0.0 && cfl <= 1.0) {
                    c.issue(
                        "solver.time_step.cfl",
                        format!("must be in (0, 1], got {cfl}"),
                    );
                }
                c.positive("solver.time_step.max_dt", max_dt);
            }
        }
        match s.end_time {
            None => c.issue(
                "solver.end_time",
                "required for the explicit solver (the simulated time at which the run stops, s)",
            ),
            Some(t) => {
                c.positive("solver.end_time", t);
            }
        }
        // A fixed-step run makes round(end_time / dt) steps: at least one.
        if let (Some(TimeStep::Fixed { dt }), Some(t)) = (s.time_step, s.end_time)
            && dt > 0.0
            && t > 0.0
            && (t / dt).round() < 1.0
        {
            c.issue(
                "solver.time_step.dt",
                format!(
                    "{dt} s is more than twice solver.end_time = {t} s: a fixed-step run makes \
                     round(end_time / dt) steps, here none"
                ),
            );
        }
    }

    fn check_implicit(&self, c: &mut Checker) {
        let s = &self.solver;
        for (i, m) in self.materials.iter().enumerate() {
            if m.model == ModelKind::Fluid {
                c.issue(
                    format!("materials[{i}].model"),
                    "\"fluid\" is for the explicit solver: the implicit path has no rate of \
                     deformation (no viscosity) and a fluid has no shear stiffness, so its \
                     tangent is singular",
                );
            }
            if m.model == ModelKind::DruckerPrager && m.elasticity == Some(Elasticity::Jaumann) {
                c.issue(
                    format!("materials[{i}].elasticity"),
                    "\"jaumann\" is for the explicit solver: its hypoelastic rate update is \
                     integrated over small time steps, not over implicit load steps; use \
                     \"hencky\" (the implicit default)",
                );
            }
        }
        match s.load_steps {
            None => c.issue(
                "solver.load_steps",
                "required for the implicit solver (the number of load steps, at least 1)",
            ),
            Some(0) => c.issue("solver.load_steps", "must be at least 1, got 0"),
            Some(_) => {}
        }
        if let Some(dt) = s.newmark_dt {
            c.positive("solver.newmark_dt", dt);
        }
        if s.balance_initial_stress == Some(true)
            && self.bodies.iter().all(|b| b.initial_stress.is_none())
        {
            c.issue(
                "solver.balance_initial_stress",
                "no body has an initial_stress to balance; give one (e.g. initial_stress = \
                 { type = \"geostatic\", k0 = 0.5 }) or remove the key",
            );
        }
        if let Some(n) = &s.newton {
            c.open_unit("solver.newton.residual_tol", n.residual_tol);
            c.positive("solver.newton.increment_tol", n.increment_tol);
            if n.max_iterations == 0 {
                c.issue("solver.newton.max_iterations", "must be at least 1, got 0");
            }
        }
        if let Some(l) = &s.linear {
            if l.kind.is_iterative() {
                if let Some(tol) = l.rel_tol {
                    c.open_unit("solver.linear.rel_tol", tol);
                }
                if l.max_iterations == Some(0) {
                    c.issue("solver.linear.max_iterations", "must be at least 1, got 0");
                }
            } else {
                for (key, given) in [
                    ("preconditioner", l.preconditioner.is_some()),
                    ("rel_tol", l.rel_tol.is_some()),
                    ("max_iterations", l.max_iterations.is_some()),
                ] {
                    if given {
                        c.issue(
                            format!("solver.linear.{key}"),
                            "only used by the iterative solvers \"cg\", \"bicgstab\" and \"gmres\"; \
                             remove it or change solver.linear.type",
                        );
                    }
                }
            }
        }
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

/// The ranges of the `[fos]` keys.
fn check_fos_values(c: &mut Checker, fos: &FosSpec) {
    for (key, value) in [
        ("tolerance", fos.tolerance),
        ("start", fos.start),
        ("displacement_limit", fos.displacement_limit),
    ] {
        if let Some(v) = value {
            c.positive(&format!("fos.{key}"), v);
        }
    }
    if fos.max_trials == Some(0) {
        c.issue("fos.max_trials", "must be at least 1, got 0");
    }
    if let Some(g) = fos.growth_limit
        && c.finite("fos.growth_limit", g)
        && g <= 1.0
    {
        c.issue(
            "fos.growth_limit",
            format!("must be above 1 (a multiple of the first load step's growth), got {g}"),
        );
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

/// Why `[[constraints]]` and `[[point_loads]]` are rejected in an explicit scene.
const IMPLICIT_ONLY_LOADING: &str = "only applied by the implicit solver; set solver.type = \
                                     \"implicit\" or remove them (the explicit solver takes \
                                     [boundaries] and [loads])";

/// The face and the box of a surface (`[[tractions]]`, `[[pore_fluid.inflow]]`) at `path`:
/// a face of the grid's dimension, corners of `dim` coordinates, `lo ≤ hi`.
fn check_surface(
    c: &mut Checker,
    path: &str,
    face: crate::schema::Face,
    (lo, hi): (&Option<Vec<f64>>, &Option<Vec<f64>>),
    dim: usize,
) {
    if face.axis_side().0 >= dim {
        c.issue(
            format!("{path}.face"),
            format!("{} is not a face of a {dim}D grid", face.name()),
        );
    }
    let lo_ok = lo
        .as_ref()
        .is_none_or(|lo| c.coords(&format!("{path}.lo"), lo, dim));
    let hi_ok = hi
        .as_ref()
        .is_none_or(|hi| c.coords(&format!("{path}.hi"), hi, dim));
    if let (Some(lo), Some(hi), true, true) = (lo, hi, lo_ok, hi_ok)
        && let Some(a) = (0..dim).find(|&a| lo[a] > hi[a])
    {
        c.issue(
            format!("{path}.hi[{a}]"),
            format!("{} is below lo[{a}] = {}", hi[a], lo[a]),
        );
    }
}

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

    /// A number in the open interval (0, 1).
    fn open_unit(&mut self, path: &str, x: f64) -> bool {
        if !self.finite(path, x) {
            return false;
        }
        let ok = x > 0.0 && x < 1.0;
        if !ok {
            self.issue(path, format!("must be in (0, 1), got {x}"));
        }
        ok
    }

    /// A point of the scene's dimension with finite coordinates.
    fn coords(&mut self, path: &str, v: &[f64], dim: usize) -> bool {
        self.vector(path, v, dim, "coordinates")
    }

    /// A vector of the scene's dimension with finite entries (`noun` names them).
    fn vector(&mut self, path: &str, v: &[f64], dim: usize, noun: &str) -> bool {
        if v.len() != dim {
            self.issue(
                path,
                format!(
                    "expected {dim} {noun} (the grid is {dim}D), got {}",
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

/// A point written `(x, y)` or `(x, y, z)`.
struct Point<'a>(&'a [f64]);

impl std::fmt::Display for Point<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("(")?;
        for (a, x) in self.0.iter().enumerate() {
            if a > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{x}")?;
        }
        f.write_str(")")
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
