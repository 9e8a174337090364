//! An inversion file set up once and evaluated at any parameters: the loss `L(θ)` and its
//! gradient `dL/dθ` by the discrete adjoint, as `loam gradient` computes them, for front
//! ends that drive the parameters themselves (the Python package's `gradient` and its JAX and
//! PyTorch layers).

use super::{Invalid, Limits, SetUp, outcome_of};
use crate::Outcome;
use loam_inverse::AdjointError;
use std::path::Path;

/// Why an inversion could not be set up or evaluated: the outcome a command would have
/// ([`Outcome::BadInput`] or [`Outcome::Failed`]) and the message it would print.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Failure {
    /// The outcome: invalid input or a failed run.
    pub outcome: Outcome,
    /// What went wrong, naming the file and the field or the parameter.
    pub message: String,
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Failure {}

/// An inversion file (`docs/inversion-format.md`) read, validated and set up once: a scene's
/// inversion (explicit or implicit, 2D or 3D) or element tests.
///
/// The unknowns `θ` are the named parameters (in the file's order, in their physical units)
/// followed by the weights of any velocity field's network.
pub struct Study(SetUp);

impl Study {
    /// Reads and sets up the inversion file at `path`, with the adjoint's memory budget
    /// `memory` in bytes (`--memory`; `None`: the least memory) within `limits`: the same
    /// checks as `loam check` on the file, with the same messages.
    pub fn open(path: &Path, memory: Option<u64>, limits: Limits) -> Result<Self, Failure> {
        SetUp::read(path, memory, limits)
            .map(Self)
            .map_err(|Invalid(message)| Failure {
                outcome: Outcome::BadInput,
                message,
            })
    }

    /// The inversion file.
    pub fn path(&self) -> &Path {
        self.0.inverse().path()
    }

    /// The names of the named parameters, the first unknowns (`materials[0].young`, …).
    pub fn names(&self) -> &[String] {
        self.0.inverse().names()
    }

    /// The first guess of every unknown, from the file.
    pub fn initial(&self) -> &[f64] {
        self.0.inverse().initial()
    }

    /// The named parameters' truth values, when the file gives one for every parameter.
    pub fn truth(&self) -> Option<&[f64]> {
        self.0.inverse().truth()
    }

    /// The relative L2 error against the truth of each velocity field at `theta`,
    /// `‖v(θ) − v_true‖ / ‖v_true‖` over the field's particles, where the file's `[synthetic]`
    /// run gives the truth (empty otherwise): the error `loam invert` prints per iteration.
    pub fn field_errors(&self, theta: &[f64]) -> Vec<f64> {
        self.0.inverse().field_errors(theta)
    }

    /// `L(θ)` and `dL/dθ` at `theta` (every unknown), by the discrete adjoint: the values
    /// `loam gradient` prints at the file's first guess. `theta` of the wrong length or with
    /// a value that is not finite is invalid input, named as `theta[k]`.
    pub fn gradient(&self, theta: &[f64]) -> Result<(f64, Vec<f64>), Failure> {
        self.check_theta(theta)?;
        let (loss, gradient, _) = self.failed(self.0.inverse().evaluate(theta, true, false))?;
        Ok((loss, gradient))
    }

    /// Every observed quantity `yᵢ` of the file: what it is (`step 120: x of particle 7`),
    /// its data `dᵢ` and its weight `cᵢ`, in the order of [`Study::observe`]; the loss is
    /// `L = Σᵢ cᵢ (yᵢ − dᵢ)²`.
    pub fn observations(&self) -> Vec<(String, f64, f64)> {
        self.0.inverse().observations()
    }

    /// The observed quantities `y(θ)` at `theta` by a forward run (model values, not
    /// misfits). `theta` is checked as by [`Study::gradient`].
    pub fn observe(&self, theta: &[f64]) -> Result<Vec<f64>, Failure> {
        self.check_theta(theta)?;
        self.failed(self.0.inverse().observe(theta))
    }

    /// The vector–Jacobian product `ȳᵀ ∂y/∂θ` of the observed quantities at `theta` with
    /// the cotangent `ȳ` (one value per quantity, in the order of [`Study::observations`]),
    /// by the discrete adjoint seeded with `ȳ` (forward-mode duals for element tests): the
    /// gradient of any loss `ℓ(y)` defined outside loam, with `ȳ = ∂ℓ/∂y`. With
    /// `ȳᵢ = 2cᵢ (yᵢ − dᵢ)` it is [`Study::gradient`]'s `dL/dθ`. A `theta` or a cotangent
    /// of the wrong length or with a value that is not finite is invalid input, named.
    pub fn vjp(&self, theta: &[f64], cotangent: &[f64]) -> Result<Vec<f64>, Failure> {
        self.check_theta(theta)?;
        let n = self.observations().len();
        if cotangent.len() != n {
            return Err(self.invalid(format!(
                "cotangent has {} value(s); expected {n}, one per observed quantity",
                cotangent.len()
            )));
        }
        if let Some(k) = cotangent.iter().position(|v| !v.is_finite()) {
            return Err(self.invalid(format!(
                "cotangent[{k}] = {}: expected a finite number",
                cotangent[k]
            )));
        }
        self.failed(self.0.inverse().vjp(theta, cotangent))
    }

    /// Invalid input: `message` after the file's path.
    fn invalid(&self, message: String) -> Failure {
        Failure {
            outcome: Outcome::BadInput,
            message: format!("{}: {message}", self.path().display()),
        }
    }

    /// A run's or an adjoint's error as a failure, after the file's path.
    fn failed<T>(&self, result: Result<T, AdjointError>) -> Result<T, Failure> {
        result.map_err(|e| Failure {
            outcome: outcome_of(&e),
            message: format!("{}: {e}", self.path().display()),
        })
    }

    /// Refuses `theta` of the wrong length or with a value that is not finite.
    fn check_theta(&self, theta: &[f64]) -> Result<(), Failure> {
        let inverse = self.0.inverse();
        let n = inverse.initial().len();
        if theta.len() != n {
            return Err(self.invalid(format!(
                "theta has {} value(s); expected {n} (the {} named parameter(s) then any \
                 velocity field's weights)",
                theta.len(),
                inverse.names().len()
            )));
        }
        if let Some(k) = theta.iter().position(|v| !v.is_finite()) {
            return Err(self.invalid(format!(
                "theta[{k}] = {}: expected a finite number",
                theta[k]
            )));
        }
        Ok(())
    }

    /// Runs the file's optimiser from its first guess as `loam invert` does, writing the
    /// history, the checkpoint after every iteration and the report into `dir` (the
    /// optimisation continues from the checkpoint there with `resume`); stops between
    /// iterations when [`crate::run::interrupt::requested`].
    pub fn invert(&self, dir: &Path, resume: bool) -> Outcome {
        super::invert_with(self.0.inverse(), dir, resume)
    }
}

#[cfg(test)]
#[path = "vjp_tests.rs"]
mod vjp_tests;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::preflight::{MAX_INVERSION_STEPS, StepLimit};
    use std::path::PathBuf;

    fn friction() -> Study {
        let path =
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/inverse/friction.toml");
        let limits = Limits {
            memory: None,
            steps: StepLimit::new(None, MAX_INVERSION_STEPS),
        };
        Study::open(&path, None, limits).expect("the example is valid")
    }

    /// The study's gradient against central differences of its own loss, per friction
    /// coefficient of the dam-break's floor. The loss is smooth in μ where no particle
    /// changes between sticking and sliding within ±h, so with h = 1e-6 the difference's
    /// truncation (h² L‴ ≈ 1e-12 relative) and round-off (ε L / h ≈ 1e-10 relative) leave
    /// agreement far inside 1e-5.
    #[test]
    fn the_gradient_of_an_inversion_file_matches_central_differences() {
        let study = friction();
        assert_eq!(study.names().len(), 3);
        let theta = study.initial().to_vec();
        let (loss, g) = study.gradient(&theta).unwrap();
        assert!(loss > 0.0, "the first guess is off the truth");
        let h = 1e-6;
        for k in 0..theta.len() {
            let at = |d: f64| {
                let mut t = theta.clone();
                t[k] += d;
                study.gradient(&t).unwrap().0
            };
            let central = (at(h) - at(-h)) / (2.0 * h);
            let rel = (g[k] - central).abs() / central.abs();
            assert!(rel < 1e-5, "μ[{k}]: adjoint {} central {central}", g[k]);
        }
    }

    #[test]
    fn parameters_of_the_wrong_length_or_not_finite_are_refused_by_name() {
        let study = friction();
        let e = study.gradient(&[0.3, 0.1]).unwrap_err();
        assert_eq!(e.outcome, Outcome::BadInput);
        assert!(
            e.message.contains("theta has 2 value(s); expected 3"),
            "{e}"
        );
        let e = study.gradient(&[0.3, f64::NAN, 0.2]).unwrap_err();
        assert!(e.message.contains("theta[1] = NaN"), "{e}");
    }
}
