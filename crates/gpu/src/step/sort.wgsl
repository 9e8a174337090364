// The stable counting sort of the particles by the cell of their stencil's base node, cells
// numbered block by block (blocks of 4^D cells), and the permutation of the particle buffers.
//
// The launcher prepends `D` and `WG` (workgroup size). The sort (group 0) runs `histogram`,
// `scan` (one workgroup), `scatter` and `rank`; `permute` (group 1 too) then moves one buffer's sections into the scratch buffer, which the host copies
// back. The destination of a particle is `start[bin] + #{j in bin : id_j < id_p}`: the order
// within a bin is that of the original ids, whatever order the atomics arrive in, so the
// sorted order is a function of the bins alone (deterministic).

struct Sort {
    origin: vec4<f32>,
    // Nodes per axis (1 along unused axes).
    nodes: vec4<u32>,
    // Blocks of 4 nodes per axis (1 along unused axes).
    blocks: vec4<u32>,
    inv_h: f32,
    particles: u32,
    bins: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> sp: Sort;
// Particle kinematics: x first (D n), as common.wgsl lays them out.
@group(0) @binding(1) var<storage, read> kin: array<f32>;
// The particle stress and mass buffer; its last section (from 10 n) holds the original ids.
@group(0) @binding(2) var<storage, read> mat: array<u32>;
// Particles per bin; after `scatter`, again the counts.
@group(0) @binding(3) var<storage, read_write> counts: array<atomic<u32>>;
// The exclusive prefix sum of the counts: the first sorted slot of each bin.
@group(0) @binding(4) var<storage, read_write> starts: array<u32>;
// The bin of each particle, by its current slot.
@group(0) @binding(5) var<storage, read_write> keys: array<u32>;
// The current slots of each bin's particles, in the order the atomics gave them.
@group(0) @binding(6) var<storage, read_write> order: array<u32>;
// Where each current slot goes.
@group(0) @binding(7) var<storage, read_write> perm: array<u32>;
// The bin of each sorted slot.
@group(0) @binding(8) var<storage, read_write> sorted_bins: array<u32>;

fn stride(groups: vec3<u32>) -> u32 {
    return groups.x * WG;
}

// The bin of the particle in slot `p`: its base node floor((x − origin)/h − ½) per axis (the
// stencil's, common.wgsl), clamped onto the grid, numbered block-major: block index (x
// fastest), then the node within the block (x fastest).
fn bin_of(p: u32) -> u32 {
    var block = 0u;
    var cell = 0u;
    for (var a = i32(D) - 1; a >= 0; a--) {
        let xi = (kin[p * D + u32(a)] - sp.origin[a]) * sp.inv_h;
        // A NaN coordinate (flagged by the step) goes to node 0.
        var base = 0u;
        if xi == xi {
            base = u32(clamp(floor(xi - 0.5), 0.0, f32(sp.nodes[a] - 1u)));
        }
        block = block * sp.blocks[a] + base / 4u;
        cell = cell * 4u + base % 4u;
    }
    return block * (1u << (2u * D)) + cell;
}

fn id_of(p: u32) -> u32 {
    return mat[10u * sp.particles + p];
}

@compute @workgroup_size(WG)
fn histogram(@builtin(global_invocation_id) gid: vec3<u32>,
             @builtin(num_workgroups) groups: vec3<u32>) {
    for (var p = gid.x; p < sp.particles; p += stride(groups)) {
        let k = bin_of(p);
        keys[p] = k;
        atomicAdd(&counts[k], 1u);
    }
}

var<workgroup> partial: array<u32, WG>;

// One workgroup: each thread sums a contiguous run of bins, the WG sums are scanned in
// workgroup memory (Hillis–Steele), and each thread writes its run's exclusive prefix sums,
// zeroing the counts for `scatter` to count again.
@compute @workgroup_size(WG)
fn scan(@builtin(local_invocation_index) t: u32) {
    let run = (sp.bins + WG - 1u) / WG;
    let lo = min(t * run, sp.bins);
    let hi = min(lo + run, sp.bins);
    var sum = 0u;
    for (var b = lo; b < hi; b++) {
        sum += atomicLoad(&counts[b]);
    }
    partial[t] = sum;
    workgroupBarrier();
    for (var d = 1u; d < WG; d *= 2u) {
        var x = 0u;
        if t >= d {
            x = partial[t - d];
        }
        workgroupBarrier();
        partial[t] += x;
        workgroupBarrier();
    }
    var start = partial[t] - sum;
    for (var b = lo; b < hi; b++) {
        let c = atomicLoad(&counts[b]);
        starts[b] = start;
        atomicStore(&counts[b], 0u);
        start += c;
    }
}

@compute @workgroup_size(WG)
fn scatter(@builtin(global_invocation_id) gid: vec3<u32>,
           @builtin(num_workgroups) groups: vec3<u32>) {
    for (var p = gid.x; p < sp.particles; p += stride(groups)) {
        let k = keys[p];
        order[starts[k] + atomicAdd(&counts[k], 1u)] = p;
    }
}

@compute @workgroup_size(WG)
fn rank(@builtin(global_invocation_id) gid: vec3<u32>,
        @builtin(num_workgroups) groups: vec3<u32>) {
    for (var s = gid.x; s < sp.particles; s += stride(groups)) {
        let p = order[s];
        let k = keys[p];
        let id = id_of(p);
        let lo = starts[k];
        let hi = lo + atomicLoad(&counts[k]);
        var r = 0u;
        for (var j = lo; j < hi; j++) {
            r += select(0u, 1u, id_of(order[j]) < id);
        }
        perm[p] = lo + r;
        sorted_bins[lo + r] = k;
    }
}

// One run of sections of a particle buffer: `sections` arrays of n items of `width` words,
// starting at word `offset`.
struct Section {
    width: u32,
    sections: u32,
    offset: u32,
    particles: u32,
}

@group(1) @binding(0) var<uniform> sec: Section;
@group(1) @binding(1) var<storage, read> src: array<u32>;
@group(1) @binding(2) var<storage, read_write> dst: array<u32>;

// dst[item perm[p] of each section] = src[item p].
@compute @workgroup_size(WG)
fn permute(@builtin(global_invocation_id) gid: vec3<u32>,
           @builtin(num_workgroups) groups: vec3<u32>) {
    let n = sec.particles;
    for (var j = gid.x; j < sec.sections * n; j += stride(groups)) {
        let s = j / n;
        let p = j % n;
        let i_from = sec.offset + (s * n + p) * sec.width;
        let i_to = sec.offset + (s * n + perm[p]) * sec.width;
        for (var k = 0u; k < sec.width; k++) {
            dst[i_to + k] = src[i_from + k];
        }
    }
}
