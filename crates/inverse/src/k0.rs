//! K0, the lateral earth-pressure coefficient of a geostatic initial stress, as a parameter of
//! both paths: the state it sets and its derivative.
//!
//! A geostatic body starts at `σ′_v = −ρ₀ g d` along gravity and `σ′_h = K0 σ′_v` across
//! (`loam_scene`'s `initial_stress`). As a parameter, K0 moves the horizontal stresses of its
//! material's particles with the vertical one held (it is the weight above) and each
//! particle's deformation gradient held: the Kirchhoff stress `τ₀ = J σ₀` moves at the rate
//! `∂τ₀/∂K0` and the history that carries it follows ([`Material::prestressed_state`]).
//! In 2D the out-of-plane stress moves as the scene sets it: `τ_zz = K0 τ_v` for Modified
//! Cam-Clay and the Jaumann Drucker–Prager (whose states at rest carry the target stress
//! itself), `τ_zz = ν (τ_xx + τ_yy)` for the Hencky models, whose states at rest have no
//! out-of-plane strain, so `∂τ_zz/∂K0 = ν τ_v`.

use loam_core::constitutive::{Elasticity, MaterialState, Model};
use loam_core::tensor::{Vector, det};
use loam_core::{Material, Particles};
use nalgebra::Matrix3;
use num_dual::Dual64;

/// The K0 state of one material's particles.
#[derive(Clone, Debug, PartialEq)]
pub struct K0State {
    /// `K0 = τ_h/τ_v`, the same at every particle along every horizontal axis.
    pub k0: f64,
    /// Per particle of the material: its index, its initial Kirchhoff stress `τ₀ = J σ₀`
    /// and the rate `∂τ₀/∂K0`.
    pub particles: Vec<(usize, Matrix3<f64>, Matrix3<f64>)>,
}

impl K0State {
    /// The K0 state of the particles of `material` (number `k`) under `gravity`.
    ///
    /// # Errors
    /// A model that carries its initial stress in its deformation gradient (the elastic
    /// models and the fluid: their K0 follows from ν), no gravity, no particle of the
    /// material with a vertical stress (no `initial_stress`), or particles that do not share
    /// one K0.
    pub fn of<const D: usize>(
        material: &Material<f64>,
        gravity: &Vector<f64, D>,
        particles: &Particles<f64, D>,
        k: usize,
    ) -> Result<Self, String> {
        let out_of_plane = match &material.model {
            Model::ModifiedCamClay(_) => 1.0,
            Model::DruckerPrager(m) if m.elasticity == Elasticity::Jaumann => 1.0,
            Model::DruckerPrager(m) => m.lame.poisson(),
            Model::J2(m) => m.lame.poisson(),
            Model::MohrCoulomb(m) => m.lame.poisson(),
            other => {
                return Err(format!(
                    "model \"{}\" carries its initial stress in its deformation gradient, \
                     where K0 follows from ν: K0 is a parameter of j2, drucker_prager, \
                     mohr_coulomb and modified_cam_clay",
                    other.kind().name()
                ));
            }
        };
        let axis = (0..D)
            .max_by(|&a, &b| gravity[a].abs().total_cmp(&gravity[b].abs()))
            .filter(|&a| gravity[a] != 0.0)
            .ok_or("a geostatic state needs gravity: the scene has none")?;
        let stresses: Vec<(usize, Matrix3<f64>)> = (0..particles.len())
            .filter(|&p| particles.material[p] as usize == k)
            .map(|p| (p, particles.stress[p] * det(&particles.f[p])))
            .collect();
        let (p0, deepest) = (stresses.iter())
            .max_by(|a, b| a.1[(axis, axis)].abs().total_cmp(&b.1[(axis, axis)].abs()))
            .filter(|(_, tau)| tau[(axis, axis)] != 0.0)
            .ok_or(
                "the K0 of a geostatic initial stress: no particle of the material carries one \
                 (`initial_stress = { type = \"geostatic\", k0 = … }` on its bodies)",
            )?;
        let tau_deep = deepest[(axis, axis)];
        let k0 = deepest[((axis + 1) % D, (axis + 1) % D)] / tau_deep;
        // The scene's states at rest carry their target stress to ~1e-12 of the deepest one.
        let tolerance = 1e-8 * tau_deep.abs();
        let mut out = Vec::with_capacity(stresses.len());
        for &(p, tau) in &stresses {
            let tau_v = tau[(axis, axis)];
            for a in (0..D).filter(|&a| a != axis) {
                if (tau[(a, a)] - k0 * tau_v).abs() > tolerance {
                    return Err(format!(
                        "the particles of the material do not share one K0 (σ_h/σ_v = {k0} at \
                         particle {p0}, {} at particle {p}): give each layer its own material",
                        tau[(a, a)] / tau_v
                    ));
                }
            }
            let rate = Matrix3::from_fn(|a, b| match (a == b, a == axis, a < D) {
                (true, false, true) => tau_v,
                (true, false, false) => out_of_plane * tau_v,
                _ => 0.0,
            });
            out.push((p, tau, rate));
        }
        Ok(Self { k0, particles: out })
    }

    /// Sets the particles to K0 = `value`: the stress `τ₀ + (K0′ − K0) ∂τ₀/∂K0`, the history
    /// that carries it in `material`, the Cauchy stress `τ₀/J`.
    ///
    /// # Errors
    /// A particle left with no compressive mean stress (Modified Cam-Clay), or with a stress
    /// outside the yield surface.
    pub fn set<const D: usize>(
        &self,
        material: &Material<f64>,
        particles: &mut Particles<f64, D>,
        value: f64,
    ) -> Result<(), String> {
        let identity = Matrix3::identity();
        for &(p, tau, rate) in &self.particles {
            let tau = tau + rate * (value - self.k0);
            let h = material.prestressed_state(&tau).ok_or_else(|| {
                format!("K0 = {value} leaves particle {p} no compressive mean stress")
            })?;
            let (back, _) = material.kirchhoff_update(&identity, &identity, &h);
            if (back - tau).amax() > 1e-9 * tau.amax() {
                return Err(format!(
                    "K0 = {value} puts the initial stress of particle {p} outside the yield \
                     surface of its material"
                ));
            }
            particles.state[p] = h;
            particles.stress[p] = tau / det(&particles.f[p]);
        }
        Ok(())
    }

    /// Per particle, `(p, ∂σ₀/∂K0, ∂h₀/∂K0)`: the Cauchy stress rate `(∂τ₀/∂K0)/J` and the
    /// history's, from `material` at the dual stress.
    pub fn rates<const D: usize>(
        &self,
        material: &Material<f64>,
        particles: &Particles<f64, D>,
    ) -> Vec<(usize, Matrix3<f64>, MaterialState<f64>)> {
        let dual = material.lift::<Dual64>();
        (self.particles.iter())
            .filter_map(|&(p, tau, rate)| {
                let tau = Matrix3::from_fn(|i, j| Dual64::new(tau[(i, j)], rate[(i, j)]));
                let h = dual.prestressed_state(&tau)?;
                Some((p, rate / det(&particles.f[p]), h.map(|c| c.eps)))
            })
            .collect()
    }
}
