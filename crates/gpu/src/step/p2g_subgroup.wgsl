// Particle to grid with the entries summed within a subgroup first: a run of consecutive
// lanes whose particles share a stencil (the same first node, so the same B^D nodes) sums
// its entries by shuffles, and only the run's first lane adds them to the grid. Particles
// filled in as a lattice lie side by side along x, two or more to a cell, so the scatter
// adds about half as often or less; where they have parted, the runs are shorter, with the
// same sums. Compiled after p2g.wgsl where the adapter has subgroup operations
// (`Features::SUBGROUP`).

// The key of a thread without a particle on the grid (no stencil has this first node).
const NO_KEY: u32 = 0xffffffffu;

// How many lanes from `lane` on hold its key without a break: one more than the run of set
// bits from bit `lane` of `same`, the ballot of "lane + 1 holds my key" (at most 128 lanes).
fn run_length(same: vec4<u32>, lane: u32) -> u32 {
    var n = 1u;
    var j = lane;
    loop {
        let off = j % 32u;
        // Trailing ones of the word from bit `off`; the bits shifted in are zeros, so the
        // count stops at the end of the word.
        let t = countTrailingZeros(~(same[j / 32u] >> off));
        n += t;
        j += t;
        if t < 32u - off || j >= 128u {
            break;
        }
    }
    return n;
}

// The sum of `x` over the lanes [lane, lane + len): the suffix sums of a segmented scan, by
// doubling (the partner lane + d is taken while it lies in the run, and it then holds the sum
// of its own next d lanes of the run or fewer).
fn run_sum(x: vec4<f32>, len: u32, size: u32) -> vec4<f32> {
    var s = x;
    for (var d = 1u; d < size; d <<= 1u) {
        let o = subgroupShuffleDown(s, d);
        s += select(vec4<f32>(0.0), o, d < len);
    }
    return s;
}

@compute @workgroup_size(WG)
fn p2g_subgroup(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(subgroup_invocation_id) lane: u32,
    @builtin(subgroup_size) size: u32,
) {
    // Every thread goes round the same number of times, so the shuffles see the whole
    // subgroup.
    let step = stride(groups);
    let rounds = (prm.particles + step - 1u) / step;
    for (var round = 0u; round < rounds; round++) {
        let i = gid.x + round * step;
        var sc: Scatter;
        var key = NO_KEY;
        if i < prm.particles {
            sc = prepare(i);
            if sc.st.on_grid {
                key = sc.st.first;
            }
        }
        let next = subgroupShuffleDown(key, 1u);
        let len = run_length(subgroupBallot(lane + 1u < size && next == key), lane);
        let before = subgroupShuffleUp(key, 1u);
        let head = key != NO_KEY && (lane == 0u || before != key);
        for (var k = 0u; k < NK; k++) {
            for (var j = 0u; j < B; j++) {
                let rs = row_sums(sc, j, k);
                for (var n = 0u; n < B; n++) {
                    var e = entry(sc, rs, n);
                    e.mp = run_sum(e.mp, len, size);
                    if TRANSFER != TRANSFER_MLS {
                        e.f = run_sum(vec4<f32>(e.f, 0.0), len, size).xyz;
                    }
                    if head {
                        add_entry(e);
                    }
                }
            }
        }
    }
}
