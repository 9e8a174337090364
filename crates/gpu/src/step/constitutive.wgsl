// The constitutive updates of the particle end, per material as loam-core's
// `Material::update_region` dispatches them: the weakly compressible fluid, small-strain
// linear elasticity, Neo-Hookean and Hencky hyperelasticity, J2 plasticity in Hencky strain
// space, and Drucker–Prager plasticity with its return mapping
// (loam-core's constitutive/*.rs, path by path, in f32). Launched by step/mod.rs in front of
// g2p.wgsl.
//
// A material is MATERIAL_ENTRIES entries of `table` (params.rs writes them):
//   0: (model, μ, λ, K = λ + ⅔μ)
//   1: fluid: (K, γ, η, γ as a whole number ≤ 64 or 0); Drucker–Prager: (α, k, σ_t, q_c);
//      J2: (σ_y, H, 0, 0), and K = λ + ⅔μ in entry 0's w
//   2: (α_ψ (Drucker–Prager, else 0), c, 0, 0), c the elastic wave speed of the material
//      (`Material::wave_speed`, the fixed step's stability bound h / (c + |v|) in p2g.wgsl)
// The Drucker–Prager constants are the CPU's own f32 values (`DruckerPrager::alpha`, `k`,
// `corner`, `alpha_psi`, `bulk_modulus` evaluated in f32 on the host), so both sides start
// every return from the same bits.

const MATERIAL_ENTRIES: u32 = 3u;
const MODEL_FLUID: u32 = 0u;
const MODEL_NEO_HOOKEAN: u32 = 1u;
const MODEL_HENCKY: u32 = 2u;
const MODEL_DRUCKER_PRAGER: u32 = 3u;
const MODEL_LINEAR_ELASTIC: u32 = 4u;
const MODEL_J2: u32 = 5u;

const IDENTITY: mat3x3<f32> = mat3x3<f32>(
    vec3<f32>(1.0, 0.0, 0.0),
    vec3<f32>(0.0, 1.0, 0.0),
    vec3<f32>(0.0, 0.0, 1.0),
);

// Whether a material of the scene has model `k`: `MODELS`, which the launcher prepends, has
// bit k set.
fn has_model(k: u32) -> bool {
    return (MODELS & (1u << k)) != 0u;
}

fn material_entry(m: u32, e: u32) -> vec4<f32> {
    return table[m * MATERIAL_ENTRIES + e];
}

fn trace3(m: mat3x3<f32>) -> f32 {
    return m[0][0] + m[1][1] + m[2][2];
}

// The squared Frobenius norm, summed column by column as nalgebra's `norm_squared` sums a
// 3×3 matrix.
fn frobenius2(m: mat3x3<f32>) -> f32 {
    var s = 0.0;
    for (var c = 0u; c < 3u; c++) {
        for (var r = 0u; r < 3u; r++) {
            s += m[c][r] * m[c][r];
        }
    }
    return s;
}

// The Frobenius norm (nalgebra's `norm`).
fn frobenius(m: mat3x3<f32>) -> f32 {
    return sqrt(frobenius2(m));
}

// m / x entry by entry (nalgebra's `Matrix / scalar`; WGSL has no matrix division).
fn divided(m: mat3x3<f32>, x: f32) -> mat3x3<f32> {
    return mat3x3<f32>(m[0] / x, m[1] / x, m[2] / x);
}

// ln x. Vulkan lets `log` be off by 2⁻²¹ (absolute) on [0.5, 2], which is 5e-4 of a strain of
// 1e-3: near 1 the logarithm is 2 atanh(u) = 2 (u + u³/3 + u⁵/5 + …), u = (x − 1)/(x + 1)
// (x − 1 exact there), |u| ≤ 1/5, seven terms (truncation below 0.2¹⁵/15 ≈ 2e-12 relative).
// The CPU takes Rust's correctly rounded `ln` (in f32 for Neo-Hookean's ln J, in f64 for the
// Hencky eigenvalues).
fn natural_log(x: f32) -> f32 {
    if x < 0.66 || x > 1.5 {
        return log(x);
    }
    return atanh_series((x - 1.0) / (x + 1.0));
}

// ln(1 + y) as `natural_log` computes ln x, from y itself: u = y/(y + 2) keeps the digits of a
// small y that 1 + y would round away.
fn ln_1p(y: f32) -> f32 {
    if y < -0.34 || y > 0.5 {
        return log(1.0 + y);
    }
    return atanh_series(y / (y + 2.0));
}

// 2 atanh(u) = 2 (u + u³/3 + … + u¹³/13) for |u| ≤ 1/5.
fn atanh_series(u: f32) -> f32 {
    let u2 = u * u;
    let series = 1.0 + u2 * (1.0 / 3.0 + u2 * (1.0 / 5.0 + u2 * (1.0 / 7.0
        + u2 * (1.0 / 9.0 + u2 * (1.0 / 11.0 + u2 * (1.0 / 13.0))))));
    return 2.0 * u * series;
}

// eˣ − 1. Vulkan lets `exp` be off by 3 + 2|x| ulps of eˣ ≈ 1, which is 1e-4 of a strain of
// 1e-3: for |x| ≤ 1/2 the Taylor series x (1 + x/2 (1 + x/3 (…))) to x¹³/13! (truncation
// below 0.5¹⁴/14! ≈ 7e-16), in additions and multiplications, which Vulkan rounds correctly.
fn exp_m1(x: f32) -> f32 {
    if abs(x) > 0.5 {
        return exp(x) - 1.0;
    }
    var sum = 1.0;
    for (var k = 13u; k >= 2u; k--) {
        sum = 1.0 + x * sum * (1.0 / f32(k));
    }
    return x * sum;
}

// ---- fluid (constitutive/fluid.rs) ----

// Tait pressure p(J) = (K/γ)(J^−γ − 1); a whole γ up to 64 by repeated squaring, in the
// order of `whole_power`.
fn pressure(m: vec4<f32>, j: f32) -> f32 {
    var power: f32;
    var n = u32(m.w);
    if n > 0u {
        var acc = 1.0;
        var base = j;
        loop {
            if (n & 1u) == 1u {
                acc *= base;
            }
            n = n >> 1u;
            if n == 0u {
                break;
            }
            base *= base;
        }
        power = 1.0 / acc;
    } else {
        power = exp(-m.y * log(j));
    }
    return (m.x / m.y) * (power - 1.0);
}

// σ = −p(det F) I + 2η dev sym L (the viscous term skipped when η = 0).
fn fluid_stress(m: vec4<f32>, f: mat3x3<f32>, l: mat3x3<f32>) -> mat3x3<f32> {
    let p = pressure(m, det3(f));
    let iso = IDENTITY * -p;
    if m.z == 0.0 {
        return iso;
    }
    let d = (l + transpose(l)) * 0.5;
    let tr = trace3(d) / 3.0;
    let dev = d - IDENTITY * tr;
    return dev * (m.z * 2.0) + iso;
}

// ---- elasticity (constitutive/linear_elastic.rs, neo_hookean.rs, hencky.rs) ----

// Small-strain linear elasticity on ε = ½(F + Fᵀ) − I: σ = λ tr(ε) I + 2μ ε, in the CPU's
// order of operations.
fn linear_elastic_stress(e: vec4<f32>, f: mat3x3<f32>) -> mat3x3<f32> {
    let eps = (f + transpose(f)) * 0.5 - IDENTITY;
    return IDENTITY * (e.z * trace3(eps)) + eps * (e.y * 2.0);
}

// Neo-Hookean: σ = τ / J, τ = μ (F Fᵀ − I) + λ ln J I.
fn neo_hookean_stress(e: vec4<f32>, f: mat3x3<f32>) -> mat3x3<f32> {
    let j = det3(f);
    let tau = (f * transpose(f) - IDENTITY) * e.y + IDENTITY * (e.z * natural_log(j));
    return divided(tau, j);
}

// The eigenvalues and eigenvectors (columns of q) of a symmetric 3×3 matrix, by the cyclic
// Jacobi sweeps of loam-core's `spectral::symmetric_eigen`, rotation for rotation, in f32.
// The CPU runs them in f64 on the f32 entries of F Fᵀ: the f32 sweeps leave the eigenvalues
// a few ulps of ‖F Fᵀ‖ (≈ 1e-7) from those, an error of the same size as the rounding of
// F Fᵀ itself that both sides share, so the Hencky strain differs by ~1e-7 absolute
// (relative 1e-4 at a strain of 1e-3, like the CPU f32 run's own error against f64).
struct Eigen {
    values: vec3<f32>,
    q: mat3x3<f32>,
}

fn symmetric_eigen(a: mat3x3<f32>) -> Eigen {
    var m = (a + transpose(a)) * 0.5;
    var q = IDENTITY;
    let scale = max(frobenius(m), 1.17549435e-38);
    // Jacobi converges quadratically: f32 reaches exact zeros (or the threshold) in a few
    // sweeps; the CPU's cap is 50.
    for (var sweep = 0u; sweep < 50u; sweep++) {
        let off = m[1][0] * m[1][0] + m[2][0] * m[2][0] + m[2][1] * m[2][1];
        if sqrt(off) <= 1e-17 * scale {
            break;
        }
        for (var p = 0u; p < 3u; p++) {
            for (var r = p + 1u; r < 3u; r++) {
                let apr = m[r][p];
                if apr == 0.0 {
                    continue;
                }
                // tan 2θ = 2 a_pr / (a_rr − a_pp); signum(0) = 1 as in Rust. Past 1e15,
                // √(θ² + 1) = |θ| in f32 and t = 1/(2θ) exactly; θ² would overflow near 2e19.
                let theta = (m[r][r] - m[p][p]) / (2.0 * apr);
                var t: f32;
                if abs(theta) > 1e15 {
                    t = 0.5 / theta;
                } else {
                    let sgn = select(1.0, -1.0, theta < 0.0);
                    t = sgn / (abs(theta) + sqrt(theta * theta + 1.0));
                }
                let cs = 1.0 / sqrt(t * t + 1.0);
                let sn = t * cs;
                // Columns p and r of m (m[col][row]), then rows p and r, then q's columns.
                for (var k = 0u; k < 3u; k++) {
                    let mkp = m[p][k];
                    let mkr = m[r][k];
                    m[p][k] = cs * mkp - sn * mkr;
                    m[r][k] = sn * mkp + cs * mkr;
                }
                for (var k = 0u; k < 3u; k++) {
                    let mpk = m[k][p];
                    let mrk = m[k][r];
                    m[k][p] = cs * mpk - sn * mrk;
                    m[k][r] = sn * mpk + cs * mrk;
                }
                for (var k = 0u; k < 3u; k++) {
                    let qkp = q[p][k];
                    let qkr = q[r][k];
                    q[p][k] = cs * qkp - sn * qkr;
                    q[r][k] = sn * qkp + cs * qkr;
                }
            }
        }
    }
    var e: Eigen;
    e.values = vec3<f32>(m[0][0], m[1][1], m[2][2]);
    e.q = q;
    return e;
}

// The isotropic law 2μ ε + λ tr(ε) I (`Lame::stress`).
fn lame_stress(e: vec4<f32>, eps: mat3x3<f32>) -> mat3x3<f32> {
    return eps * (e.y * 2.0) + IDENTITY * (e.z * trace3(eps));
}

// Hencky: σ = τ / J, τ = 2μ ε + λ tr(ε) I, ε = ½ ln(F Fᵀ) = ½ Q diag(ln λ_k) Qᵀ.
fn hencky_stress(e: vec4<f32>, f: mat3x3<f32>) -> mat3x3<f32> {
    let eig = symmetric_eigen(f * transpose(f));
    let v = eig.values;
    let logs = mat3x3<f32>(
        vec3<f32>(natural_log(v.x), 0.0, 0.0),
        vec3<f32>(0.0, natural_log(v.y), 0.0),
        vec3<f32>(0.0, 0.0, natural_log(v.z)),
    );
    let eps = (eig.q * logs * transpose(eig.q)) * 0.5;
    return divided(lame_stress(e, eps), det3(f));
}

// ---- J2 (constitutive/j2.rs) ----

// Q diag(g(λ_k)) Qᵀ of a symmetric matrix with eigenvalues λ and eigenvectors Q:
// g(λ) = ln(1 + λ) (`ln_1p`) or, with `exponential`, g(λ) = e^λ − 1 (`exp_m1`).
fn spectral(a: mat3x3<f32>, exponential: bool) -> mat3x3<f32> {
    let eig = symmetric_eigen(a);
    var g = eig.values;
    for (var k = 0u; k < 3u; k++) {
        g[k] = select(ln_1p(g[k]), exp_m1(g[k]), exponential);
    }
    let d = mat3x3<f32>(
        vec3<f32>(g.x, 0.0, 0.0),
        vec3<f32>(0.0, g.y, 0.0),
        vec3<f32>(0.0, 0.0, g.z),
    );
    return eig.q * d * transpose(eig.q);
}

// Simo's return in Hencky strain space (`J2::return_map`) from the stress σₙ at the start of
// the step, of a particle whose det F was `j_n` then. The CPU keeps the elastic left
// Cauchy–Green tensor bₑ as the state; the GPU has no buffer for it and rebuilds it from the
// stress, as it rebuilds the Drucker–Prager state: τₙ = jₙ σₙ, εₙ = C⁻¹:τₙ (the Hencky law
// inverted), bₑ = exp(2 εₙ), the same tensor up to f32 round-off. Then the trial
// bₑᵗʳ = ΔF bₑ ΔFᵀ (symmetrised), εᵗʳ = ½ ln bₑᵗʳ, τᵗʳ = 2μ εᵗʳ + λ tr(εᵗʳ) I, the yield
// function f = ‖dev τᵗʳ‖ − √(2/3) (σ_y + H ε̄ᵖ), and for f > 0 the radial return
// Δγ = f / (2μ + ⅔H), τ = τᵗʳ − 2μ Δγ n, ε̄ᵖ += √(2/3) Δγ; σ = τ / det F.
//
// bₑ is carried as bₑ − I, of the size of the strain: with G = ΔF − I,
// bₑᵗʳ − I = ΔF (bₑ − I) ΔFᵀ + G + Gᵀ + G Gᵀ, so that a strain of 1e-3 keeps f32's digits
// through the rebuild and the trial instead of a few ulps of 1 (the CPU's f32 run keeps bₑ
// and takes its logarithm in f64). The eigenvectors of bₑ − I are those of bₑ.
fn j2_update(
    e: vec4<f32>,
    surface: vec4<f32>,
    f: mat3x3<f32>,
    delta_f: mat3x3<f32>,
    j_n: f32,
    sigma_n: mat3x3<f32>,
    plastic_strain: f32,
) -> Returned {
    let b_n = spectral(dp_compliance(e, sigma_n * j_n) * 2.0, true);
    let g = delta_f - IDENTITY;
    let b = delta_f * b_n * transpose(delta_f) + g + transpose(g) + g * transpose(g);
    let b_trial = (b + transpose(b)) * 0.5;
    let eps_trial = spectral(b_trial, false) * 0.5;
    let tau_trial = lame_stress(e, eps_trial);
    let s = tau_trial - IDENTITY * (trace3(tau_trial) / 3.0);
    let s_norm = frobenius(s);
    let yield_f = s_norm - (surface.x + surface.y * plastic_strain) * sqrt(2.0 / 3.0);
    var out: Returned;
    out.plastic = 0.0;
    if yield_f <= 0.0 || s_norm == 0.0 {
        out.sigma = divided(tau_trial, det3(f));
        return out;
    }
    let two_mu = e.y * 2.0;
    let dgamma = yield_f / (two_mu + surface.y * (2.0 / 3.0));
    let n = divided(s, s_norm);
    out.sigma = divided(tau_trial - n * (two_mu * dgamma), det3(f));
    out.plastic = dgamma * sqrt(2.0 / 3.0);
    return out;
}

// ---- Drucker–Prager (constitutive/drucker_prager.rs) ----

// The elastic trial σᵗʳ = Q σₙ Qᵀ + C:(Δt D), Q = I + 2 (A + A²)/(1 + ½‖A‖²), A = ½ Δt W
// (`DruckerPrager::trial_stress`), symmetrised after the rotation.
fn dp_trial(e: vec4<f32>, sigma_n: mat3x3<f32>, dl: mat3x3<f32>) -> mat3x3<f32> {
    let a = (dl - transpose(dl)) * 0.25;
    let d = (dl + transpose(dl)) * 0.5;
    let a2 = a * a;
    let q = IDENTITY + (a + a2) * (2.0 / (1.0 + frobenius2(a) * 0.5));
    let rotated = q * sigma_n * transpose(q);
    return (rotated + transpose(rotated)) * 0.5 + lame_stress(e, d);
}

// C⁻¹:σ = s/(2μ) + p/(3K) I.
fn dp_compliance(e: vec4<f32>, sigma: mat3x3<f32>) -> mat3x3<f32> {
    let p = trace3(sigma) / 3.0;
    let s = sigma - IDENTITY * p;
    return divided(s, e.y * 2.0) + IDENTITY * (p / (e.w * 3.0));
}

struct Returned {
    sigma: mat3x3<f32>,
    // The equivalent plastic strain increment √(2/3) ‖C⁻¹:(σᵗʳ − σ)‖ (0 when elastic).
    plastic: f32,
}

// The closed-form return of `DruckerPrager::return_map`: elastic inside {f ≤ 0, p ≤ σ_t};
// else the shear return to the cone when it lands at or above the corner (q ≥ q_c), else the
// tension return (qᵗʳ ≤ q_c: p = σ_t, s = sᵗʳ) or the corner / apex (p = σ_t,
// s = sᵗʳ q_c/qᵗʳ). Branches are decided on the same quantities, in the same order.
fn dp_return(e: vec4<f32>, surface: vec4<f32>, alpha_psi: f32, trial: mat3x3<f32>) -> Returned {
    let alpha = surface.x;
    let k = surface.y;
    let sigma_t = surface.z;
    let q_c = surface.w;
    let p_tr = trace3(trial) / 3.0;
    let s_tr = trial - IDENTITY * p_tr;
    let q_tr = frobenius(s_tr) * 0.70710678118654752;
    let f_shear = q_tr + alpha * p_tr * 3.0 - k;
    let f_tension = p_tr - sigma_t;
    var out: Returned;
    out.plastic = 0.0;
    if f_shear <= 0.0 && f_tension <= 0.0 {
        out.sigma = trial;
        return out;
    }
    let mu = e.y;
    let bulk = e.w;
    var shear = false;
    if f_shear > 0.0 {
        let dgamma = f_shear / (mu + bulk * alpha * alpha_psi * 9.0);
        let q = q_tr - mu * dgamma;
        if q >= q_c {
            let p = p_tr - bulk * alpha_psi * dgamma * 3.0;
            out.sigma = s_tr * (q / q_tr) + IDENTITY * p;
            shear = true;
        }
    }
    if !shear {
        if q_tr <= q_c {
            out.sigma = s_tr + IDENTITY * sigma_t;
        } else {
            out.sigma = s_tr * (q_c / q_tr) + IDENTITY * sigma_t;
        }
    }
    let deps_p = dp_compliance(e, trial) - dp_compliance(e, out.sigma);
    out.plastic = frobenius(deps_p) * sqrt(2.0 / 3.0);
    return out;
}

// ---- dispatch ----

struct Updated {
    sigma: mat3x3<f32>,
    // The equivalent plastic strain gained this step (0 for the models without plasticity).
    plastic: f32,
}

// The constitutive update of material `m` at the end of a step: F is the new deformation
// gradient, ΔF = I + Δt L the step's relative one, L the velocity gradient, and σₙ, det Fₙ
// and ε̄ᵖ the stress, the volume ratio and the equivalent plastic strain at the start of the
// step (3×3 with a zero out-of-plane row and column of L and F_zz = 1 in 2D, as loam-core's
// `to3` embeds them).
fn update_stress(
    m: u32,
    f: mat3x3<f32>,
    delta_f: mat3x3<f32>,
    l: mat3x3<f32>,
    sigma_n: mat3x3<f32>,
    j_n: f32,
    plastic_strain: f32,
) -> Updated {
    let e = material_entry(m, 0u);
    var out: Updated;
    out.plastic = 0.0;
    let model = u32(e.x);
    // Only the models of the scene's materials are compiled in (`has_model`): the others'
    // code, Hencky's eigenvalues and the Drucker–Prager return above all, would hold
    // registers in every scene's kernel.
    if has_model(MODEL_NEO_HOOKEAN) && model == MODEL_NEO_HOOKEAN {
        out.sigma = neo_hookean_stress(e, f);
    } else if has_model(MODEL_LINEAR_ELASTIC) && model == MODEL_LINEAR_ELASTIC {
        out.sigma = linear_elastic_stress(e, f);
    } else if has_model(MODEL_HENCKY) && model == MODEL_HENCKY {
        out.sigma = hencky_stress(e, f);
    } else if has_model(MODEL_J2) && model == MODEL_J2 {
        let r = j2_update(e, material_entry(m, 1u), f, delta_f, j_n, sigma_n, plastic_strain);
        out.sigma = r.sigma;
        out.plastic = r.plastic;
    } else if has_model(MODEL_DRUCKER_PRAGER) && model == MODEL_DRUCKER_PRAGER {
        let trial = dp_trial(e, sigma_n, l * prm.dt);
        let r = dp_return(e, material_entry(m, 1u), material_entry(m, 2u).x, trial);
        out.sigma = r.sigma;
        out.plastic = r.plastic;
    } else if has_model(MODEL_FLUID) {
        out.sigma = fluid_stress(material_entry(m, 1u), f, l);
    }
    return out;
}
