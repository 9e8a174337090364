//! `loam`: run, check, verify and bench MPM scenes, and search their factor of safety.
//!
//! Exit codes: 0 success; 1 a run or a verification failed (a run on the GPU also when no
//! GPU adapter is found); 2 the input (scene file, arguments) is invalid, or the scene would
//! not fit in memory or run stably, or uses a feature the GPU path lacks (with `--device gpu`);
//! 130 a run or a `loam fos` search was interrupted by a signal (its summary says
//! `interrupted`). A closed stdout or stderr pipe ends the process by SIGPIPE, as for other
//! Unix tools.

mod bench;
mod verify;

use loam_driver::{Outcome, check, fos, invert, material, preflight, run};

use clap::{Parser, Subcommand};
// The CPU commands (`gradient`, `invert`, `verify`) run on the rayon pool with its other
// workers awake, as `run` does: see `loam_explicit::pool`.
use loam_explicit::pool::hold;
use std::path::PathBuf;
use std::process::ExitCode;

/// loam: a differentiable Material Point Method solver for geomechanics.
#[derive(Parser, Debug)]
#[command(name = "loam", version, about, long_about = None)]
struct Cli {
    /// Worker threads, at most 1024 (default: all cores). Results are bitwise identical for
    /// any count.
    #[arg(long, global = true)]
    threads: Option<usize>,
    /// Memory a run may use, in GiB (default: the memory available now, MemAvailable in
    /// /proc/meminfo). `run` and `check` refuse a scene whose estimate exceeds it.
    #[arg(long, global = true, value_name = "GIB")]
    memory_limit: Option<f64>,
    /// The most steps a run may take (default 1e8; 1e6 for each run of an inversion).
    /// `run` and `check` refuse a scene estimated at more (an end time or a stiffness in the
    /// wrong unit), `fos` a scene with more load steps per trial, `gradient`, `invert` and
    /// `check` an inversion file.
    #[arg(long, global = true, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    max_steps: Option<u64>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run a scene and write ParaView output (.vtu frames + .pvd) and a JSON summary.
    Run {
        /// Scene file (.toml or .json); not with --resume.
        #[arg(required_unless_present = "resume")]
        scene: Option<PathBuf>,
        /// Output folder (overrides the scene's `output.dir`).
        #[arg(long, conflicts_with = "resume")]
        out: Option<PathBuf>,
        /// No progress display and no Newton table.
        #[arg(long)]
        quiet: bool,
        /// Seconds between progress lines when stderr is not a terminal (a bar is drawn
        /// when it is).
        #[arg(long, default_value_t = 5.0, value_name = "SECONDS")]
        progress_every: f64,
        /// Explicit runs: save the state every N steps in OUT/checkpoint/ (the latest only),
        /// so the run can be continued with --resume.
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
        checkpoint_every: Option<u64>,
        /// Continue the run whose output folder is DIR from its checkpoint, with the scene
        /// recorded there.
        #[arg(long, value_name = "DIR", conflicts_with = "scene")]
        resume: Option<PathBuf>,
        /// Explicit runs: where the steps run, overriding the scene's `solver.device`; `gpu`
        /// runs them in f32 on the first GPU adapter (Vulkan, Metal or DX12).
        #[arg(long, value_enum)]
        device: Option<Device>,
        /// Runs on the GPU: how P2G adds into the grid, instead of the adapter's choice
        /// (native f32 atomics where it has them, else the gather); `gather` gives the same
        /// bits on every run.
        #[arg(long, value_enum)]
        p2g: Option<run::gpu::P2g>,
    },
    /// Factor of safety by strength reduction: run the scene's quasi-static loading with
    /// c and tan φ (and tan ψ) of every Mohr–Coulomb and Drucker–Prager material divided by a
    /// trial factor F (σ_y of J2), bisect F on failure (a load step that does not converge),
    /// and write fos.json and fos.png; settings from the scene's [fos] section.
    Fos {
        /// Scene file (.toml or .json), implicit and quasi-static.
        scene: PathBuf,
        /// Output folder (default: the scene's `output.dir`).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Stop when the bracket [stable, failed] of F is this narrow (default: the scene's
        /// `fos.tolerance`, else 0.01).
        #[arg(long, allow_negative_numbers = true)]
        tolerance: Option<f64>,
        /// No table of trials.
        #[arg(long)]
        quiet: bool,
    },
    /// Element test: drive one material point through the laboratory paths of FILE
    /// (drained/undrained triaxial, oedometer, isotropic, simple shear) and write
    /// element.csv and plots (compression positive, kPa).
    Material {
        /// Element-test file (.toml or .json).
        file: PathBuf,
        /// Output folder (default: the file's `output_dir`, or out/<file stem>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// No summary line.
        #[arg(long)]
        quiet: bool,
    },
    /// Validate a scene file and estimate its size, memory and steps (or validate an
    /// inversion file, its scene and observations): exit 0 if it can run, 2 with the
    /// problems otherwise.
    Check {
        /// Scene file (.toml or .json).
        scene: PathBuf,
    },
    /// Back-analysis: the loss of an inversion file and its gradient with respect to every
    /// parameter, by the discrete adjoint.
    Gradient {
        /// Inversion file (.toml).
        file: PathBuf,
        /// Also print, per parameter, the forward-mode dual derivative, central finite
        /// differences and a Taylor test; exit 1 when the adjoint and the dual differ, or
        /// agree but differ from a converged central difference.
        #[arg(long)]
        check: bool,
        /// Memory the adjoint may keep (checkpoints and one traced segment), such as 512MB or
        /// 2GiB: the longest segments that fit, so the fewest steps are run twice (default:
        /// the segment length of least memory, or the file's `segment`).
        #[arg(long, value_name = "SIZE", value_parser = parse_size)]
        memory: Option<u64>,
        /// Also write the loss, the parameters and dL/dθ to this JSON file, every number to
        /// the last bit (the printed table rounds them to 11 digits).
        #[arg(long, value_name = "PATH")]
        json: Option<PathBuf>,
    },
    /// Back-analysis: recover the parameters of an inversion file by optimisation, writing
    /// the history (CSV, JSON, plots), the recovered scene and a checkpoint.
    Invert {
        /// Inversion file (.toml).
        file: PathBuf,
        /// Output folder (default out/<file stem>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Continue from the checkpoint in the output folder.
        #[arg(long)]
        resume: bool,
        /// Memory the adjoint may keep per gradient, as for `loam gradient --memory`.
        #[arg(long, value_name = "SIZE", value_parser = parse_size)]
        memory: Option<u64>,
    },
    /// Run verification cases against analytical solutions.
    Verify {
        /// Cases to run (default: all).
        cases: Vec<String>,
        /// List the cases and exit.
        #[arg(long)]
        list: bool,
        /// Write the results as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Folder for CSV files and plots.
        #[arg(long, default_value = "out/verify")]
        out: PathBuf,
        /// Run the reduced sizes used by the test suite (seconds instead of minutes).
        #[arg(long)]
        reduced: bool,
        /// Where the explicit runs step: `gpu` runs the cases that can (default: all of them)
        /// in f32 on the first GPU adapter, against the same references and tolerances.
        #[arg(long, value_enum, default_value_t = Device::Cpu)]
        device: Device,
    },
    /// Time the bench scenes on this machine (particle-steps per second).
    Bench {
        /// Benches to run (default: all).
        benches: Vec<String>,
        /// List the benches and exit.
        #[arg(long)]
        list: bool,
        /// Timed steps of every explicit bench, points of the tangent bench (default: per
        /// bench, a few seconds each).
        #[arg(long)]
        steps: Option<usize>,
        /// Run the explicit benches in single precision.
        #[arg(long)]
        f32: bool,
        /// Where the explicit benches run: `gpu` runs the 3D dam-breaks and cylinder collapses
        /// (default: all nine) in f32 on the first GPU adapter (Vulkan, Metal or DX12).
        #[arg(long, value_enum, default_value_t = Device::Cpu)]
        device: Device,
        /// With `--device gpu`: after the timed steps, take this many more with every kernel
        /// timed by the device's timestamps, and print each kernel's time per step and share.
        #[arg(long, value_name = "STEPS")]
        profile: Option<usize>,
        /// With `--device gpu`: how P2G adds into the grid instead of the adapter's choice
        /// (native f32 atomics where it has them, else the gather).
        #[arg(long, value_enum)]
        p2g: Option<run::gpu::P2g>,
        /// The gradient bench's memory for the adjoint, as for `loam gradient --memory`
        /// (default: the segment length of least memory).
        #[arg(long, value_name = "SIZE", value_parser = parse_size)]
        memory: Option<u64>,
        /// Write the results as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
}

/// The processor an explicit run or bench uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Device {
    /// The CPU solver (all features, f64 or f32).
    Cpu,
    /// The GPU solver of `loam-gpu` (f32; every explicit scene).
    Gpu,
}

impl Device {
    /// The scene's name for the same device (`solver.device`).
    fn scene(self) -> loam_scene::Device {
        match self {
            Self::Cpu => loam_scene::Device::Cpu,
            Self::Gpu => loam_scene::Device::Gpu,
        }
    }
}

/// The most worker threads `--threads` accepts: far above the cores of any machine loam
/// runs on, and far below the tens of thousands that would load a machine for minutes just
/// to start and stop them.
const MAX_THREADS: usize = 1024;

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, so printing to a closed pipe (`loam verify --list | head -1`)
    // would panic with "failed printing to stdout"; with the default action loam ends quietly
    // as other Unix tools do. The frames, the series file and the inversion history on disk
    // are each complete after every write, so what was written is kept. Setting a signal's
    // action needs `unsafe`, which this workspace denies; the `sigpipe` crate holds that call.
    sigpipe::reset();
    let cli = Cli::parse();
    if let Some(n) = cli.threads.filter(|&n| n > MAX_THREADS) {
        let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
        eprintln!(
            "error: --threads {n}: at most {MAX_THREADS} worker threads (this machine has {cores} \
             cores; more threads than cores do not make a run faster)"
        );
        return ExitCode::from(2);
    }
    if let Some(g) = cli.memory_limit.filter(|g| !(g.is_finite() && *g > 0.0)) {
        eprintln!("error: --memory-limit {g}: expected a positive number of GiB");
        return ExitCode::from(2);
    }
    let memory_limit = preflight::MemoryLimit::new(cli.memory_limit);
    let max_steps = preflight::StepLimit::new(cli.max_steps, preflight::MAX_STEPS);
    let inversion = invert::Limits {
        memory: memory_limit,
        steps: preflight::StepLimit::new(cli.max_steps, preflight::MAX_INVERSION_STEPS),
    };
    if let Some(n) = cli.threads
        && let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
    {
        eprintln!("error: --threads {n}: {e}");
        return ExitCode::from(2);
    }
    let outcome = match cli.command {
        Command::Run { progress_every, .. }
            if !(progress_every.is_finite() && progress_every >= 0.0) =>
        {
            eprintln!("error: --progress-every {progress_every}: expected seconds, 0 or more");
            Outcome::BadInput
        }
        Command::Run {
            scene,
            out,
            quiet,
            progress_every,
            checkpoint_every,
            resume,
            device,
            p2g,
        } => {
            let options = run::Options {
                out: out.as_deref(),
                quiet,
                progress_every,
                memory_limit,
                max_steps,
                checkpoint_every: checkpoint_every
                    .map(|n| usize::try_from(n).unwrap_or(usize::MAX)),
                device: device.map(Device::scene),
                p2g,
            };
            match (resume, scene) {
                (Some(dir), _) => run::resume(&dir, &options),
                (None, Some(scene)) => run::run(&scene, &options),
                // clap requires one of the two.
                (None, None) => Outcome::BadInput,
            }
        }
        Command::Material { file, out, quiet } => material::material(&file, out.as_deref(), quiet),
        Command::Fos { tolerance, .. }
            if tolerance.is_some_and(|t| !(t.is_finite() && t > 0.0)) =>
        {
            eprintln!(
                "error: --tolerance {}: expected a positive number (the width of the bracket \
                 of factors at which the search stops)",
                tolerance.unwrap_or_default()
            );
            Outcome::BadInput
        }
        Command::Fos {
            scene,
            out,
            tolerance,
            quiet,
        } => fos::fos(
            &scene,
            &fos::Options {
                out: out.as_deref(),
                tolerance,
                quiet,
                memory_limit,
                max_steps,
            },
        ),
        Command::Check { scene } if invert::is_inversion(&scene) => {
            invert::check(&scene, inversion)
        }
        Command::Check { scene } => check::check(&scene, memory_limit, max_steps),
        Command::Gradient {
            file,
            check,
            memory,
            json,
        } => hold(|| invert::gradient(&file, check, memory, json.as_deref(), inversion)),
        Command::Invert {
            file,
            out,
            resume,
            memory,
        } => hold(|| invert::invert(&file, out.as_deref(), resume, memory, inversion)),
        Command::Verify {
            cases,
            list,
            json,
            out,
            reduced,
            device,
        } => hold(|| {
            verify::verify(
                &cases,
                list,
                json.as_deref(),
                &out,
                reduced,
                device == Device::Gpu,
            )
        }),
        Command::Bench {
            benches,
            list,
            steps,
            f32,
            device,
            profile,
            p2g,
            memory,
            json,
        } => {
            if device == Device::Cpu && profile.is_some() {
                eprintln!("error: --profile times the GPU kernels; use it with --device gpu");
                Outcome::BadInput
            } else if device == Device::Cpu && p2g.is_some() {
                eprintln!("error: --p2g chooses the GPU's transfer; use it with --device gpu");
                Outcome::BadInput
            } else if memory.is_some() && !benches.iter().any(|b| b == "gradient") {
                eprintln!("error: --memory sets the gradient bench's memory; name `gradient`");
                Outcome::BadInput
            } else {
                bench::bench(
                    &benches,
                    list,
                    steps,
                    f32,
                    (device == Device::Gpu).then_some(bench::GpuBench { profile, p2g }),
                    memory,
                    json.as_deref(),
                )
            }
        }
    };
    match outcome {
        Outcome::Ok => ExitCode::SUCCESS,
        Outcome::Failed => ExitCode::from(1),
        Outcome::BadInput => ExitCode::from(2),
        Outcome::Interrupted => ExitCode::from(run::interrupt::EXIT_CODE),
    }
}

/// Parses a memory size: a positive number and a unit, `B`, `kB`, `MB`, `GB` (powers of 1000)
/// or `KiB`, `MiB`, `GiB` (powers of 1024), in any case: `512MB`, `1.5GiB`.
fn parse_size(text: &str) -> Result<u64, String> {
    let expected = || format!("`{text}`: expected a size such as 512MB or 2GiB");
    let at = text
        .find(|c: char| c.is_ascii_alphabetic())
        .ok_or_else(expected)?;
    let (number, unit) = text.split_at(at);
    let value: f64 = number.trim().parse().map_err(|_| expected())?;
    let scale: f64 = match unit.to_ascii_lowercase().as_str() {
        "b" => 1.0,
        "kb" => 1e3,
        "mb" => 1e6,
        "gb" => 1e9,
        "kib" => 1024.0,
        "mib" => 1024.0 * 1024.0,
        "gib" => 1024.0 * 1024.0 * 1024.0,
        _ => return Err(expected()),
    };
    let bytes = value * scale;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("`{text}`: expected a positive size"));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::parse_size;

    #[test]
    fn sizes_read_with_decimal_and_binary_units() {
        assert_eq!(parse_size("512MB"), Ok(512_000_000));
        assert_eq!(parse_size("1.5GiB"), Ok(1_610_612_736));
        assert_eq!(parse_size("64 kib"), Ok(65_536));
        assert_eq!(parse_size("100B"), Ok(100));
        for bad in ["512", "MB", "-1MB", "0MB", "12XB", "nanGB"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }
}
