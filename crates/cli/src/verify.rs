//! `loam verify`: run verification cases and report each metric against its tolerance.

use crate::Outcome;
use loam_verification::{Bound, Case, Metric, Size, case, cases};
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

/// Runs the named cases (all when empty); exit 1 if any metric fails.
pub fn verify(
    names: &[String],
    list: bool,
    json: Option<&Path>,
    out: &Path,
    reduced: bool,
) -> Outcome {
    if list {
        for c in cases() {
            println!("{:<21} {}", c.name, c.description);
        }
        return Outcome::Ok;
    }
    let selected: Vec<Case> = if names.is_empty() {
        cases()
    } else {
        match names.iter().map(|n| case(n)).collect::<Result<_, _>>() {
            Ok(c) => c,
            Err(e) => {
                eprintln!("error: {e}");
                return Outcome::BadInput;
            }
        }
    };
    let size = if reduced { Size::Reduced } else { Size::Full };
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
        match (c.run)(size, &dir) {
            Ok(report) => {
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
                metrics.push(Metric::at_most(c.name, "run", f64::NAN, 0.0));
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
