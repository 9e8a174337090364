// The cubic B-spline (b = 4) on the nodes base..base+4, base = ⌊ξ⌋ − 1, f = ξ − base in
// [1, 2): N(r) = ½|r|³ − r² + 2/3 for |r| < 1, (2 − |r|)³/6 for 1 ≤ |r| < 2 (loam-core's
// shape.rs, in its order of operations). Prepended by step/mod.rs for scenes with
// `shape_function = "cubic_bspline"`.

// The support width, the vector of one axis' factors, and whether APIC's inertia tensor is
// κ h² I (B-splines: `prm.apic_scale` = 1/(κ h²)).
const B: u32 = 4u;
alias Wv = vec4<f32>;
const BSPLINE: bool = true;

// N and dN/dr at 1 ≤ r < 2: (2 − r)³/6 and −(2 − r)²/2.
fn cubic_outer(r: f32) -> vec2<f32> {
    let s = 2.0 - r;
    return vec2<f32>(s * s * s / 6.0, -s * s * 0.5);
}

// N and dN/dr at 0 ≤ r < 1: ½r³ − r² + 2/3 and 3/2 r² − 2r.
fn cubic_inner(r: f32) -> vec2<f32> {
    return vec2<f32>(0.5 * r * r * r - r * r + 2.0 / 3.0, 1.5 * r * r - 2.0 * r);
}

// The factors of one axis at the grid coordinate ξ (`l`, the half-width, unused); the signed
// distances ξ − ξ_k are f, f − 1 (≥ 0) and f − 2, f − 3 (< 0), and N' is odd.
fn axis(xi: f32, l: f32) -> Axis {
    let base = i32(floor(xi)) - 1;
    let f = xi - f32(base);
    let n0 = cubic_outer(f);
    let n1 = cubic_inner(f - 1.0);
    let n2 = cubic_inner(2.0 - f);
    let n3 = cubic_outer(3.0 - f);
    var r: Axis;
    r.base = base;
    r.w = vec4<f32>(n0.x, n1.x, n2.x, n3.x);
    r.dw = vec4<f32>(n0.y * prm.inv_h, n1.y * prm.inv_h, -n2.y * prm.inv_h, -n3.y * prm.inv_h);
    r.o = (vec4<f32>(f32(base), f32(base + 1), f32(base + 2), f32(base + 3)) - xi) * prm.h;
    return r;
}
