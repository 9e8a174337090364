//! The adjoint of the particle state.

use loam_core::constitutive::MaterialState;
use loam_core::tensor::{Tensor, Vector};
use nalgebra::Matrix3;

/// The adjoint `∂L/∂(state)` of every field of the particle state that a step reads, by
/// particle id: what the reverse pass carries backwards from one step to the one before.
///
/// Position, velocity, affine matrix, `F`, stress and history are the state at one time; mass
/// and reference volume are constants of the run, so their adjoints sum the contributions of
/// every step (and of the objective).
#[derive(Clone, Debug, PartialEq)]
pub struct ParticleAdjoint<const D: usize> {
    /// `x̄_p`.
    pub x: Vec<Vector<f64, D>>,
    /// `v̄_p`.
    pub v: Vec<Vector<f64, D>>,
    /// `C̄_p`.
    pub c: Vec<Tensor<f64, D>>,
    /// `F̄_p`.
    pub f: Vec<Tensor<f64, D>>,
    /// `σ̄_p` (3×3).
    pub stress: Vec<Matrix3<f64>>,
    /// Adjoint of the history ([`MaterialState`], component by component).
    pub history: Vec<MaterialState<f64>>,
    /// `m̄_p`, summed over the run.
    pub mass: Vec<f64>,
    /// `V̄⁰_p`, summed over the run.
    pub volume0: Vec<f64>,
}

impl<const D: usize> ParticleAdjoint<D> {
    /// All zero, for `n` particles.
    pub fn zeros(n: usize) -> Self {
        Self {
            x: vec![Vector::zeros(); n],
            v: vec![Vector::zeros(); n],
            c: vec![Tensor::zeros(); n],
            f: vec![Tensor::zeros(); n],
            stress: vec![Matrix3::zeros(); n],
            history: vec![MaterialState::zeros(); n],
            mass: vec![0.0; n],
            volume0: vec![0.0; n],
        }
    }

    /// Bytes held by the adjoint of `n` particles.
    pub fn bytes(n: usize) -> u64 {
        let per_particle = 2 * size_of::<Vector<f64, D>>()
            + 2 * size_of::<Tensor<f64, D>>()
            + size_of::<Matrix3<f64>>()
            + size_of::<MaterialState<f64>>()
            + 2 * size_of::<f64>();
        (n * per_particle) as u64
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Whether there are no particles.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }
}
