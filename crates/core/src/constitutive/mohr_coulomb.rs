//! Mohr–Coulomb plasticity in Hencky strain space, with the multi-surface return in principal
//! stress space (de Souza Neto, Perić & Owen, *Computational Methods for Plasticity*, Wiley
//! 2008, §8.2.2: main plane, the two edges and the apex).
//!
//! **Sign convention.** Stresses are tension positive, as everywhere in loam; principal values
//! are ordered `τ₁ ≥ τ₂ ≥ τ₃` (so `τ₃` is the major compressive stress). In soil mechanics'
//! compression-positive terms the yield condition below is `σ′₁ − σ′₃ = 2c cos φ + (σ′₁ + σ′₃)
//! sin φ`, with `σ′₁/σ′₃ = (1 + sin φ)/(1 − sin φ)` when `c = 0`.
//!
//! **Elasticity.** Hyperelastic in the Hencky strain, as [`super::J2`]: with `F = Fₑ Fₚ`,
//! `bₑ = Fₑ Fₑᵀ` and `εₑ = ½ ln bₑ`, the Kirchhoff stress is `τ = λ tr(εₑ) I + 2μ εₑ`, coaxial
//! with `εₑ`, so in principal values `τ_i = Σ_j D_ij ε_j`, `D = λ 1⊗1 + 2μ I`.
//!
//! **Yield surface and plastic potential** (perfectly plastic; `ψ ≤ φ`, `ψ = φ` associated):
//!
//! ```text
//! f = (τ₁ − τ₃) + (τ₁ + τ₃) sin φ − 2c cos φ,     g = (τ₁ − τ₃) + (τ₁ + τ₃) sin ψ
//! ```
//!
//! **Return mapping** (closed form, no local iteration). The trial `bₑᵗʳ = ΔF bₑⁿ ΔFᵀ` gives the
//! trial principal strains `εᵗʳ` and stresses `τᵗʳ = D εᵗʳ` (the principal directions are those
//! of `bₑᵗʳ` and do not change in the return). With `N_a = ∂f_a/∂τ`, `A_a = D ∂g_a/∂τ`:
//!
//! 1. **main plane**: `Δγ = fᵗʳ / (N·A)`, `τ = τᵗʳ − Δγ A`; valid when the order
//!    `τ₁ ≥ τ₂ ≥ τ₃` survives;
//! 2. **edge** (two planes active; Koiter's rule): the compression edge `τ₁ = τ₂` when the main
//!    plane return put `τ₂` above `τ₁`, otherwise the extension edge `τ₂ = τ₃`. The second plane
//!    is the main plane with `τ₂` in place of `τ₁` (compression edge) or of `τ₃` (extension
//!    edge); `[N_a·A_b] Δγ = fᵗʳ`, `τ = τᵗʳ − Δγ₁ A₁ − Δγ₂ A₂`; valid when both `Δγ ≥ 0` and the
//!    pair stays on its side of the third stress (`τ₂ ≥ τ₃` on the compression edge, `τ₁ ≥ τ₂`
//!    on the extension edge);
//! 3. **apex**: otherwise `τ = c cot φ I` (for perfect plasticity the apex is a point).
//!
//! **Tension cutoff** (optional, `σ_t ≤ c cot φ`; none is the apex): the Rankine planes
//! `f_Ti = τ_i − σ_t` with associated flow (`A_Ti = D e_i`). When the pyramid's return (or the
//! elastic trial) leaves a principal stress above `σ_t`, the return is taken over the nine
//! planes of the cut pyramid in unordered principal space (the six Mohr–Coulomb planes
//! `(τ_i − τ_j) + (τ_i + τ_j) sin φ = 2c cos φ`, `i ≠ j`, and the three cutoffs): the first
//! active set of one, two or three planes, holding a cutoff, whose multipliers solve
//! `[N_a·A_b] Δγ = fᵗʳ` with `Δγ ≥ 0` and whose stress lies inside every plane. Three sets
//! suffice (Carathéodory: a return direction in the cone of four or more flow vectors is a
//! non-negative combination of three of them). With only cutoffs active the region is
//! `Tension` (`σ_t I` at the corner of all three), with a Mohr–Coulomb plane too, `Corner`.
//! The search runs on real parts and the chosen set is solved again in the scalar type, so a
//! dual evaluation is exact in these regions as well.
//!
//! The stress tensor is `τ = Σ τ_i n_i n_iᵀ` on the eigenvectors of `bₑᵗʳ`, `εₑ = C⁻¹:τ`,
//! `bₑ = exp(2εₑ)`, and the equivalent plastic strain grows by `√(2/3) ‖εᵗʳ − εₑ‖`.
//!
//! **Derivatives.** The principal return is applied through [`super::trial_return`] (one
//! eigen-decomposition of `bₑᵗʳ` for the trial strain, `τ` and `bₑ`), which carries a dual
//! perturbation through the eigenbasis of the real part with the divided differences
//! `(τ_i − τ_j)/(b_i − b_j)` (their limit from the Jacobian of the return where two stretches
//! coincide, as in a triaxial test), so
//! a dual evaluation gives the exact consistent tangent in every region, edges and apex
//! included, and the derivative with respect to `c`, `φ`, `ψ`, `E`, `ν`.

use super::trial_return::{PrincipalReturn, trial_return};
use super::{Constitutive, Kinematics, Lame, MaterialState, Region};
use crate::scalar::Scalar;
use crate::spectral::{Log, symmetric_fn};
use crate::tensor::det;
use nalgebra::Matrix3;
use num_dual::DualSVec64;

/// Mohr–Coulomb elastoplasticity (perfectly plastic, non-associated) in Hencky strain space.
/// Angles in radians. State ([`MaterialState`]): `tensor` is `bₑ`, `plastic_strain` the
/// equivalent plastic strain. See the module docs for the equations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MohrCoulomb<T> {
    /// Lamé parameters of the Hencky elastic law.
    pub lame: Lame<T>,
    /// Friction angle `φ` (radians), `0 < φ < π/2`.
    pub friction_angle: T,
    /// Dilation angle `ψ` (radians), `0 ≤ ψ ≤ φ`.
    pub dilation_angle: T,
    /// Cohesion `c ≥ 0` (Pa).
    pub cohesion: T,
    /// Tension cutoff `σ_t` on every principal stress (Pa), `0 ≤ σ_t ≤ c cot φ`; `None`: the
    /// apex `c cot φ` bounds the tension.
    pub tension_cutoff: Option<T>,
}

/// One plane of the cut pyramid in unordered principal stress space: `f = n·τ − k ≤ 0`,
/// return direction `A = D g` (`g` the gradient of the plastic potential).
#[derive(Clone, Copy)]
struct Plane<T> {
    n: [T; 3],
    a: [T; 3],
    k: T,
    cutoff: bool,
}

/// Planes of [`MohrCoulomb::planes`]: the three cutoffs, then the six Mohr–Coulomb planes.
const PLANES: usize = 9;

impl<T: Scalar> PrincipalReturn<T> for MohrCoulomb<T> {
    type Lanes = MohrCoulomb<DualSVec64<3>>;

    /// [`MohrCoulomb::principal_return`], with the principal elastic strains of a plastic
    /// step, `εₑ_i = (τ_i − λ/(3λ + 2μ) tr τ) / 2μ` ([`Lame::strain`] in principal axes).
    fn principal_state(&self, eps: [T; 3]) -> ([T; 3], Option<[T; 3]>, Region) {
        let (tau, region) = self.principal_return(eps);
        if region == Region::Elastic {
            return (tau, None, region);
        }
        let Lame { mu, lambda } = self.lame;
        let two_mu = mu * T::cst(2.0);
        let volumetric = (tau[0] + tau[1] + tau[2]) * lambda / (lambda * T::cst(3.0) + two_mu);
        let elastic = tau.map(|t| (t - volumetric) / two_mu);
        (tau, Some(elastic), region)
    }

    fn lanes(&self) -> Self::Lanes {
        self.real().lift()
    }
}

impl<T: Scalar> MohrCoulomb<T> {
    /// The real parts of the parameters.
    pub fn real(&self) -> MohrCoulomb<f64> {
        MohrCoulomb {
            lame: Lame {
                mu: self.lame.mu.re(),
                lambda: self.lame.lambda.re(),
            },
            friction_angle: self.friction_angle.re(),
            dilation_angle: self.dilation_angle.re(),
            cohesion: self.cohesion.re(),
            tension_cutoff: self.tension_cutoff.map(|t| t.re()),
        }
    }

    /// The yield function `f = (τ₁ − τ₃) + (τ₁ + τ₃) sin φ − 2c cos φ` of principal stresses
    /// in any order (negative inside the pyramid).
    pub fn yield_function(&self, tau: [T; 3]) -> T {
        let hi = max3(tau);
        let lo = min3(tau);
        (hi - lo) + (hi + lo) * self.friction_angle.sin()
            - self.cohesion * T::cst(2.0) * self.friction_angle.cos()
    }

    /// Mean stress at the apex of the pyramid, `c cot φ`.
    pub fn apex(&self) -> T {
        self.cohesion / self.friction_angle.tan()
    }

    /// The return of trial principal strains `εᵗʳ` (any order) to principal Kirchhoff stresses
    /// in the same order, with the region taken (see the module docs): the pyramid's return,
    /// then the cut pyramid's where a stress is left above the tension cutoff.
    pub fn principal_return(&self, eps: [T; 3]) -> ([T; 3], Region) {
        let (tau, region) = self.pyramid_return(eps);
        match self.tension_cutoff {
            Some(cutoff) if max3(tau).re() > cutoff.re() * (1.0 + 1e-12) => {
                self.cutoff_return(eps, cutoff)
            }
            _ => (tau, region),
        }
    }

    /// The trial stresses `τᵗʳ = D εᵗʳ`.
    fn trial(&self, eps: [T; 3]) -> [T; 3] {
        let (lambda, two_mu) = (self.lame.lambda, self.lame.mu * T::cst(2.0));
        let tr = eps[0] + eps[1] + eps[2];
        std::array::from_fn(|i| lambda * tr + two_mu * eps[i])
    }

    /// `D v = λ (Σ v) 1 + 2μ v`.
    fn stiff(&self, v: [T; 3]) -> [T; 3] {
        let tr = v[0] + v[1] + v[2];
        std::array::from_fn(|i| self.lame.lambda * tr + self.lame.mu * T::cst(2.0) * v[i])
    }

    /// The planes of the cut pyramid (module docs) for the cutoff `σ_t`.
    fn planes(&self, cutoff: T) -> [Plane<T>; PLANES] {
        let (sin_phi, sin_psi) = (self.friction_angle.sin(), self.dilation_angle.sin());
        let k = self.cohesion * T::cst(2.0) * self.friction_angle.cos();
        let unit = |i: usize| -> [T; 3] {
            std::array::from_fn(|a| if a == i { T::one() } else { T::zero() })
        };
        let mohr = |i: usize, j: usize, sin: T| -> [T; 3] {
            std::array::from_fn(|a| {
                if a == i {
                    T::one() + sin
                } else if a == j {
                    sin - T::one()
                } else {
                    T::zero()
                }
            })
        };
        const PAIRS: [(usize, usize); 6] = [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)];
        std::array::from_fn(|p| {
            if p < 3 {
                Plane {
                    n: unit(p),
                    a: self.stiff(unit(p)),
                    k: cutoff,
                    cutoff: true,
                }
            } else {
                let (i, j) = PAIRS[p - 3];
                Plane {
                    n: mohr(i, j, sin_phi),
                    a: self.stiff(mohr(i, j, sin_psi)),
                    k,
                    cutoff: false,
                }
            }
        })
    }

    /// The return to the cut pyramid (module docs) of trial strains `εᵗʳ` whose pyramid
    /// return breaks the cutoff `σ_t`.
    fn cutoff_return(&self, eps: [T; 3], cutoff: T) -> ([T; 3], Region) {
        let trial = self.trial(eps);
        let real = self.real();
        let real_trial = real.trial(eps.map(|e| e.re()));
        let real_planes = real.planes(cutoff.re());
        let scale = real_trial.iter().fold(0.0f64, |m, t| m.max(t.abs()))
            + real_planes[3].k.abs()
            + cutoff.re().abs();
        // A stress is inside a plane to 1e-10 of the stress scale (round-off of the solves).
        let inside =
            |tau: &[f64; 3]| (real_planes.iter()).all(|p| dot(&p.n, tau) - p.k <= 1e-10 * scale);
        let mut chosen = None;
        'sets: for size in 1..=3 {
            for set in active_sets(size) {
                if set.iter().all(|&p| !real_planes[p].cutoff) {
                    continue;
                }
                if let Some((tau, dgamma)) = solve_set(&real_planes, &set, &real_trial)
                    && dgamma.iter().all(|&g| g >= -1e-14)
                    && inside(&tau)
                {
                    chosen = Some(set);
                    break 'sets;
                }
            }
        }
        let Some(set) = chosen else {
            return ([cutoff; 3], Region::Tension);
        };
        let region = if set.iter().all(|&p| real_planes[p].cutoff) {
            Region::Tension
        } else {
            Region::Corner
        };
        match solve_set(&self.planes(cutoff), &set, &trial) {
            Some((tau, _)) => (tau, region),
            None => ([cutoff; 3], Region::Tension),
        }
    }

    /// The return of trial principal strains to the pyramid alone (no cutoff).
    fn pyramid_return(&self, eps: [T; 3]) -> ([T; 3], Region) {
        let trial = self.trial(eps);
        // Sorted descending on real parts: τ₁ ≥ τ₂ ≥ τ₃.
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| trial[b].re().total_cmp(&trial[a].re()));
        let s: [T; 3] = std::array::from_fn(|k| trial[order[k]]);
        let (sin_phi, sin_psi) = (self.friction_angle.sin(), self.dilation_angle.sin());
        let two_c_cos = self.cohesion * T::cst(2.0) * self.friction_angle.cos();
        let one = T::one();
        let plane = |i: usize, j: usize, sin: T| -> [T; 3] {
            // ∂/∂τ of (τ_i − τ_j) + (τ_i + τ_j) sin θ.
            let mut n = [T::zero(); 3];
            n[i] = one + sin;
            n[j] = sin - one;
            n
        };
        let f_of = |i: usize, j: usize| (s[i] - s[j]) + (s[i] + s[j]) * sin_phi - two_c_cos;
        let f_main = f_of(0, 2);
        if f_main.re() <= 0.0 {
            return (trial, Region::Elastic);
        }
        let stiff = |n: [T; 3]| self.stiff(n);
        let dot = |a: [T; 3], b: [T; 3]| dot(&a, &b);
        let ordered = |t: &[T; 3]| t[0].re() >= t[1].re() && t[1].re() >= t[2].re();
        let unsort = |t: [T; 3]| {
            let mut out = [T::zero(); 3];
            for k in 0..3 {
                out[order[k]] = t[k];
            }
            out
        };
        let n1 = plane(0, 2, sin_phi);
        let a1 = stiff(plane(0, 2, sin_psi));
        let dgamma = f_main / dot(n1, a1);
        let main: [T; 3] = std::array::from_fn(|i| s[i] - a1[i] * dgamma);
        if ordered(&main) {
            return (unsort(main), Region::Shear);
        }
        // Edge: τ₁ = τ₂ (compression) when the main return overshot τ₂ above τ₁, else τ₂ = τ₃.
        let compression = main[1].re() > main[0].re();
        let (n2, a2, f2) = if compression {
            (
                plane(1, 2, sin_phi),
                stiff(plane(1, 2, sin_psi)),
                f_of(1, 2),
            )
        } else {
            (
                plane(0, 1, sin_phi),
                stiff(plane(0, 1, sin_psi)),
                f_of(0, 1),
            )
        };
        let (m11, m12, m21, m22) = (dot(n1, a1), dot(n1, a2), dot(n2, a1), dot(n2, a2));
        let det = m11 * m22 - m12 * m21;
        let g1 = (f_main * m22 - m12 * f2) / det;
        let g2 = (m11 * f2 - m21 * f_main) / det;
        let edge: [T; 3] = std::array::from_fn(|i| s[i] - a1[i] * g1 - a2[i] * g2);
        // The edge makes two stresses equal (up to round-off, so only the third is compared).
        let edge_ordered = if compression {
            edge[1].re() >= edge[2].re()
        } else {
            edge[0].re() >= edge[1].re()
        };
        if g1.re() >= 0.0 && g2.re() >= 0.0 && edge_ordered {
            return (unsort(edge), Region::Edge);
        }
        let apex = self.apex();
        ([apex; 3], Region::Apex)
    }

    /// One step of the return mapping from the relative deformation gradient `ΔF` and the
    /// state at the start of the step: the Kirchhoff stress, the new state and the region.
    /// Pure; with dual `ΔF` its derivative is the consistent tangent.
    pub fn return_map(
        &self,
        delta_f: &Matrix3<T>,
        state: &MaterialState<T>,
    ) -> (Matrix3<T>, MaterialState<T>, Region) {
        let (tau, b_e, tag) = trial_return(self, delta_f, state);
        let plastic_strain = if tag.region == Region::Elastic {
            state.plastic_strain
        } else {
            state.plastic_strain + tag.plastic * T::cst(2.0 / 3.0).sqrt()
        };
        let state = MaterialState {
            plastic_strain,
            tensor: b_e,
            hardening: state.hardening,
        };
        (tau, state, tag.region)
    }

    /// The explicit stress update: `σ = τ / det F` with `τ` from [`MohrCoulomb::return_map`]
    /// on `kin.delta_f`; commits the new state and returns the region taken.
    pub fn update_region(
        &self,
        kin: &Kinematics<'_, T>,
        state: &mut MaterialState<T>,
    ) -> (Matrix3<T>, Region) {
        let (tau, new_state, region) = self.return_map(kin.delta_f, state);
        *state = new_state;
        (tau / det::<T, 3>(kin.f), region)
    }

    /// Elastic stored energy per unit reference volume, `ψ = μ εₑ:εₑ + ½λ (tr εₑ)²` with
    /// `εₑ = ½ ln bₑ`.
    pub fn stored_energy(&self, state: &MaterialState<T>) -> T {
        self.lame
            .energy(&(symmetric_fn(&state.tensor, &Log) * T::cst(0.5)))
    }
}

impl MohrCoulomb<f64> {
    /// The same parameters as constants of another scalar type (zero derivative parts).
    pub fn lift<T: Scalar>(&self) -> MohrCoulomb<T> {
        MohrCoulomb {
            lame: self.lame.lift(),
            friction_angle: T::cst(self.friction_angle),
            dilation_angle: T::cst(self.dilation_angle),
            cohesion: T::cst(self.cohesion),
            tension_cutoff: self.tension_cutoff.map(T::cst),
        }
    }
}

/// `a·b` of principal triples.
fn dot<T: Scalar>(a: &[T; 3], b: &[T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The sets of `size` plane indices `i < j < l` out of [`PLANES`], in lexicographic order.
fn active_sets(size: usize) -> Vec<Vec<usize>> {
    let mut out = Vec::new();
    let mut set = Vec::with_capacity(size);
    fn grow(from: usize, size: usize, set: &mut Vec<usize>, out: &mut Vec<Vec<usize>>) {
        if set.len() == size {
            out.push(set.clone());
            return;
        }
        for p in from..PLANES {
            set.push(p);
            grow(p + 1, size, set, out);
            set.pop();
        }
    }
    grow(0, size, &mut set, &mut out);
    out
}

/// The return onto the planes `set` (all active): `Σ_b (N_a·A_b) Δγ_b = N_a·τᵗʳ − k_a`,
/// `τ = τᵗʳ − Σ Δγ_b A_b`, solved by Cramer's rule (at most 3 × 3); `None` when the system
/// is singular (planes that do not meet in a point, line or plane of their own).
fn solve_set<T: Scalar>(
    planes: &[Plane<T>; PLANES],
    set: &[usize],
    trial: &[T; 3],
) -> Option<([T; 3], Vec<T>)> {
    let n = set.len();
    let m = |a: usize, b: usize| dot(&planes[set[a]].n, &planes[set[b]].a);
    let rhs: Vec<T> = (set.iter())
        .map(|&p| dot(&planes[p].n, trial) - planes[p].k)
        .collect();
    let det3 = |c: [[T; 3]; 3]| {
        c[0][0] * (c[1][1] * c[2][2] - c[1][2] * c[2][1])
            - c[0][1] * (c[1][0] * c[2][2] - c[1][2] * c[2][0])
            + c[0][2] * (c[1][0] * c[2][1] - c[1][1] * c[2][0])
    };
    // The matrix padded to 3 × 3 with the identity, and its columns replaced by the rhs.
    let matrix = |column: Option<usize>| -> [[T; 3]; 3] {
        std::array::from_fn(|a| {
            std::array::from_fn(|b| {
                if a >= n || b >= n {
                    if a == b { T::one() } else { T::zero() }
                } else if Some(b) == column {
                    rhs[a]
                } else {
                    m(a, b)
                }
            })
        })
    };
    let det = det3(matrix(None));
    let size = (0..n)
        .flat_map(|a| (0..n).map(move |b| (a, b)))
        .fold(0.0f64, |s, (a, b)| s.max(m(a, b).re().abs()));
    if det.re().abs() <= 1e-12 * size.powi(n as i32) {
        return None;
    }
    let dgamma: Vec<T> = (0..n).map(|b| det3(matrix(Some(b))) / det).collect();
    let mut tau = *trial;
    for (g, &p) in dgamma.iter().zip(set) {
        for i in 0..3 {
            tau[i] -= *g * planes[p].a[i];
        }
    }
    Some((tau, dgamma))
}

impl<T: Scalar> Constitutive<T> for MohrCoulomb<T> {
    /// `σ = τ / det F` with `τ` from [`MohrCoulomb::return_map`]; commits the new state.
    fn update(&self, kin: &Kinematics<'_, T>, state: &mut MaterialState<T>) -> Matrix3<T> {
        self.update_region(kin, state).0
    }

    /// `λ + 2μ`: the elastic constrained modulus bounds the wave speed.
    fn p_wave_modulus(&self) -> f64 {
        self.lame.p_wave_modulus().re()
    }
}

fn max3<T: Scalar>(t: [T; 3]) -> T {
    let mut m = t[0];
    for x in &t[1..] {
        if x.re() > m.re() {
            m = *x;
        }
    }
    m
}

fn min3<T: Scalar>(t: [T; 3]) -> T {
    let mut m = t[0];
    for x in &t[1..] {
        if x.re() < m.re() {
            m = *x;
        }
    }
    m
}
