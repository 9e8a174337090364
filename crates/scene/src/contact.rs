//! The explicit solver's contact ([`Contact`]) from `[[friction]]` and `[[obstacles]]`.

use crate::schema::{ObstacleKind, ObstacleSpec, Scene};
use loam_core::{Contact, FrictionSegment, Obstacle, ObstacleShape};

impl ObstacleSpec {
    /// The core obstacle (the fields must be valid and of dimension `D`).
    pub fn obstacle<const D: usize>(&self) -> Obstacle<f64, D> {
        let arr = |v: &Option<Vec<f64>>| -> [f64; D] {
            let v = v.as_deref().unwrap_or(&[]);
            std::array::from_fn(|a| v.get(a).copied().unwrap_or(0.0))
        };
        let shape = match self.shape {
            ObstacleKind::Box => ObstacleShape::Box {
                lo: arr(&self.lo),
                hi: arr(&self.hi),
            },
            ObstacleKind::Cylinder => {
                let (centre, radius) = (arr(&self.centre), self.radius.unwrap_or(0.0));
                match self.axis {
                    Some(axis) if D == 3 => ObstacleShape::cylinder(
                        centre,
                        radius,
                        axis as usize,
                        self.length.unwrap_or(0.0),
                    ),
                    _ => ObstacleShape::disk(centre, radius),
                }
            }
        };
        Obstacle {
            shape,
            velocity: arr(&self.velocity).into(),
            mu: self.friction.unwrap_or(0.0),
        }
    }
}

impl Scene {
    /// The friction segments and obstacles as a core [`Contact`] for the scene's shape
    /// function (the fields must be valid and of dimension `D`). A segment written without
    /// `from`/`to` covers the whole face of the domain.
    pub fn contact<const D: usize>(&self) -> Contact<f64, D> {
        let mut contact = Contact::new(self.grid.shape_function);
        let (lo, hi) = (&self.grid.lo, &self.grid.hi);
        for f in &self.friction {
            let (axis, side) = f.wall.axis_side();
            let mut from: [f64; D] = std::array::from_fn(|a| lo.get(a).copied().unwrap_or(0.0));
            let mut to: [f64; D] = std::array::from_fn(|a| hi.get(a).copied().unwrap_or(0.0));
            // The normal component is unused; it is set to the face's coordinate.
            let face = if side == 0 { from[axis] } else { to[axis] };
            (from[axis], to[axis]) = (face, face);
            if let (Some(f0), Some(t0)) = (&f.from, &f.to) {
                for (k, a) in (0..D).filter(|&a| a != axis).enumerate() {
                    from[a] = f0[k];
                    to[a] = t0[k];
                }
            }
            contact.segments.push(FrictionSegment {
                axis,
                side,
                from,
                to,
                mu: f.mu,
            });
        }
        contact.obstacles = self.obstacles.iter().map(|o| o.obstacle()).collect();
        contact
    }
}
