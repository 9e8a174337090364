//! Constitutive models behind one trait.
//!
//! Models work on the 3×3 deformation gradient: in plane strain (`D = 2`) the solver embeds
//! the in-plane `F` with `F_zz = 1` ([`crate::tensor::to3`]), so `σ_zz` comes out of the same
//! code. Parameters are generic over `T` so a derivative with respect to a material parameter
//! is the same code run with a dual parameter.

mod cam_clay;
pub mod constants;
mod drucker_prager;
mod fluid;
mod hencky;
mod j2;
mod linear_elastic;
mod mohr_coulomb;
mod neo_hookean;
mod strength;
mod trial_return;

pub use cam_clay::{ModifiedCamClay, Preconsolidation, REFERENCE_PRESSURE, Shear};
pub use drucker_prager::{Cone, DruckerPrager, Elasticity};
pub use fluid::Fluid;
pub use hencky::Hencky;
pub use j2::J2;
pub use linear_elastic::LinearElastic;
pub use mohr_coulomb::MohrCoulomb;
pub use neo_hookean::NeoHookean;

use crate::scalar::Scalar;
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

/// Lamé parameters `μ`, `λ` of an isotropic elastic law.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lame<T> {
    /// Shear modulus `μ = E / (2(1 + ν))`.
    pub mu: T,
    /// First Lamé parameter `λ = E ν / ((1 + ν)(1 − 2ν))`.
    pub lambda: T,
}

impl<T: Scalar> Lame<T> {
    /// From Young's modulus `E` and Poisson's ratio `ν` (−1 < ν < ½).
    pub fn from_young_poisson(e: T, nu: T) -> Self {
        let one = T::one();
        Self {
            mu: e / (T::cst(2.0) * (one + nu)),
            lambda: e * nu / ((one + nu) * (one - T::cst(2.0) * nu)),
        }
    }

    /// Young's modulus `E = μ(3λ + 2μ)/(λ + μ)`.
    pub fn young(&self) -> T {
        self.mu * (self.lambda * T::cst(3.0) + self.mu * T::cst(2.0)) / (self.lambda + self.mu)
    }

    /// Poisson's ratio `ν = λ/(2(λ + μ))`.
    pub fn poisson(&self) -> T {
        self.lambda / ((self.lambda + self.mu) * T::cst(2.0))
    }

    /// P-wave (constrained) modulus `M = λ + 2μ`, which sets the elastic wave speed
    /// `c = √(M/ρ)`.
    pub fn p_wave_modulus(&self) -> T {
        self.lambda + self.mu * T::cst(2.0)
    }

    /// The isotropic linear law `2μ ε + λ tr(ε) I` on a symmetric strain `ε` (the Kirchhoff
    /// stress of Hencky elasticity when `ε` is the logarithmic strain).
    pub fn stress(&self, eps: &Matrix3<T>) -> Matrix3<T> {
        eps * (self.mu * T::cst(2.0)) + Matrix3::identity() * (self.lambda * eps.trace())
    }

    /// The strain of a symmetric stress under [`Lame::stress`], its inverse:
    /// `ε = dev τ / (2μ) + tr τ / (3 (3λ + 2μ)) I`.
    pub fn strain(&self, tau: &Matrix3<T>) -> Matrix3<T> {
        let tr = tau.trace();
        let dev = tau - Matrix3::identity() * (tr / T::cst(3.0));
        dev / (self.mu * T::cst(2.0))
            + Matrix3::identity()
                * (tr / ((self.lambda * T::cst(3.0) + self.mu * T::cst(2.0)) * T::cst(3.0)))
    }

    /// The quadratic energy `μ ε:ε + ½λ (tr ε)²` whose derivative is [`Lame::stress`].
    pub fn energy(&self, eps: &Matrix3<T>) -> T {
        let tr = eps.trace();
        self.mu * eps.component_mul(eps).sum() + self.lambda * tr * tr * T::cst(0.5)
    }
}

impl Lame<f64> {
    /// The same parameters as constants of another scalar type (zero derivative parts).
    pub fn lift<T: Scalar>(&self) -> Lame<T> {
        Lame {
            mu: T::cst(self.mu),
            lambda: T::cst(self.lambda),
        }
    }
}

/// The elastic trial state of a Hencky model with a multiplicative split: the trial left
/// Cauchy–Green tensor `bₑᵗʳ = ΔF bₑⁿ ΔFᵀ` (symmetrised, so that round-off asymmetry does not
/// accumulate over many steps) and its Hencky strain `εᵗʳ = ½ ln bₑᵗʳ` (dual-safe at repeated
/// stretches). Shared by [`J2`], the Hencky [`DruckerPrager`] and [`MohrCoulomb`].
pub fn hencky_trial<T: Scalar>(delta_f: &Matrix3<T>, b_n: &Matrix3<T>) -> (Matrix3<T>, Matrix3<T>) {
    let half = T::cst(0.5);
    let b = delta_f * b_n * delta_f.transpose();
    let b_trial = (b + b.transpose()) * half;
    let eps_trial = crate::spectral::symmetric_fn(&b_trial, &crate::spectral::Log) * half;
    (b_trial, eps_trial)
}

/// History variables a particle carries for its constitutive model (unused by elastic
/// models). This is the one declaration of the history's shape: checkpoints, the adjoints'
/// packing and the dual lanes of the implicit adjoint all go through
/// [`MaterialState::components`] and [`MaterialState::from_components`].
///
/// | model | `plastic_strain` | `tensor` | `hardening` |
/// |---|---|---|---|
/// | [`J2`], [`MohrCoulomb`], Hencky [`DruckerPrager`] | `ε̄ᵖ` | `bₑ` | unused (0) |
/// | Jaumann [`DruckerPrager`] | `ε̄ᵖ` | `I + 2 εₑ` | unused (0) |
/// | [`ModifiedCamClay`] | `ε̄ᵖ` | `bₑ` | `p_c` (Pa, compression positive) |
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialState<T> {
    /// Equivalent (accumulated) plastic strain `ε̄ᵖ = Σ √(2/3) ‖Δεᵖ‖`.
    pub plastic_strain: T,
    /// A tensor-valued internal variable (e.g. the elastic left Cauchy–Green tensor).
    pub tensor: Matrix3<T>,
    /// A scalar hardening variable: the preconsolidation pressure `p_c` of
    /// [`ModifiedCamClay`]; zero for the other models.
    pub hardening: T,
}

/// Number of scalars in a [`MaterialState`]: `ε̄ᵖ`, the 9 entries of the tensor, the hardening
/// variable.
pub const HISTORY_LEN: usize = 11;

impl<T: nalgebra::Scalar + Copy> MaterialState<T> {
    /// The components in their fixed order: `ε̄ᵖ`, the tensor row by row, the hardening
    /// variable ([`HISTORY_LEN`] in all).
    pub fn components(&self) -> [T; HISTORY_LEN] {
        std::array::from_fn(|k| match k {
            0 => self.plastic_strain,
            10 => self.hardening,
            k => self.tensor[((k - 1) / 3, (k - 1) % 3)],
        })
    }

    /// The state from its components in the order of [`MaterialState::components`].
    pub fn from_components(c: impl Fn(usize) -> T) -> Self {
        Self {
            plastic_strain: c(0),
            tensor: Matrix3::from_fn(|r, col| c(1 + 3 * r + col)),
            hardening: c(10),
        }
    }

    /// The state with `f` applied to every component.
    pub fn map<U: nalgebra::Scalar + Copy>(&self, f: impl Fn(T) -> U) -> MaterialState<U> {
        let c = self.components();
        MaterialState::from_components(|k| f(c[k]))
    }
}

impl MaterialState<f64> {
    /// The same state as constants of another scalar type.
    pub fn lift<T: Scalar>(&self) -> MaterialState<T> {
        self.map(T::cst)
    }
}

impl<T: Scalar> MaterialState<T> {
    /// Every component zero: the zero adjoint of a state (not a valid state itself, whose
    /// tensor is the identity at rest: see [`Default`]).
    pub fn zeros() -> Self {
        Self::from_components(|_| T::zero())
    }
}

impl<T: Scalar> Default for MaterialState<T> {
    fn default() -> Self {
        Self {
            plastic_strain: T::zero(),
            tensor: Matrix3::identity(),
            hardening: T::zero(),
        }
    }
}

/// What a stress update sees of the motion over one step.
#[derive(Clone, Copy, Debug)]
pub struct Kinematics<'a, T> {
    /// Deformation gradient at the end of the step (3×3, `F_zz = 1` in plane strain).
    pub f: &'a Matrix3<T>,
    /// Relative deformation gradient over the step, `ΔF = F F_n⁻¹` (3×3).
    pub delta_f: &'a Matrix3<T>,
    /// Velocity gradient `L = ∇v` over the step (3×3, zero out-of-plane row/column in 2D).
    pub velocity_gradient: &'a Matrix3<T>,
    /// Time step.
    pub dt: T,
    /// Cauchy stress at the start of the step (rate models integrate from it).
    pub stress: &'a Matrix3<T>,
}

/// Which branch a stress update took: what a reverse pass replays. Branches are decided on
/// real parts; the dual parts follow the branch taken.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Region {
    /// No return mapping: elastic models, the fluid, and a trial state inside the yield
    /// surface.
    #[default]
    Elastic,
    /// Return to the yield surface along the flow direction: [`J2`]'s radial return, or
    /// [`DruckerPrager`]'s return to the cone along its plastic potential.
    Shear,
    /// [`DruckerPrager`]: return to the tension cutoff plane `p = σ_t` (deviator unchanged);
    /// [`MohrCoulomb`]: return to one, two or all three of the cutoff planes `τ_i = σ_t`.
    Tension,
    /// [`DruckerPrager`]: return to the corner where the cone meets the cutoff (the apex when
    /// `σ_t = c cot φ`); [`MohrCoulomb`]: to where a cutoff plane meets the pyramid.
    Corner,
    /// [`MohrCoulomb`]: return to an edge of the pyramid (two planes active).
    Edge,
    /// [`MohrCoulomb`]: return to the apex of the pyramid.
    Apex,
}

/// A constitutive model: kinematics and history in, Cauchy stress and new history out.
pub trait Constitutive<T: Scalar>: Send + Sync {
    /// Cauchy stress `σ` at the end of the step; updates `state` in place.
    fn update(&self, kin: &Kinematics<'_, T>, state: &mut MaterialState<T>) -> Matrix3<T>;

    /// The constrained modulus `M` at small strain (real part), for the time-step bound
    /// `Δt ≤ h / (√(M/ρ) + |v|)`.
    fn p_wave_modulus(&self) -> f64;

    /// The constrained modulus of a point in `state` (real part), for models whose elastic
    /// stiffness depends on the state ([`Constitutive::stiffness_depends_on_state`]); the
    /// others return [`Constitutive::p_wave_modulus`].
    fn p_wave_modulus_in(&self, _state: &MaterialState<T>) -> f64 {
        self.p_wave_modulus()
    }

    /// Whether the elastic stiffness, and so the wave speed, depends on the state (Modified
    /// Cam-Clay's grows with the pressure): the explicit solver then bounds its step with
    /// every particle's own [`Constitutive::p_wave_modulus_in`].
    fn stiffness_depends_on_state(&self) -> bool {
        false
    }
}

/// A hyperelastic model: stress derives from a stored energy `ψ(F)`.
pub trait Hyperelastic<T: Scalar>: Send + Sync {
    /// Stored energy per unit reference volume `ψ(F)`.
    fn energy_density(&self, f: &Matrix3<T>) -> T;

    /// Kirchhoff stress `τ = P Fᵀ = J σ`, with `P = ∂ψ/∂F`.
    fn kirchhoff_stress(&self, f: &Matrix3<T>) -> Matrix3<T>;

    /// Lamé parameters (for the wave speed).
    fn lame(&self) -> Lame<T>;

    /// First Piola–Kirchhoff stress `P = τ F⁻ᵀ`.
    fn first_piola(&self, f: &Matrix3<T>) -> Matrix3<T> {
        let finv = crate::tensor::inverse::<T, 3>(f).expect("deformation gradient is singular");
        self.kirchhoff_stress(f) * finv.transpose()
    }

    /// Cauchy stress `σ = τ / J`, `J = det F`.
    fn cauchy_stress(&self, f: &Matrix3<T>) -> Matrix3<T> {
        self.kirchhoff_stress(f) / crate::tensor::det::<T, 3>(f)
    }
}

/// Implements [`Constitutive`] for hyperelastic models: `σ = τ(F) / J`, no history. (One
/// impl per model rather than a blanket impl over [`Hyperelastic`], which would overlap with
/// the impl of the history-dependent [`J2`].)
macro_rules! hyperelastic_constitutive {
    ($($model:ident),*) => {$(
        impl<T: Scalar> Constitutive<T> for $model<T> {
            fn update(
                &self,
                kin: &Kinematics<'_, T>,
                _state: &mut MaterialState<T>,
            ) -> Matrix3<T> {
                self.cauchy_stress(kin.f)
            }

            fn p_wave_modulus(&self) -> f64 {
                self.lame().p_wave_modulus().re()
            }
        }
    )*};
}

hyperelastic_constitutive!(LinearElastic, NeoHookean, Hencky);

/// The names of the available models (what a scene file may ask for).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ModelKind {
    /// [`LinearElastic`].
    LinearElastic,
    /// [`NeoHookean`].
    NeoHookean,
    /// [`Hencky`].
    Hencky,
    /// [`J2`] (von Mises plasticity), written `j2`.
    J2,
    /// [`Fluid`] (weakly compressible Newtonian fluid), written `fluid`.
    Fluid,
    /// [`DruckerPrager`] (non-associated Drucker–Prager plasticity with a tension cutoff,
    /// Jaumann-rate hypoelastic or Hencky hyperelastic), written `drucker_prager`.
    DruckerPrager,
    /// [`MohrCoulomb`] (Mohr–Coulomb plasticity in Hencky strain), written `mohr_coulomb`.
    MohrCoulomb,
    /// [`ModifiedCamClay`] (critical-state plasticity in Hencky strain), written
    /// `modified_cam_clay`.
    ModifiedCamClay,
}

impl ModelKind {
    /// The name written in a scene file (`"linear_elastic"`, …, `"j2"`, `"fluid"`,
    /// `"drucker_prager"`).
    pub fn name(self) -> &'static str {
        match self {
            Self::LinearElastic => "linear_elastic",
            Self::NeoHookean => "neo_hookean",
            Self::Hencky => "hencky",
            Self::J2 => "j2",
            Self::Fluid => "fluid",
            Self::DruckerPrager => "drucker_prager",
            Self::MohrCoulomb => "mohr_coulomb",
            Self::ModifiedCamClay => "modified_cam_clay",
        }
    }
}

/// A material: density plus one constitutive model. The solver dispatches on the variant
/// once per particle.
#[derive(Clone, Debug, PartialEq)]
pub struct Material<T> {
    /// Reference mass density `ρ₀` (a `T`: a derivative with respect to it reaches the run
    /// through the particle masses `m_p = ρ₀ V_p⁰` built from it).
    pub density: T,
    /// The constitutive model and its parameters.
    pub model: Model<T>,
}

/// The constitutive models, as one enum for run-time selection.
#[derive(Clone, Debug, PartialEq)]
pub enum Model<T> {
    /// Small-strain linear elasticity.
    LinearElastic(LinearElastic<T>),
    /// Compressible Neo-Hookean hyperelasticity.
    NeoHookean(NeoHookean<T>),
    /// Hencky (logarithmic-strain) hyperelasticity.
    Hencky(Hencky<T>),
    /// J2 (von Mises) plasticity in Hencky strain space.
    J2(J2<T>),
    /// Weakly compressible Newtonian fluid (Tait pressure plus viscosity).
    Fluid(Fluid<T>),
    /// Non-associated Drucker–Prager plasticity with a tension cutoff (Jaumann-rate
    /// hypoelastic, or Hencky hyperelastic).
    DruckerPrager(DruckerPrager<T>),
    /// Mohr–Coulomb plasticity in Hencky strain space.
    MohrCoulomb(MohrCoulomb<T>),
    /// Modified Cam-Clay in Hencky strain space.
    ModifiedCamClay(ModifiedCamClay<T>),
}

impl<T> Model<T> {
    /// The model's name ([`ModelKind`]).
    pub fn kind(&self) -> ModelKind {
        match self {
            Self::LinearElastic(_) => ModelKind::LinearElastic,
            Self::NeoHookean(_) => ModelKind::NeoHookean,
            Self::Hencky(_) => ModelKind::Hencky,
            Self::J2(_) => ModelKind::J2,
            Self::Fluid(_) => ModelKind::Fluid,
            Self::DruckerPrager(_) => ModelKind::DruckerPrager,
            Self::MohrCoulomb(_) => ModelKind::MohrCoulomb,
            Self::ModifiedCamClay(_) => ModelKind::ModifiedCamClay,
        }
    }
}

impl<T: Scalar> Material<T> {
    /// An isotropic elastic material of the given kind from `E`, `ν` and `ρ₀`.
    ///
    /// [`ModelKind::J2`] gives a J2 material with an infinite yield stress, which never yields
    /// (Hencky elasticity carried in the J2 state); use [`Material::j2`] for a finite one.
    /// Likewise [`ModelKind::DruckerPrager`] gives an infinite cohesion (`φ = ψ = 0`,
    /// `c = ∞`), which never yields: Jaumann-rate hypoelasticity; use
    /// [`Material::drucker_prager`] for a frictional one.
    ///
    /// # Panics
    ///
    /// On [`ModelKind::Fluid`]: a fluid has no Young's modulus or Poisson's ratio (and no
    /// shear stiffness), so there is no elastic fluid to build; use [`Material::fluid`]. On
    /// [`ModelKind::ModifiedCamClay`], whose stiffness is set by `κ` and the pressure.
    pub fn elastic(kind: ModelKind, young: T, poisson: T, density: T) -> Self {
        let lame = Lame::from_young_poisson(young, poisson);
        let model = match kind {
            ModelKind::LinearElastic => Model::LinearElastic(LinearElastic { lame }),
            ModelKind::NeoHookean => Model::NeoHookean(NeoHookean { lame }),
            ModelKind::Hencky => Model::Hencky(Hencky { lame }),
            ModelKind::J2 => Model::J2(J2 {
                lame,
                yield_stress: T::cst(f64::INFINITY),
                hardening: T::zero(),
            }),
            ModelKind::DruckerPrager => Model::DruckerPrager(DruckerPrager {
                lame,
                friction_angle: T::zero(),
                dilation_angle: T::zero(),
                cohesion: T::cst(f64::INFINITY),
                tension_cutoff: None,
                cone: Cone::PlaneStrain,
                elasticity: Elasticity::Jaumann,
            }),
            ModelKind::MohrCoulomb => Model::MohrCoulomb(MohrCoulomb {
                lame,
                friction_angle: T::cst(std::f64::consts::FRAC_PI_6),
                dilation_angle: T::zero(),
                cohesion: T::cst(f64::INFINITY),
                tension_cutoff: None,
            }),
            ModelKind::Fluid => panic!(
                "Material::elastic: model `fluid` takes a bulk modulus, not E and ν; \
                 use Material::fluid"
            ),
            ModelKind::ModifiedCamClay => panic!(
                "Material::elastic: model `modified_cam_clay` has a pressure-dependent \
                 stiffness set by κ, not E"
            ),
        };
        Self { density, model }
    }

    /// A [`J2`] elastoplastic material from `E`, `ν`, the uniaxial yield stress `σ_y`, the
    /// linear hardening modulus `H` (`0` for perfect plasticity) and `ρ₀`.
    pub fn j2(young: T, poisson: T, yield_stress: T, hardening: T, density: T) -> Self {
        Self {
            density,
            model: Model::J2(J2 {
                lame: Lame::from_young_poisson(young, poisson),
                yield_stress,
                hardening,
            }),
        }
    }

    /// A weakly compressible Newtonian [`Fluid`] from its bulk modulus `K` (Pa), Tait exponent
    /// `γ ≥ 1`, dynamic viscosity `η ≥ 0` (Pa·s) and `ρ₀`. (From a sound speed `c`:
    /// `K = ρ₀ c²`, see [`Fluid::from_sound_speed`].)
    pub fn fluid(bulk_modulus: T, gamma: T, viscosity: T, density: T) -> Self {
        Self {
            density,
            model: Model::Fluid(Fluid {
                bulk_modulus,
                gamma,
                viscosity,
            }),
        }
    }

    /// A non-associated [`DruckerPrager`] material from `E`, `ν`, the friction angle `φ` and
    /// the dilation angle `ψ` (**radians**, `0 < φ < π/2`, `0 ≤ ψ ≤ φ`), the cohesion `c ≥ 0`
    /// (Pa), the tension cutoff `σ_t` on the mean stress (Pa; `None` for the apex of the
    /// cone, `c cot φ`) and `ρ₀`. The cone is the plane-strain match of Mohr–Coulomb,
    /// `α = tan φ / √(9 + 12 tan²φ)`, `k = 3c / √(9 + 12 tan²φ)`.
    pub fn drucker_prager(
        young: T,
        poisson: T,
        friction_angle: T,
        dilation_angle: T,
        cohesion: T,
        tension_cutoff: Option<T>,
        density: T,
    ) -> Self {
        Self {
            density,
            model: Model::DruckerPrager(DruckerPrager {
                lame: Lame::from_young_poisson(young, poisson),
                friction_angle,
                dilation_angle,
                cohesion,
                tension_cutoff,
                cone: Cone::PlaneStrain,
                elasticity: Elasticity::Jaumann,
            }),
        }
    }

    /// Elastic P-wave speed `c = √(M/ρ₀)` (real part); the sound speed `√(K/ρ₀)` of a
    /// [`Fluid`].
    pub fn wave_speed(&self) -> f64 {
        (self.constitutive().p_wave_modulus() / self.density.re()).sqrt()
    }

    /// The elastic shear modulus `G` of a point in `state`: the Lamé `μ` of the models with
    /// constant elasticity, `G(p′)` of [`ModifiedCamClay`], zero for a [`Fluid`].
    pub fn shear_modulus_in(&self, state: &MaterialState<T>) -> T {
        match &self.model {
            Model::LinearElastic(m) => m.lame.mu,
            Model::NeoHookean(m) => m.lame.mu,
            Model::Hencky(m) => m.lame.mu,
            Model::J2(m) => m.lame.mu,
            Model::Fluid(_) => T::zero(),
            Model::DruckerPrager(m) => m.lame.mu,
            Model::MohrCoulomb(m) => m.lame.mu,
            Model::ModifiedCamClay(m) => m.shear_modulus_in(state),
        }
    }

    /// The elastic P-wave speed `√(M/ρ₀)` of a point in `state`, with `M` from
    /// [`Constitutive::p_wave_modulus_in`] (the same as [`Material::wave_speed`] for models
    /// whose stiffness does not depend on the state).
    pub fn wave_speed_in(&self, state: &MaterialState<T>) -> f64 {
        (self.constitutive().p_wave_modulus_in(state) / self.density.re()).sqrt()
    }

    /// The model as a trait object (for code that does not need static dispatch).
    pub fn constitutive(&self) -> &dyn Constitutive<T> {
        match &self.model {
            Model::LinearElastic(m) => m,
            Model::NeoHookean(m) => m,
            Model::Hencky(m) => m,
            Model::J2(m) => m,
            Model::Fluid(m) => m,
            Model::DruckerPrager(m) => m,
            Model::MohrCoulomb(m) => m,
            Model::ModifiedCamClay(m) => m,
        }
    }

    /// Stored (elastic) energy per unit reference volume: `ψ(F)` for the hyperelastic models
    /// (`state` unused), `ψ(bₑ) = μ ε:ε + ½λ (tr ε)²` with `ε = ½ ln bₑ` for [`J2`] (`f`
    /// unused; the plastic work is dissipated, not stored), the compression energy
    /// `ψ(det F) = −∫₁ᴶ p dJ'` for [`Fluid`] (`state` unused; viscous work is dissipated), the
    /// elastic energy of the stress `det F · ½ σ:C⁻¹:σ` for [`DruckerPrager`]
    /// ([`DruckerPrager::stored_energy`], from the elastic strain the state carries).
    #[inline]
    pub fn energy_density(&self, f: &Matrix3<T>, state: &MaterialState<T>) -> T {
        match &self.model {
            Model::LinearElastic(m) => m.energy_density(f),
            Model::NeoHookean(m) => m.energy_density(f),
            Model::Hencky(m) => m.energy_density(f),
            Model::J2(m) => m.stored_energy(state),
            Model::Fluid(m) => m.energy_density(f),
            Model::DruckerPrager(m) => m.stored_energy(f, state),
            Model::MohrCoulomb(m) => m.stored_energy(state),
            Model::ModifiedCamClay(m) => m.stored_energy(state),
        }
    }

    /// The history state in which a model with elastic history carries the Kirchhoff stress
    /// `τ₀` with no plastic strain: `bₑ = exp(2 C⁻¹:τ₀)` for [`J2`], [`MohrCoulomb`] and the
    /// Hencky [`DruckerPrager`], `I + 2 C⁻¹:τ₀` for the Jaumann one, and
    /// [`ModifiedCamClay::initial_state`] (its `p_c₀` too). `None` for the models whose stress
    /// is a function of `F` alone (the elastic models, the fluid): they carry a stress only
    /// through their deformation; and for [`ModifiedCamClay`] at `p′₀ ≤ 0`. Whether `τ₀` lies inside the yield surface is
    /// the caller's to check (a step with `ΔF = I` from the state returns it). With dual
    /// constants the derivative parts are the state's derivatives (the initial stress held).
    pub fn prestressed_state(&self, tau0: &Matrix3<T>) -> Option<MaterialState<T>> {
        let hencky = |lame: &Lame<T>| MaterialState {
            plastic_strain: T::zero(),
            tensor: crate::spectral::symmetric_fn(
                &(lame.strain(tau0) * T::cst(2.0)),
                &crate::spectral::Exp,
            ),
            hardening: T::zero(),
        };
        match &self.model {
            Model::J2(m) => Some(hencky(&m.lame)),
            Model::MohrCoulomb(m) => Some(hencky(&m.lame)),
            Model::ModifiedCamClay(m) => m.initial_state(tau0),
            Model::DruckerPrager(m) => Some(MaterialState {
                plastic_strain: T::zero(),
                tensor: m.state_tensor(&m.compliance(tau0)),
                hardening: T::zero(),
            }),
            Model::LinearElastic(_) | Model::NeoHookean(_) | Model::Hencky(_) | Model::Fluid(_) => {
                None
            }
        }
    }

    /// Kirchhoff stress `τ` and new state at the end of a step, without committing anything:
    /// for the hyperelastic models `τ(F)` of the total deformation gradient `f` with the state
    /// unchanged, for [`J2`] its return mapping on the relative deformation gradient `delta_f`
    /// from `state` ([`J2::kirchhoff_update`]), for [`Fluid`] the pressure part
    /// `τ = −J p(J) I` only ([`Fluid::kirchhoff_stress`]: without a rate of deformation the
    /// implicit path treats the fluid as inviscid), for [`DruckerPrager`] its Jaumann update and
    /// return mapping with `Δt L = ΔF − I` from the stress its state stands for
    /// ([`DruckerPrager::kirchhoff_update`]; scenes keep it out of the implicit solver). For
    /// implicit solvers, which re-evaluate a step from the last converged state at every
    /// Newton iterate; with dual inputs the derivative is the consistent tangent.
    pub fn kirchhoff_update(
        &self,
        delta_f: &Matrix3<T>,
        f: &Matrix3<T>,
        state: &MaterialState<T>,
    ) -> (Matrix3<T>, MaterialState<T>) {
        match &self.model {
            Model::LinearElastic(m) => (m.kirchhoff_stress(f), *state),
            Model::NeoHookean(m) => (m.kirchhoff_stress(f), *state),
            Model::Hencky(m) => (m.kirchhoff_stress(f), *state),
            Model::J2(m) => m.kirchhoff_update(delta_f, state),
            Model::Fluid(m) => (m.kirchhoff_stress(f), *state),
            Model::DruckerPrager(m) => m.kirchhoff_update(delta_f, f, state),
            Model::MohrCoulomb(m) => {
                let (tau, state, _) = m.return_map(delta_f, state);
                (tau, state)
            }
            Model::ModifiedCamClay(m) => {
                let (tau, state, _) = m.return_map(delta_f, state);
                (tau, state)
            }
        }
    }

    /// Stress update by static dispatch on the model.
    #[inline]
    pub fn update(&self, kin: &Kinematics<'_, T>, state: &mut MaterialState<T>) -> Matrix3<T> {
        self.update_region(kin, state).0
    }

    /// [`Material::update`] with the branch the update took ([`Region::Elastic`] for the
    /// models without a return mapping), for a step record.
    #[inline]
    pub fn update_region(
        &self,
        kin: &Kinematics<'_, T>,
        state: &mut MaterialState<T>,
    ) -> (Matrix3<T>, Region) {
        match &self.model {
            Model::LinearElastic(m) => (m.update(kin, state), Region::Elastic),
            Model::NeoHookean(m) => (m.update(kin, state), Region::Elastic),
            Model::Hencky(m) => (m.update(kin, state), Region::Elastic),
            Model::J2(m) => m.update_region(kin, state),
            Model::Fluid(m) => (m.update(kin, state), Region::Elastic),
            Model::DruckerPrager(m) => m.update_region(kin, state),
            Model::MohrCoulomb(m) => m.update_region(kin, state),
            Model::ModifiedCamClay(m) => m.update_region(kin, state),
        }
    }
}

impl Material<f64> {
    /// The same material with its parameters as constants of another scalar type (zero
    /// derivative parts), e.g. to evaluate dual-number tangents with respect to the motion.
    pub fn lift<T: Scalar>(&self) -> Material<T> {
        let model = match &self.model {
            Model::LinearElastic(m) => Model::LinearElastic(LinearElastic {
                lame: m.lame.lift(),
            }),
            Model::NeoHookean(m) => Model::NeoHookean(NeoHookean {
                lame: m.lame.lift(),
            }),
            Model::Hencky(m) => Model::Hencky(Hencky {
                lame: m.lame.lift(),
            }),
            Model::J2(m) => Model::J2(J2 {
                lame: m.lame.lift(),
                yield_stress: T::cst(m.yield_stress),
                hardening: T::cst(m.hardening),
            }),
            Model::Fluid(m) => Model::Fluid(m.lift()),
            Model::DruckerPrager(m) => Model::DruckerPrager(m.lift()),
            Model::MohrCoulomb(m) => Model::MohrCoulomb(m.lift()),
            Model::ModifiedCamClay(m) => Model::ModifiedCamClay(m.lift()),
        };
        Material {
            density: T::cst(self.density),
            model,
        }
    }
}

#[cfg(test)]
mod cam_clay_tests;
#[cfg(test)]
mod drucker_prager_tests;
#[cfg(test)]
mod fluid_tests;
#[cfg(test)]
mod j2_tests;
#[cfg(test)]
mod soil_tests;
#[cfg(test)]
mod tests;
