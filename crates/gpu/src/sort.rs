//! The particles' reordering on the device: a stable counting sort by the cell of the
//! stencil's base node, cells numbered block by block, then the permutation of every particle
//! buffer (`step/sort.wgsl`).
//!
//! The bin of a particle is `((block index) · 4^D + (node within the block))` with blocks of
//! 4^D nodes, the block index and the node within it both x-fastest: the particles of one
//! block are contiguous (P2G's neighbouring threads add into the same few hundred nodes), and
//! within a block those of one cell are. The sorted slot of a particle is
//! `start[bin] + #{j in bin : id_j < id}`, `start` the exclusive prefix sum of the bin counts:
//! within a bin the original ids ascend, so the order depends on the bins only, not on the
//! order the atomic counts arrive in.

use crate::params::Params;
use crate::step::{WORKGROUP, groups};
use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

const SORT: &str = include_str!("step/sort.wgsl");

/// The node blocks' edge, in nodes.
const BLOCK: u32 = 4;

/// The uniform block of `sort.wgsl` (`struct Sort`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct SortParams {
    origin: [f32; 4],
    nodes: [u32; 4],
    blocks: [u32; 4],
    inv_h: f32,
    particles: u32,
    bins: u32,
    pad: u32,
}

/// One run of sections of a particle buffer (`struct Section` of `sort.wgsl`): `sections`
/// arrays of `n` items of `width` words from word `offset`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct Section {
    pub width: u32,
    pub sections: u32,
    pub offset: u32,
    pub particles: u32,
}

/// One particle buffer to permute: its sections' bind groups with their item counts.
struct Target {
    buffer: wgpu::Buffer,
    runs: Vec<(wgpu::BindGroup, usize)>,
}

/// The pipelines, buffers and bind groups of the sort.
pub(crate) struct Sorter {
    histogram: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    rank: wgpu::ComputePipeline,
    permute: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    counts: wgpu::Buffer,
    /// The bin of each sorted slot, from the last sort.
    pub sorted_bins: wgpu::Buffer,
    scratch: wgpu::Buffer,
    targets: Vec<Target>,
    particles: usize,
    /// The bytes of the buffers the sort allocated.
    pub device_bytes: u64,
}

fn layout_entry(binding: u32, read_only: bool, uniform: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: if uniform {
                wgpu::BufferBindingType::Uniform
            } else {
                wgpu::BufferBindingType::Storage { read_only }
            },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A bind group of `layout` holding `buffers` whole, at bindings 0, 1, … in order.
pub(crate) fn bind(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &buffers
            .iter()
            .enumerate()
            .map(|(b, buffer)| wgpu::BindGroupEntry {
                binding: b as u32,
                resource: buffer.as_entire_binding(),
            })
            .collect::<Vec<_>>(),
    })
}

fn scratch_buffer(device: &wgpu::Device, label: &str, words: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: (4 * words.max(1)) as u64,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

impl Sorter {
    /// The sort of the `prm.particles` particles of a `dim`-dimensional run whose positions
    /// are the first section of `kin`, whose original ids are the last section of `mat`, and
    /// whose buffers `targets` (each with its sections) are permuted after each sort.
    pub fn new(
        device: &wgpu::Device,
        dim: usize,
        prm: &Params,
        kin: &wgpu::Buffer,
        mat: &wgpu::Buffer,
        targets: &[(&wgpu::Buffer, &[Section])],
    ) -> Self {
        let n = prm.particles as usize;
        let mut sp = SortParams::zeroed();
        for a in 0..4 {
            let nodes = if a < dim { prm.nodes[a] } else { 1 };
            sp.origin[a] = prm.origin[a];
            sp.nodes[a] = nodes;
            sp.blocks[a] = nodes.div_ceil(BLOCK);
        }
        sp.inv_h = prm.inv_h;
        sp.particles = prm.particles;
        let bins = sp.blocks.iter().product::<u32>() * BLOCK.pow(dim as u32);
        sp.bins = bins;
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("sort params"),
            contents: bytemuck::bytes_of(&sp),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let counts = scratch_buffer(device, "bin counts", bins as usize);
        let starts = scratch_buffer(device, "bin starts", bins as usize);
        let keys = scratch_buffer(device, "particle bins", n);
        let order = scratch_buffer(device, "bin contents", n);
        let perm = scratch_buffer(device, "destinations", n);
        let sorted_bins = scratch_buffer(device, "sorted bins", n);
        let scratch_words = targets
            .iter()
            .map(|(b, _)| (b.size() / 4) as usize)
            .max()
            .unwrap_or(0);
        let scratch = scratch_buffer(device, "permuted particles", scratch_words);

        // The uniform block, the positions and ids (read only), then the sort's own buffers.
        let entries: Vec<_> = (0..=8).map(|b| layout_entry(b, b <= 2, b == 0)).collect();
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("loam sort"),
            entries: &entries,
        });
        let section_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("loam permute"),
            entries: &[
                layout_entry(0, true, true),
                layout_entry(1, true, false),
                layout_entry(2, false, false),
            ],
        });
        let bind_group = bind(
            device,
            "loam sort",
            &layout,
            &[
                &uniform,
                kin,
                mat,
                &counts,
                &starts,
                &keys,
                &order,
                &perm,
                &sorted_bins,
            ],
        );
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("loam sort"),
            source: wgpu::ShaderSource::Wgsl(
                format!("const D: u32 = {dim}u;\nconst WG: u32 = {WORKGROUP}u;\n{SORT}").into(),
            ),
        });
        let pipeline_layout = |layouts: &[Option<&wgpu::BindGroupLayout>]| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("loam sort"),
                bind_group_layouts: layouts,
                immediate_size: 0,
            })
        };
        let sort_layout = pipeline_layout(&[Some(&layout)]);
        let permute_layout = pipeline_layout(&[Some(&layout), Some(&section_layout)]);
        let pipeline = |layout: &wgpu::PipelineLayout, entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                cache: None,
            })
        };
        let targets = targets
            .iter()
            .map(|&(buffer, sections)| Target {
                buffer: buffer.clone(),
                runs: sections
                    .iter()
                    .map(|s| {
                        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                            label: Some("section"),
                            contents: bytemuck::bytes_of(s),
                            usage: wgpu::BufferUsages::UNIFORM,
                        });
                        let group = bind(
                            device,
                            "loam sort section",
                            &section_layout,
                            &[&params, buffer, &scratch],
                        );
                        (group, (s.sections * s.particles) as usize)
                    })
                    .collect(),
            })
            .collect();
        let device_bytes = [&uniform, &counts, &starts, &keys, &order, &perm]
            .iter()
            .map(|b| b.size())
            .sum::<u64>()
            + sorted_bins.size()
            + scratch.size();
        Self {
            histogram: pipeline(&sort_layout, "histogram"),
            scan: pipeline(&sort_layout, "scan"),
            scatter: pipeline(&sort_layout, "scatter"),
            rank: pipeline(&sort_layout, "rank"),
            permute: pipeline(&permute_layout, "permute"),
            bind_group,
            counts,
            sorted_bins,
            scratch,
            targets,
            particles: n,
            device_bytes,
        }
    }

    /// Records one sort and the permutation of every target buffer into `encoder`.
    pub fn record(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.clear_buffer(&self.counts, 0, None);
        let gp = groups(self.particles);
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("sort"),
                timestamp_writes: None,
            });
            pass.set_bind_group(0, &self.bind_group, &[]);
            for (pipeline, g) in [
                (&self.histogram, gp),
                (&self.scan, 1),
                (&self.scatter, gp),
                (&self.rank, gp),
            ] {
                pass.set_pipeline(pipeline);
                pass.dispatch_workgroups(g, 1, 1);
            }
        }
        for target in &self.targets {
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("permute"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&self.permute);
                pass.set_bind_group(0, &self.bind_group, &[]);
                for (group, items) in &target.runs {
                    pass.set_bind_group(1, group, &[]);
                    pass.dispatch_workgroups(groups(*items), 1, 1);
                }
            }
            let size = target.buffer.size();
            encoder.copy_buffer_to_buffer(&self.scratch, 0, &target.buffer, 0, size);
        }
    }
}
