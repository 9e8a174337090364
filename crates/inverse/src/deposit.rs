//! A deposit profile: the depth of the material at stations along the floor, as a smooth
//! function of the particle state.

use crate::adjoint_state::ParticleAdjoint;
use crate::objective::{Objective, ScalarObjective, least_squares_term};
use loam_core::tensor::{self, Vector};
use loam_core::{Particles, Scalar};
use std::collections::BTreeMap;

/// A station of a deposit profile: where on the floor the depth is measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Station<const D: usize> {
    /// The station's position; its component along the vertical axis is not used.
    pub at: Vector<f64, D>,
    /// The width `b` of the smoothing kernel (m): the depth is an average over about
    /// `±1.5 b` around the station on every horizontal axis.
    pub width: f64,
}

/// The quadratic B-spline `N(ξ)` (support `|ξ| < 3/2`, `∫N = 1`) and its derivative.
fn bspline(xi: f64) -> (f64, f64) {
    let a = xi.abs();
    if a < 0.5 {
        (0.75 - xi * xi, -2.0 * xi)
    } else if a < 1.5 {
        (0.5 * (1.5 - a).powi(2), -(1.5 - a) * xi.signum())
    } else {
        (0.0, 0.0)
    }
}

impl<const D: usize> Station<D> {
    /// The kernel `K_b(x − s) = Π_(a ≠ up) N((x_a − s_a)/b) / b` at `x` and its gradient in
    /// `x` (zero along `up`).
    fn kernel(&self, x: &Vector<f64, D>, up: usize) -> (f64, Vector<f64, D>) {
        let mut value = 1.0;
        let mut parts = [(1.0, 0.0); D];
        for a in (0..D).filter(|&a| a != up) {
            let (n, dn) = bspline((x[a] - self.at[a]) / self.width);
            parts[a] = (n / self.width, dn / (self.width * self.width));
            value *= parts[a].0;
        }
        let mut grad = Vector::zeros();
        for a in (0..D).filter(|&a| a != up) {
            grad[a] = (0..D)
                .filter(|&b| b != up && b != a)
                .fold(parts[a].1, |g, b| g * parts[b].0);
        }
        (value, grad)
    }

    /// The depth of the material at the station,
    /// `h = Σ_p J_p V⁰_p K_b(x_p − s)`, `J_p = det F_p`: the volume of material per unit
    /// floor area (per unit width in 2D) under the kernel, which for a deposit of
    /// slowly varying thickness is its free-surface height above the floor.
    pub fn depth<T: Scalar>(&self, particles: &Particles<T, D>, up: usize) -> T {
        let mut h = T::zero();
        for p in 0..particles.len() {
            let x = particles.x[p].map(|c| c.re());
            if self.kernel(&x, up).0 == 0.0 {
                continue;
            }
            let mut k = T::one();
            for a in (0..D).filter(|&a| a != up) {
                let xi = (particles.x[p][a] - T::cst(self.at[a])) / T::cst(self.width);
                k *= bspline_generic(xi) / T::cst(self.width);
            }
            h += tensor::det(&particles.f[p]) * particles.volume0[p] * k;
        }
        h
    }
}

/// [`bspline`]'s value in any scalar type (the branch chosen on the real part).
fn bspline_generic<T: Scalar>(xi: T) -> T {
    let a = xi.re().abs();
    if a < 0.5 {
        T::cst(0.75) - xi * xi
    } else if a < 1.5 {
        let r = T::cst(1.5) - xi.abs();
        r * r * T::cst(0.5)
    } else {
        T::zero()
    }
}

/// Squared mismatch of the deposit depth at stations:
/// `ℓ_n = Σ_(s, h*) ∈ targets[n] w (h_s − h*)²`, `h_s` the depth at station `s`
/// ([`Station::depth`]).
///
/// With `r_s = 2w (h_s − h*)` and `K_p = K_b(x_p − s)`:
/// `∂ℓ/∂x_p = r_s J_p V⁰_p ∇K_p`, `∂ℓ/∂F_p = r_s V⁰_p K_p J_p F_p⁻ᵀ`,
/// `∂ℓ/∂V⁰_p = r_s J_p K_p`. The kernel is a C¹ quadratic B-spline, so the loss is
/// continuously differentiable in the particle positions: a particle entering a station's
/// support changes the depth smoothly (unlike a box count or a highest particle).
#[derive(Clone, Debug, PartialEq)]
pub struct DepositProfile<const D: usize> {
    /// The stations.
    pub stations: Vec<Station<D>>,
    /// The vertical axis (the one along gravity), not smoothed over.
    pub up: usize,
    /// Per step, the observed stations (indices into `stations`) and their observed depth.
    pub targets: BTreeMap<usize, Vec<(usize, f64)>>,
    /// Weight `w` of every squared difference.
    pub weight: f64,
}

impl<const D: usize> Default for DepositProfile<D> {
    /// No stations, the last axis vertical, weight 1.
    fn default() -> Self {
        Self {
            stations: Vec::new(),
            up: D - 1,
            targets: BTreeMap::new(),
            weight: 1.0,
        }
    }
}

impl<const D: usize> Objective<D> for DepositProfile<D> {
    fn term(
        &self,
        step: usize,
        particles: &Particles<f64, D>,
        adjoint: Option<&mut ParticleAdjoint<D>>,
    ) -> f64 {
        least_squares_term(self, step, particles, adjoint)
    }
}

impl<const D: usize> ScalarObjective<D> for DepositProfile<D> {
    /// The depth `h_s` at each observed station.
    fn observed<T: Scalar>(&self, step: usize, particles: &Particles<T, D>, out: &mut Vec<T>) {
        for &(s, _) in self.targets.get(&step).into_iter().flatten() {
            out.push(self.stations[s].depth(particles, self.up));
        }
    }

    fn data(&self, step: usize, out: &mut Vec<(f64, f64)>) {
        for &(_, target) in self.targets.get(&step).into_iter().flatten() {
            out.push((target, self.weight));
        }
    }

    fn labels(&self, step: usize, out: &mut Vec<String>) {
        for &(s, _) in self.targets.get(&step).into_iter().flatten() {
            out.push(format!("depth at deposit station {s}"));
        }
    }

    /// With `r = ȳ_s` and `K_p = K_b(x_p − s)`: `∂(r h_s)/∂x_p = r J_p V⁰_p ∇K_p`,
    /// `∂/∂F_p = r V⁰_p K_p J_p F_p⁻ᵀ`, `∂/∂V⁰_p = r J_p K_p`.
    fn pull(
        &self,
        step: usize,
        particles: &Particles<f64, D>,
        cotangent: &[f64],
        adjoint: &mut ParticleAdjoint<D>,
    ) {
        let targets = self.targets.get(&step).into_iter().flatten();
        for (&(s, _), &r) in targets.zip(cotangent) {
            let station = &self.stations[s];
            for p in 0..particles.len() {
                let (k, grad) = station.kernel(&particles.x[p], self.up);
                // Outside the support the kernel and its gradient vanish together.
                if k == 0.0 {
                    continue;
                }
                let f = particles.f[p];
                let j = tensor::det(&f);
                let v0 = particles.volume0[p];
                adjoint.x[p] += grad * (r * j * v0);
                if let Some(inv) = tensor::inverse(&f) {
                    adjoint.f[p] += inv.transpose() * (r * v0 * k * j);
                }
                adjoint.volume0[p] += r * j * k;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use loam_core::tensor::Tensor;

    /// A layer of particles of depth `h` at rest, `n` per unit length, on a floor y = 0.
    fn layer(h: f64, spacing: f64) -> Particles<f64, 2> {
        let mut p = Particles::default();
        let (nx, ny) = ((2.0 / spacing) as usize, (h / spacing).round() as usize);
        for i in 0..nx {
            for j in 0..ny {
                let x = Vector::from([(i as f64 + 0.5) * spacing, (j as f64 + 0.5) * spacing]);
                p.x.push(x);
                p.v.push(Vector::zeros());
                p.a.push(Vector::zeros());
                p.f.push(Tensor::identity());
                p.c.push(Tensor::zeros());
                p.stress.push(nalgebra::Matrix3::zeros());
                p.mass.push(1.0);
                p.volume0.push(spacing * spacing);
                p.half_width0.push(Vector::repeat(spacing / 2.0));
                p.material.push(0);
                p.state.push(Default::default());
                p.pore_pressure.push(0.0);
            }
        }
        p
    }

    #[test]
    fn depth_of_a_uniform_layer_is_its_thickness() {
        // Away from the layer's ends, Σ_p V_p K(x_p − s) is a midpoint sum of ∫K = 1 times
        // the thickness; the quadratic B-spline sampled at spacing ≤ b/2 reproduces the
        // integral of a constant exactly (partition of unity), so the depth is exact to
        // round-off.
        let p = layer(0.3, 0.01);
        let s = Station {
            at: Vector::from([1.0, 0.0]),
            width: 0.02,
        };
        let h = s.depth(&p, 1);
        assert!((h - 0.3).abs() < 1e-12, "h = {h}");
        // Compressing the layer to 90 % of its volume (J = 0.9) scales the depth.
        let mut q = p.clone();
        for f in &mut q.f {
            *f = Tensor::from_diagonal(&Vector::from([1.0, 0.9]));
        }
        assert!((s.depth(&q, 1) - 0.27).abs() < 1e-12);
    }

    #[test]
    fn adjoint_matches_central_differences() {
        // A ragged layer so that every particle's kernel slope differs; central differences
        // of a C¹ piecewise-quadratic in x with step 1e-7 are exact to about 1e-8 relative.
        let mut p = layer(0.1, 0.02);
        for (i, x) in p.x.iter_mut().enumerate() {
            x[0] += 0.003 * ((i * 7 % 11) as f64 / 11.0);
        }
        p.f[3] = Tensor::from([[1.05, 0.02], [-0.01, 0.97]]);
        let profile = DepositProfile {
            stations: vec![
                Station {
                    at: Vector::from([0.5, 0.0]),
                    width: 0.03,
                },
                Station {
                    at: Vector::from([0.05, 0.0]),
                    width: 0.03,
                },
            ],
            up: 1,
            targets: BTreeMap::from([(0, vec![(0, 0.12), (1, 0.05)])]),
            weight: 3.0,
        };
        let mut adj = ParticleAdjoint::zeros(p.len());
        profile.term(0, &p, Some(&mut adj));
        let eps = 1e-7;
        for i in [0, 3, 10, 27] {
            let fd = |set: &dyn Fn(&mut Particles<f64, 2>, f64)| {
                let (mut a, mut b) = (p.clone(), p.clone());
                set(&mut a, eps);
                set(&mut b, -eps);
                (profile.term(0, &a, None) - profile.term(0, &b, None)) / (2.0 * eps)
            };
            let dx = fd(&|q, e| q.x[i][0] += e);
            let df = fd(&|q, e| q.f[i][(1, 1)] += e);
            let dv = fd(&|q, e| q.volume0[i] += e);
            for (ad, fd) in [
                (adj.x[i][0], dx),
                (adj.f[i][(1, 1)], df),
                (adj.volume0[i], dv),
            ] {
                assert!(
                    (ad - fd).abs() <= 1e-6 * fd.abs().max(1e-3),
                    "particle {i}: adjoint {ad} vs finite differences {fd}"
                );
            }
        }
    }
}
