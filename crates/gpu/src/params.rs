//! The constants of a run as the kernels read them, built from an explicit-solver
//! [`Config`], with the checks that the GPU path supports the scene.

use crate::GpuError;
use bytemuck::{Pod, Zeroable};
use loam_core::constitutive::{
    Elasticity, Hencky, Lame, LinearElastic, Material, Model, NeoHookean,
};
use loam_core::contact::{FrictionSegment, Obstacle, ObstacleShape};
use loam_core::grid::Grid;
use loam_core::step::PROJECTION_DEPTH;
use loam_core::{Scheme, TimeStep, Transfer, WallKind};
use loam_explicit::{Config, MASS_EPS};

/// The uniform block of `common.wgsl` (`struct Params`), field for field.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct Params {
    pub origin: [f32; 4],
    pub lo: [f32; 4],
    pub hi: [f32; 4],
    pub gravity: [f32; 4],
    pub nodes: [u32; 4],
    pub cells: [u32; 4],
    pub wall_lo: [u32; 4],
    pub wall_hi: [u32; 4],
    pub h: f32,
    pub inv_h: f32,
    pub dt: f32,
    pub mass_floor: f32,
    pub apic_scale: f32,
    pub depth: f32,
    pub particles: u32,
    pub pad: u32,
    pub material_entries: u32,
    pub segments: u32,
    pub obstacles: u32,
    pub reach: f32,
    pub time_end: f32,
    pub adaptive: u32,
    pub flip_alpha: f32,
    pub bins: u32,
}

/// The u32 words of a node's state (`STATE_WORDS` of common.wgsl): the first holds the walls,
/// the segments and 16 obstacles (contact.wgsl's bits), each further one 32 more obstacles.
pub(crate) fn state_words<const D: usize>(config: &Config<f32, D>) -> usize {
    1 + config
        .contact
        .obstacles
        .len()
        .saturating_sub(16)
        .div_ceil(32)
}

/// The transfer scheme as `common.wgsl` numbers it (`TRANSFER_*`).
pub(crate) fn transfer_code(transfer: Transfer) -> u32 {
    match transfer {
        Transfer::Pic => 0,
        Transfer::Apic => 1,
        Transfer::Tpic => 2,
        Transfer::Mls => 3,
        Transfer::Flip { .. } => 4,
    }
}

/// The model of a material as constitutive.wgsl numbers it (`MODEL_*`); `None` for the
/// models the kernels do not hold: Mohr–Coulomb, Modified Cam-Clay and the Hencky form of
/// Drucker–Prager.
fn gpu_model_code(model: &Model<f32>) -> Option<u32> {
    match model {
        Model::Fluid(_) => Some(0),
        Model::NeoHookean(_) => Some(1),
        Model::Hencky(_) => Some(2),
        Model::DruckerPrager(dp) if dp.elasticity == Elasticity::Jaumann => Some(3),
        Model::LinearElastic(_) => Some(4),
        Model::J2(_) => Some(5),
        Model::DruckerPrager(_) | Model::MohrCoulomb(_) | Model::ModifiedCamClay(_) => None,
    }
}

/// [`gpu_model_code`] of a material that [`check_models`] has let through.
fn model_code(model: &Model<f32>) -> u32 {
    gpu_model_code(model).expect("checked by check_models")
}

/// Refuses, naming the material, a config with a model the GPU kernels do not hold.
pub(crate) fn check_models<const D: usize>(config: &Config<f32, D>) -> Result<(), GpuError> {
    for (k, m) in config.materials.iter().enumerate() {
        if gpu_model_code(&m.model).is_none() {
            let what = match &m.model {
                Model::DruckerPrager(_) => {
                    "model \"drucker_prager\" with elasticity = \"hencky\" (the GPU runs \
                     elasticity = \"jaumann\")"
                        .to_owned()
                }
                model => format!("model \"{}\"", model.kind().name()),
            };
            return Err(GpuError::Unsupported {
                field: format!("materials[{k}].model"),
                what,
            });
        }
    }
    Ok(())
}

/// The models of the scene's materials, bit `model_code` set for each (`MODELS` of
/// constitutive.wgsl: the kernels hold only these models' updates).
pub(crate) fn models<const D: usize>(config: &Config<f32, D>) -> u32 {
    config
        .materials
        .iter()
        .fold(0, |bits, m| bits | 1 << model_code(&m.model))
}

/// The words of the node buffer of `nodes` nodes in `D` dimensions (`nodev` of
/// `common.wgsl`): the velocities and the state words ([`state_words`] per node), then for
/// FLIP the start-of-step velocities `v_iⁿ` that G2P's increment `Σ w (v_i − v_iⁿ)` reads.
pub(crate) fn node_words<const D: usize>(config: &Config<f32, D>) -> usize {
    let nodes = config.grid.num_nodes();
    let old = if config.transfer.needs_old_grid_velocity() {
        D * nodes
    } else {
        0
    };
    (D + state_words(config)) * nodes + old
}

/// A wall as `common.wgsl` encodes it: the kind, plus 16 when separable.
fn wall_code(kind: WallKind, separable: bool) -> u32 {
    let k = match kind {
        WallKind::Free => 0,
        WallKind::Fixed => 1,
        WallKind::Slip => 2,
        WallKind::NoSlip => 3,
    };
    k | if separable { 16 } else { 0 }
}

/// The uniform block of a run of `particles` particles with the largest particle mass
/// `max_mass`; with an adaptive step, `dt` and `time_end` are rewritten before every step.
pub(crate) fn params<const D: usize>(
    config: &Config<f32, D>,
    particles: usize,
    max_mass: f64,
) -> Params {
    let (dt, adaptive) = match config.time_step {
        TimeStep::Fixed { dt } => (dt, 0),
        TimeStep::Adaptive { max_dt, .. } => (max_dt, 1),
    };
    let grid = &config.grid;
    let (origin, hi, nodes) = (grid.origin(), grid.hi(), grid.nodes());
    let mut p = Params::zeroed();
    for a in 0..D {
        let [lo_wall, hi_wall] = config.boundary.walls[a];
        p.origin[a] = origin[a] as f32;
        p.lo[a] = if lo_wall.kind == WallKind::Free {
            f32::MIN
        } else {
            grid.lo[a] as f32
        };
        p.hi[a] = if hi_wall.kind == WallKind::Free {
            f32::MAX
        } else {
            hi[a] as f32
        };
        p.gravity[a] = config.gravity[a];
        p.nodes[a] = nodes[a] as u32;
        p.cells[a] = grid.cells[a] as u32;
        p.wall_lo[a] = wall_code(lo_wall.kind, lo_wall.separable);
        p.wall_hi[a] = wall_code(hi_wall.kind, hi_wall.separable);
    }
    p.nodes[3] = grid.num_nodes() as u32;
    p.h = grid.h as f32;
    p.inv_h = (1.0 / grid.h) as f32;
    p.dt = dt as f32;
    p.mass_floor = (MASS_EPS * max_mass) as f32;
    // 1/(κ h²): κ = 1/4 for the quadratic B-spline, 1/3 for the cubic; the hat and GIMP take
    // APIC's C from the velocity gradient instead (g2p.wgsl's `affine_of`).
    p.apic_scale = config
        .shape
        .apic_inverse_inertia()
        .map_or(0.0, |k| (k / (grid.h * grid.h)) as f32);
    p.depth = (PROJECTION_DEPTH * grid.h) as f32;
    p.particles = particles as u32;
    p.pad = grid.pad as u32;
    p.material_entries = (MATERIAL_ENTRIES * config.materials.len()) as u32;
    p.segments = config.contact.segments.len() as u32;
    p.obstacles = config.contact.obstacles.len() as u32;
    p.reach = (config.contact.support * grid.h) as f32;
    p.adaptive = adaptive;
    // FLIP's α in f32, as the CPU's f32 run rounds it (`T::cst`).
    if let Transfer::Flip { alpha } = config.transfer {
        p.flip_alpha = alpha as f32;
    }
    p
}

/// Entries of the table per material (`MATERIAL_ENTRIES` of constitutive.wgsl).
const MATERIAL_ENTRIES: usize = 3;

/// The entries of one material for constitutive.wgsl: `(model, μ, λ, K)` (`K` for
/// Drucker–Prager only; the fluid's moduli are in its second entry), then per model
/// the fluid's `(K, γ, η, γ as a whole number up to 64, else 0: the power then goes through
/// exp and ln, as on the CPU)` or Drucker–Prager's `(α, k, σ_t, q_c)`; then `(α_ψ, c, 0, 0)`
/// with Drucker–Prager's `α_ψ` (0 for the other models) and the wave speed `c`.
/// The Drucker–Prager constants come from loam-core's own methods evaluated in f32, the
/// values the CPU's f32 return mapping uses.
fn material_entries(material: &Material<f32>) -> [[f32; 4]; MATERIAL_ENTRIES] {
    let code = model_code(&material.model) as f32;
    let elastic = |lame: &Lame<f32>| [code, lame.mu, lame.lambda, 0.0];
    let c = material.wave_speed() as f32;
    match &material.model {
        Model::Fluid(f) => {
            let n = f.gamma as u32;
            let whole = if n as f32 == f.gamma && n <= 64 { n } else { 0 };
            [
                [code, 0.0, 0.0, 0.0],
                [f.bulk_modulus, f.gamma, f.viscosity, whole as f32],
                [0.0, c, 0.0, 0.0],
            ]
        }
        Model::NeoHookean(NeoHookean { lame })
        | Model::Hencky(Hencky { lame })
        | Model::LinearElastic(LinearElastic { lame }) => {
            [elastic(lame), [0.0; 4], [0.0, c, 0.0, 0.0]]
        }
        Model::DruckerPrager(m) => {
            let (sigma_t, q_c) = m.corner();
            [
                [code, m.lame.mu, m.lame.lambda, m.bulk_modulus()],
                [m.alpha(), m.k(), sigma_t, q_c],
                [m.alpha_psi(), c, 0.0, 0.0],
            ]
        }
        Model::MohrCoulomb(_) | Model::ModifiedCamClay(_) => {
            unreachable!("refused by check_models")
        }
        Model::J2(m) => [
            [
                code,
                m.lame.mu,
                m.lame.lambda,
                m.lame.lambda + m.lame.mu * (2.0 / 3.0),
            ],
            [m.yield_stress, m.hardening, 0.0, 0.0],
            [0.0, c, 0.0, 0.0],
        ],
    }
}

/// The table of `common.wgsl`: the materials ([`material_entries`]), then four entries per
/// friction segment and per obstacle ([`segment_entries`], [`obstacle_entries`]).
pub(crate) fn table<const D: usize>(config: &Config<f32, D>) -> Vec<[f32; 4]> {
    let mut table: Vec<[f32; 4]> = config.materials.iter().flat_map(material_entries).collect();
    for s in &config.contact.segments {
        table.extend(segment_entries(&config.grid, s));
    }
    for o in &config.contact.obstacles {
        table.extend(obstacle_entries(&config.grid, o));
    }
    table
}

/// A friction segment for contact.wgsl: `(axis, side, μ, 0)`, then per axis the first and the
/// last node index whose coordinate lies in the segment's range, found with loam-core's own
/// test ([`FrictionSegment::contains`], in f64) so that the GPU picks the same nodes (an
/// empty range has first > last), and a zero entry.
///
/// The range is a product over the tangential axes, so each axis's is found by moving one
/// index of a face node inside the segment with the others held (in 3D, holding the other
/// tangential index at a node outside its range would empty every range).
fn segment_entries<const D: usize>(grid: &Grid<D>, s: &FrictionSegment<f32, D>) -> [[f32; 4]; 4] {
    let nodes = grid.nodes();
    let mut first = [1.0f32; 4];
    let mut last = [0.0f32; 4];
    let face = if s.side == 1 { nodes[s.axis] - 1 } else { 0 };
    let inner = (0..grid.num_nodes())
        .map(|n| grid.multi(n))
        .find(|&idx| idx[s.axis] == face && s.contains(grid, idx));
    if let Some(inner) = inner {
        for a in 0..D {
            if a == s.axis {
                (first[a], last[a]) = (0.0, nodes[a] as f32);
                continue;
            }
            let node = |i: usize| {
                let mut idx = inner;
                idx[a] = i;
                idx
            };
            let inside: Vec<usize> = (0..nodes[a])
                .filter(|&i| s.contains(grid, node(i)))
                .collect();
            // Not empty: `inner` itself is inside.
            first[a] = inside[0] as f32;
            last[a] = inside[inside.len() - 1] as f32;
        }
    }
    [
        [s.axis as f32, s.side as f32, s.mu, 0.0],
        first,
        last,
        [0.0; 4],
    ]
}

/// An obstacle for contact.wgsl: the grid origin minus the shape's centre and the kind (0
/// box, 1 cylinder); the box's half-extents or the cylinder's radius, half-length and axis
/// (`D` for a 2D disk), with μ; the velocity and the tolerance of the inside test; the
/// centre. The node coordinates relative to the centre, `(origin − centre) + i h`, then carry
/// f32 round-off of the size of the obstacle's neighbourhood, not of the domain's.
///
/// The inside test is `φ < −tol`: loam-core's `10⁻⁹ ℓ` (`ℓ` the obstacle's size) absorbs the
/// round-off of a particle resting on the surface in f64; in f32, φ of a particle at `x` is
/// off by a few ulps of `|x|` (the subtraction of the centre), so the tolerance is
/// `10⁻⁹ ℓ + 4 ε₃₂ max|x|` over the domain.
fn obstacle_entries<const D: usize>(grid: &Grid<D>, o: &Obstacle<f32, D>) -> [[f32; 4]; 4] {
    let (lo, hi) = o.shape.bounds();
    // loam-core's own centre: the middle of a box, the given point of a cylinder.
    let centre: [f64; D] = match &o.shape {
        ObstacleShape::Box { .. } => std::array::from_fn(|a| 0.5 * (lo[a] + hi[a])),
        ObstacleShape::Cylinder { centre, .. } => *centre,
    };
    let origin = grid.origin();
    let far = (0..D)
        .map(|a| grid.lo[a].abs().max(grid.hi()[a].abs()))
        .fold(0.0, f64::max);
    let tol = 1e-9 * o.shape.size() + 4.0 * f64::from(f32::EPSILON) * far;
    let mut rel = [0.0f32; 4];
    let mut c = [0.0f32; 4];
    let mut velocity = [0.0f32; 4];
    for a in 0..D {
        rel[a] = (origin[a] - centre[a]) as f32;
        c[a] = centre[a] as f32;
        velocity[a] = o.velocity[a];
    }
    velocity[3] = tol as f32;
    let shape = match &o.shape {
        ObstacleShape::Box { .. } => {
            rel[3] = 0.0;
            let mut e = [0.0f32; 4];
            for a in 0..D {
                e[a] = (0.5 * (hi[a] - lo[a])) as f32;
            }
            e[3] = o.mu;
            e
        }
        ObstacleShape::Cylinder {
            radius,
            axis,
            length,
            ..
        } => {
            rel[3] = 1.0;
            let half = if *axis < D { 0.5 * length } else { 0.0 };
            [*radius as f32, half as f32, (*axis).min(D) as f32, o.mu]
        }
    };
    [rel, shape, velocity, c]
}
/// Whether the step is MUSL (a second transfer of momentum) rather than USL.
pub(crate) fn is_musl<const D: usize>(config: &Config<f32, D>) -> bool {
    config.scheme == Scheme::Musl
}
