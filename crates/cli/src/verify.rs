//! `loam verify`: run verification cases and report each metric against its tolerance.

use loam_driver::Outcome;
use loam_verification::{Bound, Case, Device, Metric, Size, case, cases};
use std::path::Path;
use std::time::Instant;

/// One row of the report: case, metric, value, bound and tolerance, and the result
/// (`pass`, `FAIL`, or `info` for a metric without tolerance).
fn metric_line(m: &Metric) -> String {
    let (bound, tolerance, result) = match (m.bound, m.tolerance) {
        (Bound::Info, _) | (_, None) => (" ", "-".to_string(), "info"),
        (Bound::Upper, Some(t)) => ("≤", format!("{t:.4e}"), pass_fail(m.passed)),
        (Bound::Lower, Some(t)) => ("≥", format!("{t:.4e}"), pass_fail(m.passed)),
    };
    format!(
        "{:<21} {:<44} {:>12.4e} {bound} {:>10}  {result}",
        m.case, m.metric, m.value, tolerance
    )
}

fn pass_fail(passed: bool) -> &'static str {
    if passed { "pass" } else { "FAIL" }
}

/// Runs the named cases (all when empty; on the GPU, all that run there); exit 1 if any
/// metric fails. With `gpu` the cases' explicit runs step on the first GPU adapter, their
/// files go to `out/gpu/CASE` and their metrics are reported as `CASE/gpu`; a case that runs
/// on the CPU only is refused (exit 2), no adapter is a failure (exit 1).
pub fn verify(
    names: &[String],
    list: bool,
    json: Option<&Path>,
    out: &Path,
    reduced: bool,
    gpu: bool,
) -> Outcome {
    if list {
        for c in cases() {
            let device = if c.on_gpu() { "cpu, gpu" } else { "cpu" };
            println!("{:<21} [{device}] {}", c.name, c.description);
        }
        return Outcome::Ok;
    }
    let selected: Vec<Case> = if names.is_empty() {
        cases().into_iter().filter(|c| !gpu || c.on_gpu()).collect()
    } else {
        match names.iter().map(|n| case(n)).collect::<Result<Vec<_>, _>>() {
            Ok(c) => c,
            Err(e) => {
                eprintln!("error: {e}");
                return Outcome::BadInput;
            }
        }
    };
    if let Some(e) = selected.iter().find_map(|c| c.check_device(gpu).err()) {
        eprintln!("error: {e}");
        return Outcome::BadInput;
    }
    let (device, out) = if gpu {
        match loam_driver::run::gpu::device(None) {
            Ok(g) => (Device::Gpu(Box::new(g)), out.join("gpu")),
            Err(e) => {
                eprintln!("error: {e}");
                return Outcome::Failed;
            }
        }
    } else {
        (Device::Cpu, out.to_path_buf())
    };
    let size = if reduced { Size::Reduced } else { Size::Full };
    println!("device: {}", device.name());
    let mut metrics: Vec<Metric> = Vec::new();
    let mut failed = false;
    println!(
        "{:<21} {:<44} {:>12} {:>12}  result",
        "case", "metric", "value", "tolerance"
    );
    for c in selected {
        let dir = out.join(c.name);
        if let Err(e) = std::fs::create_dir_all(&dir) {
            eprintln!("error: cannot create {}: {e}", dir.display());
            return Outcome::Failed;
        }
        let start = Instant::now();
        match c.run(size, &device, &dir) {
            Ok(mut report) => {
                if gpu {
                    for m in &mut report.metrics {
                        m.case = format!("{}/gpu", m.case);
                    }
                }
                for m in &report.metrics {
                    println!("{}", metric_line(m));
                    failed |= !m.passed;
                }
                let files: Vec<String> = report
                    .files
                    .iter()
                    .map(|f| f.display().to_string())
                    .collect();
                println!(
                    "{:<21} ({:.1} s; wrote {})",
                    "",
                    start.elapsed().as_secs_f64(),
                    files.join(", ")
                );
                metrics.extend(report.metrics);
            }
            Err(e) => {
                println!(
                    "{:<21} {:<44} {:>12} {:>12}  FAIL ({e})",
                    c.name, "run", "-", "-"
                );
                let name = if gpu {
                    format!("{}/gpu", c.name)
                } else {
                    c.name.to_string()
                };
                metrics.push(Metric::at_most(&name, "run", f64::NAN, 0.0));
                failed = true;
            }
        }
    }
    if let Some(path) = json {
        let text = serde_json::to_string_pretty(&metrics).expect("metrics serialise");
        if let Err(e) = std::fs::write(path, text) {
            eprintln!("error: cannot write {}: {e}", path.display());
            return Outcome::Failed;
        }
    }
    if failed { Outcome::Failed } else { Outcome::Ok }
}
