//! The particle end of a USL step with MLS-MPM and the weakly compressible fluid in closed
//! form: the friction dam-break's path, the one back-analysis runs longest, without the `Dual64`
//! evaluations of the general local VJP (its test oracle, `tests/adjoint.rs`).
//!
//! Forward, per particle (`loam_core::step`, [`Fluid`]): `C' = G.affine`, `L = C'`,
//! `x' = x + Δt G.v`, `v' = G.v`, the projection of shallow wall crossings, `F' = (I + Δt L) F`,
//! `σ' = −p(J') I + 2η dev sym L`, `p(J) = (K/γ)(J^{−γ} − 1)`, `J' = det F'`.
//!
//! Reverse, from `x̄', v̄', C̄', F̄', σ̄'`: the projection zeroes the adjoint of a coordinate put on
//! the face (a constant) and of a velocity component it removed;
//! `J̄ = K J'^{−γ−1} tr σ̄'`, `F̄' += J̄ J' F'^{−T}`; `L̄ = 2η (sym σ̄' − ⅓ tr σ̄' I) + Δt F̄' Fᵀ`
//! (in-plane block); `F̄ = (I + Δt L)ᵀ F̄'`; `Ḡ.affine = C̄' + L̄`, `Ḡ.v = v̄' + Δt x̄'`, `x̄ = x̄'`.
//! Parameters: `∂σ/∂K = −(J^{−γ} − 1)/γ I`,
//! `∂σ/∂γ = [(K/γ²)(J^{−γ} − 1) + (K/γ) ln J J^{−γ}] I`, `∂σ/∂η = 2 dev sym L`.
//! `J^{−γ} = 1 + γ p(J)/K` is taken from the forward's own pressure ([`Fluid::pressure`]: by
//! repeated multiplication for a whole `γ`), so `ln J` is formed only for the parameters.

use super::ParticleShare;
use loam_core::constitutive::{Fluid, MaterialState};
use loam_core::step::EndOfStep;
use loam_core::tensor::{Tensor, Vector, cofactor, det, to3};
use loam_core::transfer::Gathered;
use nalgebra::Matrix3;

/// The adjoints of a particle's end-of-step `x, v, C, F, σ`.
pub(super) type EndAdjoint<'a, const D: usize> = (
    &'a Vector<f64, D>,
    &'a Vector<f64, D>,
    &'a Tensor<f64, D>,
    &'a Tensor<f64, D>,
    &'a Matrix3<f64>,
);

/// The adjoints a particle's end of step hands on besides its share of the start-of-step
/// adjoint.
pub(super) struct FluidEnd<const D: usize> {
    /// Adjoint of the gathered sums (`v` and `affine`; the others are not read).
    pub g_bar: Gathered<f64, D>,
    /// `∂L/∂K`, `∂L/∂γ`, `∂L/∂η` of this particle's step (zero unless asked for).
    pub params: [f64; 3],
}

/// The closed-form reverse of one particle's USL MLS-MPM end of step with the fluid (see the
/// module docs); `y_x, y_v, y_c, y_f, y_s` are the adjoints of the end-of-step `x, v, C, F, σ`.
/// Writes every field of the particle's `share` of the start-of-step adjoint (`x̄` and `F̄`,
/// the others zero) in place. The parameters' shares are formed when `with_params`.
#[allow(clippy::too_many_arguments)]
pub(super) fn reverse<const D: usize>(
    with_params: bool,
    fluid: &Fluid<f64>,
    end: &EndOfStep<'_, f64, D>,
    dt: f64,
    g: &Gathered<f64, D>,
    x: &Vector<f64, D>,
    f: &Tensor<f64, D>,
    (y_x, y_v, y_c, y_f, y_s): EndAdjoint<'_, D>,
    share: &mut ParticleShare<D>,
) -> FluidEnd<D> {
    let (k, gamma, eta) = (fluid.bulk_modulus, fluid.gamma, fluid.viscosity);
    let l = g.affine;
    // The projection: which coordinates became constants, which velocity components it removed.
    let (mut x1, mut v1) = (x + g.v * dt, g.v);
    let projected = end.project(&mut x1, &mut v1);
    let (mut x_bar, mut v_bar) = (*y_x, *y_v);
    for a in 0..D {
        for side in 0..2 {
            if projected & (1 << (2 * a + side)) != 0 {
                x_bar[a] = 0.0;
                if v1[a] != g.v[a] {
                    v_bar[a] = 0.0;
                }
            }
        }
    }
    let delta_f = Tensor::<f64, D>::identity() + l * dt;
    let f1 = delta_f * f;
    let j = det(&f1);
    let tr = y_s.trace();
    // J^{−γ} − 1 = γ p(J)/K.
    let excess = gamma * fluid.pressure(j) / k;
    let power = 1.0 + excess;
    // J̄ = −p'(J) tr σ̄ with p'(J) = −K J^{−γ−1}.
    let j_bar = k * power / j * tr;
    let f1_bar = y_f + cofactor(&f1) * j_bar;
    // The in-plane block of 2η (sym σ̄' − ⅓ tr σ̄' I): L has no out-of-plane components.
    let s_bar = Tensor::<f64, D>::from_fn(|r, c| {
        let diagonal = if r == c { tr / 3.0 } else { 0.0 };
        (0.5 * (y_s[(r, c)] + y_s[(c, r)]) - diagonal) * (2.0 * eta)
    });
    let l_bar = s_bar + f1_bar * f.transpose() * dt;
    let params = if with_params {
        let l3 = to3(&l, 0.0);
        let s = (l3 + l3.transpose()) * 0.5;
        let dev_s = s - Matrix3::identity() * (s.trace() / 3.0);
        let dp_dgamma = -(k / (gamma * gamma)) * excess - (k / gamma) * j.ln() * power;
        [
            -tr * excess / gamma,
            -tr * dp_dgamma,
            2.0 * y_s.component_mul(&dev_s).sum(),
        ]
    } else {
        [0.0; 3]
    };
    share.x = x_bar;
    share.v = Vector::zeros();
    share.f = delta_f.transpose() * f1_bar;
    share.stress = Matrix3::zeros();
    share.history = MaterialState::zeros();
    share.mass = 0.0;
    FluidEnd {
        g_bar: Gathered {
            v: v_bar + x_bar * dt,
            dv: Vector::zeros(),
            grad_v: Tensor::zeros(),
            affine: y_c + l_bar,
        },
        params,
    }
}
