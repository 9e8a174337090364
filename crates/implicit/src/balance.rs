//! Balancing a prestressed body's initial stress against gravity on the grid.
//!
//! A geostatic stress `σ_v = −ρ g d`, `σ_h = K0 σ_v` under a level surface is in equilibrium
//! with gravity in the continuum, but not in the discrete balance `f_int = f_ext` of the grid:
//! the particles' quadrature of `∫ σ ∇N_i`, the free surface and the fixed base leave a
//! residual `R₀ = f_int(Δu = 0) − f_ext` at the nodes near them, first order in the cell size,
//! and the first load step moves the state by it (`docs/verification.md`,
//! k0-layer).
//!
//! The balance is a force per particle, `f_p = m_p Σ_i N_ip c_i` with `M c = R₀` and `M` the
//! consistent mass `M_ij = Σ_p m_p N_ip N_jp` on the step's unknowns, so that
//! `Σ_p N_ip f_p = (M c)_i = R₀_i` at every unknown: added to the external force, it makes
//! the residual of the initial state zero, an exact solution of a step that adds nothing. The particles carry it, as they carry their weight,
//! and it acts in full at every step ([`ImplicitConfig::balance`]). It is data of the initial
//! state, as the initial stress is: the adjoints hold it fixed.
//!
//! In a coupled run the particles' initial stress is effective and the water carries the
//! rest: the residual at rest is that of the total stress `σ′ − α p I`, with `p` the
//! particles' (hydrostatic) pore pressure.
//!
//! Where the initial stress is not in equilibrium in the continuum (a geostatic state under a
//! sloping surface), `R₀` is that real imbalance and balancing it would hold the ground up;
//! the scene key is therefore an explicit choice (`solver.balance_initial_stress`).

use crate::linear::{LinearSolver, LinearSolverKind};
use crate::solver::{ImplicitConfig, ImplicitError, ImplicitSolver};
use crate::system::{Inverted, StepSystem};
use loam_core::Particles;
use loam_core::tensor::{Tensor, Vector};

/// The balance of an initial stress and how far from equilibrium the state was.
#[derive(Clone, Debug, PartialEq)]
pub struct Balance<const D: usize> {
    /// Per particle, the balancing force `f_p` (N; N per m in 2D).
    pub forces: Vec<Vector<f64, D>>,
    /// `max_i |R₀_i| / max_i |f_ext,i|`: the largest out-of-balance nodal force relative to
    /// the largest nodal weight.
    pub out_of_balance: f64,
}

/// The balance (module docs) of `particles` at rest under `config`'s gravity in full, with
/// no point loads and no prescribed displacement.
///
/// # Errors
/// A particle off the grid or with a state that has no stress, or a consistent mass that
/// cannot be factored.
pub fn balance_initial_stress<const D: usize>(
    config: &ImplicitConfig<D>,
    particles: &Particles<f64, D>,
) -> Result<Balance<D>, ImplicitError> {
    let (solver, system) = at_rest(config, particles)?;
    let n = system.len();
    let mut f_int = system
        .internal_force(&vec![0.0; n], solver.materials())
        .map_err(|Inverted { particle }| ImplicitError::InvalidState { step: 1, particle })?;
    if let Some(fluid) = &config.pore_fluid {
        // The pore water's share of the total stress, −α p V I per particle.
        let s: Vec<Tensor<f64, D>> = (0..particles.len())
            .map(|p| {
                let biot = fluid.hydraulic[particles.material[p] as usize].biot;
                let volume = particles.volume0[p] * loam_core::tensor::det(&particles.f[p]);
                Tensor::<f64, D>::identity() * (-biot * particles.pore_pressure[p] * volume)
            })
            .collect();
        for (f, w) in f_int.iter_mut().zip(system.divergence(&s)) {
            *f += w;
        }
    }
    let r0: Vec<f64> = (system.f_ext.iter().zip(&f_int))
        .map(|(e, i)| i - e)
        .collect();
    let largest = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let weight = largest(&system.f_ext);
    let out_of_balance = if weight > 0.0 {
        largest(&r0) / weight
    } else {
        0.0
    };
    Ok(Balance {
        forces: spread(&system, particles, &r0)?,
        out_of_balance,
    })
}

/// The derivative of the balancing forces when the particles' initial Kirchhoff stresses
/// move at the rates `tau_rate` (3×3, one per particle; the weight held): the balance is
/// linear in the residual `R₀ = f_int − f_ext` and `f_int` at rest is linear in the stress,
/// `Ṙ₀_i = Σ_p V⁰_p τ̇_p ∇N_ip`, so the rate is the balance of `Ṙ₀`.
///
/// # Errors
/// As [`balance_initial_stress`].
pub fn balance_rate<const D: usize>(
    config: &ImplicitConfig<D>,
    particles: &Particles<f64, D>,
    tau_rate: &[nalgebra::Matrix3<f64>],
) -> Result<Vec<Vector<f64, D>>, ImplicitError> {
    let (_, system) = at_rest(config, particles)?;
    let s: Vec<Tensor<f64, D>> = (tau_rate.iter().zip(&particles.volume0))
        .map(|(t, v)| Tensor::<f64, D>::from_fn(|a, b| t[(a, b)] * v))
        .collect();
    spread(&system, particles, &system.divergence(&s))
}

/// The solver and the system of `particles` at rest under `config`'s gravity in full, with
/// no point loads and no prescribed displacement (from load factor 0 to 0): the solid's
/// unknowns alone, also in a coupled run.
fn at_rest<const D: usize>(
    config: &ImplicitConfig<D>,
    particles: &Particles<f64, D>,
) -> Result<(ImplicitSolver<D>, StepSystem<D>), ImplicitError> {
    let rest = ImplicitConfig {
        point_loads: Vec::new(),
        dynamics: None,
        gravity_in_full: true,
        balance: Vec::new(),
        pore_fluid: None,
        ..config.clone()
    };
    let solver = ImplicitSolver::new(rest, particles)?;
    let system = solver.system(particles, 0.0, 0.0)?;
    Ok((solver, system))
}

/// The particle forces `f_p = m_p Σ_i N_ip c_i` with `M c = r` on the consistent mass.
fn spread<const D: usize>(
    system: &StepSystem<D>,
    particles: &Particles<f64, D>,
    r: &[f64],
) -> Result<Vec<Vector<f64, D>>, ImplicitError> {
    let mass = system.consistent_mass(&particles.mass);
    let mut c = vec![0.0; r.len()];
    LinearSolver::new(LinearSolverKind::Cholesky)
        .solve(&mass, r, &mut c)
        .map_err(|e| ImplicitError::Config {
            field: "balance".into(),
            msg: format!("the consistent mass of the balance cannot be factored: {e}"),
        })?;
    Ok((0..particles.len())
        .map(|p| system.interpolate(p, &c) * particles.mass[p])
        .collect())
}
