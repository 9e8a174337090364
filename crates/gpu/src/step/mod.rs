//! The kernels of one explicit step and the order they run in.
//!
//! The scene's shape file (`shape_linear.wgsl`, `shape_gimp.wgsl`, `shape_quadratic.wgsl`,
//! `shape_cubic.wgsl`: the support width and the 1D weights), `common.wgsl` (bindings, the
//! stencil, the wall law, the flags and the clock) and `contact.wgsl` (friction segments,
//! obstacles) go in front of each kernel file,
//! and `constitutive.wgsl` (the stress updates, the materials' table) in front of `p2g.wgsl`
//! and `g2p.wgsl`,
//! after a header of constants: the dimension, the transfer, the
//! scheme, the axis of the ghost passes, the constitutive models of the scene's materials, and
//! the accumulator with its atomic add (native f32 atomics, or a compare-exchange loop on the
//! bits).
//!
//! One step, all on the device (each dispatch sees the writes of the one before):
//!
//! 1. `clear` the accumulator; `p2g` scatters mass, momentum and force (`p2g_subgroup`, which
//!    sums runs of particles with one stencil in a subgroup first, where the adapter can).
//!    Without float atomics ([`Atomics::Gather`]) the particles are binned by stencil
//!    (`bin_clear`, `bin_count`, `scan_tiles`, `scan_totals`, `scan_add`, `bin_place`,
//!    `bin_sort`, `bin_payload`; bins.wgsl) and `gather` sums each node from its bins
//!    (p2g_gather.wgsl).
//! 2. `fold` per axis: ghost layers behind bilateral walls onto their mirrors.
//! 3. `update`: the momentum update, contact and the wall law per node (FLIP keeps the
//!    start-of-step velocity `v_iⁿ` beside `v_i`); `reflect` per axis (both velocities).
//! 4. USL: `g2p_usl` gathers, moves and ends each particle's step. MUSL: `g2p_musl` gathers
//!    and scatters the new momentum (or `bin_payload_second` and `gather_momentum` sum it
//!    from the bins), `fold`
//!    (momentum only), `second_velocity`, `reflect`, then `end_musl`.

use loam_core::{Shape, ShapeFunction};

use crate::device::Atomics;

/// Threads per workgroup of every kernel.
pub(crate) const WORKGROUP: u32 = 128;

/// The most workgroups one dispatch may have along a dimension; the kernels stride over the
/// rest.
const MAX_GROUPS: u32 = 65_535;

const COMMON: &str = include_str!("common.wgsl");
const CONTACT: &str = include_str!("contact.wgsl");
const P2G: &str = include_str!("p2g.wgsl");
const P2G_SUBGROUP: &str = include_str!("p2g_subgroup.wgsl");
const BINS: &str = include_str!("bins.wgsl");
const P2G_GATHER: &str = include_str!("p2g_gather.wgsl");
const GRID: &str = include_str!("grid.wgsl");
const G2P: &str = include_str!("g2p.wgsl");
const CONSTITUTIVE: &str = include_str!("constitutive.wgsl");
const SHAPE_LINEAR: &str = include_str!("shape_linear.wgsl");
const SHAPE_GIMP: &str = include_str!("shape_gimp.wgsl");
const SHAPE_QUADRATIC: &str = include_str!("shape_quadratic.wgsl");
const SHAPE_CUBIC: &str = include_str!("shape_cubic.wgsl");

/// What a step's kernels are compiled for.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Variant {
    pub dim: usize,
    pub atomics: Atomics,
    /// `TRANSFER_*` of common.wgsl.
    pub transfer: u32,
    pub musl: bool,
    /// Whether the scatter sums runs of particles with one stencil in their subgroup before
    /// adding (`p2g_subgroup.wgsl`; needs `Features::SUBGROUP`).
    pub subgroups: bool,
    /// The models of the scene's materials (`params::models`: bit `MODEL_*` of
    /// constitutive.wgsl set for each).
    pub models: u32,
    /// The shape function (which shape file goes in front of common.wgsl).
    pub shape: Shape,
    /// The u32 words of a node's state (`params::state_words`).
    pub state_words: usize,
}

impl Variant {
    fn source(&self, body: &str, axis: usize, fold_all: bool) -> String {
        let d = self.dim;
        let accumulator = match self.atomics {
            Atomics::Native => {
                "@group(0) @binding(5) var<storage, read_write> acc: array<atomic<f32>>;
fn acc_add(i: u32, x: f32) { atomicAdd(&acc[i], x); }
fn acc_load(i: u32) -> f32 { return atomicLoad(&acc[i]); }
fn acc_store(i: u32, x: f32) { atomicStore(&acc[i], x); }
"
            }
            Atomics::Gather => {
                "@group(0) @binding(5) var<storage, read_write> acc: array<f32>;
fn acc_add(i: u32, x: f32) { acc[i] += x; }
fn acc_load(i: u32) -> f32 { return acc[i]; }
fn acc_store(i: u32, x: f32) { acc[i] = x; }
"
            }
            Atomics::CompareExchange => {
                "@group(0) @binding(5) var<storage, read_write> acc: array<atomic<u32>>;
fn acc_add(i: u32, x: f32) {
    var old = atomicLoad(&acc[i]);
    loop {
        let r = atomicCompareExchangeWeak(&acc[i], old, bitcast<u32>(bitcast<f32>(old) + x));
        if r.exchanged { break; }
        old = r.old_value;
    }
}
fn acc_load(i: u32) -> f32 { return bitcast<f32>(atomicLoad(&acc[i])); }
fn acc_store(i: u32, x: f32) { atomicStore(&acc[i], bitcast<u32>(x)); }
"
            }
        };
        let shape = match self.shape {
            Shape::Linear => SHAPE_LINEAR,
            Shape::Ugimp | Shape::Cpgimp => SHAPE_GIMP,
            Shape::QuadraticBspline => SHAPE_QUADRATIC,
            Shape::CubicBspline => SHAPE_CUBIC,
        };
        format!(
            "const D: u32 = {d}u;\nconst NK: u32 = {nk}u;\nconst S: u32 = {s}u;\n\
             const WG: u32 = {WORKGROUP}u;\nconst TRANSFER: u32 = {t}u;\nconst MUSL: bool = {m};\n\
             const AXIS: u32 = {axis}u;\nconst FOLD_ALL: bool = {fold_all};\n\
             const MODELS: u32 = {models}u;\nconst GATHER: bool = {gather};\n\
             const GIMP: bool = {gimp};\nconst CPGIMP: bool = {cpgimp};\n\
             const STATE_WORDS: u32 = {state_words}u;\n\
             {shape}\n{accumulator}{COMMON}\n{CONTACT}\n{body}",
            nk = if d == 3 {
                self.shape.support_width()
            } else {
                1
            },
            gimp = self.shape.is_gimp(),
            cpgimp = self.shape == Shape::Cpgimp,
            state_words = self.state_words,
            s = 1 + 2 * d,
            t = self.transfer,
            m = self.musl,
            models = self.models,
            gather = self.atomics == Atomics::Gather,
        )
    }
}

/// The compute pipelines of one step.
pub(crate) struct Kernels {
    speeds: wgpu::ComputePipeline,
    clear: wgpu::ComputePipeline,
    /// The scatter, or the gather ([`Atomics::Gather`]).
    p2g: wgpu::ComputePipeline,
    /// Per axis: the first fold (mass, momentum, force) and MUSL's (momentum).
    fold: Vec<[wgpu::ComputePipeline; 2]>,
    reflect: Vec<wgpu::ComputePipeline>,
    update: wgpu::ComputePipeline,
    second_velocity: wgpu::ComputePipeline,
    g2p_usl: wgpu::ComputePipeline,
    g2p_musl: wgpu::ComputePipeline,
    end_musl: wgpu::ComputePipeline,
    /// The binning and the gathers, where P2G is a gather ([`Atomics::Gather`]).
    gather: Option<Gather>,
    musl: bool,
}

/// The pipelines of the gather's P2G (bins.wgsl, p2g_gather.wgsl).
struct Gather {
    bin_clear: wgpu::ComputePipeline,
    bin_count: wgpu::ComputePipeline,
    scan_tiles: wgpu::ComputePipeline,
    scan_totals: wgpu::ComputePipeline,
    scan_add: wgpu::ComputePipeline,
    bin_place: wgpu::ComputePipeline,
    bin_sort: wgpu::ComputePipeline,
    bin_payload: wgpu::ComputePipeline,
    bin_payload_second: wgpu::ComputePipeline,
    gather_momentum: wgpu::ComputePipeline,
}

/// One dispatch of a step: the kernel's entry point, its pipeline and its workgroups.
pub(crate) struct Stage<'a> {
    /// The entry point (`fold`, `reflect` once per axis; MUSL's second passes with a suffix).
    pub name: &'static str,
    pub pipeline: &'a wgpu::ComputePipeline,
    pub groups: u32,
}

/// Workgroups for `n` threads, capped at [`MAX_GROUPS`].
pub(crate) fn groups(n: usize) -> u32 {
    n.div_ceil(WORKGROUP as usize).clamp(1, MAX_GROUPS as usize) as u32
}

impl Kernels {
    /// Compiles the kernels of `variant` against `layout` (the bindings of common.wgsl).
    pub fn new(device: &wgpu::Device, layout: &wgpu::BindGroupLayout, variant: Variant) -> Self {
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("loam step"),
            bind_group_layouts: &[Some(layout)],
            immediate_size: 0,
        });
        let module = |body: &str, axis: usize, fold_all: bool| {
            device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("loam step"),
                source: wgpu::ShaderSource::Wgsl(variant.source(body, axis, fold_all).into()),
            })
        };
        let pipeline = |module: &wgpu::ShaderModule, entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pipeline_layout),
                module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                cache: None,
            })
        };
        let gathers = variant.atomics == Atomics::Gather;
        let p2g_body = if gathers {
            format!("{CONSTITUTIVE}\n{P2G}\n{BINS}\n{P2G_GATHER}")
        } else if variant.subgroups {
            format!("{CONSTITUTIVE}\n{P2G}\n{P2G_SUBGROUP}")
        } else {
            format!("{CONSTITUTIVE}\n{P2G}")
        };
        let p2g = module(&p2g_body, 0, true);
        let gather = gathers.then(|| Gather {
            bin_clear: pipeline(&p2g, "bin_clear"),
            bin_count: pipeline(&p2g, "bin_count"),
            scan_tiles: pipeline(&p2g, "scan_tiles"),
            scan_totals: pipeline(&p2g, "scan_totals"),
            scan_add: pipeline(&p2g, "scan_add"),
            bin_place: pipeline(&p2g, "bin_place"),
            bin_sort: pipeline(&p2g, "bin_sort"),
            bin_payload: pipeline(&p2g, "bin_payload"),
            bin_payload_second: pipeline(&p2g, "bin_payload_second"),
            gather_momentum: pipeline(&p2g, "gather_momentum"),
        });
        let g2p = module(&format!("{CONSTITUTIVE}\n{G2P}"), 0, true);
        let grid: Vec<[wgpu::ShaderModule; 2]> = (0..variant.dim)
            .map(|a| [module(GRID, a, true), module(GRID, a, false)])
            .collect();
        Self {
            speeds: pipeline(&p2g, "speeds"),
            clear: pipeline(&p2g, "clear"),
            p2g: pipeline(
                &p2g,
                if gathers {
                    "gather"
                } else if variant.subgroups {
                    "p2g_subgroup"
                } else {
                    "p2g"
                },
            ),
            fold: grid
                .iter()
                .map(|[all, momentum]| [pipeline(all, "fold"), pipeline(momentum, "fold")])
                .collect(),
            reflect: grid.iter().map(|[m, _]| pipeline(m, "reflect")).collect(),
            update: pipeline(&grid[0][0], "update"),
            second_velocity: pipeline(&grid[0][0], "second_velocity"),
            g2p_usl: pipeline(&g2p, "g2p_usl"),
            g2p_musl: pipeline(&g2p, "g2p_musl"),
            end_musl: pipeline(&g2p, "end_musl"),
            gather,
            musl: variant.musl,
        }
    }

    /// Records the pass that finds the largest particle speed per material (the adaptive
    /// step's bound) into `pass`.
    pub fn speeds(&self, pass: &mut wgpu::ComputePass<'_>, particles: usize) {
        pass.set_pipeline(&self.speeds);
        pass.dispatch_workgroups(groups(particles), 1, 1);
    }

    /// The dispatches of one step, in order, for `particles` particles on `nodes` nodes.
    pub fn stages(&self, particles: usize, nodes: usize, dim: usize) -> Vec<Stage<'_>> {
        let (gp, gn) = (groups(particles), groups(nodes));
        let stage = |name, pipeline, groups| Stage {
            name,
            pipeline,
            groups,
        };
        let mut out = vec![stage("clear", &self.clear, groups(nodes * (1 + 2 * dim)))];
        match &self.gather {
            Some(g) => {
                let bins = groups(nodes + 1);
                out.extend([
                    stage("bin_clear", &g.bin_clear, bins),
                    stage("bin_count", &g.bin_count, gp),
                    stage("scan_tiles", &g.scan_tiles, bins),
                    stage("scan_totals", &g.scan_totals, 1),
                    stage("scan_add", &g.scan_add, bins),
                    stage("bin_place", &g.bin_place, gp),
                    stage("bin_sort", &g.bin_sort, gn),
                    stage("bin_payload", &g.bin_payload, gp),
                    stage("gather", &self.p2g, gn),
                ]);
            }
            None => out.push(stage("p2g", &self.p2g, gp)),
        }
        out.extend(self.fold.iter().map(|[all, _]| stage("fold", all, gn)));
        out.push(stage("update", &self.update, gn));
        out.extend(self.reflect.iter().map(|r| stage("reflect", r, gn)));
        if self.musl {
            out.push(stage("g2p_musl", &self.g2p_musl, gp));
            if let Some(g) = &self.gather {
                out.extend([
                    stage("bin_payload_second", &g.bin_payload_second, gp),
                    stage("gather_momentum", &g.gather_momentum, gn),
                ]);
            }
            out.extend(
                self.fold
                    .iter()
                    .map(|[_, momentum]| stage("fold momentum", momentum, gn)),
            );
            out.push(stage("second_velocity", &self.second_velocity, gn));
            out.extend(self.reflect.iter().map(|r| stage("reflect second", r, gn)));
            out.push(stage("end_musl", &self.end_musl, gp));
        } else {
            out.push(stage("g2p_usl", &self.g2p_usl, gp));
        }
        out
    }

    /// Records one step into `pass`, for `particles` particles on `nodes` nodes (the bind
    /// group must be set).
    pub fn step(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        particles: usize,
        nodes: usize,
        dim: usize,
    ) {
        for s in self.stages(particles, nodes, dim) {
            pass.set_pipeline(s.pipeline);
            pass.dispatch_workgroups(s.groups, 1, 1);
        }
    }
}
