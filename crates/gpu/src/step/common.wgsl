// Shared by every kernel of the explicit step: the bindings, the stencil, particle and node
// accessors, the wall law and the stability flags.
//
// The launcher prepends the constants `D` (dimension), `NK` (stencil rows along z: B in 3D,
// 1 in 2D), `S` (accumulator entries per node, 1 + 2D), `WG` (workgroup size), `TRANSFER`,
// `MUSL`, `AXIS` (for the per-axis ghost passes), `MODELS` (bit `MODEL_*` of constitutive.wgsl
// set for each model the scene's materials have), `GIMP` and `CPGIMP` (the shape is of the
// GIMP family; its half-length stretches with F), `STATE_WORDS` (a node's state words), the
// shape file (shape_*.wgsl: the support width `B`, the vector `Wv` of one axis' B factors,
// `BSPLINE` and the 1D factors `axis`) and the accumulator binding with its `acc_add` /
// `acc_load` / `acc_store` (native f32 atomics, or a compare-exchange loop on the f32 bits
// where the adapter has none).
//
// Vectors are vec3 and tensors mat3x3 in every dimension: in 2D the z entries are zero (the
// deformation gradient carries F_zz = 1), which leaves every in-plane value bit for bit as the
// D-dimensional formula gives it.

const TRANSFER_PIC: u32 = 0u;
const TRANSFER_APIC: u32 = 1u;
const TRANSFER_TPIC: u32 = 2u;
const TRANSFER_MLS: u32 = 3u;
const TRANSFER_FLIP: u32 = 4u;

// Whether P2G carries the affine term C_p (x_i − x_p) (loam-core's `Transfer::is_affine`).
fn affine_transfer() -> bool {
    return TRANSFER == TRANSFER_APIC || TRANSFER == TRANSFER_TPIC || TRANSFER == TRANSFER_MLS;
}

const WALL_FREE: u32 = 0u;
const WALL_FIXED: u32 = 1u;
const WALL_SLIP: u32 = 2u;
const WALL_NO_SLIP: u32 = 3u;
const WALL_SEPARABLE: u32 = 16u;

// Stability flags: counters, then up to MAX_IDS particle ids per kind.
const FLAG_NON_FINITE: u32 = 0u;
const FLAG_INVERTED: u32 = 1u;
const FLAG_ESCAPED: u32 = 2u;
const FLAG_LEFT_GRID: u32 = 3u;
const FLAG_INSIDE_OBSTACLE: u32 = 4u;
// A fixed step above the stability bound h / (c + |v|) of a particle at the start of a step.
const FLAG_TIME_STEP: u32 = 5u;
const FLAG_KINDS: u32 = 6u;
const MAX_IDS: u32 = 16u;
// After the ids: the obstacle the first particle raising FLAG_INSIDE_OBSTACLE was inside,
// the step in which FLAG_TIME_STEP was first raised, the clock (steps begun, counted by
// `clear`), then per material the largest particle speed (f32 bits, adaptive step).
const FLAG_OBSTACLE: u32 = FLAG_KINDS * (1u + MAX_IDS);
const FLAG_STEP: u32 = FLAG_OBSTACLE + 1u;
const CLOCK: u32 = FLAG_STEP + 1u;
const SPEEDS: u32 = CLOCK + 1u;

struct Params {
    origin: vec4<f32>,
    // Walled bounds of the domain per axis (±f32::MAX where the face is free).
    lo: vec4<f32>,
    hi: vec4<f32>,
    gravity: vec4<f32>,
    // Nodes per axis; w: all nodes.
    nodes: vec4<u32>,
    cells: vec4<u32>,
    // Per axis: wall kind | WALL_SEPARABLE of the lower and the upper face.
    wall_lo: vec4<u32>,
    wall_hi: vec4<u32>,
    h: f32,
    inv_h: f32,
    dt: f32,
    mass_floor: f32,
    // 1/κ h², the inverse of the APIC inertia tensor of the B-splines (zero for the hat and GIMP).
    apic_scale: f32,
    // How far past a separable wall a particle is projected back onto it.
    depth: f32,
    particles: u32,
    pad: u32,
    // Entries of `table` the materials take (MATERIAL_ENTRIES each), then friction segments
    // and obstacles (four each, contact.wgsl).
    material_entries: u32,
    segments: u32,
    obstacles: u32,
    // The obstacles' contact layer φ < reach ‖n‖₁: reach = s h, s the half-width of the
    // support in cells.
    reach: f32,
    // With an adaptive step (adaptive ≠ 0) the host writes dt and the end-of-step time before
    // each step.
    time_end: f32,
    adaptive: u32,
    // FLIP's fraction α of v_p ← α (v_p + Σ w (v_i − v_iⁿ)) + (1 − α) Σ w v_i.
    flip_alpha: f32,
    // Where the particle bins of the gather start in `flags` (bins.wgsl).
    bins: u32,
}

@group(0) @binding(0) var<uniform> prm: Params;
// Particle kinematics, structure of arrays: x (D n), v (D n), x at the end of the step (D n,
// MUSL).
@group(0) @binding(1) var<storage, read_write> kin: array<f32>;
// Affine velocity C, D² per particle (row-major).
@group(0) @binding(2) var<storage, read_write> aff: array<f32>;
// Deformation gradient F, D² per particle (row-major).
@group(0) @binding(3) var<storage, read_write> def: array<f32>;
// Stress (xx, yy, zz, xy, xz, yz; 6 n), mass (n), reference volume (n), material id (n, u32
// bits), equivalent plastic strain (n), and for GIMP the reference half-lengths (D n).
@group(0) @binding(4) var<storage, read_write> mat: array<f32>;
// Node velocities (D N), then the bits of the walls and contacts that acted on each node
// (STATE_WORDS N, u32 bits), then for FLIP the start-of-step velocities v_iⁿ = p_i / m_i
// (D N).
@group(0) @binding(6) var<storage, read_write> nodev: array<f32>;
// The stability flags (below), the clock and the speeds; where the scatter is a gather, then
// the particle bins (bins.wgsl).
@group(0) @binding(7) var<storage, read_write> flags: array<atomic<u32>>;
// Per material MATERIAL_ENTRIES entries (constitutive.wgsl); then the friction segments and
// the obstacles (contact.wgsl).
@group(0) @binding(8) var<storage, read> table: array<vec4<f32>>;

// The accumulator entry `e` (0: mass, 1..=D: momentum, D+1..=2D: force) of node `n`.
fn acc_at(n: u32, e: u32) -> u32 {
    return n * S + e;
}

// ---- grid-stride loops (at most 65,535 workgroups are dispatched per dimension) ----

fn stride(groups: vec3<u32>) -> u32 {
    return groups.x * WG;
}

// ---- particle fields ----

fn load_vec(offset: u32, i: u32) -> vec3<f32> {
    var r = vec3<f32>(0.0);
    for (var a = 0u; a < D; a++) {
        r[a] = kin[offset + i * D + a];
    }
    return r;
}

fn store_vec(offset: u32, i: u32, x: vec3<f32>) {
    for (var a = 0u; a < D; a++) {
        kin[offset + i * D + a] = x[a];
    }
}

fn x_at() -> u32 {
    return 0u;
}

fn v_at() -> u32 {
    return D * prm.particles;
}

fn x_next_at() -> u32 {
    return 2u * D * prm.particles;
}

// A D × D tensor as a mat3x3 (column c, row r at m[c][r]); `fill` goes to the zz entry in 2D.
fn load_c(i: u32) -> mat3x3<f32> {
    var m = mat3x3<f32>();
    for (var r = 0u; r < D; r++) {
        for (var c = 0u; c < D; c++) {
            m[c][r] = aff[i * D * D + r * D + c];
        }
    }
    return m;
}

fn store_c(i: u32, m: mat3x3<f32>) {
    for (var r = 0u; r < D; r++) {
        for (var c = 0u; c < D; c++) {
            aff[i * D * D + r * D + c] = m[c][r];
        }
    }
}

fn load_f(i: u32) -> mat3x3<f32> {
    var m = mat3x3<f32>();
    m[2][2] = 1.0;
    for (var r = 0u; r < D; r++) {
        for (var c = 0u; c < D; c++) {
            m[c][r] = def[i * D * D + r * D + c];
        }
    }
    return m;
}

fn store_f(i: u32, m: mat3x3<f32>) {
    for (var r = 0u; r < D; r++) {
        for (var c = 0u; c < D; c++) {
            def[i * D * D + r * D + c] = m[c][r];
        }
    }
}

fn load_stress(i: u32) -> mat3x3<f32> {
    let s = array<f32, 6>(
        mat[6u * i], mat[6u * i + 1u], mat[6u * i + 2u],
        mat[6u * i + 3u], mat[6u * i + 4u], mat[6u * i + 5u],
    );
    return mat3x3<f32>(
        vec3<f32>(s[0], s[3], s[4]),
        vec3<f32>(s[3], s[1], s[5]),
        vec3<f32>(s[4], s[5], s[2]),
    );
}

fn store_stress(i: u32, s: mat3x3<f32>) {
    mat[6u * i] = s[0][0];
    mat[6u * i + 1u] = s[1][1];
    mat[6u * i + 2u] = s[2][2];
    mat[6u * i + 3u] = s[1][0];
    mat[6u * i + 4u] = s[2][0];
    mat[6u * i + 5u] = s[2][1];
}

fn mass_of(i: u32) -> f32 {
    return mat[6u * prm.particles + i];
}

fn volume0_of(i: u32) -> f32 {
    return mat[7u * prm.particles + i];
}

fn material_of(i: u32) -> u32 {
    return bitcast<u32>(mat[8u * prm.particles + i]);
}

fn plastic_strain_of(i: u32) -> f32 {
    return mat[9u * prm.particles + i];
}

fn set_plastic_strain(i: u32, x: f32) {
    mat[9u * prm.particles + i] = x;
}

// The in-plane determinant (the D × D one: F_zz = 1 in 2D adds nothing).
fn det3(m: mat3x3<f32>) -> f32 {
    return m[0][0] * (m[1][1] * m[2][2] - m[2][1] * m[1][2])
        - m[1][0] * (m[0][1] * m[2][2] - m[2][1] * m[0][2])
        + m[2][0] * (m[0][1] * m[1][2] - m[1][1] * m[0][2]);
}

// ---- node fields ----

// The vector of node `n` in the node buffer's part that starts at word `first`.
fn node_vec(first: u32, n: u32) -> vec3<f32> {
    var r = vec3<f32>(0.0);
    for (var a = 0u; a < D; a++) {
        r[a] = nodev[first + n * D + a];
    }
    return r;
}

fn set_node_vec(first: u32, n: u32, v: vec3<f32>) {
    for (var a = 0u; a < D; a++) {
        nodev[first + n * D + a] = v[a];
    }
}

fn node_v(n: u32) -> vec3<f32> {
    return node_vec(0u, n);
}

fn set_node_v(n: u32, v: vec3<f32>) {
    set_node_vec(0u, n, v);
}

// FLIP's start-of-step velocity v_iⁿ of node `n` (after the velocities and the state words).
fn node_v_old(n: u32) -> vec3<f32> {
    return node_vec((D + STATE_WORDS) * prm.nodes.w, n);
}

fn set_node_v_old(n: u32, v: vec3<f32>) {
    set_node_vec((D + STATE_WORDS) * prm.nodes.w, n, v);
}

// The walls, friction segments and obstacles that acted on a node in the first projection
// (bits of contact.wgsl), for MUSL's second: one word, and one more for each further 32
// obstacles past the first 16 (`STATE_WORDS`, set by the launcher from the scene). Word `w`
// of node `n` lies at D N + w N + n.
alias State = array<u32, STATE_WORDS>;

fn node_state(n: u32) -> State {
    var s: State;
    for (var w = 0u; w < STATE_WORDS; w++) {
        s[w] = bitcast<u32>(nodev[(D + w) * prm.nodes.w + n]);
    }
    return s;
}

fn set_node_state(n: u32, s: State) {
    for (var w = 0u; w < STATE_WORDS; w++) {
        nodev[(D + w) * prm.nodes.w + n] = bitcast<f32>(s[w]);
    }
}

fn node_index(n: u32) -> vec3<u32> {
    let nx = prm.nodes.x;
    let ny = prm.nodes.y;
    return vec3<u32>(n % nx, (n / nx) % ny, n / (nx * ny));
}

fn node_flat(idx: vec3<u32>) -> u32 {
    return idx.x + prm.nodes.x * (idx.y + prm.nodes.y * idx.z);
}

// ---- the stencil ----

// The 1D factors of one axis: weights, their derivatives and the offsets x_i − x_p of the B
// nodes from `base` (the shape file in front, shape_*.wgsl, defines B, the vector `Wv` of B
// entries and `axis`, which forms them).
struct Axis {
    w: Wv,
    dw: Wv,
    o: Wv,
    base: i32,
}

struct Stencil {
    ax: array<Axis, 3>,
    // Flat index of the first node.
    first: u32,
    // False when a node of the stencil is off the grid.
    on_grid: bool,
}

// The stencil of a particle at `x` with half-lengths `hw` per axis (GIMP's; other shapes
// ignore them).
fn stencil(x: vec3<f32>, hw: vec3<f32>) -> Stencil {
    var st: Stencil;
    st.on_grid = true;
    // The z axis of a 2D stencil: one row of weight 1.
    st.ax[2].w = Wv(0.0);
    st.ax[2].w[0] = 1.0;
    st.ax[2].dw = Wv(0.0);
    st.ax[2].o = Wv(0.0);
    st.ax[2].base = 0;
    var idx = vec3<u32>(0u);
    for (var a = 0u; a < D; a++) {
        let xi = (x[a] - prm.origin[a]) * prm.inv_h;
        st.ax[a] = axis(xi, hw[a] * prm.inv_h);
        let b = st.ax[a].base;
        // Also false for a NaN coordinate, whose base is unspecified.
        st.on_grid = st.on_grid && b >= 0 && b + i32(B) <= i32(prm.nodes[a]) && xi == xi;
        idx[a] = u32(max(b, 0));
    }
    st.first = node_flat(idx);
    return st;
}

// Particle `i`'s half-length per axis for GIMP, zero for the other shapes: the reference
// half-length l⁰ (after the particle fields in `mat`), which cpGIMP stretches by the length of
// the deformed material axis, l_a = l⁰_a ‖F e_a‖, clamped to [10⁻⁶ h, h/2] (loam-core's
// `particle_half_width`; F is the start-of-step one wherever a stencil is formed).
fn half_width(i: u32) -> vec3<f32> {
    var l = vec3<f32>(0.0);
    if !GIMP {
        return l;
    }
    for (var a = 0u; a < D; a++) {
        l[a] = mat[10u * prm.particles + i * D + a];
    }
    if CPGIMP {
        let f = load_f(i);
        for (var a = 0u; a < D; a++) {
            var c2 = 0.0;
            for (var b = 0u; b < D; b++) {
                c2 += f[a][b] * f[a][b];
            }
            let s = l[a] * sqrt(c2);
            if s > 0.5 * prm.h {
                l[a] = 0.5 * prm.h;
            } else if s < 1e-6 * prm.h {
                l[a] = 1e-6 * prm.h;
            } else {
                l[a] = s;
            }
        }
    }
    return l;
}

// Particle `i`'s stencil at `x`.
fn particle_stencil(i: u32, x: vec3<f32>) -> Stencil {
    return stencil(x, half_width(i));
}

// One row of the stencil: nodes first + i (i < B) at fixed (j, k), with the factors of the
// axes above 0.
struct Row {
    index: u32,
    weight: f32,
    gradient: vec3<f32>,
    offset: vec3<f32>,
}

fn row(st: Stencil, j: u32, k: u32) -> Row {
    var r: Row;
    r.index = st.first + prm.nodes.x * (j + prm.nodes.y * k);
    r.gradient = vec3<f32>(0.0);
    r.offset = vec3<f32>(0.0);
    if D == 2u {
        r.weight = st.ax[1].w[j];
        r.gradient[1] = st.ax[1].dw[j];
    } else {
        r.weight = st.ax[1].w[j] * st.ax[2].w[k];
        r.gradient[1] = st.ax[1].dw[j] * st.ax[2].w[k];
        r.gradient[2] = st.ax[1].w[j] * st.ax[2].dw[k];
        r.offset[2] = st.ax[2].o[k];
    }
    r.offset[1] = st.ax[1].o[j];
    return r;
}

// ---- walls ----

fn wall_of(axis: u32, side: u32) -> u32 {
    if side == 0u {
        return prm.wall_lo[axis];
    }
    return prm.wall_hi[axis];
}

fn on_face(idx: vec3<u32>, axis: u32, side: u32) -> bool {
    if side == 0u {
        return idx[axis] <= prm.pad;
    }
    return idx[axis] >= prm.pad + prm.cells[axis];
}

// The wall law on a node's velocity. `given` holds the separable walls that acted in the
// first pass (MUSL's second velocity repeats them); with `decide` the separable walls act
// where the velocity points into them, and the bits of those that did are returned.
fn walls(idx: vec3<u32>, v: ptr<function, vec3<f32>>, given: u32, decide: bool) -> u32 {
    var acted = 0u;
    for (var axis = 0u; axis < D; axis++) {
        for (var side = 0u; side < 2u; side++) {
            let wall = wall_of(axis, side);
            let kind = wall & 15u;
            if kind == WALL_FREE || !on_face(idx, axis, side) {
                continue;
            }
            let bit = 1u << (2u * axis + side);
            let separable = (wall & WALL_SEPARABLE) != 0u;
            var acts = true;
            if separable {
                if decide {
                    var vn = (*v)[axis];
                    if side == 0u {
                        vn = -vn;
                    }
                    acts = vn > 0.0;
                } else {
                    acts = (given & bit) != 0u;
                }
                if acts {
                    acted |= bit;
                }
            }
            if kind == WALL_FIXED || (kind == WALL_NO_SLIP && acts) {
                *v = vec3<f32>(0.0);
            } else if kind == WALL_SLIP && acts {
                (*v)[axis] = 0.0;
            }
        }
    }
    return acted;
}

// ---- flags and the clock ----

// Counts particle `i` under the flag `kind` (keeping the first MAX_IDS ids); returns how many
// were counted before it.
fn raise(kind: u32, i: u32) -> u32 {
    let slot = atomicAdd(&flags[kind], 1u);
    if slot < MAX_IDS {
        atomicStore(&flags[FLAG_KINDS + kind * MAX_IDS + slot], i);
    }
    return slot;
}

// The simulated time at the end of the step under way (where contact acts): the host's with
// an adaptive step, else the steps begun times Δt.
fn end_time() -> f32 {
    if prm.adaptive != 0u {
        return prm.time_end;
    }
    return f32(atomicLoad(&flags[CLOCK])) * prm.dt;
}

fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}
