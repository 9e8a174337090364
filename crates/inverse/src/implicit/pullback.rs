//! One particle's converged sub-step linearised, and the vector–Jacobian products of the
//! reverse pass by the chain rule through it.
//!
//! Of the maps in [`super::kernel::particle_step`] only two are not linear in their inputs:
//! the stencil `(xₚ, Fₚ) ↦ (N_i, ∇N_i)` (the cpGIMP half-width follows `Fₚ`) and the stress
//! update `C: (ΔF, Fₚ, hₚ) ↦ (S = V⁰τΔF⁻ᵀ, h')`. Each is differentiated once, by one
//! evaluation with a multi-lane dual, and kept as its Jacobian: `D + D²` lanes for the
//! stencil; for the stress update the fewest arguments its model reads, composed with their
//! own Jacobian by `(ΔF, Fₚ, hₚ)` into `J_C` (`D²` lanes, the entries of `F = ΔF Fₚ`, for
//! the hyperelastic models; 7 for J2, its trial `bₑ` and `ε̄ᵖ`; `2D² + 11`, all inputs
//! (`ΔF`, `Fₚ` and the [`HISTORY_LEN`] history components), for the soil models). For the scalar
//!
//! ```text
//! ψₚ = Σ_i (a_i·S∇N_i + c_i·q N_i) + x̄'·(xₚ + Σ_i N_i Δu_i) + F̄':(ΔF Fₚ) + h̄'·h' + m̄' mₚ
//! ```
//!
//! (`q = (mₚ g + f_load) λ`, the weights a [`Cotangent`]) the rest is closed form:
//!
//! ```text
//! S̄ = Σ_i a_i ⊗ ∇N_i,     (Ḡ_C, F̄_C, h̄_C) = J_Cᵀ (S̄, h̄'),     Ḡ = Ḡ_C + F̄' Fₚᵀ
//! ∂ψ/∂Δu_i = Ḡ ∇N_i + x̄' N_i
//! N̄_i = c_i·q + x̄'·Δu_i,     ∇N̄_i = Sᵀ a_i + Ḡᵀ Δu_i
//! x̄ = x̄' + Σ_i (N̄_i ∂N_i/∂x + ∇N̄_i·∂∇N_i/∂x)
//! F̄ = F̄_C + ΔFᵀ F̄' + Σ_i (N̄_i ∂N_i/∂F + ∇N̄_i·∂∇N_i/∂F)
//! h̄ = h̄_C (h̄' for a model without history),     m̄ = m̄' + λ Σ_i N_i c_i·g,     v̄ = v̄'
//! ```
//!
//! A Newmark sub-step adds its grid terms to `ψₚ` ([`super::inertia`]): their `N̄_i` join the
//! ones above, and they give `v̄` and a share of `m̄`.
//!
//! and the step's tangent is assembled from `A = ∂S/∂ΔF`, a block of `J_C`. A sub-step's
//! right-hand side, tangent, state adjoint and parameter shares all come from the one
//! linearisation per particle.

use super::inertia::InertiaWeights;
use super::kernel::{
    Loads, ParticleState, Setting, carries_history, mass_index, state_len, velocity_index,
};
use loam_core::constitutive::{HISTORY_LEN, MaterialState, Model};
use loam_core::stencil::particle_half_width;
use loam_core::tensor::{Tensor, Vector, det, from3, inverse, product, to3};
use loam_core::{Material, Shape, Stencil};
use loam_implicit::kernel::stress_update;
use nalgebra::{Matrix3, SVector};
use num_dual::{Derivative, Dual64, DualSVec64};

/// The weights of a particle's step outputs in `ψₚ` (module docs).
#[derive(Clone, Copy, Debug)]
pub struct Cotangent<'a, const D: usize> {
    /// `a_i` per grid node (flat index).
    pub internal: &'a [Vector<f64, D>],
    /// `c_i` per grid node.
    pub external: &'a [Vector<f64, D>],
    /// `(x̄', F̄', h̄', v̄', m̄')` of the end state, in the order of
    /// [`ParticleState::components`].
    pub end: &'a [f64],
    /// The weights of a Newmark sub-step's grid terms (`None`: quasi-static).
    pub inertia: Option<&'a InertiaWeights<'a, D>>,
}

/// The material table lifted to the multi-lane duals of the stress update's Jacobian.
pub struct LaneMaterials {
    real: Vec<Material<f64>>,
    lanes4: Vec<Material<DualSVec64<4>>>,
    lanes7: Vec<Material<DualSVec64<7>>>,
    lanes9: Vec<Material<DualSVec64<9>>>,
    lanes_all2: Vec<Material<DualSVec64<ALL_INPUTS_2D>>>,
    lanes_all3: Vec<Material<DualSVec64<ALL_INPUTS_3D>>>,
}

/// Lanes of every input of a plane-strain stress update ([`constitutive_inputs`]).
const ALL_INPUTS_2D: usize = constitutive_inputs(2, true);
/// Lanes of every input of a 3D stress update ([`constitutive_inputs`]).
const ALL_INPUTS_3D: usize = constitutive_inputs(3, true);

impl LaneMaterials {
    /// Lifts a real material table.
    pub fn new(real: &[Material<f64>]) -> Self {
        Self {
            lanes4: real.iter().map(|m| m.lift()).collect(),
            lanes7: real.iter().map(|m| m.lift()).collect(),
            lanes9: real.iter().map(|m| m.lift()).collect(),
            lanes_all2: real.iter().map(|m| m.lift()).collect(),
            lanes_all3: real.iter().map(|m| m.lift()).collect(),
            real: real.to_vec(),
        }
    }
}

/// One stencil node of a linearised particle.
#[derive(Clone, Copy, Debug)]
pub(super) struct Node<const D: usize> {
    /// Flat grid index.
    pub(super) flat: usize,
    /// `N_i(xₚ)`.
    pub(super) weight: f64,
    /// `∇N_i(xₚ)`.
    pub(super) gradient: Vector<f64, D>,
    /// `Δu_i`.
    pub(super) du: Vector<f64, D>,
}

/// Lanes of the stencil's derivative: `xₚ` (`D`), then `Fₚ` row by row (`D²`), the order of
/// the first `D + D²` components of [`ParticleState::components`].
pub(super) const fn geometry_lanes(d: usize) -> usize {
    d + d * d
}

/// Inputs of the stress update's Jacobian: `ΔF` and `Fₚ` row by row, then (with a history)
/// the history's components ([`MaterialState::components`]).
const fn constitutive_inputs(d: usize, history: bool) -> usize {
    2 * d * d + if history { HISTORY_LEN } else { 0 }
}

/// A particle's converged sub-step with the Jacobians of its stencil and of its stress
/// update (module docs).
#[derive(Clone, Debug)]
pub struct Linearisation<const D: usize> {
    nodes: Vec<Node<D>>,
    /// Per node: `∂N_i/∂(x, F)` ([`geometry_lanes`] values), then `∂(∇N_i)_b/∂(x, F)` for
    /// each `b`.
    geometry: Vec<f64>,
    delta_f: Tensor<f64, D>,
    f_n: Tensor<f64, D>,
    history: MaterialState<f64>,
    volume0: f64,
    /// `S = V⁰τΔF⁻ᵀ`.
    stress: Tensor<f64, D>,
    /// `J_C`: rows `S` row by row then (with a history) `h'`, columns
    /// [`constitutive_inputs`].
    jacobian: Vec<f64>,
    carries: bool,
    mass: f64,
    velocity: Vector<f64, D>,
    load_factor: f64,
    gravity_factor: f64,
    loads: Loads<f64, D>,
}

/// The `k`-th derivative lane of `v`.
fn lane<const L: usize>(v: &DualSVec64<L>, k: usize) -> f64 {
    v.eps.0.as_ref().map_or(0.0, |e| e[k])
}

/// `v` with lane `k` seeded.
fn seed<const L: usize>(v: f64, k: usize) -> DualSVec64<L> {
    let mut e = SVector::<f64, L>::zeros();
    e[k] = 1.0;
    DualSVec64::new(v, Derivative::some(e))
}

impl<const D: usize> Linearisation<D> {
    /// Linearises particle `state` of material `material` in the sub-step of `setting` with
    /// the converged increments `du(flat, a)`; `None` at an inverted state (`det ΔF ≤ 0`).
    pub fn new(
        setting: &Setting<'_, D>,
        materials: &LaneMaterials,
        material: usize,
        state: &ParticleState<f64, D>,
        loads: &Loads<f64, D>,
        du: impl Fn(usize, usize) -> f64,
    ) -> Option<Self> {
        let (nodes, geometry) = match D {
            2 => stencil_jacobian::<6, D>(setting, state, du),
            3 => stencil_jacobian::<12, D>(setting, state, du),
            _ => unreachable!("D is 2 or 3"),
        };
        let mut delta_f = Tensor::<f64, D>::identity();
        for n in &nodes {
            delta_f += n.du * n.gradient.transpose();
        }
        let carries = carries_history(&materials.real[material]);
        let inputs = (&delta_f, state, setting.volume0, carries);
        let model = &materials.real[material].model;
        let (stress, jacobian) = match (model, D) {
            (Model::J2(_), 2) => {
                j2_stress_jacobian::<ALL_INPUTS_2D, D>(&materials.lanes7[material], inputs)?
            }
            (Model::J2(_), _) => {
                j2_stress_jacobian::<ALL_INPUTS_3D, D>(&materials.lanes7[material], inputs)?
            }
            (Model::DruckerPrager(_) | Model::MohrCoulomb(_) | Model::ModifiedCamClay(_), 2) => {
                stress_jacobian::<ALL_INPUTS_2D, D>(&materials.lanes_all2[material], inputs)?
            }
            (Model::DruckerPrager(_) | Model::MohrCoulomb(_) | Model::ModifiedCamClay(_), _) => {
                stress_jacobian::<ALL_INPUTS_3D, D>(&materials.lanes_all3[material], inputs)?
            }
            (_, 2) => hyperelastic_stress_jacobian::<8, 4, D>(&materials.lanes4[material], inputs)?,
            _ => hyperelastic_stress_jacobian::<18, 9, D>(&materials.lanes9[material], inputs)?,
        };
        Some(Self {
            nodes,
            geometry,
            delta_f,
            f_n: state.f,
            history: state.history,
            volume0: setting.volume0,
            stress,
            jacobian,
            carries,
            mass: state.mass,
            velocity: state.v,
            load_factor: setting.load_factor,
            gravity_factor: setting.gravity_factor,
            loads: *loads,
        })
    }

    /// The stencil: `(flat index, N_i)` per node.
    pub fn weights(&self) -> Vec<(usize, f64)> {
        self.nodes.iter().map(|n| (n.flat, n.weight)).collect()
    }

    /// `A[c][d] = ∂S/∂ΔF_cd`, the particle's share of the step's tangent.
    pub fn tangent(&self) -> [[Tensor<f64, D>; D]; D] {
        let cols = constitutive_inputs(D, self.carries);
        std::array::from_fn(|c| {
            std::array::from_fn(|d| {
                Tensor::<f64, D>::from_fn(|a, b| self.jacobian[(a * D + b) * cols + c * D + d])
            })
        })
    }

    /// `S̄ = Σ_i a_i ⊗ ∇N_i`.
    fn stress_bar(&self, cot: &Cotangent<'_, D>) -> Tensor<f64, D> {
        let mut s = Tensor::<f64, D>::zeros();
        for n in &self.nodes {
            s += cot.internal[n.flat] * n.gradient.transpose();
        }
        s
    }

    /// `(Ḡ, F̄_C + ΔFᵀF̄', h̄)` (module docs).
    fn pull(&self, cot: &Cotangent<'_, D>) -> (Tensor<f64, D>, Tensor<f64, D>, [f64; HISTORY_LEN]) {
        let dd = D * D;
        let h0 = D + dd;
        let cols = constitutive_inputs(D, self.carries);
        let s_bar = self.stress_bar(cot);
        let mut input_bar = vec![0.0; cols];
        let s_rows = s_bar.transpose();
        let rows = s_rows.iter().copied().chain(
            cot.end[h0..h0 + HISTORY_LEN]
                .iter()
                .copied()
                .filter(|_| self.carries),
        );
        for (o, w) in rows.enumerate() {
            if w != 0.0 {
                let row = &self.jacobian[o * cols..(o + 1) * cols];
                input_bar.iter_mut().zip(row).for_each(|(x, j)| *x += w * j);
            }
        }
        let f_end = Tensor::<f64, D>::from_fn(|r, c| cot.end[D + r * D + c]);
        let g_bar =
            Tensor::<f64, D>::from_fn(|r, c| input_bar[r * D + c]) + f_end * self.f_n.transpose();
        let f_bar = Tensor::<f64, D>::from_fn(|r, c| input_bar[dd + r * D + c])
            + self.delta_f.transpose() * f_end;
        let source = if self.carries {
            &input_bar[2 * dd..]
        } else {
            &cot.end[h0..h0 + HISTORY_LEN]
        };
        (g_bar, f_bar, std::array::from_fn(|k| source[k]))
    }

    /// `∂ψₚ/∂Δu_i` per stencil node, as `(flat index, value)`.
    pub fn increments(&self, cot: &Cotangent<'_, D>) -> Vec<(usize, Vector<f64, D>)> {
        let (g_bar, _, _) = self.pull(cot);
        let x_end = Vector::<f64, D>::from_fn(|a, _| cot.end[a]);
        (self.nodes.iter())
            .map(|n| (n.flat, g_bar * n.gradient + x_end * n.weight))
            .collect()
    }

    /// `λ Σ_i N_i c_i`, the derivative of `ψₚ` by the point load on the particle.
    pub fn load_share(&self, cot: &Cotangent<'_, D>) -> Vector<f64, D> {
        self.external_share(cot) * self.load_factor
    }

    /// `λ_g Σ_i N_i c_i`, the derivative of `ψₚ` by gravity per unit mass of the particle
    /// (`λ_g` the factor on gravity: [`Setting::gravity_factor`]).
    pub fn gravity_share(&self, cot: &Cotangent<'_, D>) -> Vector<f64, D> {
        self.external_share(cot) * self.gravity_factor
    }

    /// `Σ_i N_i c_i`, the derivative of `ψₚ` by the particle's balancing force (it acts in
    /// full).
    pub fn balance_share(&self, cot: &Cotangent<'_, D>) -> Vector<f64, D> {
        self.external_share(cot)
    }

    /// `Σ_i N_i c_i`.
    fn external_share(&self, cot: &Cotangent<'_, D>) -> Vector<f64, D> {
        (self.nodes.iter())
            .map(|n| cot.external[n.flat] * n.weight)
            .sum()
    }

    /// `∂ψₚ/∂sₚ` in the order of [`ParticleState::components`].
    pub fn state_adjoint(&self, cot: &Cotangent<'_, D>) -> Vec<f64> {
        let (g_bar, f_bar, h_bar) = self.pull(cot);
        let geo = geometry_lanes(D);
        let h0 = D + D * D;
        let x_end = Vector::<f64, D>::from_fn(|a, _| cot.end[a]);
        let q = self.loads.gravity * (self.mass * self.gravity_factor)
            + self.loads.point * self.load_factor
            + self.loads.balance;
        let (vi, mi) = (velocity_index(D), mass_index(D));
        let v_end = Vector::<f64, D>::from_fn(|a, _| cot.end[vi + a]);
        let inertia =
            (cot.inertia).map(|w| w.pull(&self.weights(), self.mass, &self.velocity, &v_end));
        let mut out = vec![0.0; state_len(D)];
        out[..D].copy_from_slice(&cot.end[..D]);
        pull_geometry(&self.nodes, &self.geometry, &mut out[..geo], |k, n| {
            let a = cot.internal[n.flat];
            let n_bar = cot.external[n.flat].dot(&q)
                + x_end.dot(&n.du)
                + inertia.as_ref().map_or(0.0, |i| i.weights[k]);
            (
                n_bar,
                self.stress.transpose() * a + g_bar.transpose() * n.du,
            )
        });
        for r in 0..D {
            for c in 0..D {
                out[D + r * D + c] += f_bar[(r, c)];
            }
        }
        out[h0..h0 + HISTORY_LEN].copy_from_slice(&h_bar);
        let (v_bar, m_dyn) = inertia.map_or((v_end, 0.0), |i| (i.velocity, i.mass));
        out[vi..vi + D].copy_from_slice(v_bar.as_slice());
        out[mi] = cot.end[mi] + self.gravity_share(cot).dot(&self.loads.gravity) + m_dyn;
        out
    }

    /// `∂ψₚ/∂θ` for a material constant `θ` seeded in `material`: `S̄:∂S/∂θ + h̄'·∂h'/∂θ`
    /// by one `Dual64` evaluation of the stress update.
    pub fn material_share(
        &self,
        material: &Material<Dual64>,
        cot: &Cotangent<'_, D>,
    ) -> Option<f64> {
        let (s, _, h) = stress_update(
            material,
            &self.f_n.map(Dual64::from_re),
            &self.history.lift(),
            Dual64::from_re(self.volume0),
            &self.delta_f.map(Dual64::from_re),
        )?;
        let h0 = D + D * D;
        let h_end = &cot.end[h0..h0 + HISTORY_LEN];
        let through_stress = self.stress_bar(cot).dot(&s.map(|v| v.eps));
        let history = h.components();
        Some(
            through_stress
                + history
                    .iter()
                    .zip(h_end)
                    .map(|(v, w)| v.eps * w)
                    .sum::<f64>(),
        )
    }
}

/// The stencil of `state` with its derivatives by `(x, F)` ([`geometry_lanes`] `= L` of
/// them), and the increments `du` on its nodes. Only cpGIMP's half-width follows `F`
/// ([`particle_half_width`]): its stencil is evaluated with all `L` lanes seeded, every other
/// shape's with the `D` lanes of `x` alone (a dual's cost grows with its lanes), the
/// derivatives by `F` then zero.
pub(super) fn stencil_jacobian<const L: usize, const D: usize>(
    setting: &Setting<'_, D>,
    state: &ParticleState<f64, D>,
    du: impl Fn(usize, usize) -> f64,
) -> (Vec<Node<D>>, Vec<f64>) {
    if setting.shape == Shape::Cpgimp {
        stencil_lanes::<L, L, D>(setting, state, du)
    } else {
        stencil_lanes::<D, L, D>(setting, state, du)
    }
}

/// [`stencil_jacobian`] from one evaluation with the first `K` of its `L` lanes seeded
/// (`K = D`: `x` alone).
fn stencil_lanes<const K: usize, const L: usize, const D: usize>(
    setting: &Setting<'_, D>,
    state: &ParticleState<f64, D>,
    du: impl Fn(usize, usize) -> f64,
) -> (Vec<Node<D>>, Vec<f64>) {
    let grid = setting.grid;
    let seeded = |v: f64, k: usize| {
        if k < K {
            seed::<K>(v, k)
        } else {
            DualSVec64::from_re(v)
        }
    };
    let x = Vector::<DualSVec64<K>, D>::from_fn(|a, _| seeded(state.x[a], a));
    let f = Tensor::<DualSVec64<K>, D>::from_fn(|r, c| seeded(state.f[(r, c)], D + r * D + c));
    let hw0 = setting.half_width0.map(DualSVec64::from_re);
    let hw = particle_half_width(setting.shape, grid.h, &hw0, &f);
    let stencil = Stencil::new(setting.shape, grid, &x, &hw);
    let lanes = |v: &DualSVec64<K>| -> [f64; L] {
        std::array::from_fn(|k| if k < K { lane(v, k) } else { 0.0 })
    };
    let mut nodes = Vec::with_capacity(stencil.len());
    let mut geometry = Vec::with_capacity(stencil.len() * L * (1 + D));
    stencil.for_each(|n| {
        nodes.push(Node {
            flat: n.flat,
            weight: n.weight.re,
            gradient: n.gradient.map(|v| v.re),
            du: Vector::<f64, D>::from_fn(|a, _| du(n.flat, a)),
        });
        geometry.extend(lanes(&n.weight));
        for b in 0..D {
            geometry.extend(lanes(&n.gradient[b]));
        }
    });
    (nodes, geometry)
}

/// Adds `Σ_i (N̄_i ∂N_i/∂(x, F) + ∇N̄_i·∂∇N_i/∂(x, F))` to `out` (the partials by `(x, F)`,
/// [`geometry_lanes`] of them), with `(N̄_i, ∇N̄_i) = bars(i, node i)` and the stencil's
/// derivative `geometry` from [`stencil_jacobian`].
pub(super) fn pull_geometry<const D: usize>(
    nodes: &[Node<D>],
    geometry: &[f64],
    out: &mut [f64],
    mut bars: impl FnMut(usize, &Node<D>) -> (f64, Vector<f64, D>),
) {
    let geo = geometry_lanes(D);
    for (i, (n, dn)) in nodes
        .iter()
        .zip(geometry.chunks_exact(geo * (1 + D)))
        .enumerate()
    {
        let (n_bar, grad_bar) = bars(i, n);
        for (k, o) in out[..geo].iter_mut().enumerate() {
            *o += n_bar * dn[k]
                + (0..D)
                    .map(|b| grad_bar[b] * dn[(1 + b) * geo + k])
                    .sum::<f64>();
        }
    }
}

/// `S = V⁰τΔF⁻ᵀ` and `J_C` (rows `S` then, with a history, `h'`; columns
/// [`constitutive_inputs`]) from one stress update with `L` lanes; `None` at `det ΔF ≤ 0`.
fn stress_jacobian<const L: usize, const D: usize>(
    material: &Material<DualSVec64<L>>,
    (delta_f, state, volume0, carries): (&Tensor<f64, D>, &ParticleState<f64, D>, f64, bool),
) -> Option<(Tensor<f64, D>, Vec<f64>)> {
    let dd = D * D;
    let g = Tensor::<DualSVec64<L>, D>::from_fn(|r, c| seed(delta_f[(r, c)], r * D + c));
    let f = Tensor::<DualSVec64<L>, D>::from_fn(|r, c| seed(state.f[(r, c)], dd + r * D + c));
    let h = &state.history;
    let history = if carries {
        let c = h.components();
        MaterialState::from_components(|k| seed(c[k], 2 * dd + k))
    } else {
        h.lift()
    };
    let (s, _, h2) = stress_update(material, &f, &history, DualSVec64::from_re(volume0), &g)?;
    Some(jacobian_rows(&s, carries.then_some(&h2)))
}

/// `S` and `J_C` from the outputs of the stress update with `L` lanes ([`stress_jacobian`]):
/// rows `S` row by row, then the new history where it is carried.
fn jacobian_rows<const L: usize, const D: usize>(
    s: &Tensor<DualSVec64<L>, D>,
    history: Option<&MaterialState<DualSVec64<L>>>,
) -> (Tensor<f64, D>, Vec<f64>) {
    let cols = constitutive_inputs(D, history.is_some());
    let mut outputs: Vec<DualSVec64<L>> = s.transpose().iter().copied().collect();
    if let Some(h) = history {
        outputs.extend(h.components());
    }
    let mut jacobian = vec![0.0; outputs.len() * cols];
    for (row, v) in jacobian.chunks_exact_mut(cols).zip(&outputs) {
        if let Some(e) = v.eps.0.as_ref() {
            row.copy_from_slice(&e.as_slice()[..cols]);
        }
    }
    (s.map(|v| v.re), jacobian)
}

/// The independent components of a symmetric 3 × 3 matrix.
const SYMMETRIC: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];

/// [`stress_jacobian`] for [`J2`](loam_core::constitutive::J2), whose update reads `ΔF` and
/// `bₑ` only through the trial state `bₑᵗʳ = sym(ΔF bₑ ΔFᵀ)`: its return mapping is
/// differentiated by `(bₑᵗʳ, ε̄ᵖ)` alone (7 lanes, at `ΔF = I` with `bₑ = bₑᵗʳ`, the same
/// trial state), and that Jacobian composed with the trial state's `L` lanes.
fn j2_stress_jacobian<const L: usize, const D: usize>(
    material: &Material<DualSVec64<7>>,
    (delta_f, state, volume0, _): (&Tensor<f64, D>, &ParticleState<f64, D>, f64, bool),
) -> Option<(Tensor<f64, D>, Vec<f64>)> {
    let dd = D * D;
    let h = &state.history;
    let g = Tensor::<DualSVec64<L>, D>::from_fn(|r, c| seed(delta_f[(r, c)], r * D + c));
    let g3 = to3(&g, DualSVec64::from_re(1.0));
    let be = Matrix3::from_fn(|r, c| seed::<L>(h.tensor[(r, c)], 2 * dd + 1 + r * 3 + c));
    let b = product(&product(&g3, &be), &g3.transpose());
    let trial = (b + b.transpose()) * DualSVec64::from_re(0.5);
    let arguments: [DualSVec64<L>; 7] = std::array::from_fn(|k| match SYMMETRIC.get(k) {
        Some(&(r, c)) => trial[(r, c)],
        None => seed(h.plastic_strain, 2 * dd),
    });
    let component = |r: usize, c: usize| {
        (SYMMETRIC.iter())
            .position(|&rc| rc == (r.min(c), r.max(c)))
            .expect("every entry has a component")
    };
    let identity = Matrix3::<DualSVec64<7>>::identity();
    let (s, mut jacobian) = composed_jacobian(&g, volume0, &arguments, |z| {
        let inner = MaterialState {
            plastic_strain: z[6],
            tensor: Matrix3::from_fn(|r, c| z[component(r, c)]),
            hardening: DualSVec64::from_re(h.hardening),
        };
        let (tau, history) = material.kirchhoff_update(&identity, &identity, &inner);
        (tau, Some(history))
    })?;
    // J2 passes the history's hardening scalar (the last of `MaterialState::components`)
    // through unread: `∂h'_k/∂h_k = 1` for that component, outside the 7 lanes.
    let k = HISTORY_LEN - 1;
    jacobian[(dd + k) * L + 2 * dd + k] = 1.0;
    Some((s, jacobian))
}

/// [`stress_jacobian`] for a hyperelastic model, whose `τ` reads the total `F = ΔF Fⁿ` only:
/// `τ` is differentiated by the `M = D²` entries of `F` and composed with the `L` lanes of
/// `(ΔF, Fⁿ)`.
fn hyperelastic_stress_jacobian<const L: usize, const M: usize, const D: usize>(
    material: &Material<DualSVec64<M>>,
    (delta_f, state, volume0, _): (&Tensor<f64, D>, &ParticleState<f64, D>, f64, bool),
) -> Option<(Tensor<f64, D>, Vec<f64>)> {
    let dd = D * D;
    let g = Tensor::<DualSVec64<L>, D>::from_fn(|r, c| seed(delta_f[(r, c)], r * D + c));
    let f_n = Tensor::<DualSVec64<L>, D>::from_fn(|r, c| seed(state.f[(r, c)], dd + r * D + c));
    let f = product(&g, &f_n);
    let arguments: [DualSVec64<L>; M] = std::array::from_fn(|k| f[(k / D, k % D)]);
    let history = state.history.lift();
    composed_jacobian(&g, volume0, &arguments, |z| {
        let f3 = to3(
            &Tensor::<_, D>::from_fn(|r, c| z[r * D + c]),
            DualSVec64::from_re(1.0),
        );
        (material.kirchhoff_update(&f3, &f3, &history).0, None)
    })
}

/// `S = V⁰ τ ΔF⁻ᵀ` and the Jacobian of [`jacobian_rows`] for an update `(τ, h') = update(z)`
/// of `M` arguments `z = arguments` (functions of the `L` input lanes): `update` is evaluated
/// once with `M` lanes, and its Jacobian composed with that of `arguments`; `None` at
/// `det ΔF ≤ 0`.
fn composed_jacobian<const L: usize, const M: usize, const D: usize>(
    g: &Tensor<DualSVec64<L>, D>,
    volume0: f64,
    arguments: &[DualSVec64<L>; M],
    update: impl Fn(
        &[DualSVec64<M>; M],
    ) -> (Matrix3<DualSVec64<M>>, Option<MaterialState<DualSVec64<M>>>),
) -> Option<(Tensor<f64, D>, Vec<f64>)> {
    if det(&g.map(|v| v.re)) <= 0.0 {
        return None;
    }
    let z: [DualSVec64<M>; M] = std::array::from_fn(|k| seed(arguments[k].re, k));
    let (tau, history) = update(&z);
    // v with ∂v/∂z carried through to the `L` lanes of the inputs.
    let compose = |v: DualSVec64<M>| {
        let mut e = SVector::<f64, L>::zeros();
        for (k, a) in arguments.iter().enumerate() {
            if let Some(da) = a.eps.0.as_ref() {
                e += da * lane(&v, k);
            }
        }
        DualSVec64::<L>::new(v.re, Derivative::some(e))
    };
    let tau = tau.map(compose);
    let history = history.map(|h| h.map(compose));
    let s = product(&from3::<_, D>(&tau), &inverse(g)?.transpose()) * DualSVec64::from_re(volume0);
    Some(jacobian_rows(&s, history.as_ref()))
}

#[cfg(test)]
mod tests {
    use super::super::kernel::{lift_loads, particle_step};
    use super::*;
    use loam_core::Scalar;
    use loam_core::constitutive::{Hencky, J2, Lame};
    use loam_core::{Grid, Shape};

    /// `ψₚ` (module docs) of a particle's step in scalar `T`.
    fn psi<T: Scalar>(
        step: &super::super::kernel::ParticleStep<T, 2>,
        cot: &Cotangent<'_, 2>,
    ) -> T {
        let mut psi = T::zero();
        for n in &step.nodes {
            for a in 0..2 {
                psi += n.internal[a] * T::cst(cot.internal[n.flat][a])
                    + n.external[a] * T::cst(cot.external[n.flat][a]);
            }
        }
        let e = &step.end;
        let f = e.f.transpose();
        let values = (e.x.iter().copied())
            .chain(f.iter().copied())
            .chain(e.history.components())
            .chain(e.v.iter().copied())
            .chain(std::iter::once(e.mass));
        for (v, w) in values.zip(cot.end) {
            psi += v * T::cst(*w);
        }
        psi
    }

    /// The largest `|a − b|` relative to the largest `|b|`.
    fn relative(a: &[f64], b: &[f64]) -> f64 {
        let scale = b.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        a.iter()
            .zip(b)
            .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()))
            / scale
    }

    /// Every product of a linearised J2 particle (cpGIMP, yielding in the step, a plastic
    /// history at its start) against `Dual64` evaluations of `ψₚ` through the generic kernel,
    /// one seeded input at a time (the constants: E and σ_y).
    #[test]
    fn j2_chain_rule_matches_dual_evaluations() {
        let j2 = |e: Dual64, sy: Dual64| Material {
            density: Dual64::from_re(2000.0),
            model: Model::J2(J2 {
                lame: Lame::from_young_poisson(e, Dual64::from_re(0.3)),
                yield_stress: sy,
                hardening: Dual64::from_re(2e4),
            }),
        };
        let real = Material {
            density: 2000.0,
            model: Model::J2(J2 {
                lame: Lame::from_young_poisson(1e6, 0.3),
                yield_stress: 1e3,
                hardening: 2e4,
            }),
        };
        check_against_duals(real, (1e6, 1e3), j2);
    }

    /// As [`j2_chain_rule_matches_dual_evaluations`] for a Hencky particle (the constants: E
    /// and ν).
    #[test]
    fn hencky_chain_rule_matches_dual_evaluations() {
        let hencky = |e: Dual64, nu: Dual64| Material {
            density: Dual64::from_re(2000.0),
            model: Model::Hencky(Hencky {
                lame: Lame::from_young_poisson(e, nu),
            }),
        };
        let real = Material {
            density: 2000.0,
            model: Model::Hencky(Hencky {
                lame: Lame::from_young_poisson(1e6, 0.3),
            }),
        };
        check_against_duals(real, (1e6, 0.3), hencky);
    }

    /// The stencil's derivative by `(x, F)` with `x`'s lanes alone seeded is the one with
    /// every lane seeded for each shape whose half-width does not follow `F` (every entry
    /// the same to the bit: the lanes do not mix), and cpGIMP's, which follows `F`, has
    /// derivatives by `F` that the `x` lanes alone would drop.
    #[test]
    fn only_cpgimp_stencils_are_differentiated_by_f() {
        let grid = Grid::<2>::new([0.0, 0.0], [8, 8], 0.25, 2);
        let state = ParticleState {
            x: Vector::<f64, 2>::new(1.03, 0.97),
            f: Tensor::<f64, 2>::new(1.4, 0.1, -0.05, 0.9),
            history: MaterialState::default(),
            v: Vector::<f64, 2>::zeros(),
            mass: 1.0,
        };
        let du = |flat: usize, a: usize| 1e-3 * (flat + a) as f64;
        for shape in Shape::ALL {
            let setting = Setting {
                grid: &grid,
                shape,
                half_width0: Vector::<f64, 2>::new(0.0625, 0.0625),
                volume0: 0.0039,
                load_factor: 1.0,
                gravity_factor: 1.0,
            };
            let (nodes, geometry) = stencil_jacobian::<6, 2>(&setting, &state, du);
            let (all_nodes, all) = stencil_lanes::<6, 6, 2>(&setting, &state, du);
            let by_f = all
                .chunks(6)
                .map(|c| c[2..].iter().fold(0.0_f64, |m, v| m.max(v.abs())));
            let by_f = by_f.fold(0.0_f64, f64::max);
            assert_eq!(nodes.len(), all_nodes.len());
            if shape == Shape::Cpgimp {
                assert!(by_f > 1e-3, "cpGIMP's stencil follows F: {by_f:e}");
            } else {
                assert_eq!(by_f, 0.0, "{shape:?}");
            }
            assert_eq!(geometry, all, "{shape:?}");
        }
    }

    /// The products of [`Linearisation`] for material `real` against `Dual64` evaluations;
    /// `seeded(a, b)` is the material with its two constants `(a, b)` (real values `values`).
    /// Both are exact derivatives; they differ by the rounding of different operation orders,
    /// far below 1e-10 of the largest entry.
    fn check_against_duals(
        real: Material<f64>,
        values: (f64, f64),
        seeded: impl Fn(Dual64, Dual64) -> Material<Dual64>,
    ) {
        let grid = Grid::<2>::new([0.0, 0.0], [8, 8], 0.25, 2);
        let plain = seeded(Dual64::from_re(values.0), Dual64::from_re(values.1));
        let setting = Setting {
            grid: &grid,
            shape: Shape::Cpgimp,
            half_width0: Vector::<f64, 2>::new(0.0625, 0.0625),
            volume0: 0.0039,
            load_factor: 0.6,
            // Gravity in full (a prestressed scene) while the point load ramps.
            gravity_factor: 1.0,
        };
        let state = ParticleState {
            x: Vector::<f64, 2>::new(1.03, 0.97),
            f: Tensor::<f64, 2>::new(1.02, 0.01, -0.015, 0.98),
            history: MaterialState {
                plastic_strain: 0.01,
                tensor: Matrix3::new(1.01, 0.005, 0.0, 0.005, 0.99, 0.0, 0.0, 0.0, 1.0),
                hardening: 0.0,
            },
            v: Vector::<f64, 2>::new(0.3, -1.2),
            mass: 7.8,
        };
        let loads = Loads {
            gravity: Vector::<f64, 2>::new(0.0, -9.81),
            point: Vector::<f64, 2>::new(3.0, -2.0),
            balance: Vector::<f64, 2>::new(-0.4, 1.7),
        };
        let du = |f: usize, a: usize| 0.004 * (0.7 * f as f64 + a as f64).sin();
        let nodes = grid.num_nodes();
        let internal: Vec<_> = (0..nodes)
            .map(|f| Vector::<f64, 2>::new((1.3 * f as f64).sin(), (0.9 * f as f64).cos()))
            .collect();
        let external: Vec<_> = (0..nodes)
            .map(|f| Vector::<f64, 2>::new((0.4 * f as f64).cos(), (1.1 * f as f64).sin()))
            .collect();
        let end: Vec<f64> = (0..state_len(2))
            .map(|k| 0.1 * (k as f64 + 1.0).sin())
            .collect();
        let cot = Cotangent {
            internal: &internal,
            external: &external,
            end: &end,
            inertia: None,
        };
        let step = particle_step(&setting, &real, &state, &loads, du).expect("not inverted");
        if matches!(real.model, Model::J2(_)) {
            assert!(
                step.end.history.plastic_strain > state.history.plastic_strain,
                "it yields"
            );
        }
        let lin = Linearisation::new(
            &setting,
            &LaneMaterials::new(&[real]),
            0,
            &state,
            &loads,
            du,
        )
        .expect("not inverted");
        let plain_du = |f: usize, a: usize| Dual64::from_re(du(f, a));
        let dual = |m: &Material<Dual64>,
                    s: &ParticleState<Dual64, 2>,
                    l: &Loads<Dual64, 2>,
                    d: &dyn Fn(usize, usize) -> Dual64| {
            psi(
                &particle_step(&setting, m, s, l, d).expect("not inverted"),
                &cot,
            )
            .eps
        };
        let constant = state.dual(&vec![0.0; state_len(2)]);
        let lifted = lift_loads(&loads);

        let (mut found, mut expected) = (Vec::new(), Vec::new());
        for (flat, g) in lin.increments(&cot) {
            for a in 0..2 {
                let seeded = |f: usize, b: usize| {
                    Dual64::new(du(f, b), if (f, b) == (flat, a) { 1.0 } else { 0.0 })
                };
                found.push(g[a]);
                expected.push(dual(&plain, &constant, &lifted, &seeded));
            }
        }
        assert!(
            relative(&found, &expected) < 1e-10,
            "increments {found:?} vs {expected:?}"
        );

        let found = lin.state_adjoint(&cot);
        let expected: Vec<f64> = (0..state_len(2))
            .map(|k| {
                let mut t = vec![0.0; state_len(2)];
                t[k] = 1.0;
                dual(&plain, &state.dual(&t), &lifted, &plain_du)
            })
            .collect();
        assert!(
            relative(&found, &expected) < 1e-10,
            "state {found:?} vs {expected:?}"
        );

        let materials = [
            seeded(Dual64::new(values.0, 1.0), Dual64::from_re(values.1)),
            seeded(Dual64::from_re(values.0), Dual64::new(values.1, 1.0)),
        ];
        let found: Vec<f64> = (materials.iter())
            .map(|m| lin.material_share(m, &cot).expect("not inverted"))
            .collect();
        let expected: Vec<f64> = (materials.iter())
            .map(|m| dual(m, &constant, &lifted, &plain_du))
            .collect();
        assert!(
            relative(&found, &expected) < 1e-10,
            "materials {found:?} vs {expected:?}"
        );

        let found: Vec<f64> = lin.load_share(&cot).iter().copied().collect();
        let expected: Vec<f64> = (0..2)
            .map(|a| {
                let mut l = lifted;
                l.point[a].eps = 1.0;
                dual(&plain, &constant, &l, &plain_du)
            })
            .collect();
        assert!(
            relative(&found, &expected) < 1e-10,
            "loads {found:?} vs {expected:?}"
        );

        // A = ∂S/∂ΔF against the stress update with one entry of ΔF seeded.
        let a = lin.tangent();
        let (mut found, mut expected) = (Vec::new(), Vec::new());
        for c in 0..2 {
            for d in 0..2 {
                let g = Tensor::<Dual64, 2>::from_fn(|r, k| {
                    Dual64::new(
                        lin.delta_f[(r, k)],
                        if (r, k) == (c, d) { 1.0 } else { 0.0 },
                    )
                });
                let (s, _, _) = stress_update(
                    &plain,
                    &constant.f,
                    &constant.history,
                    Dual64::from_re(0.0039),
                    &g,
                )
                .expect("not inverted");
                found.extend(a[c][d].iter().copied());
                expected.extend(s.iter().map(|v| v.eps));
            }
        }
        assert!(
            relative(&found, &expected) < 1e-10,
            "tangent {found:?} vs {expected:?}"
        );
    }
}
