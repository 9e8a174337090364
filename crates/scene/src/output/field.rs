//! The particle fields a frame can hold and the derived quantities behind them.

use loam_core::spectral::{Log, symmetric_fn};
use loam_core::tensor::{Tensor, to3};
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

/// A particle field written to the `.vtu` frames, named in `output.fields` and in ParaView
/// by its snake-case name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Field {
    /// Velocity `v` (m/s), 3 components (`v_z = 0` in 2D).
    Velocity,
    /// Displacement `x − x₀` (m), 3 components; written only when the initial positions are
    /// given.
    Displacement,
    /// Cauchy stress `σ` (Pa), a 3×3 tensor (row-major, 9 components).
    Stress,
    /// Hencky (logarithmic) strain `½ ln(F Fᵀ)`, a 3×3 tensor.
    Strain,
    /// Equivalent plastic strain (zero for elastic models).
    PlasticStrain,
    /// The preconsolidation pressure `p′c` of Modified Cam-Clay (Pa, compression positive;
    /// zero for the other models).
    PreconsolidationPressure,
    /// Pressure `−tr σ / 3` (Pa): the mean effective stress `p′` in a coupled run.
    Pressure,
    /// Pore water pressure `p` (Pa, positive in compression) of a coupled (u–p) run; written
    /// only for those.
    PorePressure,
    /// Excess pore pressure `p − γ_w (z_w − z)` over the hydrostatic pressure of the water
    /// table (Pa, positive in compression; all of `p` without a water table); coupled runs
    /// only.
    ExcessPorePressure,
    /// Von Mises stress `√(3/2 s:s)`, `s` the deviatoric stress (Pa).
    VonMises,
    /// Current volume `det F · V₀` (m³; m² per metre of depth in 2D).
    Volume,
    /// Mass (kg; kg per metre of depth in 2D).
    Mass,
    /// Index of the particle's material in the scene's material table.
    MaterialId,
    /// The affine velocity matrix `C` of APIC, TPIC and MLS-MPM (1/s), a 3×3 tensor (the
    /// in-plane block in 2D); written only for those transfers. With it the angular momentum
    /// of the particles, `L = Σ m (x × v) + Σ m ε:(C D)` (`D = κh² I`), can be audited
    /// from the frames (`docs/scene-format.md`).
    Affine,
    /// The particle's id: its index in the particle arrays (bodies in file order), the number
    /// that run errors quote.
    Id,
}

impl Field {
    /// Every field, in the order frames list them.
    pub const ALL: [Field; 15] = [
        Field::Velocity,
        Field::Displacement,
        Field::Stress,
        Field::Strain,
        Field::PlasticStrain,
        Field::PreconsolidationPressure,
        Field::Pressure,
        Field::PorePressure,
        Field::ExcessPorePressure,
        Field::VonMises,
        Field::Volume,
        Field::Mass,
        Field::MaterialId,
        Field::Affine,
        Field::Id,
    ];

    /// Whether the field belongs to a coupled (u–p) run only.
    pub fn coupled_only(self) -> bool {
        matches!(self, Field::PorePressure | Field::ExcessPorePressure)
    }

    /// The field's name, in scene files and as the `.vtu` array name.
    pub fn name(self) -> &'static str {
        match self {
            Field::Velocity => "velocity",
            Field::Displacement => "displacement",
            Field::Stress => "stress",
            Field::Strain => "strain",
            Field::PlasticStrain => "plastic_strain",
            Field::PreconsolidationPressure => "preconsolidation_pressure",
            Field::Pressure => "pressure",
            Field::PorePressure => "pore_pressure",
            Field::ExcessPorePressure => "excess_pore_pressure",
            Field::VonMises => "von_mises",
            Field::Volume => "volume",
            Field::Mass => "mass",
            Field::MaterialId => "material_id",
            Field::Affine => "affine",
            Field::Id => "id",
        }
    }
}

/// Hencky strain `½ ln(F Fᵀ)` of a deformation gradient, on its 3×3 embedding (`F_zz = 1`
/// in plane strain).
pub fn hencky_strain<const D: usize>(f: &Tensor<f64, D>) -> Matrix3<f64> {
    let f3 = to3(f, 1.0);
    symmetric_fn(&(f3 * f3.transpose()), &Log) * 0.5
}

/// The water table of a coupled run, for the excess pore pressure of the frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WaterTable {
    /// Height on the last axis (m).
    pub height: f64,
    /// Unit weight of water `γ_w` (N/m³).
    pub unit_weight: f64,
}

impl WaterTable {
    /// The hydrostatic pressure `γ_w (z_w − z)` at height `z`, zero above the table (Pa).
    pub fn hydrostatic(&self, z: f64) -> f64 {
        self.unit_weight * (self.height - z).max(0.0)
    }
}

/// Pressure `−tr σ / 3` (positive in compression).
pub fn pressure(stress: &Matrix3<f64>) -> f64 {
    -stress.trace() / 3.0
}

/// Von Mises equivalent stress `√(3/2 s:s)`, `s = σ − (tr σ / 3) I`.
pub fn von_mises(stress: &Matrix3<f64>) -> f64 {
    let s = stress - Matrix3::identity() * (stress.trace() / 3.0);
    (1.5 * s.norm_squared()).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix2;

    #[test]
    fn names_match_the_scene_file_spelling() {
        for field in Field::ALL {
            let json = serde_json::to_string(&field).unwrap();
            assert_eq!(json, format!("\"{}\"", field.name()));
        }
    }

    #[test]
    fn derived_quantities_of_simple_states() {
        // Uniaxial stress σ_xx = s: p = −s/3, von Mises = |s|.
        let s = Matrix3::from_diagonal(&nalgebra::vector![-3.0e5, 0.0, 0.0]);
        assert_eq!(pressure(&s), 1.0e5);
        assert!((von_mises(&s) - 3.0e5).abs() < 1e-9);
        // Hydrostatic: no von Mises stress.
        assert!(von_mises(&(Matrix3::identity() * 7.0)).abs() < 1e-12);
        // Stretch λ along x in plane strain: ε = diag(ln λ, 0, 0).
        let e = hencky_strain(&Matrix2::new(1.5, 0.0, 0.0, 1.0));
        assert!((e[(0, 0)] - 1.5f64.ln()).abs() < 1e-14);
        assert!(e[(1, 1)].abs() < 1e-14 && e[(2, 2)].abs() < 1e-14);
    }
}
