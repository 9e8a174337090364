// Grid to particle and the end of the particle's step: the gather (PIC / FLIP / APIC / TPIC /
// MLS, row by row as loam-core's `g2p` in transfer.rs), MUSL's second scatter of momentum, and the
// update of F and the stress (constitutive.wgsl) with the wall projection and the stability
// flags (loam-core's `particle_end`). Launched by step/mod.rs with common.wgsl, contact.wgsl
// and constitutive.wgsl in front.

struct Gathered {
    v: vec3<f32>,
    // Σ w v (x_i − x_p)ᵀ / (κ h²) (APIC and MLS).
    affine: mat3x3<f32>,
    // Σ v ∇wᵀ.
    grad_v: mat3x3<f32>,
    // Σ w (v_i − v_iⁿ) (FLIP).
    dv: vec3<f32>,
}

fn gather(st: Stencil) -> Gathered {
    var g: Gathered;
    g.v = vec3<f32>(0.0);
    g.affine = mat3x3<f32>();
    g.grad_v = mat3x3<f32>();
    g.dv = vec3<f32>(0.0);
    let ax0 = st.ax[0];
    for (var k = 0u; k < NK; k++) {
        for (var j = 0u; j < B; j++) {
            let r = row(st, j, k);
            var s = vec3<f32>(0.0);
            var so = vec3<f32>(0.0);
            var sd = vec3<f32>(0.0);
            var sf = vec3<f32>(0.0);
            for (var n = 0u; n < B; n++) {
                let vi = node_v(r.index + n);
                let nv = vi * ax0.w[n];
                s += nv;
                so += nv * ax0.o[n];
                sd += vi * ax0.dw[n];
                if TRANSFER == TRANSFER_FLIP {
                    sf += (vi - node_v_old(r.index + n)) * ax0.w[n];
                }
            }
            let sw = s * r.weight;
            g.v += sw;
            g.affine[0] += so * r.weight;
            g.grad_v[0] += sd * r.weight;
            g.dv += sf * r.weight;
            for (var c = 1u; c < D; c++) {
                g.affine[c] += sw * r.offset[c];
                g.grad_v[c] += s * r.gradient[c];
            }
        }
    }
    g.affine = g.affine * prm.apic_scale;
    return g;
}

// The particle's new affine velocity C: APIC's (and MLS-MPM's) Σ w v (x_i − x_p)ᵀ / (κ h²)
// for the B-splines, the gradient Σ v ∇wᵀ for TPIC and for APIC with the hat and GIMP (whose
// inertia tensor is not κ h² I).
fn affine_of(g: Gathered) -> mat3x3<f32> {
    if (TRANSFER == TRANSFER_APIC || TRANSFER == TRANSFER_MLS) && BSPLINE {
        return g.affine;
    }
    if TRANSFER == TRANSFER_TPIC || TRANSFER == TRANSFER_APIC {
        return g.grad_v;
    }
    return mat3x3<f32>();
}

// The particle's new velocity from its old one `v_p`: FLIP's blend
// α (v_p + Σ w (v_i − v_iⁿ)) + (1 − α) Σ w v_i, or Σ w v_i (loam-core's
// `Transfer::particle_velocity`).
fn velocity_of(v_p: vec3<f32>, g: Gathered) -> vec3<f32> {
    if TRANSFER == TRANSFER_FLIP {
        let a = prm.flip_alpha;
        return (v_p + g.dv) * a + g.v * (1.0 - a);
    }
    return g.v;
}

// The velocity gradient of the step: the affine field for MLS, ∇v otherwise.
fn velocity_gradient(g: Gathered) -> mat3x3<f32> {
    if TRANSFER == TRANSFER_MLS {
        return g.affine;
    }
    return g.grad_v;
}

// Project a particle just past a separable wall back onto it (removing its velocity into the
// wall), update F and the stress, store x, v, F, σ and raise the stability flags.
fn end_particle(i: u32, x0: vec3<f32>, v0: vec3<f32>, l: mat3x3<f32>) {
    var x = x0;
    var v = v0;
    for (var a = 0u; a < D; a++) {
        let lo_sep = (prm.wall_lo[a] & WALL_SEPARABLE) != 0u;
        let hi_sep = (prm.wall_hi[a] & WALL_SEPARABLE) != 0u;
        if lo_sep && x[a] < prm.lo[a] && x[a] >= prm.lo[a] - prm.depth {
            x[a] = prm.lo[a];
            v[a] = max(v[a], 0.0);
        } else if hi_sep && x[a] > prm.hi[a] && x[a] <= prm.hi[a] + prm.depth {
            x[a] = prm.hi[a];
            v[a] = min(v[a], 0.0);
        }
    }
    let f_n = load_f(i);
    var f = f_n;
    var delta_f = mat3x3<f32>(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 0.0, 1.0)) + l * prm.dt;
    if D == 2u {
        delta_f[2][2] = 1.0;
    }
    f = delta_f * f;
    let updated = update_stress(
        material_of(i), f, delta_f, l, load_stress(i), det3(f_n), plastic_strain_of(i)
    );
    let stress = updated.sigma;
    store_vec(x_at(), i, x);
    store_vec(v_at(), i, v);
    store_f(i, f);
    store_stress(i, stress);
    if updated.plastic != 0.0 {
        set_plastic_strain(i, plastic_strain_of(i) + updated.plastic);
    }
    var sum = 0.0;
    for (var a = 0u; a < 3u; a++) {
        sum += x[a] + v[a] + f[a][0] + f[a][1] + f[a][2];
        sum += stress[a][0] + stress[a][1] + stress[a][2];
    }
    if !finite(sum) {
        _ = raise(FLAG_NON_FINITE, i);
    } else if det3(f) <= 0.0 {
        _ = raise(FLAG_INVERTED, i);
    } else {
        var out = false;
        for (var a = 0u; a < D; a++) {
            out = out || x[a] < prm.lo[a] || x[a] > prm.hi[a];
        }
        if out {
            _ = raise(FLAG_ESCAPED, i);
        } else {
            let k = inside_obstacle(x, end_time());
            if k < prm.obstacles && raise(FLAG_INSIDE_OBSTACLE, i) == 0u {
                atomicStore(&flags[FLAG_OBSTACLE], k);
            }
        }
    }
}

// USL: gather, move the particle, and end its step.
@compute @workgroup_size(WG)
fn g2p_usl(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var i = gid.x; i < prm.particles; i += stride(groups)) {
        let x = load_vec(x_at(), i);
        let st = particle_stencil(i, x);
        if !st.on_grid {
            continue;
        }
        let g = gather(st);
        store_c(i, affine_of(g));
        let v = velocity_of(load_vec(v_at(), i), g);
        end_particle(i, x + g.v * prm.dt, v, velocity_gradient(g));
    }
}

// MUSL, first half: gather, keep the moved position aside, and scatter the momentum of the
// new velocity from the start-of-step position.
@compute @workgroup_size(WG)
fn g2p_musl(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var i = gid.x; i < prm.particles; i += stride(groups)) {
        let x = load_vec(x_at(), i);
        let st = particle_stencil(i, x);
        if !st.on_grid {
            continue;
        }
        let g = gather(st);
        let c = affine_of(g);
        let v = velocity_of(load_vec(v_at(), i), g);
        store_vec(x_next_at(), i, x + g.v * prm.dt);
        store_vec(v_at(), i, v);
        store_c(i, c);
        // The gather (p2g_gather.wgsl's `gather_momentum`) reads the stored v and C instead.
        if GATHER {
            continue;
        }
        let m = mass_of(i);
        let mc = c * m;
        let mv = v * m;
        let ax0 = st.ax[0];
        for (var k = 0u; k < NK; k++) {
            for (var j = 0u; j < B; j++) {
                let r = row(st, j, k);
                var p_row = mv;
                for (var col = 1u; col < D; col++) {
                    p_row += mc[col] * r.offset[col];
                }
                for (var n = 0u; n < B; n++) {
                    let p = (p_row + mc[0] * ax0.o[n]) * (ax0.w[n] * r.weight);
                    for (var a = 0u; a < D; a++) {
                        acc_add(acc_at(r.index + n, 1u + a), p[a]);
                    }
                }
            }
        }
    }
}

// MUSL, second half: the velocity gradient from the second grid velocity at the start-of-step
// stencil, then the end of the step at the moved position.
@compute @workgroup_size(WG)
fn end_musl(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var i = gid.x; i < prm.particles; i += stride(groups)) {
        let st = particle_stencil(i, load_vec(x_at(), i));
        if !st.on_grid {
            continue;
        }
        let l = velocity_gradient(gather(st));
        end_particle(i, load_vec(x_next_at(), i), load_vec(v_at(), i), l);
    }
}
