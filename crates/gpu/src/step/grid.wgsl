// The grid stages: the ghost layers behind bilateral walls folded onto their mirror images,
// the momentum update with the wall law, the ghost velocities reflected back, and (MUSL) the
// second velocity. Launched by step/mod.rs with common.wgsl and contact.wgsl in front; `AXIS` picks the axis
// of the ghost passes and `FOLD_ALL` whether a fold carries mass and force too (first
// transfer) or the momentum alone (MUSL's second one).

// The wall of `side` if it has mirrored ghost layers (a bilateral wall that is not free).
fn mirrored(side: u32) -> u32 {
    let wall = wall_of(AXIS, side);
    if (wall & WALL_SEPARABLE) != 0u {
        return WALL_FREE;
    }
    return wall & 15u;
}

// The image of a ghost vector across the wall: the normal component flips on a slip wall,
// every component on a fixed or no-slip one.
fn image(kind: u32, v: vec3<f32>) -> vec3<f32> {
    if kind == WALL_SLIP {
        var w = v;
        w[AXIS] = -w[AXIS];
        return w;
    }
    return -v;
}

fn fold_from(node: u32, ghost: u32, kind: u32) {
    if FOLD_ALL {
        acc_store(acc_at(node, 0u), acc_load(acc_at(node, 0u)) + acc_load(acc_at(ghost, 0u)));
    }
    var p = vec3<f32>(0.0);
    var f = vec3<f32>(0.0);
    for (var a = 0u; a < D; a++) {
        p[a] = acc_load(acc_at(ghost, 1u + a));
        f[a] = acc_load(acc_at(ghost, 1u + D + a));
    }
    p = image(kind, p);
    f = image(kind, f);
    for (var a = 0u; a < D; a++) {
        let e = acc_at(node, 1u + a);
        acc_store(e, acc_load(e) + p[a]);
        if FOLD_ALL {
            let g = acc_at(node, 1u + D + a);
            acc_store(g, acc_load(g) + f[a]);
        }
    }
}

// Each node of a mirror layer (1..=pad nodes inside a face) takes in its ghost image.
@compute @workgroup_size(WG)
fn fold(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let pad = prm.pad;
    let face_hi = pad + prm.cells[AXIS];
    let lo = mirrored(0u);
    let hi = mirrored(1u);
    for (var n = gid.x; n < prm.nodes.w; n += stride(groups)) {
        var idx = node_index(n);
        let i = idx[AXIS];
        if lo != WALL_FREE && i > pad && i <= 2u * pad {
            idx[AXIS] = 2u * pad - i;
            fold_from(n, node_flat(idx), lo);
            idx[AXIS] = i;
        }
        if hi != WALL_FREE && i < face_hi && i + pad >= face_hi && 2u * face_hi - i < prm.nodes[AXIS] {
            idx[AXIS] = 2u * face_hi - i;
            fold_from(n, node_flat(idx), hi);
        }
    }
}

// Each ghost node takes the image of its mirror's velocity (and, for FLIP, of its
// start-of-step velocity).
@compute @workgroup_size(WG)
fn reflect(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let pad = prm.pad;
    let face_hi = pad + prm.cells[AXIS];
    let lo = mirrored(0u);
    let hi = mirrored(1u);
    for (var n = gid.x; n < prm.nodes.w; n += stride(groups)) {
        var idx = node_index(n);
        let i = idx[AXIS];
        var kind = WALL_FREE;
        if lo != WALL_FREE && i < pad {
            idx[AXIS] = 2u * pad - i;
            kind = lo;
        } else if hi != WALL_FREE && i > face_hi && 2u * face_hi >= i {
            idx[AXIS] = 2u * face_hi - i;
            kind = hi;
        }
        if kind != WALL_FREE {
            let mirror = node_flat(idx);
            set_node_v(n, image(kind, node_v(mirror)));
            if TRANSFER == TRANSFER_FLIP {
                set_node_v_old(n, image(kind, node_v_old(mirror)));
            }
        }
    }
}

fn on_any_face(idx: vec3<u32>) -> bool {
    var face = false;
    for (var a = 0u; a < D; a++) {
        face = face || idx[a] <= prm.pad || idx[a] >= prm.pad + prm.cells[a];
    }
    return face;
}

// v = vⁿ + (f/m + g) Δt with vⁿ = p/m where the mass is above the floor (zero below), then
// contact (friction segments on face nodes, obstacles anywhere) and the wall law (loam-core's
// `momentum_update` and `NodeLaw::apply`); FLIP keeps vⁿ beside v. MUSL's second transfer
// finds the momentum entries zeroed.
@compute @workgroup_size(WG)
fn update(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var n = gid.x; n < prm.nodes.w; n += stride(groups)) {
        let m = acc_load(acc_at(n, 0u));
        var v = vec3<f32>(0.0);
        var v_old = vec3<f32>(0.0);
        var state: State;
        if m > prm.mass_floor {
            var p = vec3<f32>(0.0);
            var f = vec3<f32>(0.0);
            for (var a = 0u; a < D; a++) {
                p[a] = acc_load(acc_at(n, 1u + a));
                f[a] = acc_load(acc_at(n, 1u + D + a));
            }
            v_old = p / m;
            v = v_old + (f / m + prm.gravity.xyz) * prm.dt;
            let idx = node_index(n);
            let face = on_any_face(idx);
            if (face && prm.segments > 0u) || prm.obstacles > 0u {
                state = contact(idx, &v, end_time(), state, true);
            }
            if face {
                state[0] |= walls(idx, &v, 0u, true);
            }
        }
        if MUSL {
            for (var a = 0u; a < D; a++) {
                acc_store(acc_at(n, 1u + a), 0.0);
            }
        }
        set_node_v(n, v);
        set_node_state(n, state);
        if TRANSFER == TRANSFER_FLIP {
            set_node_v_old(n, v_old);
        }
    }
}

// MUSL: the second velocity, momentum over the (folded) mass, with the contact constraints and
// the walls that acted in the first pass (loam-core's `NodeLaw::enforce`).
@compute @workgroup_size(WG)
fn second_velocity(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var n = gid.x; n < prm.nodes.w; n += stride(groups)) {
        let m = acc_load(acc_at(n, 0u));
        var v = vec3<f32>(0.0);
        if m > prm.mass_floor {
            for (var a = 0u; a < D; a++) {
                v[a] = acc_load(acc_at(n, 1u + a)) / m;
            }
            let idx = node_index(n);
            let state = node_state(n);
            if in_contact(state) {
                _ = contact(idx, &v, end_time(), state, false);
            }
            if on_any_face(idx) {
                _ = walls(idx, &v, state[0], false);
            }
        }
        set_node_v(n, v);
    }
}
