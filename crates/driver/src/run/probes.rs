//! The histories of an implicit run's `[[probes]]`: the particle each follows, sampled after
//! every load step into the summary, and written at the end (also after a failure or an
//! interruption) as `probes.csv` and plots of the settlement and the pore pressure against
//! time (or the load factor).

use loam_core::Particles;
use loam_scene::Probe;
use loam_scene::output::{ProbeHistory, RunSummary, WaterTable, pressure, von_mises};
use loam_verification::{Series, write_plot};
use std::path::Path;

/// The probes of a run and what their samples need.
pub struct Probes {
    probes: Vec<Probe>,
    /// A coupled run's water table (`None` in a coupled run without one: the excess is the
    /// whole pore pressure).
    water: Option<WaterTable>,
    coupled: bool,
}

impl Probes {
    /// The probes of a run; `coupled`: the run has a pore fluid.
    pub fn new(probes: Vec<Probe>, water: Option<WaterTable>, coupled: bool) -> Self {
        Self {
            probes,
            water,
            coupled,
        }
    }

    /// Empty histories of the probes, with their particles' initial positions.
    pub fn histories<const D: usize>(&self, particles: &Particles<f64, D>) -> Vec<ProbeHistory> {
        self.probes
            .iter()
            .map(|p| ProbeHistory {
                name: p.name.clone(),
                particle: p.particle as u64,
                position: particles.x[p.particle].iter().copied().collect(),
                ..ProbeHistory::default()
            })
            .collect()
    }

    /// Appends the state of every probe's particle after a step.
    pub fn sample<const D: usize>(&self, summary: &mut RunSummary, particles: &Particles<f64, D>) {
        for h in &mut summary.probes {
            let i = h.particle as usize;
            let u: Vec<f64> = (0..D).map(|a| particles.x[i][a] - h.position[a]).collect();
            h.settlement.push(-u[D - 1]);
            h.displacement.push(u);
            let stress = &particles.stress[i];
            h.mean_effective_stress.push(pressure(stress));
            h.deviatoric_stress.push(von_mises(stress));
            if self.coupled {
                let p = particles.pore_pressure[i];
                let hydrostatic = self
                    .water
                    .map_or(0.0, |w| w.hydrostatic(particles.x[i][D - 1]));
                h.pore_pressure.push(p);
                h.excess_pore_pressure.push(p - hydrostatic);
            }
        }
    }

    /// Writes `probes.csv` and `probes_settlement.png` (and, coupled, `probes_pore_pressure.png`)
    /// into `dir` from the summary's histories, against each step's time (coupled runs, in
    /// `time_unit`) or load factor.
    pub fn write(&self, dir: &Path, summary: &RunSummary) -> Result<(), String> {
        if summary.probes.is_empty() {
            return Ok(());
        }
        let (x_name, x): (String, Vec<f64>) = match &summary.time_unit {
            Some(unit) => (
                format!("time ({unit})"),
                summary
                    .load_steps
                    .iter()
                    .map(|s| s.time.unwrap_or(0.0))
                    .collect(),
            ),
            None => (
                "load factor".into(),
                summary.load_steps.iter().map(|s| s.load_factor).collect(),
            ),
        };
        let mut header = vec!["step".to_owned(), x_name.clone()];
        for h in &summary.probes {
            header.push(format!("{}.settlement_m", h.name));
            header.push(format!("{}.mean_effective_stress_Pa", h.name));
            header.push(format!("{}.deviatoric_stress_Pa", h.name));
            if self.coupled {
                header.push(format!("{}.pore_pressure_Pa", h.name));
                header.push(format!("{}.excess_pore_pressure_Pa", h.name));
            }
        }
        let mut csv = header.join(",");
        csv.push('\n');
        for (k, step) in summary.load_steps.iter().enumerate() {
            let mut row = vec![step.step.to_string(), format!("{:e}", x[k])];
            for h in &summary.probes {
                let mut columns = vec![
                    &h.settlement,
                    &h.mean_effective_stress,
                    &h.deviatoric_stress,
                ];
                if self.coupled {
                    columns.extend([&h.pore_pressure, &h.excess_pore_pressure]);
                }
                row.extend(
                    columns
                        .iter()
                        .map(|c| c.get(k).map_or(String::new(), |v| format!("{v:e}"))),
                );
            }
            csv.push_str(&row.join(","));
            csv.push('\n');
        }
        let path = dir.join("probes.csv");
        std::fs::write(&path, csv).map_err(|e| format!("{}: {e}", path.display()))?;
        let curves = |values: fn(&ProbeHistory) -> &Vec<f64>| -> Vec<Series> {
            summary
                .probes
                .iter()
                .map(|h| Series {
                    name: h.name.clone(),
                    points: x.iter().copied().zip(values(h).iter().copied()).collect(),
                    markers: false,
                })
                .collect()
        };
        let plot = |name: &str, title: &str, y: &str, series: &[Series]| {
            write_plot(&dir.join(name), title, &x_name, y, series).map_err(|e| e.to_string())
        };
        plot(
            "probes_settlement.png",
            "Settlement at the probes",
            "settlement (m, downward positive)",
            &curves(|h| &h.settlement),
        )?;
        if self.coupled {
            plot(
                "probes_pore_pressure.png",
                "Pore pressure at the probes",
                "pore pressure (Pa, compression positive)",
                &curves(|h| &h.pore_pressure),
            )?;
        }
        Ok(())
    }
}
