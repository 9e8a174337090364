//! CSV tables and PNG line plots of verification histories.
//!
//! CSV here is columns of numbers with a header line: `std::fmt` does it in a few lines, so no
//! CSV crate is pulled in. Plots use plotters' bitmap backend with a bundled DejaVu Sans
//! (Bitstream Vera licence, `assets/DejaVuSans-LICENSE.txt`), registered through ab_glyph so
//! that no system font library is needed.

use crate::VerifyError;
use plotters::coord::types::RangedCoordf64;
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

/// Draws the series on one set of axes and writes a PNG (900 × 560, with a legend).
pub fn write_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> Result<(), VerifyError> {
    register_font();
    let (x, y) = ranges(series);
    let root = BitMapBackend::new(path, (900, 560)).into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error + '_>> {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .build_cartesian_2d(x, y)?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .draw()?;
        draw_series(&mut chart, series, 0)?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| io_err(path, e))
}

/// One panel of [`write_panels`]: its y-axis label (with the unit) and its curves.
#[derive(Clone, Debug)]
pub struct Panel {
    /// The y-axis label, with the unit.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Series>,
}

/// Writes `panels` as one PNG (900 wide, 240 a panel), stacked, each with its own y range
/// and legend over a shared x range, so that quantities of different magnitude (a Young's
/// modulus of 10⁶ Pa beside a Poisson's ratio of 0.3) each fill their panel. The x axis
/// counts iterations: its ticks are whole numbers. The series of all panels take the colours
/// in turn, so no two share one.
pub fn write_panels(
    path: &Path,
    title: &str,
    x_label: &str,
    panels: &[Panel],
) -> Result<(), VerifyError> {
    register_font();
    let all: Vec<Series> = panels.iter().flat_map(|p| p.series.clone()).collect();
    let (x, _) = ranges(&all);
    // At most one label per whole number: the "nice" steps plotters picks (1, 2, 5, 10, …
    // times a power of ten) are then whole numbers from 0.
    let labels = ((x.end - x.start).round() as usize + 1).clamp(2, 11);
    let height = 60 + 240 * panels.len().max(1) as u32;
    let root = BitMapBackend::new(path, (900, height)).into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error + '_>> {
        root.fill(&WHITE)?;
        let body = root.titled(title, ("sans-serif", 22))?;
        let mut colour = 0;
        for (area, panel) in body
            .split_evenly((panels.len().max(1), 1))
            .iter()
            .zip(panels)
        {
            let (_, y) = ranges(&panel.series);
            let mut chart = ChartBuilder::on(area)
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(90)
                .build_cartesian_2d(x.clone(), y)?;
            chart
                .configure_mesh()
                .x_desc(x_label)
                .y_desc(panel.y_label.as_str())
                .x_labels(labels)
                .x_label_formatter(&|v| format!("{v:.0}"))
                .y_label_formatter(&|v| tick(*v))
                .draw()?;
            draw_series(&mut chart, &panel.series, colour)?;
            colour += panel.series.len();
        }
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| io_err(path, e))
}

/// A y tick label: four significant digits, in exponent form outside `[10⁻³, 10⁴)`.
fn tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e4).contains(&a) {
        format!("{v:.3e}")
    } else {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        format!("{v:.decimals$}")
    }
}

/// The colours of the curves, in turn.
const COLOURS: [RGBColor; 8] = [
    BLUE,
    RED,
    GREEN,
    MAGENTA,
    CYAN,
    BLACK,
    RGBColor(230, 140, 0),
    RGBColor(120, 70, 20),
];

/// The x and y ranges of the finite points of `series`: the x range as it is (a unit range
/// where it is a point), the y range padded by 5 %.
fn ranges(series: &[Series]) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
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
    (x0..x1, (y0 - pad)..(y1 + pad))
}

/// Draws `series` on `chart` with their legend, colours from the `first`-th on.
fn draw_series<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    series: &[Series],
    first: usize,
) -> Result<(), Box<dyn std::error::Error + 'a>>
where
    DB::ErrorType: 'static,
{
    for (k, s) in series.iter().enumerate() {
        let colour = COLOURS[(first + k) % COLOURS.len()];
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
    Ok(())
}
