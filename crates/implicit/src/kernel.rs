//! The per-particle kernels of the implicit step, generic over the scalar type.
//!
//! Updated Lagrangian over one load step: the particles' positions `x_pⁿ`, deformation
//! gradients `Fⁿ` and history are frozen at the start of the step, and the unknowns are the
//! nodal displacement increments `Δu`. For a particle,
//!
//! - `ΔF = I + Σ_i Δu_i ⊗ ∇N_i(x_pⁿ)`, `F = ΔF Fⁿ`;
//! - the model gives the Kirchhoff stress `τ(ΔF, Fⁿ, historyⁿ)`;
//! - the nominal stress relative to the start of the step is `P = τ ΔF⁻ᵀ / Jⁿ`, so the nodal
//!   internal force is `f_i = Σ_p Vₚⁿ P ∇N_i = Σ_p Vₚ⁰ τ ΔF⁻ᵀ ∇N_i(x_pⁿ)` (with `Vₚⁿ = Jⁿ Vₚ⁰`).
//!
//! The same code runs with `f64` (residual) and with dual numbers (tangents).

use loam_core::constitutive::MaterialState;
use loam_core::tensor::{Tensor, det, from3, inverse, product, to3};
use loam_core::{Material, Scalar, Stencil};
use nalgebra::Matrix3;

/// What a particle keeps fixed during the Newton iterations of a load step.
#[derive(Clone, Debug)]
pub struct Frozen<const D: usize> {
    /// Shape functions at the start-of-step position.
    pub stencil: Stencil<f64, D>,
    /// Deformation gradient at the start of the step.
    pub f_n: Tensor<f64, D>,
    /// Constitutive history at the start of the step.
    pub state: MaterialState<f64>,
    /// Reference volume `Vₚ⁰`.
    pub volume0: f64,
    /// Index into the material table.
    pub material: usize,
}

/// `ΔF = I + Σ_i Δu_i ⊗ ∇N_i` from the nodal increments `du(flat, component)`, for a stencil
/// of scalar type `S` (`f64` in the solver; a dual type where the particle position is
/// differentiated) and increments of type `T`.
#[inline]
pub fn delta_f<S: Scalar, T: Scalar + From<S>, const D: usize>(
    stencil: &Stencil<S, D>,
    mut du: impl FnMut(usize, usize) -> T,
) -> Tensor<T, D> {
    let mut g = Tensor::<T, D>::identity();
    stencil.for_each(|n| {
        for a in 0..D {
            let u = du(n.flat, a);
            for b in 0..D {
                g[(a, b)] += u * T::from(n.gradient[b]);
            }
        }
    });
    g
}

/// The stress update of one particle for a trial `ΔF`: returns `V⁰ τ ΔF⁻ᵀ` (the in-plane
/// `D × D` block whose product with `∇N_i` is the internal force on node `i`), the Kirchhoff
/// stress and the new history, or `None` if `det ΔF ≤ 0` (an inverted trial state).
#[inline]
pub fn particle_stress<T: Scalar, const D: usize>(
    material: &Material<T>,
    frozen: &Frozen<D>,
    delta_f: &Tensor<T, D>,
) -> Option<(Tensor<T, D>, Matrix3<T>, MaterialState<T>)> {
    stress_update(
        material,
        &frozen.f_n.map(T::cst),
        &frozen.state.lift(),
        T::cst(frozen.volume0),
        delta_f,
    )
}

/// [`particle_stress`] with the start-of-step deformation gradient `Fⁿ`, history and
/// reference volume `V⁰` given in the scalar type itself, so that a derivative with respect to
/// the particle's own state is the same code with dual inputs: `F = ΔF Fⁿ`,
/// `(τ, history) = kirchhoff_update(ΔF, F, historyⁿ)`, and `V⁰ τ ΔF⁻ᵀ`.
#[inline]
pub fn stress_update<T: Scalar, const D: usize>(
    material: &Material<T>,
    f_n: &Tensor<T, D>,
    state: &MaterialState<T>,
    volume0: T,
    delta_f: &Tensor<T, D>,
) -> Option<(Tensor<T, D>, Matrix3<T>, MaterialState<T>)> {
    if det(delta_f).re() <= 0.0 {
        return None;
    }
    let f = product(delta_f, f_n);
    let (tau, state) =
        material.kirchhoff_update(&to3(delta_f, T::one()), &to3(&f, T::one()), state);
    let dfinv_t = inverse(delta_f)?.transpose();
    Some((
        product(&from3::<T, D>(&tau), &dfinv_t) * volume0,
        tau,
        state,
    ))
}
