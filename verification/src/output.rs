//! CSV tables and PNG line plots of verification histories.
//!
//! CSV here is columns of numbers with a header line: `std::fmt` does it in a few lines, so no
//! CSV crate is pulled in. Plots use plotters' bitmap backend with a bundled DejaVu Sans
//! (Bitstream Vera licence, `assets/DejaVuSans-LICENSE.txt`), registered through ab_glyph so
//! that no system font library is needed.

use crate::VerifyError;
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::Once;

/// A named curve; `markers` draws points instead of a line (for simulated samples).
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub name: String,
    /// `(x, y)` samples.
    pub points: Vec<(f64, f64)>,
    /// Draw markers instead of a line.
    pub markers: bool,
}

fn io_err(path: &Path, e: impl std::fmt::Display) -> VerifyError {
    VerifyError::Output {
        path: path.to_path_buf(),
        msg: e.to_string(),
    }
}

/// Writes a text file (Markdown tables of refinement studies).
pub fn write_text(path: &Path, text: &str) -> Result<(), VerifyError> {
    std::fs::write(path, text).map_err(|e| io_err(path, e))
}

/// Writes `header` and the rows as comma-separated values.
pub fn write_csv(path: &Path, header: &[&str], rows: &[Vec<f64>]) -> Result<(), VerifyError> {
    let mut s = header.join(",");
    s.push('\n');
    for r in rows {
        let line: Vec<String> = r.iter().map(|v| format!("{v:.10e}")).collect();
        writeln!(s, "{}", line.join(",")).expect("writing to a String cannot fail");
    }
    std::fs::write(path, s).map_err(|e| io_err(path, e))
}

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are a valid TrueType font shipped with the crate; failure is a build bug.
        plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            include_bytes!("../assets/DejaVuSans.ttf"),
        )
        .unwrap_or_else(|_| panic!("bundled DejaVuSans.ttf is not a valid font"));
    });
}

/// Draws the series on one set of axes and writes a PNG.
pub fn write_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> Result<(), VerifyError> {
    register_font();
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for s in series {
        for &(x, y) in s
            .points
            .iter()
            .filter(|(x, y)| x.is_finite() && y.is_finite())
        {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
    }
    if !(x0.is_finite() && y0.is_finite()) {
        // Nothing finite to draw: an empty unit frame.
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    if x1.partial_cmp(&x0) != Some(std::cmp::Ordering::Greater) {
        x1 = x0 + 1.0;
    }
    // A flat series gets a range of a millionth of its magnitude: a range below the
    // spacing of the numbers themselves would leave the axis no key points to find.
    let pad = 0.05
        * (y1 - y0)
            .abs()
            .max(1e-6 * y0.abs().max(y1.abs()))
            .max(1e-12);
    let root = BitMapBackend::new(path, (900, 560)).into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error + '_>> {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .draw()?;
        let colours = [BLUE, RED, GREEN, MAGENTA, CYAN, BLACK];
        for (k, s) in series.iter().enumerate() {
            let colour = colours[k % colours.len()];
            if s.markers {
                chart
                    .draw_series(s.points.iter().map(|&p| Circle::new(p, 2, colour.filled())))?
                    .label(s.name.as_str())
                    .legend(move |(x, y)| Circle::new((x + 10, y), 3, colour.filled()));
            } else {
                chart
                    .draw_series(LineSeries::new(
                        s.points.iter().copied(),
                        colour.stroke_width(2),
                    ))?
                    .label(s.name.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                    });
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| io_err(path, e))
}
