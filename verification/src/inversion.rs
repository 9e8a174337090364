//! An inversion run to its end for the back-analysis cases (`inverse-v0`,
//! `inverse-friction`, `inverse-cantilever`, `inverse-footing`, `inverse-triaxial-mcc`):
//! L-BFGS or Levenberg–Marquardt from `loam-inverse` on a loss and its gradient through the
//! reparameterisation of each unknown ([`Variable`]), stopped by an iteration limit, a
//! relative loss, or an optimiser that finds no decrease.

use crate::VerifyError;
use loam_inverse::optimise::norm;
use loam_inverse::{
    AdjointError, Evaluation, GaussNewtonModel, Lbfgs, LevenbergMarquardt, Optimiser, Variable,
};
use std::time::Instant;

/// When an inversion stops.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Stop {
    /// Iterations at most.
    pub max_iterations: usize,
    /// Stop when `L ≤ loss · L(first guess)`.
    pub loss: f64,
}

/// What an inversion reached.
#[derive(Clone, Debug)]
pub(crate) struct Recovered {
    /// The recovered unknowns `θ`.
    pub theta: Vec<f64>,
    /// Iterations taken.
    pub iterations: usize,
    /// Gradients computed (one per trial point of the line search).
    pub evaluations: usize,
    /// The loss at the first guess.
    pub first_loss: f64,
    /// The loss at the end.
    pub loss: f64,
    /// Wall-clock time (s).
    pub wall: f64,
    /// Per iteration (the first guess first): the loss and `θ`.
    pub history: Vec<(f64, Vec<f64>)>,
}

impl Recovered {
    /// The history as CSV rows: iteration, loss, then `θ`.
    pub fn rows(&self) -> Vec<Vec<f64>> {
        (self.history.iter().enumerate())
            .map(|(i, (loss, theta))| {
                [i as f64, *loss]
                    .into_iter()
                    .chain(theta.iter().copied())
                    .collect()
            })
            .collect()
    }
}

/// Minimises a loss from `theta0` by L-BFGS (10 pairs, a first step of 0.1 in the
/// optimiser's variables), each unknown moved through its [`Variable`]; `gradient` gives
/// `L(θ)` and `dL/dθ` (a [`loam_inverse::Problem`]'s or an implicit problem's).
pub(crate) fn lbfgs(
    case: &str,
    gradient: impl Fn(&[f64]) -> Result<(f64, Vec<f64>), AdjointError>,
    variables: &[Variable],
    theta0: &[f64],
    stop: Stop,
) -> Result<Recovered, VerifyError> {
    minimise(
        case,
        Optimiser::Lbfgs(Lbfgs::new(10, 0.1)),
        |theta| {
            gradient(theta).map(|(loss, gradient)| GaussNewtonModel {
                loss,
                gradient,
                matrix: Vec::new(),
            })
        },
        variables,
        theta0,
        stop,
    )
}

/// Minimises a least-squares loss from `theta0` by Levenberg–Marquardt (first damping
/// 10⁻³), each unknown moved through its [`Variable`]; `model` gives the loss's Gauss–Newton
/// model at `θ`.
pub(crate) fn levenberg_marquardt(
    case: &str,
    model: impl Fn(&[f64]) -> Result<GaussNewtonModel, AdjointError>,
    variables: &[Variable],
    theta0: &[f64],
    stop: Stop,
) -> Result<Recovered, VerifyError> {
    minimise(
        case,
        Optimiser::LevenbergMarquardt(LevenbergMarquardt::new(1e-3)),
        model,
        variables,
        theta0,
        stop,
    )
}

/// Minimises a loss from `theta0` by `optimiser`; `model` gives `L(θ)`, `dL/dθ` and, for
/// Levenberg–Marquardt, the Gauss–Newton matrix in `θ` (empty otherwise), which is carried
/// to the optimiser's variables as `Sᵀ H S`, `S = diag(dθ/dz)`.
fn minimise(
    case: &str,
    mut optimiser: Optimiser,
    model: impl Fn(&[f64]) -> Result<GaussNewtonModel, AdjointError>,
    variables: &[Variable],
    theta0: &[f64],
    stop: Stop,
) -> Result<Recovered, VerifyError> {
    let start = Instant::now();
    let physical = |z: &[f64]| -> Vec<f64> {
        z.iter()
            .zip(variables)
            .map(|(z, v)| v.physical(*z))
            .collect()
    };
    let evaluations = std::cell::Cell::new(0);
    // z ↦ (L, ∇_z L), ∇_z L = dL/dθ · dθ/dz.
    let mut evaluate = |z: &[f64]| -> Result<Evaluation, AdjointError> {
        evaluations.set(evaluations.get() + 1);
        let m = model(&physical(z))?;
        let slopes: Vec<f64> = z.iter().zip(variables).map(|(z, v)| v.slope(*z)).collect();
        let n = z.len();
        let curvature = (!m.matrix.is_empty()).then(|| {
            (0..n * n)
                .map(|i| m.matrix[i] * slopes[i / n] * slopes[i % n])
                .collect()
        });
        Ok(Evaluation {
            x: z.to_vec(),
            loss: m.loss,
            gradient: m.gradient.iter().zip(&slopes).map(|(g, s)| g * s).collect(),
            curvature,
        })
    };
    let project = |z: &mut [f64]| {
        z.iter_mut()
            .zip(variables)
            .for_each(|(z, v)| *z = v.project(*z))
    };
    let failed = |source| VerifyError::Adjoint {
        case: case.into(),
        source,
    };
    let z0: Vec<f64> = (theta0.iter().zip(variables))
        .map(|(t, v)| v.internal(*t))
        .collect();
    let mut current = evaluate(&z0).map_err(failed)?;
    let first_loss = current.loss;
    let mut iterations = 0;
    let mut history = vec![(current.loss, physical(&current.x))];
    while iterations < stop.max_iterations
        && current.loss > stop.loss * first_loss
        && norm(&current.gradient) > 0.0
    {
        match optimiser
            .iterate(&current, &mut evaluate, &project)
            .map_err(failed)?
        {
            Some(next) => {
                history.push((next.loss, physical(&next.x)));
                current = next;
            }
            None => break,
        }
        iterations += 1;
    }
    Ok(Recovered {
        theta: physical(&current.x),
        iterations,
        evaluations: evaluations.get(),
        first_loss,
        loss: current.loss,
        wall: start.elapsed().as_secs_f64(),
        history,
    })
}
