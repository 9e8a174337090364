// Particle to grid: mass, momentum and (APIC / PIC / TPIC) internal force scattered onto the
// accumulator with atomic adds, with the fixed step's stability check. Launched by
// step/mod.rs with common.wgsl, contact.wgsl and constitutive.wgsl in front (the last for
// the materials' table layout).

// Zeroes the accumulator (every entry of every node) and counts the step in the clock.
@compute @workgroup_size(WG)
fn clear(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    if gid.x == 0u {
        atomicAdd(&flags[CLOCK], 1u);
    }
    // The gather writes every entry of every node itself.
    if GATHER {
        return;
    }
    let total = prm.nodes.w * S;
    for (var e = gid.x; e < total; e += stride(groups)) {
        acc_store(e, 0.0);
    }
}

// The largest particle speed per material, for the adaptive step: atomicMax on the f32 bits,
// which order as the values do for non-negative floats; a non-finite speed is left out (the
// flags report it), as the CPU's maximum passes over a NaN.
@compute @workgroup_size(WG)
fn speeds(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var i = gid.x; i < prm.particles; i += stride(groups)) {
        let s = length(load_vec(v_at(), i));
        if finite(s) {
            atomicMax(&flags[SPEEDS + material_of(i)], bitcast<u32>(s));
        }
    }
}

// One particle's share of the scatter: its stencil, mass, momentum m v, affine momentum
// m C (less Δt σ V / (κ h²) for MLS-MPM) and −σ V (in 2D with its out-of-plane entries
// zeroed).
struct Scatter {
    st: Stencil,
    m: f32,
    mv: vec3<f32>,
    mc: mat3x3<f32>,
    nsv: mat3x3<f32>,
}

// Loads particle `i` and prepares its scatter, raising its flags: a stencil off the grid
// (then `st.on_grid` is false and nothing else is set) and the fixed step's check at the
// start of the step, as the CPU solver's `choose_dt`: Δt > h / (c + |v|), c the material's
// elastic wave speed (constitutive.wgsl's table).
fn prepare(i: u32) -> Scatter {
    let st = particle_stencil(i, load_vec(x_at(), i));
    if !st.on_grid {
        _ = raise(FLAG_LEFT_GRID, i);
        var sc: Scatter;
        sc.st = st;
        return sc;
    }
    let v = load_vec(v_at(), i);
    if prm.adaptive == 0u {
        let c = table[material_of(i) * MATERIAL_ENTRIES + 2u].y;
        if prm.dt > prm.h / (c + length(v)) && raise(FLAG_TIME_STEP, i) == 0u {
            atomicStore(&flags[FLAG_STEP], atomicLoad(&flags[CLOCK]));
        }
    }
    return payload(i, st, v);
}

// The scatter of particle `i`, with stencil `st` and velocity `v`, without the checks.
fn payload(i: u32, st: Stencil, v: vec3<f32>) -> Scatter {
    var sc: Scatter;
    sc.st = st;
    let f = load_f(i);
    let volume = volume0_of(i) * det3(f);
    var sv = load_stress(i) * volume;
    if D == 2u {
        sv[2] = vec3<f32>(0.0);
        sv[0][2] = 0.0;
        sv[1][2] = 0.0;
    }
    sc.m = mass_of(i);
    if affine_transfer() {
        sc.mc = load_c(i) * sc.m;
    }
    if TRANSFER == TRANSFER_MLS {
        sc.mc = sc.mc - sv * (prm.dt * prm.apic_scale);
    }
    sc.nsv = sv * -1.0;
    sc.mv = v * sc.m;
    return sc;
}

// A stencil row (y, z offsets j, k) of a scatter, with the row's momentum m v + Σ_{a>0}
// (m C)_a o_a and force −Σ_{a>0} (σ V)_a ∂_a w, the x axis left to `entry`.
struct RowSums {
    r: Row,
    p: vec3<f32>,
    f: vec3<f32>,
}

fn row_sums(sc: Scatter, j: u32, k: u32) -> RowSums {
    var rs: RowSums;
    rs.r = row(sc.st, j, k);
    rs.p = sc.mv;
    for (var c = 1u; c < D; c++) {
        rs.p += sc.mc[c] * rs.r.offset[c];
        rs.f += sc.nsv[c] * rs.r.gradient[c];
    }
    return rs;
}

// What a particle adds to one node: the mass w m and momentum w (m v + m C (x_i − x_p)) in
// `mp`, the force −σ V ∇w in `f` (zero for MLS-MPM, whose force rides in the momentum).
struct Entry {
    node: u32,
    mp: vec4<f32>,
    f: vec3<f32>,
}

// The entry of node `n` along x of the row `rs`: the same sums, row by row, as loam-core's
// `P2g` (the `p2g` and `p2g_momentum` row kernels of transfer.rs).
fn entry(sc: Scatter, rs: RowSums, n: u32) -> Entry {
    let ax0 = sc.st.ax[0];
    let w = ax0.w[n] * rs.r.weight;
    var e: Entry;
    e.node = rs.r.index + n;
    e.mp = vec4<f32>(sc.m * w, (rs.p + sc.mc[0] * ax0.o[n]) * w);
    if TRANSFER != TRANSFER_MLS {
        e.f = sc.nsv[0] * (ax0.dw[n] * rs.r.weight) + rs.f * ax0.w[n];
    }
    return e;
}

// Adds an entry to the accumulator.
fn add_entry(e: Entry) {
    acc_add(acc_at(e.node, 0u), e.mp.x);
    for (var a = 0u; a < D; a++) {
        acc_add(acc_at(e.node, 1u + a), e.mp[1u + a]);
    }
    if TRANSFER != TRANSFER_MLS {
        for (var a = 0u; a < D; a++) {
            acc_add(acc_at(e.node, 1u + D + a), e.f[a]);
        }
    }
}

// The scatter, one particle per thread, every entry added atomically.
@compute @workgroup_size(WG)
fn p2g(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var i = gid.x; i < prm.particles; i += stride(groups)) {
        let sc = prepare(i);
        if !sc.st.on_grid {
            continue;
        }
        for (var k = 0u; k < NK; k++) {
            for (var j = 0u; j < B; j++) {
                let rs = row_sums(sc, j, k);
                for (var n = 0u; n < B; n++) {
                    add_entry(entry(sc, rs, n));
                }
            }
        }
    }
}
