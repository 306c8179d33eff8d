//! A grouped bar chart (one cluster per group, one bar per series), for
//! summaries such as the evaluation suite's ATE per case and extractor.

use std::path::Path;

use plotters::prelude::*;

use super::error::Result;
use super::plot::{ensure_font, plot_error};

/// One series of a grouped bar chart: a name and a value per group
/// (`None`: no bar).
pub struct BarSeries {
    /// The legend's name.
    pub name: String,
    /// One value per group.
    pub values: Vec<Option<f64>>,
}

/// The bars' colours, in series order.
const COLOURS: [RGBColor; 4] = [
    RGBColor(200, 60, 40),
    RGBColor(90, 90, 200),
    RGBColor(0, 140, 70),
    RGBColor(150, 120, 0),
];

/// Writes a PNG with one cluster of bars per group, labelled below.
pub fn write_grouped_bar_plot(
    path: &Path,
    title: &str,
    y_label: &str,
    groups: &[String],
    series: &[BarSeries],
) -> Result<()> {
    ensure_font(path)?;
    let top = series
        .iter()
        .flat_map(|s| s.values.iter().flatten())
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0_f64, f64::max);
    let top = if top > 0.0 { top * 1.35 } else { 1.0 };
    let width = (240 + 90 * groups.len() as u32).clamp(800, 2400);
    let root = BitMapBackend::new(path, (width, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_error(path, e))?;
    let slots = series.len().max(1) as f64 + 1.0;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 26))
        .margin(20)
        .x_label_area_size(150)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..groups.len() as f64, 0.0..top)
        .map_err(|e| plot_error(path, e))?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(0)
        .y_desc(y_label)
        .axis_desc_style(("sans-serif", 20))
        .draw()
        .map_err(|e| plot_error(path, e))?;
    for (k, s) in series.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let bars = s.values.iter().enumerate().filter_map(|(g, v)| {
            let v = (*v).filter(|v| v.is_finite())?;
            let left = g as f64 + (k as f64 + 0.5) / slots;
            Some(Rectangle::new(
                [(left, 0.0), (left + 1.0 / slots, v.min(top))],
                colour.filled(),
            ))
        });
        chart
            .draw_series(bars)
            .map_err(|e| plot_error(path, e))?
            .label(s.name.clone())
            .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 16, y + 6)], colour.filled()));
    }
    // Group names under their clusters, written downwards.
    let style = ("sans-serif", 16)
        .into_font()
        .transform(FontTransform::Rotate90)
        .color(&BLACK);
    for (g, name) in groups.iter().enumerate() {
        let (x, y) = chart.backend_coord(&(g as f64 + 0.5, 0.0));
        root.draw(&Text::new(name.clone(), (x + 8, y + 8), style.clone()))
            .map_err(|e| plot_error(path, e))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 18))
        .draw()
        .map_err(|e| plot_error(path, e))?;
    root.present().map_err(|e| plot_error(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grouped_bar_plot_is_written_with_missing_bars() {
        let dir = std::env::temp_dir().join(format!("spslam_bar_plot_{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join("bars.png");
        let groups = vec!["a".to_string(), "b".to_string()];
        let series = [
            BarSeries {
                name: "one".into(),
                values: vec![Some(0.1), None],
            },
            BarSeries {
                name: "two".into(),
                values: vec![Some(0.3), Some(0.2)],
            },
        ];
        // `make setup` installs the font (fonts-dejavu-core).
        write_grouped_bar_plot(&path, "t", "y", &groups, &series).expect("plot");
        let png = std::fs::read(&path).expect("png");
        assert!(
            png.starts_with(b"\x89PNG") && png.len() > 1000,
            "{} bytes",
            png.len()
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
