//! The checks of a coupled (u–p) scene: the `[pore_fluid]` section, the hydraulic keys of
//! the materials, `[solver.consolidation]`, and that every drained face bounds the soil.

use super::Checker;
use crate::schema::{Face, LinearKind, PermeabilityLaw, Scene, SolverKind, TimeScheme};
use loam_implicit::flow::TimeIntegration;
use loam_implicit::linear::Preconditioner;

/// The hydraulic keys of a material: only used with a `[pore_fluid]`.
const HYDRAULIC_KEYS: [&str; 3] = ["hydraulic_conductivity", "biot_coefficient", "porosity"];

/// The most time steps a consolidation schedule may make (a first step typed in the wrong
/// unit, or no growth over a long horizon).
const MAX_CONSOLIDATION_STEPS: f64 = 1e6;

impl Scene {
    /// The field checks of a coupled scene (the first stage of validation).
    pub(super) fn check_pore_fluid(&self, c: &mut Checker, dim: Option<usize>) {
        let Some(fluid) = &self.pore_fluid else {
            for (i, m) in self.materials.iter().enumerate() {
                for key in HYDRAULIC_KEYS.iter().filter(|k| m.has(k)) {
                    c.issue(
                        format!("materials[{i}].{key}"),
                        "only used with a [pore_fluid] section (a saturated soil in an \
                         implicit run); remove it or add the section",
                    );
                }
            }
            if self.solver.consolidation.is_some() {
                c.issue(
                    "solver.consolidation",
                    "only used with a [pore_fluid] section; remove it or add the section",
                );
            }
            if (self.solver.linear.as_ref()).is_some_and(|l| {
                l.kind.is_iterative() && l.preconditioner == Some(Preconditioner::Block)
            }) {
                c.issue(
                    "solver.linear.preconditioner",
                    "\"block\" splits the unknowns into displacements and pore pressures and \
                     needs a [pore_fluid] section; use \"ilu0\" or \"amg\" for the solid alone",
                );
            }
            return;
        };
        if self.solver.kind != SolverKind::Implicit {
            c.issue(
                "pore_fluid",
                "a saturated soil (u–p coupling) needs the implicit solver: set \
                 solver.type = \"implicit\"",
            );
            return;
        }
        if self.solver.newmark_dt.is_some() {
            c.issue(
                "solver.newmark_dt",
                "a coupled (u–p) run is quasi-static; remove newmark_dt or the [pore_fluid] \
                 section",
            );
        }
        c.positive("pore_fluid.unit_weight", fluid.unit_weight);
        if let Some(k) = fluid.bulk_modulus {
            c.positive("pore_fluid.bulk_modulus", k);
        }
        if let Some(dim) = dim {
            self.check_inflow(c, dim);
            self.check_water_table(c, dim);
            let mut seen = Vec::new();
            for (i, face) in fluid.drained.iter().enumerate() {
                let path = format!("pore_fluid.drained[{i}]");
                if face.axis_side().0 >= dim {
                    c.issue(
                        path,
                        format!("the grid is {dim}D; it has no face {}", face.name()),
                    );
                } else if seen.contains(face) {
                    c.issue(path, format!("\"{}\" is listed twice", face.name()));
                } else {
                    seen.push(*face);
                }
            }
        }
        let used: Vec<&str> = self.bodies.iter().map(|b| b.material.as_str()).collect();
        for (i, m) in self.materials.iter().enumerate() {
            if !used.contains(&m.name.as_str()) || m.model == loam_core::ModelKind::Fluid {
                continue;
            }
            if !m.has("hydraulic_conductivity") {
                c.issue(
                    format!("materials[{i}].hydraulic_conductivity"),
                    "required with a [pore_fluid] section (Darcy's hydraulic conductivity k, \
                     m/s) for every material a body uses",
                );
            }
            if fluid.bulk_modulus.is_some() && !m.has("porosity") {
                c.issue(
                    format!("materials[{i}].porosity"),
                    "required with pore_fluid.bulk_modulus (the storage of the pore water is \
                     n / K_w)",
                );
            } else if fluid.permeability == PermeabilityLaw::KozenyCarman && !m.has("porosity") {
                c.issue(
                    format!("materials[{i}].porosity"),
                    "required with pore_fluid.permeability = \"kozeny_carman\" (the porosity \
                     n₀ at which the hydraulic conductivity is k)",
                );
            }
        }
        self.check_coupled_solver(c);
    }

    /// The water table lies inside the grid, on the last axis.
    /// `[[pore_fluid.inflow]]` (each surface and a finite rate) and
    /// `[[pore_fluid.drained_surface]]` (each surface).
    fn check_inflow(&self, c: &mut Checker, dim: usize) {
        let inflow = self.pore_fluid.as_ref().map_or(&[][..], |f| &f.inflow);
        for (i, q) in inflow.iter().enumerate() {
            let path = format!("pore_fluid.inflow[{i}]");
            super::check_surface(c, &path, q.face, (&q.lo, &q.hi), dim);
            c.finite(&format!("{path}.rate"), q.rate);
        }
        let drains = self
            .pore_fluid
            .as_ref()
            .map_or(&[][..], |f| &f.drained_surface);
        for (i, d) in drains.iter().enumerate() {
            let path = format!("pore_fluid.drained_surface[{i}]");
            super::check_surface(c, &path, d.face, (&d.lo, &d.hi), dim);
        }
    }

    fn check_water_table(&self, c: &mut Checker, dim: usize) {
        let Some(z) = self.pore_fluid.as_ref().and_then(|f| f.water_table) else {
            return;
        };
        let path = "pore_fluid.water_table";
        if !c.finite(path, z) || self.grid.lo.len() != dim {
            return;
        }
        let (lo, hi) = (self.grid.lo[dim - 1], self.grid.hi[dim - 1]);
        let axis = ["x", "y", "z"][dim - 1];
        if z > hi {
            c.issue(
                path,
                format!(
                    "{z} m is above the grid (grid.hi {axis} = {hi} m): the drained ground \
                     surface of a saturated soil is the top face, a water table above it \
                     needs the water above the soil modelled; lower it to {hi} or less"
                ),
            );
        } else if z < lo {
            c.issue(
                path,
                format!("{z} m is below the grid (grid.lo {axis} = {lo} m)"),
            );
        }
    }

    /// The consolidation schedule, and a linear solver for the coupled system.
    fn check_coupled_solver(&self, c: &mut Checker) {
        let s = &self.solver;
        if let Some(k) = &s.consolidation {
            let dt_ok = c.positive("solver.consolidation.time_step", k.time_step);
            let end_ok = c.positive("solver.consolidation.end_time", k.end_time);
            let growth_ok = c.finite("solver.consolidation.growth", k.growth)
                && if k.growth < 1.0 {
                    c.issue(
                        "solver.consolidation.growth",
                        format!("must be at least 1, got {}", k.growth),
                    );
                    false
                } else if k.scheme == TimeScheme::Bdf2 && k.growth > TimeIntegration::MAX_RATIO {
                    c.issue(
                        "solver.consolidation.growth",
                        format!(
                            "scheme = \"bdf2\" takes steps that grow by at most {} (beyond, \
                             it is not zero-stable), got {}",
                            TimeIntegration::MAX_RATIO,
                            k.growth
                        ),
                    );
                    false
                } else {
                    true
                };
            if dt_ok && end_ok && growth_ok {
                let steps = k.steps();
                if steps > MAX_CONSOLIDATION_STEPS {
                    c.issue(
                        "solver.consolidation.time_step",
                        format!(
                            "{} {u} to reach end_time = {} {u} makes {steps:.3e} steps (at \
                             most {MAX_CONSOLIDATION_STEPS:e}); raise time_step or growth",
                            k.time_step,
                            k.end_time,
                            u = k.time_unit.name()
                        ),
                    );
                }
            }
        }
        if let Some(l) = &s.linear {
            let refused = match l.kind {
                LinearKind::Cg | LinearKind::Cholesky => Some(
                    "the coupled system is not symmetric positive definite; use \"lu\", \
                     \"bicgstab\" or \"gmres\"",
                ),
                LinearKind::Bicgstab | LinearKind::Gmres
                    if l.preconditioner == Some(Preconditioner::Amg) =>
                {
                    Some(
                        "the AMG preconditioner is for the displacement block of a solid; use \
                         \"block\" (AMG on the displacements within a block preconditioner), \
                         \"ilu0\" or \"jacobi\" with a pore fluid, or \"lu\"",
                    )
                }
                _ => None,
            };
            if let Some(msg) = refused {
                c.issue("solver.linear", msg);
            }
        }
    }

    /// The second-stage check of a coupled scene: every drained face has particles within a
    /// cell of it (else the face drains nothing: the soil does not reach it). `nearest[face]`
    /// is the smallest distance of a particle to each face, indexed by `Face as usize`.
    pub(crate) fn drained_face_issues(&self, nearest: &[f64; 6]) -> Vec<super::Issue> {
        let mut c = Checker::default();
        let Some(fluid) = &self.pore_fluid else {
            return c.issues;
        };
        let h = self.grid.cell_size;
        for (i, face) in fluid.drained.iter().enumerate() {
            let d = nearest[*face as usize];
            if d > h {
                c.issue(
                    format!("pore_fluid.drained[{i}]"),
                    format!(
                        "no body reaches face {} (the nearest particle is {d:.4} m from it, \
                         more than a cell): a drained face must bound the soil",
                        face.name()
                    ),
                );
            }
        }
        c.issues
    }
}

/// The distance of point `x` to each face of the box `[lo, hi]`, indexed by `Face as usize`
/// (infinite for the faces of a missing axis).
pub(crate) fn face_distances<const D: usize>(x: &[f64; D], lo: &[f64], hi: &[f64]) -> [f64; 6] {
    let mut d = [f64::INFINITY; 6];
    for face in [
        Face::XMin,
        Face::XMax,
        Face::YMin,
        Face::YMax,
        Face::ZMin,
        Face::ZMax,
    ] {
        let (axis, side) = face.axis_side();
        if axis < D {
            d[face as usize] = if side == 0 {
                x[axis] - lo[axis]
            } else {
                hi[axis] - x[axis]
            };
        }
    }
    d
}
