//! Checks of an implicit gradient: central differences and the Taylor test on runs that
//! replay the reference run's sub-steps.
//!
//! The loss of a load-stepped run depends on its step sizes: a perturbed run whose Newton
//! needs one more iteration cuts a load step the reference did not, a different discrete
//! map. Both checks therefore run at the sub-steps of the run at `θ` ([`Schedule`]).

use super::{ImplicitProblem, Schedule};
use crate::error::AdjointError;

/// The central difference of the loss along unknown `k`, Richardson-extrapolated:
/// `(4 D(δ/2) − D(δ))/3` with `D(δ) = (L(θ + δ) − L(θ − δ))/(2δ)` and
/// `δ = relative_step · |θ_k|` (truncation `O(δ⁴)`), every run on `schedule`.
///
/// # Errors
/// As [`ImplicitProblem::loss`].
pub fn central_difference<const D: usize>(
    problem: &ImplicitProblem<D>,
    theta: &[f64],
    schedule: &Schedule,
    k: usize,
    relative_step: f64,
) -> Result<f64, AdjointError> {
    crate::check::richardson(
        |d| {
            let mut t = theta.to_vec();
            t[k] += d;
            problem.loss(&t, Some(schedule))
        },
        relative_step * theta[k].abs(),
    )
}

/// The Taylor remainders `r(h) = |L(θ + h v) − L(θ) − h ∇L·v|` at `h = h₀ / 2ⁱ`,
/// `i < count`, given `L(θ)` (`loss`) and `∇L·v` (`slope`), every run on `schedule`. They
/// fall 4× per halving for a correct gradient on a smooth loss (2× for a wrong one);
/// [`crate::check::observed_order`] turns them into an order.
///
/// # Errors
/// As [`ImplicitProblem::loss`].
#[allow(clippy::too_many_arguments)]
pub fn taylor_remainders<const D: usize>(
    problem: &ImplicitProblem<D>,
    theta: &[f64],
    schedule: &Schedule,
    loss: f64,
    slope: f64,
    v: &[f64],
    h0: f64,
    count: usize,
) -> Result<Vec<f64>, AdjointError> {
    (0..count)
        .map(|i| {
            let h = h0 / f64::from(1u32 << i);
            let t: Vec<f64> = theta.iter().zip(v).map(|(t, v)| t + h * v).collect();
            Ok((problem.loss(&t, Some(schedule))? - loss - h * slope).abs())
        })
        .collect()
}
