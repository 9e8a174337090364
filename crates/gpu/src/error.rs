//! What can go wrong on the GPU path.

/// An error of the GPU path: no adapter, a scene it cannot run yet, or a step that went bad.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter was found (or none could open a device).
    #[error(
        "no GPU adapter: {reason}. The GPU path needs a Vulkan, Metal or DX12 adapter; on Linux \
         without a GPU, Mesa's software Vulkan driver (lavapipe) is one: \
         `apt-get install mesa-vulkan-drivers`"
    )]
    NoAdapter {
        /// What the lookup reported.
        reason: String,
    },
    /// The config is not one the explicit solver runs (the CPU's `Config::validate`).
    #[error(transparent)]
    Config(#[from] loam_explicit::ConfigError),
    /// The scene needs what this adapter or the GPU path does not offer (a buffer larger than
    /// the adapter binds, more steps than the device's step counter holds).
    #[error("`{field}`: {what} is not supported on the GPU yet (run it with device = \"cpu\")")]
    Unsupported {
        /// The scene field that selects the feature.
        field: String,
        /// The feature.
        what: String,
    },
    /// Particles whose stencil left the grid.
    #[error("step {step}: {count} particle(s) left the grid (ids {ids:?})")]
    LeftGrid {
        /// The last step of the checked run of steps.
        step: usize,
        /// How many particles.
        count: u32,
        /// Up to 16 of their ids.
        ids: Vec<u32>,
    },
    /// Particles with a non-finite position, velocity, deformation gradient or stress.
    #[error("step {step}: non-finite state in {count} particle(s) (ids {ids:?})")]
    NonFinite {
        /// The last step of the checked run of steps.
        step: usize,
        /// How many particles.
        count: u32,
        /// Up to 16 of their ids.
        ids: Vec<u32>,
    },
    /// Particles with det F ≤ 0.
    #[error("step {step}: inverted deformation gradient in {count} particle(s) (ids {ids:?})")]
    Inverted {
        /// The last step of the checked run of steps.
        step: usize,
        /// How many particles.
        count: u32,
        /// Up to 16 of their ids.
        ids: Vec<u32>,
    },
    /// Particles outside a walled face of the domain.
    #[error("step {step}: {count} particle(s) crossed a wall (ids {ids:?})")]
    Escaped {
        /// The last step of the checked run of steps.
        step: usize,
        /// How many particles.
        count: u32,
        /// Up to 16 of their ids.
        ids: Vec<u32>,
    },
    /// Particles inside a rigid obstacle.
    #[error("step {step}: {count} particle(s) crossed into obstacles[{obstacle}] (ids {ids:?})")]
    InsideObstacle {
        /// The last step of the checked run of steps.
        step: usize,
        /// How many particles.
        count: u32,
        /// Up to 16 of their ids.
        ids: Vec<u32>,
        /// The obstacle (its index in the scene) the first of them is inside.
        obstacle: u32,
    },
    /// A fixed time step above the stability bound `h / (c_p + |v_p|)` of some particles at
    /// the start of a step (the CPU solver's per-step check of a fixed `Δt`).
    #[error(
        "step {step}: the fixed time step {dt:e} s is above the stability bound h / (c + |v|) \
         of {count} particle(s) (ids {ids:?}); lower solver.time_step.dt or use an adaptive step"
    )]
    TimeStepTooLarge {
        /// The first step (counted from 1) whose start failed the check.
        step: usize,
        /// The fixed step.
        dt: f64,
        /// How many particles failed it in that step and the steps after, up to the check.
        count: u32,
        /// Up to 16 of their ids.
        ids: Vec<u32>,
    },
    /// The step cannot be profiled here (no timestamp queries, or an adaptive step).
    #[error("cannot profile the GPU step: {0}")]
    Profile(String),
    /// A buffer could not be read back.
    #[error("reading back from the GPU failed: {0}")]
    Readback(String),
}
