// Contact on the grid: Coulomb friction segments on the faces of the domain and rigid
// obstacles (boxes and cylinders, fixed or moving with a constant velocity), as loam-core's
// `Contact` (contact/mod.rs, contact/obstacle.rs) applies them to a node's trial velocity;
// and the test of a particle inside an obstacle. Launched by step/mod.rs after common.wgsl.
//
// The segments and obstacles follow the materials in `table` (params.rs lays them out):
// a segment is 4 entries (axis, side, μ; the first and last node index in range per axis),
// an obstacle 4 (the grid origin minus the centre and the kind; the half-extents or the
// cylinder's radius, half-length and axis, and μ; the velocity and the tolerance of the
// inside test; the centre).

const OBSTACLE_BOX: f32 = 0.0;

// The bit of a node's state for the segment of face (axis, side) and for obstacle k: bit
// b of the state words is bit b % 32 of word b / 32; the wall bits of `walls` are 0..5 of
// word 0.
const SEGMENT_BITS: u32 = 8u;
const OBSTACLE_BITS: u32 = 16u;

// Whether a state holds a segment or an obstacle.
fn in_contact(s: State) -> bool {
    var any = (s[0] >> SEGMENT_BITS) != 0u;
    for (var w = 1u; w < STATE_WORDS; w++) {
        any = any || s[w] != 0u;
    }
    return any;
}

struct Touched {
    // 0: separating (untouched), 1: stuck, 2: slid.
    touch: u32,
    v: vec3<f32>,
}

// The nodal Coulomb law on the velocity `v` relative to the surface, `n` the unit normal into
// the rigid body: if Δv_n = v·n > 0 the normal part goes and |v_t| is reduced by
// min(μ Δv_n, |v_t|) along v_t (loam-core's `coulomb`).
fn coulomb(v0: vec3<f32>, n: vec3<f32>, mu: f32) -> Touched {
    var r: Touched;
    r.v = v0;
    let vn = dot(v0, n);
    if vn <= 0.0 {
        r.touch = 0u;
        return r;
    }
    r.v = v0 - n * vn;
    let vt = length(r.v);
    let slip = mu * vn;
    if slip >= vt {
        if vt > 0.0 || mu > 0.0 {
            r.v = vec3<f32>(0.0);
        }
        r.touch = 1u;
    } else {
        r.v = r.v - r.v * (slip / vt);
        r.touch = 2u;
    }
    return r;
}

// The law of `contact`: Coulomb when deciding (first projection), else the removal of the
// normal part on the constraints that acted (MUSL's second projection).
fn law(v: vec3<f32>, n: vec3<f32>, mu: f32, decide: bool, acted: bool) -> Touched {
    if decide {
        return coulomb(v, n, mu);
    }
    var r: Touched;
    r.v = v;
    r.touch = 0u;
    if acted {
        r.v = v - n * dot(v, n);
        r.touch = 1u;
    }
    return r;
}

// ---- obstacles ----

struct Distance {
    phi: f32,
    // The outward unit normal ∇φ.
    n: vec3<f32>,
}

fn sign_of(d: f32) -> f32 {
    if d < 0.0 {
        return -1.0;
    }
    return 1.0;
}

// A box of half-extents `e` around the origin of `x`: outside, the distance to the box and
// the direction to the nearest point; inside, the nearest face (the lowest axis on a tie).
fn box_distance(x: vec3<f32>, e: vec3<f32>) -> Distance {
    var q = vec3<f32>(0.0);
    var out = vec3<f32>(0.0);
    var outside = false;
    for (var a = 0u; a < D; a++) {
        q[a] = abs(x[a]) - e[a];
        outside = outside || q[a] > 0.0;
        out[a] = max(q[a], 0.0);
    }
    var r: Distance;
    r.n = vec3<f32>(0.0);
    if outside {
        r.phi = length(out);
        for (var a = 0u; a < D; a++) {
            r.n[a] = sign_of(x[a]) * out[a] / r.phi;
        }
        return r;
    }
    var k = 0u;
    for (var a = 1u; a < D; a++) {
        if q[a] > q[k] {
            k = a;
        }
    }
    r.phi = q[k];
    r.n[k] = sign_of(x[k]);
    return r;
}

// A cylinder of radius `radius` and half-length `half` along `axis` around the origin of `x`;
// `axis` ≥ D is a 2D disk (no end caps).
fn cylinder_distance(x: vec3<f32>, radius: f32, half: f32, axis: u32) -> Distance {
    var radial = vec3<f32>(0.0);
    for (var a = 0u; a < D; a++) {
        if a != axis {
            radial[a] = x[a];
        }
    }
    let rho = length(radial);
    var r_hat = vec3<f32>(0.0);
    if rho > 0.0 {
        r_hat = radial / rho;
    } else if axis == 0u {
        r_hat.y = 1.0;
    } else {
        r_hat.x = 1.0;
    }
    let q_r = rho - radius;
    var e_z = vec3<f32>(0.0);
    var r: Distance;
    if axis < D {
        let q_z = abs(x[axis]) - half;
        e_z[axis] = sign_of(x[axis]);
        if q_r > 0.0 || q_z > 0.0 {
            let o_r = max(q_r, 0.0);
            let o_z = max(q_z, 0.0);
            r.phi = sqrt(o_r * o_r + o_z * o_z);
            r.n = (r_hat * o_r + e_z * o_z) / r.phi;
        } else if q_r >= q_z {
            r.phi = q_r;
            r.n = r_hat;
        } else {
            r.phi = q_z;
            r.n = e_z;
        }
        return r;
    }
    r.phi = q_r;
    r.n = r_hat;
    return r;
}

fn obstacle_at(k: u32) -> u32 {
    return prm.material_entries + 4u * (prm.segments + k);
}

fn obstacle_velocity(k: u32) -> vec3<f32> {
    return table[obstacle_at(k) + 2u].xyz;
}

// The signed distance of obstacle `k` at the point `rel` relative to its centre at time 0.
fn obstacle_distance(k: u32, rel: vec3<f32>) -> Distance {
    let at = obstacle_at(k);
    let shape = table[at + 1u];
    if table[at].w == OBSTACLE_BOX {
        return box_distance(rel, shape.xyz);
    }
    return cylinder_distance(rel, shape.x, shape.y, u32(shape.z));
}

// Where the node `idx` is relative to obstacle `k` at time `t`: (origin − centre) + idx h − v t.
fn node_from_obstacle(k: u32, idx: vec3<u32>, t: f32) -> vec3<f32> {
    let at = obstacle_at(k);
    var rel = table[at].xyz - table[at + 2u].xyz * t;
    for (var a = 0u; a < D; a++) {
        rel[a] += f32(idx[a]) * prm.h;
    }
    return rel;
}

// The first obstacle the particle at `x` lies inside at time `t` (φ below minus the
// tolerance), or `prm.obstacles` if none.
fn inside_obstacle(x: vec3<f32>, t: f32) -> u32 {
    for (var k = 0u; k < prm.obstacles; k++) {
        let at = obstacle_at(k);
        var rel = x - table[at + 3u].xyz - table[at + 2u].xyz * t;
        for (var a = D; a < 3u; a++) {
            rel[a] = 0.0;
        }
        if obstacle_distance(k, rel).phi < -table[at + 2u].w {
            return k;
        }
    }
    return prm.obstacles;
}

// ---- the node law ----

// Contact on the trial velocity of the node `idx` at the end-of-step time `t`: the friction
// segments (on each face the first segment whose range holds the node), then every obstacle
// whose contact layer φ < s h ‖n‖₁ holds it. With `decide` the Coulomb law decides and the
// bits of the constraints the node approached are returned; otherwise the normal part is
// removed on the constraints of `given`.
fn contact(idx: vec3<u32>, v: ptr<function, vec3<f32>>, t: f32, given: State, decide: bool) -> State {
    var acted: State;
    var faces_done = 0u;
    for (var s = 0u; s < prm.segments; s++) {
        let at = prm.material_entries + 4u * s;
        let seg = table[at];
        let axis = u32(seg.x);
        let side = u32(seg.y);
        let face = 1u << (2u * axis + side);
        if (faces_done & face) != 0u || !on_face(idx, axis, side) {
            continue;
        }
        var inside = true;
        for (var a = 0u; a < D; a++) {
            let i = f32(idx[a]);
            inside = inside && (a == axis || (i >= table[at + 1u][a] && i <= table[at + 2u][a]));
        }
        if !inside {
            continue;
        }
        faces_done |= face;
        let bit = face << SEGMENT_BITS;
        // The face's outward normal, into the wall.
        var n = vec3<f32>(0.0);
        n[axis] = select(1.0, -1.0, side == 0u);
        let r = law(*v, n, seg.z, decide, (given[0] & bit) != 0u);
        *v = r.v;
        if r.touch != 0u {
            acted[0] |= bit;
        }
    }
    for (var k = 0u; k < prm.obstacles; k++) {
        let d = obstacle_distance(k, node_from_obstacle(k, idx, t));
        var l1 = 0.0;
        for (var a = 0u; a < D; a++) {
            l1 += abs(d.n[a]);
        }
        if d.phi >= prm.reach * l1 {
            continue;
        }
        let word = (OBSTACLE_BITS + k) / 32u;
        let bit = 1u << ((OBSTACLE_BITS + k) % 32u);
        let vo = obstacle_velocity(k);
        let mu = table[obstacle_at(k) + 1u].w;
        let r = law(*v - vo, -d.n, mu, decide, (given[word] & bit) != 0u);
        if r.touch != 0u {
            *v = r.v + vo;
            acted[word] |= bit;
        }
    }
    return acted;
}
