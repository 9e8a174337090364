//! Turning a scene into the plain `loam-core` structs a solver runs on.

use crate::error::{Issue, SceneError};
use crate::initial::BodyContext;
use crate::output::{Field, WaterTable};
use crate::schema::{
    ConsolidationSpec, DEFAULT_FLUID_GAMMA, DEFAULT_LINEAR_MAX_ITERATIONS, DEFAULT_LINEAR_REL_TOL,
    Device, LinearKind, LinearSpec, MaterialSpec, NewtonSpec, PermeabilityLaw, Scene, SolverKind,
    SolverSpec, TimeScheme, TimeUnit,
};
use loam_core::constitutive::{
    DruckerPrager, Elasticity, Lame, Model, ModifiedCamClay, MohrCoulomb, Preconsolidation, Shear,
};
use loam_core::{
    Boundary, Contact, Grid, Material, ModelKind, NodeConstraint, Particles, PointLoad, Scheme,
    Shape, TimeStep, Transfer,
};
use loam_implicit::NewtonSettings;
use loam_implicit::flow::{Hydraulic, Permeability, PoreFluid, Schedule, TimeIntegration};
use loam_implicit::linear::LinearSolverKind;
use loam_implicit::strength_reduction::SearchSettings;
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
    /// Prescribed displacements of grid nodes, in file order (implicit solver; empty for an
    /// explicit scene).
    pub constraints: Vec<NodeConstraint<D>>,
    /// Forces on particles (implicit solver; empty for an explicit scene): for each
    /// `[[point_loads]]` entry in file order, one load of `force / count` on each of its
    /// `count` particles, nearest first.
    pub point_loads: Vec<PointLoad<D>>,
    /// The particles `[[probes]]` follow, in file order (implicit solver; empty otherwise).
    pub probes: Vec<Probe>,
    /// The `[solver]` section as written (absent settings are `None`).
    pub solver: SolverSpec,
    /// The solver settings with every default filled in: what a front end runs.
    pub plan: SolverPlan,
    /// What to write and where.
    pub output: OutputPlan,
    /// Coulomb friction segments on walls and rigid obstacles (explicit solver; empty
    /// otherwise), for [`loam_core::Contact::apply`].
    pub contact: Contact<f64, D>,
    /// Whether a body starts from an initial stress at rest under gravity
    /// (`initial_stress`): a quasi-static implicit run then applies gravity in full from its
    /// first load step, where that stress balances it, instead of ramping it.
    pub prestressed: bool,
    /// The pore fluid of a coupled (u–p) implicit run (`[pore_fluid]`), with its schedule of
    /// time and load factor; `None` otherwise.
    pub pore_fluid: Option<PoreFluid<D>>,
}

/// A `[[probes]]` entry resolved: its name and the particle it follows.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Probe {
    /// The name (`probe_<index>` by default).
    pub name: String,
    /// The particle nearest the probe's point.
    pub particle: usize,
}

/// The solver to run and its settings, defaults filled in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SolverPlan {
    /// Explicit dynamics (`type = "explicit"`).
    Explicit(ExplicitPlan),
    /// Quasi-static implicit load stepping (`type = "implicit"`).
    Implicit(ImplicitPlan),
}

/// The explicit solver's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExplicitPlan {
    /// Update order within a step.
    pub scheme: Scheme,
    /// Particle–grid velocity transfer.
    pub transfer: Transfer,
    /// Time-step control.
    pub time_step: TimeStep,
    /// Simulated time at which the run stops (s); with a fixed step, see
    /// [`ExplicitPlan::fixed_steps`].
    pub end_time: f64,
    /// Where the steps run.
    pub device: Device,
}

impl ExplicitPlan {
    /// With a fixed step Δt, the number of steps the run makes: `round(end_time / Δt)` (halves
    /// round up), so the run ends within half a step of `end_time` and no step is ever
    /// shortened; `None` with an adaptive step.
    pub fn fixed_steps(&self) -> Option<usize> {
        match self.time_step {
            TimeStep::Fixed { dt } => Some((self.end_time / dt).round() as usize),
            TimeStep::Adaptive { .. } => None,
        }
    }
}

/// The implicit solver's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImplicitPlan {
    /// Number of load steps; gravity, point loads and prescribed displacements reach
    /// `step / load_steps` of their totals after step `step` (prescribed displacements only,
    /// in dynamics).
    pub load_steps: usize,
    /// Newmark time step (s) for implicit dynamics; `None` for a quasi-static run.
    pub newmark_dt: Option<f64>,
    /// Newton and linear-solver settings, as the solver takes them.
    pub newton: NewtonSettings,
    /// Whether the bodies' initial stress is balanced against gravity on the grid
    /// (`solver.balance_initial_stress`, [`loam_implicit::balance`]).
    pub balance_initial_stress: bool,
    /// The consolidation's time steps after the loading (`[solver.consolidation]`; coupled
    /// runs only).
    pub consolidation: Option<ConsolidationSpec>,
}

impl LinearSpec {
    /// The solver's linear method with the iterative solvers' defaults filled in
    /// (preconditioner `ilu0`, `rel_tol` 1e-10, `max_iterations` 1000).
    pub fn solver(&self) -> LinearSolverKind {
        let preconditioner = self.preconditioner.unwrap_or_default();
        let rel_tol = self.rel_tol.unwrap_or(DEFAULT_LINEAR_REL_TOL);
        let max_iter = self.max_iterations.unwrap_or(DEFAULT_LINEAR_MAX_ITERATIONS);
        match self.kind {
            LinearKind::Lu => LinearSolverKind::Lu,
            LinearKind::Cholesky => LinearSolverKind::Cholesky,
            LinearKind::Cg => LinearSolverKind::Cg {
                preconditioner,
                rel_tol,
                max_iter,
            },
            LinearKind::Bicgstab => LinearSolverKind::Bicgstab {
                preconditioner,
                rel_tol,
                max_iter,
            },
            LinearKind::Gmres => LinearSolverKind::Gmres {
                preconditioner,
                rel_tol,
                max_iter,
            },
        }
    }
}

impl NewtonSpec {
    /// The solver's Newton settings, with `linear` as the linear method.
    pub fn settings(&self, linear: LinearSolverKind) -> NewtonSettings {
        NewtonSettings {
            residual_tol: self.residual_tol,
            increment_tol: self.increment_tol,
            max_iterations: self.max_iterations,
            line_search: self.line_search,
            max_cuts: self.max_cuts,
            tangent: self.tangent,
            linear,
        }
    }
}

impl SolverSpec {
    /// The settings with the defaults filled in; `None` when a required one is missing
    /// (`time_step` or `end_time` for the explicit solver, `load_steps` for the implicit
    /// one), which validation reports.
    pub fn plan(&self) -> Option<SolverPlan> {
        Some(match self.kind {
            SolverKind::Explicit => SolverPlan::Explicit(ExplicitPlan {
                scheme: self.scheme.unwrap_or_default(),
                transfer: self.transfer.unwrap_or(Transfer::Apic),
                time_step: self.time_step?,
                end_time: self.end_time?,
                device: self.device.unwrap_or_default(),
            }),
            SolverKind::Implicit => SolverPlan::Implicit(ImplicitPlan {
                load_steps: self.load_steps?,
                newmark_dt: self.newmark_dt,
                balance_initial_stress: self.balance_initial_stress.unwrap_or(false),
                consolidation: self.consolidation,
                newton: self
                    .newton
                    .unwrap_or_default()
                    .settings(self.linear.unwrap_or_default().solver()),
            }),
        })
    }
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
    /// When to write frames, as times from 0 (the initial state).
    ///
    /// Explicit with an adaptive step: the simulated times `end_time · k / frames`,
    /// `k = 0..=frames` (the step before each is shortened to end on it). Explicit with a
    /// fixed step Δt: `step · Δt` for the [frame steps](Built::frame_steps). Implicit: the
    /// load factors `step / load_steps` (a pseudo-time from 0 to 1) of the frame steps; with a
    /// pore fluid, their times in the consolidation's `time_unit`.
    pub fn frame_times(&self) -> Vec<f64> {
        match self.plan {
            SolverPlan::Explicit(ExplicitPlan {
                time_step: TimeStep::Fixed { dt },
                ..
            }) => self
                .frame_steps()
                .into_iter()
                .map(|s| s as f64 * dt)
                .collect(),
            SolverPlan::Explicit(p) => {
                let n = self.output.frames.max(1);
                (0..=n).map(|k| p.end_time * k as f64 / n as f64).collect()
            }
            SolverPlan::Implicit(p) => {
                let unit = self.time_unit().seconds();
                self.frame_steps()
                    .into_iter()
                    .map(|s| match &self.pore_fluid {
                        Some(fluid) => fluid.schedule.time[s] / unit,
                        None => s as f64 / p.load_steps as f64,
                    })
                    .collect()
            }
        }
    }

    /// The explicit solver's configuration of this scene (`None` for an implicit scene): the
    /// one way from a scene to `loam_explicit::Solver`, used by the command line, the
    /// verification cases, the benches and the tests alike.
    pub fn explicit_config(&self) -> Option<loam_explicit::Config<f64, D>> {
        let SolverPlan::Explicit(plan) = self.plan else {
            return None;
        };
        Some(loam_explicit::Config {
            grid: self.grid.clone(),
            shape: self.shape,
            transfer: plan.transfer,
            scheme: plan.scheme,
            boundary: self.boundary,
            contact: self.contact.clone(),
            gravity: self.gravity,
            materials: self.materials.clone(),
            time_step: plan.time_step,
        })
    }

    /// The implicit solver's configuration of this scene (`None` for an explicit scene), as
    /// [`Built::explicit_config`] is for the explicit one; with
    /// `solver.balance_initial_stress`, the balance of the particles' initial stress
    /// ([`loam_implicit::balance_initial_stress`]; left empty where it cannot be computed, a
    /// state the first load step then reports).
    pub fn implicit_config(&self) -> Option<loam_implicit::ImplicitConfig<D>> {
        let SolverPlan::Implicit(plan) = self.plan else {
            return None;
        };
        let mut config = loam_implicit::ImplicitConfig {
            grid: self.grid.clone(),
            shape: self.shape,
            boundary: self.boundary,
            materials: self.materials.clone(),
            gravity: self.gravity,
            constraints: self.constraints.clone(),
            point_loads: self.point_loads.clone(),
            load_steps: self.implicit_steps(),
            newton: plan.newton,
            dynamics: plan.newmark_dt,
            gravity_in_full: self.prestressed,
            min_node_support: loam_implicit::ImplicitConfig::<D>::DEFAULT_MIN_NODE_SUPPORT,
            balance: Vec::new(),
            pore_fluid: self.pore_fluid.clone(),
        };
        if plan.balance_initial_stress
            && let Ok(balance) = loam_implicit::balance_initial_stress(&config, &self.particles)
        {
            config.balance = balance.forces;
        }
        Some(config)
    }

    /// The steps after which frames are written, from 0 (the initial state), where frames
    /// are tied to steps; the last is the final step, and repeats are dropped (a frame after
    /// every step when there are more frames than steps).
    ///
    /// - Implicit: `round(k · load_steps / frames)`, `k = 0..=frames` (halves round up).
    /// - Explicit with a fixed step: `⌈k · N / frames⌉` with `N` the
    ///   [fixed step count](ExplicitPlan::fixed_steps): the first step that reaches or passes
    ///   the frame time `k · N Δt / frames`.
    /// - Explicit with an adaptive step: empty (frames are at [times](Built::frame_times)).
    pub fn frame_steps(&self) -> Vec<usize> {
        let frames = self.output.frames;
        match self.plan {
            SolverPlan::Explicit(p) => p
                .fixed_steps()
                .map_or_else(Vec::new, |n| spread(n, frames, Rounding::Up)),
            SolverPlan::Implicit(_) => spread(self.implicit_steps(), frames, Rounding::Nearest),
        }
    }

    /// The water table of a coupled run, for the excess pore pressure of its output.
    pub fn water_table(&self) -> Option<WaterTable> {
        let fluid = self.pore_fluid.as_ref()?;
        Some(WaterTable {
            height: fluid.water_table?,
            unit_weight: fluid.unit_weight,
        })
    }

    /// The number of steps of an implicit run: `solver.load_steps`, plus the consolidation's
    /// time steps with a pore fluid (0 for an explicit scene).
    pub fn implicit_steps(&self) -> usize {
        match (&self.plan, &self.pore_fluid) {
            (SolverPlan::Explicit(_), _) => 0,
            (_, Some(fluid)) => fluid.schedule.steps(),
            (SolverPlan::Implicit(p), None) => p.load_steps,
        }
    }

    /// The unit of the times a coupled run reads and writes (`solver.consolidation.time_unit`;
    /// seconds otherwise).
    pub fn time_unit(&self) -> TimeUnit {
        match self.plan {
            SolverPlan::Implicit(ImplicitPlan {
                consolidation: Some(k),
                ..
            }) => k.time_unit,
            _ => TimeUnit::S,
        }
    }
}

/// How [`spread`] rounds.
#[derive(Clone, Copy)]
enum Rounding {
    /// To the nearest integer, halves up.
    Nearest,
    /// Up.
    Up,
}

/// `k · steps / frames` rounded, `k = 0..=frames`, without repeats (exact integer rounding).
fn spread(steps: usize, frames: usize, rounding: Rounding) -> Vec<usize> {
    let (n, f) = (steps as u128, frames.max(1) as u128);
    if f >= n {
        return (0..=steps).collect();
    }
    (0..=f)
        .map(|k| match rounding {
            Rounding::Nearest => (2 * k * n + f) / (2 * f),
            Rounding::Up => (k * n).div_ceil(f),
        } as usize)
        .collect()
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
    /// `density · volume` and the body's velocity. Then each body's initial state is set:
    /// its `initial_stress` (with the deformation gradient, history, reference volume and mass
    /// that carry it), its `rotation` (and, for an affine transfer, `C` = the rotation's
    /// velocity gradient) or its `velocity_file`.
    pub fn build<const D: usize>(&self) -> Result<Built<D>, SceneError> {
        if self.dim() != D {
            return Err(SceneError::Dimension {
                scene: self.dim(),
                requested: D,
            });
        }
        self.issues_to_result(self.field_issues())?;

        let materials: Vec<Material<f64>> = self
            .materials
            .iter()
            .map(|m| m.material(self.default_elasticity()))
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
        let mut counts = vec![0usize; self.bodies.len()];
        let mut issues = self.seed::<D>(|body, x| {
            let (id, density, v, hw) = body_data[body];
            particles.push(SVector::from(x), v, density, hw, id);
            counts[body] += 1;
        });
        issues.extend(self.placement_issues::<D>(particles.len()));
        self.issues_to_result(issues)?;
        let plan = self.solver.plan().ok_or_else(|| {
            // Unreachable on a validated scene; kept as an error rather than a panic.
            SceneError::invalid(vec![Issue::new("solver", "a required setting is missing")])
        })?;
        let gravity = vector_or_zero(self.loads.gravity.as_deref());
        let affine = self.affine_transfer();
        let mut issues = Vec::new();
        let mut start = 0;
        let water = self
            .pore_fluid
            .as_ref()
            .and_then(|f| Some((f.unit_weight, f.water_table?)));
        for (b, body) in self.bodies.iter().enumerate() {
            let range = start..start + counts[b];
            start = range.end;
            let context = BodyContext {
                index: b,
                range,
                spacing: self.grid.cell_size / body.particles_per_cell as f64,
                origin: SVector::from_column_slice(&self.grid.lo),
                material: &materials[body_data[b].0 as usize],
                gravity,
                affine,
                water,
            };
            issues.extend(self.initial_state(&context, &mut particles));
        }
        self.issues_to_result(issues)?;
        // Coupled runs start with the water at rest: the hydrostatic pressure of the water
        // table, no excess.
        if let Some((gamma, z)) = water {
            for (p, x) in particles.pore_pressure.iter_mut().zip(&particles.x) {
                *p = gamma * (z - x[D - 1]).max(0.0);
            }
        }

        let mut pore_fluid = self.pore_fluid_plan::<D>(&plan);
        if let Some(fluid) = pore_fluid.as_mut() {
            fluid.inflow = self
                .inflows(&particles)
                .or_else(|issues| self.issues_to_result(issues).map(|()| Vec::new()))?;
            fluid.drains = self
                .surface_drains(&particles)
                .or_else(|issues| self.issues_to_result(issues).map(|()| Vec::new()))?;
        }
        let mut point_loads = self.point_loads(&particles);
        point_loads.extend(
            self.traction_loads(&particles)
                .or_else(|issues| self.issues_to_result(issues).map(|()| Vec::new()))?,
        );

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
            gravity,
            materials,
            material_names,
            constraints: self.node_constraints(),
            point_loads,
            probes: self
                .probes
                .iter()
                .enumerate()
                .map(|(i, p)| Probe {
                    name: p.name.clone().unwrap_or_else(|| format!("probe_{i}")),
                    particle: nearest(&particles.x, &SVector::from_column_slice(&p.at), 1)
                        .first()
                        .copied()
                        .unwrap_or(0),
                })
                .collect(),
            particles,
            solver: self.solver.clone(),
            plan,
            output: self.output_plan(),
            contact: self.contact::<D>(),
            prestressed: self.bodies.iter().any(|b| b.initial_stress.is_some()),
            pore_fluid,
        })
    }

    /// The pore fluid of a coupled scene: per material the mobility `k/γ_w`, Biot's
    /// coefficient (default 1) and the storage `n/K_w` (zero for incompressible water); the
    /// drained faces; and the schedule, `solver.load_steps` undrained steps at `t = 0` and then
    /// the consolidation's time steps.
    fn pore_fluid_plan<const D: usize>(&self, plan: &SolverPlan) -> Option<PoreFluid<D>> {
        let spec = self.pore_fluid.as_ref()?;
        let SolverPlan::Implicit(p) = plan else {
            return None;
        };
        let hydraulic = self
            .materials
            .iter()
            .map(|m| Hydraulic {
                mobility: m.hydraulic_conductivity.unwrap_or(0.0) / spec.unit_weight,
                biot: m.biot_coefficient.unwrap_or(1.0),
                storage: match (spec.bulk_modulus, m.porosity) {
                    (Some(k), Some(n)) => n / k,
                    _ => 0.0,
                },
                permeability: match (spec.permeability, m.porosity) {
                    (PermeabilityLaw::KozenyCarman, Some(porosity)) => {
                        Permeability::KozenyCarman { porosity }
                    }
                    _ => Permeability::Constant,
                },
            })
            .collect();
        let mut drained = [[false; 2]; D];
        for face in &spec.drained {
            let (axis, side) = face.axis_side();
            if axis < D {
                drained[axis][side] = true;
            }
        }
        let schedule = match p.consolidation {
            Some(k) => {
                let unit = k.time_unit.seconds();
                Schedule::geometric(
                    p.load_steps,
                    k.time_step * unit,
                    k.growth,
                    k.end_time * unit,
                )
            }
            None => Schedule {
                time: vec![0.0; p.load_steps + 1],
                load: (0..=p.load_steps)
                    .map(|k| k as f64 / p.load_steps.max(1) as f64)
                    .collect(),
            },
        };
        Some(PoreFluid {
            hydraulic,
            unit_weight: spec.unit_weight,
            water_table: spec.water_table,
            drained,
            stabilisation: spec.stabilisation,
            schedule,
            inflow: Vec::new(),
            drains: Vec::new(),
            time_integration: match p.consolidation.map(|k| k.scheme) {
                Some(TimeScheme::Bdf2) => TimeIntegration::Bdf2,
                _ => TimeIntegration::BackwardEuler,
            },
        })
    }

    /// The settings of `loam fos`'s search: the `[fos]` section with the defaults of
    /// [`SearchSettings::default`] for what it leaves out (all of them without a section).
    pub fn fos_settings(&self) -> SearchSettings {
        let d = SearchSettings::default();
        let f = self.fos.unwrap_or_default();
        SearchSettings {
            start: f.start.unwrap_or(d.start),
            tolerance: f.tolerance.unwrap_or(d.tolerance),
            max_trials: f.max_trials.unwrap_or(d.max_trials),
            growth_limit: f.growth_limit.or(d.growth_limit),
            displacement_limit: f.displacement_limit.or(d.displacement_limit),
        }
    }

    /// The elastic law of a `drucker_prager` material that does not name one: Hencky for the
    /// implicit solver (exact over whole load steps), Jaumann for the explicit one (the model
    /// the GPU runs too).
    pub fn default_elasticity(&self) -> Elasticity {
        match self.solver.kind {
            SolverKind::Implicit => Elasticity::Hencky,
            SolverKind::Explicit => Elasticity::Jaumann,
        }
    }

    /// The constraints as core structs (the fields must be valid and of dimension `D`).
    fn node_constraints<const D: usize>(&self) -> Vec<NodeConstraint<D>> {
        self.constraints
            .iter()
            .map(|k| NodeConstraint {
                lo: std::array::from_fn(|a| k.lo[a]),
                hi: std::array::from_fn(|a| k.hi[a]),
                displacement: std::array::from_fn(|a| k.displacement.get(a).copied().flatten()),
                force: std::array::from_fn(|a| k.force.get(a).copied().flatten()),
            })
            .collect()
    }

    /// Each point load split over its `count` nearest particles (the fields must be valid,
    /// of dimension `D`, and `count` at most the number of particles).
    fn point_loads<const D: usize>(&self, particles: &Particles<f64, D>) -> Vec<PointLoad<D>> {
        let mut loads = Vec::new();
        for l in &self.point_loads {
            let at = SVector::<f64, D>::from_column_slice(&l.at);
            let share: [f64; D] = std::array::from_fn(|a| l.force[a] / l.count as f64);
            loads.extend(
                nearest(&particles.x, &at, l.count)
                    .into_iter()
                    .map(|particle| PointLoad {
                        particle,
                        force: share,
                    }),
            );
        }
        loads
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

    /// The folder a run writes to: `output.dir`, else `out/<scene file stem>` (`out/scene`
    /// for a scene not read from a file), relative to the working directory.
    pub fn output_dir(&self) -> PathBuf {
        let stem = self
            .source
            .as_deref()
            .and_then(|p| p.file_stem())
            .map_or_else(|| "scene".into(), PathBuf::from);
        self.output
            .dir
            .clone()
            .unwrap_or_else(|| PathBuf::from("out").join(stem))
    }

    /// The output settings; `affine` is left out unless the explicit transfer carries `C`.
    fn output_plan(&self) -> OutputPlan {
        OutputPlan {
            dir: self.output_dir(),
            frames: self.output.frames,
            fields: self
                .output
                .fields
                .iter()
                .copied()
                .filter(|&f| f != Field::Affine || self.affine_transfer())
                .filter(|&f| !f.coupled_only() || self.pore_fluid.is_some())
                .collect(),
        }
    }

    /// Whether the scene runs the explicit solver with a transfer that carries the affine
    /// matrix `C` (APIC, TPIC, MLS-MPM).
    fn affine_transfer(&self) -> bool {
        matches!(self.solver.plan(), Some(SolverPlan::Explicit(p)) if p.transfer.is_affine())
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
        // Particles strictly inside an obstacle at t = 0 are not generated (the obstacle owns
        // the overlap, as an earlier body would).
        let contact = self.contact::<D>();
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
                if body.shape.contains(&x)
                    && !earlier.iter().any(|e| e.shape.contains(&x))
                    && contact.penetrated(&x, 0.0).is_none()
                {
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
                        match (b > 0, !self.obstacles.is_empty()) {
                            (true, true) => " and outside earlier bodies and the obstacles",
                            (true, false) => " and outside earlier bodies",
                            (false, true) => " and outside the obstacles",
                            (false, false) => "",
                        }
                    ),
                ));
            }
        }
        issues
    }
}

/// The ids of the `count` points of `x` nearest `at`, nearest first, ties broken by the
/// lower id.
fn nearest<const D: usize>(
    x: &[SVector<f64, D>],
    at: &SVector<f64, D>,
    count: usize,
) -> Vec<usize> {
    let mut order: Vec<(f64, usize)> = x
        .iter()
        .enumerate()
        .map(|(i, x)| ((x - at).norm_squared(), i))
        .collect();
    let by_distance = |a: &(f64, usize), b: &(f64, usize)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
    if count == 0 {
        return Vec::new();
    }
    if count < order.len() {
        order.select_nth_unstable_by(count - 1, by_distance);
        order.truncate(count);
    }
    order.sort_unstable_by(by_distance);
    order.into_iter().map(|(_, i)| i).collect()
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

impl MaterialSpec {
    /// The material this (validated) entry describes; a `drucker_prager` entry that names no
    /// `elasticity` gets `default_elasticity` ([`Scene::default_elasticity`] of its scene).
    pub fn material(&self, default_elasticity: Elasticity) -> Material<f64> {
        let m = self;
        // Validated: the solid models come with E and ν (`j2` with a yield stress,
        // `drucker_prager` with a friction angle), `fluid` with a sound speed or a
        // bulk modulus. Angles are degrees in the file, radians in the model.
        let young = m.youngs_modulus.unwrap_or(f64::NAN);
        let poisson = m.poisson_ratio.unwrap_or(f64::NAN);
        match m.model {
            ModelKind::J2 => Material::j2(
                young,
                poisson,
                m.yield_stress.unwrap_or(f64::INFINITY),
                m.hardening.unwrap_or(0.0),
                m.density,
            ),
            ModelKind::DruckerPrager => Material {
                density: m.density,
                model: Model::DruckerPrager(DruckerPrager {
                    lame: Lame::from_young_poisson(young, poisson),
                    friction_angle: m.friction_angle.unwrap_or(f64::NAN).to_radians(),
                    dilation_angle: m.dilation_angle.unwrap_or(0.0).to_radians(),
                    cohesion: m.cohesion.unwrap_or(0.0),
                    tension_cutoff: m.tension_cutoff,
                    cone: m.cone.unwrap_or_default(),
                    elasticity: m.elasticity.unwrap_or(default_elasticity),
                }),
            },
            ModelKind::MohrCoulomb => Material {
                density: m.density,
                model: Model::MohrCoulomb(MohrCoulomb {
                    lame: Lame::from_young_poisson(young, poisson),
                    friction_angle: m.friction_angle.unwrap_or(f64::NAN).to_radians(),
                    dilation_angle: m.dilation_angle.unwrap_or(0.0).to_radians(),
                    cohesion: m.cohesion.unwrap_or(0.0),
                    tension_cutoff: m.tension_cutoff,
                }),
            },
            ModelKind::ModifiedCamClay => Material {
                density: m.density,
                model: Model::ModifiedCamClay(ModifiedCamClay {
                    lambda: m.lambda.unwrap_or(f64::NAN),
                    kappa: m.kappa.unwrap_or(f64::NAN),
                    critical_state_slope: m.critical_state_slope.unwrap_or(f64::NAN),
                    void_ratio: m.void_ratio.unwrap_or(f64::NAN),
                    shear: match m.shear_modulus {
                        Some(g) => Shear::Modulus(g),
                        None => Shear::Poisson(poisson),
                    },
                    preconsolidation: match m.preconsolidation_pressure {
                        Some(p) => Preconsolidation::Pressure(p),
                        None => Preconsolidation::Ratio(m.ocr.unwrap_or(1.0)),
                    },
                }),
            },
            ModelKind::Fluid => Material::fluid(
                m.fluid_bulk_modulus().unwrap_or(f64::NAN),
                m.gamma.unwrap_or(DEFAULT_FLUID_GAMMA),
                m.viscosity.unwrap_or(0.0),
                m.density,
            ),
            kind => Material::elastic(kind, young, poisson, m.density),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_steps_round_and_drop_repeats() {
        let nearest = |n, f| spread(n, f, Rounding::Nearest);
        assert_eq!(
            nearest(50, 10),
            vec![0, 5, 10, 15, 20, 25, 30, 35, 40, 45, 50]
        );
        // 7 · 1/4 = 1.75, 3.5, 5.25, 7: halves round up.
        assert_eq!(nearest(7, 4), vec![0, 2, 4, 5, 7]);
        assert_eq!(nearest(3, 20), vec![0, 1, 2, 3]);
        assert_eq!(nearest(1, 1), vec![0, 1]);
        assert_eq!(nearest(5, 5), vec![0, 1, 2, 3, 4, 5]);
        // Fixed explicit steps: the first step at or past each frame time.
        let up = |n, f| spread(n, f, Rounding::Up);
        assert_eq!(up(7, 4), vec![0, 2, 4, 6, 7]);
        assert_eq!(up(3, 20), vec![0, 1, 2, 3]);
        // The friction dam-break: 0.4 s at 3e-5 s in 20 frames, 13,333 steps; frame 1 at
        // 0.02 s needs 666.65 steps, so step 667.
        let s = up(13_333, 20);
        assert_eq!((s[1], s[19], s[20], s.len()), (667, 12_667, 13_333, 21));
    }

    #[test]
    fn nearest_points_break_ties_by_the_lower_id() {
        let x: Vec<SVector<f64, 2>> = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.5, 0.0], [3.0, 3.0]]
            .iter()
            .map(|p| SVector::from(*p))
            .collect();
        let at = SVector::zeros();
        assert_eq!(nearest(&x, &at, 1), vec![3]);
        assert_eq!(nearest(&x, &at, 3), vec![3, 0, 1]);
        assert_eq!(nearest(&x, &at, 5), vec![3, 0, 1, 2, 4]);
        assert_eq!(nearest(&x, &at, 0), Vec::<usize>::new());
    }

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
