//! An initial velocity field given by a small multilayer perceptron (MLP) of the particle's
//! initial position: the unknowns are the network's weights and biases.
//!
//! The network is written out here with its backpropagation rather than taken from a crate:
//! it is a few dense layers evaluated once per run (not per step), its parameters must be a
//! flat `Vec<f64>` for the optimisers and the checkpoint, its forward pass must be generic
//! over [`Scalar`] so that a `Dual64` run can seed one weight (the oracle of the adjoint), and
//! the crates that offer all this bring a tensor stack far heavier than the forty lines below.

use crate::adjoint_state::ParticleAdjoint;
use loam_core::{Particles, Scalar};

/// SplitMix64 (Steele, Lea & Flood 2014): a 64-bit generator whose stream is fixed by its
/// seed, for reproducible initialisations and choices. `sₖ₊₁ = sₖ + 0x9E3779B97F4A7C15`,
/// output a bijective mix of `sₖ₊₁`.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// The generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A uniform number in `[0, 1)`: the top 53 bits over `2⁵³`.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A fully connected network `ℝⁿ⁰ → ℝⁿᴸ` with layer widths `n₀, n₁, …, n_L`: hidden layers
/// `a_l = tanh(W_l a_(l−1) + b_l)` (`l < L`), a linear output `y = W_L a_(L−1) + b_L`,
/// `a₀ = x`. Its parameters are one flat slice, layer by layer, each `W_l` (`n_l × n_(l−1)`,
/// row-major) followed by `b_l`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mlp {
    /// The widths `n₀, …, n_L` (input, hidden layers, output).
    pub widths: Vec<usize>,
}

impl Mlp {
    /// The network with `inputs` inputs, the given hidden widths and `outputs` outputs.
    pub fn new(inputs: usize, hidden: &[usize], outputs: usize) -> Self {
        let mut widths = vec![inputs];
        widths.extend_from_slice(hidden);
        widths.push(outputs);
        Self { widths }
    }

    /// The number of parameters, `Σ_l n_l (n_(l−1) + 1)`.
    pub fn len(&self) -> usize {
        self.widths.windows(2).map(|w| w[1] * (w[0] + 1)).sum()
    }

    /// Whether it has no parameter (no layer).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Glorot (Xavier) uniform initialisation: `W_l` entries uniform in `[−a_l, a_l]`,
    /// `a_l = √(6 / (n_(l−1) + n_l))`, so that activations and gradients keep their variance
    /// through the layers; biases zero. The same `seed` gives the same parameters.
    pub fn glorot(&self, seed: u64) -> Vec<f64> {
        let mut rng = SplitMix64::new(seed);
        let mut out = Vec::with_capacity(self.len());
        for w in self.widths.windows(2) {
            let a = (6.0 / (w[0] + w[1]) as f64).sqrt();
            out.extend((0..w[0] * w[1]).map(|_| a * (2.0 * rng.next_f64() - 1.0)));
            out.extend(std::iter::repeat_n(0.0, w[1]));
        }
        out
    }

    /// The activations `a₀ = x, a₁, …, a_L = y` of every layer at `x` with parameters `w`.
    fn activations<T: Scalar>(&self, w: &[T], x: &[T]) -> Vec<Vec<T>> {
        let last = self.widths.len() - 2;
        let mut layers = vec![x.to_vec()];
        let mut at = 0;
        for (l, n) in self.widths.windows(2).enumerate() {
            let (weights, biases) = w[at..at + n[1] * (n[0] + 1)].split_at(n[1] * n[0]);
            at += n[1] * (n[0] + 1);
            let input = &layers[l];
            let z = (0..n[1]).map(|i| {
                let row = &weights[i * n[0]..(i + 1) * n[0]];
                row.iter()
                    .zip(input)
                    .fold(biases[i], |s, (&a, &b)| s + a * b)
            });
            let a = if l < last {
                z.map(|z| z.tanh()).collect()
            } else {
                z.collect()
            };
            layers.push(a);
        }
        layers
    }

    /// `y(x; w)`.
    pub fn forward<T: Scalar>(&self, w: &[T], x: &[T]) -> Vec<T> {
        self.activations(w, x).pop().unwrap_or_default()
    }

    /// Adds `ȳ · ∂y/∂w` to `grad` (backpropagation): with `δ_L = ȳ`,
    /// `∂W_l += δ_l a_(l−1)ᵀ`, `∂b_l += δ_l`, `δ_(l−1) = (W_lᵀ δ_l) ⊙ (1 − a_(l−1)²)`.
    pub fn backward(&self, w: &[f64], x: &[f64], ybar: &[f64], grad: &mut [f64]) {
        let a = self.activations(w, x);
        let mut delta = ybar.to_vec();
        let mut end = self.len();
        for l in (1..self.widths.len()).rev() {
            let (n_in, n_out) = (self.widths[l - 1], self.widths[l]);
            let start = end - n_out * (n_in + 1);
            let weights = &w[start..start + n_out * n_in];
            let (gw, gb) = grad[start..end].split_at_mut(n_out * n_in);
            for i in 0..n_out {
                gb[i] += delta[i];
                for j in 0..n_in {
                    gw[i * n_in + j] += delta[i] * a[l - 1][j];
                }
            }
            if l > 1 {
                delta = (0..n_in)
                    .map(|j| {
                        let back: f64 = (0..n_out).map(|i| weights[i * n_in + j] * delta[i]).sum();
                        back * (1.0 - a[l - 1][j] * a[l - 1][j])
                    })
                    .collect();
            }
            end = start;
        }
    }
}

/// The component along the unit vector `d` of the initial velocity of the particles of one
/// material (all when `None`), given by an MLP `f: ℝᴰ → ℝ` of the normalised initial position
/// `x̂ = 2 (x − lo) / (hi − lo) − 1` (`[lo, hi]` the bounding box of those particles, so
/// `x̂ ∈ [−1, 1]ᴰ`): `v_p ← v_p + (f(x̂_p; w) − v_p·d) d`, the other components kept. Its
/// gradient is `dL/dw = Σ_p (∂L/∂v_p⁰ · d) ∂f(x̂_p)/∂w`.
#[derive(Clone, Debug, PartialEq)]
pub struct VelocityField {
    /// The material whose particles it sets, or all particles.
    pub material: Option<u32>,
    /// The unit vector `d` (`D` components).
    pub direction: Vec<f64>,
    /// The network (`D` inputs, one output).
    pub mlp: Mlp,
    /// The seed of its Glorot initialisation ([`Mlp::glorot`]).
    pub seed: u64,
    /// `lo` of the normalisation.
    pub lo: Vec<f64>,
    /// `hi` of the normalisation.
    pub hi: Vec<f64>,
}

impl VelocityField {
    /// The field over the particles of `material` (all when `None`) of `particles`, with the
    /// given hidden widths; `None` when no particle has that material.
    pub fn new<const D: usize>(
        particles: &Particles<f64, D>,
        material: Option<u32>,
        direction: Vec<f64>,
        hidden: &[usize],
        seed: u64,
    ) -> Option<Self> {
        let mut field = Self {
            material,
            direction,
            mlp: Mlp::new(D, hidden, 1),
            seed,
            lo: vec![f64::INFINITY; D],
            hi: vec![f64::NEG_INFINITY; D],
        };
        let selected = field.particles(particles);
        for &p in &selected {
            for a in 0..D {
                field.lo[a] = field.lo[a].min(particles.x[p][a]);
                field.hi[a] = field.hi[a].max(particles.x[p][a]);
            }
        }
        // A flat extent (one row of particles) maps to x̂ = 0 rather than dividing by zero.
        for a in 0..D {
            if field.hi[a] <= field.lo[a] {
                field.hi[a] = field.lo[a] + 1.0;
                field.lo[a] -= 1.0;
            }
        }
        (!selected.is_empty()).then_some(field)
    }

    /// Whether it sets the velocity of a particle of `material`.
    pub fn selects(&self, material: u32) -> bool {
        self.material.is_none_or(|m| m == material)
    }

    /// The indices of the particles it sets.
    pub fn particles<T: Scalar, const D: usize>(&self, particles: &Particles<T, D>) -> Vec<usize> {
        (0..particles.len())
            .filter(|&p| self.selects(particles.material[p]))
            .collect()
    }

    /// `x̂` of the initial position `x`.
    fn input(&self, x: &[f64]) -> Vec<f64> {
        (0..x.len())
            .map(|a| 2.0 * (x[a] - self.lo[a]) / (self.hi[a] - self.lo[a]) - 1.0)
            .collect()
    }

    /// `f(x̂_p; w)` of particle `p`.
    pub fn value<T: Scalar, const D: usize>(
        &self,
        w: &[T],
        particles: &Particles<f64, D>,
        p: usize,
    ) -> T {
        let x: Vec<T> = self
            .input(particles.x[p].as_slice())
            .into_iter()
            .map(T::cst)
            .collect();
        self.mlp.forward(w, &x)[0]
    }

    /// Sets the velocities of its particles from `w`: `v_p ← v_p + (f(x̂_p; w) − v_p·d) d`.
    pub fn apply<const D: usize>(&self, w: &[f64], particles: &mut Particles<f64, D>) {
        for p in self.particles(particles) {
            let f = self.value(w, particles, p);
            let v = &mut particles.v[p];
            let along: f64 = (0..D).map(|a| v[a] * self.direction[a]).sum();
            for a in 0..D {
                v[a] += (f - along) * self.direction[a];
            }
        }
    }

    /// `dL/dw = Σ_p (v̄_p · d) ∂f(x̂_p)/∂w` from the adjoint `v̄_p = ∂L/∂v_p⁰` of the initial
    /// velocities.
    pub fn gradient<const D: usize>(
        &self,
        w: &[f64],
        particles: &Particles<f64, D>,
        adjoint: &ParticleAdjoint<D>,
    ) -> Vec<f64> {
        let mut grad = vec![0.0; w.len()];
        for p in self.particles(particles) {
            let ybar: f64 = (0..D).map(|a| adjoint.v[p][a] * self.direction[a]).sum();
            let x = self.input(particles.x[p].as_slice());
            self.mlp.backward(w, &x, &[ybar], &mut grad);
        }
        grad
    }

    /// The relative L2 error of the field set by `w` against the velocities of `truth`
    /// (particles in the same order), over its particles:
    /// `‖v(w) − v*‖ / ‖v*‖ = √(Σ_p |v_p(w) − v*_p|² / Σ_p |v*_p|²)`, with `v_p(w)` the
    /// velocity [`VelocityField::apply`] gives `truth`'s particles.
    pub fn relative_error<const D: usize>(&self, w: &[f64], truth: &Particles<f64, D>) -> f64 {
        let mut set = truth.clone();
        self.apply(w, &mut set);
        let (mut diff, mut norm) = (0.0, 0.0);
        for p in self.particles(truth) {
            diff += (set.v[p] - truth.v[p]).norm_squared();
            norm += truth.v[p].norm_squared();
        }
        (diff / norm).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::Dual64;

    /// A small network with weights away from the Glorot start (biases non-zero).
    fn net() -> (Mlp, Vec<f64>) {
        let mlp = Mlp::new(2, &[5, 4, 3], 2);
        let mut rng = SplitMix64::new(7);
        let w = (0..mlp.len()).map(|_| 2.0 * rng.next_f64() - 1.0).collect();
        (mlp, w)
    }

    #[test]
    fn backprop_equals_dual_derivatives_and_central_differences() {
        let (mlp, w) = net();
        assert_eq!(mlp.len(), 5 * 3 + 4 * 6 + 3 * 5 + 2 * 4);
        let x = [0.3, -0.7];
        let ybar = [0.8, -1.3];
        let mut grad = vec![0.0; w.len()];
        mlp.backward(&w, &x, &ybar, &mut grad);
        let xd = x.map(Dual64::from_re);
        for k in 0..w.len() {
            // Forward mode with weight k seeded: dy/dw_k exactly (round-off only).
            let wd: Vec<Dual64> = (0..w.len())
                .map(|i| Dual64::new(w[i], if i == k { 1.0 } else { 0.0 }))
                .collect();
            let y = mlp.forward(&wd, &xd);
            let dual = ybar[0] * y[0].eps + ybar[1] * y[1].eps;
            assert!(
                (grad[k] - dual).abs() <= 1e-13 * (1.0 + dual.abs()),
                "w[{k}]: {} vs {dual}",
                grad[k]
            );
            // Central difference, h = 1e-5: truncation O(h²) ≈ 1e-10 for derivatives of
            // order one, round-off ≈ 1e-16 / h ≈ 1e-11.
            let h = 1e-5;
            let at = |d: f64| {
                let mut v = w.clone();
                v[k] += d;
                let y = mlp.forward(&v, &x);
                ybar[0] * y[0] + ybar[1] * y[1]
            };
            let fd = (at(h) - at(-h)) / (2.0 * h);
            assert!((grad[k] - fd).abs() <= 1e-8, "w[{k}]: {} vs {fd}", grad[k]);
        }
    }

    #[test]
    fn glorot_is_reproducible_bounded_and_of_the_right_variance() {
        let mlp = Mlp::new(2, &[30, 30, 30], 1);
        assert_eq!(mlp.len(), 90 + 930 + 930 + 31);
        let w = mlp.glorot(3);
        assert_eq!(w, mlp.glorot(3));
        assert_ne!(w, mlp.glorot(4));
        // The second layer (30 × 30 weights, then 30 zero biases): |w| ≤ a = √(6/60), and the
        // variance of a uniform on [−a, a] is a²/3 = 1/30; 900 samples estimate it to about
        // √(2·0.8/900) ≈ 4 % (the uniform's kurtosis 1.8), so 15 % is a wide margin.
        let (weights, biases) = w[90..1020].split_at(900);
        let a = (6.0f64 / 60.0).sqrt();
        assert!(weights.iter().all(|v| v.abs() <= a));
        assert!(biases.iter().all(|&b| b == 0.0));
        let var = weights.iter().map(|v| v * v).sum::<f64>() / 900.0;
        assert!((var * 30.0 - 1.0).abs() < 0.15, "variance {var}");
    }

    #[test]
    fn splitmix_is_uniform_in_the_unit_interval() {
        let mut rng = SplitMix64::new(0);
        let n = 100_000;
        let xs: Vec<f64> = (0..n).map(|_| rng.next_f64()).collect();
        assert!(xs.iter().all(|x| (0.0..1.0).contains(x)));
        // Mean 1/2 with standard error √(1/12/n) ≈ 9e-4: 5e-3 is over five of them.
        let mean = xs.iter().sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 5e-3, "{mean}");
    }
}
