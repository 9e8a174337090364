//! Observations of a run as objectives: tracked particle positions, Eulerian velocity
//! monitors and a deposit profile, their sum, and synthetic observations recorded from a
//! "truth" run.

use crate::adjoint_state::ParticleAdjoint;
use crate::deposit::DepositProfile;
use crate::error::AdjointError;
use crate::objective::{Objective, ScalarObjective, TrackedPositions};
use loam_core::tensor::Vector;
use loam_core::{Particles, Scalar};
use loam_explicit::{Config, Solver};
use std::collections::{BTreeMap, BTreeSet};

/// An axis-aligned box `[lo, hi)` of an Eulerian velocity monitor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MonitorBox<const D: usize> {
    /// Lower corner (inclusive).
    pub lo: Vector<f64, D>,
    /// Upper corner (exclusive).
    pub hi: Vector<f64, D>,
}

impl<const D: usize> MonitorBox<D> {
    /// Whether `x` lies in `[lo, hi)`.
    pub fn contains(&self, x: &Vector<f64, D>) -> bool {
        (0..D).all(|a| self.lo[a] <= x[a] && x[a] < self.hi[a])
    }

    /// The particles inside the box (by their primal positions) and the mass-weighted mean
    /// velocity of the material there, `v̄ = Σ_(p∈S) m_p v_p / Σ_(p∈S) m_p`; `v̄ = 0` when the
    /// box holds no particle.
    pub fn mean_velocity<T: Scalar>(
        &self,
        particles: &Particles<T, D>,
    ) -> (Vec<usize>, Vector<T, D>) {
        let inside: Vec<usize> = (0..particles.len())
            .filter(|&p| self.contains(&particles.x[p].map(|c| c.re())))
            .collect();
        let mut mass = T::zero();
        let mut momentum = Vector::<T, D>::zeros();
        for &p in &inside {
            mass += particles.mass[p];
            momentum += particles.v[p] * particles.mass[p];
        }
        let mean = if inside.is_empty() {
            momentum
        } else {
            momentum / mass
        };
        (inside, mean)
    }
}

/// Squared mismatch of the mean velocity in monitor boxes:
/// `ℓ_n = Σ_(b, v*) ∈ targets[n] w ‖v̄_b − v*‖²`, `v̄_b` the mass-weighted mean velocity of the
/// particles in box `b` ([`MonitorBox::mean_velocity`]).
///
/// Which particles are in a box is decided on the forward state and held fixed: the loss
/// is differentiated through the velocities and masses of those particles, not through the
/// particles entering or leaving the box (a jump, whose derivative is zero almost
/// everywhere). With `M = Σ m_p`, `∂ℓ/∂v_p = 2w (v̄ − v*) m_p / M` and
/// `∂ℓ/∂m_p = 2w (v̄ − v*)·(v_p − v̄) / M`.
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
        if let (Some(adj), Some(targets)) = (adjoint, self.targets.get(&step)) {
            for (b, target) in targets {
                let (inside, mean) = self.boxes[*b].mean_velocity(particles);
                let mass: f64 = inside.iter().map(|&p| particles.mass[p]).sum();
                let g = (mean - target) * (2.0 * self.weight);
                for &p in &inside {
                    adj.v[p] += g * (particles.mass[p] / mass);
                    adj.mass[p] += g.dot(&(particles.v[p] - mean)) / mass;
                }
            }
        }
        self.value(step, particles)
    }
}

impl<const D: usize> ScalarObjective<D> for VelocityMonitors<D> {
    fn value<T: Scalar>(&self, step: usize, particles: &Particles<T, D>) -> T {
        let Some(targets) = self.targets.get(&step) else {
            return T::zero();
        };
        let mut loss = T::zero();
        for (b, target) in targets {
            let (_, mean) = self.boxes[*b].mean_velocity(particles);
            loss += (mean - target.map(T::cst)).norm_squared() * T::cst(self.weight);
        }
        loss
    }

    /// `√w (v̄ − v*)`, component by component.
    fn residuals<T: Scalar>(&self, step: usize, particles: &Particles<T, D>, out: &mut Vec<T>) {
        let root = T::cst(self.weight.sqrt());
        for (b, target) in self.targets.get(&step).into_iter().flatten() {
            let (_, mean) = self.boxes[*b].mean_velocity(particles);
            let d = mean - target.map(T::cst);
            out.extend(d.iter().map(|&d| d * root));
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
                    .map(|(b, m)| (b, m.mean_velocity(p).1))
                    .collect();
                out.monitors.targets.insert(s, v);
            }
        };
        let mut p = initial.clone();
        let mut solver = Solver::new(config.clone(), &p)?;
        record(0, &p);
        for s in 1..=steps {
            solver.step(&mut p, f64::INFINITY)?;
            record(s, &p);
        }
        Ok(out)
    }
}

impl<const D: usize> Objective<D> for Observations<D> {
    fn term(
        &self,
        step: usize,
        particles: &Particles<f64, D>,
        mut adjoint: Option<&mut ParticleAdjoint<D>>,
    ) -> f64 {
        self.tracked.term(step, particles, adjoint.as_deref_mut())
            + self.monitors.term(step, particles, adjoint.as_deref_mut())
            + self.deposit.term(step, particles, adjoint)
    }
}

impl<const D: usize> ScalarObjective<D> for Observations<D> {
    fn value<T: Scalar>(&self, step: usize, particles: &Particles<T, D>) -> T {
        self.tracked.value(step, particles)
            + self.monitors.value(step, particles)
            + self.deposit.value(step, particles)
    }

    /// The tracked positions', the monitors' and the deposit's residuals, in that order.
    fn residuals<T: Scalar>(&self, step: usize, particles: &Particles<T, D>, out: &mut Vec<T>) {
        self.tracked.residuals(step, particles, out);
        self.monitors.residuals(step, particles, out);
        self.deposit.residuals(step, particles, out);
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
}
