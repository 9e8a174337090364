//! The solver behind a `Simulation`, with its dimension and kind erased: the explicit
//! solver, or the implicit one stepped by load steps, each with its particles, or the
//! explicit steps on the GPU.

use crate::fields::{self, Array, Field};
use loam_core::{Particles, TimeStep};
use loam_explicit::Solver;
use loam_gpu::GpuSolver;
use loam_implicit::ImplicitSolver;
use std::sync::Mutex;

/// A solver and its particles, seen from Python.
pub trait Stepper: Send + Sync {
    /// The dimension, 2 or 3.
    fn dim(&self) -> usize;
    /// Steps (explicit) or load steps (implicit) completed.
    fn steps(&self) -> usize;
    /// Simulated time (s): zero throughout an implicit run of the solid alone.
    fn time(&self) -> f64;
    /// The load factor reached (implicit runs; `None` for explicit ones).
    fn load_factor(&self) -> Option<f64>;
    /// The cap on the next step towards the time `t` (`f64::INFINITY` for none), or `None`
    /// once `t` is reached; an error where the solver does not step in time.
    fn cap_towards(&self, t: f64) -> Result<Option<f64>, String>;
    /// One step, no longer than `cap`.
    fn step(&mut self, cap: f64) -> Result<(), String>;
    /// A copy of `field` of every particle (an error where it cannot be read back).
    fn field(&self, field: Field) -> Result<Array<f64>, String>;
    /// Every particle's material index.
    fn material(&self) -> Array<i64>;
    /// Replaces every particle's velocity by `v` (N × D values, row-major, finite), or says
    /// why the solver cannot take them.
    fn set_velocities(&mut self, v: &[f64]) -> Result<(), String>;
}

/// What a solver does for a [`Stepper`]; see the methods of the same names there.
pub trait Solve<const D: usize>: Send + Sync {
    /// Steps completed.
    fn steps(&self) -> usize;
    /// Simulated time (s).
    fn time(&self) -> f64;
    /// The load factor reached, for a solver that has one.
    fn load_factor(&self) -> Option<f64>;
    /// The cap on the next step towards `t`.
    fn cap_towards(&self, t: f64) -> Result<Option<f64>, String>;
    /// One step of `particles`, no longer than `cap`.
    fn step(&mut self, particles: &mut Particles<f64, D>, cap: f64) -> Result<(), String>;
    /// Whether the particles' velocities are state the solver integrates (else why not).
    fn takes_velocities(&self) -> Result<(), String>;
}

/// A solver and the particles it steps.
pub struct Engine<S, const D: usize> {
    /// The solver.
    pub solver: S,
    /// The particles.
    pub particles: Particles<f64, D>,
}

impl<S: Solve<D>, const D: usize> Stepper for Engine<S, D> {
    fn dim(&self) -> usize {
        D
    }

    fn steps(&self) -> usize {
        self.solver.steps()
    }

    fn time(&self) -> f64 {
        self.solver.time()
    }

    fn load_factor(&self) -> Option<f64> {
        self.solver.load_factor()
    }

    fn cap_towards(&self, t: f64) -> Result<Option<f64>, String> {
        self.solver.cap_towards(t)
    }

    fn step(&mut self, cap: f64) -> Result<(), String> {
        self.solver.step(&mut self.particles, cap)
    }

    fn field(&self, field: Field) -> Result<Array<f64>, String> {
        Ok(fields::field(&self.particles, field))
    }

    fn material(&self) -> Array<i64> {
        fields::material(&self.particles)
    }

    fn set_velocities(&mut self, v: &[f64]) -> Result<(), String> {
        self.solver.takes_velocities()?;
        for (p, v) in self.particles.v.iter_mut().zip(v.chunks_exact(D)) {
            p.copy_from_slice(v);
        }
        Ok(())
    }
}

impl<const D: usize> Solve<D> for Solver<f64, D> {
    fn steps(&self) -> usize {
        Solver::steps(self)
    }

    fn time(&self) -> f64 {
        Solver::time(self)
    }

    fn load_factor(&self) -> Option<f64> {
        None
    }

    fn cap_towards(&self, t: f64) -> Result<Option<f64>, String> {
        Ok(explicit_cap(
            &self.config().time_step,
            Solver::time(self),
            t,
            || self.next_step_cap(t),
        ))
    }

    fn step(&mut self, particles: &mut Particles<f64, D>, cap: f64) -> Result<(), String> {
        (Solver::step(self, particles, cap))
            .map(|_| ())
            .map_err(|e| e.to_string())
    }

    fn takes_velocities(&self) -> Result<(), String> {
        Ok(())
    }
}

impl<const D: usize> Solve<D> for ImplicitSolver<D> {
    fn steps(&self) -> usize {
        ImplicitSolver::steps(self)
    }

    fn time(&self) -> f64 {
        ImplicitSolver::time(self)
    }

    fn load_factor(&self) -> Option<f64> {
        Some(ImplicitSolver::load_factor(self))
    }

    fn cap_towards(&self, _: f64) -> Result<Option<f64>, String> {
        Err(
            "advance_to steps explicit scenes; an implicit scene steps by load steps, \
             with step(n)"
                .into(),
        )
    }

    /// One load step (`cap` does not apply); an error once the loading is complete.
    fn step(&mut self, particles: &mut Particles<f64, D>, _: f64) -> Result<(), String> {
        if self.finished() {
            return Err(format!(
                "the loading is complete after {} load steps (solver.load_steps)",
                ImplicitSolver::steps(self)
            ));
        }
        (ImplicitSolver::step(self, particles))
            .map(|_| ())
            .map_err(|e| e.to_string())
    }

    /// Newmark dynamics integrates the velocities; a quasi-static run has none.
    fn takes_velocities(&self) -> Result<(), String> {
        match self.config().dynamics {
            Some(_) => Ok(()),
            None => Err(
                "a quasi-static implicit run has no velocities to set (its steps \
                         are load steps; solver.dynamics steps in time)"
                    .into(),
            ),
        }
    }
}

/// The cap on the next explicit step from the time `time` towards `t`: a fixed step Δt is
/// never shortened, so the steps are those that end by `t` (with the round-off allowance of
/// [`Solver::next_step_cap`], `min(1e-9 |t|, Δt/2)`), unbounded while one more fits; an
/// adaptive step is shortened to end on `t` (its solver's cap, `adaptive()`).
fn explicit_cap(
    time_step: &TimeStep,
    time: f64,
    t: f64,
    adaptive: impl FnOnce() -> Option<f64>,
) -> Option<f64> {
    match *time_step {
        TimeStep::Fixed { dt } => {
            let allowance = (1e-9 * t.abs()).min(0.5 * dt);
            (time + dt <= t + allowance).then_some(f64::INFINITY)
        }
        TimeStep::Adaptive { .. } => adaptive(),
    }
}

/// The explicit steps on the GPU ([`GpuSolver`], in f32 on the device) and a host copy of the
/// particles in f64, read back when a field is asked for after steps were taken.
pub struct GpuEngine<const D: usize> {
    /// The solver.
    solver: GpuSolver<D>,
    /// The scene's time step, fixed or adaptive.
    time_step: TimeStep,
    /// The particles as last read back (as built, before the first step) and the step they
    /// were read at.
    host: Mutex<(Particles<f64, D>, usize)>,
}

impl<const D: usize> GpuEngine<D> {
    /// The engine of `solver`, built from `particles` with the time step `time_step`.
    pub fn new(solver: GpuSolver<D>, time_step: TimeStep, particles: Particles<f64, D>) -> Self {
        Self {
            solver,
            time_step,
            host: Mutex::new((particles, 0)),
        }
    }
}

impl<const D: usize> Stepper for GpuEngine<D> {
    fn dim(&self) -> usize {
        D
    }

    fn steps(&self) -> usize {
        self.solver.steps()
    }

    fn time(&self) -> f64 {
        self.solver.time()
    }

    fn load_factor(&self) -> Option<f64> {
        None
    }

    fn cap_towards(&self, t: f64) -> Result<Option<f64>, String> {
        Ok(explicit_cap(&self.time_step, self.solver.time(), t, || {
            self.solver.next_step_cap(t)
        }))
    }

    fn step(&mut self, cap: f64) -> Result<(), String> {
        self.solver
            .step(cap)
            .map_err(|e| format!("{e} (t = {:.6e} s, on the GPU)", self.solver.time()))
    }

    fn field(&self, field: Field) -> Result<Array<f64>, String> {
        let mut host = self.host.lock().map_err(|e| e.to_string())?;
        let (particles, read_at) = &mut *host;
        if *read_at != self.solver.steps() {
            self.solver
                .read_particles(particles)
                .map_err(|e| e.to_string())?;
            *read_at = self.solver.steps();
        }
        Ok(fields::field(particles, field))
    }

    fn set_velocities(&mut self, _: &[f64]) -> Result<(), String> {
        Err(
            "the particle state is not set on the GPU: build the Simulation with \
             device=\"cpu\" to set it"
                .into(),
        )
    }

    fn material(&self) -> Array<i64> {
        let host = self
            .host
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        fields::material(&host.0)
    }
}
