//! Point-in-shape tests and bounding boxes of body shapes.
//!
//! The functions take coordinates as slices and assume the shape has been validated (every
//! coordinate list has the scene's dimension); they never panic on short slices, they just
//! answer for the coordinates present.

use crate::schema::BodyShape;

impl BodyShape {
    /// The shape's name as written after `type =` in a scene file.
    pub fn type_name(&self) -> &'static str {
        match self {
            Self::Box { .. } => "box",
            Self::Disk { .. } => "disk",
            Self::Polygon { .. } => "polygon",
            Self::Sphere { .. } => "sphere",
            Self::Cylinder { .. } => "cylinder",
        }
    }

    /// The only dimension the shape exists in, or `None` for shapes of any dimension.
    pub fn dimension(&self) -> Option<usize> {
        match self {
            Self::Box { .. } => None,
            Self::Disk { .. } | Self::Polygon { .. } => Some(2),
            Self::Sphere { .. } | Self::Cylinder { .. } => Some(3),
        }
    }

    /// `true` when `x` lies inside the shape or on its boundary.
    pub fn contains(&self, x: &[f64]) -> bool {
        match self {
            Self::Box { lo, hi } => x
                .iter()
                .zip(lo.iter().zip(hi))
                .all(|(&xa, (&l, &h))| l <= xa && xa <= h),
            Self::Disk { centre, radius } | Self::Sphere { centre, radius } => {
                distance_squared(x, centre) <= radius * radius
            }
            Self::Polygon { vertices } => winding_number(x, vertices) != 0,
            Self::Cylinder {
                centre,
                axis,
                radius,
                length,
            } => {
                let n = norm(axis);
                let d: Vec<f64> = x.iter().zip(centre).map(|(a, c)| a - c).collect();
                let along = dot(&d, axis) / n;
                along.abs() <= 0.5 * length && dot(&d, &d) - along * along <= radius * radius
            }
        }
    }

    /// The axis-aligned bounding box `(lo, hi)` of the shape.
    pub fn bounds(&self) -> (Vec<f64>, Vec<f64>) {
        match self {
            Self::Box { lo, hi } => (lo.clone(), hi.clone()),
            Self::Disk { centre, radius } | Self::Sphere { centre, radius } => (
                centre.iter().map(|c| c - radius).collect(),
                centre.iter().map(|c| c + radius).collect(),
            ),
            Self::Polygon { vertices } => {
                let mut lo = vec![f64::INFINITY; 2];
                let mut hi = vec![f64::NEG_INFINITY; 2];
                for v in vertices {
                    for (a, &c) in v.iter().enumerate().take(2) {
                        lo[a] = lo[a].min(c);
                        hi[a] = hi[a].max(c);
                    }
                }
                (lo, hi)
            }
            Self::Cylinder {
                centre,
                axis,
                radius,
                length,
            } => {
                // Per axis a, the end discs reach ±(|n_a| L/2 + r √(1 − n_a²)) from the centre.
                let n = norm(axis);
                let reach: Vec<f64> = axis
                    .iter()
                    .map(|&a| {
                        let na = (a / n).abs();
                        na * 0.5 * length + radius * (1.0 - na * na).max(0.0).sqrt()
                    })
                    .collect();
                (
                    centre.iter().zip(&reach).map(|(c, r)| c - r).collect(),
                    centre.iter().zip(&reach).map(|(c, r)| c + r).collect(),
                )
            }
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

fn distance_squared(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// Twice the signed area of a polygon (shoelace formula); positive when counter-clockwise.
pub(crate) fn twice_signed_area(vertices: &[Vec<f64>]) -> f64 {
    edges(vertices)
        .map(|(p, q)| p[0] * q[1] - q[0] * p[1])
        .sum()
}

/// The closed polygon's edges `(v_i, v_{i+1})`, the last one back to the first vertex.
fn edges(vertices: &[Vec<f64>]) -> impl Iterator<Item = (&[f64], &[f64])> {
    vertices
        .iter()
        .zip(vertices.iter().cycle().skip(1))
        .map(|(p, q)| (p.as_slice(), q.as_slice()))
        .filter(|(p, q)| p.len() >= 2 && q.len() >= 2)
}

/// Winding number of the polygon around `x` (Sunday's crossing rule: an upward edge that
/// passes to the right of `x` counts +1, a downward one −1). Points on an edge may count
/// either way; particles sit at sub-cell centres, so ties are rare and harmless.
fn winding_number(x: &[f64], vertices: &[Vec<f64>]) -> i32 {
    let (px, py) = match x {
        [px, py, ..] => (*px, *py),
        _ => return 0,
    };
    // > 0 when x lies left of the directed edge p → q.
    let side = |p: &[f64], q: &[f64]| (q[0] - p[0]) * (py - p[1]) - (px - p[0]) * (q[1] - p[1]);
    edges(vertices).fold(0, |wn, (p, q)| {
        if p[1] <= py && q[1] > py && side(p, q) > 0.0 {
            wn + 1
        } else if p[1] > py && q[1] <= py && side(p, q) < 0.0 {
            wn - 1
        } else {
            wn
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn polygon(v: &[[f64; 2]]) -> BodyShape {
        BodyShape::Polygon {
            vertices: v.iter().map(|p| p.to_vec()).collect(),
        }
    }

    #[test]
    fn polygon_contains_in_either_orientation_and_bounds_its_vertices() {
        // An L shape, counter-clockwise and clockwise.
        let ccw = [
            [0.0, 0.0],
            [2.0, 0.0],
            [2.0, 1.0],
            [1.0, 1.0],
            [1.0, 2.0],
            [0.0, 2.0],
        ];
        let mut cw = ccw;
        cw.reverse();
        for shape in [polygon(&ccw), polygon(&cw)] {
            assert!(shape.contains(&[0.5, 0.5]));
            assert!(shape.contains(&[1.5, 0.5]));
            assert!(shape.contains(&[0.5, 1.5]));
            assert!(!shape.contains(&[1.5, 1.5]));
            assert!(!shape.contains(&[-0.5, 0.5]));
            assert_eq!(shape.bounds(), (vec![0.0, 0.0], vec![2.0, 2.0]));
        }
        let BodyShape::Polygon { vertices } = polygon(&ccw) else {
            unreachable!()
        };
        assert_eq!(twice_signed_area(&vertices), 6.0);
    }

    #[test]
    fn self_intersecting_polygon_uses_the_nonzero_rule() {
        // A pentagram: the central pentagon has winding number 2, so it is inside.
        let star: Vec<[f64; 2]> = (0..5)
            .map(|k| {
                let t =
                    std::f64::consts::FRAC_PI_2 + (2 * k) as f64 * 2.0 * std::f64::consts::PI / 5.0;
                [t.cos(), t.sin()]
            })
            .collect();
        let shape = polygon(&star);
        assert!(shape.contains(&[0.0, 0.0]));
        assert!(shape.contains(&[0.0, 0.8]));
        assert!(!shape.contains(&[0.9, 0.9]));
    }

    #[test]
    fn cylinder_contains_and_bounds_along_a_tilted_axis() {
        let cyl = BodyShape::Cylinder {
            centre: vec![0.0, 0.0, 0.0],
            axis: vec![0.0, 0.0, 2.0],
            radius: 0.5,
            length: 2.0,
        };
        assert!(cyl.contains(&[0.3, 0.3, 0.9]));
        assert!(!cyl.contains(&[0.3, 0.3, 1.1]));
        assert!(!cyl.contains(&[0.4, 0.4, 0.0]));
        assert_eq!(cyl.bounds(), (vec![-0.5, -0.5, -1.0], vec![0.5, 0.5, 1.0]));
        let tilted = BodyShape::Cylinder {
            centre: vec![1.0, 1.0, 1.0],
            axis: vec![1.0, 1.0, 0.0],
            radius: 0.1,
            length: 1.0,
        };
        let s = std::f64::consts::FRAC_1_SQRT_2;
        assert!(tilted.contains(&[1.0 + 0.45 * s, 1.0 + 0.45 * s, 1.05]));
        assert!(!tilted.contains(&[1.0 + 0.55 * s, 1.0 + 0.55 * s, 1.0]));
        let (lo, hi) = tilted.bounds();
        let reach = s * 0.5 + 0.1 * s;
        assert!((hi[0] - (1.0 + reach)).abs() < 1e-15 && (lo[2] - 0.9).abs() < 1e-15);
    }

    #[test]
    fn box_and_disk_include_their_boundary() {
        let b = BodyShape::Box {
            lo: vec![0.0, 0.0],
            hi: vec![1.0, 2.0],
        };
        assert!(b.contains(&[1.0, 2.0]) && !b.contains(&[1.0, 2.1]));
        let d = BodyShape::Disk {
            centre: vec![1.0, 1.0],
            radius: 0.5,
        };
        assert!(d.contains(&[1.5, 1.0]) && !d.contains(&[1.4, 1.4]));
        assert_eq!(d.bounds(), (vec![0.5, 0.5], vec![1.5, 1.5]));
    }
}
