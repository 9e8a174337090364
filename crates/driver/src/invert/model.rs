//! The inverse problem an inversion file sets up, by the solver of its scene: the explicit
//! path's [`Problem`] or the implicit path's [`ImplicitProblem`]. The optimiser, the history
//! and the checks see only a loss and its gradient as functions of `θ`.

use loam_inverse::check::{Convergence, Difference, Jump};
use loam_inverse::implicit::{ImplicitParam, ImplicitProblem, check as implicit_check};
use loam_inverse::{
    AdjointError, Control, GaussNewtonModel, GradientCost, Observations, Problem, check,
};

/// The loss of an inversion as a function of its unknowns.
pub enum Model<const D: usize> {
    /// A run of the explicit solver.
    Explicit(Problem<D, Observations<D>>),
    /// A quasi-static load-stepped run of the implicit solver.
    Implicit {
        /// The problem, its point-load parameters indexed by loaded particle.
        problem: ImplicitProblem<D>,
        /// The parameters as the scene names them (`point_loads[k]` a scene entry), for
        /// the recovered scene.
        scene_params: Vec<ImplicitParam>,
        /// The particles the `[[observations.piezometers]]` read, in order.
        piezometers: Vec<usize>,
    },
}

/// What a gradient took.
pub enum Cost {
    /// The explicit path's adjoint: segments, memory, time by part.
    Explicit(GradientCost),
    /// The implicit path's: seconds of the forward run (with its record) and of the reverse
    /// pass.
    Implicit {
        /// Forward run (s).
        forward: f64,
        /// Reverse pass (s).
        reverse: f64,
    },
}

impl<const D: usize> Model<D> {
    /// `L(θ)` and `dL/dθ` by the discrete adjoint.
    ///
    /// # Errors
    /// A run or an adjoint that fails.
    pub fn gradient(&self, theta: &[f64]) -> Result<(f64, Vec<f64>), AdjointError> {
        match self {
            Self::Explicit(p) => p.gradient(theta),
            Self::Implicit { problem, .. } => problem.gradient(theta).map(|g| (g.loss, g.gradient)),
        }
    }

    /// [`Model::gradient`], with what the adjoint took.
    ///
    /// # Errors
    /// As [`Model::gradient`].
    pub fn gradient_and_cost(&self, theta: &[f64]) -> Result<(f64, Vec<f64>, Cost), AdjointError> {
        match self {
            Self::Explicit(p) => p
                .gradient_and_cost(theta)
                .map(|(loss, g, cost)| (loss, g, Cost::Explicit(cost))),
            Self::Implicit { problem, .. } => problem.gradient(theta).map(|g| {
                let cost = Cost::Implicit {
                    forward: g.forward_seconds,
                    reverse: g.reverse_seconds,
                };
                (g.loss, g.gradient, cost)
            }),
        }
    }

    /// What each observed quantity is, with its data `d` and weight `c` (`L = Σ c (y − d)²`),
    /// in the order of [`Model::observe`].
    pub fn labelled(&self) -> Vec<(String, f64, f64)> {
        match self {
            Self::Explicit(p) => p.labelled(),
            Self::Implicit { problem, .. } => problem.observations.labelled(),
        }
    }

    /// The observed quantities `y(θ)` of the run at `theta`.
    ///
    /// # Errors
    /// A run that fails.
    pub fn observe(&self, theta: &[f64]) -> Result<Vec<f64>, AdjointError> {
        match self {
            Self::Explicit(p) => p.observe(theta),
            Self::Implicit { problem, .. } => problem.observe(theta),
        }
    }

    /// `ȳᵀ ∂y/∂θ` by the adjoint seeded with the cotangent `ȳ` of the observed quantities.
    ///
    /// # Errors
    /// A cotangent of the wrong length, or a run or an adjoint that fails.
    pub fn vjp(&self, theta: &[f64], cotangent: &[f64]) -> Result<Vec<f64>, AdjointError> {
        match self {
            Self::Explicit(p) => p.vjp(theta, cotangent),
            Self::Implicit { problem, .. } => problem.vjp(theta, cotangent),
        }
    }

    /// `(L, dL/dθ)` at an optimiser's trial point: on an implicit scene a run that stops
    /// gives an infinite loss ([`ImplicitProblem::trial_gradient`]).
    ///
    /// # Errors
    /// As [`Model::gradient`].
    pub fn trial_gradient(&self, theta: &[f64]) -> Result<(f64, Vec<f64>), AdjointError> {
        match self {
            Self::Explicit(p) => p.gradient(theta),
            Self::Implicit { problem, .. } => problem.trial_gradient(theta),
        }
    }

    /// The Gauss–Newton model of the loss at `θ` ([`Problem::gauss_newton`]); the file's
    /// checks allow it on explicit scenes only.
    ///
    /// # Errors
    /// A run that fails.
    pub fn gauss_newton(&self, theta: &[f64]) -> Result<GaussNewtonModel, AdjointError> {
        match self {
            Self::Explicit(p) => p.gauss_newton(theta),
            Self::Implicit { .. } => unreachable!("optimizer.method is checked for the scene"),
        }
    }

    /// The unknowns of the explicit path (none for the implicit one, whose unknowns are all
    /// named parameters).
    pub fn controls(&self) -> &[Control] {
        match self {
            Self::Explicit(p) => &p.controls,
            Self::Implicit { .. } => &[],
        }
    }

    /// What a run is, for the reports: `600 steps`, `10 load steps`, or for Newmark dynamics
    /// `5 time steps of 0.04 s`.
    pub fn run_length(&self) -> String {
        match self {
            Self::Explicit(p) => format!("{} steps", p.steps),
            Self::Implicit { problem, .. } => match problem.config.dynamics {
                Some(dt) => format!("{} time steps of {dt} s", problem.config.load_steps),
                None => format!("{} load steps", problem.config.load_steps),
            },
        }
    }

    /// How `--check` computes its columns.
    pub fn check_legend(&self) -> &'static str {
        match self {
            Self::Explicit(_) => {
                "  checks: dual = forward-mode Dual64 run; central difference: Richardson-extrapolated, at δ = 1e-4, 1e-5, 1e-6 max(|θ|, 1e-3)\n  \
                 until two neighbouring steps agree to 1e-6 (conv.: the smaller δ; perturbed runs that switch a branch are not used);\n  \
                 Taylor remainder r(h) = |L(θ + h) − L(θ) − h dL/dθ| for h = 1e-2 max(|θ|, 1e-3) and h/2, h/4, h/8\n  \
                 (r falls 4× per halving where L is smooth; a stick/slip or yield switch within h shows as a smaller ratio);\n  \
                 where the differences do not converge or r falls less than 3×, L is searched for a jump: differences across it are\n  \
                 left out, \"(jump)\" where none is clear of it, and the Taylor test starts at the first h of 1e-2 … 1e-6 short of it"
            }
            Self::Implicit { .. } => {
                "  checks: dual = forward-mode Dual64 tangent of every sub-step; central difference\n  \
                 (Richardson, at δ = 1e-4 and 1e-5 |θ|, converged when they agree to 1e-6) and Taylor remainder r(h) = |L(θ + h) − L(θ) − h dL/dθ|\n  \
                 for h = 1e-2 |θ| and h/2, h/4, h/8, every run on the sub-steps of the run at θ\n  \
                 (r falls 4× per halving where L is smooth; a yield switch within h shows as a smaller ratio);\n  \
                 where the differences do not converge or r falls less than 3×, L is searched for a jump: differences across it are\n  \
                 left out, \"(jump)\" where none is clear of it, and the Taylor test starts at the first h of 1e-2 … 1e-6 |θ| short of it"
            }
        }
    }

    /// The dual derivative, the central differences and the Taylor remainders of unknown `k`
    /// at `theta`, where the loss is `loss` and the adjoint gives `adjoint`.
    ///
    /// Where the differences do not converge or the Taylor remainders do not fall 3× per
    /// halving, the loss along `k` is searched for jumps ([`check::find_jumps`]): the
    /// differences whose stencil straddles one are left out and the Taylor test starts from
    /// the largest step of [`check::JUMP_LADDER`] short of them, so that neither reports a
    /// jump as a derivative.
    ///
    /// # Errors
    /// A run that fails.
    pub fn check_one(
        &self,
        theta: &[f64],
        loss: f64,
        adjoint: f64,
        k: usize,
    ) -> Result<CheckRow, AdjointError> {
        let moved = |d: f64| {
            let mut t = theta.to_vec();
            t[k] += d;
            t
        };
        // The run's loss along `k`, the scale of the steps, the differences and the dual.
        let (along, size, differences, dual) = match self {
            Self::Explicit(problem) => (
                Box::new(move |d| problem.loss(&moved(d))) as Along<'_>,
                theta[k].abs().max(1e-3),
                check::converged_difference(problem, theta, k)?,
                problem.dual_derivative(theta, k)?,
            ),
            Self::Implicit { problem, .. } => {
                let schedule = problem.schedule(theta)?;
                // A perturbed run that does not converge on the run's sub-steps gives no
                // difference at that step.
                let at = |step| {
                    implicit_check::central_difference(problem, theta, &schedule, k, step)
                        .ok()
                        .map(|value| Difference {
                            value,
                            relative_step: step,
                        })
                };
                let differences = Convergence::of(vec![at(1e-4), at(1e-5)]);
                (
                    Box::new(move |d| problem.loss(&moved(d), Some(&schedule))) as Along<'_>,
                    theta[k].abs(),
                    differences,
                    problem.dual_derivative(theta, k)?,
                )
            }
        };
        check_row(loss, adjoint, along, size, differences, dual)
    }
}

/// What `loam gradient --check` measures of one unknown ([`CheckRow`]), at a point where the
/// loss is `loss` and the gradient gives `adjoint`, from the loss `along` the unknown, the
/// scale `size` of its steps, its central `differences` and its dual derivative `dual`.
///
/// Where the differences do not converge or the Taylor remainders do not fall 3× per
/// halving, the loss along the unknown is searched for jumps ([`check::find_jumps`]): the
/// differences whose stencil straddles one are left out and the Taylor test starts from the
/// largest step of [`check::JUMP_LADDER`] short of them, so that neither reports a jump as a
/// derivative.
///
/// # Errors
/// A run that fails.
pub fn check_row(
    loss: f64,
    adjoint: f64,
    mut along: Along<'_>,
    size: f64,
    differences: Convergence,
    dual: f64,
) -> Result<CheckRow, AdjointError> {
    // A perturbed run that fails (Newton does not converge on the sub-steps of the run at θ,
    // or the run goes unstable) gives `NaN` and is recorded: the checks that need it are left
    // out, as across a jump, instead of ending the whole check.
    let mut failed = Vec::new();
    let mut along = |d: f64| -> Result<f64, AdjointError> {
        Ok(along(d).unwrap_or_else(|_| {
            failed.push(d);
            f64::NAN
        }))
    };
    let taylor = |h0: f64, along: &mut dyn FnMut(f64) -> Result<f64, AdjointError>| {
        let mut r = [0.0; 4];
        for (i, r) in r.iter_mut().enumerate() {
            let h = h0 / f64::from(1u32 << i);
            *r = (along(h)? - loss - h * adjoint).abs();
        }
        Ok::<_, AdjointError>(r)
    };
    let mut h0 = 1e-2 * size;
    let mut remainders = taylor(h0, &mut along)?;
    // Where a run of the Taylor test fails, it starts at the first smaller step of the ladder
    // whose four runs all succeed.
    for s in &check::JUMP_LADDER[1..] {
        if remainders.iter().all(|r| r.is_finite()) {
            break;
        }
        h0 = s * size;
        remainders = taylor(h0, &mut along)?;
    }
    let falls = remainders.windows(2).all(|w| w[0] >= 3.0 * w[1]);
    let jumps = if differences.value.is_none() || !falls {
        check::find_jumps(loss, adjoint, size, &mut along)?
    } else {
        Vec::new()
    };
    let differences = if jumps.is_empty() {
        differences
    } else {
        if let Some(h) = check::taylor_step_clear_of(&jumps, size, &check::JUMP_LADDER)
            && h != h0
        {
            h0 = h;
            remainders = taylor(h0, &mut along)?;
        }
        differences.clear_of(&jumps, size)
    };
    // Shown: the converged difference; else the estimate at the largest step that kept
    // the branches (and cleared the jumps); else, where no jump was found, a plain central
    // difference at δ = 10⁻⁴ size (none if one of its runs fails); else none.
    let shown = match (
        differences.value,
        differences.estimates.iter().flatten().next(),
    ) {
        (Some(d), _) | (None, Some(&d)) => Some(d.value),
        (None, None) if jumps.is_empty() => {
            let delta = 1e-4 * size;
            Some((along(delta)? - along(-delta)?) / (2.0 * delta)).filter(|d| d.is_finite())
        }
        (None, None) => None,
    };
    Ok(CheckRow {
        dual,
        difference: shown,
        converged: differences
            .value
            .map(|d| (d.relative_step, differences.spread)),
        remainders,
        taylor_step: h0,
        jumps,
        failed,
    })
}

/// The loss along one unknown, `d ↦ L(θ + d eₖ)`, by the run of either path.
pub type Along<'a> = Box<dyn FnMut(f64) -> Result<f64, AdjointError> + 'a>;

/// How far (relative) the dual derivative may be from a converged central difference before
/// `loam gradient --check` fails: ten times [`check::CONVERGENCE_TOLERANCE`], the agreement
/// that made the difference converged (its truncation and round-off are below that), while a
/// derivative that misses a dependence of the run on the parameter is off in the leading
/// digits.
pub const DIFFERENCE_TOLERANCE: f64 = 1e-5;

/// What `loam gradient --check` measured for one unknown ([`Model::check_one`]).
#[derive(Clone, Debug, PartialEq)]
pub struct CheckRow {
    /// The forward-mode dual derivative.
    pub dual: f64,
    /// The central difference shown: the converged one where there is one; `None` when the
    /// loss jumps within every step tried.
    pub difference: Option<f64>,
    /// Where central differences at neighbouring steps agreed to
    /// [`check::CONVERGENCE_TOLERANCE`]: the smaller relative step and their relative spread.
    /// `None` when they did not (the loss has a kink within the steps, or round-off
    /// dominates), and the difference says nothing about the gradient.
    pub converged: Option<(f64, f64)>,
    /// The Taylor remainders `r(h)`, `r(h/2)`, `r(h/4)`, `r(h/8)`.
    pub remainders: [f64; 4],
    /// The Taylor test's first step `h`.
    pub taylor_step: f64,
    /// The jumps of the loss found near `θ` (the nearest on each side), which the differences
    /// and the Taylor test avoid.
    pub jumps: Vec<Jump>,
    /// The steps `d` of the Taylor test and the jump search whose runs at `θ + d eₖ` failed,
    /// in the order tried.
    pub failed: Vec<f64>,
}

impl CheckRow {
    /// Whether the central differences converged and the dual derivative is further than
    /// [`DIFFERENCE_TOLERANCE`] (relative) from them: then a gradient that agrees with the
    /// dual misses a dependence of the run on the parameter, and `--check` fails.
    pub fn misses_the_difference(&self) -> bool {
        match (self.converged, self.difference) {
            (Some(_), Some(difference)) => {
                let scale = self.dual.abs().max(difference.abs());
                (self.dual - difference).abs() > DIFFERENCE_TOLERANCE * scale
            }
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(dual: f64, difference: f64, converged: bool) -> CheckRow {
        CheckRow {
            dual,
            difference: Some(difference),
            converged: converged.then_some((1e-5, 1e-9)),
            remainders: [0.0; 4],
            taylor_step: 1e-2,
            jumps: Vec::new(),
            failed: Vec::new(),
        }
    }

    /// Perturbed runs that fail beyond `θ + 5·10⁻³` (a Newton iteration that no longer
    /// converges there) leave the check standing: the Taylor test starts at the first step
    /// of the ladder short of them (10⁻³) and falls 4× per halving on the smooth loss
    /// `L = sin(θ + d)`, and the failed runs are recorded.
    #[test]
    fn failed_perturbed_runs_are_left_out() {
        let theta = 0.7_f64;
        let along: Along<'_> = Box::new(move |d: f64| {
            if d > 5e-3 {
                Err(AdjointError::Parameter {
                    param: "x".into(),
                    msg: "the run failed".into(),
                })
            } else {
                Ok((theta + d).sin())
            }
        });
        let slope = theta.cos();
        let differences = Convergence::of(vec![
            Some(Difference {
                value: slope,
                relative_step: 1e-4,
            }),
            Some(Difference {
                value: slope,
                relative_step: 1e-5,
            }),
        ]);
        let row = check_row(theta.sin(), slope, along, 1.0, differences, slope).unwrap();
        assert_eq!(row.taylor_step, 1e-3);
        assert!(!row.failed.is_empty() && row.failed.iter().all(|&d| d > 5e-3));
        for w in row.remainders.windows(2) {
            assert!((3.5..4.5).contains(&(w[0] / w[1])), "{:?}", row.remainders);
        }
        assert!(row.jumps.is_empty());
        assert_eq!(row.difference, Some(slope));
    }

    /// A dual derivative 1.68× a converged difference (the figure of a moving disk's velocity
    /// before its moving surface was differentiated) fails; one within round-off passes; an
    /// unconverged difference (a kink within the steps) decides nothing.
    #[test]
    fn a_converged_difference_decides_the_check() {
        assert!(row(4.944e-3, 2.9356e-3, true).misses_the_difference());
        assert!(row(-1.0, 1.0, true).misses_the_difference());
        assert!(!row(2.935_615_124e-3, 2.935_615_113e-3, true).misses_the_difference());
        assert!(!row(4.944e-3, 2.9356e-3, false).misses_the_difference());
        assert!(!row(0.0, 0.0, true).misses_the_difference());
    }
}
