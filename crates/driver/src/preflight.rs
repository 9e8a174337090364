//! Checks made before a run starts, shared by `loam check` and `loam run`: whether the scene
//! fits in memory (estimated from its fields, before a particle is generated, with the
//! bookkeeping of every frame), whether a fixed time step is stable for the initial state,
//! and whether the run can end: a run of more steps than the step limit
//! ([`StepLimit`], `--max-steps`) is refused, one of very many particle-steps or frames
//! warned about.

use loam_core::tensor::{Tensor, Vector};
use loam_core::{MaterialState, Particles, ShapeFunction, Stencil, TimeStep};
use loam_explicit::Solver;
use loam_scene::{Built, Estimate, ExplicitPlan, Scene, SolverKind};
use nalgebra::Matrix3;
use std::mem::size_of;

/// The most steps a run may take unless `--max-steps` allows more: at the 10⁴–10⁵ steps per
/// second a small scene reaches, 10⁸ steps are hours to days, and a run estimated at more
/// comes from a value typed in the wrong unit (an end time of 10¹² s, a Young's modulus of
/// 10³⁰⁰ Pa whose stability limit is a step of 10⁻¹⁵⁰ s) far more often than from a run
/// anyone means to wait for.
pub const MAX_STEPS: f64 = 1e8;

/// The most steps of one run of an inversion unless `--max-steps` allows more: an inversion
/// runs its scene forward and backward for every gradient, tens to hundreds of times.
pub const MAX_INVERSION_STEPS: f64 = 1e6;

/// Above this many particle-steps a run gets a warning: more than a day at 10⁷
/// particle-steps per second, a good rate for a many-core machine.
const MANY_PARTICLE_STEPS: f64 = 1e12;

/// Above this many frames a run gets a warning (a file each).
const MANY_FRAMES: usize = 100_000;

/// Memory kept per frame of a run, whatever its particle count (bytes, rounded up): the frame
/// point (16), its time or step (16), the collection entry with its file name (about 64), the
/// summary's frame path (about 100) and energy sample (48), and the summary and collection
/// texts written from them (about 300).
const FRAME_BYTES: f64 = 600.0;

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// The most steps a run may take, and where the figure comes from.
#[derive(Clone, Copy, Debug)]
pub struct StepLimit {
    steps: f64,
    /// Where the figure comes from, as a phrase after it.
    source: &'static str,
}

impl StepLimit {
    /// `--max-steps N` when given, else `default` ([`MAX_STEPS`] for a run,
    /// [`MAX_INVERSION_STEPS`] for an inversion).
    pub fn new(flag: Option<u64>, default: f64) -> Self {
        match flag {
            Some(n) => Self {
                steps: n as f64,
                source: "allowed by --max-steps",
            },
            None => Self {
                steps: default,
                source: "a run may take unless --max-steps N allows more",
            },
        }
    }

    /// What is wrong when `steps` (estimated; `what` says of what) is above the limit.
    pub fn exceeded(&self, steps: f64, what: &str) -> Option<String> {
        (steps > self.steps).then(|| {
            format!(
                "about {steps:.2e} steps ({what}), more than the {:.0e} steps {}",
                self.steps, self.source
            )
        })
    }

    /// [`StepLimit::exceeded`] as an error naming `field`.
    pub fn check(&self, steps: f64, field: &str, what: &str) -> Result<(), String> {
        match self.exceeded(steps, what) {
            Some(msg) => Err(format!("{field}: {msg}")),
            None => Ok(()),
        }
    }
}

/// The memory a run may use, in bytes, and where the figure comes from.
#[derive(Clone, Copy, Debug)]
pub struct MemoryLimit {
    bytes: f64,
    /// Where the figure comes from, as a phrase after the amount.
    source: &'static str,
}

impl MemoryLimit {
    /// `--memory-limit GIB` when given, else the memory available now (`MemAvailable` in
    /// `/proc/meminfo`); `None` where neither is known (not Linux, no flag): no check then.
    pub fn new(flag_gib: Option<f64>) -> Option<Self> {
        if let Some(gib) = flag_gib {
            return Some(Self {
                bytes: gib * GIB,
                source: "allowed by --memory-limit",
            });
        }
        let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
        let kib: f64 = meminfo
            .lines()
            .find_map(|l| l.strip_prefix("MemAvailable:"))?
            .trim()
            .trim_end_matches("kB")
            .trim()
            .parse()
            .ok()?;
        Some(Self {
            bytes: kib * 1024.0,
            source: "available (MemAvailable in /proc/meminfo; --memory-limit GIB sets a limit)",
        })
    }
}

impl MemoryLimit {
    /// What is wrong when `bytes` (what `what` needs) is above the limit.
    pub fn exceeded(&self, bytes: f64, what: &str) -> Option<String> {
        (bytes > self.bytes).then(|| {
            format!(
                "{what} need about {}, more than the {} {}",
                gib(bytes),
                gib(self.bytes),
                self.source
            )
        })
    }
}

/// What the size check found.
pub struct Size {
    /// The estimated counts.
    pub estimate: Estimate,
    /// The frames the run writes.
    pub frames: f64,
    /// Estimated peak memory of a run (bytes).
    pub bytes: f64,
    /// The limit it was checked against.
    pub limit: Option<MemoryLimit>,
}

impl Size {
    /// One line: particles, nodes, frames, memory and the limit.
    pub fn describe(&self) -> String {
        let limit = self
            .limit
            .map(|l| format!(" ({} {})", gib(l.bytes), l.source))
            .unwrap_or_default();
        format!("{}{limit}", self.describe_needs())
    }
}

fn gib(bytes: f64) -> String {
    if bytes >= GIB {
        format!("{:.1} GiB", bytes / GIB)
    } else {
        format!("{:.1} MiB", bytes / (1024.0 * 1024.0))
    }
}

/// Estimates the scene's particles, grid nodes and memory from its fields (which must be
/// sound) and refuses a scene whose estimate exceeds the limit, naming `grid.cell_size` (or
/// the particles per cell, when the particles are most of it, or `output.frames`, when the
/// frames' bookkeeping is).
pub fn size(scene: &Scene, limit: Option<MemoryLimit>) -> Result<Size, String> {
    let estimate = scene.estimate();
    let (per_particle, per_node) = match scene.dim() {
        2 => bytes_per_item::<2>(),
        _ => bytes_per_item::<3>(),
    };
    let particles = estimate.particles * per_particle;
    let mut grid = estimate.nodes * per_node;
    if scene.solver.kind == SolverKind::Implicit {
        grid += estimate.body_nodes * implicit_bytes_per_node(scene);
    }
    let frame_count = frames(scene);
    let frames = frame_count * FRAME_BYTES;
    let bytes = particles + grid + frames;
    let size = Size {
        estimate,
        frames: frame_count,
        bytes,
        limit,
    };
    match limit {
        Some(l) if bytes > l.bytes => {
            let field = if frames > particles.max(grid) {
                "output.frames"
            } else if particles > grid {
                "grid.cell_size (and bodies[].particles_per_cell)"
            } else {
                "grid.cell_size"
            };
            let remedy = if field == "output.frames" {
                "write fewer frames"
            } else {
                "use a larger cell size or a smaller domain"
            };
            Err(format!(
                "{field}: the scene needs {}, more than the {} {}; {remedy}",
                size.describe_needs(),
                gib(l.bytes),
                l.source
            ))
        }
        _ => Ok(size),
    }
}

/// The frames a run of the scene writes, from its fields: `output.frames`, or the steps
/// where there are fewer (frames tied to steps, a fixed explicit step or load steps, are
/// written at most once a step).
fn frames(scene: &Scene) -> f64 {
    let s = &scene.solver;
    let frames = scene.output.frames as f64;
    let steps = match (s.kind, s.time_step, s.end_time, s.load_steps) {
        (SolverKind::Explicit, Some(TimeStep::Fixed { dt }), Some(t), _) => (t / dt).round(),
        (SolverKind::Implicit, _, _, Some(n)) => n as f64 + consolidation_steps(scene),
        _ => f64::INFINITY,
    };
    frames.min(steps)
}

/// The time steps of a coupled run's consolidation (`[solver.consolidation]`; zero without).
pub fn consolidation_steps(scene: &Scene) -> f64 {
    scene
        .solver
        .consolidation
        .filter(|_| scene.pore_fluid.is_some())
        .map_or(0.0, |k| k.steps())
}

/// Refuses an implicit run of more steps than `limit`, naming `solver.load_steps` (or
/// `solver.consolidation.time_step` when the consolidation's steps pass it); an explicit
/// run's steps are checked on its initial state, [`explicit`].
pub fn implicit_steps(scene: &Scene, limit: StepLimit) -> Result<(), String> {
    match (scene.solver.kind, scene.solver.load_steps) {
        (SolverKind::Implicit, Some(n)) => {
            limit.check(
                n as f64,
                "solver.load_steps",
                "load steps of the implicit run",
            )?;
            limit.check(
                n as f64 + consolidation_steps(scene),
                "solver.consolidation.time_step",
                "steps of the coupled run (loading and consolidation)",
            )
        }
        _ => Ok(()),
    }
}

impl Size {
    fn describe_needs(&self) -> String {
        format!(
            "about {:.3e} particles and {:.3e} grid nodes, {} frames, {} of memory",
            self.estimate.particles,
            self.estimate.nodes,
            self.frames,
            gib(self.bytes)
        )
    }
}

/// Bytes per particle and per grid node of an explicit run in `f64`: the particle arrays
/// (x, v, a, F, C, σ, m, V₀, half-width, material, state) and the initial positions kept for
/// the displacement field; the solver's per-particle scratch (sort key and order, stencil,
/// new x, v, C); a frame being written (every field, 30 numbers, held about ten times over
/// while vtkio encodes it); per node the grid arrays (mass, velocity, old velocity, active
/// constraints) and the P2G block buffers, which cover each node of an occupied block up to
/// `(6/4)^D` times. Where a size is not public it is rounded up. Measured: the peak resident
/// memory of a 250,000-particle 2D run and a 64,000-particle 3D run (two frames each) was
/// 0.77 and 0.87 of this estimate.
fn bytes_per_item<const D: usize>() -> (f64, f64) {
    let (vector, tensor) = (size_of::<Vector<f64, D>>(), size_of::<Tensor<f64, D>>());
    let particle = 5 * vector
        + 2 * tensor
        + size_of::<Matrix3<f64>>()
        + 2 * size_of::<f64>()
        + size_of::<u32>()
        + size_of::<MaterialState<f64>>();
    let scratch = 2 * size_of::<u32>() + size_of::<Stencil<f64, D>>() + 2 * vector + tensor;
    let frame = 30 * 8 * 10;
    let accumulator = size_of::<f64>() + 2 * vector;
    let overlap = 1.5f64.powi(D as i32);
    let node = size_of::<f64>() + 2 * vector + 16;
    (
        (particle + scratch + frame) as f64,
        node as f64 + overlap * accumulator as f64,
    )
}

/// Bytes per grid node in the bodies' reach for the implicit solver's tangent: `D` unknowns
/// a node, each coupled to the `D` unknowns of `(2b − 1)^D` nodes (`b` the support width), 16
/// bytes a non-zero (value and index), and four times that for a direct factorisation's
/// fill-in. A rough figure: the fill-in depends on the ordering.
fn implicit_bytes_per_node(scene: &Scene) -> f64 {
    let d = scene.dim() as i32;
    let b = scene.grid.shape_function.support_width() as f64;
    let nonzeros = (d * d) as f64 * (2.0 * b - 1.0).powi(d);
    4.0 * 16.0 * nonzeros
}

/// The explicit solver's checks of the initial state: a fixed step above the stability limit
/// `h / (c + |v|)` is an error naming `solver.time_step.dt`, the limit and the particle and
/// material that set it; so is a run of more steps than `max_steps` (its estimate: the fixed
/// step count, or `end_time` over the first adaptive step, and at least a step per frame),
/// naming `solver.end_time` (or `output.frames`, when the frames set the count); a run of
/// very many particle-steps or frames gets warnings (returned).
pub fn explicit<const D: usize>(
    built: &Built<D>,
    plan: &ExplicitPlan,
    solver: &Solver<f64, D>,
    particles: &Particles<f64, D>,
    max_steps: StepLimit,
) -> Result<Vec<String>, String> {
    let (limit, particle, wave_speed, speed) = solver.stability_limit(particles);
    let material = particles
        .material
        .get(particle)
        .and_then(|&m| built.material_names.get(m as usize))
        .map_or_else(String::new, |n| format!(" of material \"{n}\""));
    let dt = match plan.time_step {
        TimeStep::Fixed { dt } => {
            if dt > limit {
                return Err(format!(
                    "solver.time_step.dt: {dt:e} s is above the stability limit {limit:.3e} s of \
                     the initial state, h / (c + |v|) at particle {particle}{material} \
                     (c = {wave_speed:.4e} m/s, |v| = {speed:.4e} m/s); use dt ≤ {limit:.3e} s \
                     or an adaptive step"
                ));
            }
            dt
        }
        TimeStep::Adaptive { cfl, max_dt } => (cfl * limit).min(max_dt),
    };
    let frames = built.output.frames;
    let steps = explicit_steps(plan, solver, particles);
    let set_by = match plan.time_step {
        TimeStep::Fixed { .. } => "solver.time_step.dt".to_owned(),
        TimeStep::Adaptive { .. } => format!(
            "the adaptive step, at least: set by the stability limit {limit:.3e} s of the \
             initial state at particle {particle}{material}"
        ),
    };
    let what = format!("Δt = {dt:.3e} s, {set_by}");
    if matches!(plan.time_step, TimeStep::Adaptive { .. }) && frames as f64 > steps {
        // Each frame ends a step: the frames set the count.
        max_steps.check(
            frames as f64,
            "output.frames",
            "a step at least per frame of an adaptive run",
        )?;
    }
    max_steps.check(steps, "solver.end_time", &what)?;
    let mut warnings = Vec::new();
    let particle_steps = steps * particles.len() as f64;
    if particle_steps > MANY_PARTICLE_STEPS {
        warnings.push(format!(
            "solver.end_time: about {steps:.2e} steps ({what}), {particle_steps:.2e} \
             particle-steps: this run may take days"
        ));
    }
    if frames > MANY_FRAMES {
        warnings.push(format!(
            "output.frames: {frames} frames, a file each of {} particles",
            particles.len()
        ));
    }
    Ok(warnings)
}

/// The estimated number of steps of an explicit run: the fixed step count
/// `round(end_time / Δt)` (as a float, so that a step of 10⁻³⁰⁰ s counts 10³⁰⁰ steps), or
/// `end_time` over the first adaptive step.
pub fn explicit_steps<const D: usize>(
    plan: &ExplicitPlan,
    solver: &Solver<f64, D>,
    particles: &Particles<f64, D>,
) -> f64 {
    match plan.time_step {
        TimeStep::Fixed { dt } => (plan.end_time / dt).round(),
        TimeStep::Adaptive { cfl, max_dt } => {
            plan.end_time / (cfl * solver.stability_limit(particles).0).min(max_dt)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_memory_limit_comes_from_the_flag_or_the_machine() {
        let flag = MemoryLimit::new(Some(2.0)).expect("a limit");
        assert_eq!(flag.bytes, 2.0 * GIB);
        assert_eq!(flag.source, "allowed by --memory-limit");
        // On Linux /proc/meminfo gives the memory available now.
        if cfg!(target_os = "linux") {
            let machine = MemoryLimit::new(None).expect("MemAvailable is read");
            assert!(machine.bytes > 0.0 && machine.source.contains("MemAvailable"));
        }
    }

    #[test]
    fn per_item_sizes_cover_the_particle_arrays_and_the_grid_arrays() {
        // A 2D particle holds at least x, v, a (2 each), F, C (4 each), σ (9), m, V₀,
        // half-width (2) and the state (10) in f64: 38 numbers; a node at least its mass and
        // two velocities: 5 numbers.
        let (particle, node) = bytes_per_item::<2>();
        assert!(particle >= 38.0 * 8.0 && node >= 5.0 * 8.0);
        let (particle3, node3) = bytes_per_item::<3>();
        assert!(particle3 > particle && node3 > node);
    }
}
