//! Particle ↔ grid transfers: PIC, FLIP (blend) and APIC, generic over the scalar type.
//!
//! P2G (per particle, per stencil node `i`, weight `w_ip`, gradient `∇w_ip`):
//! - mass `m_i += w_ip m_p`;
//! - momentum `(m v)_i += w_ip m_p (v_p + C_p (x_i − x_p))` (`C_p = 0` for PIC / FLIP);
//! - internal force `f_i −= V_p σ_p ∇w_ip`, `V_p = J_p V_p⁰`.
//!
//! G2P gathers `v̄ = Σ w_ip v_i`, `L_p = Σ v_i ⊗ ∇w_ip` and, for APIC,
//! `C_p = D_p⁻¹-scaled Σ w_ip v_i (x_i − x_p)ᵀ` (B-splines, `D_p = κ h² I`) or `C_p = L_p`
//! (hat and GIMP, whose `D_p` is position dependent and may be singular); TPIC always takes
//! `C_p = L_p`.
//!
//! MLS-MPM (Hu et al. 2018) keeps the APIC transfers and replaces `∇w_ip` by its
//! moving-least-squares form `w_ip D_p⁻¹ (x_i − x_p)` in the internal force, and `L_p` by
//! `C_p`. The force then has the form of the affine term, and P2G adds both at once (see
//! [`mls_affine_momentum`]).

use crate::grid::Grid;
use crate::scalar::Scalar;
use crate::serde_form::name_or_table;
use crate::shape::Shape;
use crate::stencil::{Layout, Stencil};
use crate::tensor::{Tensor, Vector};
use serde::{Deserialize, Deserializer, Serialize};

/// The particle-velocity update scheme.
///
/// Written as its name, `"pic"`, `"apic"`, `"tpic"` or `"mls"`, or as a table tagged by
/// `type`, `{ type = "flip", alpha = 0.95 }` (FLIP needs the table); an unknown key is an
/// error. `Deserialize` is written by hand for that (see [`crate::serde_form`]); `Serialize`
/// writes the table.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Transfer {
    /// Particle-in-cell: `v_p = Σ w v_i` (dissipative, stable).
    Pic,
    /// FLIP/PIC blend: `v_p ← α (v_p + Σ w (v_i − v_iⁿ)) + (1 − α) Σ w v_i`.
    Flip {
        /// FLIP fraction `α ∈ [0, 1]` (0 = PIC, 1 = pure FLIP).
        alpha: f64,
    },
    /// Affine particle-in-cell (Jiang et al. 2015): PIC plus the affine matrix `C_p`,
    /// conserving linear and angular momentum.
    Apic,
    /// Taylor particle-in-cell (Nakamura et al. 2023): like APIC, but the particle carries the
    /// velocity gradient `C_p = L_p = Σ_i v_i ⊗ ∇w_ip` for every shape function, a first-order
    /// Taylor expansion of the grid velocity about the particle.
    Tpic,
    /// MLS-MPM (Hu et al. 2018): the APIC transfers with the moving-least-squares internal
    /// force `f_i = −V_p σ_p D_p⁻¹ (x_i − x_p) w_ip` and velocity gradient `L_p = C_p`
    /// (B-splines only, `D_p = κ h² I`). No shape-function gradient is evaluated, which makes
    /// it the cheapest affine transfer; it is the discretisation of JAX-MPM and Taichi's
    /// MLS-MPM.
    Mls,
}

/// The strict table form of [`Transfer`]: empty struct variants in place of the unit
/// variants, so that `deny_unknown_fields` rejects an extra key on every variant.
#[derive(Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
enum TransferTable {
    Pic {},
    Flip { alpha: f64 },
    Apic {},
    Tpic {},
    Mls {},
}

impl From<TransferTable> for Transfer {
    fn from(t: TransferTable) -> Self {
        match t {
            TransferTable::Pic {} => Self::Pic,
            TransferTable::Flip { alpha } => Self::Flip { alpha },
            TransferTable::Apic {} => Self::Apic,
            TransferTable::Tpic {} => Self::Tpic,
            TransferTable::Mls {} => Self::Mls,
        }
    }
}

impl<'de> Deserialize<'de> for Transfer {
    /// Reads the name (`"apic"`, the table `{ type = "apic" }`) or the table.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        name_or_table::<D, TransferTable>(d, "type").map(Self::from)
    }
}

impl Transfer {
    /// Whether P2G carries the affine term `C_p (x_i − x_p)`.
    pub fn is_affine(&self) -> bool {
        matches!(self, Transfer::Apic | Transfer::Tpic | Transfer::Mls)
    }

    /// Whether the internal force and the velocity gradient take the moving-least-squares
    /// form ([`Transfer::Mls`]).
    pub fn is_mls(&self) -> bool {
        matches!(self, Transfer::Mls)
    }

    /// Whether G2P needs the grid velocity at the start of the step.
    pub fn needs_old_grid_velocity(&self) -> bool {
        matches!(self, Transfer::Flip { .. })
    }
}

/// Adds one particle's mass, momentum and internal force contributions to the nodes of its
/// stencil: `add(&mut nodes[index], m_ip, p_ip, f_ip)` for every stencil node, `index` its
/// entry in an array of the given `layout` (see the module docs for the formulas).
/// `stress_volume = V_p σ_p` (the in-plane block in 2D); `affine` is `C_p` or `None`.
///
/// Evaluated row by row ([`Stencil::for_each_row`]): with `m v_p`, `m C_p` and `−V σ` formed
/// once, the parts of `m v_p + m C_p (x_i − x_p)` and `−V σ ∇w` along the axes above 0 once per
/// row, a node adds only its axis-0 terms. A row is one slice of `nodes`, so its `b` entries
/// are reached with a single bounds check.
#[inline(always)]
pub fn p2g<T: Scalar, const D: usize, X>(
    stencil: &Stencil<T, D>,
    layout: &Layout<D>,
    v: &Vector<T, D>,
    affine: Option<&Tensor<T, D>>,
    mass: T,
    stress_volume: &Tensor<T, D>,
    nodes: &mut [X],
    add: impl FnMut(&mut X, T, Vector<T, D>, Vector<T, D>),
) {
    let (l, sv) = (layout, stress_volume);
    match stencil.width() {
        2 => p2g_rows::<2, T, D, X>(stencil, l, v, affine, mass, sv, nodes, add),
        3 => p2g_rows::<3, T, D, X>(stencil, l, v, affine, mass, sv, nodes, add),
        _ => p2g_rows::<4, T, D, X>(stencil, l, v, affine, mass, sv, nodes, add),
    }
}

/// The `B` entries of `nodes` from `index` (one bounds check for a row of a stencil).
#[inline(always)]
fn row_mut<const B: usize, X>(nodes: &mut [X], index: usize) -> &mut [X; B] {
    (&mut nodes[index..index + B])
        .try_into()
        .expect("a stencil row has b nodes")
}

/// The `B` entries of `nodes` from `index`, read only.
#[inline(always)]
fn row_ref<const B: usize, X>(nodes: &[X], index: usize) -> &[X; B] {
    nodes[index..index + B]
        .try_into()
        .expect("a stencil row has b nodes")
}

/// [`p2g`] for stencils of width `B` (a constant, so the node loop of a row unrolls).
#[inline(always)]
fn p2g_rows<const B: usize, T: Scalar, const D: usize, X>(
    stencil: &Stencil<T, D>,
    layout: &Layout<D>,
    v: &Vector<T, D>,
    affine: Option<&Tensor<T, D>>,
    mass: T,
    stress_volume: &Tensor<T, D>,
    nodes: &mut [X],
    mut add: impl FnMut(&mut X, T, Vector<T, D>, Vector<T, D>),
) {
    let mv = v * mass;
    let mc = affine.map_or_else(Tensor::zeros, |c| c * mass);
    let nsv = -stress_volume;
    let (mc0, nsv0) = (mc.column(0).into_owned(), nsv.column(0).into_owned());
    let [w0, dw0, o0] = stencil.axis0();
    stencil.for_each_row(
        layout,
        #[inline(always)]
        |row| {
            let (mut p_row, mut f_row) = (mv, Vector::<T, D>::zeros());
            for c in 1..D {
                p_row += mc.column(c) * row.offset[c];
                f_row += nsv.column(c) * row.gradient[c];
            }
            let dst = row_mut::<B, X>(nodes, row.index);
            for i in 0..B {
                let w = w0[i] * row.weight;
                add(
                    &mut dst[i],
                    mass * w,
                    (p_row + mc0 * o0[i]) * w,
                    nsv0 * (dw0[i] * row.weight) + f_row * w0[i],
                );
            }
        },
    );
}

/// The momentum-only transfer: `add(&mut nodes[index], m_ip, p_ip)` for every stencil node,
/// `p_ip = w_ip (m_p v_p + A_p (x_i − x_p))` with the affine momentum `A_p` (`m_p C_p` for
/// APIC, zero for PIC, [`mls_affine_momentum`] for MLS-MPM); `index` as in [`p2g`], evaluated
/// row by row in the same way. MUSL's second P2G and the whole P2G of MLS-MPM.
#[inline(always)]
pub fn p2g_momentum<T: Scalar, const D: usize, X>(
    stencil: &Stencil<T, D>,
    layout: &Layout<D>,
    v: &Vector<T, D>,
    affine_momentum: &Tensor<T, D>,
    mass: T,
    nodes: &mut [X],
    add: impl FnMut(&mut X, T, Vector<T, D>),
) {
    let (l, n) = (layout, nodes);
    let a = affine_momentum;
    match stencil.width() {
        2 => p2g_momentum_rows::<2, T, D, X>(stencil, l, v, a, mass, n, add),
        3 => p2g_momentum_rows::<3, T, D, X>(stencil, l, v, a, mass, n, add),
        _ => p2g_momentum_rows::<4, T, D, X>(stencil, l, v, a, mass, n, add),
    }
}

/// The affine momentum of MLS-MPM's P2G, `A_p = m_p C_p − Δt V_p σ_p D_p⁻¹` with
/// `D_p⁻¹ = I/(κ h²)` (`inverse_inertia = 1/κ`, see [`Shape::apic_inverse_inertia`]): with it,
/// [`p2g_momentum`] adds `(m v)_i + Δt f_i` in one term, `f_i = −V_p σ_p D_p⁻¹ (x_i − x_p) w_ip`.
#[inline(always)]
pub fn mls_affine_momentum<T: Scalar, const D: usize>(
    mass: T,
    affine: &Tensor<T, D>,
    stress_volume: &Tensor<T, D>,
    dt: T,
    inverse_inertia: f64,
    h: f64,
) -> Tensor<T, D> {
    affine * mass - stress_volume * (dt * T::cst(inverse_inertia / (h * h)))
}

/// [`p2g_momentum`] for stencils of width `B`.
#[inline(always)]
fn p2g_momentum_rows<const B: usize, T: Scalar, const D: usize, X>(
    stencil: &Stencil<T, D>,
    layout: &Layout<D>,
    v: &Vector<T, D>,
    mc: &Tensor<T, D>,
    mass: T,
    nodes: &mut [X],
    mut add: impl FnMut(&mut X, T, Vector<T, D>),
) {
    let mv = v * mass;
    let mc0 = mc.column(0).into_owned();
    let [w0, _, o0] = stencil.axis0();
    stencil.for_each_row(
        layout,
        #[inline(always)]
        |row| {
            let mut p_row = mv;
            for c in 1..D {
                p_row += mc.column(c) * row.offset[c];
            }
            let dst = row_mut::<B, X>(nodes, row.index);
            for i in 0..B {
                let w = w0[i] * row.weight;
                add(&mut dst[i], mass * w, (p_row + mc0 * o0[i]) * w);
            }
        },
    );
}

/// What G2P gathers from the grid for one particle.
#[derive(Clone, Copy, Debug)]
pub struct Gathered<T: Scalar, const D: usize> {
    /// `Σ w_ip v_i` with the updated grid velocity.
    pub v: Vector<T, D>,
    /// `Σ w_ip (v_i − v_iⁿ)` (FLIP increment; zero unless requested).
    pub dv: Vector<T, D>,
    /// Velocity gradient `L_p = Σ v_i ⊗ ∇w_ip` (zero unless requested, see [`g2p`]).
    pub grad_v: Tensor<T, D>,
    /// APIC affine matrix `C_p` (zero unless requested).
    pub affine: Tensor<T, D>,
}

/// Gathers the grid velocity field at a particle. `velocity[index]` is the updated nodal
/// velocity of the node with entry `index` in `layout` and `old[index]` its velocity at the
/// start of the step (read by FLIP only; pass an empty slice otherwise). The velocity gradient
/// [`Gathered::grad_v`] is formed when `gradient` is set or when the affine matrix is the
/// gradient (TPIC, and APIC with the hat and GIMP); otherwise it is left zero.
///
/// Evaluated row by row ([`Stencil::for_each_row`]): a row sums `Σ_i N_i v_i`,
/// `Σ_i N_i o_i v_i` and `Σ_i N'_i v_i` over its nodes (axis-0 factors only) and multiplies
/// the sums by the row's factors once. A row is one slice of `velocity` (one bounds check).
#[inline(always)]
pub fn g2p<T: Scalar, const D: usize>(
    stencil: &Stencil<T, D>,
    layout: &Layout<D>,
    grid: &Grid<D>,
    shape: Shape,
    transfer: Transfer,
    gradient: bool,
    velocity: &[Vector<T, D>],
    old: &[Vector<T, D>],
) -> Gathered<T, D> {
    let (l, t, g) = (layout, transfer, gradient);
    match stencil.width() {
        2 => g2p_flags::<2, T, D>(stencil, l, grid, shape, t, g, velocity, old),
        3 => g2p_flags::<3, T, D>(stencil, l, grid, shape, t, g, velocity, old),
        _ => g2p_flags::<4, T, D>(stencil, l, grid, shape, t, g, velocity, old),
    }
}

/// [`g2p`] for stencils of width `B`: picks the kernel for the sums the transfer needs, so
/// that none of them is tested (or formed) node by node.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn g2p_flags<const B: usize, T: Scalar, const D: usize>(
    stencil: &Stencil<T, D>,
    layout: &Layout<D>,
    grid: &Grid<D>,
    shape: Shape,
    transfer: Transfer,
    gradient: bool,
    velocity: &[Vector<T, D>],
    old: &[Vector<T, D>],
) -> Gathered<T, D> {
    let flip = transfer.needs_old_grid_velocity();
    let apic_b = if matches!(transfer, Transfer::Apic | Transfer::Mls) {
        shape.apic_inverse_inertia()
    } else {
        None
    };
    let want_grad = gradient || (transfer.is_affine() && apic_b.is_none());
    let (st, l, t, v, o) = (stencil, layout, transfer, velocity, old);
    let k = apic_b.unwrap_or(0.0);
    // The APIC sum belongs to APIC and MLS-MPM, which never need the FLIP increment.
    match (apic_b.is_some(), want_grad, flip) {
        (true, false, _) => g2p_rows::<B, T, D, true, false, false>(st, l, grid, t, k, v, o),
        (true, true, _) => g2p_rows::<B, T, D, true, true, false>(st, l, grid, t, k, v, o),
        (false, true, false) => g2p_rows::<B, T, D, false, true, false>(st, l, grid, t, k, v, o),
        (false, false, false) => g2p_rows::<B, T, D, false, false, false>(st, l, grid, t, k, v, o),
        (false, true, true) => g2p_rows::<B, T, D, false, true, true>(st, l, grid, t, k, v, o),
        (false, false, true) => g2p_rows::<B, T, D, false, false, true>(st, l, grid, t, k, v, o),
    }
}

/// [`g2p`] for stencils of width `B`, with the APIC sum `Σ w v (x_i − x_p)ᵀ` (`APIC`, scaled
/// by `apic_b/h²`), the gradient sum `Σ v ∇wᵀ` (`GRAD`) and the FLIP increment (`FLIP`)
/// chosen at compile time.
#[inline(always)]
fn g2p_rows<
    const B: usize,
    T: Scalar,
    const D: usize,
    const APIC: bool,
    const GRAD: bool,
    const FLIP: bool,
>(
    stencil: &Stencil<T, D>,
    layout: &Layout<D>,
    grid: &Grid<D>,
    transfer: Transfer,
    apic_b: f64,
    velocity: &[Vector<T, D>],
    old: &[Vector<T, D>],
) -> Gathered<T, D> {
    let mut out = Gathered {
        v: Vector::zeros(),
        dv: Vector::zeros(),
        grad_v: Tensor::zeros(),
        affine: Tensor::zeros(),
    };
    let (flip, want_grad) = (FLIP, GRAD);
    let apic_b = APIC.then_some(apic_b);
    let [w0, dw0, o0] = stencil.axis0();
    stencil.for_each_row(
        layout,
        #[inline(always)]
        |row| {
            // Σ N v, Σ N o v, Σ N' v and Σ N (v − vⁿ) over the row.
            let (mut s, mut so, mut sd, mut sf) = (
                Vector::<T, D>::zeros(),
                Vector::<T, D>::zeros(),
                Vector::<T, D>::zeros(),
                Vector::<T, D>::zeros(),
            );
            let v_row = row_ref::<B, _>(velocity, row.index);
            let old_row = flip.then(|| row_ref::<B, _>(old, row.index));
            for i in 0..B {
                let vi = v_row[i];
                let nv = vi * w0[i];
                s += nv;
                if apic_b.is_some() {
                    so += nv * o0[i];
                }
                if want_grad {
                    sd += vi * dw0[i];
                }
                if let Some(old_row) = old_row {
                    sf += (vi - old_row[i]) * w0[i];
                }
            }
            // Column 0 of Σ w v (x_i − x_p)ᵀ and Σ v ∇wᵀ comes from the axis-0 sums, the
            // other columns from the row's factors (explicit loops: nalgebra's views and outer
            // products compile to more work here).
            for r in 0..D {
                let sw = s[r] * row.weight;
                out.v[r] += sw;
                if apic_b.is_some() {
                    out.affine[(r, 0)] += so[r] * row.weight;
                    for c in 1..D {
                        out.affine[(r, c)] += sw * row.offset[c];
                    }
                }
                if want_grad {
                    out.grad_v[(r, 0)] += sd[r] * row.weight;
                    for c in 1..D {
                        out.grad_v[(r, c)] += s[r] * row.gradient[c];
                    }
                }
                if flip {
                    out.dv[r] += sf[r] * row.weight;
                }
            }
        },
    );
    if transfer.is_affine() {
        out.affine = match apic_b {
            Some(k) => out.affine * T::cst(k / (grid.h * grid.h)),
            None => out.grad_v,
        };
    }
    out
}

impl Transfer {
    /// New particle velocity and affine matrix from the gathered grid field and the old
    /// particle velocity.
    #[inline]
    pub fn particle_velocity<T: Scalar, const D: usize>(
        &self,
        v_old: &Vector<T, D>,
        g: &Gathered<T, D>,
    ) -> (Vector<T, D>, Tensor<T, D>) {
        match *self {
            Transfer::Pic => (g.v, Tensor::zeros()),
            Transfer::Flip { alpha } => {
                let a = T::cst(alpha);
                ((v_old + g.dv) * a + g.v * (T::one() - a), Tensor::zeros())
            }
            Transfer::Apic | Transfer::Tpic | Transfer::Mls => (g.v, g.affine),
        }
    }
}

#[cfg(test)]
mod tests;
