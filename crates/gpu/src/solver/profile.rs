//! Where the device's time goes: every kernel of the step timed with timestamp queries.

use super::GpuSolver;
use crate::error::GpuError;
use loam_core::TimeStep;

/// The device time of each kernel of the step, summed over the profiled steps.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    /// Steps profiled.
    pub steps: usize,
    /// Per kernel, in the order a step runs them: its entry point and its device time in
    /// seconds over all profiled steps (the passes of all axes of `fold` and `reflect`
    /// summed under one name).
    pub stages: Vec<(&'static str, f64)>,
}

impl Profile {
    /// The device time of all kernels, in seconds.
    pub fn total(&self) -> f64 {
        self.stages.iter().map(|(_, t)| t).sum()
    }
}

impl<const D: usize> GpuSolver<D> {
    /// Takes `steps` fixed steps with every kernel in a compute pass of its own, timed by a
    /// timestamp at the start and the end of the pass: `t = (end − start) · period`, the
    /// queue's timestamp period in ns per tick. The state advances as with
    /// [`GpuSolver::advance`] (the same kernels in the same order); the flags are read at the
    /// end. Steps are submitted one at a time, so the figures hold the kernels alone, not the
    /// host's recording. Needs an adapter with timestamp queries ([`crate::Gpu::timestamps`])
    /// and a fixed step.
    pub fn profile(&mut self, steps: usize) -> Result<Profile, GpuError> {
        if !self.gpu.timestamps() {
            return Err(GpuError::Profile(format!(
                "the adapter {} has no timestamp queries",
                self.gpu.name()
            )));
        }
        if let TimeStep::Adaptive { .. } = self.time_step {
            return Err(GpuError::Profile(
                "the scene has an adaptive time step; profile it with a fixed one".into(),
            ));
        }
        let device = &self.gpu.device;
        let count = self.kernels.stages(self.particles, self.nodes, D).len();
        let queries = (2 * count) as u32;
        let bytes = 8 * u64::from(queries);
        let set = device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("kernel times"),
            ty: wgpu::QueryType::Timestamp,
            count: queries,
        });
        let resolved = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("kernel times"),
            size: bytes,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let period = f64::from(self.gpu.queue.get_timestamp_period()) * 1e-9;
        let mut stages: Vec<(&'static str, f64)> = Vec::new();
        for _ in 0..steps {
            let mut encoder =
                self.gpu
                    .device
                    .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                        label: Some("profiled step"),
                    });
            let order = self.kernels.stages(self.particles, self.nodes, D);
            for (i, stage) in order.iter().enumerate() {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(stage.name),
                    timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                        query_set: &set,
                        beginning_of_pass_write_index: Some(2 * i as u32),
                        end_of_pass_write_index: Some(2 * i as u32 + 1),
                    }),
                });
                pass.set_bind_group(0, &self.bind_group, &[]);
                pass.set_pipeline(stage.pipeline);
                pass.dispatch_workgroups(stage.groups, 1, 1);
            }
            encoder.resolve_query_set(&set, 0..queries, &resolved, 0);
            self.gpu.queue.submit([encoder.finish()]);
            let ticks = self.read_bytes(&resolved, 0, bytes)?;
            let ticks: Vec<u64> = bytemuck::pod_collect_to_vec(&ticks);
            for (i, stage) in order.iter().enumerate() {
                // A driver may write timestamps that do not increase across a pass (the
                // counter of another engine); such a pass counts as zero.
                let t = ticks[2 * i + 1].saturating_sub(ticks[2 * i]) as f64 * period;
                match stages.iter_mut().find(|(name, _)| *name == stage.name) {
                    Some((_, sum)) => *sum += t,
                    None => stages.push((stage.name, t)),
                }
            }
            drop(order);
            self.count_steps(1);
        }
        self.check()?;
        Ok(Profile { steps, stages })
    }
}
