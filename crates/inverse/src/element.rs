//! Back-analysis of element tests: material constants fitted to laboratory curves.
//!
//! An element test ([`loam_implicit::element`]) drives one material point through the stages
//! of a laboratory test; its curve is the sequence of states after every increment, read as
//! soil mechanics reads them (compression positive): the deviator stress `q`, the mean
//! effective stress `p′`, the volumetric strain `ε_v` and the void ratio
//! `e = (1 + e₀)(1 − ε_v) − 1`, against the axial strain `ε_a`. An observation is a point
//! `(ε_a, d)` of one of them with a standard deviation `σ`; the model's value `m(ε_a)` is the
//! curve interpolated linearly in `ε_a` between the increments on either side,
//!
//! `m(ε_a) = y_k + w (y_(k+1) − y_k)`, `w = (ε_a − ε_a,k)/(ε_a,(k+1) − ε_a,k)`,
//!
//! which is differentiable in the parameters through both the values `y` and the curve's own
//! axial strains (of the stages that control a stress). The loss over the observations of
//! every test is `L = ½ Σ r_i²`, `r_i = (m_i − d_i)/σ_i`.
//!
//! Derivatives are forward mode: the test is run once per parameter with the material lifted
//! to `Dual64` and that parameter seeded ([`crate::Param`]'s material seeding), the start
//! state built from the dual material (the history that carries the initial stress moves
//! with the elastic constants), and the driver carrying the derivative through every
//! increment ([`loam_implicit::element::run_carrying`]). That gives the Jacobian
//! `J_ij = ∂r_i/∂θ_j` of the residuals, so the gradient `Jᵀr` and the Gauss–Newton matrix
//! `JᵀJ` of Levenberg–Marquardt come from the same runs. An element path is a few hundred
//! constitutive updates: a run per parameter costs milliseconds.

use crate::error::AdjointError;
use crate::implicit::Identifiability;
use crate::params::{MaterialField, seed_material, set_material};
use crate::problem::GaussNewtonModel;
use loam_core::Scalar;
use loam_core::constitutive::{Material, Model};
use loam_implicit::element::{LabStage, PointState, run_test};
use nalgebra::Matrix3;
use num_dual::Dual64;

/// A quantity of an element test's curve, compression positive.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Measure {
    /// The deviator stress `q = σ′_a − σ′_r` (Pa).
    DeviatorStress,
    /// The mean effective stress `p′ = −tr σ/3` (Pa).
    MeanStress,
    /// The volumetric strain `ε_v = 1 − det F`.
    VolumetricStrain,
    /// The void ratio `e = (1 + e₀) det F − 1`.
    VoidRatio,
}

impl Measure {
    /// Every quantity, in the order of the enum.
    pub const ALL: [Measure; 4] = [
        Self::DeviatorStress,
        Self::MeanStress,
        Self::VolumetricStrain,
        Self::VoidRatio,
    ];

    /// The name in files: `q`, `p`, `volumetric_strain`, `void_ratio`.
    pub fn name(self) -> &'static str {
        match self {
            Self::DeviatorStress => "q",
            Self::MeanStress => "p",
            Self::VolumetricStrain => "volumetric_strain",
            Self::VoidRatio => "void_ratio",
        }
    }

    /// Whether it is a stress (Pa; files write kPa), rather than a pure number.
    pub fn is_stress(self) -> bool {
        matches!(self, Self::DeviatorStress | Self::MeanStress)
    }
}

/// One point of an element test's curve: the state after an increment, compression
/// positive (stresses in Pa).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurvePoint<T = f64> {
    /// The axial strain `ε_a = 1 − F_zz`.
    pub axial_strain: T,
    /// The deviator stress `q`.
    pub q: T,
    /// The mean effective stress `p′`.
    pub p: T,
    /// The volumetric strain `ε_v`.
    pub volumetric_strain: T,
    /// The void ratio, where the test has an initial one.
    pub void_ratio: Option<T>,
}

impl<T: Scalar> CurvePoint<T> {
    /// The value of `measure` (`None`: a void ratio without an initial one).
    pub fn value(&self, measure: Measure) -> Option<T> {
        match measure {
            Measure::DeviatorStress => Some(self.q),
            Measure::MeanStress => Some(self.p),
            Measure::VolumetricStrain => Some(self.volumetric_strain),
            Measure::VoidRatio => self.void_ratio,
        }
    }
}

/// An observed point of a test's curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observed {
    /// What was measured.
    pub measure: Measure,
    /// At which axial strain.
    pub axial_strain: f64,
    /// The measured value (Pa for a stress).
    pub value: f64,
    /// Its standard deviation `σ` (same unit).
    pub sigma: f64,
}

/// One element test of an inversion and what was observed of it.
#[derive(Clone, Debug)]
pub struct LabTest {
    /// The material at the test file's values (the parameters are set on it).
    pub material: Material<f64>,
    /// The initial Cauchy stress (Pa, tension positive), carried at `F = I`.
    pub stress: Matrix3<f64>,
    /// The stages.
    pub stages: Vec<LabStage>,
    /// The initial void ratio `e₀` of a model that has none of its own (Modified Cam-Clay
    /// uses its `e₀`, a parameter).
    pub void_ratio: Option<f64>,
    /// The observations.
    pub observed: Vec<Observed>,
}

/// A least-squares loss over element tests as a function of material constants `θ`, each
/// set on the material of every test.
#[derive(Clone, Debug)]
pub struct ElementProblem {
    /// The tests.
    pub tests: Vec<LabTest>,
    /// The parameters, in the order of `θ`.
    pub params: Vec<MaterialField>,
}

/// The initial void ratio of `material` in a test that gives `given`: Modified Cam-Clay's own
/// `e₀` (with its derivative when it is seeded), else `given`.
fn void_ratio<T: Scalar>(material: &Material<T>, given: Option<f64>) -> Option<T> {
    match &material.model {
        Model::ModifiedCamClay(m) => Some(m.void_ratio),
        _ => given.map(T::cst),
    }
}

/// How far beyond its ends, relative to its span, a curve is read (by the end segment): the
/// round-off of the axial strain the path reaches (`1 − (1 − 0.2)` is not `0.2` to the last
/// bit), so that a point observed at the test's last strain is on it.
const END_TOLERANCE: f64 = 1e-9;

/// The segment of `xs` (real parts) that holds `x`: the first whose ends bracket it, or the
/// end segment where `x` is within [`END_TOLERANCE`] of that end; `None` elsewhere.
fn segment<T: Scalar>(xs: &[T], x: f64) -> Option<usize> {
    let n = xs.len();
    if n < 2 {
        return None;
    }
    let (first, last) = (xs[0].re(), xs[n - 1].re());
    let tolerance = END_TOLERANCE * (last - first).abs();
    (0..n - 1)
        .find(|&k| {
            let (a, b) = (xs[k].re(), xs[k + 1].re());
            (a - x) * (b - x) <= 0.0 && a != b
        })
        .or_else(|| {
            if (x - first).abs() <= tolerance {
                Some(0)
            } else if (x - last).abs() <= tolerance {
                Some(n - 2)
            } else {
                None
            }
        })
}

/// `ε_a`-interpolation of one quantity of a curve at `x` (the module's formula) on the
/// [`segment`] that holds `x`; `None` off the curve.
fn interpolate<T: Scalar>(xs: &[T], ys: &[T], x: f64) -> Option<T> {
    let k = segment(xs, x)?;
    let w = (T::cst(x) - xs[k]) / (xs[k + 1] - xs[k]);
    Some(ys[k] + w * (ys[k + 1] - ys[k]))
}

/// Whether a point observed at the axial strain `x` lies on `curve` (between its ends, or
/// within the round-off of one).
pub fn on_path<T: Scalar>(curve: &[CurvePoint<T>], x: f64) -> bool {
    let xs: Vec<T> = curve.iter().map(|c| c.axial_strain).collect();
    segment(&xs, x).is_some()
}

/// The value of `measure` on `curve` at the axial strain `x`, interpolated linearly between
/// the increments on either side (the module's formula); `None` outside the curve's range or
/// for a void ratio of a test without an initial one.
pub fn interpolated<T: Scalar>(curve: &[CurvePoint<T>], measure: Measure, x: f64) -> Option<T> {
    let xs: Vec<T> = curve.iter().map(|c| c.axial_strain).collect();
    let ys: Option<Vec<T>> = curve.iter().map(|c| c.value(measure)).collect();
    interpolate(&xs, &ys?, x)
}

impl LabTest {
    /// The curve of the test with `material` in `T` (`real` its real parts), from the start
    /// state that carries the initial stress under that material; `index` names the test in
    /// errors.
    ///
    /// # Errors
    /// [`AdjointError::Element`] when a stage cannot be completed.
    pub fn curve<T: Scalar>(
        &self,
        real: &Material<f64>,
        material: &Material<T>,
        index: usize,
    ) -> Result<Vec<CurvePoint<T>>, AdjointError> {
        let start = PointState::at_rest(material, &self.stress);
        let path = run_test(real, material, start, &self.stages);
        if let Some(source) = path.failure {
            return Err(AdjointError::Element {
                test: index,
                source,
            });
        }
        let e0 = void_ratio(material, self.void_ratio);
        Ok((path.states.iter())
            .map(|s| {
                let m = s.measures();
                CurvePoint {
                    axial_strain: m.axial_strain,
                    q: m.q,
                    p: m.p,
                    volumetric_strain: m.volumetric_strain,
                    void_ratio: e0
                        .map(|e0| (T::one() + e0) * (T::one() - m.volumetric_strain) - T::one()),
                }
            })
            .collect())
    }

    /// The scaled residuals `(m − d)/σ` of the observations against `curve`.
    ///
    /// # Errors
    /// As [`LabTest::modelled`].
    pub fn residuals<T: Scalar>(
        &self,
        curve: &[CurvePoint<T>],
        index: usize,
    ) -> Result<Vec<T>, AdjointError> {
        let m = self.modelled(curve, index)?;
        Ok((m.into_iter().zip(&self.observed))
            .map(|(m, o)| (m - T::cst(o.value)) / T::cst(o.sigma))
            .collect())
    }

    /// The model values `m` of the observations on `curve`: each observed quantity
    /// interpolated at the observation's axial strain.
    ///
    /// # Errors
    /// [`AdjointError::Observation`] naming the test (`tests[index]`) when the curve's axial
    /// strain does not move monotonically (observations are placed by it), or an observed
    /// axial strain lies outside the curve, or a void ratio is observed of a test without an
    /// initial one.
    pub fn modelled<T: Scalar>(
        &self,
        curve: &[CurvePoint<T>],
        index: usize,
    ) -> Result<Vec<T>, AdjointError> {
        let fail = |msg: String| AdjointError::Observation {
            field: format!("tests[{index}]"),
            msg,
        };
        let xs: Vec<T> = curve.iter().map(|c| c.axial_strain).collect();
        let (first, last) = (xs[0].re(), xs[xs.len() - 1].re());
        let rising = last > first;
        if let Some(k) = (1..xs.len()).find(|&k| {
            let d = xs[k].re() - xs[k - 1].re();
            if rising { d <= 0.0 } else { d >= 0.0 }
        }) {
            return Err(fail(format!(
                "the axial strain of the test's path {} at increment {k} ({:.6e} after {:.6e}): \
                 observations are placed by axial strain, which must grow (or fall) over the \
                 whole path",
                if rising {
                    "stops growing"
                } else {
                    "stops falling"
                },
                xs[k].re(),
                xs[k - 1].re()
            )));
        }
        let (lo, hi) = (first.min(last), first.max(last));
        (self.observed.iter())
            .map(|o| {
                let ys: Option<Vec<T>> = curve.iter().map(|c| c.value(o.measure)).collect();
                let ys = ys.ok_or_else(|| {
                    fail(
                        "a void ratio is observed, but the test has no initial void ratio \
                         (`initial.void_ratio`)"
                            .into(),
                    )
                })?;
                interpolate(&xs, &ys, o.axial_strain).ok_or_else(|| {
                    fail(format!(
                        "an observation at axial strain {} lies outside the test's path, \
                         {lo:.6e} to {hi:.6e}",
                        o.axial_strain
                    ))
                })
            })
            .collect()
    }
}

impl ElementProblem {
    /// The parameters' values in the first test's material.
    ///
    /// # Errors
    /// A parameter its model does not have.
    pub fn values(&self) -> Result<Vec<f64>, AdjointError> {
        let material = &self.tests[0].material;
        (self.params.iter())
            .map(|&field| {
                seed_material(material, field)
                    .map(|(_, v)| v)
                    .ok_or_else(|| no_such(field, 0, material))
            })
            .collect()
    }

    /// The material of every test with the parameters set to `theta`.
    ///
    /// # Errors
    /// A parameter the model of a test does not have.
    pub fn materials(&self, theta: &[f64]) -> Result<Vec<Material<f64>>, AdjointError> {
        (self.tests.iter().enumerate())
            .map(|(i, t)| {
                let mut m = t.material.clone();
                for (&field, &v) in self.params.iter().zip(theta) {
                    set_material(&mut m, field, v).ok_or_else(|| no_such(field, i, &m))?;
                }
                Ok(m)
            })
            .collect()
    }

    /// The curve of every test at `theta`.
    ///
    /// # Errors
    /// As [`ElementProblem::materials`] and [`LabTest::curve`].
    pub fn curves(&self, theta: &[f64]) -> Result<Vec<Vec<CurvePoint>>, AdjointError> {
        let materials = self.materials(theta)?;
        (self.tests.iter().zip(&materials).enumerate())
            .map(|(i, (t, m))| t.curve(m, m, i))
            .collect()
    }

    /// The residuals of every test, in the scalar of `lifted` (each test's material at
    /// `theta` lifted by it).
    fn residuals_in<T: Scalar>(
        &self,
        theta: &[f64],
        lifted: impl Fn(&Material<f64>) -> Result<Material<T>, AdjointError>,
    ) -> Result<Vec<T>, AdjointError> {
        self.of_curves(theta, lifted, LabTest::residuals)
    }

    /// `of(test, its curve, its index)` of every test, concatenated, the curves in the scalar
    /// of `lifted` (each test's material at `theta` lifted by it).
    fn of_curves<T: Scalar>(
        &self,
        theta: &[f64],
        lifted: impl Fn(&Material<f64>) -> Result<Material<T>, AdjointError>,
        of: impl Fn(&LabTest, &[CurvePoint<T>], usize) -> Result<Vec<T>, AdjointError>,
    ) -> Result<Vec<T>, AdjointError> {
        let materials = self.materials(theta)?;
        let mut out = Vec::new();
        for (i, (t, m)) in self.tests.iter().zip(&materials).enumerate() {
            let curve = t.curve(m, &lifted(m)?, i)?;
            out.extend(of(t, &curve, i)?);
        }
        Ok(out)
    }

    /// The model value `m_i` of every observation at `theta`, test by test.
    ///
    /// # Errors
    /// As [`ElementProblem::residuals`].
    pub fn modelled(&self, theta: &[f64]) -> Result<Vec<f64>, AdjointError> {
        self.of_curves(theta, |m| Ok(m.clone()), LabTest::modelled)
    }

    /// The vector–Jacobian product `ȳᵀ ∂m/∂θ` of the model values ([`ElementProblem::modelled`])
    /// with `cotangent` (one value per observation): `Σᵢ ȳᵢ ∂mᵢ/∂θ_k` from one `Dual64` run
    /// of the tests per parameter, as the gradient's.
    ///
    /// # Errors
    /// A cotangent whose length is not the number of observations, or as
    /// [`ElementProblem::residuals`].
    pub fn vjp(&self, theta: &[f64], cotangent: &[f64]) -> Result<Vec<f64>, AdjointError> {
        let n = self.observations();
        if cotangent.len() != n {
            return Err(AdjointError::cotangent_length(cotangent.len(), n));
        }
        (0..self.params.len())
            .map(|k| {
                let m = self.of_curves(theta, self.seeding(k), LabTest::modelled)?;
                Ok(m.iter().zip(cotangent).map(|(m, b)| m.eps * b).sum())
            })
            .collect()
    }

    /// The scaled residuals `r_i = (m_i − d_i)/σ_i` of every observation at `theta`.
    ///
    /// # Errors
    /// As [`ElementProblem::curves`] and [`LabTest::residuals`].
    pub fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>, AdjointError> {
        self.residuals_in(theta, |m| Ok(m.clone()))
    }

    /// `L(θ) = ½ Σ r_i²`.
    ///
    /// # Errors
    /// As [`ElementProblem::residuals`].
    pub fn loss(&self, theta: &[f64]) -> Result<f64, AdjointError> {
        Ok(half_sum_of_squares(&self.residuals(theta)?))
    }

    /// The residuals with their derivative with respect to parameter `k` (a `Dual64` run of
    /// every test with that parameter seeded).
    fn seeded_residuals(&self, theta: &[f64], k: usize) -> Result<Vec<Dual64>, AdjointError> {
        self.residuals_in(theta, self.seeding(k))
    }

    /// Each material lifted to `Dual64` with parameter `k` seeded.
    fn seeding(
        &self,
        k: usize,
    ) -> impl Fn(&Material<f64>) -> Result<Material<Dual64>, AdjointError> + use<> {
        let field = self.params[k];
        move |m| {
            seed_material(m, field)
                .map(|(dual, _)| dual)
                .ok_or_else(|| no_such(field, 0, m))
        }
    }

    /// The residuals `r` and the columns `∂r/∂θ_j` of their Jacobian, one seeded run per
    /// parameter.
    ///
    /// # Errors
    /// As [`ElementProblem::residuals`].
    pub fn jacobian(&self, theta: &[f64]) -> Result<(Vec<f64>, Vec<Vec<f64>>), AdjointError> {
        let mut residuals = Vec::new();
        let mut columns = Vec::with_capacity(self.params.len());
        for k in 0..self.params.len() {
            let r = self.seeded_residuals(theta, k)?;
            if k == 0 {
                residuals = r.iter().map(|r| r.re).collect();
            }
            columns.push(r.iter().map(|r| r.eps).collect());
        }
        Ok((residuals, columns))
    }

    /// The Gauss–Newton model of the loss at `theta`: `L = ½ Σ r²`, `∇L = Jᵀr` and `H = JᵀJ`.
    ///
    /// # Errors
    /// As [`ElementProblem::residuals`].
    pub fn gauss_newton(&self, theta: &[f64]) -> Result<GaussNewtonModel, AdjointError> {
        let (r, columns) = self.jacobian(theta)?;
        Ok(GaussNewtonModel::new(0.5, &r, &columns))
    }

    /// [`ElementProblem::gauss_newton`] at an optimiser's trial point: a test that cannot be
    /// completed there (a stress target beyond the material's strength) gives `L = ∞`, a zero
    /// gradient and a zero matrix, so that the step is shortened (or damped) instead of
    /// ending the inversion.
    ///
    /// # Errors
    /// As [`ElementProblem::gauss_newton`], but for a test that stops.
    pub fn trial_gauss_newton(&self, theta: &[f64]) -> Result<GaussNewtonModel, AdjointError> {
        match self.gauss_newton(theta) {
            Err(AdjointError::Element { .. }) => Ok(GaussNewtonModel::unbounded(theta.len())),
            other => other,
        }
    }

    /// `dL/dθ_k` from the loss evaluated in `Dual64` with parameter `k` seeded,
    /// `Σ r_i ṙ_i` (the oracle of the gradient's `k`-th component).
    ///
    /// # Errors
    /// As [`ElementProblem::residuals`].
    pub fn dual_derivative(&self, theta: &[f64], k: usize) -> Result<f64, AdjointError> {
        Ok(half_sum_of_squares(&self.seeded_residuals(theta, k)?).eps)
    }

    /// The Gauss–Newton analysis of the observations at `theta` ([`Identifiability`]: `JᵀJ`
    /// of the residuals in relative parameter changes).
    ///
    /// # Errors
    /// As [`ElementProblem::residuals`].
    pub fn identifiability(&self, theta: &[f64]) -> Result<Identifiability, AdjointError> {
        let (r, columns) = self.jacobian(theta)?;
        // The columns are dr/dθ = (dm/dθ)/σ already: unit σ.
        Ok(Identifiability::new(&columns, theta, &vec![1.0; r.len()]))
    }

    /// What each observation is, test by test (`tests[0]: q at axial strain 0.01`), with its
    /// data `d_i` and weight `c_i = 1/(2σ_i²)` (`L = Σ c_i (m_i − d_i)²`).
    pub fn labelled(&self) -> Vec<(String, f64, f64)> {
        (self.tests.iter().enumerate())
            .flat_map(|(i, t)| {
                t.observed.iter().map(move |o| {
                    (
                        format!(
                            "tests[{i}]: {} at axial strain {}",
                            o.measure.name(),
                            o.axial_strain
                        ),
                        o.value,
                        0.5 / (o.sigma * o.sigma),
                    )
                })
            })
            .collect()
    }

    /// The number of observations.
    pub fn observations(&self) -> usize {
        self.tests.iter().map(|t| t.observed.len()).sum()
    }

    /// Replaces the observations by synthetic ones from the curves at `truth`: for every
    /// test `i`, each quantity of `fitted[i]` (with its `σ`) after every `every`-th
    /// increment (the first after `every` increments: the start is fixed by the initial
    /// stress, which no parameter moves).
    ///
    /// # Errors
    /// As [`ElementProblem::curves`]; [`AdjointError::Observation`] for a void ratio of a
    /// test without an initial one.
    pub fn observe(
        &mut self,
        truth: &[f64],
        every: usize,
        fitted: &[Vec<(Measure, f64)>],
    ) -> Result<(), AdjointError> {
        let curves = self.curves(truth)?;
        for (i, (test, curve)) in self.tests.iter_mut().zip(&curves).enumerate() {
            test.observed.clear();
            for point in curve.iter().skip(every).step_by(every.max(1)) {
                for &(measure, sigma) in &fitted[i] {
                    let value = point
                        .value(measure)
                        .ok_or_else(|| AdjointError::Observation {
                            field: format!("tests[{i}]"),
                            msg:
                                "a void ratio is observed, but the test has no initial void ratio \
                              (`initial.void_ratio`)"
                                    .into(),
                        })?;
                    test.observed.push(Observed {
                        measure,
                        axial_strain: point.axial_strain,
                        value,
                        sigma,
                    });
                }
            }
        }
        Ok(())
    }
}

/// `½ Σ r²`.
fn half_sum_of_squares<T: Scalar>(r: &[T]) -> T {
    r.iter().fold(T::zero(), |s, &r| s + r * r) * T::cst(0.5)
}

/// The error of a parameter that the material of test `test` does not have.
fn no_such(field: MaterialField, test: usize, material: &Material<f64>) -> AdjointError {
    AdjointError::Parameter {
        param: format!("material.{}", field.name()),
        msg: format!(
            "the material of test {test}: {}",
            crate::params::no_such_constant(material)
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use loam_core::constitutive::{Lame, ModifiedCamClay, MohrCoulomb, Preconsolidation, Shear};
    use loam_implicit::element::Loading;

    /// Linear interpolation of a straight line is exact, and its derivative with respect to
    /// the nodes' values and abscissae is the closed form `∂m/∂y_k = 1 − w`,
    /// `∂m/∂x_k = −(1 − w) (y_(k+1) − y_k)/(x_(k+1) − x_k)`; outside the nodes there is none.
    #[test]
    fn interpolation_between_increments_and_its_derivatives() {
        let xs = [0.0, 0.1, 0.3].map(Dual64::from_re);
        let mut ys = [1.0, 2.0, 4.0].map(Dual64::from_re);
        ys[1].eps = 1.0;
        let m = interpolate(&xs, &ys, 0.15).unwrap();
        // w = 0.25 on the second segment: m = 2 + 0.25·2, ∂m/∂y₁ = 0.75.
        assert!((m.re - 2.5).abs() < 1e-15 && (m.eps - 0.75).abs() < 1e-15);
        let mut xs = xs;
        xs[1].eps = 1.0;
        let ys = [1.0, 2.0, 4.0].map(Dual64::from_re);
        let m = interpolate(&xs, &ys, 0.15).unwrap();
        // ∂m/∂x₁ = −0.75 · (4 − 2)/0.2 = −7.5.
        assert!((m.eps + 7.5).abs() < 1e-12, "{}", m.eps);
        assert!(interpolate(&xs, &ys, 0.31).is_none());
        // The round-off of the last strain reached is on the curve (the end segment).
        let m = interpolate(&xs, &ys, 0.3 + 1e-12).unwrap();
        assert!((m.re - 4.0).abs() < 1e-9);
        // A falling curve (extension) is read the same way.
        let down = [0.0, -0.1].map(Dual64::from_re);
        let m = interpolate(&down, &ys[..2], -0.05).unwrap();
        assert!((m.re - 1.5).abs() < 1e-15);
    }

    fn clay() -> Material<f64> {
        Material {
            density: 1800.0,
            model: Model::ModifiedCamClay(ModifiedCamClay {
                lambda: 0.2,
                kappa: 0.04,
                critical_state_slope: 1.0,
                void_ratio: 1.0,
                shear: Shear::Poisson(0.3),
                preconsolidation: Preconsolidation::Ratio(1.0),
            }),
        }
    }

    /// An undrained test of normally consolidated clay from 200 kPa to 10 % axial strain in
    /// 20 increments.
    fn undrained() -> LabTest {
        LabTest {
            material: clay(),
            stress: Matrix3::identity() * -200e3,
            stages: vec![LabStage {
                loading: Loading::UndrainedTriaxial { axial_strain: 0.1 },
                increments: 20,
            }],
            void_ratio: None,
            observed: Vec::new(),
        }
    }

    /// With synthetic observations from `truth`, the residuals vanish there; 20 % off, the
    /// Gauss–Newton gradient `Jᵀr` from the seeded runs is the derivative of the loss: it
    /// agrees with the loss evaluated in `Dual64` to round-off (1e-12: the two sum the same
    /// products in another order) and with a central difference of the real loss at
    /// `h = 10⁻⁵ θ` to 1e-6 (truncation `O(h²)` ≈ 1e-10, the increments' convergence to
    /// round-off ≈ 1e-10 after the division by `2h`).
    fn assert_the_gradient_is_the_derivative(
        mut problem: ElementProblem,
        fitted: &[(Measure, f64)],
        points: usize,
    ) {
        let truth = problem.values().unwrap();
        problem.observe(&truth, 4, &[fitted.to_vec()]).unwrap();
        assert_eq!(problem.observations(), points * fitted.len());
        assert!(problem.loss(&truth).unwrap() < 1e-24);
        let theta: Vec<f64> = truth.iter().map(|t| 1.2 * t).collect();
        let model = problem.gauss_newton(&theta).unwrap();
        for k in 0..theta.len() {
            let dual = problem.dual_derivative(&theta, k).unwrap();
            let g = model.gradient[k];
            assert!(g != 0.0, "{k}: the loss must depend on the parameter");
            assert!(
                (g - dual).abs() <= 1e-12 * g.abs(),
                "{k}: {g:e} vs {dual:e}"
            );
            let h = 1e-5 * theta[k];
            let at = |d: f64| {
                let mut t = theta.clone();
                t[k] += d;
                problem.loss(&t).unwrap()
            };
            let fd = (at(h) - at(-h)) / (2.0 * h);
            assert!((g - fd).abs() <= 1e-6 * g.abs(), "{k}: {g:e} vs {fd:e}");
        }
    }

    /// Modified Cam-Clay's λ, κ, M and e₀ from an undrained test.
    #[test]
    fn the_gradient_of_the_loss_is_its_derivative() {
        use MaterialField::{CriticalStateSlope, Kappa, Lambda, VoidRatio};
        let problem = ElementProblem {
            tests: vec![undrained()],
            params: vec![Lambda, Kappa, CriticalStateSlope, VoidRatio],
        };
        assert_eq!(problem.values().unwrap(), vec![0.2, 0.04, 1.0, 1.0]);
        let fitted = [
            (Measure::DeviatorStress, 1e3),
            (Measure::MeanStress, 1e3),
            (Measure::VoidRatio, 1e-3),
        ];
        assert_the_gradient_is_the_derivative(problem, &fitted, 5);
    }

    /// Mohr–Coulomb's tension cutoff, with E and ν, from a drained extension test that
    /// reaches it: from 20 kPa all round, the axial stress turns tensile and is held at
    /// σ_t = 5 kPa (the cutoff is met at 5 kPa of tension, the shear planes at 16.4 kPa), so
    /// `q = −σ_t/J − 20 kPa` and the plastic volume change depend on σ_t.
    #[test]
    fn the_gradient_through_the_tension_cutoff_is_its_derivative() {
        use MaterialField::{Poisson, TensionCutoff, Young};
        let sand = Material {
            density: 1800.0,
            model: Model::MohrCoulomb(MohrCoulomb {
                lame: Lame::from_young_poisson(20e6, 0.3),
                friction_angle: 30f64.to_radians(),
                dilation_angle: 0.0,
                cohesion: 20e3,
                tension_cutoff: Some(5e3),
            }),
        };
        let extension = LabTest {
            material: sand,
            stress: Matrix3::identity() * -20e3,
            stages: vec![LabStage {
                loading: Loading::DrainedTriaxial {
                    axial_strain: -0.01,
                },
                increments: 20,
            }],
            void_ratio: None,
            observed: Vec::new(),
        };
        let problem = ElementProblem {
            tests: vec![extension],
            params: vec![Young, Poisson, TensionCutoff],
        };
        assert_eq!(problem.values().unwrap()[2], 5e3);
        let curve = &problem.curves(&[20e6, 0.3, 5e3]).unwrap()[0];
        // The cutoff bounds the Kirchhoff stress: the axial Cauchy stress is σ_t/J, and the
        // radial stress is held at 20 kPa, so q = −σ_t/J − 20 kPa with J = 1 − ε_v.
        let end = curve.last().unwrap();
        let q_end = end.value(Measure::DeviatorStress).unwrap();
        let j = 1.0 - end.value(Measure::VolumetricStrain).unwrap();
        assert!(j > 1.001, "the sample dilates in tension: J = {j}");
        let q_cut = -5e3 / j - 20e3;
        assert!(
            (q_end - q_cut).abs() < 1e-9 * 25e3,
            "q at the end {q_end}, −σ_t/J − 20 kPa = {q_cut}"
        );
        let fitted = [
            (Measure::DeviatorStress, 1e3),
            (Measure::VolumetricStrain, 1e-4),
        ];
        assert_the_gradient_is_the_derivative(problem, &fitted, 5);
    }

    /// Observations are placed by axial strain: one outside the path, or a path whose axial
    /// strain turns back, is refused naming the test.
    #[test]
    fn observations_off_the_path_are_refused() {
        let mut test = undrained();
        test.observed.push(Observed {
            measure: Measure::DeviatorStress,
            axial_strain: 0.2,
            value: 50e3,
            sigma: 1e3,
        });
        let problem = ElementProblem {
            tests: vec![test],
            params: vec![MaterialField::Lambda],
        };
        let err = problem.loss(&[0.2]).unwrap_err().to_string();
        assert!(err.contains("tests[0]") && err.contains("outside"), "{err}");
        let mut back = problem.clone();
        back.tests[0].stages.push(LabStage {
            loading: Loading::UndrainedTriaxial {
                axial_strain: -0.05,
            },
            increments: 5,
        });
        let err = back.loss(&[0.2]).unwrap_err().to_string();
        assert!(
            err.contains("increment 21") && err.contains("grow"),
            "{err}"
        );
    }

    /// A constant the model does not have is refused naming it and the model.
    #[test]
    fn a_constant_of_another_model_is_refused() {
        let problem = ElementProblem {
            tests: vec![undrained()],
            params: vec![MaterialField::FrictionAngle],
        };
        let err = problem.values().unwrap_err().to_string();
        assert!(
            err.contains("material.friction_angle") && err.contains("modified_cam_clay"),
            "{err}"
        );
    }
}
