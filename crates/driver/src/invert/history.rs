//! What an inversion writes: the history (CSV and JSON), its plots, the optimiser's
//! checkpoint and the recovered scene.

use super::units::quantity;
use loam_core::constitutive::constants::partner;
use loam_inverse::implicit::ImplicitParam;
use loam_inverse::{Control, Evaluation, MaterialField, Optimiser, Param};
use loam_scene::{InitialStressSpec, MaterialSpec, Scene};
use loam_verification::{Panel, Series, write_panels};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::Path;

/// One iteration of an inversion.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Entry {
    /// Iteration, 0 the first guess.
    pub iteration: usize,
    /// `L`.
    pub loss: f64,
    /// `‖∇_z L‖` in the optimiser's variables.
    pub gradient_norm: f64,
    /// `θ` of the named parameters.
    pub parameters: Vec<f64>,
    /// `dL/dθ` of the named parameters.
    pub gradient: Vec<f64>,
    /// The relative L2 error of each velocity field against the truth, when known.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub field_errors: Vec<f64>,
    /// Loss evaluations (forward and adjoint runs) this iteration took.
    pub evaluations: usize,
    /// Wall time of the iteration (s).
    pub seconds: f64,
}

/// The history file: the parameter names and the iterations.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct History {
    /// The parameters' names.
    pub names: Vec<String>,
    /// Their truth values, when known.
    pub truth: Option<Vec<f64>>,
    /// The iterations so far.
    pub entries: Vec<Entry>,
}

/// Everything `--resume` continues from.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Checkpoint {
    /// The inversion file as read, `[stop]` left out (it may change between runs).
    pub file: serde_json::Value,
    /// The optimiser's state.
    pub optimiser: Optimiser,
    /// The current point, the last entry of the history.
    pub current: Evaluation,
    /// The history so far.
    pub history: History,
}

impl Checkpoint {
    /// The file name in the output folder.
    pub const NAME: &str = "checkpoint.json";

    /// The inversion file as a checkpoint records it: without `[stop]`.
    pub fn key(file: &impl Serialize) -> serde_json::Value {
        let mut v = serde_json::to_value(file).expect("the inversion file serialises");
        if let Some(map) = v.as_object_mut() {
            map.remove("stop");
        }
        v
    }
}

/// Writes `text` to `path` through a temporary file and a rename, so that an interruption
/// never leaves it half-written.
pub fn write_atomic(path: &Path, text: &str) -> Result<(), String> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, text)
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|e| format!("cannot write {}: {e}", path.display()))
}

impl History {
    /// Writes `history.csv` and `history.json` in `dir`.
    pub fn write(&self, dir: &Path) -> Result<(), String> {
        let mut csv = String::from("iteration,loss,gradient_norm,evaluations,seconds");
        for n in &self.names {
            write!(csv, ",{n}").expect("string");
        }
        for n in &self.names {
            write!(csv, ",dL/d {n}").expect("string");
        }
        let fields = self.entries.first().map_or(0, |e| e.field_errors.len());
        for k in 0..fields {
            write!(csv, ",velocity_field[{k}] error").expect("string");
        }
        csv.push('\n');
        for e in &self.entries {
            write!(
                csv,
                "{},{:e},{:e},{},{:.3}",
                e.iteration, e.loss, e.gradient_norm, e.evaluations, e.seconds
            )
            .expect("string");
            for v in e
                .parameters
                .iter()
                .chain(&e.gradient)
                .chain(&e.field_errors)
            {
                write!(csv, ",{v:e}").expect("string");
            }
            csv.push('\n');
        }
        write_atomic(&dir.join("history.csv"), &csv)?;
        let json = serde_json::to_string_pretty(self).expect("the history serialises");
        write_atomic(&dir.join("history.json"), &json)
    }

    /// Plots `log₁₀ L`, the parameters (with their truth as markers) and the velocity fields'
    /// relative errors against the iteration (whole-number ticks): `history_loss.png`,
    /// `history_parameters.png` (with parameters: one panel each, with its unit and its own
    /// range, so a Young's modulus and a Poisson's ratio are both readable),
    /// `history_field_error.png` (with fields and their truth) in `dir`.
    pub fn plot(&self, dir: &Path) -> Result<(), String> {
        let iterations = |value: &dyn Fn(&Entry) -> f64| -> Vec<(f64, f64)> {
            (self.entries.iter())
                .map(|e| (e.iteration as f64, value(e)))
                .collect()
        };
        let line = |name: String, points| Series {
            name,
            points,
            markers: false,
        };
        let err = |e: loam_verification::VerifyError| e.to_string();
        let loss = Panel {
            y_label: "log10 L".into(),
            series: vec![line(
                "log10 loss".into(),
                iterations(&|e| {
                    if e.loss > 0.0 {
                        e.loss.log10()
                    } else {
                        f64::NAN
                    }
                }),
            )],
        };
        write_panels(&dir.join("history_loss.png"), "Loss", "iteration", &[loss]).map_err(err)?;
        let fields = self.entries.first().map_or(0, |e| e.field_errors.len());
        if fields > 0 {
            let errors = Panel {
                y_label: "relative L2 error (–)".into(),
                series: (0..fields)
                    .map(|k| {
                        line(
                            format!("velocity_field[{k}]"),
                            iterations(&|e| e.field_errors[k]),
                        )
                    })
                    .collect(),
            };
            write_panels(
                &dir.join("history_field_error.png"),
                "Velocity field: relative L2 error",
                "iteration",
                &[errors],
            )
            .map_err(err)?;
        }
        if self.names.is_empty() {
            return Ok(());
        }
        let panels: Vec<Panel> = (self.names.iter().enumerate())
            .map(|(k, name)| {
                let mut series = vec![line(name.clone(), iterations(&|e| e.parameters[k]))];
                if let Some(t) = &self.truth {
                    series.push(Series {
                        name: format!("truth {}", t[k]),
                        points: iterations(&|_| t[k]),
                        markers: true,
                    });
                }
                Panel {
                    y_label: format!("{name} ({})", quantity(name).unit),
                    series,
                }
            })
            .collect();
        write_panels(
            &dir.join("history_parameters.png"),
            "Parameters",
            "iteration",
            &panels,
        )
        .map_err(err)
    }
}

/// Sets the explicit path's unknowns `controls` to `theta` (in their order) in the scene.
/// Material angles are written in degrees, as scene files hold them.
pub fn set_controls(s: &mut Scene, controls: &[Control], theta: &[f64], material_names: &[String]) {
    for (control, &v) in controls.iter().zip(theta) {
        match control {
            Control::VelocityField(_) => {}
            Control::Param(p) => set(s, *p, v),
            Control::K0 { material } => set_k0(s, *material, v),
            Control::InitialVelocity {
                material,
                direction,
            } => {
                let dim = s.dim();
                for b in &mut s.bodies {
                    let selected =
                        material.is_none_or(|m| material_names[m as usize] == b.material);
                    if selected {
                        let vel = b.velocity.get_or_insert_with(|| vec![0.0; dim]);
                        let along: f64 = vel.iter().zip(direction).map(|(a, d)| a * d).sum();
                        vel.iter_mut()
                            .zip(direction)
                            .for_each(|(a, d)| *a += (v - along) * d);
                    }
                }
            }
        }
    }
}

/// Sets the K0 of every geostatic body of material `k` to `v`.
fn set_k0(s: &mut Scene, k: usize, v: f64) {
    let name = s.materials[k].name.clone();
    for body in s.bodies.iter_mut().filter(|b| b.material == name) {
        if let Some(InitialStressSpec::Geostatic { k0, .. }) = &mut body.initial_stress {
            *k0 = Some(v);
        }
    }
}

/// Sets the implicit path's parameters `params` (as the scene numbers them) to `theta` in
/// the scene.
pub fn set_implicit(s: &mut Scene, params: &[ImplicitParam], theta: &[f64]) {
    let dim = s.dim();
    for (&p, &v) in params.iter().zip(theta) {
        match p {
            ImplicitParam::Material(k, field) => set_material(&mut s.materials[k], field, v),
            ImplicitParam::K0(k) => set_k0(s, k, v),
            ImplicitParam::Gravity(a) => {
                s.loads.gravity.get_or_insert_with(|| vec![0.0; dim])[a] = v;
            }
            ImplicitParam::PointLoad(k, a) => s.point_loads[k].force[a] = v,
            ImplicitParam::Displacement(k, a) => s.constraints[k].displacement[a] = Some(v),
            ImplicitParam::ConstraintForce(k, a) => s.constraints[k].force[a] = Some(v),
            ImplicitParam::Conductivity(k) => s.materials[k].hydraulic_conductivity = Some(v),
        }
    }
}

/// The scene `s` (its parameters set to `theta`) as TOML, with a header naming them.
/// `velocity_file` is the file of every particle's recovered initial velocity when velocity
/// fields were recovered: a scene of one body reads it as that body's `velocity_file`;
/// otherwise the header points to it.
pub fn recovered_scene(
    mut s: Scene,
    names: &[String],
    theta: &[f64],
    source: &Path,
    velocity_file: Option<&Path>,
) -> Result<String, String> {
    let body = toml::to_string(&s).map_err(|e| format!("cannot write the recovered scene: {e}"))?;
    let mut head = recovered_header(source, names, theta);
    if let Some(file) = velocity_file {
        if let [body] = s.bodies.as_mut_slice() {
            body.velocity_file = Some(file.to_path_buf());
            (body.velocity, body.rotation) = (None, None);
        } else {
            writeln!(
                head,
                "#   the recovered initial velocities of every particle: {}",
                file.display()
            )
            .expect("string");
        }
    }
    Ok(head + "\n" + &body)
}

/// The comment that heads a recovered file: where it was recovered from and the values.
pub fn recovered_header(source: &Path, names: &[String], theta: &[f64]) -> String {
    let mut head = format!("# Recovered by `loam invert` from {}:\n", source.display());
    for (n, v) in names.iter().zip(theta) {
        writeln!(head, "#   {n} = {v}").expect("string");
    }
    head
}

/// Sets one parameter's field of the scene (validated: it exists).
fn set(s: &mut Scene, p: Param, v: f64) {
    let dim = s.dim();
    match p {
        Param::Friction(k) => s.friction[k].mu = v,
        Param::ObstacleFriction(k) => s.obstacles[k].friction = Some(v),
        Param::ObstacleVelocity(k, a) => {
            s.obstacles[k]
                .velocity
                .get_or_insert_with(|| vec![0.0; dim])[a] = v
        }
        Param::Gravity(a) => s.loads.gravity.get_or_insert_with(|| vec![0.0; dim])[a] = v,
        Param::Material(k, field) => set_material(&mut s.materials[k], field, v),
    }
}

/// Sets one constant of a scene material (or of an element test's `[material]`): the scene
/// key its declaration names, in the scene's unit (degrees for an angle); the other key of a
/// pair of which the model takes one (a fluid's sound speed and bulk modulus) is cleared.
pub fn set_material(m: &mut MaterialSpec, field: MaterialField, v: f64) {
    let key = field.key();
    let v = field.gradient().to_scene(v);
    if field == MaterialField::Density {
        m.density = v;
        return;
    }
    *m.constant_mut(key)
        .expect("a parameter's key is a numeric constant") = Some(v);
    if let Some(other) = partner(m.model, key) {
        *m.constant_mut(other)
            .expect("a pair's keys are numeric constants") = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Width and height of a PNG, from its header chunk.
    fn png_size(path: &Path) -> (u32, u32) {
        let bytes = std::fs::read(path).unwrap();
        let word = |at: usize| u32::from_be_bytes(bytes[at..at + 4].try_into().unwrap());
        (word(16), word(20))
    }

    /// E (10⁶ Pa) and ν (0.3) over 12 iterations: one panel each (so the parameters plot is
    /// two panels high), the loss alone in its own.
    #[test]
    fn parameters_of_different_magnitude_get_a_panel_each() {
        let dir = tempfile::tempdir().unwrap();
        let entries = (0..12)
            .map(|k| Entry {
                iteration: k,
                loss: 10f64.powi(-(k as i32)),
                gradient_norm: 1.0,
                parameters: vec![1.3e6 - 2.5e4 * k as f64, 0.35 - 0.008 * k as f64],
                gradient: vec![0.0, 0.0],
                field_errors: Vec::new(),
                evaluations: 1,
                seconds: 0.1,
            })
            .collect();
        let history = History {
            names: vec!["materials[0].young".into(), "materials[0].poisson".into()],
            truth: Some(vec![1.0e6, 0.25]),
            entries,
        };
        history.plot(dir.path()).unwrap();
        assert_eq!(
            png_size(&dir.path().join("history_parameters.png")),
            (900, 60 + 2 * 240)
        );
        assert_eq!(
            png_size(&dir.path().join("history_loss.png")),
            (900, 60 + 240)
        );
        assert!(!dir.path().join("history_field_error.png").exists());
    }
}
