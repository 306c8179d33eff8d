//! PNG plots of trajectories and errors (plotters).

use std::path::Path;

use plotters::prelude::*;

use super::ate::position_errors;
use super::error::{EvalError, Result};
use super::trajectory::Trajectory;

/// Image size of the plots.
pub const PLOT_SIZE: (u32, u32) = (1000, 800);

/// The plane of a top view (evo's plot modes `xy`, `xz`, `yz`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlotPlane {
    /// x–z: KITTI's camera frame (x right, z forward).
    Xz,
    /// x–y: TUM, EuRoC and other world frames with z up.
    Xy,
    /// y–z.
    Yz,
}

impl PlotPlane {
    /// The plane of the two axes along which `trajectory`'s positions
    /// spread most (their range, max − min), so that a top view is never
    /// drawn edge-on: a camera-frame trajectory (y down) gives x–z, a
    /// world frame with z up gives x–y. x–y for an empty trajectory; on a
    /// tie the earlier axis wins.
    pub fn of_largest_extent(trajectory: &Trajectory) -> Self {
        let extent = |axis: usize| {
            let values = trajectory.poses.iter().map(|p| p.translation.vector[axis]);
            let (low, high) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
            if high >= low {
                high - low
            } else {
                0.0
            }
        };
        let extents = [extent(0), extent(1), extent(2)];
        // Leave out the axis of least extent (the later one on a tie).
        let dropped = (0..3)
            .rev()
            .min_by(|&a, &b| extents[a].total_cmp(&extents[b]))
            .unwrap_or(2);
        match dropped {
            0 => Self::Yz,
            1 => Self::Xz,
            _ => Self::Xy,
        }
    }

    /// The plane's name as in evo's plot modes: `xy`, `xz` or `yz`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Xz => "xz",
            Self::Xy => "xy",
            Self::Yz => "yz",
        }
    }

    fn project(self, v: &nalgebra::Vector3<f64>) -> (f64, f64) {
        match self {
            Self::Xz => (v.x, v.z),
            Self::Xy => (v.x, v.y),
            Self::Yz => (v.y, v.z),
        }
    }

    fn labels(self) -> (&'static str, &'static str) {
        match self {
            Self::Xz => ("x [m]", "z [m]"),
            Self::Xy => ("x [m]", "y [m]"),
            Self::Yz => ("y [m]", "z [m]"),
        }
    }
}

/// Font files tried for the plots' text, after `SPSLAM_FONT`.
const FONT_CANDIDATES: [&str; 2] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
];

/// Registers a TrueType font as "sans-serif" once per process. The font is
/// read at run time (pure Rust rendering: the library links no freetype or
/// fontconfig, which matters for the C++ users of `libspslam.a`).
pub(super) fn ensure_font(path: &Path) -> Result<()> {
    static REGISTERED: std::sync::OnceLock<std::result::Result<(), String>> =
        std::sync::OnceLock::new();
    let outcome = REGISTERED.get_or_init(|| {
        let candidates: Vec<std::path::PathBuf> = std::env::var_os("SPSLAM_FONT")
            .map(std::path::PathBuf::from)
            .into_iter()
            .chain(FONT_CANDIDATES.iter().map(std::path::PathBuf::from))
            .collect();
        for candidate in &candidates {
            if let Ok(bytes) = std::fs::read(candidate) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                return plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
                    .map_err(|_| format!("{} is not a usable TrueType font", candidate.display()));
            }
        }
        Err(format!(
            "no font found for the plot's text (tried {}); install fonts-dejavu-core or set SPSLAM_FONT",
            candidates.iter().map(|c| c.display().to_string()).collect::<Vec<_>>().join(", ")
        ))
    });
    outcome.clone().map_err(|message| plot_error(path, message))
}

pub(super) fn plot_error(path: &Path, e: impl std::fmt::Display) -> EvalError {
    EvalError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// A range covering `values` with a margin, never empty (degenerate ranges widened by 1).
fn padded_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() || !hi.is_finite() {
        return (-1.0, 1.0);
    }
    if hi - lo < 1e-9 {
        lo -= 1.0;
        hi += 1.0;
    }
    let margin = 0.05 * (hi - lo);
    (lo - margin, hi + margin)
}

/// Widens the smaller of two ranges so that both axes have the same metres per pixel.
fn equal_aspect(x: (f64, f64), y: (f64, f64)) -> ((f64, f64), (f64, f64)) {
    let (w, h) = (PLOT_SIZE.0 as f64, PLOT_SIZE.1 as f64);
    let per_px = ((x.1 - x.0) / w).max((y.1 - y.0) / h);
    let grow = |r: (f64, f64), px: f64| {
        let c = 0.5 * (r.0 + r.1);
        (c - 0.5 * per_px * px, c + 0.5 * per_px * px)
    };
    (grow(x, w), grow(y, h))
}

/// Draws the estimate over the ground truth, seen from above in `plane`.
pub fn write_trajectory_plot(
    gt: &Trajectory,
    est: &Trajectory,
    path: &Path,
    plane: PlotPlane,
) -> Result<()> {
    write_trajectory_plot_with_links(gt, est, path, plane, &[])
}

/// The index of the estimate pose whose timestamp is nearest `t`.
fn nearest_pose(est: &Trajectory, t: f64) -> Option<usize> {
    est.timestamps
        .iter()
        .enumerate()
        .min_by(|a, b| (a.1 - t).abs().total_cmp(&(b.1 - t).abs()))
        .map(|(i, _)| i)
}

/// [`write_trajectory_plot`] with `links`, pairs of estimate timestamps
/// (loop closures: the query and the matched frame), drawn as green lines
/// between the two estimated positions.
pub fn write_trajectory_plot_with_links(
    gt: &Trajectory,
    est: &Trajectory,
    path: &Path,
    plane: PlotPlane,
    links: &[(f64, f64)],
) -> Result<()> {
    ensure_font(path)?;
    let project = |t: &Trajectory| -> Vec<(f64, f64)> {
        t.poses
            .iter()
            .map(|p| plane.project(&p.translation.vector))
            .collect()
    };
    let (g, e) = (project(gt), project(est));
    let x = padded_range(g.iter().chain(&e).map(|p| p.0));
    let y = padded_range(g.iter().chain(&e).map(|p| p.1));
    let (x, y) = equal_aspect(x, y);
    let root = BitMapBackend::new(path, PLOT_SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_error(path, e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption("Trajectory (top view)", ("sans-serif", 28))
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)
        .map_err(|e| plot_error(path, e))?;
    let (xl, yl) = plane.labels();
    chart
        .configure_mesh()
        .x_desc(xl)
        .y_desc(yl)
        .axis_desc_style(("sans-serif", 20))
        .draw()
        .map_err(|e| plot_error(path, e))?;
    chart
        .draw_series(LineSeries::new(g.clone(), RED.stroke_width(2)))
        .map_err(|e| plot_error(path, e))?
        .label("ground truth")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
    chart
        .draw_series(LineSeries::new(e.clone(), BLUE.stroke_width(2)))
        .map_err(|e| plot_error(path, e))?
        .label("estimate")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE.stroke_width(2)));
    let segments: Vec<Vec<(f64, f64)>> = links
        .iter()
        .filter_map(|(a, b)| {
            let (i, j) = (nearest_pose(est, *a)?, nearest_pose(est, *b)?);
            Some(vec![*e.get(i)?, *e.get(j)?])
        })
        .collect();
    if !segments.is_empty() {
        let green = RGBColor(0, 150, 0);
        chart
            .draw_series(
                segments
                    .into_iter()
                    .map(|s| PathElement::new(s, green.stroke_width(3))),
            )
            .map_err(|e| plot_error(path, e))?
            .label("loop closures")
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], green.stroke_width(3))
            });
    }
    if let Some(&start) = g.first() {
        chart
            .draw_series(std::iter::once(Circle::new(start, 6, BLACK.filled())))
            .map_err(|e| plot_error(path, e))?
            .label("start")
            .legend(|(x, y)| Circle::new((x + 10, y), 5, BLACK.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 20))
        .draw()
        .map_err(|e| plot_error(path, e))?;
    root.present().map_err(|e| plot_error(path, e))
}

/// Draws the position error |p_gt − p_est| of corresponding poses over the
/// distance travelled along the ground truth.
pub fn write_error_plot(gt: &Trajectory, est: &Trajectory, path: &Path) -> Result<()> {
    ensure_font(path)?;
    let distances = gt.distances();
    let errors = position_errors(gt, est);
    let points: Vec<(f64, f64)> = distances
        .iter()
        .copied()
        .zip(errors.iter().copied())
        .collect();
    let x = padded_range(distances.iter().copied());
    let y_max = errors
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let y = (0.0, if y_max > 1e-9 { 1.05 * y_max } else { 1.0 });
    let root = BitMapBackend::new(path, PLOT_SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_error(path, e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption("Translation error over distance", ("sans-serif", 28))
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(x.0.max(0.0)..x.1, y.0..y.1)
        .map_err(|e| plot_error(path, e))?;
    chart
        .configure_mesh()
        .x_desc("distance travelled [m]")
        .y_desc("translation error [m]")
        .axis_desc_style(("sans-serif", 20))
        .draw()
        .map_err(|e| plot_error(path, e))?;
    chart
        .draw_series(LineSeries::new(points, BLUE.stroke_width(2)))
        .map_err(|e| plot_error(path, e))?;
    root.present().map_err(|e| plot_error(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    /// A trajectory through `points`.
    fn through(points: &[[f64; 3]]) -> Trajectory {
        Trajectory::from_poses(
            points
                .iter()
                .map(|p| {
                    Isometry3::from_parts(
                        Translation3::new(p[0], p[1], p[2]),
                        UnitQuaternion::identity(),
                    )
                })
                .collect(),
        )
    }

    #[test]
    fn the_plane_of_largest_extent_leaves_out_the_flattest_axis() {
        // A camera-frame square (y down, nearly constant): x–z.
        let camera = through(&[
            [0.0, 0.1, 0.0],
            [5.0, 0.0, 0.0],
            [5.0, 0.2, 4.0],
            [0.0, 0.0, 4.0],
        ]);
        assert_eq!(PlotPlane::of_largest_extent(&camera), PlotPlane::Xz);
        // A world frame with z up: x–y.
        let world = through(&[[0.0, 0.0, 1.0], [3.0, 2.0, 1.1], [1.0, 6.0, 0.9]]);
        assert_eq!(PlotPlane::of_largest_extent(&world), PlotPlane::Xy);
        // Motion in y–z only: y–z.
        let side = through(&[[0.0, 0.0, 0.0], [0.01, 3.0, 1.0], [0.0, -2.0, 5.0]]);
        assert_eq!(PlotPlane::of_largest_extent(&side), PlotPlane::Yz);
        // Degenerate cases: x–y.
        assert_eq!(PlotPlane::of_largest_extent(&through(&[])), PlotPlane::Xy);
        assert_eq!(
            PlotPlane::of_largest_extent(&through(&[[1.0, 2.0, 3.0]])),
            PlotPlane::Xy
        );
        // A straight line along z: z and the earlier of the flat axes.
        let line = through(&[[0.0, 0.0, 0.0], [0.0, 0.0, 9.0]]);
        assert_eq!(PlotPlane::of_largest_extent(&line), PlotPlane::Xz);
    }
}
