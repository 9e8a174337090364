//! Gradient-based optimisers that run one iteration at a time from a state that can be saved
//! and restored (so an inversion can be interrupted and resumed): Adam with an exponentially
//! decaying learning rate, L-BFGS with a projected backtracking Armijo line search, and
//! Levenberg–Marquardt on a least-squares loss's Gauss–Newton model.
//!
//! L-BFGS is written here rather than taken from `argmin` (0.11 builds here): the inversion
//! needs bounds enforced by projection inside the line search, an optimiser state that is
//! plain data saved between iterations, and control after every iteration (progress lines,
//! interruption); argmin's L-BFGS has no bounds and runs its own loop. The method is short.

use serde::{Deserialize, Serialize};

/// A point with its loss and gradient.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Evaluation {
    /// The variables `z`.
    pub x: Vec<f64>,
    /// `L(z)`.
    pub loss: f64,
    /// `∇L(z)`.
    pub gradient: Vec<f64>,
    /// A model of the Hessian `∇²L(z)`, row-major `n × n` (the Gauss–Newton `2 JᵀJ` of a
    /// least-squares loss), where the optimiser asks for one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub curvature: Option<Vec<f64>>,
}

/// Adam (Kingma & Ba 2015) with the learning rate `α_t = α₀ r^(t/T)` (exponential decay:
/// rate `r` every `T` iterations). With `g` the gradient at iteration `t = 1, 2, …`:
/// `m ← β₁ m + (1 − β₁) g`, `v ← β₂ v + (1 − β₂) g²`,
/// `z ← z − α_t m̂ / (√v̂ + ε)` with `m̂ = m / (1 − β₁ᵗ)`, `v̂ = v / (1 − β₂ᵗ)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Adam {
    /// `α₀`.
    pub learning_rate: f64,
    /// `r`.
    pub decay_rate: f64,
    /// `T`.
    pub decay_steps: f64,
    /// `β₁` (0.9).
    pub beta1: f64,
    /// `β₂` (0.999).
    pub beta2: f64,
    /// `ε` (1e-8).
    pub epsilon: f64,
    /// First moment `m`.
    pub m: Vec<f64>,
    /// Second moment `v`.
    pub v: Vec<f64>,
    /// Iterations done `t`.
    pub t: u64,
}

impl Adam {
    /// Adam for `n` variables with the usual `β₁ = 0.9`, `β₂ = 0.999`, `ε = 1e-8`.
    pub fn new(n: usize, learning_rate: f64, decay_rate: f64, decay_steps: f64) -> Self {
        Self {
            learning_rate,
            decay_rate,
            decay_steps,
            beta1: 0.9,
            beta2: 0.999,
            epsilon: 1e-8,
            m: vec![0.0; n],
            v: vec![0.0; n],
            t: 0,
        }
    }

    /// The learning rate of the next iteration, `α₀ r^(t/T)`.
    pub fn rate(&self) -> f64 {
        self.learning_rate * self.decay_rate.powf(self.t as f64 / self.decay_steps)
    }

    /// The next point from `at` (before projection).
    fn next(&mut self, at: &Evaluation) -> Vec<f64> {
        let rate = self.rate();
        self.t += 1;
        let t = self.t as f64;
        let (b1, b2) = (self.beta1, self.beta2);
        (0..at.x.len())
            .map(|i| {
                let g = at.gradient[i];
                self.m[i] = b1 * self.m[i] + (1.0 - b1) * g;
                self.v[i] = b2 * self.v[i] + (1.0 - b2) * g * g;
                let m_hat = self.m[i] / (1.0 - b1.powf(t));
                let v_hat = self.v[i] / (1.0 - b2.powf(t));
                at.x[i] - rate * m_hat / (v_hat.sqrt() + self.epsilon)
            })
            .collect()
    }
}

/// Limited-memory BFGS (Nocedal & Wright 2006, Alg. 7.4–7.5): the direction `p = −H g`
/// from the last `memory` pairs `s = z₊ − z`, `y = g₊ − g` by the two-loop recursion, with
/// `H₀ = (sᵀy / yᵀy) I` from the latest pair (`H₀ = (first_step / ‖g‖) I` before any), then a
/// backtracking line search on the projected path `z(α) = P(z + α p)`, `α = 1, ½, ¼, …`,
/// accepting the first `α` with the Armijo decrease `L(z(α)) ≤ L(z) + c₁ gᵀ(z(α) − z)`,
/// `c₁ = 10⁻⁴`. A pair is kept only when `sᵀy > 0` (the curvature condition that keeps `H`
/// positive definite); a direction that is not a descent direction restarts from `−g`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Lbfgs {
    /// Pairs kept.
    pub memory: usize,
    /// Length of the first step, in the variables' units.
    pub first_step: f64,
    /// The pairs `(s, y)`, oldest first.
    pub pairs: Vec<(Vec<f64>, Vec<f64>)>,
}

impl Lbfgs {
    /// The most halvings of the step before the line search gives up.
    const MAX_HALVINGS: usize = 30;
    /// `c₁` of the Armijo condition.
    const ARMIJO: f64 = 1e-4;

    /// L-BFGS keeping `memory` pairs, whose first step has length `first_step`.
    pub fn new(memory: usize, first_step: f64) -> Self {
        Self {
            memory: memory.max(1),
            first_step,
            pairs: Vec::new(),
        }
    }

    /// `−H g` by the two-loop recursion.
    fn direction(&self, g: &[f64]) -> Vec<f64> {
        let mut q = g.to_vec();
        let mut alphas = Vec::with_capacity(self.pairs.len());
        for (s, y) in self.pairs.iter().rev() {
            let rho = 1.0 / dot(y, s);
            let a = rho * dot(s, &q);
            axpy(-a, y, &mut q);
            alphas.push((a, rho));
        }
        let gamma = match self.pairs.last() {
            Some((s, y)) => dot(s, y) / dot(y, y),
            None => self.first_step / norm(g).max(f64::MIN_POSITIVE),
        };
        q.iter_mut().for_each(|v| *v *= gamma);
        for ((s, y), (a, rho)) in self.pairs.iter().zip(alphas.into_iter().rev()) {
            let b = rho * dot(y, &q);
            axpy(a - b, s, &mut q);
        }
        q.iter_mut().for_each(|v| *v = -*v);
        q
    }
}

/// Levenberg–Marquardt (Nocedal & Wright 2006, §10.3) on the Gauss–Newton model of a
/// least-squares loss: with `g = ∇L` and `H = 2 JᵀJ` at `z` ([`Evaluation::curvature`]), the
/// step `δ` over the free variables solves `(H + λ diag H) δ = −g` (Marquardt's scaling, so
/// the step does not depend on the variables' units), and `z₊ = P(z + δ)` is accepted when
/// `L(z₊) < L(z)`, then `λ ← max(λ/3, 10⁻¹²)`; otherwise `λ ← 4λ` and the step is solved
/// again. For a loss that fits the data exactly at its minimum the model is exact there and
/// the steps converge quadratically, however unevenly the parameters are seen by the data
/// (where a quasi-Newton method must learn that from differences of gradients).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LevenbergMarquardt {
    /// `λ`.
    pub damping: f64,
}

impl LevenbergMarquardt {
    /// The most times a rejected step is solved again with more damping.
    const MAX_TRIES: usize = 12;

    /// Levenberg–Marquardt starting from the damping `λ`.
    pub fn new(damping: f64) -> Self {
        Self { damping }
    }

    /// `δ` solving `(H + λ diag H) δ = −g` over the variables not `fixed` (zero for those),
    /// by Cholesky; `None` when the damped matrix is not positive definite.
    fn step(&self, h: &[f64], g: &[f64], fixed: &[bool]) -> Option<Vec<f64>> {
        let free: Vec<usize> = (0..g.len()).filter(|&i| !fixed[i]).collect();
        let n = g.len();
        // A variable the data do not see (`Hᵢᵢ = 0`) is damped relative to the largest
        // diagonal, so the system stays regular.
        let floor = 1e-12 * (0..n).map(|i| h[i * n + i]).fold(0.0, f64::max);
        let a = nalgebra::DMatrix::from_fn(free.len(), free.len(), |r, c| {
            let (i, j) = (free[r], free[c]);
            h[i * n + j]
                + if i == j {
                    self.damping * h[i * n + i].max(floor)
                } else {
                    0.0
                }
        });
        let b = nalgebra::DVector::from_iterator(free.len(), free.iter().map(|&i| -g[i]));
        let x = a.cholesky()?.solve(&b);
        let mut delta = vec![0.0; n];
        free.iter().zip(x.iter()).for_each(|(&i, &x)| delta[i] = x);
        Some(delta)
    }
}

/// An optimiser and its state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Optimiser {
    /// [`Adam`].
    Adam(Adam),
    /// [`Lbfgs`].
    Lbfgs(Lbfgs),
    /// [`LevenbergMarquardt`].
    LevenbergMarquardt(LevenbergMarquardt),
}

impl Optimiser {
    /// One iteration from `at`: the next point, evaluated by `evaluate`, with its variables
    /// kept feasible by `project`; `None` when L-BFGS's line search or Levenberg–Marquardt's
    /// damping finds no decrease (the iterate is a minimum to the precision of the loss).
    /// Adam evaluates once per iteration, L-BFGS and Levenberg–Marquardt once per trial step.
    /// Levenberg–Marquardt needs [`Evaluation::curvature`] at `at`.
    ///
    /// # Errors
    /// Those of `evaluate`.
    pub fn iterate<E>(
        &mut self,
        at: &Evaluation,
        evaluate: &mut dyn FnMut(&[f64]) -> Result<Evaluation, E>,
        project: &dyn Fn(&mut [f64]),
    ) -> Result<Option<Evaluation>, E> {
        match self {
            Optimiser::Adam(adam) => {
                let mut x = adam.next(at);
                project(&mut x);
                evaluate(&x).map(Some)
            }
            Optimiser::Lbfgs(lbfgs) => {
                // Variables held at a bound (a small step down the gradient is projected
                // back) are kept fixed this iteration: the quasi-Newton step acts on the
                // others, with their gradient.
                let active = blocked(at, project);
                let free = |v: &mut [f64]| {
                    v.iter_mut()
                        .zip(&active)
                        .filter(|(_, a)| **a)
                        .for_each(|(v, _)| *v = 0.0)
                };
                let mut g = at.gradient.clone();
                free(&mut g);
                let mut p = lbfgs.direction(&g);
                free(&mut p);
                if dot(&p, &g) >= 0.0 {
                    lbfgs.pairs.clear();
                    p = lbfgs.direction(&g);
                }
                let mut alpha = 1.0;
                for _ in 0..Lbfgs::MAX_HALVINGS {
                    let mut x: Vec<f64> = at.x.iter().zip(&p).map(|(x, p)| x + alpha * p).collect();
                    project(&mut x);
                    let s: Vec<f64> = x.iter().zip(&at.x).map(|(a, b)| a - b).collect();
                    if norm(&s) == 0.0 {
                        return Ok(None);
                    }
                    let trial = evaluate(&x)?;
                    if trial.loss <= at.loss + Lbfgs::ARMIJO * dot(&at.gradient, &s) {
                        let mut y: Vec<f64> = (trial.gradient.iter().zip(&at.gradient))
                            .map(|(a, b)| a - b)
                            .collect();
                        free(&mut y);
                        if dot(&s, &y) > 1e-12 * norm(&s) * norm(&y) {
                            if lbfgs.pairs.len() == lbfgs.memory {
                                lbfgs.pairs.remove(0);
                            }
                            lbfgs.pairs.push((s, y));
                        }
                        return Ok(Some(trial));
                    }
                    alpha *= 0.5;
                }
                Ok(None)
            }
            Optimiser::LevenbergMarquardt(lm) => {
                let fixed = blocked(at, project);
                let h = at
                    .curvature
                    .as_deref()
                    .expect("Levenberg–Marquardt evaluates the Gauss–Newton curvature");
                for _ in 0..LevenbergMarquardt::MAX_TRIES {
                    if let Some(delta) = lm.step(h, &at.gradient, &fixed) {
                        let mut x: Vec<f64> = at.x.iter().zip(&delta).map(|(x, d)| x + d).collect();
                        project(&mut x);
                        if x == at.x {
                            return Ok(None);
                        }
                        let trial = evaluate(&x)?;
                        if trial.loss < at.loss {
                            lm.damping = (lm.damping / 3.0).max(1e-12);
                            return Ok(Some(trial));
                        }
                    }
                    lm.damping *= 4.0;
                }
                Ok(None)
            }
        }
    }
}

/// The norm of the gradient over the variables not held on a bound the gradient pushes
/// against (those `project` sends back, as [`Optimiser::iterate`] holds them): zero at a
/// minimum, also one on a bound.
pub fn free_gradient_norm(at: &Evaluation, project: &dyn Fn(&mut [f64])) -> f64 {
    let held = blocked(at, project);
    let free: Vec<f64> = (at.gradient.iter().zip(&held))
        .map(|(g, h)| if *h { 0.0 } else { *g })
        .collect();
    norm(&free)
}

/// Which variables sit on a bound that the gradient pushes against: a step of `10⁻⁷ (1 + |zᵢ|)`
/// down the gradient is projected back to less than half of it.
fn blocked(at: &Evaluation, project: &dyn Fn(&mut [f64])) -> Vec<bool> {
    let step = |x: f64| 1e-7 * (1.0 + x.abs());
    let mut moved: Vec<f64> = (at.x.iter().zip(&at.gradient))
        .map(|(x, g)| x - step(*x) * g.signum())
        .collect();
    project(&mut moved);
    (0..at.x.len())
        .map(|i| at.gradient[i] != 0.0 && (moved[i] - at.x[i]).abs() < 0.5 * step(at.x[i]))
        .collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

/// The Euclidean norm `‖a‖`.
pub fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    y.iter_mut().zip(x).for_each(|(y, x)| *y += a * x);
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::convert::Infallible;

    /// `L = ½ Σ kᵢ (zᵢ − cᵢ)²` (condition number 100), minimum at `c`.
    fn quadratic(x: &[f64]) -> Result<Evaluation, Infallible> {
        let (k, c) = ([1.0, 10.0, 100.0], [1.0, -2.0, 0.5]);
        Ok(Evaluation {
            x: x.to_vec(),
            loss: (0..3).map(|i| 0.5 * k[i] * (x[i] - c[i]).powi(2)).sum(),
            gradient: (0..3).map(|i| k[i] * (x[i] - c[i])).collect(),
            curvature: None,
        })
    }

    /// Rosenbrock's `L = (1 − a)² + 100 (b − a²)²`, minimum 0 at `(1, 1)` in a curved valley.
    fn rosenbrock(x: &[f64]) -> Result<Evaluation, Infallible> {
        let (a, b) = (x[0], x[1]);
        Ok(Evaluation {
            x: x.to_vec(),
            loss: (1.0 - a).powi(2) + 100.0 * (b - a * a).powi(2),
            gradient: vec![
                -2.0 * (1.0 - a) - 400.0 * a * (b - a * a),
                200.0 * (b - a * a),
            ],
            curvature: None,
        })
    }

    /// Rosenbrock as least squares, `r = (1 − a, 10 (b − a²))`, `L = ‖r‖²`, with its
    /// Gauss–Newton curvature `2 JᵀJ`.
    fn rosenbrock_residuals(x: &[f64]) -> Result<Evaluation, Infallible> {
        let (a, b) = (x[0], x[1]);
        let r = [1.0 - a, 10.0 * (b - a * a)];
        let j = [[-1.0, 0.0], [-20.0 * a, 10.0]];
        let jtj = |k: usize, l: usize| 2.0 * (j[0][k] * j[0][l] + j[1][k] * j[1][l]);
        Ok(Evaluation {
            x: x.to_vec(),
            loss: r[0] * r[0] + r[1] * r[1],
            gradient: (0..2)
                .map(|k| 2.0 * (j[0][k] * r[0] + j[1][k] * r[1]))
                .collect(),
            curvature: Some(vec![jtj(0, 0), jtj(0, 1), jtj(1, 0), jtj(1, 1)]),
        })
    }

    /// Linear residuals `r = (10³ (a − 1), 10⁻³ (b + 2))`: the curvatures along `a` and `b`
    /// differ by 10¹², as between a parameter the data see everywhere and one they barely see.
    fn uneven(x: &[f64]) -> Result<Evaluation, Infallible> {
        let (ka, kb) = (1e3, 1e-3);
        let r = [ka * (x[0] - 1.0), kb * (x[1] + 2.0)];
        Ok(Evaluation {
            x: x.to_vec(),
            loss: r[0] * r[0] + r[1] * r[1],
            gradient: vec![2.0 * ka * r[0], 2.0 * kb * r[1]],
            curvature: Some(vec![2.0 * ka * ka, 0.0, 0.0, 2.0 * kb * kb]),
        })
    }

    /// Runs `iterations` iterations (or until no decrease) from `x0`; returns the last point
    /// and the iterations made.
    fn minimise(
        mut opt: Optimiser,
        f: fn(&[f64]) -> Result<Evaluation, Infallible>,
        x0: &[f64],
        iterations: usize,
        project: &dyn Fn(&mut [f64]),
    ) -> (Evaluation, usize) {
        let mut at = f(x0).unwrap();
        for k in 0..iterations {
            match opt.iterate(&at, &mut |x| f(x), project).unwrap() {
                Some(next) => at = next,
                None => return (at, k),
            }
        }
        (at, iterations)
    }

    fn free(_: &mut [f64]) {}

    /// On the bound `z₀ ≥ 2` of the quadratic (whose minimum, `z₀ = 1`, is beyond it) the
    /// gradient pushes against the bound and only the other variables count: a minimum there
    /// has no free gradient; away from the bound every component counts.
    #[test]
    fn the_free_gradient_leaves_out_variables_held_on_a_bound() {
        let bound = |z: &mut [f64]| z[0] = z[0].max(2.0);
        let on_bound = quadratic(&[2.0, -2.0, 0.5]).unwrap();
        assert_eq!(norm(&on_bound.gradient), 1.0);
        assert_eq!(free_gradient_norm(&on_bound, &bound), 0.0);
        let inside = quadratic(&[3.0, -1.0, 0.5]).unwrap();
        assert_eq!(free_gradient_norm(&inside, &bound), norm(&inside.gradient));
    }

    #[test]
    fn lbfgs_solves_a_quadratic_and_rosenbrock() {
        let (q, n) = minimise(
            Optimiser::Lbfgs(Lbfgs::new(5, 0.1)),
            quadratic,
            &[0.0; 3],
            50,
            &free,
        );
        // A quadratic in 3 variables: L-BFGS with exact curvature pairs reaches the minimum
        // to round-off in a few tens of iterations (a line search that only backtracks).
        assert!(
            (q.x[0] - 1.0).abs() < 1e-8
                && (q.x[1] + 2.0).abs() < 1e-8
                && (q.x[2] - 0.5).abs() < 1e-8,
            "{:?} after {n}",
            q.x
        );
        let (r, n) = minimise(
            Optimiser::Lbfgs(Lbfgs::new(8, 0.1)),
            rosenbrock,
            &[-1.2, 1.0],
            200,
            &free,
        );
        // From the classic start (−1.2, 1): to 1e-6 of (1, 1) (quasi-Newton converges
        // superlinearly near the minimum, so the remaining error is the stopping point's).
        assert!(
            (r.x[0] - 1.0).abs() < 1e-6 && (r.x[1] - 1.0).abs() < 1e-6,
            "{:?}, L = {:e} after {n}",
            r.x,
            r.loss
        );
        assert!(n < 200, "took {n} iterations");
    }

    #[test]
    fn levenberg_marquardt_solves_rosenbrock_and_an_uneven_quadratic() {
        let (r, n) = minimise(
            Optimiser::LevenbergMarquardt(LevenbergMarquardt::new(1e-3)),
            rosenbrock_residuals,
            &[-1.2, 1.0],
            100,
            &free,
        );
        // A zero-residual problem: the Gauss–Newton model is exact at (1, 1) and the steps
        // converge quadratically once the damping has fallen, to round-off of the loss.
        assert!(
            (r.x[0] - 1.0).abs() < 1e-10 && (r.x[1] - 1.0).abs() < 1e-10,
            "{:?}, L = {:e} after {n}",
            r.x,
            r.loss
        );
        assert!(n < 30, "took {n} iterations");
        let (q, n) = minimise(
            Optimiser::LevenbergMarquardt(LevenbergMarquardt::new(1e-3)),
            uneven,
            &[0.0, 0.0],
            100,
            &free,
        );
        // Linear residuals: each step removes all but λ/(1 + λ) of the error along each
        // variable, whatever its curvature (Marquardt's scaling), and λ falls by 3 per step,
        // so `b` (curvature 10⁻¹² of `a`'s) is found to 1e-9 within a handful of steps.
        assert!(
            (q.x[0] - 1.0).abs() < 1e-9 && (q.x[1] + 2.0).abs() < 1e-9,
            "{:?} after {n}",
            q.x
        );
        assert!(n <= 6, "took {n} iterations");
        let (b, _) = minimise(
            Optimiser::LevenbergMarquardt(LevenbergMarquardt::new(1e-3)),
            uneven,
            &[0.0, 0.0],
            100,
            &|x: &mut [f64]| x[1] = x[1].max(-1.0),
        );
        // `b` bounded below by −1: held on the bound, `a` still converges.
        assert!((b.x[0] - 1.0).abs() < 1e-9 && b.x[1] == -1.0, "{:?}", b.x);
    }

    #[test]
    fn adam_with_decay_solves_a_quadratic_and_approaches_rosenbrock() {
        let (q, _) = minimise(
            Optimiser::Adam(Adam::new(3, 0.1, 0.5, 200.0)),
            quadratic,
            &[0.0; 3],
            2000,
            &free,
        );
        // Adam's steps shrink with the decayed rate (0.1 · 0.5^10 ≈ 1e-4 at the end): the
        // error is a fraction of the last steps.
        for (x, c) in q.x.iter().zip([1.0, -2.0, 0.5]) {
            assert!((x - c).abs() < 1e-3, "{:?}", q.x);
        }
        let (r, _) = minimise(
            Optimiser::Adam(Adam::new(2, 0.05, 0.5, 1000.0)),
            rosenbrock,
            &[-1.2, 1.0],
            10000,
            &free,
        );
        // First-order steps along the curved valley: close to (1, 1), not to round-off.
        assert!(
            (r.x[0] - 1.0).abs() < 1e-2 && (r.x[1] - 1.0).abs() < 2e-2,
            "{:?}",
            r.x
        );
    }

    #[test]
    fn projection_keeps_the_bound_and_finds_the_constrained_minimum() {
        // min of the quadratic with z₀ ≤ 0.5: the constrained minimum is (0.5, −2, 0.5).
        let clamp = |x: &mut [f64]| x[0] = x[0].min(0.5);
        for opt in [
            Optimiser::Lbfgs(Lbfgs::new(5, 0.1)),
            Optimiser::Adam(Adam::new(3, 0.1, 0.5, 200.0)),
        ] {
            let (q, _) = minimise(opt, quadratic, &[0.0; 3], 2000, &clamp);
            assert!((q.x[0] - 0.5).abs() < 1e-12, "{:?}", q.x);
            assert!(
                (q.x[1] + 2.0).abs() < 1e-3 && (q.x[2] - 0.5).abs() < 1e-3,
                "{:?}",
                q.x
            );
        }
    }

    #[test]
    fn the_state_round_trips_through_json() {
        let mut opt = Optimiser::Lbfgs(Lbfgs::new(3, 0.1));
        let at = rosenbrock(&[-1.2, 1.0]).unwrap();
        let next = opt
            .iterate(&at, &mut |x| rosenbrock(x), &free)
            .unwrap()
            .unwrap();
        let text = serde_json::to_string(&opt).unwrap();
        let back: Optimiser = serde_json::from_str(&text).unwrap();
        assert_eq!(back, opt);
        // The restored optimiser continues exactly as the original.
        let (mut a, mut b) = (opt, back);
        let na = a.iterate(&next, &mut |x| rosenbrock(x), &free).unwrap();
        let nb = b.iterate(&next, &mut |x| rosenbrock(x), &free).unwrap();
        assert_eq!(na, nb);
    }
}
