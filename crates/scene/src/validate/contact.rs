//! Validation of `[[friction]]` (Coulomb segments on walls) and `[[obstacles]]` (rigid
//! obstacles), both for the explicit solver only.

use super::{AXES, Checker, GEOMETRY_TOLERANCE, Interval};
use crate::schema::{ObstacleKind, ObstacleSpec, Scene, SolverKind};
use loam_core::{Wall, WallKind};

/// Why `[[friction]]` and `[[obstacles]]` are rejected in an implicit scene.
/// A sound segment: its index, face (axis, side) and range over the tangential axes.
struct Range {
    index: usize,
    axis: usize,
    side: usize,
    from: Vec<f64>,
    to: Vec<f64>,
}

/// Keys of an obstacle shape and whether each is given.
type Keys<'a> = &'a [(&'a str, bool)];

const EXPLICIT_ONLY_CONTACT: &str = "only applied by the explicit solver (the implicit solver \
                                     has no frictional or obstacle contact yet); set \
                                     solver.type = \"explicit\" or remove them";

impl Scene {
    /// The grid's `(lo, hi)` when both are usable `dim`-vectors (otherwise the grid's own
    /// issues are reported and geometry checks against it are skipped).
    fn domain(&self, dim: usize) -> Option<(&[f64], &[f64])> {
        let (lo, hi) = (&self.grid.lo, &self.grid.hi);
        let ok = lo.len() == dim
            && hi.len() == dim
            && lo.iter().chain(hi).all(|x| x.is_finite())
            && (0..dim).all(|a| hi[a] > lo[a]);
        ok.then_some((lo.as_slice(), hi.as_slice()))
    }

    /// `[[friction]]`: explicit solver only; the face exists and is a unilateral slip wall;
    /// `μ ≥ 0`; `from` and `to` both or neither, `D − 1` coordinates each, `from < to`, within
    /// the face; no two segments of one face overlap.
    pub(super) fn check_friction(&self, c: &mut Checker, dim: Option<usize>) {
        if self.friction.is_empty() {
            return;
        }
        if self.solver.kind == SolverKind::Implicit {
            c.issue("friction", EXPLICIT_ONLY_CONTACT);
            return;
        }
        let Some(dim) = dim else { return };
        let domain = self.domain(dim);
        // Sound segments as (index, axis, side, from, to) over the tangential axes.
        let mut ranges: Vec<Range> = Vec::new();
        for (i, f) in self.friction.iter().enumerate() {
            let path = format!("friction[{i}]");
            let (axis, side) = f.wall.axis_side();
            let name = f.wall.name();
            let mu_ok = c.finite(&format!("{path}.mu"), f.mu);
            if mu_ok && f.mu < 0.0 {
                c.issue(
                    format!("{path}.mu"),
                    format!("must be zero or positive, got {}", f.mu),
                );
            }
            if axis >= dim {
                c.issue(
                    format!("{path}.wall"),
                    format!("the grid is {dim}D; it has no {} faces", AXES[axis]),
                );
                continue;
            }
            let wall = self.boundaries.faces()[2 * axis + side].3;
            if !matches!(
                wall,
                Some(Wall {
                    kind: WallKind::Slip,
                    separable: true
                })
            ) {
                let now = match wall {
                    None => "not declared (free)".to_string(),
                    Some(w) if w.kind == WallKind::Slip => "a bilateral slip wall".to_string(),
                    Some(w) => format!("\"{}\"", wall_name(w)),
                };
                c.issue(
                    format!("{path}.wall"),
                    format!(
                        "friction needs a unilateral slip wall on {name}, which is {now}: set \
                         boundaries.{name} = {{ kind = \"slip\", separable = true }} (Coulomb \
                         contact acts only while the material presses on the wall; a bilateral \
                         wall's mirror ghosts would carry part of the normal force outside the \
                         friction law)"
                    ),
                );
            }
            let tangential: Vec<usize> = (0..dim).filter(|&a| a != axis).collect();
            let along = tangential
                .iter()
                .map(|&a| AXES[a])
                .collect::<Vec<_>>()
                .join(", ");
            let range = match (&f.from, &f.to) {
                (None, None) => domain.map(|(lo, hi)| {
                    (
                        tangential.iter().map(|&a| lo[a]).collect(),
                        tangential.iter().map(|&a| hi[a]).collect(),
                    )
                }),
                (Some(_), None) | (None, Some(_)) => {
                    let missing = if f.to.is_none() { "to" } else { "from" };
                    c.issue(
                        format!("{path}.{missing}"),
                        "give both `from` and `to` (the segment's ends along the face), or \
                         neither for the whole face",
                    );
                    None
                }
                (Some(from), Some(to)) => {
                    let mut ok = true;
                    for (key, v) in [("from", from), ("to", to)] {
                        let kpath = format!("{path}.{key}");
                        if v.len() != dim - 1 {
                            c.issue(
                                kpath,
                                format!(
                                    "expected {} coordinate{} along the face ([{along}]: the \
                                     axes other than {} in a {dim}D grid), got {}",
                                    dim - 1,
                                    if dim == 2 { "" } else { "s" },
                                    AXES[axis],
                                    v.len()
                                ),
                            );
                            ok = false;
                        } else {
                            for (k, &x) in v.iter().enumerate() {
                                ok &= c.finite(&format!("{kpath}[{k}]"), x);
                            }
                        }
                    }
                    if ok {
                        for k in 0..dim - 1 {
                            if to[k] <= from[k] {
                                c.issue(
                                    format!("{path}.to[{k}]"),
                                    format!(
                                        "must be greater than from[{k}] = {}, got {}",
                                        from[k], to[k]
                                    ),
                                );
                                ok = false;
                            }
                        }
                    }
                    if ok && let Some((lo, hi)) = domain {
                        let inside = tangential.iter().enumerate().all(|(k, &a)| {
                            let tol = GEOMETRY_TOLERANCE * (hi[a] - lo[a]);
                            from[k] >= lo[a] - tol && to[k] <= hi[a] + tol
                        });
                        if !inside {
                            let (flo, fhi): (Vec<f64>, Vec<f64>) =
                                tangential.iter().map(|&a| (lo[a], hi[a])).unzip();
                            c.issue(
                                path.clone(),
                                format!(
                                    "the segment {} ([{along}]) does not lie on the {name} face \
                                     {}",
                                    Interval(from, to),
                                    Interval(&flo, &fhi)
                                ),
                            );
                            ok = false;
                        }
                    }
                    ok.then(|| (from.clone(), to.clone()))
                }
            };
            if let Some((from, to)) = range {
                ranges.push(Range {
                    index: i,
                    axis,
                    side,
                    from,
                    to,
                });
            }
        }
        // Overlaps of positive length (area in 3D) on one face.
        let tol = domain.map_or(0.0, |(lo, hi)| {
            GEOMETRY_TOLERANCE * (0..dim).map(|a| hi[a] - lo[a]).fold(0.0, f64::max)
        });
        for (k, r) in ranges.iter().enumerate() {
            if let Some(earlier) = ranges[..k].iter().find(|e| {
                e.axis == r.axis
                    && e.side == r.side
                    && (0..r.from.len())
                        .all(|m| r.from[m].max(e.from[m]) < r.to[m].min(e.to[m]) - tol)
            }) {
                c.issue(
                    format!("friction[{}]", r.index),
                    format!(
                        "overlaps friction[{}] on the {} face; segments of one face may touch \
                         but not overlap",
                        earlier.index,
                        self.friction[r.index].wall.name()
                    ),
                );
            }
        }
    }

    /// `[[obstacles]]`: explicit solver only; the keys of the shape (and only those) with
    /// sound values; `friction ≥ 0`; the bounding box at `t = 0` inside the domain.
    pub(super) fn check_obstacles(&self, c: &mut Checker, dim: Option<usize>) {
        if self.obstacles.is_empty() {
            return;
        }
        if self.solver.kind == SolverKind::Implicit {
            c.issue("obstacles", EXPLICIT_ONLY_CONTACT);
            return;
        }
        let Some(dim) = dim else { return };
        for (i, o) in self.obstacles.iter().enumerate() {
            let path = format!("obstacles[{i}]");
            if check_obstacle_shape(c, &path, o, dim)
                && let Some((lo, hi)) = self.domain(dim)
            {
                let (blo, bhi) = obstacle_bounds(o, dim);
                let inside = (0..dim).all(|a| {
                    let tol = GEOMETRY_TOLERANCE * (hi[a] - lo[a]);
                    blo[a] >= lo[a] - tol && bhi[a] <= hi[a] + tol
                });
                if !inside {
                    c.issue(
                        path.clone(),
                        format!(
                            "obstacle lies outside the grid domain: its bounding box {} is not \
                             inside {}",
                            Interval(&blo, &bhi),
                            Interval(lo, hi)
                        ),
                    );
                }
            }
            if let Some(v) = &o.velocity {
                c.vector(&format!("{path}.velocity"), v, dim, "components");
            }
            if let Some(mu) = o.friction {
                let fpath = format!("{path}.friction");
                if c.finite(&fpath, mu) && mu < 0.0 {
                    c.issue(fpath, format!("must be zero or positive, got {mu}"));
                }
            }
        }
    }
}

/// A wall's kind as written in `[boundaries]`.
fn wall_name(w: Wall) -> &'static str {
    match w.kind {
        WallKind::Free => "free",
        WallKind::Fixed => "fixed",
        WallKind::Slip => "slip",
        WallKind::NoSlip => "no_slip",
    }
}

/// Checks an obstacle's shape keys; `true` when the geometry is sound.
fn check_obstacle_shape(c: &mut Checker, path: &str, o: &ObstacleSpec, dim: usize) -> bool {
    let before = c.issues.len();
    let (name, own, other): (&str, Keys, Keys) = match o.shape {
        ObstacleKind::Box => (
            "box",
            &[("lo", o.lo.is_some()), ("hi", o.hi.is_some())],
            &[
                ("centre", o.centre.is_some()),
                ("radius", o.radius.is_some()),
                ("axis", o.axis.is_some()),
                ("length", o.length.is_some()),
            ],
        ),
        ObstacleKind::Cylinder => (
            "cylinder",
            &[
                ("centre", o.centre.is_some()),
                ("radius", o.radius.is_some()),
            ],
            &[("lo", o.lo.is_some()), ("hi", o.hi.is_some())],
        ),
    };
    for (key, given) in other {
        if *given {
            c.issue(
                format!("{path}.{key}"),
                format!("not used by shape \"{name}\"; remove it or change the shape"),
            );
        }
    }
    for (key, given) in own {
        if !*given {
            let what = match *key {
                "lo" => "the lower corner, m",
                "hi" => "the upper corner, m",
                "centre" => "the centre, m",
                _ => "m",
            };
            c.issue(
                format!("{path}.{key}"),
                format!("required for shape \"{name}\" ({what})"),
            );
        }
    }
    match o.shape {
        ObstacleKind::Box => {
            if let (Some(lo), Some(hi)) = (&o.lo, &o.hi)
                && c.coords(&format!("{path}.lo"), lo, dim)
                    & c.coords(&format!("{path}.hi"), hi, dim)
            {
                for a in 0..dim {
                    if hi[a] <= lo[a] {
                        c.issue(
                            format!("{path}.hi[{a}]"),
                            format!("must be greater than lo[{a}] = {}, got {}", lo[a], hi[a]),
                        );
                    }
                }
            }
        }
        ObstacleKind::Cylinder => {
            if let Some(centre) = &o.centre {
                c.coords(&format!("{path}.centre"), centre, dim);
            }
            if let Some(r) = o.radius {
                c.positive(&format!("{path}.radius"), r);
            }
            if dim == 2 {
                for (key, given) in [("axis", o.axis.is_some()), ("length", o.length.is_some())] {
                    if given {
                        c.issue(
                            format!("{path}.{key}"),
                            "not used in 2D: a cylinder in a 2D (plane-strain) scene is a disk, \
                             infinitely long out of the plane; remove it",
                        );
                    }
                }
            } else {
                if o.axis.is_none() {
                    c.issue(
                        format!("{path}.axis"),
                        "required for a cylinder in 3D (the coordinate axis it is parallel \
                         to: \"x\", \"y\" or \"z\")",
                    );
                }
                match o.length {
                    None => c.issue(
                        format!("{path}.length"),
                        "required for a cylinder in 3D (its length along the axis, m)",
                    ),
                    Some(l) => {
                        c.positive(&format!("{path}.length"), l);
                    }
                }
            }
        }
    }
    c.issues.len() == before
}

/// The bounding box of a validated obstacle at `t = 0`.
fn obstacle_bounds(o: &ObstacleSpec, dim: usize) -> (Vec<f64>, Vec<f64>) {
    match o.shape {
        ObstacleKind::Box => (
            o.lo.clone().unwrap_or_default(),
            o.hi.clone().unwrap_or_default(),
        ),
        ObstacleKind::Cylinder => {
            let centre = o.centre.clone().unwrap_or_default();
            let r = o.radius.unwrap_or(0.0);
            let axis = o.axis.map(|a| a as usize).filter(|&a| a < dim);
            let reach = |a: usize| {
                if Some(a) == axis {
                    0.5 * o.length.unwrap_or(0.0)
                } else {
                    r
                }
            };
            (
                (0..dim).map(|a| centre[a] - reach(a)).collect(),
                (0..dim).map(|a| centre[a] + reach(a)).collect(),
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::schema::FrictionSpec;

    #[test]
    fn friction_spec_is_strict() {
        let ok: Result<FrictionSpec, _> = toml::from_str("wall = \"y_min\"\nmu = 0.3\n");
        assert!(ok.is_ok());
        let bad: Result<FrictionSpec, _> = toml::from_str("wall = \"floor\"\nmu = 0.3\n");
        assert!(bad.is_err());
    }
}
