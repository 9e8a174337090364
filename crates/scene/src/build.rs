//! Turning a scene into the plain `loam-core` structs a solver runs on.

use crate::error::{Issue, SceneError};
use crate::output::Field;
use crate::schema::{Scene, SolverSpec};
use loam_core::{Boundary, Grid, Material, ModelKind, Particles, Shape};
use nalgebra::SVector;
use std::path::PathBuf;

/// A scene ready to run: the grid, materials, particles and settings as core types.
#[derive(Clone, Debug)]
pub struct Built<const D: usize> {
    /// The grid over the domain, padded by the shape function's ghost cells.
    pub grid: Grid<D>,
    /// The shape-function family.
    pub shape: Shape,
    /// Wall conditions on the faces of the domain.
    pub boundary: Boundary<D>,
    /// Gravitational acceleration.
    pub gravity: SVector<f64, D>,
    /// The material table, in file order; particles refer to it by index.
    pub materials: Vec<Material<f64>>,
    /// The materials' names (same order as `materials`).
    pub material_names: Vec<String>,
    /// The particles of all bodies, body by body in file order.
    pub particles: Particles<f64, D>,
    /// Time-integration settings.
    pub solver: SolverSpec,
    /// What to write and where.
    pub output: OutputPlan,
}

/// The output settings with the folder resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct OutputPlan {
    /// Output folder (`output.dir`, or `out/<scene file stem>`; `out/scene` for a scene not
    /// read from a file).
    pub dir: PathBuf,
    /// Number of frames after the initial one.
    pub frames: usize,
    /// Particle fields to write.
    pub fields: Vec<Field>,
}

impl<const D: usize> Built<D> {
    /// The simulated times of the frames to write: `0` (the initial state) and then
    /// `output.frames` equal intervals up to `end_time`, `frames + 1` times in all.
    pub fn frame_times(&self) -> Vec<f64> {
        let n = self.output.frames.max(1);
        (0..=n)
            .map(|k| self.solver.end_time * k as f64 / n as f64)
            .collect()
    }
}

impl Scene {
    /// The scene's dimension, 2 or 3 (the number of coordinates of `grid.lo`); dispatch on
    /// it to call [`Scene::build`] with the matching `D`.
    pub fn dim(&self) -> usize {
        self.grid.lo.len()
    }

    /// Builds the grid, materials, boundary and particles. `D` must equal [`Scene::dim`].
    ///
    /// Particles fill each body on a regular sub-grid: in a cell `[x₀, x₀ + h]` the points
    /// are `x₀ + (k + ½) h / ppc`, `k = 0..ppc` per axis, kept when inside the body's shape
    /// and not inside an earlier body's (the first body listed owns an overlap). Each gets
    /// the volume `(h / ppc)^D`, the half-width `h / (2 ppc)` per axis, the mass
    /// `density · volume` and the body's velocity.
    pub fn build<const D: usize>(&self) -> Result<Built<D>, SceneError> {
        if self.dim() != D {
            return Err(SceneError::Dimension {
                scene: self.dim(),
                requested: D,
            });
        }
        self.issues_to_result(self.field_issues())?;

        let materials = self
            .materials
            .iter()
            .map(|m| match (m.model, m.yield_stress) {
                (ModelKind::J2, Some(yield_stress)) => Material::j2(
                    m.youngs_modulus,
                    m.poisson_ratio,
                    yield_stress,
                    m.hardening.unwrap_or(0.0),
                    m.density,
                ),
                // Validated: `j2` always comes with a yield stress.
                (kind, _) => Material::elastic(kind, m.youngs_modulus, m.poisson_ratio, m.density),
            })
            .collect();
        let material_names: Vec<String> = self.materials.iter().map(|m| m.name.clone()).collect();
        // Per body: (material id, density, velocity, half-width); names were validated.
        let body_data: Vec<(u32, f64, SVector<f64, D>, SVector<f64, D>)> = self
            .bodies
            .iter()
            .map(|b| {
                let id = material_names
                    .iter()
                    .position(|n| *n == b.material)
                    .unwrap_or_default();
                let v = vector_or_zero(b.velocity.as_deref());
                let hw = SVector::repeat(self.grid.cell_size / (2.0 * b.particles_per_cell as f64));
                (id as u32, self.materials[id].density, v, hw)
            })
            .collect();

        let mut particles = Particles::default();
        let issues = self.seed::<D>(|body, x| {
            let (id, density, v, hw) = body_data[body];
            particles.push(SVector::from(x), v, density, hw, id);
        });
        self.issues_to_result(issues)?;

        let mut boundary = Boundary::all(Default::default());
        for (_, axis, side, wall) in self.boundaries.faces() {
            if let Some(wall) = wall.filter(|_| axis < D) {
                boundary.walls[axis][side] = wall;
            }
        }
        Ok(Built {
            grid: self.grid::<D>(),
            shape: self.grid.shape_function,
            boundary,
            gravity: vector_or_zero(self.loads.gravity.as_deref()),
            materials,
            material_names,
            particles,
            solver: self.solver.clone(),
            output: self.output_plan(),
        })
    }

    /// The core grid (the fields must be valid and of dimension `D`).
    fn grid<const D: usize>(&self) -> Grid<D> {
        let g = &self.grid;
        let cells = std::array::from_fn(|a| ((g.hi[a] - g.lo[a]) / g.cell_size).round() as usize);
        Grid::new(
            std::array::from_fn(|a| g.lo[a]),
            cells,
            g.cell_size,
            g.shape_function.ghost_cells(),
        )
    }

    fn output_plan(&self) -> OutputPlan {
        let stem = self
            .source
            .as_deref()
            .and_then(|p| p.file_stem())
            .map_or_else(|| "scene".into(), PathBuf::from);
        OutputPlan {
            dir: self
                .output
                .dir
                .clone()
                .unwrap_or_else(|| PathBuf::from("out").join(stem)),
            frames: self.output.frames,
            fields: self.output.fields.clone(),
        }
    }

    /// Generates the particle positions body by body, calling `visit(body index, x)` for
    /// each, and returns an issue for every body that generates none. The fields must be
    /// valid and of dimension `D`.
    pub(crate) fn seed<const D: usize>(
        &self,
        mut visit: impl FnMut(usize, [f64; D]),
    ) -> Vec<Issue> {
        let grid = self.grid::<D>();
        let mut issues = Vec::new();
        for (b, body) in self.bodies.iter().enumerate() {
            let ppc = body.particles_per_cell as usize;
            let spacing = grid.h / ppc as f64;
            // Sub-cells whose centres can fall inside the body's bounding box.
            let (blo, bhi) = body.shape.bounds();
            let first: [usize; D] = std::array::from_fn(|a| {
                ((blo[a] - grid.lo[a]) / spacing).floor().max(0.0) as usize
            });
            let end = std::array::from_fn(|a| {
                let n = grid.cells[a] * ppc;
                (((bhi[a] - grid.lo[a]) / spacing).ceil().max(0.0) as usize).min(n)
            });
            let earlier = &self.bodies[..b];
            let mut count = 0usize;
            for_each_index(first, end, |m| {
                let x: [f64; D] =
                    std::array::from_fn(|a| grid.lo[a] + (m[a] as f64 + 0.5) * spacing);
                if body.shape.contains(&x) && !earlier.iter().any(|e| e.shape.contains(&x)) {
                    count += 1;
                    visit(b, x);
                }
            });
            if count == 0 {
                issues.push(Issue::new(
                    format!("bodies[{b}]"),
                    format!(
                        "generates no particles: none of the particle positions (spaced \
                         {spacing}) lies inside its shape{}",
                        if b > 0 {
                            " and outside earlier bodies"
                        } else {
                            ""
                        }
                    ),
                ));
            }
        }
        issues
    }
}

/// A validated optional vector of `D` components, zero when absent.
fn vector_or_zero<const D: usize>(v: Option<&[f64]>) -> SVector<f64, D> {
    v.map_or_else(SVector::zeros, SVector::from_column_slice)
}

/// Calls `f` for every multi-index `m` with `first[a] ≤ m[a] < end[a]`, axis 0 fastest.
fn for_each_index<const D: usize>(
    first: [usize; D],
    end: [usize; D],
    mut f: impl FnMut([usize; D]),
) {
    if (0..D).any(|a| first[a] >= end[a]) {
        return;
    }
    let mut m = first;
    loop {
        f(m);
        let mut a = 0;
        loop {
            m[a] += 1;
            if m[a] < end[a] {
                break;
            }
            m[a] = first[a];
            a += 1;
            if a == D {
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_box_is_visited_once_per_index_axis_zero_fastest() {
        let mut seen = Vec::new();
        for_each_index([1, 2], [3, 4], |m| seen.push(m));
        assert_eq!(seen, vec![[1, 2], [2, 2], [1, 3], [2, 3]]);
        let mut n = 0;
        for_each_index([0, 5, 0], [4, 5, 2], |_| n += 1);
        assert_eq!(n, 0);
    }
}
