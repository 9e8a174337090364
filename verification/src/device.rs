//! Where a case's explicit runs step: the CPU solver in f64, or a GPU through `loam-gpu` in
//! f32 (`loam verify --device gpu`), so that a user can check an adapter and its driver
//! against the same analytical solutions the CPU is held to.

use crate::VerifyError;
use loam_core::Particles;
use loam_core::energy::Energy;
use loam_explicit::{Config, Solver};
use loam_gpu::{Gpu, GpuSolver};

/// The device of a case's explicit runs.
#[derive(Clone, Debug, Default)]
pub enum Device {
    /// `loam_explicit::Solver` in f64.
    #[default]
    Cpu,
    /// `loam_gpu::GpuSolver` in f32 on this adapter (boxed: the handle is large beside
    /// `Cpu`).
    Gpu(Box<Gpu>),
}

impl Device {
    /// The device in words: `cpu (f64)`, or the adapter and its P2G (`Gpu::name`), in f32.
    pub fn name(&self) -> String {
        match self {
            Device::Cpu => "cpu (f64)".into(),
            Device::Gpu(gpu) => format!("{} (f32)", gpu.name()),
        }
    }
}

/// A case's explicit run on its device. The CPU solver is kept on the GPU too: its
/// configuration gives the energy of the particles read back.
pub(crate) struct ExplicitRun<const D: usize> {
    case: &'static str,
    cpu: Solver<f64, D>,
    gpu: Option<GpuSolver<D>>,
}

impl<const D: usize> ExplicitRun<D> {
    /// The run of `config` from `particles` on `device` (a rejected set-up is an error of the
    /// case, as is a GPU that cannot take it).
    pub fn new(
        case: &'static str,
        config: Config<f64, D>,
        particles: &Particles<f64, D>,
        device: &Device,
    ) -> Result<Self, VerifyError> {
        let gpu = match device {
            Device::Cpu => None,
            Device::Gpu(gpu) => Some(
                GpuSolver::new(gpu, &config.lift(), &particles.lift())
                    .map_err(|source| VerifyError::Gpu { case, source })?,
            ),
        };
        let cpu = Solver::new(config, particles).map_err(|source| VerifyError::Config {
            case: case.into(),
            source,
        })?;
        Ok(Self { case, cpu, gpu })
    }

    /// Advances to the time `t` and leaves the state in `particles` (a run that stops is an
    /// error of the case). The CPU lands on `t` exactly, the last step shortened also with a
    /// fixed step, so that the samples a case takes are at their nominal times; the GPU lands
    /// on `t` with an adaptive step, and with a fixed one on the step within round-off of it
    /// (the cases sample at multiples of their fixed steps), then reads the particles back.
    pub fn advance(
        &mut self,
        particles: &mut Particles<f64, D>,
        t: f64,
    ) -> Result<(), VerifyError> {
        let case = self.case;
        match &mut self.gpu {
            None => self
                .cpu
                .advance_exactly_to(particles, t, |_, _| {})
                .map_err(|source| VerifyError::Solver {
                    case: case.into(),
                    source,
                }),
            Some(gpu) => gpu
                .advance_toward(t, usize::MAX)
                .and_then(|_| gpu.read_particles(particles))
                .map_err(|source| VerifyError::Gpu { case, source }),
        }
    }

    /// Steps taken.
    pub fn steps(&self) -> usize {
        match &self.gpu {
            None => self.cpu.steps(),
            Some(gpu) => gpu.steps(),
        }
    }

    /// Whether the run has reached the time `t` (the solver's own test: within round-off of
    /// it, or with the GPU's fixed step within half a step).
    pub fn reached(&self, t: f64) -> bool {
        match &self.gpu {
            None => self.cpu.next_step_cap(t).is_none(),
            Some(gpu) => gpu.next_step_cap(t).is_none(),
        }
    }

    /// Takes one step towards `t`, as a step of `Solver::advance_to` (an adaptive step is
    /// shortened to land on `t`, a fixed one keeps its size), none once `t` is reached, and
    /// leaves the state in `particles`; returns the time reached.
    pub fn step_toward(
        &mut self,
        particles: &mut Particles<f64, D>,
        t: f64,
    ) -> Result<f64, VerifyError> {
        let case = self.case;
        match &mut self.gpu {
            None => {
                let Some(cap) = self.cpu.next_step_cap(t) else {
                    return Ok(self.cpu.time());
                };
                let info = self
                    .cpu
                    .step(particles, cap)
                    .map_err(|source| VerifyError::Solver {
                        case: case.into(),
                        source,
                    })?;
                Ok(info.time)
            }
            Some(gpu) => {
                gpu.advance_toward(t, 1)
                    .and_then(|_| gpu.read_particles(particles))
                    .map_err(|source| VerifyError::Gpu { case, source })?;
                Ok(gpu.time())
            }
        }
    }

    /// The mass on the grid after the last step's transfer, over the nodes that carry the
    /// body's mass (not the ghosts behind a bilateral wall, which hold copies).
    pub fn grid_mass(&self) -> Result<f64, VerifyError> {
        match &self.gpu {
            None => Ok(crate::obstacles::grid_mass(&self.cpu)),
            Some(gpu) => gpu.grid_mass().map_err(|source| VerifyError::Gpu {
                case: self.case,
                source,
            }),
        }
    }

    /// The energy of `particles` under the run's configuration.
    pub fn energy(&self, particles: &Particles<f64, D>) -> Energy {
        self.cpu.energy(particles)
    }
}
