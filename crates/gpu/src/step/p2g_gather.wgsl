// Particle to grid as a gather, for adapters without float atomics: one thread per node sums
// what the particles of the B^D bins around it (bins.wgsl: the particles whose stencil's
// first node is the node less (i, j, k), i, j, k < B) give it, bin by bin in a fixed order
// and in each bin by particle index. No atomics, and the sums are the same bits from run to
// run. The particles' scatters are read from their places (`bin_payload`), the stencil formed
// again from the position. Compiled after p2g.wgsl and bins.wgsl.

// The node's index along each axis.
fn node_coords(n: u32) -> vec3<u32> {
    let nx = prm.nodes.x;
    let ny = prm.nodes.y;
    return vec3<u32>(n % nx, (n / nx) % ny, n / (nx * ny));
}

// What the particles give node `n`: mass and momentum (x, y, z of `mp`) and force, from the
// scatters of its bins' places (`placed`).
fn gather_node(n: u32) -> Entry {
    let c = node_coords(n);
    var sum: Entry;
    sum.node = n;
    for (var k = 0u; k < NK; k++) {
        for (var j = 0u; j < B; j++) {
            for (var i = 0u; i < B; i++) {
                if c.x < i || c.y < j || c.z < k {
                    continue;
                }
                let b = node_flat(c - vec3<u32>(i, j, k));
                let hi = word(bin_at(b + 1u));
                for (var q = word(bin_at(b)); q < hi; q++) {
                    let sc = placed(q);
                    let e = entry(sc, row_sums(sc, j, k), i);
                    sum.mp += e.mp;
                    sum.f += e.f;
                }
            }
        }
    }
    return sum;
}

// The first transfer: every entry of every node.
@compute @workgroup_size(WG)
fn gather(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var n = gid.x; n < prm.nodes.w; n += stride(groups)) {
        let e = gather_node(n);
        acc_store(acc_at(n, 0u), e.mp.x);
        for (var a = 0u; a < D; a++) {
            acc_store(acc_at(n, 1u + a), e.mp[1u + a]);
            acc_store(acc_at(n, 1u + D + a), e.f[a]);
        }
    }
}

// MUSL's second transfer: the momentum entries, from the places' momentum that
// `bin_payload_second` rewrote (the particles' updated velocity and affine matrix at their
// start-of-step stencils).
@compute @workgroup_size(WG)
fn gather_momentum(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var n = gid.x; n < prm.nodes.w; n += stride(groups)) {
        let e = gather_node(n);
        for (var a = 0u; a < D; a++) {
            acc_store(acc_at(n, 1u + a), e.mp[1u + a]);
        }
    }
}
