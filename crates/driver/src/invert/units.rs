//! What a parameter of an inversion file is, by its name: its unit (for the plots) and its
//! physical range (values outside are refused).

use loam_inverse::MaterialField;

/// A parameter's unit and physical range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quantity {
    /// The unit (`–` for a pure number).
    pub unit: &'static str,
    /// `[lo, hi]` and what the parameter is, where physics bounds it: a value outside is a
    /// placeholder or a value in another unit.
    pub range: Option<(f64, f64, &'static str)>,
}

/// The quantity of the parameter named `name` (as an inversion file writes it, or as the
/// history names it: `velocity(1,0)`).
///
/// A material constant's unit and range are those its declaration gives
/// ([`loam_core::constitutive::constants`]); a K0 is in `[0, 10]` (heavily overconsolidated
/// clays reach 3); Coulomb coefficients `μ` in [0, 10] (soils, rock and metals are below 1.5).
/// Velocities, gravity, loads and displacements have no range here.
pub fn quantity(name: &str) -> Quantity {
    let last = name.rsplit('.').next().unwrap_or(name);
    let of = |unit, range| Quantity { unit, range };
    if name.starts_with("friction[") || last == "friction" {
        return of("–", Some((0.0, 10.0, "a Coulomb friction coefficient")));
    }
    if name.starts_with("velocity") || last.starts_with("velocity[") {
        return of("m/s", None);
    }
    if name.starts_with("gravity[") {
        return of("m/s²", None);
    }
    if last.starts_with("force[") {
        return of("N", None);
    }
    if last.starts_with("displacement[") {
        return of("m", None);
    }
    if last == "k0" {
        return of(
            "–",
            Some((0.0, 10.0, "a coefficient of earth pressure at rest")),
        );
    }
    match MaterialField::named(last) {
        Some(field) => {
            let g = field.gradient();
            of(g.unit, g.bounds)
        }
        None => of("", None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_give_units_and_ranges() {
        assert_eq!(quantity("friction[2]").range.map(|r| r.1), Some(10.0));
        assert_eq!(quantity("obstacle[0].friction").unit, "–");
        assert_eq!(quantity("obstacle[0].velocity[1]").unit, "m/s");
        assert_eq!(quantity("velocity[water](1,0)").unit, "m/s");
        assert_eq!(quantity("gravity[1]").unit, "m/s²");
        assert_eq!(quantity("materials[0].young").unit, "Pa");
        assert_eq!(
            quantity("materials[1].poisson").range.map(|r| r.0),
            Some(-1.0)
        );
        assert_eq!(quantity("point_loads[0].force[1]").unit, "N");
        assert_eq!(quantity("constraints[2].displacement[0]").unit, "m");
        assert_eq!(quantity("materials[0].viscosity").range, None);
        assert_eq!(quantity("material.lambda").range.map(|r| r.1), Some(10.0));
        assert_eq!(quantity("material.critical_state_slope").unit, "–");
        assert_eq!(quantity("material.shear_modulus").unit, "Pa");
        assert_eq!(quantity("material.ocr").range.map(|r| r.0), Some(1.0));
        assert_eq!(quantity("material.preconsolidation_pressure").unit, "Pa");
        assert_eq!(quantity("materials[0].tension_cutoff").unit, "Pa");
        assert_eq!(quantity("materials[0].friction_angle").unit, "rad");
        assert_eq!(quantity("materials[1].k0").range.map(|r| r.1), Some(10.0));
    }
}
