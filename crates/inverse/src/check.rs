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

/// The Richardson-extrapolated central difference of `along(d) = L(θ + d e)` at `d = 0`:
/// `(4 D(δ/2) − D(δ))/3` with `D(δ) = (L(θ + δ) − L(θ − δ))/(2δ)`, whose truncation is
/// `O(δ⁴)`.
///
/// # Errors
/// Those of `along`.
pub fn richardson<E>(mut along: impl FnMut(f64) -> Result<f64, E>, delta: f64) -> Result<f64, E> {
    let d1 = (along(delta)? - along(-delta)?) / (2.0 * delta);
    let d2 = (along(0.5 * delta)? - along(-0.5 * delta)?) / delta;
    Ok((4.0 * d2 - d1) / 3.0)
}

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
    let moved = |d: f64| {
        let mut t = theta.to_vec();
        t[k] += d;
        t
    };
    for d in [delta, -delta, 0.5 * delta, -0.5 * delta] {
        if !same_branches(problem, &moved(d), base)? {
            return Ok(None);
        }
    }
    Ok(Some(Difference {
        value: richardson(|d| problem.loss(&moved(d)), delta)?,
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

/// A jump of the loss along a line through `θ`: `L(θ + d e)` changes by about `size` between
/// `d = lo` and `d = hi`, however close they are brought.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jump {
    /// The near end of the interval that holds the jump (`θ + lo`).
    pub lo: f64,
    /// The far end.
    pub hi: f64,
    /// `L(θ + hi) − L(θ + lo)` less the slope's share: the jump.
    pub size: f64,
}

impl Jump {
    /// Whether the points `θ + d` for `d` in `[from, to]` (either order) can lie on both
    /// sides of the jump: the interval reaches into `[lo, hi]`.
    pub fn straddled_by(&self, from: f64, to: f64) -> bool {
        let (a, b) = (from.min(to), from.max(to));
        let (lo, hi) = (self.lo.min(self.hi), self.lo.max(self.hi));
        a < hi && b > lo
    }
}

/// The relative steps of the ladder [`find_jumps`] samples on each side of `θ` (times
/// `max(|θ|, 10⁻³)` on the explicit path): from the Taylor test's first step down to the
/// smallest difference step.
pub const JUMP_LADDER: [f64; 5] = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6];

/// How many times [`find_jumps`] halves the interval it suspects: a smooth loss keeps 2⁻¹²
/// of its excess over the slope, a jump all of it.
pub const JUMP_BISECTIONS: usize = 12;

/// Looks for jumps of `along(d) = L(θ + d e)` near `θ`, given `L(θ)` (`loss`), the slope
/// `dL/dd` of the smooth piece at `θ` (the adjoint's, `slope`) and the sampling scale `size`:
/// the nearest to `θ` on each side, nearer first.
///
/// `L` is sampled at `d = ±size · s` for `s` in [`JUMP_LADDER`]; between neighbouring samples
/// the excess `|ΔL − slope Δd|` is what the slope does not explain. Each interval, nearest to
/// `θ` first, is halved up to [`JUMP_BISECTIONS`] times, each time keeping the half with the
/// larger excess, as long as that half keeps at least half the interval's first excess and
/// the other half at most a quarter of the kept one. Over an interval of width `w` a smooth
/// loss, a kink or a wrong slope leave an excess of order `w`, shared between the halves
/// (the bisection stops within a halving or two), a jump its whole size, in one half;
/// round-off does not shrink either, but is as large in both halves. An interval that passes
/// every halving holds a jump; the search goes on on the other side only.
///
/// # Errors
/// Those of `along`.
pub fn find_jumps<E>(
    loss: f64,
    slope: f64,
    size: f64,
    mut along: impl FnMut(f64) -> Result<f64, E>,
) -> Result<Vec<Jump>, E> {
    let mut samples = vec![(0.0, loss)];
    for s in JUMP_LADDER {
        for d in [size * s, -size * s] {
            samples.push((d, along(d)?));
        }
    }
    samples.sort_by(|a, b| a.0.total_cmp(&b.0));
    let excess = |a: (f64, f64), b: (f64, f64)| (b.1 - a.1 - slope * (b.0 - a.0)).abs();
    let mut intervals: Vec<((f64, f64), (f64, f64))> =
        samples.windows(2).map(|w| (w[0], w[1])).collect();
    intervals.sort_by(|p, q| {
        let near = |(a, b): &((f64, f64), (f64, f64))| a.0.abs().min(b.0.abs());
        near(p).total_cmp(&near(q))
    });
    let mut jumps: Vec<Jump> = Vec::new();
    'intervals: for (mut a, mut b) in intervals {
        // Samples are on one side of θ or end at it: the side is the sign of the far end.
        let side = (a.0 + b.0).signum();
        let first = excess(a, b);
        if jumps.iter().any(|j| j.hi.signum() == side) || !(first > 0.0 && first.is_finite()) {
            continue;
        }
        for _ in 0..JUMP_BISECTIONS {
            let m = 0.5 * (a.0 + b.0);
            let mid = (m, along(m)?);
            let (left, right) = (excess(a, mid), excess(mid, b));
            let (kept, other) = (left.max(right), left.min(right));
            if kept < 0.5 * first || other > 0.25 * kept {
                continue 'intervals;
            }
            if left >= right {
                b = mid;
            } else {
                a = mid;
            }
        }
        // The near end first.
        let (lo, hi) = if a.0.abs() <= b.0.abs() {
            (a.0, b.0)
        } else {
            (b.0, a.0)
        };
        jumps.push(Jump {
            lo,
            hi,
            size: b.1 - a.1 - slope * (b.0 - a.0),
        });
    }
    Ok(jumps)
}

impl Convergence {
    /// The differences without those whose stencil (`±δ`, `δ = relative_step · size`)
    /// straddles one of `jumps`, and the converged value among the rest (the first
    /// neighbouring pair that agrees to [`CONVERGENCE_TOLERANCE`]): a difference across a
    /// jump measures the jump, not the derivative.
    pub fn clear_of(&self, jumps: &[Jump], size: f64) -> Self {
        let clear = |d: &Difference| {
            let delta = d.relative_step * size;
            !jumps.iter().any(|j| j.straddled_by(-delta, delta))
        };
        Self::of(self.estimates.iter().map(|e| e.filter(clear)).collect())
    }

    /// The estimates at steps largest first (`None` where a step is not used) and the first
    /// neighbouring pair that agrees to [`CONVERGENCE_TOLERANCE`]: its smaller step's
    /// estimate is the converged value.
    pub fn of(estimates: Vec<Option<Difference>>) -> Self {
        let mut out = Self {
            estimates,
            value: None,
            spread: f64::NAN,
        };
        for w in out.estimates.windows(2) {
            if let (Some(a), Some(b)) = (w[0], w[1]) {
                let spread = (a.value - b.value).abs() / a.value.abs().max(b.value.abs());
                if out.spread.is_nan() || spread < out.spread {
                    out.spread = spread;
                }
                if spread <= CONVERGENCE_TOLERANCE {
                    out.value = Some(b);
                    out.spread = spread;
                    break;
                }
            }
        }
        out
    }
}

/// The first Taylor step `h₀` of `steps` (largest first; relative, times `size`) whose points
/// `θ + h₀/2ⁱ` stay on `θ`'s side of every one of `jumps`: `None` when every one reaches one.
pub fn taylor_step_clear_of(jumps: &[Jump], size: f64, steps: &[f64]) -> Option<f64> {
    steps
        .iter()
        .map(|s| s * size)
        .find(|&h0| !jumps.iter().any(|j| j.straddled_by(0.0, h0)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::convert::Infallible;

    /// `L(θ + d) = (1 + d)² + J H(d − s)`: slope 2 at θ and a jump of `J` at `s`.
    fn stepped(jump: f64, at: f64) -> impl Fn(f64) -> Result<f64, Infallible> {
        move |d: f64| Ok((1.0 + d).powi(2) + if d > at { jump } else { 0.0 })
    }

    /// The central differences of [`converged_difference`] at its steps, as it would take
    /// them on `f` (no branches here), all of them.
    fn differences(f: &dyn Fn(f64) -> Result<f64, Infallible>) -> Convergence {
        let estimates = CONVERGENCE_STEPS
            .iter()
            .map(|&s| {
                Some(Difference {
                    value: richardson(f, s).unwrap(),
                    relative_step: s,
                })
            })
            .collect();
        Convergence {
            estimates,
            value: None,
            spread: f64::NAN,
        }
    }

    /// A jump of 10⁻⁹ at `d = 3·10⁻⁶`: the differences at `δ = 10⁻⁴` and `10⁻⁵` straddle it
    /// (off by `J/δ`, up to 10⁻⁴ of the slope) and are dropped, the one at `10⁻⁶` is the slope
    /// to round-off; the Taylor test starts at `h₀ = 10⁻⁶`, below the jump, where its
    /// remainder is the smooth `h²`. The jump is found within `2⁻¹²` of the ladder's interval.
    #[test]
    fn a_jump_is_found_and_the_steps_that_straddle_it_are_left_out() {
        let f = stepped(1e-9, 3e-6);
        let jumps = find_jumps(1.0, 2.0, 1.0, &f).unwrap();
        let [jump] = jumps[..] else {
            panic!("one jump: {jumps:?}")
        };
        assert!(jump.lo < 3e-6 && 3e-6 <= jump.hi, "{jump:?}");
        assert!(jump.hi - jump.lo < 1e-5 / 4000.0, "{jump:?}");
        assert!((jump.size - 1e-9).abs() < 1e-11, "{jump:?}");
        let all = differences(&f);
        // Before: the largest step is off by the jump over it.
        let first = all.estimates[0].unwrap().value;
        assert!((first - 2.0).abs() > 1e-6, "{first}");
        let clear = all.clear_of(&jumps, 1.0);
        assert!(clear.estimates[0].is_none() && clear.estimates[1].is_none());
        let kept = clear.estimates[2].expect("δ = 1e-6 is clear").value;
        // Round-off of a loss of 1 over δ = 1e-6: about 1e-10.
        assert!((kept - 2.0).abs() < 1e-8, "{kept}");
        assert_eq!(clear.value, None, "one difference alone does not converge");
        let h0 = taylor_step_clear_of(&jumps, 1.0, &JUMP_LADDER).expect("a clear step");
        assert_eq!(h0, 1e-6);
        // On the other side of θ the jump leaves the Taylor test alone.
        let left = stepped(1e-9, -3e-6);
        let jumps = find_jumps(left(0.0).unwrap(), 2.0, 1.0, &left).unwrap();
        assert!(
            jumps.len() == 1 && jumps[0].hi <= -3e-6 && -3e-6 < jumps[0].lo,
            "{jumps:?}"
        );
        assert_eq!(taylor_step_clear_of(&jumps, 1.0, &JUMP_LADDER), Some(1e-2));
        // One on each side: both are found, the nearer first, and both are kept clear of.
        let both = |d: f64| Ok::<_, Infallible>(f(d)? + left(d)? - (1.0 + d).powi(2));
        let jumps = find_jumps(both(0.0).unwrap(), 2.0, 1.0, both).unwrap();
        assert_eq!(jumps.len(), 2, "{jumps:?}");
        assert!(jumps[0].lo.abs() <= jumps[1].lo.abs(), "{jumps:?}");
        assert_eq!(taylor_step_clear_of(&jumps, 1.0, &JUMP_LADDER), Some(1e-6));
    }

    /// A jump between the difference steps (at `d = 3·10⁻⁵`): the two smaller steps agree
    /// and converge to the slope once the straddling one is left out.
    #[test]
    fn differences_clear_of_a_jump_converge() {
        let f = stepped(1e-7, 3e-5);
        let jumps = find_jumps(1.0, 2.0, 1.0, &f).unwrap();
        assert_eq!(jumps.len(), 1, "{jumps:?}");
        let clear = differences(&f).clear_of(&jumps, 1.0);
        let value = clear.value.expect("converged").value;
        assert!((value - 2.0).abs() < 1e-8, "{value}");
    }

    /// No jump in a smooth loss, in one with a kink (`|d − s|`) or under a wrong slope.
    #[test]
    fn smooth_losses_and_kinks_have_no_jump() {
        let smooth = |d: f64| Ok::<_, Infallible>((1.0 + d).sin() * 1e3);
        assert_eq!(
            find_jumps(1f64.sin() * 1e3, 1f64.cos() * 1e3, 1.0, smooth),
            Ok(vec![])
        );
        let kink = |d: f64| Ok::<_, Infallible>((1.0 + d).powi(2) + 0.5 * (d - 3e-6).abs());
        assert_eq!(find_jumps(1.0 + 1.5e-6, 1.5, 1.0, kink), Ok(vec![]));
        let wrong = |d: f64| Ok::<_, Infallible>((1.0 + d).powi(2));
        assert_eq!(find_jumps(1.0, 2.7, 1.0, wrong), Ok(vec![]));
    }
}
