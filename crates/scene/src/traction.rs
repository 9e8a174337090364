//! Loads and flows through free surfaces: `[[tractions]]` ([`crate::TractionSpec`]) turned into
//! point loads, `[[pore_fluid.inflow]]` ([`InflowSpec`]) into particle sources and
//! `[[pore_fluid.drained_surface]]` ([`crate::SurfaceSpec`]) into particle drains, all carried
//! by the particles of the surface layer.

use crate::error::Issue;
use crate::schema::{Face, InflowSpec, Scene};
use loam_core::{Particles, PointLoad};
use loam_implicit::flow::{Inflow, SurfaceDrain};
use std::collections::BTreeMap;

/// Relative size of the cells that group particles into columns across a face's normal: two
/// particles are in one column when their coordinates across the normal agree to this
/// fraction of their half-width (lattice positions agree to round-off).
const COLUMN_RESOLUTION: f64 = 1e-3;

/// A surface of the bodies: the side it faces and the box that holds its particles.
struct Surface<'a> {
    face: Face,
    lo: &'a [f64],
    hi: &'a [f64],
}

impl Scene {
    /// The surface of `face` within `lo..hi` (default: the grid's box).
    fn surface<'a>(
        &'a self,
        face: Face,
        lo: &'a Option<Vec<f64>>,
        hi: &'a Option<Vec<f64>>,
    ) -> Surface<'a> {
        Surface {
            face,
            lo: lo.as_deref().unwrap_or(&self.grid.lo),
            hi: hi.as_deref().unwrap_or(&self.grid.hi),
        }
    }

    /// The point loads of every `[[tractions]]` entry, in file order (the fields must be valid
    /// and of dimension `D`), or the entries that load no particle.
    pub(crate) fn traction_loads<const D: usize>(
        &self,
        particles: &Particles<f64, D>,
    ) -> Result<Vec<PointLoad<D>>, Vec<Issue>> {
        let per_entry = self.tractions.iter().enumerate().map(|(i, t)| {
            let surface = self.surface(t.face, &t.lo, &t.hi);
            let layer = surface.layer(particles, &format!("tractions[{i}]"))?;
            Ok(layer
                .into_iter()
                .map(|(particle, area)| PointLoad {
                    particle,
                    force: std::array::from_fn(|a| t.traction[a] * area),
                })
                .collect())
        });
        collect(per_entry)
    }

    /// The particle sources of every `[[pore_fluid.inflow]]` entry, in file order (the fields
    /// must be valid and of dimension `D`), or the entries that reach no particle.
    pub(crate) fn inflows<const D: usize>(
        &self,
        particles: &Particles<f64, D>,
    ) -> Result<Vec<Inflow>, Vec<Issue>> {
        let specs: &[InflowSpec] = self.pore_fluid.as_ref().map_or(&[], |f| &f.inflow);
        let per_entry = specs.iter().enumerate().map(|(i, q)| {
            let surface = self.surface(q.face, &q.lo, &q.hi);
            let layer = surface.layer(particles, &format!("pore_fluid.inflow[{i}]"))?;
            Ok(layer
                .into_iter()
                .map(|(particle, area)| Inflow {
                    particle,
                    rate: q.rate * area,
                })
                .collect())
        });
        collect(per_entry)
    }

    /// The particle drains of every `[[pore_fluid.drained_surface]]` entry, in file order (the
    /// fields must be valid and of dimension `D`), or the entries that reach no particle.
    pub(crate) fn surface_drains<const D: usize>(
        &self,
        particles: &Particles<f64, D>,
    ) -> Result<Vec<SurfaceDrain>, Vec<Issue>> {
        let specs = self
            .pore_fluid
            .as_ref()
            .map_or(&[][..], |f| &f.drained_surface);
        let per_entry = specs.iter().enumerate().map(|(i, d)| {
            let surface = self.surface(d.face, &d.lo, &d.hi);
            let layer = surface.layer(particles, &format!("pore_fluid.drained_surface[{i}]"))?;
            let (normal, _) = d.face.axis_side();
            Ok(layer
                .into_iter()
                .map(|(particle, area)| SurfaceDrain {
                    particle,
                    conductance: area / particles.half_width0[particle][normal],
                })
                .collect())
        });
        collect(per_entry)
    }
}

/// The items of every entry in order, or every entry's issue.
fn collect<T>(
    per_entry: impl Iterator<Item = Result<Vec<T>, Issue>>,
) -> Result<Vec<T>, Vec<Issue>> {
    let mut items = Vec::new();
    let mut issues = Vec::new();
    for entry in per_entry {
        match entry {
            Ok(v) => items.extend(v),
            Err(issue) => issues.push(issue),
        }
    }
    if issues.is_empty() {
        Ok(items)
    } else {
        Err(issues)
    }
}

impl Surface<'_> {
    /// The particles inside the box that are outermost along the face's normal in their
    /// column, in increasing id order, each with its share of the surface `∏_{a ≠ n} 2 h_a`
    /// (m²; m in 2D); an issue at `path` when there is none.
    fn layer<const D: usize>(
        &self,
        particles: &Particles<f64, D>,
        path: &str,
    ) -> Result<Vec<(usize, f64)>, Issue> {
        let (normal, side) = self.face.axis_side();
        // Outward coordinate: larger is further out.
        let outward = |p: usize| {
            let x = particles.x[p][normal];
            if side == 1 { x } else { -x }
        };
        // Column key: the coordinates across the normal, on a lattice fine against the
        // particles.
        let mut columns: BTreeMap<Vec<i64>, usize> = BTreeMap::new();
        for p in 0..particles.len() {
            let x = &particles.x[p];
            if !(0..D).all(|a| x[a] >= self.lo[a] && x[a] <= self.hi[a]) {
                continue;
            }
            let key: Vec<i64> = (0..D)
                .filter(|&a| a != normal)
                .map(|a| (x[a] / (COLUMN_RESOLUTION * particles.half_width0[p][a])).round() as i64)
                .collect();
            columns
                .entry(key)
                .and_modify(|q| {
                    if outward(p) > outward(*q) {
                        *q = p;
                    }
                })
                .or_insert(p);
        }
        let mut layer: Vec<usize> = columns.into_values().collect();
        if layer.is_empty() {
            return Err(Issue::new(
                path,
                "no particle lies in the box lo..hi: the surface is empty",
            ));
        }
        layer.sort_unstable();
        Ok(layer
            .into_iter()
            .map(|p| {
                let area = (0..D)
                    .filter(|&a| a != normal)
                    .map(|a| 2.0 * particles.half_width0[p][a])
                    .product();
                (p, area)
            })
            .collect())
    }
}
