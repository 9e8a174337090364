//! Initial states of bodies beyond a uniform velocity: a rigid rotation (with the APIC affine
//! matrix it implies), per-particle velocities from a CSV file, and stresses at rest under
//! gravity (geostatic, hydrostatic) with the deformation gradient and history that stand for
//! them. `docs/scene-format.md` documents the keys and the CSV columns.

use crate::error::Issue;
use crate::output::von_mises;
use crate::schema::{BodySpec, InitialStressSpec, Scene};
use loam_core::constitutive::{DruckerPrager, Elasticity, Hencky, Kinematics, Model};
use loam_core::tensor::{Tensor, det, to3};
use loam_core::{Material, MaterialState, Particles};
use nalgebra::{DMatrix, DVector, Matrix3, SVector};
use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// How far (in particle spacings) a position column of a velocity file may be from the
/// particle's position: positions lie on a lattice of that spacing, so a row of another
/// particle is at least one spacing away, and coordinates printed to six significant digits
/// are well within it.
const POSITION_TOLERANCE: f64 = 1e-3;

/// Residual at which the stretches of an elastic state at rest are accepted, relative to the
/// largest stress; the round-off floor `16 ε M` (`M = λ + 2μ`, the stress of a strain of one
/// ulp) is added, since shallow particles carry stresses of strains of order 1e-5.
const ELASTIC_TOLERANCE: f64 = 1e-12;

/// Iterations allowed to find those stretches (each gains a factor of about `σ/E`).
const ELASTIC_ITERATIONS: usize = 200;

/// What the initial state of one body needs to know about the scene.
pub(crate) struct BodyContext<'a, const D: usize> {
    /// The body's index in `bodies`.
    pub index: usize,
    /// Its particles (contiguous: bodies are filled in order).
    pub range: Range<usize>,
    /// The particle spacing `h / ppc`.
    pub spacing: f64,
    /// The lower corner of the grid, where the particle lattice starts.
    pub origin: SVector<f64, D>,
    /// The body's material.
    pub material: &'a Material<f64>,
    /// The scene's gravity.
    pub gravity: SVector<f64, D>,
    /// Whether the explicit transfer carries the affine matrix `C`.
    pub affine: bool,
    /// A coupled scene's water: `(γ_w, z_w)`, the unit weight of water (N/m³) and the water
    /// table's height along the last axis (m). A geostatic stress is then effective:
    /// `σ′_v = −(ρ g d − p_h)`, `p_h = γ_w (z_w − z)` below the table.
    pub water: Option<(f64, f64)>,
}

impl Scene {
    /// Sets the initial stress (with `F`, the state, `V⁰`, the half-widths and the mass that
    /// go with it), then the rotation or the velocity file, of one body's particles; returns
    /// the problems found (file contents, inadmissible stresses).
    pub(crate) fn initial_state<const D: usize>(
        &self,
        body: &BodyContext<'_, D>,
        particles: &mut Particles<f64, D>,
    ) -> Vec<Issue> {
        let spec = &self.bodies[body.index];
        let path = format!("bodies[{}]", body.index);
        let mut issues = Vec::new();
        if let Some(stress) = &spec.initial_stress
            && let Err(message) = set_stress(spec, stress, body, particles)
        {
            issues.push(Issue::new(format!("{path}.initial_stress"), message));
        }
        if let Some(file) = &spec.velocity_file {
            let resolved = self.resolve(file);
            let x = &particles.x[body.range.clone()];
            match read_velocities(&resolved, x, body.spacing) {
                Ok(v) => particles.v[body.range.clone()].copy_from_slice(&v),
                Err(message) => issues.push(Issue::new(
                    format!("{path}.velocity_file"),
                    format!("{}: {message}", resolved.display()),
                )),
            }
        }
        if let Some(rotation) = &spec.rotation {
            let range = body.range.clone();
            let centre = match &rotation.centre {
                Some(c) => SVector::from_column_slice(c),
                None => centre_of_mass(&particles.mass[range.clone()], &particles.x[range.clone()]),
            };
            let spin = skew::<D>(&rotation.angular_velocity);
            for p in range {
                let r = particles.x[p] - centre;
                particles.v[p] += spin * r;
                if body.affine {
                    particles.c[p] = spin;
                }
            }
        }
        issues
    }

    /// A path in the scene resolved against the scene file's folder (the working directory
    /// for a scene not read from a file).
    fn resolve(&self, file: &Path) -> PathBuf {
        match self.source.as_deref().and_then(Path::parent) {
            Some(dir) if file.is_relative() => dir.join(file),
            _ => file.to_path_buf(),
        }
    }
}

/// `Σ m x / Σ m`.
fn centre_of_mass<const D: usize>(mass: &[f64], x: &[SVector<f64, D>]) -> SVector<f64, D> {
    let total: f64 = mass.iter().sum();
    mass.iter()
        .zip(x)
        .fold(SVector::zeros(), |s, (&m, x)| s + x * m)
        / total
}

/// The velocity gradient of the rigid rotation `v = ω × r`: in 2D `[[0, −ω], [ω, 0]]`, in 3D
/// the cross-product matrix `[ω]×` (`C_ij = −ε_ijk ω_k`). Validated: one component in 2D,
/// three in 3D.
fn skew<const D: usize>(omega: &[f64]) -> Tensor<f64, D> {
    let mut w = Tensor::<f64, D>::zeros();
    if D == 2 {
        w[(0, 1)] = -omega[0];
        w[(1, 0)] = omega[0];
    } else {
        let (x, y, z) = (omega[0], omega[1], omega[2]);
        w[(0, 1)] = -z;
        w[(0, 2)] = y;
        w[(1, 0)] = z;
        w[(1, 2)] = -x;
        w[(2, 0)] = -y;
        w[(2, 1)] = x;
    }
    w
}

/// Reads a body's velocities from a CSV file: a header naming the columns (`vx, vy[, vz]`,
/// and optionally the positions `x, y[, z]` as a check of the order), then one row per
/// particle of the body in generation order. Blank lines and lines starting with `#` are
/// skipped, and so is a byte-order mark before the header. The error names the line and the
/// column.
fn read_velocities<const D: usize>(
    file: &Path,
    x: &[SVector<f64, D>],
    spacing: f64,
) -> Result<Vec<SVector<f64, D>>, String> {
    const POSITIONS: [&str; 3] = ["x", "y", "z"];
    const VELOCITIES: [&str; 3] = ["vx", "vy", "vz"];
    let text = crate::csv::read_csv(file).map_err(|e| format!("cannot read it: {e}"))?;
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let expected = {
        let mut names: Vec<&str> = POSITIONS[..D].to_vec();
        names.extend(&VELOCITIES[..D]);
        names.join(", ")
    };
    let (line, header) = lines
        .next()
        .ok_or_else(|| format!("is empty; expected a header naming the columns {expected}"))?;
    // Column k holds axis `a` of the position (`false`) or of the velocity (`true`).
    let mut columns: Vec<(bool, usize, &str)> = Vec::new();
    for name in header.split(',').map(str::trim) {
        let column = VELOCITIES[..D]
            .iter()
            .position(|&v| v == name)
            .map(|a| (true, a))
            .or_else(|| {
                POSITIONS[..D]
                    .iter()
                    .position(|&p| p == name)
                    .map(|a| (false, a))
            })
            .ok_or_else(|| {
                format!(
                    "line {line}: unknown column `{name}`; expected {expected} (the positions \
                     are optional)"
                )
            })?;
        if columns.iter().any(|&(v, a, _)| (v, a) == column) {
            return Err(format!("line {line}: column `{name}` is given twice"));
        }
        columns.push((column.0, column.1, name));
    }
    for (velocity, names) in [(true, &VELOCITIES), (false, &POSITIONS)] {
        let given = columns.iter().filter(|c| c.0 == velocity).count();
        if given != D && (velocity || given != 0) {
            return Err(format!(
                "line {line}: the header must name all of {} (got {})",
                names[..D].join(", "),
                header
            ));
        }
    }
    let mut v = Vec::with_capacity(x.len());
    for (line, row) in lines {
        let values: Vec<&str> = row.split(',').map(str::trim).collect();
        if values.len() != columns.len() {
            return Err(format!(
                "line {line}: expected {} values ({}), got {}",
                columns.len(),
                header,
                values.len()
            ));
        }
        let (mut position, mut velocity) = (SVector::<f64, D>::zeros(), SVector::zeros());
        for (&(is_velocity, a, name), text) in columns.iter().zip(&values) {
            let value: f64 = text
                .parse()
                .map_err(|_| format!("line {line}, column {name}: `{text}` is not a number"))?;
            if !value.is_finite() {
                return Err(format!(
                    "line {line}, column {name}: must be finite, got {value}"
                ));
            }
            if is_velocity {
                velocity[a] = value;
            } else {
                position[a] = value;
            }
        }
        let p = v.len();
        if p < x.len()
            && columns.len() > D
            && (position - x[p]).amax() > POSITION_TOLERANCE * spacing
        {
            return Err(format!(
                "line {line}: the position {} is not that of the body's particle {p}, {}: rows \
                 follow the particles in generation order (axis x fastest)",
                coordinates(&position),
                coordinates(&x[p])
            ));
        }
        v.push(velocity);
    }
    if v.len() != x.len() {
        return Err(format!(
            "has {} rows of velocities but the body has {} particles",
            v.len(),
            x.len()
        ));
    }
    Ok(v)
}

fn coordinates<const D: usize>(x: &SVector<f64, D>) -> String {
    let parts: Vec<String> = x.iter().map(|c| c.to_string()).collect();
    format!("({})", parts.join(", "))
}

/// The axis gravity acts along and the sign of "up" on it (validated: one non-zero
/// component), and `|g|`.
fn vertical<const D: usize>(gravity: &SVector<f64, D>) -> (usize, f64, f64) {
    let axis = (0..D).find(|&a| gravity[a] != 0.0).unwrap_or(D - 1);
    let up = if gravity[axis] > 0.0 { -1.0 } else { 1.0 };
    (axis, up, gravity[axis].abs())
}

/// The depth of every particle of the body below its top surface (per column of the particle
/// lattice `(origin, spacing)`, the top particle plus half a spacing) or below the level
/// `surface`.
fn depths<const D: usize>(
    x: &[SVector<f64, D>],
    (origin, spacing): (SVector<f64, D>, f64),
    axis: usize,
    up: f64,
    surface: Option<f64>,
) -> Result<Vec<f64>, String> {
    let height = |x: &SVector<f64, D>| up * x[axis];
    if let Some(level) = surface {
        let top = x.iter().map(height).fold(f64::NEG_INFINITY, f64::max);
        if top > up * level {
            return Err(format!(
                "surface = {level} lies below particles of the body (the highest at {} = {})",
                ["x", "y", "z"][axis],
                up * top
            ));
        }
        return Ok(x.iter().map(|x| up * level - height(x)).collect());
    }
    let column = |x: &SVector<f64, D>| -> [i64; 2] {
        let mut key = [0i64; 2];
        for (k, a) in (0..D).filter(|&a| a != axis).enumerate() {
            // Particles sit at origin + (k + ½) spacing.
            key[k] = ((x[a] - origin[a]) / spacing - 0.5).round() as i64;
        }
        key
    };
    let mut tops: HashMap<[i64; 2], f64> = HashMap::new();
    for x in x {
        let top = tops.entry(column(x)).or_insert(f64::NEG_INFINITY);
        *top = top.max(height(x));
    }
    Ok(x.iter()
        .map(|x| tops[&column(x)] + 0.5 * spacing - height(x))
        .collect())
}

/// Sets the stress at rest of a body's particles (see [`InitialStressSpec`]) with the
/// deformation gradient and history that the material needs to carry it: the particle keeps
/// its current volume (its share of the body's shape) and position, so its reference volume
/// is `V / det F`, its half-widths `hw / F_aa` and its mass `ρ₀ V⁰`.
fn set_stress<const D: usize>(
    spec: &BodySpec,
    stress: &InitialStressSpec,
    body: &BodyContext<'_, D>,
    p: &mut Particles<f64, D>,
) -> Result<(), String> {
    let (axis, up, g) = vertical(&body.gravity);
    let range = body.range.clone();
    let lattice = (body.origin, body.spacing);
    let d = depths(&p.x[range.clone()], lattice, axis, up, stress.surface())?;
    let material = body.material;
    let rho = material.density;
    let k0 = match *stress {
        InitialStressSpec::Geostatic { k0, .. } => Some(k0.unwrap_or_else(|| default_k0(material))),
        InitialStressSpec::Hydrostatic { .. } => None,
    };
    // The shallowest depth at which the state is inadmissible, and why.
    let mut failure: Option<(f64, String)> = None;
    for (i, depth) in range.zip(d) {
        // The pore water carries p_h of the total overburden ρ g d (ρ the saturated density
        // below the water table); the skeleton carries the rest, the effective stress.
        let water = body
            .water
            .map_or(0.0, |(gamma, z)| gamma * (z - p.x[i][D - 1]).max(0.0));
        let overburden = rho * g * depth - water;
        let target: [f64; 3] = match (k0, &material.model) {
            (None, Model::Fluid(fluid)) => {
                let p = tait_hydrostatic(fluid.bulk_modulus, fluid.gamma, rho * g * depth);
                [-p; 3]
            }
            (k0, _) => {
                let vertical = -overburden;
                let horizontal = k0.unwrap_or(1.0) * vertical;
                std::array::from_fn(|a| if a == axis { vertical } else { horizontal })
            }
        };
        match state_at_rest::<D>(material, target, k0, overburden) {
            Ok(rest) => {
                let j = det(&rest.f);
                let volume = p.volume0[i];
                p.volume0[i] = volume / j;
                p.mass[i] = rho * p.volume0[i];
                for a in 0..D {
                    p.half_width0[i][a] /= rest.f[(a, a)];
                }
                p.f[i] = rest.f;
                p.stress[i] = rest.stress;
                p.state[i] = rest.state;
            }
            Err(why) => {
                if failure.as_ref().is_none_or(|(d, _)| depth < *d) {
                    failure = Some((depth, why));
                }
            }
        }
    }
    match failure {
        None => Ok(()),
        Some((depth, why)) => Err(format!(
            "at depth {} m below the body's surface (material \"{}\"): {why}",
            significant(depth),
            spec.material
        )),
    }
}

/// `x` to six significant digits (for messages: depths sum round-off).
fn significant(x: f64) -> f64 {
    format!("{x:.5e}").parse().unwrap_or(x)
}

/// The default lateral coefficient: Jaky's `1 − sin φ` for Drucker–Prager, raised to the
/// smallest value the cone admits without cohesion where it lies outside (φ above about
/// 36°, see [`cone_k0_range`]); `ν/(1 − ν)` (uniaxial strain) for the other models.
fn default_k0(material: &Material<f64>) -> f64 {
    match &material.model {
        Model::DruckerPrager(dp) => {
            let jaky = 1.0 - dp.friction_angle.sin();
            jaky.max(cone_k0_range(dp).0)
        }
        // Jaky's value lies inside the pyramid for every φ: (1 − sin φ)(1 + sin φ) ≤ 1.
        Model::MohrCoulomb(mc) => 1.0 - mc.friction_angle.sin(),
        // Jaky's with the friction angle of the critical state line in triaxial compression,
        // sin φ′ = 3M/(6 + M).
        Model::ModifiedCamClay(m) => {
            let slope = m.critical_state_slope;
            1.0 - 3.0 * slope / (6.0 + slope)
        }
        model => {
            let lame = match model {
                Model::LinearElastic(m) => m.lame,
                Model::NeoHookean(m) => m.lame,
                Model::Hencky(m) => m.lame,
                Model::J2(m) => m.lame,
                // Validated: geostatic is not offered for fluids.
                Model::Fluid(_)
                | Model::DruckerPrager(_)
                | Model::MohrCoulomb(_)
                | Model::ModifiedCamClay(_) => return 1.0,
            };
            let nu = lame.poisson();
            nu / (1.0 - nu)
        }
    }
}

/// The range of `K0` for which the state `σ_h = K0 σ_v` lies in the Drucker–Prager cone
/// without cohesion: `|1 − K0|/√3 ≤ α (1 + 2 K0)` (`√J₂ = |σ_v| |1 − K0|/√3`,
/// `I₁ = σ_v (1 + 2 K0)`), i.e. `(1 − √3α)/(1 + 2√3α) ≤ K0 ≤ (1 + √3α)/(1 − 2√3α)`.
fn cone_k0_range(dp: &DruckerPrager<f64>) -> (f64, f64) {
    let a = 3f64.sqrt() * dp.alpha();
    let upper = if 2.0 * a < 1.0 {
        (1.0 + a) / (1.0 - 2.0 * a)
    } else {
        f64::INFINITY
    };
    ((1.0 - a) / (1.0 + 2.0 * a), upper)
}

/// The pressure at depth `d` in a column of Tait fluid at rest, from `dp/dd = ρ(p) g` with
/// `ρ/ρ₀ = (1 + γp/K)^{1/γ}`, given `w = ρ₀ g d`:
/// `p = (K/γ) [(1 + (γ − 1) w/K)^{γ/(γ − 1)} − 1]`, `p = K (e^{w/K} − 1)` for `γ = 1`
/// (`p = w (1 + w/(2K) + …)`: the weight of the column, slightly more as the fluid is
/// compressed under it).
pub(crate) fn tait_hydrostatic(k: f64, gamma: f64, w: f64) -> f64 {
    let x = w / k;
    let u = if gamma == 1.0 {
        x.exp()
    } else {
        ((gamma / (gamma - 1.0)) * ((gamma - 1.0) * x).ln_1p()).exp()
    };
    (k / gamma) * (u - 1.0)
}

/// A particle state at rest: diagonal `F` (in plane strain `F_zz = 1`), the Cauchy stress
/// and the history.
struct Rest<const D: usize> {
    f: Tensor<f64, D>,
    stress: Matrix3<f64>,
    state: MaterialState<f64>,
}

/// The state at rest in which `material` carries the principal stresses `target` (along x,
/// y, z): for a fluid the volume ratio of the pressure (`F = J^{1/D} I`); for
/// Drucker–Prager the stress itself, `F = I`, and the state `I + 2 C⁻¹:σ`; for the
/// hyperelastic models and J2 the stretches whose stress it is (in plane strain the in-plane
/// components; `σ_zz` is the model's), found by iterating `e ← e + M⁻¹ (σ* − σ(e))` on the
/// logarithmic stretches with the elastic constrained stiffness `M`. `k0` and `w = ρ₀ g d`
/// go into the messages.
fn state_at_rest<const D: usize>(
    material: &Material<f64>,
    target: [f64; 3],
    k0: Option<f64>,
    w: f64,
) -> Result<Rest<D>, String> {
    let k0_text = k0.map_or_else(String::new, |k| format!(" with K0 = {k}"));
    let lame = match &material.model {
        Model::Fluid(fluid) => {
            // J from p(J) = p: J^{−γ} = 1 + γ p / K.
            let p = -target[0];
            let j = (1.0 + fluid.gamma * p / fluid.bulk_modulus).powf(-1.0 / fluid.gamma);
            let f = Tensor::<f64, D>::identity() * j.powf(1.0 / D as f64);
            let (stress, state) = evaluate(material, &f);
            return Ok(Rest { f, stress, state });
        }
        Model::DruckerPrager(dp) if dp.elasticity == Elasticity::Jaumann => {
            let stress = Matrix3::from_diagonal(&target.into());
            let scale = target.iter().fold(0.0f64, |m, s| m.max(s.abs()));
            let tolerance = 1e-12 * scale.max(dp.k());
            if dp.yield_function(&stress) > tolerance {
                let (lo, hi) = cone_k0_range(dp);
                return Err(format!(
                    "the stress{k0_text} lies outside the Drucker–Prager cone (without \
                     cohesion the cone admits K0 in [{lo:.4}, {hi:.4}])"
                ));
            }
            if stress.trace() / 3.0 > dp.tension_limit() + tolerance {
                return Err(format!(
                    "the mean stress exceeds the tension cutoff {}",
                    dp.tension_limit()
                ));
            }
            let state = MaterialState {
                plastic_strain: 0.0,
                tensor: Matrix3::identity() + dp.compliance(&stress) * 2.0,
                hardening: 0.0,
            };
            let f = Tensor::<f64, D>::identity();
            return Ok(Rest { f, stress, state });
        }
        Model::ModifiedCamClay(m) => {
            // No stiffness at zero stress: the stress is carried by the history at F = I.
            let stress = Matrix3::from_diagonal(&target.into());
            let state = m.initial_state(&stress).ok_or_else(|| {
                format!(
                    "model \"modified_cam_clay\" needs a compressive mean effective stress, \
                     got {} Pa",
                    -stress.trace() / 3.0
                )
            })?;
            let (p, q) = (-stress.trace() / 3.0, von_mises(&stress));
            if m.yield_function(p, q, state.hardening) > 1e-9 * state.hardening.powi(2) {
                return Err(format!(
                    "the stress{k0_text} (p′ = {p:.6e} Pa, q = {q:.6e} Pa) lies outside the \
                     Modified Cam-Clay ellipse of p′c0 = {:.6e} Pa (raise \
                     preconsolidation_pressure, or give ocr instead)",
                    state.hardening
                ));
            }
            let f = Tensor::<f64, D>::identity();
            return Ok(Rest { f, stress, state });
        }
        Model::DruckerPrager(dp) => dp.lame,
        Model::MohrCoulomb(m) => m.lame,
        Model::LinearElastic(m) => m.lame,
        Model::NeoHookean(m) => m.lame,
        Model::Hencky(m) => m.lame,
        Model::J2(m) => m.lame,
    };
    let stiffness = DMatrix::<f64>::from_fn(D, D, |a, b| {
        lame.lambda + if a == b { 2.0 * lame.mu } else { 0.0 }
    });
    let compliance = stiffness
        .try_inverse()
        .ok_or_else(|| "the elastic constants give no stiffness".to_owned())?;
    let scale = target.iter().fold(0.0f64, |m, s| m.max(s.abs()));
    let tolerance = ELASTIC_TOLERANCE * scale + 16.0 * f64::EPSILON * (lame.lambda + 2.0 * lame.mu);
    // J2 and the Hencky soil models are Hencky elasticity until they yield: find the
    // stretches on the elastic law, then let the model say whether the state is admissible
    // (and set its bₑ).
    let elastic = match &material.model {
        Model::J2(_) | Model::DruckerPrager(_) | Model::MohrCoulomb(_) => Material {
            density: material.density,
            model: Model::Hencky(Hencky { lame }),
        },
        _ => material.clone(),
    };
    let mut e = DVector::<f64>::zeros(D);
    for _ in 0..ELASTIC_ITERATIONS {
        let f = Tensor::<f64, D>::from_diagonal(&SVector::from_fn(|a, _| e[a].exp()));
        let (stress, _) = evaluate(&elastic, &f);
        let residual = DVector::from_fn(D, |a, _| target[a] - stress[(a, a)]);
        if residual.amax() <= tolerance {
            let (stress, state) = evaluate(material, &f);
            if state.plastic_strain > 0.0 {
                let hint = match &material.model {
                    Model::J2(_) => "use a K0 closer to 1 or a higher yield_stress",
                    _ => "use a K0 closer to 1 − sin φ, or more cohesion",
                };
                return Err(format!(
                    "the stress{k0_text} lies outside the yield surface of model \"{}\" ({hint})",
                    material.model.kind().name()
                ));
            }
            return Ok(Rest { f, stress, state });
        }
        e += &compliance * residual;
    }
    Err(format!(
        "found no elastic state carrying the stress ρ₀ g d = {w} Pa{k0_text} (strains too \
         large for the model?)"
    ))
}

/// The Cauchy stress and state the model gives for `F` at rest (from the reference state,
/// no velocity gradient).
fn evaluate<const D: usize>(
    material: &Material<f64>,
    f: &Tensor<f64, D>,
) -> (Matrix3<f64>, MaterialState<f64>) {
    let f3 = to3(f, 1.0);
    let zero = Matrix3::zeros();
    let mut state = MaterialState::default();
    let kin = Kinematics {
        f: &f3,
        delta_f: &f3,
        velocity_gradient: &zero,
        dt: 0.0,
        stress: &zero,
    };
    let stress = material.update(&kin, &mut state);
    (stress, state)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tait_hydrostatic_pressure_solves_its_equation() {
        // dp/dd = ρ₀ g (1 + γp/K)^{1/γ}: check by a central difference in w = ρ₀ g d.
        for (k, gamma) in [
            (1.2e6, 7.0),
            (2.0e5, 1.0),
            (1.0e5, 1.0 + 1e-9),
            (3.0e4, 2.5),
        ] {
            for w in [0.0, 1.0e3, 3.0e4] {
                let dw = 1e-3 * (w + 1.0);
                let slope = (tait_hydrostatic(k, gamma, w + dw)
                    - tait_hydrostatic(k, gamma, w - dw))
                    / (2.0 * dw);
                let p = tait_hydrostatic(k, gamma, w);
                let expected = (1.0 + gamma * p / k).powf(1.0 / gamma);
                assert!(
                    (slope - expected).abs() < 1e-6,
                    "{k} {gamma} {w}: {slope} {expected}"
                );
            }
        }
        assert_eq!(tait_hydrostatic(1.0e6, 7.0, 0.0), 0.0);
    }

    #[test]
    fn rotation_matrix_is_the_cross_product() {
        let w = skew::<3>(&[0.3, -1.2, 2.0]);
        let r = SVector::<f64, 3>::new(0.7, 0.1, -0.4);
        let cross = SVector::<f64, 3>::new(0.3, -1.2, 2.0).cross(&r);
        assert!((w * r - cross).amax() < 1e-15);
        let w2 = skew::<2>(&[2.0]);
        let r2 = SVector::<f64, 2>::new(0.5, 0.25);
        assert_eq!(w2 * r2, SVector::<f64, 2>::new(-0.5, 1.0));
    }

    #[test]
    fn the_default_k0_of_drucker_prager_stays_in_its_cone() {
        for phi in [20.0f64, 30.0, 35.0, 40.0, 45.0] {
            let m = Material::drucker_prager(1e7, 0.3, phi.to_radians(), 0.0, 0.0, None, 2000.0);
            let Model::DruckerPrager(dp) = &m.model else {
                unreachable!()
            };
            let k0 = default_k0(&m);
            let (lo, hi) = cone_k0_range(dp);
            assert!(
                k0 >= lo && k0 <= hi,
                "φ = {phi}: K0 = {k0} not in [{lo}, {hi}]"
            );
            // Jaky's value where it fits.
            if phi <= 35.0 {
                assert_eq!(k0, 1.0 - phi.to_radians().sin());
            }
            // The bounds are on the cone: f = 0 there.
            let sigma = Matrix3::from_diagonal(&nalgebra::vector![lo * -1e4, -1e4, lo * -1e4]);
            assert!(dp.yield_function(&sigma).abs() < 1e-9);
        }
    }
}
