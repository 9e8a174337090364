//! The adapter and the device: which GPU runs the step, and how it adds floats atomically.

use crate::error::GpuError;

/// How the particle-to-grid scatter adds f32 values into the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Atomics {
    /// Native `atomicAdd` on `atomic<f32>` (`Features::SHADER_FLOAT32_ATOMIC`).
    Native,
    /// A compare-exchange loop on `atomic<u32>` holding the f32 bits (any adapter).
    CompareExchange,
    /// No float atomics: the particles are binned by stencil (a counting sort with integer
    /// atomics) and each node sums its share from the bins around it, in a fixed order, so
    /// the step gives the same bits from run to run (any adapter; the fallback where the
    /// adapter has no float atomics).
    Gather,
}

/// An open GPU device and what the step needs to know of it.
#[derive(Clone, Debug)]
pub struct Gpu {
    pub(crate) device: wgpu::Device,
    pub(crate) queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    atomics: Atomics,
    /// Whether the device writes timestamps at the start and end of compute passes.
    timestamps: bool,
    /// Whether the scatter uses subgroup operations (`Features::SUBGROUP`).
    subgroups: bool,
}

impl Gpu {
    /// Opens the system's preferred high-performance adapter. Native f32 atomics are used
    /// where the adapter offers them, and the gather ([`Atomics::Gather`]) where it does not;
    /// `compare_exchange` asks for the compare-exchange loop instead of either.
    pub fn new(compare_exchange: bool) -> Result<Self, GpuError> {
        pollster::block_on(Self::open(compare_exchange))
    }

    async fn open(compare_exchange: bool) -> Result<Self, GpuError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN | wgpu::Backends::METAL | wgpu::Backends::DX12,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapter = instance
            .request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                ..wgpu::RequestAdapterOptions::default()
            })
            .await
            .map_err(|e| GpuError::NoAdapter {
                reason: e.to_string(),
            })?;
        let native = adapter
            .features()
            .contains(wgpu::Features::SHADER_FLOAT32_ATOMIC);
        let atomics = match (compare_exchange, native) {
            (true, _) => Atomics::CompareExchange,
            (false, true) => Atomics::Native,
            (false, false) => Atomics::Gather,
        };
        // Timestamps only time the kernels (`GpuSolver::profile`); a device without them
        // runs the step all the same.
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let mut required_features = if native {
            wgpu::Features::SHADER_FLOAT32_ATOMIC
        } else {
            wgpu::Features::empty()
        };
        if timestamps {
            required_features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        let subgroups = adapter.features().contains(wgpu::Features::SUBGROUP);
        if subgroups {
            required_features |= wgpu::Features::SUBGROUP;
        }
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("loam"),
                required_features,
                required_limits: adapter.limits(),
                ..wgpu::DeviceDescriptor::default()
            })
            .await
            .map_err(|e| GpuError::NoAdapter {
                reason: format!("the adapter could not open a device: {e}"),
            })?;
        Ok(Self {
            device,
            queue,
            info: adapter.get_info(),
            atomics,
            timestamps,
            subgroups,
        })
    }

    /// The adapter's name, back-end and kind, e.g. `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan,
    /// Cpu)`.
    pub fn name(&self) -> String {
        format!(
            "{} ({:?}, {:?})",
            self.info.name, self.info.backend, self.info.device_type
        )
    }

    /// How the scatter adds floats on this device.
    pub fn atomics(&self) -> Atomics {
        self.atomics
    }

    /// How P2G adds into the grid on this device, in words: `gather from binned particles`,
    /// or `scatter` with the atomics (`native f32 atomics`, `compare-exchange`) and, where
    /// the scatter sums runs of particles within a subgroup, `subgroup sums`.
    pub fn p2g(&self) -> &'static str {
        match (self.atomics, self.subgroups) {
            (Atomics::Gather, _) => "gather from binned particles",
            (Atomics::Native, true) => "scatter, native f32 atomics, subgroup sums",
            (Atomics::Native, false) => "scatter, native f32 atomics",
            (Atomics::CompareExchange, true) => "scatter, compare-exchange, subgroup sums",
            (Atomics::CompareExchange, false) => "scatter, compare-exchange",
        }
    }

    /// Whether the scatter sums each subgroup's runs of particles that share a stencil
    /// before it adds them to the grid (where the adapter has `Features::SUBGROUP`).
    pub fn subgroups(&self) -> bool {
        self.subgroups
    }

    /// The same device with the scatter adding every particle's entries itself, without
    /// subgroup operations (as on an adapter without them).
    pub fn without_subgroups(mut self) -> Self {
        self.subgroups = false;
        self
    }

    /// The same device with P2G as a gather ([`Atomics::Gather`]), as on an adapter without
    /// float atomics.
    pub fn with_gather(mut self) -> Self {
        self.atomics = Atomics::Gather;
        self
    }

    /// Whether the device can time compute passes (`Features::TIMESTAMP_QUERY`), which
    /// `GpuSolver::profile` needs.
    pub fn timestamps(&self) -> bool {
        self.timestamps
    }

    /// The largest storage buffer one binding may hold, in bytes.
    pub fn max_binding(&self) -> u64 {
        self.device.limits().max_storage_buffer_binding_size
    }
}
