// GIMP (b = 3): the hat averaged over a particle of half-length l ≤ ½ cells, base =
// ⌊ξ + ½⌋ − 1; with r = ξ − ξ_i: S = 1 − (r² + l²)/(2l) for |r| < l, 1 − |r| for
// l ≤ |r| < 1 − l, (1 + l − |r|)²/(4l) for 1 − l ≤ |r| < 1 + l, 0 beyond (loam-core's
// shape.rs). uGIMP keeps the particle's reference half-length, cpGIMP stretches it by ‖F e_a‖
// (`half_width` of common.wgsl). Prepended by step/mod.rs for scenes with
// `shape_function = "ugimp"` or `"cpgimp"`.

// The support width, the vector of one axis' factors, and whether APIC's inertia tensor is
// κ h² I (not for GIMP: APIC takes C = Σ v ∇wᵀ).
const B: u32 = 3u;
alias Wv = vec3<f32>;
const BSPLINE: bool = false;

// The factors of one axis at the grid coordinate ξ for a particle of half-length `l` cells.
fn axis(xi: f32, l: f32) -> Axis {
    let base = i32(floor(xi + 0.5)) - 1;
    var r: Axis;
    r.base = base;
    for (var k = 0u; k < 3u; k++) {
        let d = xi - f32(base + i32(k));
        var a = d;
        var sgn = 1.0;
        if d < 0.0 {
            a = -d;
            sgn = -1.0;
        }
        var s = 0.0;
        var ds = 0.0;
        if a < l {
            s = 1.0 - (d * d + l * l) / (2.0 * l);
            ds = -d / l;
        } else if a < 1.0 - l {
            s = 1.0 - a;
            ds = -sgn;
        } else if a < 1.0 + l {
            let q = 1.0 + l - a;
            s = q * q / (4.0 * l);
            ds = -sgn * q / (2.0 * l);
        }
        r.w[k] = s;
        r.dw[k] = ds * prm.inv_h;
        r.o[k] = (f32(base + i32(k)) - xi) * prm.h;
    }
    return r;
}
