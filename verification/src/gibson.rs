//! Gibson's one-dimensional finite-strain consolidation, solved by finite volumes: the
//! reference of `consolidation-large`.
//!
//! A weightless column of initial height `H₀` between slip walls, on a fixed base that drains
//! (a porous stone), carries a compressive total stress `q` on its impermeable top from
//! `t = 0` (applied undrained). The skeleton is Neo-Hookean, the constituents incompressible,
//! and the Darcy flux is `−κ ∂p/∂y` in the current configuration with a constant mobility `κ`
//! (loam's coupled formulation, `loam_implicit::flow`).
//!
//! With the Lagrangian coordinate `X ∈ [0, H₀]` (initial height above the base), the current
//! height `y(X, t)`, the stretch `λ = ∂y/∂X` (= `J`: the sides do not move) and Lamé's
//! first parameter `Λ`:
//!
//! ```text
//! skeleton:     σ′(λ) = [μ (λ² − 1) + Λ ln λ] / λ     (Cauchy σ′_yy = τ′_yy/J)
//! equilibrium:  σ′(λ) − p = −q                        ⇒  p = q + σ′(λ)
//! water:        ∂λ/∂t = ∂/∂X( (κ/λ) ∂p/∂X )           (the flux −κ ∂p/∂y, ∂y = λ ∂X)
//! ```
//!
//! so `∂λ/∂t = ∂/∂X( (κ/λ) σ′_λ(λ) ∂λ/∂X )`, a nonlinear diffusion, with `λ = 1` at `t = 0⁺`
//! (undrained: `p = q`), `p = 0` at the base (`σ′(λ_base) = −q`) and no flux through the top.
//! The settlement of the material point at `X` is `X − ∫₀^X λ dX′`; the final stretch `λ_∞`
//! solves `σ′(λ_∞) = −q`, and the final settlement of the top is `H₀ (1 − λ_∞)`. The equations
//! are unchanged by `X → H₀ − X`: the top settles as that of a column drained at its top over
//! an impermeable base. For `q` small against the constrained modulus `M = 2μ + Λ`, `1 − λ` is
//! Terzaghi's strain and the diffusivity `κ M`: Terzaghi's theory.
//!
//! **Discretisation.** `λ` is constant over each of `N` equal cells of the reference column;
//! the flux through a face is `κ m (p_b − p_a)/ΔX`, with `m` the mean of `1/λ` on either side
//! (the drained base is half a cell from the first centre, at `λ_∞`, `p = 0`). The scheme
//! conserves the water: the settlement of the top changes by the flux through the base alone.
//! In time, TR-BDF2 (the trapezoidal rule to `t + γΔt`, then BDF2 to `t + Δt`, `γ = 2 − √2`),
//! second order and L-stable, so that the jump of `λ` at the base at `t = 0⁺` does not ring;
//! Newton on each stage's tridiagonal system. The steps grow geometrically from a small first
//! step (consolidation slows as `√t`) and are cut to land on the output times.

/// The column and its load (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gibson {
    /// Initial height `H₀` (m).
    pub height: f64,
    /// Compressive total stress on the top `q` (Pa).
    pub load: f64,
    /// Mobility `κ = k/γ_w` (m²/(Pa·s)).
    pub mobility: f64,
    /// Shear modulus `μ` of the Neo-Hookean skeleton (Pa).
    pub shear_modulus: f64,
    /// Lamé's first parameter `Λ` of the skeleton (Pa).
    pub lame: f64,
}

/// The resolution of a solve: cells over the column, the first time step and the steps'
/// growth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Resolution {
    /// Cells over `H₀`.
    pub cells: usize,
    /// The first step, in `T_v` (`c_v t/H₀²` with the small-strain `c_v = κ M`).
    pub first_step: f64,
    /// Each step is `growth` times the last (cut to land on the output times).
    pub growth: f64,
}

impl Resolution {
    /// The resolution of the case's reference: 800 cells, a first step of `ΔT_v = 10⁻⁶`
    /// growing by 1 % a step (1,000 steps to `T_v = 2`). Twice the cells, half the first
    /// step and half the growth rate change the settlements at `T_v = 0.1 … 2` by less than
    /// 1e-6 of their value (`tests::converged`).
    pub const CONVERGED: Self = Self {
        cells: 800,
        first_step: 1e-6,
        growth: 1.01,
    };
}

/// The stretch over the column at one time.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    /// `λ` of each cell, from the base up.
    pub stretch: Vec<f64>,
    /// The column it belongs to.
    column: Gibson,
}

impl Profile {
    /// Cell size `ΔX` (m).
    fn cell(&self) -> f64 {
        self.column.height / self.stretch.len() as f64
    }

    /// The settlement of the material point at initial height `x` (m), `x − ∫₀^x λ dX`.
    pub fn settlement(&self, x: f64) -> f64 {
        let h = self.cell();
        let full = ((x / h).floor() as usize).min(self.stretch.len());
        let below: f64 = self.stretch[..full].iter().sum::<f64>() * h;
        let part = self
            .stretch
            .get(full)
            .map_or(0.0, |s| s * (x - full as f64 * h));
        x - below - part
    }

    /// The excess pore pressure `p = q + σ′(λ)` at initial height `x` (Pa): linear from
    /// `p = 0` at the drained base to the first cell's centre and between the centres,
    /// constant above the last centre (no flux through the top).
    pub fn pressure(&self, x: f64) -> f64 {
        let n = self.stretch.len();
        let at = |i: usize| self.column.load + self.column.stress(self.stretch[i]).0;
        // Position in cells from the first centre, at -½ on the base.
        let u = (x / self.cell() - 0.5).clamp(-0.5, (n - 1) as f64);
        if u < 0.0 {
            return at(0) * (1.0 + 2.0 * u);
        }
        let i = (u.floor() as usize).min(n - 1);
        let w = u - i as f64;
        at(i) * (1.0 - w) + if w > 0.0 { at(i + 1) * w } else { 0.0 }
    }
}

impl Gibson {
    /// Constrained modulus `M = 2μ + Λ` (Pa), the small-strain stiffness in one dimension.
    pub fn constrained_modulus(&self) -> f64 {
        2.0 * self.shear_modulus + self.lame
    }

    /// Small-strain `c_v = κ M` (m²/s).
    pub fn cv(&self) -> f64 {
        self.mobility * self.constrained_modulus()
    }

    /// The time (s) of `T_v = c_v t/H₀²`.
    pub fn time(&self, tv: f64) -> f64 {
        tv * self.height * self.height / self.cv()
    }

    /// The skeleton's vertical Cauchy stress `σ′(λ)` under uniaxial strain (tension
    /// positive, Pa) and its derivative `dσ′/dλ`.
    pub fn stress(&self, stretch: f64) -> (f64, f64) {
        let (mu, lame, s) = (self.shear_modulus, self.lame, stretch);
        let ln = s.ln();
        (
            mu * (s - 1.0 / s) + lame * ln / s,
            mu * (1.0 + 1.0 / (s * s)) + lame * (1.0 - ln) / (s * s),
        )
    }

    /// The final stretch `λ_∞`, `σ′(λ_∞) = −q` (bisection on `(0, 1]`, where `σ′` increases).
    pub fn final_stretch(&self) -> f64 {
        let (mut lo, mut hi) = (f64::MIN_POSITIVE, 1.0);
        while hi - lo > 1e-15 {
            let mid = 0.5 * (lo + hi);
            if self.stress(mid).0 < -self.load {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// `R(λ) = ∂/∂X((κ/λ) ∂p/∂X)` per cell and its tridiagonal Jacobian `(sub, diag, sup)`;
    /// `base` is `λ` at the drained base.
    fn rate(&self, stretch: &[f64], base: f64) -> (Vec<f64>, [Vec<f64>; 3]) {
        let n = stretch.len();
        let h = self.height / n as f64;
        let p: Vec<(f64, f64)> = stretch
            .iter()
            .map(|&s| {
                let (stress, slope) = self.stress(s);
                (self.load + stress, slope)
            })
            .collect();
        let mut rate = vec![0.0; n];
        let [mut sub, mut diag, mut sup] = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        // The flux `F = κ m (p_b − p_a)/distance` through the lower face of cell b, from cell
        // a = b − 1 or, under the first cell, from the drained base (`λ_base`, `p = 0`, half a
        // cell away); the top face is impermeable. `R_b −= F/ΔX`, `R_a += F/ΔX`.
        for b in 0..n {
            let (sa, pa, dpa, k) = match b.checked_sub(1) {
                Some(a) => (stretch[a], p[a].0, p[a].1, self.mobility / h),
                None => (base, 0.0, 0.0, 2.0 * self.mobility / h),
            };
            let (sb, pb, dpb) = (stretch[b], p[b].0, p[b].1);
            let m = 0.5 * (1.0 / sa + 1.0 / sb);
            let jump = pb - pa;
            let flux = k * m * jump / h;
            let d_a = k * (-0.5 / (sa * sa) * jump - m * dpa) / h;
            let d_b = k * (-0.5 / (sb * sb) * jump + m * dpb) / h;
            rate[b] -= flux;
            diag[b] -= d_b;
            if b > 0 {
                sub[b] -= d_a;
                rate[b - 1] += flux;
                diag[b - 1] += d_a;
                sup[b - 1] += d_b;
            }
        }
        (rate, [sub, diag, sup])
    }

    /// Solves `λ − c R(λ) = b` by Newton from `λ`.
    fn stage(&self, stretch: &mut [f64], c: f64, b: &[f64], base: f64) {
        for _ in 0..50 {
            let (rate, [sub, diag, sup]) = self.rate(stretch, base);
            let residual: Vec<f64> = (0..stretch.len())
                .map(|i| stretch[i] - c * rate[i] - b[i])
                .collect();
            let delta = thomas(
                &sub.iter().map(|v| -c * v).collect::<Vec<_>>(),
                &diag.iter().map(|v| 1.0 - c * v).collect::<Vec<_>>(),
                &sup.iter().map(|v| -c * v).collect::<Vec<_>>(),
                &residual,
            );
            let mut largest = 0.0f64;
            for (s, d) in stretch.iter_mut().zip(&delta) {
                *s -= d;
                largest = largest.max(d.abs());
            }
            if largest < 1e-14 {
                return;
            }
        }
        panic!("Newton did not converge in a TR-BDF2 stage");
    }

    /// The stretch over the column at each of `times` (s, increasing).
    pub fn solve(&self, times: &[f64], resolution: Resolution) -> Vec<Profile> {
        let gamma = 2.0 - 2f64.sqrt();
        let base = self.final_stretch();
        let mut stretch = vec![1.0; resolution.cells];
        let (mut t, mut dt) = (0.0, self.time(resolution.first_step));
        let mut profiles = Vec::with_capacity(times.len());
        for &target in times {
            while t < target {
                let step = dt.min(target - t);
                let old = stretch.clone();
                // Trapezoidal rule to t + γΔt.
                let c = 0.5 * gamma * step;
                let (rate, _) = self.rate(&old, base);
                let b: Vec<f64> = old.iter().zip(&rate).map(|(s, r)| s + c * r).collect();
                self.stage(&mut stretch, c, &b, base);
                // BDF2 from tⁿ and t + γΔt to t + Δt.
                let c = (1.0 - gamma) / (2.0 - gamma) * step;
                let b: Vec<f64> = stretch
                    .iter()
                    .zip(&old)
                    .map(|(s, o)| (s - (1.0 - gamma) * (1.0 - gamma) * o) / (gamma * (2.0 - gamma)))
                    .collect();
                self.stage(&mut stretch, c, &b, base);
                if step == dt {
                    dt *= resolution.growth;
                }
                t = if step == target - t { target } else { t + step };
            }
            profiles.push(Profile {
                stretch: stretch.clone(),
                column: *self,
            });
        }
        profiles
    }
}

/// Solves the tridiagonal system `(sub, diag, sup) x = rhs` (Thomas' algorithm; the systems
/// here are diagonally dominant).
fn thomas(sub: &[f64], diag: &[f64], sup: &[f64], rhs: &[f64]) -> Vec<f64> {
    let n = diag.len();
    let (mut c, mut d) = (vec![0.0; n], vec![0.0; n]);
    for i in 0..n {
        let below = if i > 0 { sub[i] } else { 0.0 };
        let (cp, dp) = if i > 0 {
            (c[i - 1], d[i - 1])
        } else {
            (0.0, 0.0)
        };
        let m = diag[i] - below * cp;
        c[i] = sup[i] / m;
        d[i] = (rhs[i] - below * dp) / m;
    }
    for i in (0..n.saturating_sub(1)).rev() {
        d[i] -= c[i] * d[i + 1];
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::terzaghi::{pressure_ratio, settlement_ratio};

    /// GeoWarp's large-consolidation column (E = 36 kPa, ν = 0.2, `κ = 1e-6 m²/(Pa·s)`,
    /// `H₀ = 10 m`) under `q`.
    fn column(load: f64) -> Gibson {
        let (e, nu) = (36e3, 0.2);
        Gibson {
            height: 10.0,
            load,
            mobility: 1e-6,
            shear_modulus: e / (2.0 * (1.0 + nu)),
            lame: e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
        }
    }

    /// The case's output times (`T_v`).
    const TIMES: [f64; 5] = [0.1, 0.2, 0.5, 1.0, 2.0];

    fn times(column: &Gibson, tv: &[f64]) -> Vec<f64> {
        tv.iter().map(|&t| column.time(t)).collect()
    }

    /// At `q/M = 1e-5` the strains are 1e-5: the top settles as Terzaghi's `U (q H/M)` and the
    /// pressure is his, up to terms of the order of `q/M` (the final settlement alone is
    /// `H (1 − λ_∞) = (q H/M)(1 − 0.75 q/M + …)` here) plus the discretisation's 4e-6:
    /// 1e-5 of the settlement, 1e-5 of `q` for the pressure.
    #[test]
    fn small_load_is_terzaghi() {
        let column = column(40e3 * 1e-5);
        let small = column.load / column.constrained_modulus() * column.height;
        let tv = [0.05, 0.1, 0.2, 0.5, 1.0, 2.0];
        let profiles = column.solve(&times(&column, &tv), Resolution::CONVERGED);
        for (profile, &tv) in profiles.iter().zip(&tv) {
            let u = profile.settlement(column.height) / small;
            assert!(
                (u / settlement_ratio(0.0, tv) - 1.0).abs() < 1e-5,
                "T_v = {tv}: U = {u}"
            );
            for x in [0.5, 2.0, 5.0, 8.0, 10.0] {
                let p = profile.pressure(x) / column.load;
                let exact = pressure_ratio(x / column.height, tv);
                assert!((p - exact).abs() < 1e-5, "T_v = {tv}, X = {x}: p/q = {p}");
            }
        }
    }

    /// Long after the loading (`T_v = 20`, the slowest mode left at `exp(−π²/4 · 20)` of its
    /// amplitude), the column is `λ_∞` throughout: `σ′(λ_∞) = −q`, the top settled by
    /// `H₀ (1 − λ_∞)` (up to round-off) and no excess pressure left.
    #[test]
    fn final_settlement() {
        let column = column(10e3);
        let stretch = column.final_stretch();
        assert!((column.stress(stretch).0 + column.load).abs() < 1e-9 * column.load);
        let profile = &column.solve(&times(&column, &[20.0]), Resolution::CONVERGED)[0];
        let s = profile.settlement(column.height);
        let exact = column.height * (1.0 - stretch);
        assert!((s / exact - 1.0).abs() < 1e-9, "{s} against {exact}");
        assert!(profile.pressure(column.height).abs() < 1e-9 * column.load);
    }

    /// [`Resolution::CONVERGED`] is converged: twice the cells, half the first step and half
    /// the growth rate change the settlement of the case's top row of particles (half a
    /// particle spacing, 0.1 m/12, below the top) at the case's times by less than 1e-5 of its
    /// value: 9.8e-7 at most, and 2.5e-7 when refined once more (second order).
    #[test]
    fn converged() {
        let column = column(10e3);
        let times = times(&column, &TIMES);
        let x = column.height - 0.1 / 12.0;
        let fine = Resolution {
            cells: 2 * Resolution::CONVERGED.cells,
            first_step: Resolution::CONVERGED.first_step / 2.0,
            growth: 1.0 + (Resolution::CONVERGED.growth - 1.0) / 2.0,
        };
        let coarse = column.solve(&times, Resolution::CONVERGED);
        for (c, f) in coarse.iter().zip(column.solve(&times, fine)) {
            let (c, f) = (c.settlement(x), f.settlement(x));
            assert!((c / f - 1.0).abs() < 1e-5, "{c} against {f}");
        }
    }
}
