//! `loam`: run, check, verify and bench MPM scenes.
//!
//! Exit codes: 0 success; 1 a run or a verification failed; 2 the input (scene file,
//! arguments) is invalid.

mod bench;
mod check;
mod run;
mod verify;

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

/// loam: a differentiable Material Point Method solver for geomechanics.
#[derive(Parser, Debug)]
#[command(name = "loam", version, about, long_about = None)]
struct Cli {
    /// Worker threads (default: all cores). Results are bitwise identical for any count.
    #[arg(long, global = true)]
    threads: Option<usize>,
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
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
        /// Explicit runs: save the state every N steps in OUT/checkpoint/ (the latest only),
        /// so the run can be continued with --resume.
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
        checkpoint_every: Option<u64>,
        /// Continue the run whose output folder is DIR from its checkpoint, with the scene
        /// recorded there.
        #[arg(long, value_name = "DIR", conflicts_with = "scene")]
        resume: Option<PathBuf>,
    },
    /// Validate a scene file: exit 0 if it is valid, 2 with the problems otherwise.
    Check {
        /// Scene file (.toml or .json).
        scene: PathBuf,
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
    },
    /// Time the bench scenes on this machine (particle-steps per second).
    Bench {
        /// Benches to run (default: all).
        benches: Vec<String>,
        /// List the benches and exit.
        #[arg(long)]
        list: bool,
        /// Timed steps of every explicit bench (default: per bench, a few seconds each).
        #[arg(long)]
        steps: Option<usize>,
        /// Run the explicit benches in single precision.
        #[arg(long)]
        f32: bool,
        /// Write the results as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
}

/// The outcome of a command: which exit code, after the command printed its own messages.
pub enum Outcome {
    /// Everything passed.
    Ok,
    /// A run or a check of results failed (exit 1).
    Failed,
    /// The input was invalid (exit 2).
    BadInput,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Some(n) = cli.threads
        && let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
    {
        eprintln!("error: --threads {n}: {e}");
        return ExitCode::from(2);
    }
    let outcome = match cli.command {
        Command::Run {
            scene,
            out,
            quiet,
            checkpoint_every,
            resume,
        } => {
            let every = checkpoint_every.map(|n| usize::try_from(n).unwrap_or(usize::MAX));
            match (resume, scene) {
                (Some(dir), _) => run::resume(&dir, quiet, every),
                (None, Some(scene)) => run::run(&scene, out.as_deref(), quiet, every),
                // clap requires one of the two.
                (None, None) => Outcome::BadInput,
            }
        }
        Command::Check { scene } => check::check(&scene),
        Command::Verify {
            cases,
            list,
            json,
            out,
            reduced,
        } => verify::verify(&cases, list, json.as_deref(), &out, reduced),
        Command::Bench {
            benches,
            list,
            steps,
            f32,
            json,
        } => bench::bench(&benches, list, steps, f32, json.as_deref()),
    };
    match outcome {
        Outcome::Ok => ExitCode::SUCCESS,
        Outcome::Failed => ExitCode::from(1),
        Outcome::BadInput => ExitCode::from(2),
    }
}
