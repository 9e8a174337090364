//! Checks of a gradient against other derivatives of the same loss: branch-aware central
//! finite differences and the Taylor test (`loam gradient --check`, the `adjoint-fd`
//! verification case and the adjoint tests).
//!
//! The loss of an explicit run is piecewise smooth in its parameters: a node switching between
//! stick and slip, a particle starting to yield or being projected back onto a wall changes
//! the branch of the step, and across such a switch a finite difference measures the jump, not
//! the derivative. The checks here therefore compare the branches every step of a perturbed
//! run took ([`branches`]) with those of the run at the point, and use the largest
//! perturbation that keeps them all.

use crate::error::AdjointError;
use crate::objective::ScalarObjective;
use crate::problem::Problem;
use loam_core::Particles;
use loam_core::step::{NodeState, ParticleBranch, StepRecord};
use loam_explicit::{Config, Solver};

/// The branches one step took: the contact and wall states of the nodes where a unilateral
/// constraint acted, and the projections and stress-update regions of the particles.
pub type Branches = (Vec<(usize, NodeState)>, Vec<ParticleBranch>);

/// The branches every step of a run of `steps` steps took.
///
/// # Errors
/// A run that is refused or stops.
pub fn branches<const D: usize>(
    config: &Config<f64, D>,
    particles: &Particles<f64, D>,
    steps: usize,
) -> Result<Vec<Branches>, AdjointError> {
    let mut solver = Solver::new(config.clone(), particles)?;
    let mut p = particles.clone();
    (0..steps)
        .map(|_| {
            let mut record = StepRecord::default();
            solver.step_recorded(&mut p, f64::INFINITY, &mut record)?;
            Ok((record.nodes, record.particles))
        })
        .collect()
}

/// Whether the run of `problem` at `theta` takes the branches `base` in every step.
fn same_branches<const D: usize, O: ScalarObjective<D>>(
    problem: &Problem<D, O>,
    theta: &[f64],
    base: &[Branches],
) -> Result<bool, AdjointError> {
    let (config, particles) = problem.setup(theta)?;
    Ok(branches(&config, &particles, problem.steps)? == base)
}

/// The relative steps `δ / max(|θ|, 10⁻³)` [`central_difference`] tries, largest first.
pub const DIFFERENCE_STEPS: [f64; 5] = [1e-4, 3e-5, 1e-5, 3e-6, 1e-6];

/// A central difference and the relative step it was taken with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Difference {
    /// The difference quotient.
    pub value: f64,
    /// `δ / max(|θ|, 10⁻³)`.
    pub relative_step: f64,
}

/// The central difference of the loss with respect to the unknown `k` at `theta`,
/// Richardson-extrapolated, `(4 D(δ/2) − D(δ))/3` with `D(δ) = (L(θ + δ) − L(θ − δ))/(2δ)`
/// (truncation O(δ⁴)), at the steps `δ` of [`DIFFERENCE_STEPS`] (relative to
/// `max(|θ_k|, 10⁻³)`) for which the four perturbed runs take the branches of the run at
/// `theta` in every step; of those, the one that agrees best with the estimate at the next
/// smaller such step (the plateau between truncation and round-off), or the only one. `None`
/// when every step switches a branch.
///
/// No single step suits every loss: a loss of order one that moves by 1e-11 when a viscosity
/// moves by δ = 5e-8 loses its difference in the round-off of the run, while a constant with a
/// large higher derivative (ν or E of a Neo-Hookean body in an impact) needs δ ≤ 10⁻⁵ |θ| for
/// a truncation error below 1e-8. Where the estimates at neighbouring steps agree, both
/// errors are below their difference.
///
/// # Errors
/// As [`Problem::loss`].
pub fn central_difference<const D: usize, O: ScalarObjective<D>>(
    problem: &Problem<D, O>,
    theta: &[f64],
    k: usize,
) -> Result<Option<Difference>, AdjointError> {
    let (config, particles) = problem.setup(theta)?;
    let base = branches(&config, &particles, problem.steps)?;
    // The estimate at every step, `None` where a perturbed run switches a branch.
    let mut estimates: Vec<Option<Difference>> = Vec::new();
    for relative_step in DIFFERENCE_STEPS {
        estimates.push(difference_at(problem, theta, k, relative_step, &base)?);
    }
    let plateau = (estimates.windows(2))
        .filter_map(|w| match (w[0], w[1]) {
            (Some(a), Some(b)) => Some((a, (a.value - b.value).abs())),
            _ => None,
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(a, _)| a);
    Ok(plateau.or_else(|| estimates.into_iter().flatten().next()))
}

/// The relative steps [`converged_difference`] tries, largest first: a decade apart, so that
/// agreement between neighbours shows the truncation error and the round-off are both small.
pub const CONVERGENCE_STEPS: [f64; 3] = [1e-4, 1e-5, 1e-6];

/// How close the central differences at two neighbouring steps of [`CONVERGENCE_STEPS`] must
/// be, relative to the larger of the two, for [`converged_difference`] to call them converged.
///
/// On a loss that is smooth over the steps, the Richardson estimates at `δ = 10⁻⁴, 10⁻⁵ |θ|`
/// differ by their truncation (O(δ⁴), below 1e-12 relative) and their round-off (that of the
/// loss over `δ`, about 1e-10 relative on a loss of order one), so 1e-6 is met with room; a
/// derivative that depends on the step (a kink or a jump within it) is not.
pub const CONVERGENCE_TOLERANCE: f64 = 1e-6;

/// The central differences of [`converged_difference`]: the estimate at each step and the
/// converged value, if any.
#[derive(Clone, Debug, PartialEq)]
pub struct Convergence {
    /// The estimate at each step tried, largest first; `None` where a perturbed run switched
    /// a branch.
    pub estimates: Vec<Option<Difference>>,
    /// The estimate at the smaller step of the first neighbouring pair that agrees to
    /// [`CONVERGENCE_TOLERANCE`]; `None` when no pair does.
    pub value: Option<Difference>,
    /// The relative difference `|a − b| / max(|a|, |b|)` of that pair, or of the closest pair
    /// when none agrees (`NaN` when fewer than two steps kept the branches).
    pub spread: f64,
}

/// Branch-aware central differences of the loss with respect to the unknown `k` at `theta`
/// at the steps of [`CONVERGENCE_STEPS`], largest first, each as in [`central_difference`]
/// (Richardson-extrapolated, `None` where one of its perturbed runs switches a branch), until
/// two neighbouring estimates agree to [`CONVERGENCE_TOLERANCE`]: the derivative of the loss
/// on the smooth piece at `theta`, independent of the step, which a correct gradient must
/// equal. A step-dependent estimate (the loss has a kink within the steps, or round-off
/// dominates) gives no converged value.
///
/// # Errors
/// As [`Problem::loss`].
pub fn converged_difference<const D: usize, O: ScalarObjective<D>>(
    problem: &Problem<D, O>,
    theta: &[f64],
    k: usize,
) -> Result<Convergence, AdjointError> {
    let (config, particles) = problem.setup(theta)?;
    let base = branches(&config, &particles, problem.steps)?;
    let mut out = Convergence {
        estimates: Vec::new(),
        value: None,
        spread: f64::NAN,
    };
    for relative_step in CONVERGENCE_STEPS {
        let estimate = difference_at(problem, theta, k, relative_step, &base)?;
        if let (Some(a), Some(Some(b))) = (estimate, out.estimates.last()) {
            let spread = (a.value - b.value).abs() / a.value.abs().max(b.value.abs());
            if out.spread.is_nan() || spread < out.spread {
                out.spread = spread;
            }
            if spread <= CONVERGENCE_TOLERANCE {
                out.estimates.push(estimate);
                out.value = Some(a);
                out.spread = spread;
                return Ok(out);
            }
        }
        out.estimates.push(estimate);
    }
    Ok(out)
}

/// The Richardson estimate of [`central_difference`] at one relative step
/// (`δ = relative_step · max(|θ_k|, 10⁻³)`), `None` when one of its four perturbed runs leaves
/// the branches `base` of the run at `theta` ([`branches`]).
///
/// # Errors
/// As [`Problem::loss`].
pub fn difference_at<const D: usize, O: ScalarObjective<D>>(
    problem: &Problem<D, O>,
    theta: &[f64],
    k: usize,
    relative_step: f64,
    base: &[Branches],
) -> Result<Option<Difference>, AdjointError> {
    let delta = relative_step * theta[k].abs().max(1e-3);
    let points = [delta, -delta, 0.5 * delta, -0.5 * delta].map(|d| {
        let mut t = theta.to_vec();
        t[k] += d;
        t
    });
    for t in &points {
        if !same_branches(problem, t, base)? {
            return Ok(None);
        }
    }
    let [up, down, half_up, half_down] = points.map(|t| problem.loss(&t));
    let d1 = (up? - down?) / (2.0 * delta);
    let d2 = (half_up? - half_down?) / delta;
    Ok(Some(Difference {
        value: (4.0 * d2 - d1) / 3.0,
        relative_step,
    }))
}

/// The Taylor remainders `r(h) = |L(θ + h d) − L(θ) − h ∇L·d|` for `h = h₀, h₀/2, …`
/// (`count` values), given `L(θ)` (`loss`) and the directional derivative `∇L·d` (`slope`).
/// Where `L` is smooth over the steps the remainder is `O(h²)` and falls 4× per halving; a
/// wrong gradient leaves an `O(h)` remainder that falls 2×.
///
/// # Errors
/// As [`Problem::loss`].
pub fn taylor_remainders<const D: usize, O: ScalarObjective<D>>(
    problem: &Problem<D, O>,
    theta: &[f64],
    loss: f64,
    slope: f64,
    direction: &[f64],
    h0: f64,
    count: usize,
) -> Result<Vec<f64>, AdjointError> {
    (0..count)
        .map(|i| {
            let h = h0 / f64::from(1u32 << i);
            let t: Vec<f64> = theta
                .iter()
                .zip(direction)
                .map(|(t, d)| t + h * d)
                .collect();
            Ok((problem.loss(&t)? - loss - h * slope).abs())
        })
        .collect()
}

/// The observed order of remainders at steps that halve: the mean of `log₂(r(h)/r(h/2))`
/// over consecutive pairs, `log₂(r(h₀)/r(h_last)) / (n − 1)` (2 for a correct gradient on a
/// smooth loss).
pub fn observed_order(remainders: &[f64]) -> f64 {
    match (remainders.first(), remainders.last()) {
        (Some(first), Some(last)) if remainders.len() > 1 => {
            (first / last).log2() / (remainders.len() - 1) as f64
        }
        _ => f64::NAN,
    }
}

/// A Taylor test: the remainders, the first step and whether the runs kept the branches.
#[derive(Clone, Debug, PartialEq)]
pub struct Taylor {
    /// `h₀` (the remainders are at `h₀ / 2ⁱ`).
    pub h0: f64,
    /// `r(h₀ / 2ⁱ)`.
    pub remainders: Vec<f64>,
    /// Whether every perturbed run took the branches of the run at `θ` in every step.
    pub same_branches: bool,
}

impl Taylor {
    /// [`observed_order`] of the remainders.
    pub fn order(&self) -> f64 {
        observed_order(&self.remainders)
    }
}

/// The Taylor test along `direction` at the largest `h₀` of `steps` (largest first) for which
/// the `count` perturbed runs keep the branches of the run at `theta`, so that the loss is
/// smooth over them; when every `h₀` switches a branch, the test at the first `h₀`, marked as
/// such (its order shows the kink).
///
/// # Errors
/// As [`Problem::loss`].
pub fn taylor_test<const D: usize, O: ScalarObjective<D>>(
    problem: &Problem<D, O>,
    theta: &[f64],
    loss: f64,
    slope: f64,
    direction: &[f64],
    steps: &[f64],
    count: usize,
) -> Result<Taylor, AdjointError> {
    let (config, particles) = problem.setup(theta)?;
    let base = branches(&config, &particles, problem.steps)?;
    for &h0 in steps {
        let mut kept = true;
        for i in 0..count {
            let h = h0 / f64::from(1u32 << i);
            let t: Vec<f64> = theta
                .iter()
                .zip(direction)
                .map(|(t, d)| t + h * d)
                .collect();
            kept &= same_branches(problem, &t, &base)?;
            if !kept {
                break;
            }
        }
        if kept {
            return Ok(Taylor {
                h0,
                remainders: taylor_remainders(problem, theta, loss, slope, direction, h0, count)?,
                same_branches: true,
            });
        }
    }
    let h0 = steps.first().copied().unwrap_or(1e-2);
    Ok(Taylor {
        h0,
        remainders: taylor_remainders(problem, theta, loss, slope, direction, h0, count)?,
        same_branches: false,
    })
}
