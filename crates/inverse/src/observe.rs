//! Observations of a run as objectives: tracked particle positions, Eulerian velocity
//! monitors and a deposit profile, their sum, and synthetic observations recorded from a
//! "truth" run.

use crate::adjoint_state::ParticleAdjoint;
use crate::deposit::DepositProfile;
use crate::error::AdjointError;
use crate::objective::{
    Objective, ScalarObjective, TrackedPositions, axis, least_squares_term, vector_data,
};
use loam_core::tensor::Vector;
use loam_core::{Particles, Scalar};
use loam_explicit::{Config, Solver};
use std::collections::{BTreeMap, BTreeSet};

/// An axis-aligned box `[lo, hi]` of an Eulerian velocity monitor, with edges smoothed
/// over a width `ε`.
///
/// A particle at `x` counts with the weight `W(x) = Π_a s((x_a − lo_a)/ε + ½) ·
/// (1 − s((x_a − hi_a)/ε + ½))`, `s(t) = t³ (10 − 15t + 6t²)` on `[0, 1]` (0 below, 1 above):
/// 1 inside the box at least `ε/2` from its faces, 0 outside it at least `ε/2` from them,
/// ½ on a face, and twice continuously differentiable in `x`. So the mean velocity changes
/// smoothly as particles cross a face and the loss has no jumps. `ε = 0` is the sharp box
/// `[lo, hi)`: a particle counts or not, decided on the forward state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MonitorBox<const D: usize> {
    /// Lower corner.
    pub lo: Vector<f64, D>,
    /// Upper corner.
    pub hi: Vector<f64, D>,
    /// Width `ε ≥ 0` of the smoothed edges (m).
    pub edge: f64,
}

/// The quintic ramp `s(t) = t³ (10 − 15t + 6t²)`, clamped to 0 for `t ≤ 0` and 1 for
/// `t ≥ 1`, of `t` given by its value `t.re()`; `s'(t) = 30 t² (1 − t)²`.
fn ramp<T: Scalar>(t: T) -> T {
    if t.re() <= 0.0 {
        T::zero()
    } else if t.re() >= 1.0 {
        T::one()
    } else {
        t * t * t * (t * (t * T::cst(6.0) - T::cst(15.0)) + T::cst(10.0))
    }
}

/// The derivative of [`ramp`].
fn ramp_slope(t: f64) -> f64 {
    if t <= 0.0 || t >= 1.0 {
        0.0
    } else {
        30.0 * t * t * (1.0 - t) * (1.0 - t)
    }
}

impl<const D: usize> MonitorBox<D> {
    /// The weight `W(x)` of a particle at `x` (the type's doc), in any scalar type so that
    /// dual positions carry its derivative.
    pub fn weight<T: Scalar>(&self, x: &Vector<T, D>) -> T {
        let mut w = T::one();
        for a in 0..D {
            let f = if self.edge > 0.0 {
                let e = T::cst(self.edge);
                let half = T::cst(0.5);
                ramp((x[a] - T::cst(self.lo[a])) / e + half)
                    * (T::one() - ramp((x[a] - T::cst(self.hi[a])) / e + half))
            } else if self.lo[a] <= x[a].re() && x[a].re() < self.hi[a] {
                T::one()
            } else {
                T::zero()
            };
            if f.re() == 0.0 {
                return T::zero();
            }
            w *= f;
        }
        w
    }

    /// `W(x)` and its gradient `∇W(x)` (zero for the sharp box).
    pub fn weight_and_gradient(&self, x: &Vector<f64, D>) -> (f64, Vector<f64, D>) {
        let w = self.weight(x);
        let mut grad = Vector::<f64, D>::zeros();
        if w == 0.0 || self.edge == 0.0 {
            return (w, grad);
        }
        for a in 0..D {
            let (tl, th) = (
                (x[a] - self.lo[a]) / self.edge + 0.5,
                (x[a] - self.hi[a]) / self.edge + 0.5,
            );
            let f = ramp(tl) * (1.0 - ramp(th));
            let df = (ramp_slope(tl) * (1.0 - ramp(th)) - ramp(tl) * ramp_slope(th)) / self.edge;
            grad[a] = w / f * df;
        }
        (w, grad)
    }

    /// The mass- and weight-averaged velocity of the material in the box,
    /// `v̄ = Σ_p m_p W_p v_p / Σ_p m_p W_p`; `v̄ = 0` when no particle has weight.
    pub fn mean_velocity<T: Scalar>(&self, particles: &Particles<T, D>) -> Vector<T, D> {
        let mut mass = T::zero();
        let mut momentum = Vector::<T, D>::zeros();
        for p in 0..particles.len() {
            let w = self.weight(&particles.x[p]);
            if w.re() != 0.0 {
                mass += particles.mass[p] * w;
                momentum += particles.v[p] * (particles.mass[p] * w);
            }
        }
        if mass.re() == 0.0 {
            momentum
        } else {
            momentum / mass
        }
    }
}

/// Squared mismatch of the mean velocity in monitor boxes:
/// `ℓ_n = Σ_(b, v*) ∈ targets[n] w ‖v̄_b − v*‖²`, `v̄_b` the weighted mean velocity of the
/// material in box `b` ([`MonitorBox::mean_velocity`]).
///
/// With `M = Σ m_q W_q` and `g = 2w (v̄ − v*)`: `∂ℓ/∂v_p = g m_p W_p / M`,
/// `∂ℓ/∂m_p = g·(v_p − v̄) W_p / M` and `∂ℓ/∂x_p = g·(v_p − v̄) m_p ∇W_p / M`. With sharp
/// boxes (`ε = 0`) `∇W = 0`: the loss is differentiated through the velocities and masses
/// of the particles inside, not through particles entering or leaving (a jump, whose
/// derivative is zero almost everywhere).
#[derive(Clone, Debug, PartialEq)]
pub struct VelocityMonitors<const D: usize> {
    /// The boxes.
    pub boxes: Vec<MonitorBox<D>>,
    /// Per step, the observed boxes (indices into `boxes`) and their observed mean velocity.
    pub targets: BTreeMap<usize, Vec<(usize, Vector<f64, D>)>>,
    /// Weight `w` of every squared difference.
    pub weight: f64,
}

impl<const D: usize> Default for VelocityMonitors<D> {
    /// No boxes, no targets, weight 1.
    fn default() -> Self {
        Self {
            boxes: Vec::new(),
            targets: BTreeMap::new(),
            weight: 1.0,
        }
    }
}

impl<const D: usize> Objective<D> for VelocityMonitors<D> {
    fn term(
        &self,
        step: usize,
        particles: &Particles<f64, D>,
        adjoint: Option<&mut ParticleAdjoint<D>>,
    ) -> f64 {
        least_squares_term(self, step, particles, adjoint)
    }
}

impl<const D: usize> ScalarObjective<D> for VelocityMonitors<D> {
    /// The components of the mean velocity `v̄_b` in each observed box.
    fn observed<T: Scalar>(&self, step: usize, particles: &Particles<T, D>, out: &mut Vec<T>) {
        for (b, _) in self.targets.get(&step).into_iter().flatten() {
            out.extend(self.boxes[*b].mean_velocity(particles).iter().copied());
        }
    }

    fn data(&self, step: usize, out: &mut Vec<(f64, f64)>) {
        vector_data(&self.targets, step, self.weight, out);
    }

    fn labels(&self, step: usize, out: &mut Vec<String>) {
        for (b, _) in self.targets.get(&step).into_iter().flatten() {
            out.extend((0..D).map(|a| format!("v{} in monitor box {b}", axis(a))));
        }
    }

    /// With `M = Σ m_q W_q` and `g = ȳ_b`: `∂(g·v̄)/∂v_p = g m_p W_p / M`,
    /// `∂/∂m_p = g·(v_p − v̄) W_p / M`, `∂/∂x_p = g·(v_p − v̄) m_p ∇W_p / M`. With sharp
    /// boxes (`ε = 0`) `∇W = 0`: particles entering or leaving are a jump, whose derivative
    /// is zero almost everywhere.
    fn pull(
        &self,
        step: usize,
        particles: &Particles<f64, D>,
        cotangent: &[f64],
        adjoint: &mut ParticleAdjoint<D>,
    ) {
        let targets = self.targets.get(&step).into_iter().flatten();
        for ((b, _), bar) in targets.zip(cotangent.chunks(D)) {
            let monitor = &self.boxes[*b];
            let weights: Vec<(usize, f64, Vector<f64, D>)> = (0..particles.len())
                .filter_map(|p| {
                    let (w, dw) = monitor.weight_and_gradient(&particles.x[p]);
                    (w != 0.0).then_some((p, w, dw))
                })
                .collect();
            let mass: f64 = weights.iter().map(|&(p, w, _)| particles.mass[p] * w).sum();
            if mass == 0.0 {
                continue;
            }
            let mean = monitor.mean_velocity(particles);
            let g = Vector::<f64, D>::from_column_slice(bar);
            for &(p, w, dw) in &weights {
                let m = particles.mass[p];
                let along = g.dot(&(particles.v[p] - mean));
                adjoint.v[p] += g * (m * w / mass);
                adjoint.mass[p] += along * w / mass;
                adjoint.x[p] += dw * (along * m / mass);
            }
        }
    }
}

/// Every observation of an inversion: `L = L_tracked + L_monitors + L_deposit`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Observations<const D: usize> {
    /// Tracked particle positions.
    pub tracked: TrackedPositions<D>,
    /// Eulerian velocity monitors.
    pub monitors: VelocityMonitors<D>,
    /// Deposit depths at stations.
    pub deposit: DepositProfile<D>,
}

impl<const D: usize> Observations<D> {
    /// No targets yet: velocity monitors in `boxes`, every weight 1 (the sensors of
    /// [`Observations::record`] when nothing but particles and boxes is observed).
    pub fn with_monitors(boxes: Vec<MonitorBox<D>>) -> Self {
        Self {
            monitors: VelocityMonitors {
                boxes,
                ..Default::default()
            },
            ..Default::default()
        }
    }

    /// The steps at which something is observed, in order.
    pub fn steps(&self) -> BTreeSet<usize> {
        self.tracked
            .targets
            .keys()
            .chain(self.monitors.targets.keys())
            .chain(self.deposit.targets.keys())
            .copied()
            .collect()
    }

    /// Synthetic observations: runs `config` from `initial` for `steps` steps and records,
    /// at each of `observed` (steps, 0 the initial state), the positions of the particles
    /// `ids` and the mean velocity in every monitor box of `sensors`, and after the last
    /// step the depth at every deposit station of `sensors` (the final deposit). The boxes,
    /// stations and weights are those of `sensors`, whose targets are replaced.
    ///
    /// # Errors
    /// A run that is refused or stops.
    pub fn record(
        config: &Config<f64, D>,
        initial: &Particles<f64, D>,
        steps: usize,
        observed: &BTreeSet<usize>,
        ids: &[usize],
        sensors: Self,
    ) -> Result<Self, AdjointError> {
        let mut out = sensors;
        out.tracked.targets.clear();
        out.monitors.targets.clear();
        out.deposit.targets.clear();
        let mut record = |s: usize, p: &Particles<f64, D>| {
            if s == steps && !out.deposit.stations.is_empty() {
                let h = (out.deposit.stations.iter().enumerate())
                    .map(|(k, station)| (k, station.depth(p, out.deposit.up)))
                    .collect();
                out.deposit.targets.insert(s, h);
            }
            if !observed.contains(&s) {
                return;
            }
            if !ids.is_empty() {
                let x = ids.iter().map(|&i| (i, p.x[i])).collect();
                out.tracked.targets.insert(s, x);
            }
            if !out.monitors.boxes.is_empty() {
                let v = (out.monitors.boxes.iter().enumerate())
                    .map(|(b, m)| (b, m.mean_velocity(p)))
                    .collect();
                out.monitors.targets.insert(s, v);
            }
        };
        let mut p = initial.clone();
        let mut solver = Solver::new(config.clone(), &p)?;
        loam_explicit::pool::hold(|| {
            record(0, &p);
            for s in 1..=steps {
                solver.step(&mut p, f64::INFINITY)?;
                record(s, &p);
            }
            Ok::<_, AdjointError>(())
        })?;
        Ok(out)
    }
}

impl<const D: usize> Objective<D> for Observations<D> {
    fn term(
        &self,
        step: usize,
        particles: &Particles<f64, D>,
        adjoint: Option<&mut ParticleAdjoint<D>>,
    ) -> f64 {
        least_squares_term(self, step, particles, adjoint)
    }
}

impl<const D: usize> Observations<D> {
    /// The number of quantities the tracked positions and the monitors observe after
    /// `step` steps (the deposit's follow them).
    fn counts(&self, step: usize) -> (usize, usize) {
        let n = |t: Option<&Vec<_>>| t.map_or(0, |t| t.len() * D);
        (
            n(self.tracked.targets.get(&step)),
            n(self.monitors.targets.get(&step)),
        )
    }
}

impl<const D: usize> ScalarObjective<D> for Observations<D> {
    /// The tracked positions', the monitors' and the deposit's quantities, in that order.
    fn observed<T: Scalar>(&self, step: usize, particles: &Particles<T, D>, out: &mut Vec<T>) {
        self.tracked.observed(step, particles, out);
        self.monitors.observed(step, particles, out);
        self.deposit.observed(step, particles, out);
    }

    fn data(&self, step: usize, out: &mut Vec<(f64, f64)>) {
        self.tracked.data(step, out);
        self.monitors.data(step, out);
        self.deposit.data(step, out);
    }

    fn labels(&self, step: usize, out: &mut Vec<String>) {
        self.tracked.labels(step, out);
        self.monitors.labels(step, out);
        self.deposit.labels(step, out);
    }

    fn pull(
        &self,
        step: usize,
        particles: &Particles<f64, D>,
        cotangent: &[f64],
        adjoint: &mut ParticleAdjoint<D>,
    ) {
        let (a, b) = self.counts(step);
        let (tracked, rest) = cotangent.split_at(a.min(cotangent.len()));
        let (monitors, deposit) = rest.split_at(b.min(rest.len()));
        self.tracked.pull(step, particles, tracked, adjoint);
        self.monitors.pull(step, particles, monitors, adjoint);
        self.deposit.pull(step, particles, deposit, adjoint);
    }
}

/// `count` distinct particle ids out of `n`, pseudo-random from `seed` (splitmix64 driving
/// a partial Fisher–Yates shuffle), in increasing order: the same for the same arguments on
/// every machine.
pub fn choose(n: usize, count: usize, seed: u64) -> Vec<usize> {
    let mut rng = crate::SplitMix64::new(seed);
    let mut next = || rng.next_u64();
    let mut ids: Vec<usize> = (0..n).collect();
    for i in 0..count.min(n) {
        let j = i + (next() % (n - i) as u64) as usize;
        ids.swap(i, j);
    }
    ids.truncate(count.min(n));
    ids.sort_unstable();
    ids
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn choice_is_distinct_sorted_and_reproducible() {
        let a = choose(1000, 100, 7);
        assert_eq!(a, choose(1000, 100, 7));
        assert_ne!(a, choose(1000, 100, 8));
        assert!(a.windows(2).all(|w| w[0] < w[1]) && a.len() == 100 && a[99] < 1000);
        assert_eq!(choose(5, 9, 1), vec![0, 1, 2, 3, 4]);
    }

    fn unit_box(edge: f64) -> MonitorBox<2> {
        MonitorBox {
            lo: Vector::from([0.0, 0.0]),
            hi: Vector::from([1.0, 2.0]),
            edge,
        }
    }

    #[test]
    fn smoothed_box_weight_is_one_inside_half_on_a_face_and_zero_outside() {
        let b = unit_box(0.2);
        // s(½) = ½ exactly: a face is half in; the corner is half of half.
        assert_eq!(b.weight(&Vector::from([0.5, 1.0])), 1.0);
        assert_eq!(b.weight(&Vector::from([0.0, 1.0])), 0.5);
        assert_eq!(b.weight(&Vector::from([1.0, 2.0])), 0.25);
        assert_eq!(b.weight(&Vector::from([-0.1, 1.0])), 0.0);
        assert_eq!(b.weight(&Vector::from([0.5, 2.1])), 0.0);
        // The sharp box is `[lo, hi)`.
        let sharp = unit_box(0.0);
        assert_eq!(sharp.weight(&Vector::from([0.0, 1.0])), 1.0);
        assert_eq!(sharp.weight(&Vector::from([1.0, 1.0])), 0.0);
        assert_eq!(
            sharp.weight_and_gradient(&Vector::from([0.5, 0.5])).1,
            Vector::<f64, 2>::zeros()
        );
    }

    #[test]
    fn smoothed_box_gradient_matches_the_dual_derivative() {
        use num_dual::Dual64;
        let b = unit_box(0.2);
        // Points in one ramp, in two ramps (a corner) and in the flat part.
        for x in [[0.03, 1.0], [0.95, 1.93], [-0.05, 0.07], [0.5, 1.0]] {
            let (w, grad) = b.weight_and_gradient(&Vector::from(x));
            for a in 0..2 {
                let xd = Vector::<Dual64, 2>::from_fn(|k, _| {
                    let d = Dual64::from(x[k]);
                    if k == a { d.derivative() } else { d }
                });
                let wd = b.weight(&xd);
                assert_eq!(wd.re, w);
                // The same polynomial evaluated two ways: equal to round-off.
                assert!(
                    (wd.eps - grad[a]).abs() <= 1e-12,
                    "{x:?} axis {a}: {} vs {}",
                    wd.eps,
                    grad[a]
                );
            }
        }
    }
}
