//! `loam.Simulation`: a scene built and stepped from Python, its particle state read as
//! NumPy arrays.
//!
//! Steps run with the GIL released, in slices of a few milliseconds; between slices the
//! interpreter's signals are checked, so Ctrl-C raises `KeyboardInterrupt` with the state of
//! the last completed step.

use crate::engine::{Engine, GpuEngine, Stepper};
use crate::errors::{refused_scene, scene_error, simulation_error};
use crate::fields::Field;
use crate::scene::expect_scene;
use loam_driver::preflight::{self, MAX_STEPS, MemoryLimit, StepLimit};
use loam_explicit::Solver;
use loam_gpu::{GpuError, GpuSolver};
use loam_implicit::ImplicitSolver;
use loam_scene::{Built, ExplicitPlan, SolverPlan};
use numpy::PyArrayDyn;
use pyo3::exceptions::{PyNotImplementedError, PyValueError};
use pyo3::prelude::*;
use std::time::{Duration, Instant};

/// How long the steps run between two checks for a signal.
const SLICE: Duration = Duration::from_millis(20);

/// A scene's solver and particles, stepped from Python (`loam.Simulation`).
#[pyclass(module = "loam")]
pub struct Simulation {
    engine: Box<dyn Stepper>,
}

/// The solver of an explicit scene, with the checks `loam run` makes before the first step
/// (their warnings go to Python's `warnings`).
fn explicit_solver<const D: usize>(
    py: Python<'_>,
    scene: &loam_scene::Scene,
    built: &Built<D>,
    plan: &ExplicitPlan,
) -> PyResult<Solver<f64, D>> {
    let refused = |msg: String| refused_scene(py, scene.source.as_deref(), &msg);
    let config = built.explicit_config().expect("an explicit plan");
    let solver = Solver::new(config, &built.particles).map_err(|e| refused(e.to_string()))?;
    let limit = StepLimit::new(None, MAX_STEPS);
    let warnings =
        preflight::explicit(built, plan, &solver, &built.particles, limit).map_err(refused)?;
    let warn = py.import("warnings")?;
    for w in warnings {
        warn.call_method1("warn", (w,))?;
    }
    Ok(solver)
}

/// Builds `scene` in `D` dimensions and makes its solver, with the checks `loam run` makes
/// before the first step; explicit steps go to the first GPU adapter with `gpu`.
fn build<const D: usize>(
    py: Python<'_>,
    scene: &loam_scene::Scene,
    gpu: bool,
) -> PyResult<Box<dyn Stepper>> {
    let refused = |msg: String| refused_scene(py, scene.source.as_deref(), &msg);
    let built: Built<D> = scene.build().map_err(|e| scene_error(py, &e))?;
    match &built.plan {
        SolverPlan::Explicit(plan) if gpu => {
            let cpu = explicit_solver(py, scene, &built, plan)?;
            let time_step = cpu.config().time_step;
            let device =
                loam_driver::run::gpu::device(None).map_err(|e| simulation_error(e.to_string()))?;
            let solver = GpuSolver::new(&device, &cpu.config().lift(), &built.particles.lift())
                .map_err(|e| match e {
                    GpuError::Unsupported { .. } | GpuError::Config(_) => refused(e.to_string()),
                    e => simulation_error(e.to_string()),
                })?;
            Ok(Box::new(GpuEngine::new(solver, time_step, built.particles)))
        }
        SolverPlan::Explicit(plan) => {
            let solver = explicit_solver(py, scene, &built, plan)?;
            Ok(Box::new(Engine {
                solver,
                particles: built.particles,
            }))
        }
        SolverPlan::Implicit(_) if gpu => Err(PyValueError::new_err(
            "device: \"gpu\" steps explicit scenes; this scene is implicit (solver.type)",
        )),
        SolverPlan::Implicit(_) => {
            let config = built.implicit_config().expect("an implicit plan");
            let solver = ImplicitSolver::new(config, &built.particles)
                .map_err(|e| refused(e.to_string()))?;
            Ok(Box::new(Engine {
                solver,
                particles: built.particles,
            }))
        }
    }
}

/// Steps `engine` with the caps `plan(engine, steps taken)` until it gives `None` or
/// [`SLICE`] has passed (`Ok(true)` when done), on the rayon pool with its workers awake as
/// `loam run` steps ([`loam_explicit::pool::hold`]).
fn slice(
    engine: &mut dyn Stepper,
    plan: &(impl Fn(&dyn Stepper, usize) -> Option<f64> + Sync),
    taken: &mut usize,
) -> Result<bool, String> {
    let start = Instant::now();
    loam_explicit::pool::hold(|| {
        while start.elapsed() < SLICE {
            let Some(cap) = plan(engine, *taken) else {
                return Ok(true);
            };
            engine.step(cap)?;
            *taken += 1;
        }
        Ok(false)
    })
}

impl Simulation {
    /// Steps with the caps `plan(engine, steps taken)` until it gives `None`, releasing the
    /// GIL and checking for signals between slices of steps.
    fn drive(
        &mut self,
        py: Python<'_>,
        plan: impl Fn(&dyn Stepper, usize) -> Option<f64> + Sync,
    ) -> PyResult<()> {
        let mut taken = 0;
        loop {
            let engine = &mut *self.engine;
            match py.detach(|| slice(engine, &plan, &mut taken)) {
                Ok(true) => return Ok(()),
                Ok(false) => py.check_signals()?,
                Err(msg) => return Err(simulation_error(msg)),
            }
        }
    }

    /// A copy of `field` as a NumPy array.
    fn array<'py>(&self, py: Python<'py>, field: Field) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        (self.engine.field(field))
            .map_err(simulation_error)?
            .into_numpy(py)
    }
}

#[pymethods]
impl Simulation {
    /// Builds `scene` (checked as `loam run` checks it) for stepping on `device`: `"cpu"`,
    /// or `"gpu"` for an explicit scene's steps in f32 on the first GPU adapter (as
    /// `loam run --device gpu`; the state is read back from the device when asked for).
    #[new]
    #[pyo3(signature = (scene, device = "cpu"))]
    fn new(py: Python<'_>, scene: &Bound<'_, PyAny>, device: &str) -> PyResult<Self> {
        let scene = expect_scene(scene)?;
        let gpu = match device {
            "cpu" => false,
            "gpu" => true,
            other => {
                return Err(PyValueError::new_err(format!(
                    "device: expected \"cpu\" or \"gpu\", got {other:?}"
                )));
            }
        };
        let scene = &scene.inner;
        preflight::size(scene, MemoryLimit::new(None))
            .map_err(|msg| refused_scene(py, scene.source.as_deref(), &msg))?;
        let engine = match scene.dim() {
            2 => build::<2>(py, scene, gpu)?,
            _ => build::<3>(py, scene, gpu)?,
        };
        Ok(Self { engine })
    }

    /// Takes `n` steps (explicit) or load steps (implicit).
    #[pyo3(signature = (n = 1))]
    fn step(&mut self, py: Python<'_>, n: i64) -> PyResult<()> {
        let n = usize::try_from(n).map_err(|_| {
            PyValueError::new_err(format!("n: must be a number of steps ≥ 0, got {n}"))
        })?;
        self.drive(py, |_, taken| (taken < n).then_some(f64::INFINITY))
    }

    /// Steps an explicit scene to the time `t` (s): with an adaptive step, the last step is
    /// shortened to end on `t`; with a fixed step Δt, the steps taken are those that end by
    /// `t` (none is shortened). Nothing happens when `t` is not ahead of the time.
    fn advance_to(&mut self, py: Python<'_>, t: f64) -> PyResult<()> {
        if !t.is_finite() {
            return Err(PyValueError::new_err(format!(
                "t: must be a finite time, got {t}"
            )));
        }
        if let Err(msg) = self.engine.cap_towards(t) {
            return Err(PyNotImplementedError::new_err(msg));
        }
        self.drive(py, |engine, _| engine.cap_towards(t).ok().flatten())
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.engine.time()
    }

    /// Steps (explicit) or load steps (implicit) completed.
    #[getter]
    fn steps(&self) -> usize {
        self.engine.steps()
    }

    /// The load factor reached by an implicit scene (0 … 1), None for an explicit one.
    #[getter]
    fn load_factor(&self) -> Option<f64> {
        self.engine.load_factor()
    }

    /// The dimension, 2 or 3.
    #[getter]
    fn dim(&self) -> usize {
        self.engine.dim()
    }

    /// Particle positions, N × D (m); a copy.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        self.array(py, Field::Positions)
    }

    /// Particle velocities, N × D (m/s); a copy.
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        self.array(py, Field::Velocities)
    }

    /// Sets every particle's velocity (m/s) from an N × D float64 array of finite values,
    /// e.g. an initial velocity field made in Python; the next step starts from them. Raises
    /// `TypeError` for another dtype, `ValueError` naming `velocities` for another shape or
    /// a value that is not finite, and `SimulationError` where the solver takes no velocities
    /// (a quasi-static implicit run; the GPU).
    #[setter]
    fn set_velocities(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let (n, d) = (self.engine.material().data.len(), self.engine.dim());
        let v = crate::arrays::matrix(value, "velocities", [n, d])?;
        self.engine.set_velocities(&v).map_err(simulation_error)
    }

    /// Cauchy stress, N × 3 × 3 (Pa, tension positive); a copy.
    #[getter]
    fn stress<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        self.array(py, Field::Stress)
    }

    /// Deformation gradient, N × D × D; a copy.
    #[getter]
    fn deformation_gradient<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        self.array(py, Field::DeformationGradient)
    }

    /// Pore pressure, N (Pa, compression positive); a copy.
    #[getter]
    fn pore_pressure<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        self.array(py, Field::PorePressure)
    }

    /// Particle masses, N (kg; per metre of thickness in 2D); a copy.
    #[getter]
    fn masses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        self.array(py, Field::Mass)
    }

    /// Material index of every particle, N (its place in the scene's materials); a copy.
    #[getter]
    fn material<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<i64>>> {
        self.engine.material().into_numpy(py)
    }

    /// `Simulation(<dim>D, step <steps>, t = <time>)`.
    fn __repr__(&self) -> String {
        format!(
            "Simulation({}D, step {}, t = {})",
            self.engine.dim(),
            self.engine.steps(),
            self.engine.time()
        )
    }
}
