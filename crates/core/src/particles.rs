//! Material points, stored as a structure of arrays (one `Vec` per field).

use crate::constitutive::MaterialState;
use crate::scalar::Scalar;
use crate::tensor::{Tensor, Vector};
use nalgebra::Matrix3;

/// The particle state of an MPM body. All vectors have the same length; index `p` is
/// particle `p`. Fields are generic over the scalar type so a whole run can be carried with
/// dual numbers.
#[derive(Debug, PartialEq)]
pub struct Particles<T: Scalar, const D: usize> {
    /// Position `x_p`.
    pub x: Vec<Vector<T, D>>,
    /// Velocity `v_p`.
    pub v: Vec<Vector<T, D>>,
    /// Acceleration `a_p`: the end-of-step acceleration of implicit Newmark dynamics (for
    /// output; a step takes its start acceleration from the forces); zero otherwise.
    pub a: Vec<Vector<T, D>>,
    /// Deformation gradient `F_p` (in-plane block in plane strain, where `F_zz = 1`).
    pub f: Vec<Tensor<T, D>>,
    /// APIC affine velocity matrix `C_p = B_p D_p⁻¹` (zero for PIC / FLIP).
    pub c: Vec<Tensor<T, D>>,
    /// Cauchy stress `σ_p`, always 3×3 (plane strain keeps `σ_zz`).
    pub stress: Vec<Matrix3<T>>,
    /// Mass `m_p`.
    pub mass: Vec<T>,
    /// Reference volume `V_p⁰`; the current volume is `det F_p · V_p⁰`.
    pub volume0: Vec<T>,
    /// Reference half-length of the particle domain per axis (GIMP shape functions).
    pub half_width0: Vec<Vector<T, D>>,
    /// Index of the particle's material in the material table.
    pub material: Vec<u32>,
    /// History variables of the constitutive model.
    pub state: Vec<MaterialState<T>>,
    /// Pore water pressure `p` (Pa, positive in compression) of a saturated soil in a
    /// coupled (u–p) run; zero otherwise. `stress` is then the effective stress `σ′` and the
    /// total stress is `σ′ − α p I`.
    pub pore_pressure: Vec<T>,
}

impl<T: Scalar, const D: usize> Default for Particles<T, D> {
    fn default() -> Self {
        Self {
            x: Vec::new(),
            v: Vec::new(),
            a: Vec::new(),
            f: Vec::new(),
            c: Vec::new(),
            stress: Vec::new(),
            mass: Vec::new(),
            volume0: Vec::new(),
            half_width0: Vec::new(),
            material: Vec::new(),
            state: Vec::new(),
            pore_pressure: Vec::new(),
        }
    }
}

impl<T: Scalar, const D: usize> Clone for Particles<T, D> {
    fn clone(&self) -> Self {
        let mut out = Self::default();
        out.clone_from(self);
        out
    }

    /// Copies `source` field by field into the buffers already held (no allocation when they
    /// are large enough): what a run that keeps many states reuses.
    fn clone_from(&mut self, source: &Self) {
        let Self {
            x,
            v,
            a,
            f,
            c,
            stress,
            mass,
            volume0,
            half_width0,
            material,
            state,
            pore_pressure,
        } = source;
        self.x.clone_from(x);
        self.v.clone_from(v);
        self.a.clone_from(a);
        self.f.clone_from(f);
        self.c.clone_from(c);
        self.stress.clone_from(stress);
        self.mass.clone_from(mass);
        self.volume0.clone_from(volume0);
        self.half_width0.clone_from(half_width0);
        self.material.clone_from(material);
        self.state.clone_from(state);
        self.pore_pressure.clone_from(pore_pressure);
    }
}

impl<T: Scalar, const D: usize> Particles<T, D> {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// `true` when there are no particles.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Appends an undeformed, stress-free particle of cubic domain `volume0 = Π 2·half_width`.
    pub fn push(
        &mut self,
        x: Vector<T, D>,
        v: Vector<T, D>,
        density: T,
        half_width: Vector<T, D>,
        material: u32,
    ) {
        let mut vol = T::one();
        for a in 0..D {
            vol *= half_width[a] * T::cst(2.0);
        }
        self.x.push(x);
        self.v.push(v);
        self.a.push(Vector::zeros());
        self.f.push(Tensor::<T, D>::identity());
        self.c.push(Tensor::<T, D>::zeros());
        self.stress.push(Matrix3::zeros());
        self.mass.push(density * vol);
        self.volume0.push(vol);
        self.half_width0.push(half_width);
        self.material.push(material);
        self.state.push(MaterialState::default());
        self.pore_pressure.push(T::zero());
    }

    /// Total mass `Σ m_p`.
    pub fn total_mass(&self) -> T {
        self.mass.iter().fold(T::zero(), |s, &m| s + m)
    }

    /// Linear momentum `Σ m_p v_p`.
    pub fn momentum(&self) -> Vector<T, D> {
        self.mass
            .iter()
            .zip(&self.v)
            .fold(Vector::<T, D>::zeros(), |s, (&m, v)| s + v * m)
    }

    /// Kinetic energy `½ Σ m_p |v_p|²` (the APIC affine part is not included).
    pub fn kinetic_energy(&self) -> T {
        self.mass
            .iter()
            .zip(&self.v)
            .fold(T::zero(), |s, (&m, v)| s + m * v.norm_squared())
            * T::cst(0.5)
    }

    /// Mass-weighted centre-of-mass velocity `Σ m_p v_p / Σ m_p`.
    pub fn centre_of_mass_velocity(&self) -> Vector<T, D> {
        self.momentum() / self.total_mass()
    }
}

impl<const D: usize> Particles<f64, D> {
    /// The same particles with every field as constants of another scalar type (position,
    /// velocity, acceleration, `F`, affine matrix, stress, mass, volume, half-width, material
    /// state and pore pressure); seed the derivative parts of the result to differentiate
    /// with respect to the initial state.
    pub fn lift<T: Scalar>(&self) -> Particles<T, D> {
        let vectors = |v: &[Vector<f64, D>]| v.iter().map(|x| x.map(T::cst)).collect();
        let tensors = |v: &[Tensor<f64, D>]| v.iter().map(|x| x.map(T::cst)).collect();
        let scalars = |v: &[f64]| v.iter().map(|&x| T::cst(x)).collect();
        Particles {
            x: vectors(&self.x),
            v: vectors(&self.v),
            a: vectors(&self.a),
            f: tensors(&self.f),
            c: tensors(&self.c),
            stress: self.stress.iter().map(|s| s.map(T::cst)).collect(),
            mass: scalars(&self.mass),
            volume0: scalars(&self.volume0),
            half_width0: vectors(&self.half_width0),
            material: self.material.clone(),
            state: self.state.iter().map(MaterialState::lift).collect(),
            pore_pressure: scalars(&self.pore_pressure),
        }
    }
}
