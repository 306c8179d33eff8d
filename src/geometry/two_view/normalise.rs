//! Hartley-style normalisation, as ORB-SLAM3's `TwoViewReconstruction::Normalize`:
//! translate to the centroid, scale each axis so its mean absolute deviation is 1.

use nalgebra::{Matrix3, Point2};

/// Points after normalisation, with the transform that produced them.
#[derive(Debug, Clone)]
pub(crate) struct Normalised {
    /// `T · p` for every input point.
    pub points: Vec<Point2<f64>>,
    /// The normalising transform `T` (pixels to normalised coordinates).
    pub transform: Matrix3<f64>,
}

/// Smallest mean absolute deviation (pixels) accepted on either axis; below it the
/// points are (nearly) all identical and no model can be fitted.
const MIN_MEAN_DEVIATION: f64 = 1e-9;

/// Normalises `points`; `None` when they are empty, not finite, or collapse
/// onto a line parallel to an axis or a single point (zero deviation on an axis).
pub(crate) fn normalise(points: &[Point2<f64>]) -> Option<Normalised> {
    if points.is_empty() {
        return None;
    }
    let n = points.len() as f64;
    let (sx, sy) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p.x, b + p.y));
    let (mean_x, mean_y) = (sx / n, sy / n);
    let (dx, dy) = points.iter().fold((0.0, 0.0), |(a, b), p| {
        (a + (p.x - mean_x).abs(), b + (p.y - mean_y).abs())
    });
    let (dev_x, dev_y) = (dx / n, dy / n);
    // Written so that NaN deviations reject.
    let spread = dev_x > MIN_MEAN_DEVIATION && dev_y > MIN_MEAN_DEVIATION;
    let finite = [mean_x, mean_y, dev_x, dev_y].iter().all(|v| v.is_finite());
    if !spread || !finite {
        return None;
    }
    let (scale_x, scale_y) = (1.0 / dev_x, 1.0 / dev_y);
    let normalised = points
        .iter()
        .map(|p| Point2::new((p.x - mean_x) * scale_x, (p.y - mean_y) * scale_y))
        .collect();
    #[rustfmt::skip]
    let transform = Matrix3::new(
        scale_x, 0.0, -mean_x * scale_x,
        0.0, scale_y, -mean_y * scale_y,
        0.0, 0.0, 1.0,
    );
    Some(Normalised {
        points: normalised,
        transform,
    })
}
