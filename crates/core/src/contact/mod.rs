//! Frictional walls and rigid obstacles acting on nodal velocities (explicit path).
//!
//! [`Contact`] is applied to every node's updated (trial) velocity before the plain wall
//! conditions of [`crate::Boundary`]; it is empty (a no-op) unless a scene declares friction
//! segments or obstacles.
//!
//! # The nodal Coulomb law
//!
//! Contact is enforced on the grid, node by node, in the predictor–corrector form of
//! Bardenhagen et al. (2001): the momentum update gives a trial velocity `v`; against a rigid
//! surface moving with `v_o`, with unit normal `n` pointing *into* the rigid body, the
//! relative velocity `v_r = v − v_o` approaches when `Δv_n = v_r·n > 0`. Then the normal part
//! is removed and the tangential part `v_t = v_r − (v_r·n) n` is reduced by the Coulomb bound
//! on the impulse per unit nodal mass:
//!
//! ```text
//! v_r ← v_t − min(μ Δv_n, |v_t|) v_t/|v_t|,     v ← v_o + v_r
//! ```
//!
//! so the node sticks (`v_t = 0`) when `|v_t| ≤ μ Δv_n` and slides with the friction impulse
//! `m μ Δv_n` otherwise (the normal impulse is `m Δv_n`). A separating node (`Δv_n ≤ 0`) is
//! left alone. `μ = 0` removes the normal part only: exactly a slip wall. See [`coulomb`].
//! MUSL's second projection removes only the normal part, on the constraints that acted in the
//! first one ([`Contact::enforce`]).
//!
//! # Friction segments on walls
//!
//! A [`FrictionSegment`] covers a range of a face of the domain; it acts on the nodes *on or
//! beyond* the face (ghost nodes included) whose tangential coordinates lie in its range, with
//! `n` the face's outward normal and `v_o = 0`. Where segments of one face touch, the node on
//! the shared edge takes the first segment listed.
//!
//! A friction face must be *unilateral*: declare its plain wall `slip` with `separable = true`
//! (the scene files require it). On a bilateral wall the ghost nodes are the mirror image of the
//! body ([`crate::Boundary::fold_ghosts`]): part of the normal reaction then reaches the body as
//! the image's internal force on the first interior nodes, which no nodal law sees, and the
//! friction force is not `μ N` (a block on an incline then slides 2 % to 90 % off
//! `g (sin α − μ cos α)`, see `docs/architecture.md`). On a unilateral wall every bit of the
//! normal reaction is a nodal `m Δv_n` on a face or ghost node, so the total friction is
//! exactly `μ N` when all contact nodes slide.
//!
//! # Rigid obstacles and the contact layer
//!
//! An [`Obstacle`] acts on every node within its *contact layer*,
//! `φ(x_i) < s h ‖n_i‖₁`, where `φ` is the signed distance to the obstacle at the end of the
//! step, `n_i = ∇φ(x_i)` its outward normal, `h` the cell size and `s = b/2` the half-width of
//! a particle's support in cells ([`Contact::support`]). `s h ‖n‖₁` is how far the support box
//! `[−s h, s h]^D` reaches along `n`. For a convex obstacle (boxes and cylinders are) this makes
//! every node of the support of a particle that touches the obstacle a contact node: with `y`
//! the point of the obstacle nearest `x_i`, `(x_p − y)·n_i ≤ 0` for every `x_p` in the obstacle,
//! so `φ(x_i) = (x_i − y)·n_i ≤ (x_i − x_p)·n_i ≤ s h ‖n_i‖₁`. Such a particle's velocity
//! relative to the obstacle is a weighted mean of nodal velocities none of which approaches
//! the surface, so it does not move deeper; with a thinner layer (e.g. `φ < 0`) the nodes a
//! cell or so outside stay free and drag the particles next to the surface into the obstacle
//! (up to `s h` deep). Particles approaching the surface slow down smoothly, as the weights of
//! the free nodes in their support vanish, so the material feels the obstacle from about
//! `s h` away and flows come to rest about a cell from its surface.

mod obstacle;

pub use obstacle::{Obstacle, ObstacleShape};

use crate::grid::Grid;
use crate::scalar::Scalar;
use crate::shape::{Shape, ShapeFunction};
use crate::tensor::Vector;

/// Coulomb friction on a range of one face of the domain.
///
/// The range is given in the face's tangential coordinates: the node `x` is in the segment
/// when `from[a] ≤ x[a] ≤ to[a]` (to `10⁻⁹ h`) for every axis `a ≠ axis`; `from[axis]` and
/// `to[axis]` are ignored.
#[derive(Clone, Debug, PartialEq)]
pub struct FrictionSegment<T: Scalar, const D: usize> {
    /// The axis the face is normal to (`< D`).
    pub axis: usize,
    /// 0 for the lower face (`x[axis] = lo[axis]`), 1 for the upper one.
    pub side: usize,
    /// Lower corner of the range (component `axis` unused).
    pub from: [f64; D],
    /// Upper corner of the range (component `axis` unused).
    pub to: [f64; D],
    /// Coulomb coefficient `μ ≥ 0`.
    pub mu: T,
}

impl<T: Scalar, const D: usize> FrictionSegment<T, D> {
    /// A segment covering the whole face `(axis, side)`.
    pub fn whole_face(axis: usize, side: usize, mu: T) -> Self {
        Self {
            axis,
            side,
            from: [f64::NEG_INFINITY; D],
            to: [f64::INFINITY; D],
            mu,
        }
    }

    /// The outward normal of the face, `∓e_axis`.
    pub fn normal(&self) -> Vector<T, D> {
        let mut n = Vector::zeros();
        n[self.axis] = if self.side == 0 { -T::one() } else { T::one() };
        n
    }

    /// Whether the segment acts on `node`: on or beyond its face, tangential coordinates in
    /// range.
    #[inline]
    pub fn contains(&self, grid: &Grid<D>, node: [usize; D]) -> bool {
        if !grid.on_face(node, self.axis, self.side) {
            return false;
        }
        let o = grid.origin();
        let tol = 1e-9 * grid.h;
        (0..D).filter(|&a| a != self.axis).all(|a| {
            let x = o[a] + node[a] as f64 * grid.h;
            x >= self.from[a] - tol && x <= self.to[a] + tol
        })
    }
}

/// The nodal Coulomb contact law: `v` is the velocity relative to the rigid surface, `n` the
/// unit normal pointing into the rigid body. If `Δv_n = v·n > 0` (approaching), removes the
/// normal part and reduces the tangential part `v_t` by `min(μ Δv_n, |v_t|)` along `v_t`;
/// returns which branch it took ([`Touch`]).
/// A separating node is untouched. Branches are taken on real parts; `μ` may be a dual
/// number (the slide branch is differentiable in `μ`, the stick branch has `v_t ≡ 0`).
#[inline]
pub fn coulomb<T: Scalar, const D: usize>(v: &mut Vector<T, D>, n: &Vector<T, D>, mu: T) -> Touch {
    let vn = v.dot(n);
    if vn.re() <= 0.0 {
        return Touch::Separate;
    }
    *v -= n * vn;
    let vt = v.norm();
    let slip = mu * vn;
    if slip.re() >= vt.re() {
        if vt.re() > 0.0 || mu.re() > 0.0 {
            *v = Vector::zeros();
        }
        Touch::Stick
    } else {
        let scale = slip / vt;
        *v -= *v * scale;
        Touch::Slip
    }
}

/// The branch [`coulomb`] took at a node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Touch {
    /// Separating (`Δv_n ≤ 0`): the velocity is untouched.
    Separate,
    /// Approaching within the friction cone (`|v_t| ≤ μ Δv_n`): the relative velocity is
    /// removed.
    Stick,
    /// Approaching outside the cone: the normal part is removed and `|v_t|` reduced by
    /// `μ Δv_n`.
    Slip,
}

/// The constraints of [`Contact`] that acted on a node: bit `2·axis + side` for a face, bit
/// `2·D + k` for obstacle `k` (at most [`Contact::MAX_OBSTACLES`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ContactSet {
    /// The constraints the node approached (stick or slip): the active set that
    /// [`Contact::enforce`] applies again.
    pub active: u64,
    /// Those of `active` on which the node slid ([`Touch::Slip`]); the others stuck.
    pub slip: u64,
}

/// Coulomb friction segments on grid walls and rigid obstacles (see the [module](self)
/// documentation for the law and the contact layer).
#[derive(Clone, Debug, PartialEq)]
pub struct Contact<T: Scalar, const D: usize> {
    /// Friction segments on the faces of the domain.
    pub segments: Vec<FrictionSegment<T, D>>,
    /// Rigid obstacles; [`Contact::penetrated`] reports their index.
    pub obstacles: Vec<Obstacle<T, D>>,
    /// Half-width `s = b/2` of a particle's shape-function support, in cells; sets the
    /// obstacles' contact layer `φ < s h ‖n‖₁` (1.5 by default: quadratic B-splines).
    pub support: f64,
}

impl<T: Scalar, const D: usize> Default for Contact<T, D> {
    fn default() -> Self {
        Self::new(Shape::QuadraticBspline)
    }
}

impl<T: Scalar, const D: usize> Contact<T, D> {
    /// No segments or obstacles, for particles interpolated with `shape` (`s = b/2`).
    pub fn new(shape: Shape) -> Self {
        Self {
            segments: Vec::new(),
            obstacles: Vec::new(),
            support: 0.5 * shape.support_width() as f64,
        }
    }

    /// Whether there is nothing to apply.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.segments.is_empty() && self.obstacles.is_empty()
    }

    /// The largest number of obstacles: one bit each in the active set of [`Contact::apply`],
    /// after the `2·3` bits of the faces.
    pub const MAX_OBSTACLES: usize = 64 - 6;

    /// Applies contact to the trial velocity `v` of `node` at simulated time `time` (the end
    /// of the step): first the friction segments (on each face the first segment containing
    /// the node), then every obstacle whose contact layer holds the node, each by [`coulomb`]
    /// on the velocity relative to the surface. Returns the active set, the constraints that
    /// acted (the node approached): bit `2·axis + side` for a face, bit `2·D + k` for
    /// obstacle `k` (at most [`Contact::MAX_OBSTACLES`]), for [`Contact::enforce`], and which
    /// of them slid.
    #[inline]
    pub fn apply(
        &self,
        grid: &Grid<D>,
        node: [usize; D],
        time: f64,
        v: &mut Vector<T, D>,
    ) -> ContactSet {
        self.act(grid, node, time, v, None, |_, _| ())
    }

    /// [`Contact::apply`], reporting to `on_obstacle(k, Δv)` the change `Δv` of the node's
    /// velocity that obstacle `k` made (for each obstacle the node approached): `m Δv` is the
    /// impulse obstacle `k` gave the node of mass `m` over the step, and `−m Δv / Δt` the
    /// force the node exerts on the obstacle.
    #[inline]
    pub fn apply_measured(
        &self,
        grid: &Grid<D>,
        node: [usize; D],
        time: f64,
        v: &mut Vector<T, D>,
        on_obstacle: impl FnMut(usize, Vector<T, D>),
    ) -> ContactSet {
        self.act(grid, node, time, v, None, on_obstacle)
    }

    /// Non-penetration on another velocity of the node (MUSL's second projection), exactly on
    /// the constraints of `active` (from [`Contact::apply`]): their normal part of the velocity
    /// relative to the surface is removed whatever its sign, and the others are left alone.
    /// Re-testing the approach on the second velocity field instead holds nodes that have
    /// already separated, which pumps energy into a rebounding body (`docs/architecture.md`).
    #[inline]
    pub fn enforce(
        &self,
        grid: &Grid<D>,
        node: [usize; D],
        time: f64,
        v: &mut Vector<T, D>,
        active: u64,
    ) {
        if active != 0 {
            self.act(grid, node, time, v, Some(active), |_, _| ());
        }
    }

    /// [`Contact::apply`] (`given = None`) and [`Contact::enforce`] (`given`: the active set);
    /// `on_obstacle(k, Δv)` is told the change of velocity each obstacle that acted made.
    #[inline(always)]
    fn act(
        &self,
        grid: &Grid<D>,
        node: [usize; D],
        time: f64,
        v: &mut Vector<T, D>,
        given: Option<u64>,
        mut on_obstacle: impl FnMut(usize, Vector<T, D>),
    ) -> ContactSet {
        let mut acted = ContactSet::default();
        if self.is_empty() {
            return acted;
        }
        // The law on the velocity `w` relative to a surface with inward normal `n`: Coulomb
        // for `apply`, removal of the normal part on the given constraints for `enforce`
        // (reported as a stick: `enforce` keeps no set).
        let law = |w: &mut Vector<T, D>, n: &Vector<T, D>, mu: T, bit: u64| match given {
            None => coulomb(w, n, mu),
            Some(active) if active & bit != 0 => {
                *w -= n * w.dot(n);
                Touch::Stick
            }
            Some(_) => Touch::Separate,
        };
        let mut record = |touch: Touch, bit: u64| {
            if touch != Touch::Separate {
                acted.active |= bit;
            }
            if touch == Touch::Slip {
                acted.slip |= bit;
            }
        };
        let mut faces_done = [[false; 2]; D];
        for s in &self.segments {
            if faces_done[s.axis][s.side] || !s.contains(grid, node) {
                continue;
            }
            faces_done[s.axis][s.side] = true;
            let bit = 1 << (2 * s.axis + s.side);
            record(law(v, &s.normal(), s.mu, bit), bit);
        }
        if self.obstacles.is_empty() {
            return acted;
        }
        let o = grid.origin();
        let x: [f64; D] = std::array::from_fn(|a| o[a] + node[a] as f64 * grid.h);
        let reach = self.support * grid.h;
        for (k, ob) in self.obstacles.iter().enumerate() {
            let (phi, n_out) = ob.distance(&x, time);
            let l1: f64 = n_out.iter().map(|c| c.abs()).sum();
            if phi >= reach * l1 {
                continue;
            }
            let bit = 1 << (2 * D + k);
            let vo = ob.velocity;
            // The layer (a branch) is decided on the real geometry; the normal carries the
            // derivative of the surface's position `v_o t` in a run seeded on `v_o`.
            let n_obs = ob.normal(&x, time, &n_out);
            let n_in = Vector::<T, D>::from_fn(|a, _| -n_obs[a]);
            let mut vr = *v - vo;
            let touch = law(&mut vr, &n_in, ob.mu, bit);
            if touch != Touch::Separate {
                let before = *v;
                *v = vr + vo;
                on_obstacle(k, *v - before);
            }
            record(touch, bit);
        }
        acted
    }

    /// The obstacle a particle at `x` (real parts) lies strictly inside at `time`, if any:
    /// the first with `φ(x) < −10⁻⁹ ℓ`, `ℓ` the obstacle's size
    /// ([`ObstacleShape::size`]); the tolerance only absorbs round-off of a particle resting
    /// on the surface.
    pub fn penetrated(&self, x: &[f64; D], time: f64) -> Option<usize> {
        self.obstacles
            .iter()
            .position(|ob| ob.distance(x, time).0 < -1e-9 * ob.shape.size())
    }
}

impl<const D: usize> Contact<f64, D> {
    /// The same contact with its parameters (each segment's and obstacle's `μ`, each
    /// obstacle's velocity) as constants of another scalar type; seed the derivative parts of
    /// the result to differentiate with respect to one of them. A seeded velocity also moves
    /// the obstacle's surface, `x_o(t) = x_o(0) + v_o t`: the contact normal carries that
    /// ([`Obstacle::normal`]).
    pub fn lift<T: Scalar>(&self) -> Contact<T, D> {
        Contact {
            segments: self
                .segments
                .iter()
                .map(|s| FrictionSegment {
                    axis: s.axis,
                    side: s.side,
                    from: s.from,
                    to: s.to,
                    mu: T::cst(s.mu),
                })
                .collect(),
            obstacles: self
                .obstacles
                .iter()
                .map(|o| Obstacle {
                    shape: o.shape.clone(),
                    velocity: o.velocity.map(T::cst),
                    mu: T::cst(o.mu),
                })
                .collect(),
            support: self.support,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::Dual64;

    type V2 = Vector<f64, 2>;

    fn floor() -> V2 {
        V2::new(0.0, -1.0)
    }

    #[test]
    fn sticks_when_the_tangential_speed_is_within_the_cone() {
        // Δv_n = 1, |v_t| = 0.4 ≤ μ Δv_n = 0.5: stops.
        let mut v = V2::new(0.4, -1.0);
        assert_eq!(coulomb(&mut v, &floor(), 0.5), Touch::Stick);
        assert_eq!(v, V2::zeros());
    }

    #[test]
    fn slides_with_the_tangential_speed_reduced_by_mu_dvn() {
        // Δv_n = 2, μ = 0.25: |v_t| goes from 3 to 3 − 0.5 along v_t.
        let mut v = V2::new(-3.0, -2.0);
        assert_eq!(coulomb(&mut v, &floor(), 0.25), Touch::Slip);
        assert_eq!(v, V2::new(-2.5, 0.0));
        // In 3D the reduction is along v_t.
        let mut v = Vector::<f64, 3>::new(3.0, -1.0, 4.0);
        let n = Vector::<f64, 3>::new(0.0, -1.0, 0.0);
        coulomb(&mut v, &n, 1.0);
        assert!((v - Vector::<f64, 3>::new(2.4, 0.0, 3.2)).norm() < 1e-15);
    }

    #[test]
    fn separating_nodes_are_untouched() {
        for v0 in [V2::new(1.0, 0.5), V2::new(-2.0, 0.0)] {
            let mut v = v0;
            assert_eq!(coulomb(&mut v, &floor(), 0.7), Touch::Separate);
            assert_eq!(v, v0);
        }
    }

    #[test]
    fn zero_friction_is_exactly_the_slip_wall() {
        let g = Grid::<2>::new([0.0, 0.0], [8, 8], 0.25, 2);
        let mut c = Contact::<f64, 2>::default();
        c.segments.push(FrictionSegment::whole_face(1, 0, 0.0));
        let slip = crate::Boundary {
            walls: [
                [crate::Wall::default(); 2],
                [crate::Wall::new(crate::WallKind::Slip); 2],
            ],
        };
        for v0 in [V2::new(0.3, -1.7), V2::new(-1e-3, -2.0), V2::new(0.1, 0.4)] {
            for node in [[4, 2], [5, 1], [3, 0]] {
                let (mut a, mut b) = (v0, v0);
                c.apply(&g, node, 0.0, &mut a);
                slip.apply(&g, node, &mut a);
                slip.apply(&g, node, &mut b);
                assert_eq!(a, b);
                assert_eq!(a[0], v0[0]);
            }
        }
    }

    /// `apply` returns the constraints that acted (a face bit, an obstacle bit); `enforce`
    /// removes the normal part on exactly those, approaching or not, without friction.
    #[test]
    fn enforce_removes_the_normal_part_on_the_constraints_that_acted() {
        // h = 0.25, pad 2: node (i, j) sits at ((i − 2)/4, (j − 2)/4).
        let g = Grid::<2>::new([0.0, 0.0], [8, 8], 0.25, 2);
        let mut c = Contact::<f64, 2>::new(Shape::QuadraticBspline);
        c.segments.push(FrictionSegment::whole_face(1, 0, 0.5));
        let floor_node = [4, 2];
        let mut v = V2::new(1.0, -0.5);
        let set = c.apply(&g, floor_node, 0.0, &mut v);
        assert_eq!(set.active, 1 << 2, "the y_min face (bit 2·1 + 0) acted");
        assert_eq!(set.slip, 1 << 2, "|v_t| = 1 > μ Δv_n = 0.25: it slid");
        let active = set.active;
        assert_eq!(
            v,
            V2::new(0.75, 0.0),
            "Coulomb: |v_t| reduced by μ Δv_n = 0.25"
        );
        // Second velocity, separating: its normal part goes too, its tangent part stays.
        let mut w = V2::new(1.0, 0.3);
        c.enforce(&g, floor_node, 0.0, &mut w, active);
        assert_eq!(w, V2::new(1.0, 0.0));
        // Nothing acted: nothing is enforced.
        let mut u = V2::new(1.0, -0.3);
        c.enforce(&g, floor_node, 0.0, &mut u, 0);
        assert_eq!(u, V2::new(1.0, -0.3));
    }

    #[test]
    fn segments_act_on_face_and_ghost_nodes_in_range_first_one_wins() {
        // h = 0.25, pad 2: node i sits at x = (i − 2)/4.
        let g = Grid::<2>::new([0.0, 0.0], [8, 8], 0.25, 2);
        let mut c = Contact::<f64, 2>::default();
        c.segments.push(FrictionSegment {
            axis: 1,
            side: 0,
            from: [0.0, 0.0],
            to: [1.0, 0.0],
            mu: 1.0,
        });
        c.segments.push(FrictionSegment {
            axis: 1,
            side: 0,
            from: [1.0, 0.0],
            to: [2.0, 0.0],
            mu: 0.0,
        });
        let run = |node: [usize; 2]| {
            let mut v = V2::new(0.5, -1.0);
            c.apply(&g, node, 0.0, &mut v);
            v
        };
        assert_eq!(run([4, 2]), V2::zeros()); // x = 0.5 on the face: μ = 1, sticks
        assert_eq!(run([4, 1]), V2::zeros()); // ghost below it
        assert_eq!(run([6, 2]), V2::zeros()); // x = 1: shared edge, first segment
        assert_eq!(run([7, 2]), V2::new(0.5, 0.0)); // x = 1.25: μ = 0
        assert_eq!(run([4, 3]), V2::new(0.5, -1.0)); // interior node
        assert_eq!(run([1, 2]), V2::new(0.5, -1.0)); // x = −0.25: out of range
    }

    #[test]
    fn obstacle_contact_uses_the_outward_normal_and_relative_velocity() {
        let g = Grid::<2>::new([0.0, 0.0], [20, 20], 0.1, 2);
        let mut c = Contact::<f64, 2>::default();
        // Box [1, 1.5] × [0, 1]; node (i, j) at ((i − 2)/10, (j − 2)/10).
        c.obstacles.push(Obstacle::fixed(
            ObstacleShape::Box {
                lo: [1.0, 0.0],
                hi: [1.5, 1.0],
            },
            0.0,
        ));
        let run = |node: [usize; 2], v0: V2, time: f64| {
            let mut v = v0;
            c.apply(&g, node, time, &mut v);
            v
        };
        // x = 0.9 (φ = 0.1 < 1.5 h): approaching from the left → normal part removed.
        assert_eq!(run([11, 7], V2::new(2.0, 0.5), 0.0), V2::new(0.0, 0.5));
        // Leaving: untouched.
        assert_eq!(run([11, 7], V2::new(-2.0, 0.5), 0.0), V2::new(-2.0, 0.5));
        // x = 0.8 (φ = 0.2 > 0.15): outside the layer.
        assert_eq!(run([10, 7], V2::new(2.0, 0.5), 0.0), V2::new(2.0, 0.5));
        // Above the top face (y = 1.1, n = +y), moving down: stopped in y.
        assert_eq!(run([14, 13], V2::new(0.3, -1.0), 0.0), V2::new(0.3, 0.0));
        // Inside near the right face, moving left (into the body): normal part removed.
        assert_eq!(run([16, 7], V2::new(-1.0, 0.2), 0.0), V2::new(0.0, 0.2));
    }

    #[test]
    fn moving_obstacles_push_with_their_velocity_and_drag_by_friction() {
        let g = Grid::<2>::new([0.0, 0.0], [20, 20], 0.1, 2);
        let mut c = Contact::<f64, 2>::default();
        // A disk of radius 0.3 at (0.5, 1.0) at t = 0 moving up at 1 m/s; at t = 0.2 its
        // centre is at (0.5, 1.2).
        c.obstacles.push(Obstacle {
            shape: ObstacleShape::disk([0.5, 1.0], 0.3),
            velocity: Vector::from([0.0, 1.0]),
            mu: 0.5,
        });
        // Node at (0.5, 1.6): φ = 0.1 at t = 0.2 (n = +y); a resting node is approached by
        // the disk at relative speed 1, so it is pushed up to the disk's speed, and a
        // tangential speed 0.3 ≤ μ·1 sticks.
        let mut v = V2::new(0.3, 0.0);
        c.apply(&g, [7, 18], 0.2, &mut v);
        assert!((v - V2::new(0.0, 1.0)).norm() < 1e-15, "{v}");
        // Tangential speed 2 slides, reduced by μ·1 = 0.5.
        let mut v = V2::new(2.0, 0.0);
        c.apply(&g, [7, 18], 0.2, &mut v);
        assert!((v - V2::new(1.5, 1.0)).norm() < 1e-15, "{v}");
        // A node moving up faster than the disk separates.
        let mut v = V2::new(2.0, 1.5);
        c.apply(&g, [7, 18], 0.2, &mut v);
        assert_eq!(v, V2::new(2.0, 1.5));
        // At t = 0 the same node is 0.3 away: out of the layer.
        let mut v = V2::new(0.3, 0.0);
        c.apply(&g, [7, 18], 0.0, &mut v);
        assert_eq!(v, V2::new(0.3, 0.0));
        // Penetration moves with the disk.
        assert_eq!(c.penetrated(&[0.5, 1.35], 0.0), None);
        assert_eq!(c.penetrated(&[0.5, 1.35], 0.2), Some(0));
        assert_eq!(c.penetrated(&[0.5, 1.5], 0.2), None); // on the surface
    }

    /// The contact layer holds every node of the support of a particle touching the obstacle
    /// (the convexity bound of the module documentation), for a disk at several sizes.
    #[test]
    fn the_layer_covers_the_support_of_particles_on_the_surface() {
        for (h, r) in [(0.1, 0.5), (0.1, 0.12), (0.05, 1.0)] {
            let g = Grid::<2>::new([0.0, 0.0], [(4.0 / h) as usize; 2], h, 2);
            let o = Obstacle::<f64, 2>::fixed(ObstacleShape::disk([2.0, 2.0], r), 0.0);
            let mut c = Contact::<f64, 2>::default();
            c.obstacles.push(o.clone());
            for k in 0..97 {
                let t = k as f64 * 0.0654;
                let xp = [2.0 + r * t.cos(), 2.0 + r * t.sin()];
                let st = crate::Stencil::<f64, 2>::new(
                    Shape::QuadraticBspline,
                    &g,
                    &Vector::<f64, 2>::from(xp),
                    &Vector::<f64, 2>::repeat(h / 4.0),
                );
                st.for_each(|n| {
                    if n.weight > 0.0 {
                        // A node moving straight at the centre must be stopped.
                        let xi: V2 = g.node_position(n.index);
                        let mut v = V2::new(2.0, 2.0) - xi;
                        c.apply(&g, n.index, 0.0, &mut v);
                        let (_, nn) = o.distance(&[xi[0], xi[1]], 0.0);
                        assert!(v.dot(&V2::from(nn)) >= -1e-12, "h {h} r {r} node {xi}");
                    }
                });
            }
        }
    }

    /// The derivative of the contact law with respect to a moving obstacle's velocity in a
    /// dual run equals the central difference of the `f64` law, in which the surface moves by
    /// `v_o t`: it includes the turn of the normal at the node as the obstacle moves
    /// (`−t (I − n nᵀ)/ρ` for a disk), not only the velocity the node is pushed to. Nodes off
    /// the disk's centre line and off a box's face (in its corner region), where the normal
    /// depends on the position, with the law sliding and sticking. The law is smooth in `v_o`
    /// over ±1e-6 here (no node changes branch), so the difference is exact to its
    /// truncation and round-off, 1e-8 leaving room for both.
    #[test]
    fn obstacle_velocity_derivative_includes_the_moving_surface() {
        let g = Grid::<2>::new([0.0, 0.0], [20, 20], 0.1, 2);
        let time = 0.2;
        let shapes = [
            ObstacleShape::disk([0.5, 1.0], 0.3),
            ObstacleShape::Box {
                lo: [0.1, 0.8],
                hi: [0.42, 1.15],
            },
        ];
        // Node (i, j) at ((i − 2)/10, (j − 2)/10).
        let cases = [
            ([9, 17], V2::new(2.0, -0.5), 0.5), // (0.7, 1.5): slides on the disk
            ([8, 17], V2::new(0.1, -0.3), 0.9), // (0.6, 1.5): sticks to the disk
            ([9, 16], V2::new(-1.0, -2.0), 0.2), // (0.7, 1.4): box corner region
        ];
        for (shape, (node, v0, mu)) in shapes.iter().zip(cases).chain([(&shapes[0], cases[2])]) {
            let velocity = [0.4, 1.0];
            let law = |vo: [f64; 2]| {
                let mut c = Contact::<f64, 2>::default();
                c.obstacles.push(Obstacle {
                    shape: shape.clone(),
                    velocity: Vector::from(vo),
                    mu,
                });
                let mut v = v0;
                let set = c.apply(&g, node, time, &mut v);
                (v, set)
            };
            let (_, set) = law(velocity);
            assert_ne!(set.active, 0, "{shape:?} {node:?}: the node is in contact");
            for a in 0..2 {
                let mut c = Contact::<f64, 2>::default();
                c.obstacles.push(Obstacle {
                    shape: shape.clone(),
                    velocity: Vector::from(velocity),
                    mu,
                });
                let mut lifted: Contact<Dual64, 2> = c.lift();
                lifted.obstacles[0].velocity[a].eps = 1.0;
                let mut v = v0.map(Dual64::from_re);
                assert_eq!(lifted.apply(&g, node, time, &mut v), set);
                let d = 1e-6;
                let (mut up, mut down) = (velocity, velocity);
                up[a] += d;
                down[a] -= d;
                let ((vp, sp), (vm, sm)) = (law(up), law(down));
                assert_eq!((sp, sm), (set, set), "the branches are kept");
                for b in 0..2 {
                    let fd = (vp[b] - vm[b]) / (2.0 * d);
                    assert!(
                        (v[b].eps - fd).abs() <= 1e-8 * (1.0 + fd.abs()),
                        "{shape:?} node {node:?}: dv[{b}]/dv_o[{a}] dual {} vs difference {fd}",
                        v[b].eps
                    );
                }
            }
        }
    }

    #[test]
    fn friction_is_differentiable_in_mu_when_sliding() {
        // v_t = 3 − μ·2 with μ = 0.25 + ε: dv_t/dμ = −2.
        let mut v = Vector::<Dual64, 2>::new(Dual64::from_re(3.0), Dual64::from_re(-2.0));
        let n = Vector::<Dual64, 2>::new(Dual64::from_re(0.0), Dual64::from_re(-1.0));
        coulomb(&mut v, &n, Dual64::new(0.25, 1.0));
        assert_eq!(v[0].re, 2.5);
        assert_eq!(v[0].eps, -2.0);
        assert_eq!(v[1].re, 0.0);
    }
}
