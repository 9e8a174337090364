//! Shape functions: linear hat, uGIMP / cpGIMP, quadratic and cubic B-splines.
//!
//! Every shape function is a tensor product of 1D functions `N(ξ)` of the distance
//! `ξ = (x − x_i)/h` in cell units. [`ShapeFunction::weights_1d`] returns the `b` non-zero 1D
//! weights and their derivatives for one axis; [`crate::stencil::Stencil`] forms the `b^D`
//! products `w_ip = Π_a N(ξ_a)` and `∂w_ip/∂x_a = N'(ξ_a)/h · Π_{c≠a} N(ξ_c)`.

use crate::scalar::{Scalar, c};
use serde::{Deserialize, Serialize};

/// The widest support among loam's shape functions (cubic B-spline, b = 4).
pub const MAX_SUPPORT: usize = 4;

/// 1D weights on one axis: node `base + k` has weight `w[k]` and derivative `dw[k]`
/// (per unit length) for `k < b`.
#[derive(Clone, Copy, Debug)]
pub struct Weights1D<T> {
    /// Index (in grid nodes) of the first node of the support.
    pub base: isize,
    /// Weights `N(ξ_k)`.
    pub w: [T; MAX_SUPPORT],
    /// Derivatives `dN/dx = N'(ξ_k)/h`.
    pub dw: [T; MAX_SUPPORT],
}

/// A 1D shape-function family; the `D`-dimensional function is its tensor product.
pub trait ShapeFunction {
    /// Number of nodes `b` per axis in the support of a particle; the stencil has `b^D` nodes.
    fn support_width(&self) -> usize;

    /// Weights and derivatives on one axis for a particle at grid coordinate `xi = (x − x_0)/h`
    /// (cell units from node 0). `half_width` is the particle half-length in cell units (only
    /// the GIMP family uses it). `inv_h = 1/h` scales derivatives to physical units.
    fn weights_1d<T: Scalar>(&self, xi: T, half_width: T, inv_h: T) -> Weights1D<T>;
}

/// The shape-function families loam offers; one enum so scenes can choose at run time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shape {
    /// Linear hat `N(ξ) = 1 − |ξ|` (b = 2).
    Linear,
    /// Uniform GIMP: the hat convolved with a particle box of fixed half-length `l_p` (b = 3).
    Ugimp,
    /// Contiguous-particle GIMP: as uGIMP with `l_p` stretched by the fibre stretch `‖F e_a‖` (b = 3).
    Cpgimp,
    /// Quadratic B-spline (b = 3).
    QuadraticBspline,
    /// Cubic B-spline (b = 4).
    CubicBspline,
}

impl Shape {
    /// All families, for tests and listings.
    pub const ALL: [Shape; 5] = [
        Shape::Linear,
        Shape::Ugimp,
        Shape::Cpgimp,
        Shape::QuadraticBspline,
        Shape::CubicBspline,
    ];

    /// `true` for the GIMP family (the weights depend on the particle size).
    pub fn is_gimp(self) -> bool {
        matches!(self, Shape::Ugimp | Shape::Cpgimp)
    }

    /// Ghost cells needed outside a wall so that the support of a particle inside the domain
    /// stays on the grid.
    pub fn ghost_cells(self) -> usize {
        match self {
            Shape::Linear => 1,
            _ => 2,
        }
    }

    /// Index of the first node of the support of a particle at grid coordinate
    /// `xi = (x − x_0)/h`; the same as [`ShapeFunction::weights_1d`]'s `base`, without the
    /// weights (for sorting particles by their stencil).
    #[inline]
    pub fn first_node<T: Scalar>(self, xi: T) -> isize {
        match self {
            Shape::Linear => floor_index(xi),
            Shape::Ugimp | Shape::Cpgimp => floor_index(xi + c(0.5)) - 1,
            Shape::QuadraticBspline => floor_index(xi - c(0.5)),
            Shape::CubicBspline => floor_index(xi) - 1,
        }
    }

    /// The APIC inertia-like tensor `D_p = Σ_i w_ip (x_i − x_p)(x_i − x_p)ᵀ` is `κ h² I` for
    /// B-splines (κ = 1/4 quadratic, 1/3 cubic); returns `1/κ`. For the hat and GIMP `D_p`
    /// depends on the particle position (and vanishes for the hat on a node), so APIC uses the
    /// gradient form `C_p = Σ_i v_i ∇w_ipᵀ` there and this returns `None`.
    pub fn apic_inverse_inertia(self) -> Option<f64> {
        match self {
            Shape::QuadraticBspline => Some(4.0),
            Shape::CubicBspline => Some(3.0),
            _ => None,
        }
    }
}

impl ShapeFunction for Shape {
    fn support_width(&self) -> usize {
        match self {
            Shape::Linear => 2,
            Shape::Ugimp | Shape::Cpgimp | Shape::QuadraticBspline => 3,
            Shape::CubicBspline => 4,
        }
    }

    #[inline(always)]
    fn weights_1d<T: Scalar>(&self, xi: T, half_width: T, inv_h: T) -> Weights1D<T> {
        match self {
            Shape::Linear => linear(xi, inv_h),
            Shape::Ugimp | Shape::Cpgimp => gimp(xi, half_width, inv_h),
            Shape::QuadraticBspline => quadratic(xi, inv_h),
            Shape::CubicBspline => cubic(xi, inv_h),
        }
    }
}

/// `⌊x⌋` (of the real part) as an index: the same value as `x.re().floor() as isize` (NaN gives
/// 0, infinities saturate) without a call into libm, which baseline x86-64 makes for `floor`.
#[inline(always)]
fn floor_index<T: Scalar>(x: T) -> isize {
    let x = x.re();
    let t = x as isize;
    if (t as f64) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// Hat: `N = 1 − |ξ|` on the two nodes of the cell that holds the particle.
#[inline(always)]
fn linear<T: Scalar>(xi: T, inv_h: T) -> Weights1D<T> {
    let base = Shape::Linear.first_node(xi);
    let f = xi - c::<T>(base as f64);
    let z = T::zero();
    Weights1D {
        base,
        w: [T::one() - f, f, z, z],
        dw: [-inv_h, inv_h, z, z],
    }
}

/// Quadratic B-spline on the nodes `base..base+3`, `base = ⌊ξ − ½⌋`, `f = ξ − base ∈ [½, 3/2)`:
/// `N₀ = ½(3/2 − f)²`, `N₁ = 3/4 − (f − 1)²`, `N₂ = ½(f − ½)²`.
#[inline(always)]
fn quadratic<T: Scalar>(xi: T, inv_h: T) -> Weights1D<T> {
    let base = Shape::QuadraticBspline.first_node(xi);
    let f = xi - c::<T>(base as f64);
    let (a, m, p) = (c::<T>(1.5) - f, f - T::one(), f - c(0.5));
    let z = T::zero();
    Weights1D {
        base,
        w: [
            c::<T>(0.5) * a * a,
            c::<T>(0.75) - m * m,
            c::<T>(0.5) * p * p,
            z,
        ],
        dw: [-a * inv_h, c::<T>(-2.0) * m * inv_h, p * inv_h, z],
    }
}

/// Cubic B-spline on `base..base+4`, `base = ⌊ξ⌋ − 1`:
/// `N(r) = ½|r|³ − r² + 2/3` for `|r| < 1`, `(2 − |r|)³/6` for `1 ≤ |r| < 2`.
#[inline(always)]
fn cubic<T: Scalar>(xi: T, inv_h: T) -> Weights1D<T> {
    let base = Shape::CubicBspline.first_node(xi);
    let f = xi - c::<T>(base as f64); // ∈ [1, 2)
    let outer = |r: T| {
        // 1 ≤ r < 2 (r ≥ 0): N = (2 − r)³/6, dN/dr = −(2 − r)²/2
        let s = c::<T>(2.0) - r;
        (s * s * s / c(6.0), -s * s * c(0.5))
    };
    let inner = |r: T| {
        // 0 ≤ r < 1: N = ½r³ − r² + 2/3, dN/dr = 3/2 r² − 2r
        (
            c::<T>(0.5) * r * r * r - r * r + c(2.0 / 3.0),
            c::<T>(1.5) * r * r - c::<T>(2.0) * r,
        )
    };
    // signed distances ξ − x_k: f, f−1 (≥ 0) and f−2, f−3 (< 0); N' is odd in r.
    let (w0, d0) = outer(f);
    let (w1, d1) = inner(f - T::one());
    let (w2, d2) = inner(c::<T>(2.0) - f);
    let (w3, d3) = outer(c::<T>(3.0) - f);
    Weights1D {
        base,
        w: [w0, w1, w2, w3],
        dw: [d0 * inv_h, d1 * inv_h, -d2 * inv_h, -d3 * inv_h],
    }
}

/// GIMP: the hat averaged over a particle of half-length `l ≤ ½` (cell units). With
/// `r = ξ − ξ_i`:
/// `S = 1 − (r² + l²)/(2l)` for `|r| < l`; `1 − |r|` for `l ≤ |r| < 1 − l`;
/// `(1 + l − |r|)²/(4l)` for `1 − l ≤ |r| < 1 + l`; 0 beyond.
#[inline(always)]
fn gimp<T: Scalar>(xi: T, l: T, inv_h: T) -> Weights1D<T> {
    let base = Shape::Ugimp.first_node(xi);
    let mut w = [T::zero(); MAX_SUPPORT];
    let mut dw = [T::zero(); MAX_SUPPORT];
    let (lr, one) = (l.re(), T::one());
    for k in 0..3 {
        let r = xi - c::<T>((base + k as isize) as f64);
        let (ar, sgn) = if r.re() >= 0.0 { (r, one) } else { (-r, -one) };
        let a = ar.re();
        let (s, ds) = if a < lr {
            (one - (r * r + l * l) / (c::<T>(2.0) * l), -r / l)
        } else if a < 1.0 - lr {
            (one - ar, -sgn)
        } else if a < 1.0 + lr {
            let q = one + l - ar;
            (q * q / (c::<T>(4.0) * l), -sgn * q / (c::<T>(2.0) * l))
        } else {
            (T::zero(), T::zero())
        };
        w[k] = s;
        dw[k] = ds * inv_h;
    }
    Weights1D { base, w, dw }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_index_matches_floor_as_isize() {
        let xs = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            2.0,
            -2.0,
            2.999_999_999_999_999_6,
            -1e-300,
            1e300,
            -1e300,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            9.2e18,
            -9.2e18,
        ];
        for x in xs {
            assert_eq!(floor_index(x), x.floor() as isize, "x = {x}");
        }
    }

    /// Central difference of the 1D weights; the functions are C¹ (hat and GIMP: C⁰, so the
    /// sample points avoid their kinks), so the step-size error is O(ε²) ≈ 1e-12.
    #[test]
    fn one_d_derivatives_match_finite_differences() {
        let eps = 1e-6;
        for shape in Shape::ALL {
            for &xi in &[3.13, 3.37, 3.71, 3.9, 4.55] {
                let l = 0.25;
                let wm = shape.weights_1d::<f64>(xi - eps, l, 1.0);
                let wp = shape.weights_1d::<f64>(xi + eps, l, 1.0);
                let w = shape.weights_1d::<f64>(xi, l, 1.0);
                assert_eq!(
                    wm.base, wp.base,
                    "{shape:?} at {xi}: sample too close to a knot"
                );
                for k in 0..shape.support_width() {
                    let fd = (wp.w[k] - wm.w[k]) / (2.0 * eps);
                    assert!(
                        (fd - w.dw[k]).abs() < 1e-8,
                        "{shape:?} ξ={xi} k={k}: fd {fd} vs {}",
                        w.dw[k]
                    );
                }
            }
        }
    }
}
