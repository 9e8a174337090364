//! What a parameter of an inversion file is, by its name: its unit (for the plots) and its
//! physical range (values outside are refused).

use std::f64::consts::FRAC_PI_2;

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
/// Ranges: Coulomb coefficients `μ` in [0, 10] (soils, rock and metals are below 1.5);
/// moduli and strengths in [0, 10¹³] Pa (diamond's Young's modulus is 1.2·10¹² Pa), a
/// hardening modulus in ±10¹³ Pa; the `e–ln p′` slopes `λ`, `κ` of Modified Cam-Clay in
/// [0, 10] (peats reach `λ` ≈ 3), its critical state slope `M = 6 sin φ′/(3 − sin φ′)` in
/// [0, 3] (its value at φ′ = 90°), its void ratio in [0, 20], its overconsolidation ratio in
/// [1, 10³] (1: normally consolidated) and its preconsolidation pressure in [0, 10¹³] Pa;
/// Poisson's ratio in [−1, 0.5]; densities in [0, 10⁵] kg/m³
/// (osmium's is 2.26·10⁴); friction and dilation angles in [0, π/2] rad; a fluid's sound
/// speed in [0, 10⁵] m/s and its Tait exponent in [0, 100]. Velocities, gravity, loads,
/// displacements and viscosities have no range here.
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
    let modulus = (0.0, 1e13, "a modulus (Pa)");
    match last {
        "young" | "bulk_modulus" | "cohesion" | "yield_stress" | "shear_modulus" => {
            of("Pa", Some(modulus))
        }
        "lambda" | "kappa" => of("–", Some((0.0, 10.0, "a slope of the e–ln p′ line"))),
        "critical_state_slope" => of("–", Some((0.0, 3.0, "a critical state slope M"))),
        "void_ratio" => of("–", Some((0.0, 20.0, "a void ratio"))),
        "ocr" => of("–", Some((1.0, 1e3, "an overconsolidation ratio"))),
        "preconsolidation_pressure" => of("Pa", Some((0.0, 1e13, "a pressure (Pa)"))),
        "hardening" => of("Pa", Some((-1e13, 1e13, "a hardening modulus (Pa)"))),
        "poisson" => of("–", Some((-1.0, 0.5, "Poisson's ratio"))),
        "density" => of("kg/m³", Some((0.0, 1e5, "a density (kg/m³)"))),
        "friction_angle" | "dilation_angle" => of("rad", Some((0.0, FRAC_PI_2, "an angle (rad)"))),
        "sound_speed" => of("m/s", Some((0.0, 1e5, "a sound speed (m/s)"))),
        "gamma" => of("–", Some((0.0, 100.0, "a Tait exponent"))),
        "viscosity" => of("Pa·s", None),
        _ => of("", None),
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
    }
}
