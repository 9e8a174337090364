//! How well observations identify parameters: the Gauss–Newton matrix of the scaled
//! residuals.
//!
//! With residuals `r_k = (m_k − d_k)/σ_k` and the parameters scaled by their values,
//! `θ_j = θ*_j (1 + ζ_j)`, the Jacobian is `J_kj = θ*_j (dm_k/dθ_j) / σ_k` and the
//! Gauss–Newton matrix `H = JᵀJ` is the loss's Hessian at a noise-free minimum. Its
//! eigenvalues say how sharply the loss rises along each combination of relative changes;
//! `H⁻¹` is the covariance of the relative errors `ζ` under unit noise on every residual
//! (`σ_k` the noise's standard deviation), so `√(H⁻¹)_jj` is the relative standard
//! deviation of parameter `j` and `(H⁻¹)_ij / √((H⁻¹)_ii (H⁻¹)_jj)` the correlation of two
//! estimates.

use nalgebra::DMatrix;

/// The Gauss–Newton analysis of one set of observations.
#[derive(Clone, Debug, PartialEq)]
pub struct Identifiability {
    /// `H = JᵀJ` in relative parameter changes.
    pub matrix: DMatrix<f64>,
    /// Its eigenvalues, ascending.
    pub eigenvalues: Vec<f64>,
    /// `λ_max / λ_min` (infinite when `H` is singular).
    pub condition: f64,
    /// `√(H⁻¹)_jj`: the relative standard deviation of each parameter under unit noise
    /// (`None` when `H` is singular).
    pub relative_std: Option<Vec<f64>>,
    /// The correlations of the estimates, `(H⁻¹)_ij / √((H⁻¹)_ii (H⁻¹)_jj)`.
    pub correlation: Option<DMatrix<f64>>,
}

impl Identifiability {
    /// The analysis from `sensitivities[j][k] = dm_k/dθ_j`, the values `theta` and each
    /// observation's `sigma`.
    pub fn new(sensitivities: &[Vec<f64>], theta: &[f64], sigma: &[f64]) -> Self {
        let n = theta.len();
        let scaled = |j: usize, k: usize| theta[j] * sensitivities[j][k] / sigma[k];
        let matrix = DMatrix::from_fn(n, n, |i, j| {
            (0..sigma.len())
                .map(|k| scaled(i, k) * scaled(j, k))
                .sum::<f64>()
        });
        let mut eigenvalues: Vec<f64> = matrix
            .clone()
            .symmetric_eigen()
            .eigenvalues
            .iter()
            .copied()
            .collect();
        eigenvalues.sort_by(f64::total_cmp);
        let (lo, hi) = (eigenvalues[0], eigenvalues[n - 1]);
        let condition = if lo > 0.0 { hi / lo } else { f64::INFINITY };
        let covariance = (lo > 0.0).then(|| matrix.clone().try_inverse()).flatten();
        let relative_std =
            (covariance.as_ref()).map(|c| (0..n).map(|j| c[(j, j)].sqrt()).collect::<Vec<f64>>());
        let correlation = covariance
            .map(|c| DMatrix::from_fn(n, n, |i, j| c[(i, j)] / (c[(i, i)] * c[(j, j)]).sqrt()));
        Self {
            matrix,
            eigenvalues,
            condition,
            relative_std,
            correlation,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two parameters seen only through their product `m_k = a_k θ₀ θ₁` cannot be told
    /// apart: `H` is singular (one eigenvalue zero to round-off). Seen through `θ₀ + θ₁`
    /// and `θ₀ − θ₁` at `θ = (1, 1)`, `H = 2 I`: condition 1, no correlation, σ_rel = 1/√2.
    #[test]
    fn gauss_newton_matrix_of_known_jacobians() {
        let theta = [2.0, 3.0];
        let a = [1.0, -0.5, 2.0];
        // dm_k/dθ₀ = a_k θ₁, dm_k/dθ₁ = a_k θ₀: scaled columns θ₀θ₁ a_k are equal.
        let s = vec![
            a.map(|a| a * theta[1]).to_vec(),
            a.map(|a| a * theta[0]).to_vec(),
        ];
        let g = Identifiability::new(&s, &theta, &[1.0; 3]);
        assert!(g.eigenvalues[0].abs() < 1e-12 * g.eigenvalues[1]);
        assert!(g.condition > 1e12);
        let s = vec![vec![1.0, 1.0], vec![1.0, -1.0]];
        let g = Identifiability::new(&s, &[1.0, 1.0], &[1.0, 1.0]);
        assert_eq!(g.eigenvalues, vec![2.0, 2.0]);
        assert_eq!(g.condition, 1.0);
        let c = g.correlation.expect("regular");
        assert_eq!(c[(0, 1)], 0.0);
        let std = g.relative_std.expect("regular");
        assert!((std[0] - 0.5f64.sqrt()).abs() < 1e-15);
    }
}
