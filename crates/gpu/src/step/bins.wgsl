// The particle bins of the gather (p2g_gather.wgsl): every particle on the grid goes into the
// bin of its stencil's first node, and the bins are laid out one after another in `flags`
// (from `prm.bins` on) by a counting sort:
//
// 1. `bin_clear` zeroes the counts; `bin_count` checks each particle as the scatter does
//    (`prepare`: a stencil off the grid, the fixed step's bound), counts it into its bin and
//    keeps its key and its slot in the bin (the count before its own atomic add);
// 2. `scan_tiles`, `scan_totals`, `scan_add`: the exclusive prefix sum of the counts, the
//    bins' starts (per tile of WG bins in workgroup memory, then over the tiles' totals in one
//    workgroup, then the tiles' starts added back);
// 3. `bin_place` puts each particle's index at its bin's start plus its slot;
// 4. `bin_sort` sorts each bin by particle index, so that the order of the gather's sums does
//    not depend on the order in which the atomic counts were taken: the gather is
//    deterministic;
// 5. `bin_payload` writes each binned particle's scatter (`payload`) at its place, so that the
//    gather reads it from consecutive words instead of forming it for each of the particle's
//    B^D nodes (MUSL's second transfer rewrites the momentum part: `bin_payload_second`).
//
// Words from `prm.bins` on: the N + 1 counts (then the starts; the last is the total), the
// tiles' totals (then starts), per particle its key, its slot and the sorted indices, then
// per place the scatter (`PAYLOAD` words; f32 bits).
// Compiled after p2g.wgsl (for `prepare`).

// The key of a particle whose stencil is off the grid (it goes into no bin).
const OFF_GRID: u32 = 0xffffffffu;

fn bins_len() -> u32 {
    return prm.nodes.w + 1u;
}

fn tiles() -> u32 {
    return (bins_len() + WG - 1u) / WG;
}

fn bin_at(b: u32) -> u32 {
    return prm.bins + b;
}

fn tile_at(t: u32) -> u32 {
    return prm.bins + bins_len() + t;
}

fn key_at(i: u32) -> u32 {
    return tile_at(tiles()) + i;
}

fn slot_at(i: u32) -> u32 {
    return key_at(prm.particles + i);
}

fn order_at(q: u32) -> u32 {
    return key_at(2u * prm.particles + q);
}

fn word(at: u32) -> u32 {
    return atomicLoad(&flags[at]);
}

// A place's scatter: x (3), m (1), m v (3), m C (9, by columns), but for MLS-MPM −σ V
// (6: xx, yy, zz, xy, xz, yz), and for GIMP the particle's half-lengths (3).
const HALF_WIDTH_WORD: u32 = select(22u, 16u, TRANSFER == TRANSFER_MLS);
const PAYLOAD: u32 = HALF_WIDTH_WORD + select(0u, 3u, GIMP);

fn payload_at(q: u32) -> u32 {
    return order_at(prm.particles) + q * PAYLOAD;
}

fn store_word(at: u32, x: f32) {
    atomicStore(&flags[at], bitcast<u32>(x));
}

fn load_word(at: u32) -> f32 {
    return bitcast<f32>(atomicLoad(&flags[at]));
}

fn store_words(at: u32, v: vec3<f32>) {
    for (var a = 0u; a < 3u; a++) {
        store_word(at + a, v[a]);
    }
}

fn load_words(at: u32) -> vec3<f32> {
    return vec3<f32>(load_word(at), load_word(at + 1u), load_word(at + 2u));
}

// The momentum part of place `q`'s scatter: m v and m C.
fn put_momentum(q: u32, mv: vec3<f32>, mc: mat3x3<f32>) {
    let at = payload_at(q);
    store_words(at + 4u, mv);
    for (var c = 0u; c < 3u; c++) {
        store_words(at + 7u + 3u * c, mc[c]);
    }
}

// Place `q`'s scatter, with the stencil of its position.
fn placed(q: u32) -> Scatter {
    let at = payload_at(q);
    var sc: Scatter;
    var hw = vec3<f32>(0.0);
    if GIMP {
        hw = load_words(at + HALF_WIDTH_WORD);
    }
    sc.st = stencil(load_words(at), hw);
    sc.m = load_word(at + 3u);
    sc.mv = load_words(at + 4u);
    for (var c = 0u; c < 3u; c++) {
        sc.mc[c] = load_words(at + 7u + 3u * c);
    }
    if TRANSFER != TRANSFER_MLS {
        let s = array<f32, 6>(
            load_word(at + 16u), load_word(at + 17u), load_word(at + 18u), load_word(at + 19u), load_word(at + 20u), load_word(at + 21u),
        );
        sc.nsv = mat3x3<f32>(
            vec3<f32>(s[0], s[3], s[4]),
            vec3<f32>(s[3], s[1], s[5]),
            vec3<f32>(s[4], s[5], s[2]),
        );
    }
    return sc;
}

@compute @workgroup_size(WG)
fn bin_clear(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var b = gid.x; b < bins_len(); b += stride(groups)) {
        atomicStore(&flags[bin_at(b)], 0u);
    }
}

@compute @workgroup_size(WG)
fn bin_count(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var i = gid.x; i < prm.particles; i += stride(groups)) {
        let st = prepare(i).st;
        var key = OFF_GRID;
        if st.on_grid {
            key = st.first;
            atomicStore(&flags[slot_at(i)], atomicAdd(&flags[bin_at(key)], 1u));
        }
        atomicStore(&flags[key_at(i)], key);
    }
}

var<workgroup> scan: array<u32, WG>;

// The inclusive prefix sum of `scan` in place (Hillis and Steele: log2 WG rounds), called by
// every thread of the workgroup, `l` its local index.
fn scan_workgroup(l: u32) {
    for (var d = 1u; d < WG; d *= 2u) {
        workgroupBarrier();
        var x = 0u;
        if l >= d {
            x = scan[l - d];
        }
        workgroupBarrier();
        scan[l] += x;
    }
    workgroupBarrier();
}

// Per tile of WG bins: the exclusive prefix sum of its counts, and its total.
@compute @workgroup_size(WG)
fn scan_tiles(
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let l = lid.x;
    for (var t = wid.x; t < tiles(); t += groups.x) {
        let b = t * WG + l;
        var c = 0u;
        if b < bins_len() {
            c = word(bin_at(b));
        }
        scan[l] = c;
        scan_workgroup(l);
        if b < bins_len() {
            atomicStore(&flags[bin_at(b)], scan[l] - c);
        }
        if l == WG - 1u {
            atomicStore(&flags[tile_at(t)], scan[l]);
        }
        workgroupBarrier();
    }
}

// The exclusive prefix sum of the tiles' totals, in one workgroup, WG tiles at a time.
@compute @workgroup_size(WG)
fn scan_totals(@builtin(local_invocation_id) lid: vec3<u32>) {
    let l = lid.x;
    var carry = 0u;
    for (var t0 = 0u; t0 < tiles(); t0 += WG) {
        let t = t0 + l;
        var c = 0u;
        if t < tiles() {
            c = word(tile_at(t));
        }
        scan[l] = c;
        scan_workgroup(l);
        if t < tiles() {
            atomicStore(&flags[tile_at(t)], carry + scan[l] - c);
        }
        carry += scan[WG - 1u];
        workgroupBarrier();
    }
}

// The bins' starts: each tile's start added to its bins.
@compute @workgroup_size(WG)
fn scan_add(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var b = gid.x; b < bins_len(); b += stride(groups)) {
        atomicAdd(&flags[bin_at(b)], word(tile_at(b / WG)));
    }
}

@compute @workgroup_size(WG)
fn bin_place(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var i = gid.x; i < prm.particles; i += stride(groups)) {
        let key = word(key_at(i));
        if key != OFF_GRID {
            atomicStore(&flags[order_at(word(bin_at(key)) + word(slot_at(i)))], i);
        }
    }
}

// Each bin sorted by particle index (insertion sort: a bin holds the particles of about one
// cell).
@compute @workgroup_size(WG)
fn bin_sort(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    for (var b = gid.x; b < prm.nodes.w; b += stride(groups)) {
        let lo = word(bin_at(b));
        let hi = word(bin_at(b + 1u));
        for (var q = lo + 1u; q < hi; q++) {
            let p = word(order_at(q));
            var r = q;
            while r > lo && word(order_at(r - 1u)) > p {
                atomicStore(&flags[order_at(r)], word(order_at(r - 1u)));
                r -= 1u;
            }
            atomicStore(&flags[order_at(r)], p);
        }
    }
}

// Each place's scatter (bins of the first transfer).
@compute @workgroup_size(WG)
fn bin_payload(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let placed_count = word(bin_at(prm.nodes.w));
    for (var q = gid.x; q < placed_count; q += stride(groups)) {
        let p = word(order_at(q));
        let x = load_vec(x_at(), p);
        let hw = half_width(p);
        let sc = payload(p, stencil(x, hw), load_vec(v_at(), p));
        let at = payload_at(q);
        store_words(at, x);
        if GIMP {
            store_words(at + HALF_WIDTH_WORD, hw);
        }
        store_word(at + 3u, sc.m);
        put_momentum(q, sc.mv, sc.mc);
        if TRANSFER != TRANSFER_MLS {
            store_word(at + 16u, sc.nsv[0][0]);
            store_word(at + 17u, sc.nsv[1][1]);
            store_word(at + 18u, sc.nsv[2][2]);
            store_word(at + 19u, sc.nsv[1][0]);
            store_word(at + 20u, sc.nsv[2][0]);
            store_word(at + 21u, sc.nsv[2][1]);
        }
    }
}

// MUSL's second transfer: each place's momentum from the velocity and affine matrix that
// `g2p_musl` stored (the force part is not read).
@compute @workgroup_size(WG)
fn bin_payload_second(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let placed_count = word(bin_at(prm.nodes.w));
    for (var q = gid.x; q < placed_count; q += stride(groups)) {
        let p = word(order_at(q));
        let m = mass_of(p);
        var mc = mat3x3<f32>();
        if affine_transfer() {
            mc = load_c(p) * m;
        }
        put_momentum(q, load_vec(v_at(), p) * m, mc);
    }
}
