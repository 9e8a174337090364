// The linear hat N = 1 − |ξ − ξ_i| (b = 2) on the two nodes of the cell that holds the
// particle, base = ⌊ξ⌋ (loam-core's shape.rs). Prepended by step/mod.rs for scenes with
// `shape_function = "linear"`.

// The support width, the vector of one axis' factors, and whether APIC's inertia tensor is
// κ h² I (not for the hat: APIC takes C = Σ v ∇wᵀ).
const B: u32 = 2u;
alias Wv = vec2<f32>;
const BSPLINE: bool = false;

// The factors of one axis at the grid coordinate ξ (`l`, the half-width, unused).
fn axis(xi: f32, l: f32) -> Axis {
    let base = i32(floor(xi));
    let f = xi - f32(base);
    var r: Axis;
    r.base = base;
    r.w = vec2<f32>(1.0 - f, f);
    r.dw = vec2<f32>(-prm.inv_h, prm.inv_h);
    r.o = (vec2<f32>(f32(base), f32(base + 1)) - xi) * prm.h;
    return r;
}
