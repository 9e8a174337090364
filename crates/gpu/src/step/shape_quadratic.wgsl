// The quadratic B-spline (b = 3) on the nodes base..base+3, base = ⌊ξ − ½⌋, f = ξ − base in
// [½, 3/2): N₀ = ½(3/2 − f)², N₁ = 3/4 − (f − 1)², N₂ = ½(f − ½)² (loam-core's shape.rs).
// Prepended by step/mod.rs for scenes with `shape_function = "quadratic_bspline"`.

// The support width, the vector of one axis' factors, and whether APIC's inertia tensor is
// κ h² I (B-splines: `prm.apic_scale` = 1/(κ h²)).
const B: u32 = 3u;
alias Wv = vec3<f32>;
const BSPLINE: bool = true;

// The factors of one axis at the grid coordinate ξ (`l`, the half-width, unused).
fn axis(xi: f32, l: f32) -> Axis {
    let base = i32(floor(xi - 0.5));
    let f = xi - f32(base);
    let a = 1.5 - f;
    let m = f - 1.0;
    let p = f - 0.5;
    var r: Axis;
    r.base = base;
    r.w = vec3<f32>(0.5 * a * a, 0.75 - m * m, 0.5 * p * p);
    r.dw = vec3<f32>(-a * prm.inv_h, -2.0 * m * prm.inv_h, p * prm.inv_h);
    r.o = (vec3<f32>(f32(base), f32(base + 1), f32(base + 2)) - xi) * prm.h;
    return r;
}
