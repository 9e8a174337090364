//! `[[tractions]]`: distributed loads on free surfaces, turned into point loads on the
//! particles of the surface layer ([`TractionSpec`]).

use crate::error::Issue;
use crate::schema::{Scene, TractionSpec};
use loam_core::{Particles, PointLoad};
use std::collections::BTreeMap;

/// Relative size of the cells that group particles into columns across a face's normal: two
/// particles are in one column when their coordinates across the normal agree to this
/// fraction of their half-width (lattice positions agree to round-off).
const COLUMN_RESOLUTION: f64 = 1e-3;

impl Scene {
    /// The point loads of every `[[tractions]]` entry, in file order (the fields must be valid
    /// and of dimension `D`), or the entries that load no particle.
    pub(crate) fn traction_loads<const D: usize>(
        &self,
        particles: &Particles<f64, D>,
    ) -> Result<Vec<PointLoad<D>>, Vec<Issue>> {
        let mut loads = Vec::new();
        let mut issues = Vec::new();
        for (i, spec) in self.tractions.iter().enumerate() {
            let lo = spec.lo.as_deref().unwrap_or(&self.grid.lo);
            let hi = spec.hi.as_deref().unwrap_or(&self.grid.hi);
            let surface = surface_layer(spec, lo, hi, particles);
            if surface.is_empty() {
                issues.push(Issue::new(
                    format!("tractions[{i}]"),
                    "no particle lies in the box lo..hi: the traction loads nothing",
                ));
            }
            let (normal, _) = spec.face.axis_side();
            loads.extend(surface.into_iter().map(|p| {
                let area: f64 = (0..D)
                    .filter(|&a| a != normal)
                    .map(|a| 2.0 * particles.half_width0[p][a])
                    .product();
                PointLoad {
                    particle: p,
                    force: std::array::from_fn(|a| spec.traction[a] * area),
                }
            }));
        }
        if issues.is_empty() {
            Ok(loads)
        } else {
            Err(issues)
        }
    }
}

/// The particles inside the box `lo..hi` that are outermost along `spec.face`'s normal in
/// their column, in increasing id order.
fn surface_layer<const D: usize>(
    spec: &TractionSpec,
    lo: &[f64],
    hi: &[f64],
    particles: &Particles<f64, D>,
) -> Vec<usize> {
    let (normal, side) = spec.face.axis_side();
    // Outward coordinate: larger is further out.
    let outward = |p: usize| {
        let x = particles.x[p][normal];
        if side == 1 { x } else { -x }
    };
    // Column key: the coordinates across the normal, on a lattice fine against the particles.
    let mut columns: BTreeMap<Vec<i64>, usize> = BTreeMap::new();
    for p in 0..particles.len() {
        let x = &particles.x[p];
        if !(0..D).all(|a| x[a] >= lo[a] && x[a] <= hi[a]) {
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
    let mut surface: Vec<usize> = columns.into_values().collect();
    surface.sort_unstable();
    surface
}
