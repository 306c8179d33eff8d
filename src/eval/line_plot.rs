//! Stacked line charts sharing one x axis (one panel per quantity), for
//! series sampled over a run such as a soak run's memory and map size.

use std::path::Path;

use plotters::prelude::*;

use super::error::Result;
use super::plot::{ensure_font, plot_error};

/// One line: a legend name and its `(x, y)` points.
pub struct LineSeries {
    /// The legend's name.
    pub name: String,
    /// The points, in x order.
    pub points: Vec<(f64, f64)>,
}

/// One panel: a y-axis label and the lines drawn in it.
pub struct LinePanel {
    /// The y axis' label.
    pub y_label: String,
    /// The lines.
    pub series: Vec<LineSeries>,
}

/// The lines' colours, in series order within a panel.
const COLOURS: [RGBColor; 4] = [
    RGBColor(200, 60, 40),
    RGBColor(90, 90, 200),
    RGBColor(0, 140, 70),
    RGBColor(150, 120, 0),
];

/// The range of `values` with some headroom; `0..1` when there are none.
fn padded_range(values: impl Iterator<Item = f64>, from_zero: bool) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return 0.0..1.0;
    }
    let lo = if from_zero { lo.min(0.0) } else { lo };
    let span = (hi - lo).max(hi.abs() * 1e-3).max(1e-9);
    lo..hi + 0.08 * span
}

/// Writes a PNG with the panels stacked top to bottom over a shared x axis;
/// every panel's y axis starts at zero, so that growth reads as it is.
pub fn write_line_panels(
    path: &Path,
    title: &str,
    x_label: &str,
    panels: &[LinePanel],
) -> Result<()> {
    ensure_font(path)?;
    let x_range = padded_range(
        panels
            .iter()
            .flat_map(|p| p.series.iter().flat_map(|s| s.points.iter().map(|p| p.0))),
        false,
    );
    let height = 120 + 320 * panels.len().max(1) as u32;
    let root = BitMapBackend::new(path, (1100, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_error(path, e))?;
    let root = root
        .titled(title, ("sans-serif", 26))
        .map_err(|e| plot_error(path, e))?;
    let areas = root.split_evenly((panels.len().max(1), 1));
    for (panel, area) in panels.iter().zip(areas.iter()) {
        let y_range = padded_range(
            panel
                .series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.1)),
            true,
        );
        let mut chart = ChartBuilder::on(area)
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(80)
            .build_cartesian_2d(x_range.clone(), y_range)
            .map_err(|e| plot_error(path, e))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(panel.y_label.as_str())
            .axis_desc_style(("sans-serif", 18))
            .draw()
            .map_err(|e| plot_error(path, e))?;
        for (i, series) in panel.series.iter().enumerate() {
            let colour = COLOURS[i % COLOURS.len()];
            chart
                .draw_series(plotters::series::LineSeries::new(
                    series.points.iter().copied(),
                    colour.stroke_width(2),
                ))
                .map_err(|e| plot_error(path, e))?
                .label(series.name.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 16))
            .draw()
            .map_err(|e| plot_error(path, e))?;
    }
    root.present().map_err(|e| plot_error(path, e))?;
    Ok(())
}
