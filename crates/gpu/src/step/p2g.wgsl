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

// The scatter of one particle: the same sums, row by row, as loam-core's `P2g` (the
// `p2g` and `p2g_momentum` row kernels of transfer.rs).
@compute @workgroup_size(WG)
fn p2g(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var i = gid.x; i < prm.particles; i += stride(groups)) {
        let x = load_vec(x_at(), i);
        let st = stencil(x);
        if !st.on_grid {
            _ = raise(FLAG_LEFT_GRID, i);
            continue;
        }
        let v = load_vec(v_at(), i);
        // The fixed step's check at the start of the step, as the CPU solver's `choose_dt`:
        // Δt > h / (c + |v|), c the material's elastic wave speed (constitutive.wgsl's table).
        if prm.adaptive == 0u {
            let c = table[material_of(i) * MATERIAL_ENTRIES + 2u].y;
            if prm.dt > prm.h / (c + length(v)) && raise(FLAG_TIME_STEP, i) == 0u {
                atomicStore(&flags[FLAG_STEP], atomicLoad(&flags[CLOCK]));
            }
        }
        let f = load_f(i);
        let volume = volume0_of(i) * det3(f);
        var sv = load_stress(i) * volume;
        if D == 2u {
            sv[2] = vec3<f32>(0.0);
            sv[0][2] = 0.0;
            sv[1][2] = 0.0;
        }
        let m = mass_of(i);
        let mls = TRANSFER == TRANSFER_MLS;
        var mc = mat3x3<f32>();
        if affine_transfer() {
            mc = load_c(i) * m;
        }
        if mls {
            mc = mc - sv * (prm.dt * prm.apic_scale);
        }
        let nsv = sv * -1.0;
        let mv = v * m;
        let ax0 = st.ax[0];
        for (var k = 0u; k < NK; k++) {
            for (var j = 0u; j < 3u; j++) {
                let r = row(st, j, k);
                var p_row = mv;
                var f_row = vec3<f32>(0.0);
                for (var c = 1u; c < D; c++) {
                    p_row += mc[c] * r.offset[c];
                    f_row += nsv[c] * r.gradient[c];
                }
                for (var n = 0u; n < 3u; n++) {
                    let w = ax0.w[n] * r.weight;
                    let node = r.index + n;
                    let p = (p_row + mc[0] * ax0.o[n]) * w;
                    acc_add(acc_at(node, 0u), m * w);
                    for (var a = 0u; a < D; a++) {
                        acc_add(acc_at(node, 1u + a), p[a]);
                    }
                    if !mls {
                        let fi = nsv[0] * (ax0.dw[n] * r.weight) + f_row * ax0.w[n];
                        for (var a = 0u; a < D; a++) {
                            acc_add(acc_at(node, 1u + D + a), fi[a]);
                        }
                    }
                }
            }
        }
    }
}
