//! `loam bench`: times the bench scenes of `loam_benches` on this machine.
//!
//! The scenes are scene files (`examples/dambreak_friction.toml`, `examples/cantilever.toml`
//! and `benches/scenes/*.toml`, which `loam run` runs too), built by
//! `loam_benches::explicit_scene` and `loam_benches::implicit_scene`, the same loaders the
//! criterion benches use (`cargo bench -p loam-benches`), so the figures are comparable with
//! `docs/performance.md`. An explicit scene takes [`WARM_UP_STEPS`] untimed steps (scratch
//! allocated, material moving), then the timed steps; the figure is particle-steps per
//! second, `particles · steps / wall time`. The implicit cantilever runs its 50 load steps
//! end to end and reports the wall time (solver set-up included, scene building not) and the
//! Newton iterations. The `tangent` bench times one material point's AD tangent per model
//! ([`tangent`]).

mod tangent;

use loam_benches::{explicit_scene, implicit_scene};
use loam_core::Scalar;
use loam_driver::Outcome;
use loam_explicit::Solver;
use loam_implicit::ImplicitSolver;
use std::path::Path;
use std::time::Instant;

/// Untimed steps before an explicit bench starts its clock.
const WARM_UP_STEPS: usize = 5;

/// One bench: a name, what it is, and its default number of timed steps (explicit scenes).
struct Bench {
    name: &'static str,
    description: &'static str,
    steps: usize,
    /// Timed steps with `--device gpu` (0: not a GPU bench).
    gpu_steps: usize,
}

/// The benches, in the order `loam bench` runs them. The default step counts keep each one
/// to a few seconds on two cores, except `dambreak`, which runs the whole 0.4 s scene.
const BENCHES: [Bench; 18] = [
    Bench {
        name: "dambreak",
        description: "friction dam-break, 6,000 particles, the whole 0.4 s (13,333 steps of 3e-5 s)",
        steps: 13_333,
        gpu_steps: 0,
    },
    Bench {
        name: "dambreak-96k",
        description: "friction dam-break at 4× the resolution, 96,000 particles",
        steps: 200,
        gpu_steps: 0,
    },
    Bench {
        name: "dambreak-1m",
        description: "friction dam-break at 13× the resolution, 1,014,000 particles",
        steps: 20,
        gpu_steps: 0,
    },
    Bench {
        name: "block-2d",
        description: "2D Neo-Hookean block collapse, 101,124 particles",
        steps: 100,
        gpu_steps: 0,
    },
    Bench {
        name: "block-3d",
        description: "3D Neo-Hookean block collapse, 110,592 particles",
        steps: 50,
        gpu_steps: 0,
    },
    Bench {
        name: "column-3d",
        description: "3D Drucker–Prager column collapse on a Coulomb floor, 93,312 particles",
        steps: 50,
        gpu_steps: 0,
    },
    Bench {
        name: "cantilever",
        description: "implicit reference cantilever, 5,760 particles, 50 load steps (f64 only)",
        steps: 0,
        gpu_steps: 0,
    },
    Bench {
        name: "gradient",
        description: "gradient of the friction dam-break by the adjoint / its forward run (f64 only)",
        steps: 1000,
        gpu_steps: 0,
    },
    Bench {
        name: "tangent",
        description: "AD tangent of one 3D material point past yield, per model, vs Hencky's (f64 only)",
        steps: 20_000,
        gpu_steps: 0,
    },
    Bench {
        name: "dambreak-3d-125k",
        description: "3D water dam-break, 125,000 particles (CPU or GPU)",
        steps: 50,
        gpu_steps: 200,
    },
    Bench {
        name: "dambreak-3d-1m",
        description: "3D water dam-break, 1,000,000 particles (CPU or GPU)",
        steps: 10,
        gpu_steps: 200,
    },
    Bench {
        name: "dambreak-3d-1920k",
        description: "3D water dam-break, 1,920,000 particles, JAX-MPM's size (CPU or GPU)",
        steps: 10,
        gpu_steps: 200,
    },
    Bench {
        name: "dambreak-obstacles-3d-123k",
        description: "3D water dam-break against two columns, 122,880 particles (CPU or GPU)",
        steps: 50,
        gpu_steps: 200,
    },
    Bench {
        name: "dambreak-obstacles-3d-1m",
        description: "3D water dam-break against two columns, 983,040 particles (CPU or GPU)",
        steps: 10,
        gpu_steps: 200,
    },
    Bench {
        name: "dambreak-obstacles-3d-1920k",
        description: "3D water dam-break against two columns, 1,920,000 particles (CPU or GPU)",
        steps: 10,
        gpu_steps: 200,
    },
    Bench {
        name: "cylinder-collapse-3d-100k",
        description: "3D Drucker–Prager cylinder collapse, 101,592 particles (CPU or GPU)",
        steps: 50,
        gpu_steps: 200,
    },
    Bench {
        name: "cylinder-collapse-3d-1m",
        description: "3D Drucker–Prager cylinder collapse, 993,208 particles (CPU or GPU)",
        steps: 10,
        gpu_steps: 200,
    },
    Bench {
        name: "cylinder-collapse-3d-2710k",
        description: "3D Drucker–Prager cylinder collapse, 2,712,288 particles (CPU or GPU)",
        steps: 10,
        gpu_steps: 200,
    },
];

/// What one bench measured.
struct Measured {
    name: &'static str,
    precision: &'static str,
    particles: usize,
    /// Timed steps (load steps for the cantilever).
    steps: usize,
    wall: f64,
    /// Newton iterations (implicit only).
    iterations: Option<usize>,
    /// The gradient against its forward run (the gradient bench only).
    ratio: Option<Ratio>,
    /// The bytes of the buffers the GPU solver allocated (GPU benches only).
    device_bytes: Option<u64>,
}

/// A gradient timed against one forward run of the same steps.
struct Ratio {
    /// Wall time of the forward run, seconds.
    forward: f64,
    /// The adjoint's segment length `K`.
    segment: usize,
    /// The gradient's own parts.
    phases: loam_inverse::Phases,
}

impl Measured {
    /// Particle-steps per second (load steps for the implicit bench).
    fn rate(&self) -> f64 {
        self.particles as f64 * self.steps as f64 / self.wall
    }
}

/// The GPU benches' options.
#[derive(Clone, Copy, Debug)]
pub struct GpuBench {
    /// Profiled steps after the timed ones.
    pub profile: Option<usize>,
    /// P2G, where not the adapter's choice.
    pub p2g: Option<loam_driver::run::gpu::P2g>,
}

/// Runs the named benches (all when empty) and prints a table; `steps` overrides the
/// default step counts of the explicit scenes, `f32` runs them in single precision. `gpu`
/// runs them on the GPU (`Some`), with its options. `memory` is the gradient bench's budget for the adjoint (bytes;
/// `None`: the segment length of least memory).
pub fn bench(
    names: &[String],
    list: bool,
    steps: Option<usize>,
    f32: bool,
    gpu: Option<GpuBench>,
    memory: Option<u64>,
    json: Option<&Path>,
) -> Outcome {
    if list {
        for b in &BENCHES {
            println!("{:<w$} {}", b.name, b.description, w = name_width());
        }
        return Outcome::Ok;
    }
    let mut selected = Vec::new();
    for name in names {
        match BENCHES.iter().find(|b| b.name == name) {
            Some(b) => selected.push(b),
            None => {
                let known: Vec<&str> = BENCHES.iter().map(|b| b.name).collect();
                eprintln!(
                    "error: unknown bench `{name}`; expected one of {}",
                    known.join(", ")
                );
                return Outcome::BadInput;
            }
        }
    }
    if selected.is_empty() {
        selected = BENCHES
            .iter()
            .filter(|b| gpu.is_none() || b.gpu_steps > 0)
            .collect();
    }
    if steps == Some(0) {
        eprintln!("error: --steps must be at least 1");
        return Outcome::BadInput;
    }
    match gpu {
        Some(GpuBench {
            profile: Some(0), ..
        }) => {
            eprintln!("error: --profile must be at least 1 step");
            return Outcome::BadInput;
        }
        Some(options) => return gpu_benches(&selected, steps, options, json),
        None => {}
    }
    println!("{} ({} threads)", cpu_model(), rayon::current_num_threads());
    let w = name_width();
    println!(
        "{:<w$} {:>9} {:>10} {:>7} {:>10} {:>14}  note",
        "bench", "precision", "particles", "steps", "wall (s)", "p-steps/s"
    );
    let mut results = Vec::new();
    for b in selected {
        let n = steps.unwrap_or(b.steps);
        if b.name == "tangent" {
            if f32 {
                eprintln!("error: the tangent bench runs in f64 only (drop --f32)");
                return Outcome::BadInput;
            }
            results.extend(tangent_rows(n, w));
            continue;
        }
        let m = match (b.name, f32) {
            ("cantilever", _) => match cantilever() {
                Ok(m) => m,
                Err(e) => {
                    eprintln!("error: cantilever: {e}");
                    return Outcome::Failed;
                }
            },
            ("gradient", true) => {
                eprintln!("error: the gradient bench runs in f64 only (drop --f32)");
                return Outcome::BadInput;
            }
            ("gradient", false) => match gradient(n, memory) {
                Ok(m) => m,
                Err(e @ loam_inverse::AdjointError::Memory { .. }) => {
                    eprintln!("error: --memory: {e}");
                    return Outcome::BadInput;
                }
                Err(e) => {
                    eprintln!("error: gradient: {e}");
                    return Outcome::Failed;
                }
            },
            (_, false) => explicit::<f64>(b.name, n),
            (_, true) => explicit::<f32>(b.name, n),
        };
        let note = match (m.iterations, &m.ratio) {
            (Some(k), _) => format!("{k} Newton iterations"),
            (_, Some(r)) => {
                let p = r.phases;
                format!(
                    "gradient / forward {:.2} (forward {:.3} s; the gradient's forward pass {:.3} s, \
                     recomputation {:.3} s, reverse steps {:.3} s; segments of {} steps; peak RSS {})",
                    m.wall / r.forward,
                    r.forward,
                    p.forward,
                    p.recomputed,
                    p.reverse,
                    r.segment,
                    peak_memory()
                )
            }
            _ => String::new(),
        };
        let row = format!(
            "{:<w$} {:>9} {:>10} {:>7} {:>10.3} {:>14.3e}  {note}",
            m.name,
            m.precision,
            m.particles,
            m.steps,
            m.wall,
            m.rate()
        );
        println!("{}", row.trim_end());
        results.push(m);
    }
    if let Some(path) = json
        && let Err(e) = write_json(path, &results)
    {
        eprintln!("error: cannot write {}: {e}", path.display());
        return Outcome::Failed;
    }
    Outcome::Ok
}

/// Runs [`tangent::measure`] over `evaluations` points and prints one row per model, with
/// its time per point and its ratio to Hencky's (the first row).
fn tangent_rows(evaluations: usize, w: usize) -> Vec<Measured> {
    let costs = tangent::measure(evaluations);
    let hencky = costs[0].per_point_us();
    costs
        .iter()
        .map(|c| {
            let m = Measured {
                name: c.name,
                precision: "f64",
                particles: 1,
                steps: c.evaluations,
                wall: c.wall,
                iterations: None,
                ratio: None,
                device_bytes: None,
            };
            let (way, other) = if c.one_pass {
                ("one 9-lane pass", "nine 1-lane passes")
            } else {
                ("nine 1-lane passes", "one 9-lane pass")
            };
            println!(
                "{:<w$} {:>9} {:>10} {:>7} {:>10.3} {:>14.3e}  {:.2} µs per point, {:.2}× \
                 Hencky's ({way}; {other}: {:.2} µs){}",
                m.name,
                m.precision,
                m.particles,
                m.steps,
                m.wall,
                m.rate(),
                c.per_point_us(),
                c.per_point_us() / hencky,
                c.other_per_point_us(),
                if c.plastic { ", plastic step" } else { "" }
            );
            m
        })
        .collect()
}

/// Times `steps` explicit steps of the bench `name` in precision `T`.
/// The GPU benches (`--device gpu`): the 3D dam-breaks and cylinder collapses in f32 on the
/// first adapter.
fn gpu_benches(
    selected: &[&Bench],
    steps: Option<usize>,
    options: GpuBench,
    json: Option<&Path>,
) -> Outcome {
    if let Some(b) = selected.iter().find(|b| b.gpu_steps == 0) {
        let gpu: Vec<&str> = BENCHES
            .iter()
            .filter(|b| b.gpu_steps > 0)
            .map(|b| b.name)
            .collect();
        eprintln!(
            "error: bench `{}` runs on the CPU only; the GPU benches are {}",
            b.name,
            gpu.join(", ")
        );
        return Outcome::BadInput;
    }
    let device = match loam_driver::run::gpu::device(options.p2g) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("error: {e}");
            return Outcome::Failed;
        }
    };
    println!("{} (P2G: {})", device.name(), device.p2g());
    let w = name_width();
    println!(
        "{:<w$} {:>9} {:>10} {:>7} {:>10} {:>14} {:>11}",
        "bench", "precision", "particles", "steps", "wall (s)", "p-steps/s", "device MiB"
    );
    let mut results = Vec::new();
    for b in selected {
        // The GPU benches' scene files are their names with underscores.
        let scene = b.name.replace('-', "_");
        let run = time_gpu_steps(
            &device,
            b.name,
            &scene,
            steps.unwrap_or(b.gpu_steps),
            options.profile,
        );
        let (m, kernels) = match run {
            Ok(m) => m,
            Err(e) => {
                eprintln!("error: {}: {e}", b.name);
                return Outcome::Failed;
            }
        };
        println!(
            "{:<w$} {:>9} {:>10} {:>7} {:>10.3} {:>14.3e} {:>11.1}",
            m.name,
            m.precision,
            m.particles,
            m.steps,
            m.wall,
            m.rate(),
            m.device_bytes.unwrap_or(0) as f64 / (1u64 << 20) as f64
        );
        if let Some(p) = kernels {
            print_profile(&p);
        }
        results.push(m);
    }
    if let Some(path) = json
        && let Err(e) = write_json(path, &results)
    {
        eprintln!("error: cannot write {}: {e}", path.display());
        return Outcome::Failed;
    }
    Outcome::Ok
}

/// Prints each kernel's device time per step and its share of the step.
fn print_profile(p: &loam_gpu::Profile) {
    let total = p.total();
    println!(
        "  kernels over {} profiled steps: {:.3} ms/step on the device",
        p.steps,
        1e3 * total / p.steps as f64
    );
    for (name, t) in &p.stages {
        println!(
            "    {:<18} {:>9.3} ms/step {:>6.1} %",
            name,
            1e3 * t / p.steps as f64,
            100.0 * t / total
        );
    }
}

/// [`time_steps`] on the GPU: the steps are recorded and submitted in batches, with the
/// stability flags read back every `loam_gpu::CHECK_EVERY` steps and at the end (so the wall
/// time covers the finished work); also the device memory the solver's buffers take, and
/// with `profile`, that many more steps with every kernel timed ([`loam_gpu::GpuSolver::profile`]).
fn time_gpu_steps(
    device: &loam_gpu::Gpu,
    name: &'static str,
    scene: &str,
    steps: usize,
    profile: Option<usize>,
) -> Result<(Measured, Option<loam_gpu::Profile>), loam_gpu::GpuError> {
    let (config, particles) = explicit_scene::<f32, 3>(scene);
    let mut solver = loam_gpu::GpuSolver::new(device, &config, &particles)?;
    solver.advance(WARM_UP_STEPS)?;
    let start = Instant::now();
    solver.advance(steps)?;
    let measured = Measured {
        name,
        precision: "f32",
        particles: particles.len(),
        steps,
        wall: start.elapsed().as_secs_f64(),
        iterations: None,
        ratio: None,
        device_bytes: Some(solver.device_bytes()),
    };
    let kernels = profile.map(|k| solver.profile(k)).transpose()?;
    Ok((measured, kernels))
}

fn explicit<T: Scalar>(name: &'static str, steps: usize) -> Measured {
    match name {
        "dambreak" => time_steps::<T, 2>(name, "dambreak_friction", steps),
        "dambreak-96k" => time_steps::<T, 2>(name, "dambreak_friction_96k", steps),
        "dambreak-1m" => time_steps::<T, 2>(name, "dambreak_friction_1m", steps),
        "block-2d" => time_steps::<T, 2>(name, "block_2d_100k", steps),
        "block-3d" => time_steps::<T, 3>(name, "block_3d_100k", steps),
        "column-3d" => time_steps::<T, 3>(name, "column_3d_93k", steps),
        "dambreak-3d-125k" => time_steps::<T, 3>(name, "dambreak_3d_125k", steps),
        "dambreak-3d-1m" => time_steps::<T, 3>(name, "dambreak_3d_1m", steps),
        "dambreak-3d-1920k" => time_steps::<T, 3>(name, "dambreak_3d_1920k", steps),
        "dambreak-obstacles-3d-123k" => {
            time_steps::<T, 3>(name, "dambreak_obstacles_3d_123k", steps)
        }
        "dambreak-obstacles-3d-1m" => time_steps::<T, 3>(name, "dambreak_obstacles_3d_1m", steps),
        "dambreak-obstacles-3d-1920k" => {
            time_steps::<T, 3>(name, "dambreak_obstacles_3d_1920k", steps)
        }
        "cylinder-collapse-3d-100k" => time_steps::<T, 3>(name, "cylinder_collapse_3d_100k", steps),
        "cylinder-collapse-3d-1m" => time_steps::<T, 3>(name, "cylinder_collapse_3d_1m", steps),
        "cylinder-collapse-3d-2710k" => {
            time_steps::<T, 3>(name, "cylinder_collapse_3d_2710k", steps)
        }
        _ => unreachable!("`{name}` is in BENCHES"),
    }
}

/// Builds the bench scene `scene` (a stem of `loam_benches::EXPLICIT_SCENES`), warms the
/// solver up, then times `steps` steps.
fn time_steps<T: Scalar, const D: usize>(
    name: &'static str,
    scene: &str,
    steps: usize,
) -> Measured {
    let (config, mut particles) = explicit_scene::<T, D>(scene);
    let mut solver = Solver::new(config, &particles).expect("bench scenes are valid");
    let n = particles.len();
    let mut advance = |k: usize| {
        for _ in 0..k {
            solver
                .step(&mut particles, f64::INFINITY)
                .expect("bench scenes are stable");
        }
    };
    // As `loam run` steps: on the pool, its other workers awake.
    let wall = loam_explicit::pool::hold(|| {
        advance(WARM_UP_STEPS);
        let start = Instant::now();
        advance(steps);
        start.elapsed().as_secs_f64()
    });
    Measured {
        name,
        precision: if size_of::<T>() == 4 { "f32" } else { "f64" },
        particles: n,
        steps,
        wall,
        iterations: None,
        ratio: None,
        device_bytes: None,
    }
}

/// One gradient of the friction dam-break over `steps` steps with respect to the friction
/// coefficients of its first four floor segments (the loss: squared distance of every 12th
/// particle, 500 of them, from its initial position at every 10th step), timed against one
/// forward run of the same steps; the adjoint's segments are the longest that fit in
/// `memory` bytes, or those of least memory.
fn gradient(steps: usize, memory: Option<u64>) -> Result<Measured, loam_inverse::AdjointError> {
    use loam_inverse::{Param, TrackedPositions};
    let (config, particles) = explicit_scene::<f64, 2>("dambreak_friction");
    let start = Instant::now();
    let mut solver = Solver::new(config.clone(), &particles)?;
    let mut p = particles.clone();
    loam_explicit::pool::hold(|| -> Result<(), loam_explicit::StepError> {
        for _ in 0..steps {
            solver.step(&mut p, f64::INFINITY)?;
        }
        Ok(())
    })?;
    let forward = start.elapsed().as_secs_f64();
    let tracked: Vec<_> = (0..particles.len())
        .step_by(12)
        .map(|i| (i, particles.x[i]))
        .collect();
    let objective = TrackedPositions {
        targets: (10..=steps)
            .step_by(10)
            .map(|s| (s, tracked.clone()))
            .collect(),
        weight: 1.0,
    };
    let params: Vec<Param> = (0..4).map(Param::Friction).collect();
    let start = Instant::now();
    let checkpoints = memory.map_or(
        loam_inverse::Checkpoints::Least,
        loam_inverse::Checkpoints::Memory,
    );
    let g = loam_inverse::gradient(&config, &particles, steps, &params, &objective, checkpoints)?;
    let wall = start.elapsed().as_secs_f64();
    Ok(Measured {
        name: "gradient",
        precision: "f64",
        particles: particles.len(),
        steps,
        wall,
        iterations: None,
        ratio: Some(Ratio {
            forward,
            segment: g.segment,
            phases: g.phases,
        }),
        device_bytes: None,
    })
}

/// The width of the bench-name column: the longest name, so the columns line up.
fn name_width() -> usize {
    BENCHES.iter().map(|b| b.name.len()).max().unwrap_or(0)
}

/// The peak resident memory of this process so far (`VmHWM` of `/proc/self/status`).
fn peak_memory() -> String {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .map(|l| l["VmHWM:".len()..].trim().to_string())
        })
        .unwrap_or_else(|| "unknown".to_string())
}

/// The reference cantilever (`examples/cantilever.toml`, cpGIMP) end to end, every load
/// step.
fn cantilever() -> Result<Measured, loam_implicit::ImplicitError> {
    let (config, mut particles) = implicit_scene::<2>("cantilever");
    let steps = config.load_steps;
    let start = Instant::now();
    let mut solver = ImplicitSolver::new(config, &particles)?;
    let mut iterations = 0;
    loam_explicit::pool::hold(|| -> Result<(), loam_implicit::ImplicitError> {
        while !solver.finished() {
            iterations += solver.step(&mut particles)?.iterations();
        }
        Ok(())
    })?;
    Ok(Measured {
        name: "cantilever",
        precision: "f64",
        particles: particles.len(),
        steps,
        wall: start.elapsed().as_secs_f64(),
        iterations: Some(iterations),
        ratio: None,
        device_bytes: None,
    })
}

/// The CPU's model name (Linux `/proc/cpuinfo`), or a placeholder elsewhere.
fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".to_string())
}

/// Writes the results as a JSON array.
fn write_json(path: &Path, results: &[Measured]) -> std::io::Result<()> {
    let rows: Vec<serde_json::Value> = results
        .iter()
        .map(|m| {
            serde_json::json!({
                "bench": m.name,
                "precision": m.precision,
                "particles": m.particles,
                "steps": m.steps,
                "wall_s": m.wall,
                "particle_steps_per_s": m.rate(),
                "newton_iterations": m.iterations,
                "gradient_over_forward": m.ratio.as_ref().map(|r| m.wall / r.forward),
                "forward_s": m.ratio.as_ref().map(|r| r.forward),
                "gradient_forward_pass_s": m.ratio.as_ref().map(|r| r.phases.forward),
                "gradient_recomputation_s": m.ratio.as_ref().map(|r| r.phases.recomputed),
                "gradient_reverse_s": m.ratio.as_ref().map(|r| r.phases.reverse),
                "segment_steps": m.ratio.as_ref().map(|r| r.segment),
                "device_bytes": m.device_bytes,
                "threads": rayon::current_num_threads(),
                "cpu": cpu_model(),
            })
        })
        .collect();
    let text = serde_json::to_string_pretty(&rows).map_err(std::io::Error::other)?;
    std::fs::write(path, text)
}
