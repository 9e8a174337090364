//! Times the gradient of an implicit scene against its forward run and reports the peak
//! resident memory: `cargo run --release -p loam-inverse --example implicit_gradient --
//! SCENE.toml`.
//!
//! The loss is a least-squares misfit of the run against itself with every observed value
//! shifted by 1 % (so its gradient is not zero): with point loads, the displacement of the
//! first loaded particle along its load after every load step; otherwise the reaction of the
//! last constraint along its last prescribed axis after every load step. The parameters are
//! `E` of material 0 and, for a J2 material, its yield stress.

use loam_core::constitutive::Model;
use loam_inverse::MaterialField;
use loam_inverse::implicit::{
    ImplicitObservations, ImplicitParam, ImplicitProblem, Observation, Quantity, run_recorded,
};
use loam_scene::Scene;
use std::time::Instant;

/// Peak resident set size (`VmHWM`) in MiB, where `/proc/self/status` exists.
fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: implicit_gradient SCENE.toml")?;
    let built = Scene::read_path(std::path::Path::new(&path))?.build::<2>()?;
    let config = built.implicit_config().ok_or("not an implicit scene")?;
    let initial = built.particles;
    let quantity = match (config.point_loads.first(), config.constraints.last()) {
        (Some(load), _) => Quantity::Displacement {
            particle: load.particle,
            component: if load.force[1] != 0.0 { 1 } else { 0 },
        },
        (None, Some(c)) => Quantity::Reaction {
            constraint: config.constraints.len() - 1,
            component: (0..2)
                .rev()
                .find(|&a| c.displacement[a].is_some())
                .unwrap_or(0),
        },
        (None, None) => return Err("the scene has neither point loads nor constraints".into()),
    };
    let clock = Instant::now();
    let truth = run_recorded(&config, &initial, None)?;
    let plain = clock.elapsed().as_secs_f64();
    let items = (1..=config.load_steps)
        .map(|step| {
            let mut o = Observation {
                step,
                quantity,
                value: 0.0,
                sigma: 1.0,
            };
            o.value = 1.01 * ImplicitObservations::model(&o, &truth);
            o
        })
        .collect();
    let mut params = vec![ImplicitParam::Material(0, MaterialField::Young)];
    if matches!(config.materials[0].model, Model::J2(_)) {
        params.push(ImplicitParam::Material(0, MaterialField::YieldStress));
    }
    let problem = ImplicitProblem {
        config,
        initial,
        params,
        observations: ImplicitObservations { items },
    };
    let theta = problem.values()?;
    let g = problem.gradient(&theta)?;
    println!(
        "{path}: {} particles, {} load steps, {} accepted sub-steps, {} Newton iterations",
        problem.initial.len(),
        problem.config.load_steps,
        truth.substeps.len(),
        truth.iterations
    );
    println!(
        "forward run (recorded) {:.3} s, plain {plain:.3} s",
        g.forward_seconds
    );
    println!(
        "reverse pass {:.3} s, gradient/forward {:.3}",
        g.reverse_seconds,
        g.reverse_seconds / g.forward_seconds
    );
    for (p, d) in problem.params.iter().zip(&g.gradient) {
        println!("dL/d{p} = {d:.6e}");
    }
    if let Some(rss) = peak_rss_mib() {
        println!("peak RSS {rss:.1} MiB");
    }
    Ok(())
}
