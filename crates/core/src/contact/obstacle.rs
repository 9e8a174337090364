//! Rigid obstacles: analytic signed distances and normals of boxes and cylinders that may move
//! with a constant velocity.
//!
//! The shapes are plain `f64`. An obstacle's velocity and friction coefficient are scalars
//! `T`; since a moving obstacle's surface at time `t` is the shape's at `x − v_o t`, its normal
//! depends on the velocity, and [`Obstacle::normal`] carries that dependence into a dual run
//! (the node set of the contact layer, a branch, is decided on real parts).

use crate::scalar::Scalar;
use crate::tensor::Vector;

/// The shape of a rigid obstacle at time 0.
#[derive(Clone, Debug, PartialEq)]
pub enum ObstacleShape<const D: usize> {
    /// The axis-aligned box `lo ≤ x ≤ hi`.
    Box {
        /// Lower corner.
        lo: [f64; D],
        /// Upper corner (greater than `lo` on every axis).
        hi: [f64; D],
    },
    /// A circular cylinder of radius `radius` around the line through `centre` along the
    /// coordinate axis `axis`, of length `length` centred on `centre`:
    /// `|x − c|_⊥ ≤ r` and `|x_axis − c_axis| ≤ L/2`, where `|·|_⊥` omits the `axis`
    /// component. With `axis ≥ D` the axis is out of the plane and the cylinder is the disk
    /// `|x − c| ≤ r` (in 2D, plane strain: an infinitely long cylinder; `length` is unused).
    Cylinder {
        /// A point on the axis, the middle of the cylinder.
        centre: [f64; D],
        /// Radius, positive.
        radius: f64,
        /// Coordinate axis the cylinder's axis is parallel to; `≥ D` for a 2D disk.
        axis: usize,
        /// Length along the axis (ignored for a disk).
        length: f64,
    },
}

impl<const D: usize> ObstacleShape<D> {
    /// A disk `|x − c| ≤ r` (2D; in 3D it would be an infinitely long cylinder along z, so use
    /// [`ObstacleShape::cylinder`] there).
    pub fn disk(centre: [f64; D], radius: f64) -> Self {
        Self::Cylinder {
            centre,
            radius,
            axis: D,
            length: f64::INFINITY,
        }
    }

    /// A cylinder along the coordinate axis `axis` (`< D`) of the given length, centred on
    /// `centre`.
    pub fn cylinder(centre: [f64; D], radius: f64, axis: usize, length: f64) -> Self {
        Self::Cylinder {
            centre,
            radius,
            axis,
            length,
        }
    }

    /// The axis-aligned bounding box `(lo, hi)` at time 0.
    pub fn bounds(&self) -> ([f64; D], [f64; D]) {
        match self {
            Self::Box { lo, hi } => (*lo, *hi),
            Self::Cylinder {
                centre,
                radius,
                axis,
                length,
            } => {
                let reach = |a: usize| if a == *axis { 0.5 * length } else { *radius };
                (
                    std::array::from_fn(|a| centre[a] - reach(a)),
                    std::array::from_fn(|a| centre[a] + reach(a)),
                )
            }
        }
    }

    /// A length that characterises the shape's size: the smallest half-extent of a box, the
    /// radius (or half-length, if smaller) of a cylinder.
    pub fn size(&self) -> f64 {
        match self {
            Self::Box { lo, hi } => (0..D)
                .map(|a| 0.5 * (hi[a] - lo[a]))
                .fold(f64::INFINITY, f64::min),
            Self::Cylinder {
                radius,
                axis,
                length,
                ..
            } => {
                if *axis < D {
                    radius.min(0.5 * length)
                } else {
                    *radius
                }
            }
        }
    }

    /// Signed distance `φ(x)` to the surface (negative inside) and the outward unit normal
    /// `n = ∇φ`, for the shape at rest (time 0).
    ///
    /// Box with centre `c` and half-extents `e`: `q = |x − c| − e` per axis; outside,
    /// `φ = |max(q, 0)|` and `n = sign(x − c) ∘ max(q, 0)/φ`; inside, `φ = max_a q_a ≤ 0` and
    /// `n = sign(x_a − c_a) e_a` for the axis `a` of the nearest face (the lowest on a tie).
    /// Cylinder: the same construction in the two coordinates (radial distance `ρ = |x − c|_⊥`,
    /// `|x_axis − c_axis|`) with half-extents `(r, L/2)`. Where a normal is undefined (the
    /// centre of a box or on a cylinder's axis) a coordinate direction is returned.
    pub fn distance(&self, x: &[f64; D]) -> (f64, [f64; D]) {
        self.distance_at(x)
    }

    /// [`ObstacleShape::distance`] at a point of any scalar type: the branches (outside or
    /// inside, nearest face) are taken on the real parts, and the distance and the normal carry
    /// the derivative parts of `x` through the branch taken. A moving obstacle's geometry at
    /// time `t` is the shape's at `x − v_o t`, so with a dual `v_o` this is how the normal
    /// depends on the obstacle's velocity ([`Obstacle::normal`]).
    pub fn distance_at<T: Scalar>(&self, x: &[T; D]) -> (T, [T; D]) {
        // `max(q, 0)` with the branch on the real part.
        let positive = |q: T| if q.re() > 0.0 { q } else { T::zero() };
        match self {
            Self::Box { lo, hi } => {
                let mut q = [T::zero(); D];
                let mut sign = [0.0; D];
                for a in 0..D {
                    let c = 0.5 * (lo[a] + hi[a]);
                    let d = x[a] - T::cst(c);
                    sign[a] = if d.re() < 0.0 { -1.0 } else { 1.0 };
                    q[a] = d * T::cst(sign[a]) - T::cst(0.5 * (hi[a] - lo[a]));
                }
                if q.iter().any(|qa| qa.re() > 0.0) {
                    let out: [T; D] = std::array::from_fn(|a| positive(q[a]));
                    let phi = out.iter().fold(T::zero(), |s, &o| s + o * o).sqrt();
                    (phi, std::array::from_fn(|a| out[a] * T::cst(sign[a]) / phi))
                } else {
                    let mut k = 0;
                    for a in 1..D {
                        if q[a].re() > q[k].re() {
                            k = a;
                        }
                    }
                    let mut n = [T::zero(); D];
                    n[k] = T::cst(sign[k]);
                    (q[k], n)
                }
            }
            Self::Cylinder {
                centre,
                radius,
                axis,
                length,
            } => {
                let mut radial = [T::zero(); D];
                for a in (0..D).filter(|a| a != axis) {
                    radial[a] = x[a] - T::cst(centre[a]);
                }
                let rho = radial.iter().fold(T::zero(), |s, &r| s + r * r).sqrt();
                let r_hat: [T; D] = if rho.re() > 0.0 {
                    std::array::from_fn(|a| radial[a] / rho)
                } else {
                    // On the axis: any radial direction (the first axis that is not `axis`).
                    let first = if *axis == 0 { 1 } else { 0 };
                    std::array::from_fn(|a| if a == first { T::one() } else { T::zero() })
                };
                let q_r = rho - T::cst(*radius);
                let (q_z, s_z) = if *axis < D {
                    let d = x[*axis] - T::cst(centre[*axis]);
                    let s = if d.re() < 0.0 { -1.0 } else { 1.0 };
                    (d * T::cst(s) - T::cst(0.5 * length), s)
                } else {
                    (T::cst(f64::NEG_INFINITY), 0.0)
                };
                let e_z = |a: usize| T::cst(if a == *axis { s_z } else { 0.0 });
                if q_r.re() > 0.0 || q_z.re() > 0.0 {
                    let (or, oz) = (positive(q_r), positive(q_z));
                    let phi = (or * or + oz * oz).sqrt();
                    (
                        phi,
                        std::array::from_fn(|a| (or * r_hat[a] + oz * e_z(a)) / phi),
                    )
                } else if q_r.re() >= q_z.re() {
                    (q_r, r_hat)
                } else {
                    (q_z, std::array::from_fn(e_z))
                }
            }
        }
    }
}

/// A rigid obstacle: a shape moving with a constant velocity, `x(t) = x(0) + v t`, with a
/// Coulomb friction coefficient against the material.
#[derive(Clone, Debug, PartialEq)]
pub struct Obstacle<T: Scalar, const D: usize> {
    /// The shape at time 0.
    pub shape: ObstacleShape<D>,
    /// Constant velocity `v_o` (m/s); zero for a static obstacle. A `T`, so that the contact
    /// law is differentiable in it, through the relative velocity and through the normal of
    /// the surface that has moved by `v_o t` ([`Obstacle::normal`]).
    pub velocity: Vector<T, D>,
    /// Coulomb friction coefficient `μ ≥ 0` (0: frictionless).
    pub mu: T,
}

impl<T: Scalar, const D: usize> Obstacle<T, D> {
    /// A static obstacle.
    pub fn fixed(shape: ObstacleShape<D>, mu: T) -> Self {
        Self {
            shape,
            velocity: Vector::zeros(),
            mu,
        }
    }

    /// Signed distance `φ(x, t)` (negative inside) and outward normal at time `t`: the shape's
    /// at `x − v_o t`.
    #[inline]
    pub fn distance(&self, x: &[f64; D], time: f64) -> (f64, [f64; D]) {
        let x0: [f64; D] = std::array::from_fn(|a| x[a] - self.velocity[a].re() * time);
        self.shape.distance(&x0)
    }

    /// The outward normal at `x` and time `t` as a `T`, given `n_re`, its real part from
    /// [`Obstacle::distance`]: the shape's normal at `x − v_o t` with `v_o` a `T`, so that in a
    /// dual run it carries `∂n/∂v_o = −t ∂n/∂x` (for a disk, `−t (I − n nᵀ)/ρ`). With a
    /// constant velocity (every `f64` run, and a dual run not seeded on it) this is `n_re`.
    #[inline]
    pub fn normal(&self, x: &[f64; D], time: f64, n_re: &[f64; D]) -> [T; D] {
        if self.velocity.iter().all(Scalar::is_constant) {
            return n_re.map(T::cst);
        }
        let t = T::cst(time);
        let x0: [T; D] = std::array::from_fn(|a| T::cst(x[a]) - self.velocity[a] * t);
        self.shape.distance_at(&x0).1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &[f64], b: &[f64]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
    }

    #[test]
    fn box_distance_and_normals() {
        let b = ObstacleShape::<2>::Box {
            lo: [0.0, 0.0],
            hi: [2.0, 1.0],
        };
        // Outside a face, outside a corner, inside near the top face.
        let (d, n) = b.distance(&[3.0, 0.5]);
        assert!((d - 1.0).abs() < 1e-15 && close(&n, &[1.0, 0.0]));
        let (d, n) = b.distance(&[-3.0, -4.0]);
        assert!((d - 5.0).abs() < 1e-15 && close(&n, &[-0.6, -0.8]));
        let (d, n) = b.distance(&[1.5, 0.9]);
        assert!((d + 0.1).abs() < 1e-15 && close(&n, &[0.0, 1.0]));
        assert_eq!(b.bounds(), ([0.0, 0.0], [2.0, 1.0]));
        assert_eq!(b.size(), 0.5);
    }

    #[test]
    fn disk_and_cylinder_distance_and_normals() {
        let d2 = ObstacleShape::<2>::disk([1.0, 1.0], 0.5);
        let (d, n) = d2.distance(&[1.0, 2.0]);
        assert!((d - 0.5).abs() < 1e-15 && close(&n, &[0.0, 1.0]));
        let (d, n) = d2.distance(&[1.3, 1.4]);
        assert!((d - 0.0).abs() < 1e-15 && close(&n, &[0.6, 0.8]));
        assert_eq!(d2.bounds(), ([0.5, 0.5], [1.5, 1.5]));
        // Cylinder along y from y = 0 to y = 2, radius 1, centred at (0, 1, 0).
        let c = ObstacleShape::<3>::cylinder([0.0, 1.0, 0.0], 1.0, 1, 2.0);
        let (d, n) = c.distance(&[0.0, 1.5, 2.0]);
        assert!((d - 1.0).abs() < 1e-15 && close(&n, &[0.0, 0.0, 1.0]));
        let (d, n) = c.distance(&[0.0, 3.0, 0.0]);
        assert!((d - 1.0).abs() < 1e-15 && close(&n, &[0.0, 1.0, 0.0]));
        // Beyond the rim: distance to the circle edge.
        let (d, n) = c.distance(&[4.0, 6.0, 0.0]);
        assert!((d - 5.0).abs() < 1e-15 && close(&n, &[0.6, 0.8, 0.0]));
        // Inside, nearer the end cap than the mantle.
        let (d, n) = c.distance(&[0.1, 0.2, 0.0]);
        assert!((d + 0.2).abs() < 1e-15 && close(&n, &[0.0, -1.0, 0.0]));
        assert_eq!(c.bounds(), ([-1.0, 0.0, -1.0], [1.0, 2.0, 1.0]));
    }

    /// The normal is the gradient of the distance (central differences off the medial axis).
    #[test]
    fn normals_are_distance_gradients() {
        let shapes = [
            ObstacleShape::<3>::Box {
                lo: [0.0, 0.0, 0.0],
                hi: [1.0, 2.0, 3.0],
            },
            ObstacleShape::<3>::cylinder([0.5, 0.5, 0.5], 0.4, 2, 1.0),
        ];
        let points = [
            [1.7, 0.3, 1.1],
            [-0.2, 2.5, 3.3],
            [0.9, 1.0, 1.4],
            [0.55, 0.61, 0.7],
            [1.2, 0.7, 1.3],
        ];
        let eps = 1e-6;
        for s in &shapes {
            for x in &points {
                let (_, n) = s.distance(x);
                for a in 0..3 {
                    let mut xp = *x;
                    let mut xm = *x;
                    xp[a] += eps;
                    xm[a] -= eps;
                    let g = (s.distance(&xp).0 - s.distance(&xm).0) / (2.0 * eps);
                    assert!((g - n[a]).abs() < 1e-6, "{s:?} at {x:?}: {g} vs {n:?}");
                }
            }
        }
    }

    #[test]
    fn moving_obstacles_translate() {
        let o = Obstacle::<f64, 2> {
            shape: ObstacleShape::Box {
                lo: [0.0, 0.0],
                hi: [1.0, 1.0],
            },
            velocity: [2.0, 0.0].into(),
            mu: 0.0,
        };
        assert!((o.distance(&[2.5, 0.5], 0.0).0 - 1.5).abs() < 1e-15);
        assert!((o.distance(&[2.5, 0.5], 0.5).0 - 0.5).abs() < 1e-15);
        assert!(o.distance(&[2.5, 0.5], 1.0).0 < 0.0);
    }
}
