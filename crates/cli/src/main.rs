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
        /// Scene file (.toml or .json).
        scene: PathBuf,
        /// Output folder (overrides the scene's `output.dir`).
        #[arg(long)]
        out: Option<PathBuf>,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
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
        Command::Run { scene, out, quiet } => run::run(&scene, out.as_deref(), quiet),
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
