//! # loam-verification
//!
//! Verification of loam against analytical and classic reference solutions. Each case builds
//! its problem (from its reference scene file through `loam-scene`, see [`scenes`], where the
//! problem is a scene), runs it, measures an error norm against the reference, and writes a
//! CSV of the histories and a PNG plot of simulated vs reference. `loam verify` runs the cases at full
//! size; the test suite runs them at reduced size.

pub mod adjoint_fd;
pub mod axial_bar;
pub mod bui;
pub mod cantilever;
pub mod column;
pub mod consolidation_large;
pub mod dambreak;
mod device;
pub mod disk_collision;
pub mod elastica;
pub mod fe_beam;
pub mod footing;
pub mod footing_consolidation;
mod gibson;
pub mod granular;
pub mod implicit_adjoint_fd;
pub mod incline;
pub mod inverse_element;
pub mod inverse_friction;
pub mod inverse_implicit;
pub mod inverse_mlp;
pub mod inverse_v0;
mod inversion;
pub mod k0_layer;
pub mod mandel;
pub mod mandel_series;
pub mod newmark_bar;
pub mod newmark_energy;
pub mod newton_quadratic;
pub mod obstacle_velocity_fd;
pub mod obstacles;
mod output;
pub mod runout;
pub mod scenes;
pub mod slope_fos;
pub mod tangent_fd;
pub mod terzaghi;
pub mod triaxial;
pub mod triaxial_mcc;

pub use device::Device;
pub use output::{Panel, Series, write_csv, write_panels, write_plot, write_text};

use serde::Serialize;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// One measured quantity of a case, with its acceptance threshold (or none, for a quantity
/// reported as information only).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Metric {
    /// Case name (e.g. `axial-bar`).
    pub case: String,
    /// What is measured (e.g. `max_rel_error_vcm`).
    pub metric: String,
    /// Measured value.
    pub value: f64,
    /// Acceptance threshold; `None` (JSON `null`) for an information-only metric.
    pub tolerance: Option<f64>,
    /// Whether the tolerance is an upper bound (`value ≤ tolerance`), a lower bound, or
    /// there is none (information).
    pub bound: Bound,
    /// Whether the value is within tolerance; always `true` for an information-only metric,
    /// which never fails a case.
    pub passed: bool,
}

/// Which side of the tolerance passes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Bound {
    /// `value ≤ tolerance` passes (errors, drifts).
    Upper,
    /// `value ≥ tolerance` passes (convergence orders).
    Lower,
    /// Reported as information: no tolerance, does not decide pass or fail (e.g. the error
    /// against a reference that the converged model is known not to match).
    Info,
}

impl Metric {
    /// A metric that passes when `value ≤ tolerance` (and is finite).
    pub fn at_most(case: &str, metric: &str, value: f64, tolerance: f64) -> Self {
        Self {
            case: case.into(),
            metric: metric.into(),
            value,
            tolerance: Some(tolerance),
            bound: Bound::Upper,
            passed: value.is_finite() && value <= tolerance,
        }
    }

    /// A metric that passes when `value ≥ tolerance` (and is finite).
    pub fn at_least(case: &str, metric: &str, value: f64, tolerance: f64) -> Self {
        Self {
            bound: Bound::Lower,
            passed: value.is_finite() && value >= tolerance,
            ..Self::at_most(case, metric, value, tolerance)
        }
    }

    /// A value reported as information only: no tolerance, never fails.
    pub fn info(case: &str, metric: &str, value: f64) -> Self {
        Self {
            case: case.into(),
            metric: metric.into(),
            value,
            tolerance: None,
            bound: Bound::Info,
            passed: true,
        }
    }
}

/// Problem size: the test suite runs `Reduced` (seconds), `loam verify` runs `Full`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Size {
    /// Coarse resolution for the test suite.
    Reduced,
    /// The resolution the documented figures come from.
    Full,
}

/// What a case produced.
#[derive(Clone, Debug)]
pub struct CaseReport {
    /// Metrics with tolerances.
    pub metrics: Vec<Metric>,
    /// Files written (CSV, PNG, Markdown tables).
    pub files: Vec<PathBuf>,
}

/// Errors of a verification run.
#[derive(Debug, Error)]
pub enum VerifyError {
    /// The simulation stopped.
    #[error("{case}: simulation failed: {source}")]
    Solver {
        /// Case name.
        case: String,
        /// The solver's error.
        #[source]
        source: loam_explicit::StepError,
    },
    /// An implicit run stopped.
    #[error("{case}: implicit solve failed: {source}")]
    Implicit {
        /// Case name.
        case: String,
        /// The solver's error.
        #[source]
        source: loam_implicit::ImplicitError,
    },
    /// The solver rejected the set-up (a bug in the case).
    #[error("{case}: invalid set-up: {source}")]
    Config {
        /// Case name.
        case: String,
        /// The solver's error.
        #[source]
        source: loam_explicit::ConfigError,
    },
    /// Writing CSV or plots failed.
    #[error("{path}: {msg}")]
    Output {
        /// File.
        path: PathBuf,
        /// What went wrong.
        msg: String,
    },
    /// A gradient or an inversion failed.
    #[error("{case}: {source}")]
    Adjoint {
        /// Case name.
        case: String,
        /// The error of `loam-inverse`.
        #[source]
        source: loam_inverse::AdjointError,
    },
    /// A reference solution could not be computed.
    #[error("{case}: reference solution failed: {msg}")]
    Reference {
        /// Case name.
        case: String,
        /// What went wrong.
        msg: String,
    },
    /// No case of that name.
    #[error("unknown verification case \"{0}\"; run `loam verify --list` to see the cases")]
    UnknownCase(String),
    /// A GPU run failed, or the GPU could not take the set-up.
    #[error("{case}: GPU run failed: {source}")]
    Gpu {
        /// Case name.
        case: &'static str,
        /// The GPU path's error.
        #[source]
        source: loam_gpu::GpuError,
    },
    /// A case that runs on the CPU only was asked for the GPU.
    #[error("{case} runs on the CPU only; the cases that run on the GPU: {gpu_cases}")]
    CpuOnly {
        /// Case name.
        case: String,
        /// The cases that do.
        gpu_cases: String,
    },
}

/// A verification case.
pub struct Case {
    /// Name used on the command line.
    pub name: &'static str,
    /// One-line description with the reference.
    pub description: &'static str,
    /// Runs the case, writing its files under the given directory.
    pub runner: Runner,
}

/// How a case runs.
#[derive(Clone, Copy)]
pub enum Runner {
    /// On the CPU only.
    Cpu(fn(Size, &Path) -> Result<CaseReport, VerifyError>),
    /// Its explicit runs on either [`Device`].
    Explicit(fn(Size, &Device, &Path) -> Result<CaseReport, VerifyError>),
}

impl Case {
    /// Whether the case's runs can step on the GPU.
    pub fn on_gpu(&self) -> bool {
        matches!(self.runner, Runner::Explicit(_))
    }

    /// Whether the case runs on the GPU when `gpu` is asked for: a CPU-only case is
    /// [`VerifyError::CpuOnly`], naming the cases that do.
    pub fn check_device(&self, gpu: bool) -> Result<(), VerifyError> {
        if gpu && !self.on_gpu() {
            return Err(VerifyError::CpuOnly {
                case: self.name.into(),
                gpu_cases: cases()
                    .iter()
                    .filter(|c| c.on_gpu())
                    .map(|c| c.name)
                    .collect::<Vec<_>>()
                    .join(", "),
            });
        }
        Ok(())
    }

    /// Runs the case at `size` on `device`, writing its files under `out` (see
    /// [`Case::check_device`]).
    pub fn run(&self, size: Size, device: &Device, out: &Path) -> Result<CaseReport, VerifyError> {
        self.check_device(matches!(device, Device::Gpu(_)))?;
        match self.runner {
            Runner::Cpu(run) => run(size, out),
            Runner::Explicit(run) => run(size, device, out),
        }
    }
}

/// Every case, in the order `loam verify` runs them.
pub fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "axial-bar",
            description: "1D axial vibration of a fixed-free elastic bar vs the modal solution v_cm(t) = v0/(β1 L) cos(ω1 t)",
            runner: Runner::Cpu(axial_bar::run),
        },
        Case {
            name: "axial-bar-newmark",
            description: "the axial bar by the implicit solver with Newmark dynamics at twice the explicit stability limit",
            runner: Runner::Cpu(newmark_bar::run),
        },
        Case {
            name: "newmark-energy",
            description: "free vibration of the dynamic cantilever (Hencky, first-mode velocity, tip amplitude L/100) by implicit Newmark at 20 steps per period for 10 periods: total energy drift",
            runner: Runner::Cpu(newmark_energy::run),
        },
        Case {
            name: "tangent-fd",
            description: "sparse-AD tangents (per-particle and colour-seeded) vs central finite differences, Neo-Hookean / Hencky / J2, 2D and 3D",
            runner: Runner::Cpu(tangent_fd::run),
        },
        Case {
            name: "newton-quadratic",
            description: "quadratic convergence of Newton with the AD tangent (r_{k+1}/r_k² bounded)",
            runner: Runner::Cpu(newton_quadratic::run),
        },
        Case {
            name: "cantilever",
            description: "large-deflection plane-strain cantilever (Hencky, 50 load steps) vs the elastica",
            runner: Runner::Cpu(cantilever::run),
        },
        Case {
            name: "column-compaction",
            description: "soil column compacting under self-weight (Hencky, 40 load steps) vs the exact stress",
            runner: Runner::Cpu(column::run),
        },
        Case {
            name: "footing-prandtl",
            description: "rigid strip footing on weightless Tresca (J2) soil: limit pressure vs (2 + π) c_u",
            runner: Runner::Cpu(footing::run),
        },
        Case {
            name: "footing-cphi",
            description: "rigid strip footing on weightless c–φ soil (Mohr–Coulomb, φ = ψ = 30°): limit pressure vs Prandtl's c N_c = 30.14 c at two cell sizes, the finer closer",
            runner: Runner::Cpu(footing::run_cphi),
        },
        Case {
            name: "slope-fos",
            description: "factor of safety of Griffiths & Lane's 2:1 slope (φ′ = 20°, c′ = 10 kPa, ψ = 0) by strength reduction over gravity switch-on: F vs 1.40",
            runner: Runner::Cpu(slope_fos::run),
        },
        Case {
            name: "k0-layer",
            description: "soil layer at rest: σ′_h/σ′_v = ν/(1 − ν) after gravity switch-on; a K0 = 0.5 state kept through the first load step",
            runner: Runner::Cpu(k0_layer::run),
        },
        Case {
            name: "terzaghi",
            description: "one-dimensional consolidation by the coupled u–p solver (GeoWarp's column, steps of 100 s, 25 s and growing) vs Terzaghi's series: pore pressures and settlement",
            runner: Runner::Cpu(terzaghi::run),
        },
        Case {
            name: "mandel",
            description: "Mandel's problem (plane strain) by the coupled u–p solver under a force-controlled rigid plate vs the series solution: pore pressures, the plate's settlement, the Mandel–Cryer peak",
            runner: Runner::Cpu(mandel::run),
        },
        Case {
            name: "consolidation-large",
            description: "large-strain one-dimensional consolidation by the coupled u–p solver (GeoWarp's Neo-Hookean column, q/M = 0.25, drained base) vs Gibson's finite-strain theory by finite volumes: settlement within 1 %, pore pressures; Terzaghi's settlement 13–20 % off at T_v = 1–2",
            runner: Runner::Cpu(consolidation_large::run),
        },
        Case {
            name: "footing-consolidation-3d",
            description: "rigid square footing on a saturated elastic block in 3D by the coupled u–p solver (quarter symmetry, force-controlled): immediate over long-term settlement vs the half-space's (1 − ν_u)/(1 − ν), the long-term settlement vs a drained run, the consolidation curve between them",
            runner: Runner::Cpu(footing_consolidation::run),
        },
        Case {
            name: "triaxial-dp",
            description: "drained triaxial compression of Drucker–Prager sand (Hencky, compression cone): q_f vs 3Mp′₀/(3 − M); φ = 0 vs von Mises and J2",
            runner: Runner::Cpu(triaxial::run_dp),
        },
        Case {
            name: "triaxial-mc",
            description: "drained triaxial compression and extension of Mohr–Coulomb soil vs σ′₁/σ′₃ = (1 + sin φ)/(1 − sin φ) (+ cohesion); tangent vs central differences in every return region",
            runner: Runner::Cpu(triaxial::run_mc),
        },
        Case {
            name: "triaxial-mcc",
            description: "Modified Cam-Clay, normally consolidated: undrained path vs its closed form, p′_f/p′₀ = 0.574 and s_u/p′₀ = 0.287; drained q_f = 3Mp′₀/(3 − M); oedometer slopes λ and κ",
            runner: Runner::Cpu(triaxial_mcc::run),
        },
        Case {
            name: "disk-collision",
            description: "Sulsky's two elastic disks: total energy drift through the collision (APIC)",
            runner: Runner::Explicit(disk_collision::run),
        },
        Case {
            name: "bui-collapse",
            description: "plane-strain collapse of Bui et al.'s (2008) aluminium-bar column (Drucker–Prager φ = 19.8°, Coulomb floor): final runout and height at the wall",
            runner: Runner::Explicit(bui::run),
        },
        Case {
            name: "column-runout",
            description: "granular column collapse, a = 0.5, 1, 2, 4 (Drucker–Prager φ = 32°, Coulomb floor): (L∞ − L0)/L0 between Lube et al. (2005) and Lajeunesse et al. (2005)",
            runner: Runner::Explicit(runout::run),
        },
        Case {
            name: "dambreak-2d",
            description: "2D dam break on a frictionless bed (weakly compressible fluid; APIC, TPIC, FLIP): surge front vs Ritter's x_f = L0 + 2√(gH0) t",
            runner: Runner::Explicit(dambreak::run),
        },
        Case {
            name: "incline-friction",
            description: "block on a 30° incline with Coulomb friction: acceleration vs g(sin α − μ cos α) for μ = 0.1, 0.3; sticking for μ = 0.7 > tan α",
            runner: Runner::Explicit(incline::run),
        },
        Case {
            name: "dambreak-obstacles-3d",
            description: "3D dam break against two rigid cylinders: no particle inside a column, mass conserved on particles and grid, energy never above its initial value",
            runner: Runner::Explicit(obstacles::run),
        },
        Case {
            name: "adjoint-fd",
            description: "discrete adjoint vs forward-mode duals (1e-10) vs branch-aware central differences (1e-6), Taylor test: fluid on friction segments, Neo-Hookean block vs moving obstacle, Drucker–Prager column, 3D block; USL and MUSL",
            runner: Runner::Cpu(adjoint_fd::run),
        },
        Case {
            name: "obstacle-velocity-fd",
            description: "derivative w.r.t. a moving disk's velocity (pushed into water) by the adjoint and forward-mode duals vs central differences converged over three steps (1e-6); USL and MUSL",
            runner: Runner::Cpu(obstacle_velocity_fd::run),
        },
        Case {
            name: "implicit-adjoint-fd",
            description: "adjoint of implicit runs vs forward-mode duals (1e-10) vs central differences on the reference's sub-steps (1e-6), Taylor test: Hencky cantilever (E, ν, tip load, ρ₀), J2 footing with a cut load step (σ_y, E, H, settlement), the cantilever in Newmark dynamics under a sudden tip load (E, ν, tip load, ρ₀; tip deflection and velocity)",
            runner: Runner::Cpu(implicit_adjoint_fd::run),
        },
        Case {
            name: "inverse-v0",
            description: "initial velocity of a dam break (truth 2.0 m/s, first guess 0.5) recovered by L-BFGS from all particle positions, 100 tracked particles, four velocity monitors: within 0.5 %",
            runner: Runner::Cpu(inverse_v0::run),
        },
        Case {
            name: "inverse-friction",
            description: "friction of four floor bands under a dam break (μ = 0, 0.5, 0.1, 0.2) recovered by L-BFGS through a softplus from 0.798, 100 tracked particles: within 1 %, the zero band below 0.005",
            runner: Runner::Cpu(inverse_friction::run),
        },
        Case {
            name: "inverse-mlp",
            description: "initial velocity field of a water column given by an MLP (2 → 30 → 30 → 30 → 1) recovered by L-BFGS from 100, 500, 1,000 tracked particles: relative L2 error below 6.4 % (500) and 3.7 % (1,000)",
            runner: Runner::Cpu(inverse_mlp::run),
        },
        Case {
            name: "inverse-cantilever",
            description: "Study 4: Hencky cantilever, E from the tip displacement at 10 load steps (ν known) within 0.1 %; E and ν from all particles at 3 load steps within 1 % each; Gauss–Newton identifiability, tip vs all particles",
            runner: Runner::Cpu(inverse_implicit::run_cantilever),
        },
        Case {
            name: "inverse-footing",
            description: "Study 5: strip footing on J2 clay under a prescribed settlement, σ_y (√3 c_u) and E from the load–settlement curve (reactions) within 0.5 % each",
            runner: Runner::Cpu(inverse_implicit::run_footing),
        },
        Case {
            name: "inverse-footing-cphi",
            description: "strip footing on Mohr–Coulomb soil under gravity, φ and c from the load–settlement curve (reactions at 8 load steps) by L-BFGS from 20 % off: within 1 % each",
            runner: Runner::Cpu(inverse_implicit::run_footing_cphi),
        },
        Case {
            name: "inverse-triaxial-mcc",
            description: "Modified Cam-Clay λ, κ, M fitted to a drained (q, ε_v) and an undrained (q, p′) triaxial curve (synthetic truth λ = 0.2, κ = 0.04, M = 1) by Levenberg–Marquardt with forward-mode derivatives through the element driver, from 25 % off: within 1 % each",
            runner: Runner::Cpu(inverse_element::run),
        },
    ]
}

/// Looks a case up by name.
pub fn case(name: &str) -> Result<Case, VerifyError> {
    cases()
        .into_iter()
        .find(|c| c.name == name)
        .ok_or_else(|| VerifyError::UnknownCase(name.into()))
}
