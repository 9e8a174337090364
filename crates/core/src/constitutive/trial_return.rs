//! The return mapping of a Hencky-strain plastic model from the trial `bₑᵗʳ`, with one
//! eigen-decomposition for the trial strain, the stress and the new elastic state.
//!
//! A model with isotropic elasticity in Hencky strain and a return in principal strains
//! ([`MohrCoulomb`](super::MohrCoulomb), [`ModifiedCamClay`](super::ModifiedCamClay)) maps
//! the principal values `b_i` of `bₑᵗʳ = ΔF bₑⁿ ΔFᵀ` to the principal Kirchhoff stresses
//! `τ_i(εᵗʳ)`, `εᵗʳ_i = ½ ln b_i`, and the new `bₑ`, whose principal values are
//! `exp(2 εₑ_i)` (coaxial with `τ`). [`TrialReturn`] is that map as [`PrincipalMaps`] with two
//! outputs, so [`isotropic_maps`] assembles `τ` and `bₑ` from one decomposition of `bₑᵗʳ`
//! (before, the trial strain, the stress and `bₑ` each took their own). Its tag carries the
//! plastic strain increment `‖εᵗʳ − εₑ‖` and the plastic volume change `tr εₑ − tr εᵗʳ`,
//! symmetric functions of the principal values, so exact in the dual type too.

use super::{MaterialState, Region};
use crate::scalar::Scalar;
use crate::spectral::{PrincipalMaps, isotropic_maps};
use nalgebra::{Matrix3, SVector};
use num_dual::{Derivative, DualSVec64};

/// A return mapping in principal Hencky strains.
pub trait PrincipalReturn<T: Scalar> {
    /// The same return with the parameters' real parts in three dual lanes (the Jacobian at
    /// repeated eigenvalues).
    type Lanes: PrincipalReturn<DualSVec64<3>>;

    /// The principal Kirchhoff stresses of the trial principal strains `εᵗʳ` (any order),
    /// with the principal elastic strains for a plastic step (`None` when elastic), and the
    /// region taken.
    fn principal_state(&self, eps: [T; 3]) -> ([T; 3], Option<[T; 3]>, Region);

    /// [`PrincipalReturn::Lanes`].
    fn lanes(&self) -> Self::Lanes;
}

/// What a return reports besides `τ` and `bₑ`.
#[derive(Clone, Copy, Debug)]
pub struct ReturnTag<T> {
    /// The region taken.
    pub region: Region,
    /// `‖εᵗʳ − εₑ‖` (Frobenius); zero for an elastic step.
    pub plastic: T,
    /// `ε_vᵗʳ − ε_v = tr εₑ − tr εᵗʳ`, the plastic volume change, compression positive.
    pub plastic_volume: T,
}

/// A [`PrincipalReturn`] as [`PrincipalMaps`] of the principal values of `bₑᵗʳ` to those of
/// `τ` and of the new `bₑ` (module docs).
struct TrialReturn<'a, R>(&'a R);

impl<T: Scalar, R: PrincipalReturn<T>> PrincipalMaps<T, 2> for TrialReturn<'_, R> {
    type Tag = ReturnTag<T>;

    fn principal(&self, b: [T; 3]) -> ([[T; 3]; 2], ReturnTag<T>) {
        let eps: [T; 3] = std::array::from_fn(|i| b[i].ln() * T::cst(0.5));
        let (tau, elastic, region) = self.0.principal_state(eps);
        let Some(elastic) = elastic else {
            let tag = ReturnTag {
                region,
                plastic: T::zero(),
                plastic_volume: T::zero(),
            };
            return ([tau, b], tag);
        };
        let d: [T; 3] = std::array::from_fn(|i| eps[i] - elastic[i]);
        let tag = ReturnTag {
            region,
            plastic: (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt(),
            plastic_volume: -(d[0] + d[1] + d[2]),
        };
        ([tau, elastic.map(|e| (e * T::cst(2.0)).exp())], tag)
    }

    fn jacobian(&self, b: [f64; 3]) -> [[[f64; 3]; 3]; 2] {
        let lanes: [DualSVec64<3>; 3] = std::array::from_fn(|i| {
            let mut e = SVector::<f64, 3>::zeros();
            e[i] = 1.0;
            DualSVec64::new(b[i], Derivative::some(e))
        });
        let model = self.0.lanes();
        let (out, _) = TrialReturn(&model).principal(lanes);
        std::array::from_fn(|n| {
            std::array::from_fn(|i| {
                std::array::from_fn(|j| out[n][i].eps.0.as_ref().map_or(0.0, |e| e[j]))
            })
        })
    }
}

/// The return from `ΔF` and the start state's `bₑⁿ`: the Kirchhoff stress, the new `bₑ` (the
/// trial `bₑᵗʳ` itself for an elastic step) and the [`ReturnTag`].
pub fn trial_return<T: Scalar, R: PrincipalReturn<T>>(
    model: &R,
    delta_f: &Matrix3<T>,
    state: &MaterialState<T>,
) -> (Matrix3<T>, Matrix3<T>, ReturnTag<T>) {
    let half = T::cst(0.5);
    let b = delta_f * state.tensor * delta_f.transpose();
    let b_trial = (b + b.transpose()) * half;
    let ([tau, b_e], tag) = isotropic_maps(&b_trial, &TrialReturn(model));
    let tau = (tau + tau.transpose()) * half;
    if tag.region == Region::Elastic {
        return (tau, b_trial, tag);
    }
    (tau, (b_e + b_e.transpose()) * half, tag)
}
