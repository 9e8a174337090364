//! Energy bookkeeping of a particle state.

use crate::constitutive::Material;
use crate::particles::Particles;
use crate::scalar::Scalar;
use crate::tensor::{Vector, to3};

/// Kinetic, stored (strain) and gravitational potential energy (real parts, joules; per
/// metre of thickness in plane strain).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energy {
    /// `½ Σ m_p |v_p|²`.
    pub kinetic: f64,
    /// `Σ V_p⁰ ψ(F_p)`.
    pub strain: f64,
    /// `−Σ m_p g·x_p` (zero at the origin).
    pub gravity: f64,
}

impl Energy {
    /// Sum of the three parts.
    pub fn total(&self) -> f64 {
        self.kinetic + self.strain + self.gravity
    }
}

/// Energy of a particle state (serial sums, so the result is deterministic).
pub fn energy<T: Scalar, const D: usize>(
    particles: &Particles<T, D>,
    materials: &[Material<T>],
    gravity: &Vector<T, D>,
) -> Energy {
    let mut e = Energy::default();
    for p in 0..particles.len() {
        let m = particles.mass[p].re();
        e.kinetic += 0.5 * m * particles.v[p].map(|x| x.re()).norm_squared();
        let mat = &materials[particles.material[p] as usize];
        let f = to3(&particles.f[p], T::one());
        e.strain += particles.volume0[p].re() * mat.energy_density(&f, &particles.state[p]).re();
        e.gravity -= m * gravity.map(|x| x.re()).dot(&particles.x[p].map(|x| x.re()));
    }
    e
}
