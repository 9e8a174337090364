//! [`GpuSolver`]: the particle and grid buffers on the device, the run of steps, the checks
//! and the read-back.

use crate::device::{Atomics, Gpu};
use crate::error::GpuError;
use crate::params::{self, Params};
use crate::step::{Kernels, Variant, WORKGROUP};
use loam_core::constitutive::Model;
use loam_core::tensor::{Tensor, Vector, det};
use loam_core::{Boundary, Grid, Particles, Scalar, TimeStep, WallKind};
use loam_explicit::Config;
use nalgebra::Matrix3;
use wgpu::util::DeviceExt;

mod profile;

pub use profile::Profile;

/// Steps recorded into one command buffer.
const STEPS_PER_SUBMIT: usize = 32;

/// Steps between two reads of the stability flags.
pub const CHECK_EVERY: usize = 128;

/// Flag counters (non-finite, inverted, escaped, left the grid, inside an obstacle, a fixed
/// step above the stability bound), 16 ids per kind, the obstacle of the first particle
/// inside one, the step of the first stability flag, and the clock, as `common.wgsl` lays
/// them out.
const FLAG_KINDS: usize = 6;
const MAX_IDS: usize = 16;
const FLAG_TIME_STEP: usize = 5;
const FLAG_OBSTACLE: usize = FLAG_KINDS * (1 + MAX_IDS);
const FLAG_STEP: usize = FLAG_OBSTACLE + 1;
/// The clock: the steps begun, which a fixed step's contact reads its time from.
const CLOCK: usize = FLAG_STEP + 1;
const FLAG_WORDS: usize = FLAG_OBSTACLE + 3;
/// Where the largest speed per material starts in the flags buffer (after the clock).
const SPEEDS: usize = FLAG_WORDS;

/// The explicit step of a [`Config`] on the GPU, in f32: particles and grid stay on the device
/// and only the stability flags come back between runs of steps.
pub struct GpuSolver<const D: usize> {
    gpu: Gpu,
    kernels: Kernels,
    bind_group: wgpu::BindGroup,
    uniform: wgpu::Buffer,
    kin: wgpu::Buffer,
    aff: wgpu::Buffer,
    def: wgpu::Buffer,
    mat: wgpu::Buffer,
    flags: wgpu::Buffer,
    acc: wgpu::Buffer,
    /// The bytes of every buffer the solver allocated on the device.
    device_bytes: u64,
    /// Per material, its model: the read-back rebuilds the state tensor of Drucker–Prager
    /// (`I + 2 C⁻¹:σ`) and J2 (`bₑ = exp(2 C⁻¹:τ)`) from the stress.
    models: Vec<Model<f32>>,
    grid: Grid<D>,
    boundary: Boundary<D>,
    particles: usize,
    nodes: usize,
    /// The step the last step took (the fixed step until one is taken).
    dt: f64,
    /// The smallest and largest step taken.
    dt_range: (f64, f64),
    time_step: TimeStep,
    /// Per material, the elastic wave speed `c` of the stability bound `h / (c + |v|)`.
    wave_speed: Vec<f64>,
    /// Steps since the flags were last read.
    unchecked: usize,
    steps: usize,
    time: f64,
}

fn storage(gpu: &Gpu, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    gpu.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytes,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
        })
}

fn zeroed(gpu: &Gpu, label: &str, words: usize) -> wgpu::Buffer {
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: (4 * words.max(1)) as u64,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

fn flat_vectors<const D: usize>(v: &[Vector<f32, D>], out: &mut Vec<f32>) {
    out.extend(v.iter().flat_map(|x| x.iter().copied()));
}

fn flat_tensors<const D: usize>(t: &[Tensor<f32, D>]) -> Vec<f32> {
    t.iter()
        .flat_map(|m| (0..D * D).map(move |k| m[(k / D, k % D)]))
        .collect()
}

fn layout_entry(binding: u32, ty: wgpu::BufferBindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl<const D: usize> GpuSolver<D> {
    /// Uploads `particles` and compiles the step of `config` (the lifted f32 config the CPU
    /// solver takes); fails with [`GpuError::Config`] for a config the CPU solver refuses, and
    /// with [`GpuError::Unsupported`] naming the scene field that sizes a buffer larger than
    /// the adapter binds or a material whose model the GPU does not run.
    pub fn new(
        gpu: &Gpu,
        config: &Config<f32, D>,
        particles: &Particles<f32, D>,
    ) -> Result<Self, GpuError> {
        config.validate()?;
        params::check_models(config)?;
        let n = particles.len();
        let nodes = config.grid.num_nodes();
        let max_mass = particles.mass.iter().fold(0.0f64, |m, &x| m.max(x as f64));
        let mut prm: Params = params::params(config, n, max_mass);
        // The gather's particle bins follow the flags (bins.wgsl): the counts and starts of
        // the N + 1 bins, the tiles' totals, per particle its key, slot and place, and per
        // place its scatter (`PAYLOAD` words).
        prm.bins = (SPEEDS + config.materials.len()) as u32;
        let bin_words = if gpu.atomics() == Atomics::Gather {
            // bins.wgsl's `PAYLOAD`.
            let force = if config.transfer == loam_core::Transfer::Mls {
                0
            } else {
                6
            };
            let payload = 16 + force + if config.shape.is_gimp() { 3 } else { 0 };
            (nodes + 1) + (nodes + 1).div_ceil(WORKGROUP as usize) + (3 + payload) * n
        } else {
            0
        };
        let variant = Variant {
            dim: D,
            atomics: gpu.atomics(),
            transfer: params::transfer_code(config.transfer),
            musl: params::is_musl(config),
            subgroups: gpu.subgroups(),
            models: params::models(config),
            shape: config.shape,
            state_words: params::state_words(config),
        };
        let mut kin = Vec::with_capacity(3 * D * n);
        flat_vectors(&particles.x, &mut kin);
        flat_vectors(&particles.v, &mut kin);
        flat_vectors(&particles.x, &mut kin);
        let mut mat = Vec::with_capacity((10 + D) * n);
        for s in &particles.stress {
            mat.extend([
                s[(0, 0)],
                s[(1, 1)],
                s[(2, 2)],
                s[(0, 1)],
                s[(0, 2)],
                s[(1, 2)],
            ]);
        }
        mat.extend(&particles.mass);
        mat.extend(&particles.volume0);
        mat.extend(particles.material.iter().map(|&m| f32::from_bits(m)));
        mat.extend(particles.state.iter().map(|s| s.plastic_strain));
        if config.shape.is_gimp() {
            flat_vectors(&particles.half_width0, &mut mat);
        }
        let table = params::table(config);
        // Each buffer with the scene field that sizes it: the particles' by the bodies, the
        // grid's by the cell size; the gather's bins mostly by the particles.
        let buffers = [
            (
                "particle kinematics",
                bytemuck::cast_slice::<f32, u8>(&kin).len(),
                "bodies",
            ),
            ("particle C", 4 * D * D * n, "bodies"),
            ("particle F", 4 * D * D * n, "bodies"),
            ("particle stress and mass", 4 * mat.len(), "bodies"),
            (
                "grid accumulator",
                4 * (1 + 2 * D) * nodes,
                "grid.cell_size",
            ),
            (
                "grid velocity",
                4 * params::node_words(config),
                "grid.cell_size",
            ),
            (
                "flags and particle bins",
                4 * (prm.bins as usize + bin_words),
                "bodies",
            ),
        ];
        for (what, bytes, field) in buffers {
            if bytes as u64 > gpu.max_binding() {
                return Err(GpuError::Unsupported {
                    field: field.into(),
                    what: format!(
                        "a {what} buffer of {} MiB (this adapter binds at most {} MiB)",
                        bytes >> 20,
                        gpu.max_binding() >> 20
                    ),
                });
            }
        }
        let uniform = gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("params"),
                contents: bytemuck::bytes_of(&prm),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
        let kin = storage(gpu, "kinematics", bytemuck::cast_slice(&kin));
        let aff = storage(
            gpu,
            "affine",
            bytemuck::cast_slice(&flat_tensors(&particles.c)),
        );
        let def = storage(
            gpu,
            "deformation",
            bytemuck::cast_slice(&flat_tensors(&particles.f)),
        );
        let mat = storage(gpu, "stress and mass", bytemuck::cast_slice(&mat));
        let acc = zeroed(gpu, "accumulator", (1 + 2 * D) * nodes);
        let nodev = zeroed(gpu, "node velocity", params::node_words(config));
        let flags = zeroed(gpu, "flags", prm.bins as usize + bin_words);
        let table = storage(gpu, "table", bytemuck::cast_slice(&table));
        use wgpu::BufferBindingType::{Storage, Uniform};
        let rw = Storage { read_only: false };
        let mut entries = vec![layout_entry(0, Uniform)];
        entries.extend((1..=7).map(|b| layout_entry(b, rw)));
        entries.push(layout_entry(8, Storage { read_only: true }));
        let layout = gpu
            .device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("loam step"),
                entries: &entries,
            });
        let bound = [
            &uniform, &kin, &aff, &def, &mat, &acc, &nodev, &flags, &table,
        ];
        let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("loam step"),
            layout: &layout,
            entries: &bound
                .iter()
                .enumerate()
                .map(|(b, buffer)| wgpu::BindGroupEntry {
                    binding: b as u32,
                    resource: buffer.as_entire_binding(),
                })
                .collect::<Vec<_>>(),
        });
        let kernels = Kernels::new(&gpu.device, &layout, variant);
        let device_bytes = bound.iter().map(|b| b.size()).sum();
        Ok(Self {
            gpu: gpu.clone(),
            kernels,
            bind_group,
            uniform,
            kin,
            aff,
            def,
            mat,
            flags,
            acc,
            device_bytes,
            models: config.materials.iter().map(|m| m.model.clone()).collect(),
            grid: config.grid.clone(),
            boundary: config.boundary,
            particles: n,
            nodes,
            dt: f64::from(prm.dt),
            dt_range: (f64::INFINITY, 0.0),
            time_step: config.time_step,
            // A material no particle has sets no bound (as on the CPU, whose bound is a
            // maximum over the particles).
            wave_speed: (0..config.materials.len())
                .map(|k| {
                    let used = particles.material.iter().any(|&m| m as usize == k);
                    if used {
                        config.materials[k].wave_speed()
                    } else {
                        0.0
                    }
                })
                .collect(),
            unchecked: 0,
            steps: 0,
            time: 0.0,
        })
    }

    /// Sets the clock of a run continued from a saved state (the solver built from its
    /// particles): `steps` steps taken, simulated time `time`, as
    /// `loam_explicit::Solver::set_clock`. The device's step counter, from which a fixed
    /// step's contact takes the time (`end_time` in `common.wgsl`), is set too, so the
    /// continued run takes the steps the run that never stopped takes.
    ///
    /// # Errors
    /// [`GpuError::Unsupported`] for more steps than the device's 32-bit counter holds.
    pub fn set_clock(&mut self, time: f64, steps: usize) -> Result<(), GpuError> {
        let counter = u32::try_from(steps).map_err(|_| GpuError::Unsupported {
            field: "solver.end_time".into(),
            what: format!(
                "a run of {steps} steps (the step counter holds {})",
                u32::MAX
            ),
        })?;
        self.gpu.queue.write_buffer(
            &self.flags,
            (4 * CLOCK) as u64,
            bytemuck::bytes_of(&counter),
        );
        self.steps = steps;
        self.time = time;
        Ok(())
    }

    /// Steps taken.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Simulated time (the sum of the steps, in f64 on the host).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// The last step taken (before any, the fixed step, or the adaptive step's `max_dt`).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// The smallest and the largest step taken (`(∞, 0)` before any).
    pub fn dt_range(&self) -> (f64, f64) {
        self.dt_range
    }

    /// The device memory the solver holds: the sum of the sizes of the buffers it allocated
    /// (particles, grid, flags, table, uniform block), in bytes.
    pub fn device_bytes(&self) -> u64 {
        self.device_bytes
    }

    /// The adapter the steps run on ([`Gpu::name`]) and how P2G adds into the grid
    /// ([`Gpu::p2g`]).
    pub fn device_name(&self) -> String {
        format!("{} (P2G: {})", self.gpu.name(), self.gpu.p2g())
    }

    /// Records `steps` steps into command buffers of [`STEPS_PER_SUBMIT`] steps each and
    /// submits them, without waiting.
    fn submit(&mut self, steps: usize) {
        let mut left = steps;
        while left > 0 {
            let k = left.min(STEPS_PER_SUBMIT);
            let mut encoder =
                self.gpu
                    .device
                    .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                        label: Some("steps"),
                    });
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("steps"),
                    timestamp_writes: None,
                });
                pass.set_bind_group(0, &self.bind_group, &[]);
                for _ in 0..k {
                    self.kernels.step(&mut pass, self.particles, self.nodes, D);
                }
            }
            self.gpu.queue.submit([encoder.finish()]);
            left -= k;
            self.count_steps(k);
        }
    }

    /// Counts `k` submitted steps of the current `dt` in the step counter and the clock.
    fn count_steps(&mut self, k: usize) {
        self.steps += k;
        // Summed step by step, as the CPU solver's clock is.
        for _ in 0..k {
            self.time += self.dt;
        }
        self.dt_range = (self.dt_range.0.min(self.dt), self.dt_range.1.max(self.dt));
    }

    /// Takes `steps` steps, reading the stability flags back every [`CHECK_EVERY`] steps and
    /// at the end; the first flag raised stops the run with the ids of the particles.
    pub fn advance(&mut self, steps: usize) -> Result<(), GpuError> {
        if let TimeStep::Adaptive { .. } = self.time_step {
            for _ in 0..steps {
                self.adaptive_step(f64::INFINITY)?;
            }
            return self.check();
        }
        let mut left = steps;
        while left > 0 {
            let k = left.min(CHECK_EVERY);
            self.submit(k);
            self.check()?;
            left -= k;
        }
        Ok(())
    }

    /// The cap on the next step that makes a run land on `t_end`, as
    /// `loam_explicit::Solver::next_step_cap`: `None` once `t_end` is reached; with a fixed
    /// step, unbounded while more than a round-off allowance remains; with an adaptive step,
    /// the time left.
    pub fn next_step_cap(&self, t_end: f64) -> Option<f64> {
        let left = t_end - self.time;
        match self.time_step {
            TimeStep::Fixed { dt } => {
                let allowance = (1e-9 * t_end.abs()).min(0.5 * dt);
                (left > allowance).then_some(f64::INFINITY)
            }
            TimeStep::Adaptive { .. } => (left > 1e-12 * t_end.abs().max(1e-300)).then_some(left),
        }
    }

    /// Takes up to `steps` steps towards `t_end` (see [`GpuSolver::next_step_cap`]), the last
    /// one shortened to land on it with an adaptive step; returns whether `t_end` is reached.
    /// The flags are read every [`CHECK_EVERY`] steps and at the end.
    pub fn advance_toward(&mut self, t_end: f64, steps: usize) -> Result<bool, GpuError> {
        for _ in 0..steps {
            let Some(cap) = self.next_step_cap(t_end) else {
                break;
            };
            self.submit_one(cap)?;
        }
        self.check()?;
        Ok(self.next_step_cap(t_end).is_none())
    }

    /// One step, an adaptive one no longer than `cap` (a fixed step is never shortened), and
    /// the stability flags read back: the GPU's `loam_explicit::Solver::step`.
    pub fn step(&mut self, cap: f64) -> Result<(), GpuError> {
        self.submit_one(cap)?;
        self.check()
    }

    /// Submits one step, an adaptive one capped at `cap`.
    fn submit_one(&mut self, cap: f64) -> Result<(), GpuError> {
        match self.time_step {
            TimeStep::Fixed { .. } => self.submit(1),
            TimeStep::Adaptive { .. } => self.adaptive_step(cap)?,
        }
        Ok(())
    }

    /// One adaptive step capped at `cap`: the largest particle speed per material comes back
    /// from the device, and `Δt = min(cfl h / max(c + |v|), max_dt, cap)` (in f64, as the CPU
    /// solver chooses it) goes into the uniform block with the end-of-step time.
    fn adaptive_step(&mut self, cap: f64) -> Result<(), GpuError> {
        let TimeStep::Adaptive { cfl, max_dt } = self.time_step else {
            unreachable!("called for adaptive steps only");
        };
        let materials = self.wave_speed.len();
        let queue = &self.gpu.queue;
        queue.write_buffer(&self.flags, (4 * SPEEDS) as u64, &vec![0u8; 4 * materials]);
        let mut encoder = self
            .gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("speeds"),
            });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("speeds"),
                timestamp_writes: None,
            });
            pass.set_bind_group(0, &self.bind_group, &[]);
            self.kernels.speeds(&mut pass, self.particles);
        }
        queue.submit([encoder.finish()]);
        let speeds = self.read_at(&self.flags, SPEEDS, materials)?;
        let rate = speeds
            .iter()
            .zip(&self.wave_speed)
            .map(|(&v, &c)| c + f64::from(v))
            .fold(0.0, f64::max);
        let dt = (cfl * self.grid.h / rate).min(max_dt).min(cap);
        let write = |offset: usize, x: f32| {
            queue.write_buffer(&self.uniform, offset as u64, bytemuck::bytes_of(&x));
        };
        write(std::mem::offset_of!(Params, dt), dt as f32);
        write(
            std::mem::offset_of!(Params, time_end),
            (self.time + dt) as f32,
        );
        self.dt = dt;
        // `submit` adds one step of `self.dt` to the clock and the range.
        self.submit(1);
        self.unchecked += 1;
        if self.unchecked >= CHECK_EVERY {
            self.unchecked = 0;
            self.check()?;
        }
        Ok(())
    }

    /// Reads the first `words` f32 words of `buffer` back.
    fn read(&self, buffer: &wgpu::Buffer, words: usize) -> Result<Vec<f32>, GpuError> {
        self.read_at(buffer, 0, words)
    }

    /// Reads `words` f32 words of `buffer` from word `first` on back.
    fn read_at(
        &self,
        buffer: &wgpu::Buffer,
        first: usize,
        words: usize,
    ) -> Result<Vec<f32>, GpuError> {
        let bytes = self.read_bytes(buffer, (4 * first) as u64, (4 * words) as u64)?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }

    /// Reads `size` bytes of `buffer` from byte `offset` on back, through a mapped copy.
    fn read_bytes(
        &self,
        buffer: &wgpu::Buffer,
        offset: u64,
        size: u64,
    ) -> Result<Vec<u8>, GpuError> {
        let staging = self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("read-back"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self
            .gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("read-back"),
            });
        encoder.copy_buffer_to_buffer(buffer, offset, &staging, 0, size);
        self.gpu.queue.submit([encoder.finish()]);
        let slice = staging.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.gpu
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        rx.recv()
            .map_err(|e| GpuError::Readback(e.to_string()))?
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        let view = slice
            .get_mapped_range()
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        let out = view.to_vec();
        drop(view);
        staging.unmap();
        Ok(out)
    }

    /// Reads the stability flags; an error names the first kind raised and its particles (a
    /// fixed step above the stability bound first, with the step it was found in).
    pub fn check(&self) -> Result<(), GpuError> {
        let words: Vec<u32> = self
            .read(&self.flags, FLAG_WORDS)?
            .iter()
            .map(|x| x.to_bits())
            .collect();
        let step = self.steps;
        // The step's stability check comes first: it flags the cause of what follows.
        for kind in [FLAG_TIME_STEP, 0, 1, 2, 3, 4] {
            let count = words[kind];
            if count == 0 {
                continue;
            }
            let start = FLAG_KINDS + kind * MAX_IDS;
            let mut ids = words[start..start + (count as usize).min(MAX_IDS)].to_vec();
            ids.sort_unstable();
            return Err(match kind {
                FLAG_TIME_STEP => GpuError::TimeStepTooLarge {
                    step: words[FLAG_STEP] as usize,
                    dt: self.dt,
                    count,
                    ids,
                },
                0 => GpuError::NonFinite { step, count, ids },
                1 => GpuError::Inverted { step, count, ids },
                2 => GpuError::Escaped { step, count, ids },
                3 => GpuError::LeftGrid { step, count, ids },
                _ => GpuError::InsideObstacle {
                    step,
                    count,
                    ids,
                    obstacle: words[FLAG_OBSTACLE],
                },
            });
        }
        Ok(())
    }

    /// The mass on the grid after the last step's transfer, over the nodes that are not
    /// ghosts behind a bilateral wall (those were folded onto their mirrors): the particles'
    /// total mass up to f32 round-off.
    pub fn grid_mass(&self) -> Result<f64, GpuError> {
        let acc = self.read(&self.acc, (1 + 2 * D) * self.nodes)?;
        let (pad, cells) = (self.grid.pad, self.grid.cells);
        let folded = |a: usize, side: usize| {
            let w = self.boundary.walls[a][side];
            w.kind != WallKind::Free && !w.separable
        };
        let mut total = 0.0;
        for n in 0..self.nodes {
            let idx = self.grid.multi(n);
            let ghost = (0..D).any(|a| {
                (folded(a, 0) && idx[a] < pad) || (folded(a, 1) && idx[a] > pad + cells[a])
            });
            if !ghost {
                total += acc[n * (1 + 2 * D)] as f64;
            }
        }
        Ok(total)
    }

    /// Copies the device's particle state (x, v, C, F, stress, the equivalent plastic strain)
    /// into `particles` (the particles the solver was built from, in f32 or widened to another
    /// scalar type such as f64 for output); once a step is taken, a Drucker–Prager particle's
    /// state tensor is `I + 2 C⁻¹:σ` of its stress, as the CPU's return mapping leaves it
    /// (computed in f32 by `DruckerPrager::compliance`), and a J2 particle's is
    /// `bₑ = exp(2 C⁻¹:(det F σ))` (`J2::elastic_left_cauchy_green`). Their other fields are
    /// left as they are.
    pub fn read_particles<T: Scalar>(
        &self,
        particles: &mut Particles<T, D>,
    ) -> Result<(), GpuError> {
        let n = self.particles;
        let kin = self.read(&self.kin, 2 * D * n)?;
        let aff = self.read(&self.aff, D * D * n)?;
        let def = self.read(&self.def, D * D * n)?;
        let mat = self.read(&self.mat, 10 * n)?;
        let t = |x: f32| T::cst(f64::from(x));
        for i in 0..n {
            particles.x[i] = Vector::from_fn(|a, _| t(kin[i * D + a]));
            particles.v[i] = Vector::from_fn(|a, _| t(kin[D * n + i * D + a]));
            particles.c[i] = Tensor::from_fn(|r, c| t(aff[i * D * D + r * D + c]));
            particles.f[i] = Tensor::from_fn(|r, c| t(def[i * D * D + r * D + c]));
            let s = &mat[6 * i..6 * i + 6];
            let stress = Matrix3::new(s[0], s[3], s[4], s[3], s[1], s[5], s[4], s[5], s[2]);
            particles.stress[i] = stress.map(t);
            particles.state[i].plastic_strain = t(mat[9 * n + i]);
            let tensor = match &self.models[particles.material[i] as usize] {
                _ if self.steps == 0 => None,
                Model::DruckerPrager(dp) => {
                    Some(Matrix3::identity() + dp.compliance(&stress) * 2.0)
                }
                Model::J2(j2) => {
                    let f = Tensor::<f32, D>::from_fn(|r, c| def[i * D * D + r * D + c]);
                    Some(j2.elastic_left_cauchy_green(&(stress * det(&f))))
                }
                _ => None,
            };
            if let Some(tensor) = tensor {
                particles.state[i].tensor = tensor.map(t);
            }
        }
        Ok(())
    }
}
