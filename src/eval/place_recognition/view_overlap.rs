//! How much of one camera's view another camera sees: the ground truth of
//! place recognition. A grid of the query image's pixels is lifted to 3-D
//! with the query's depth (a depth image, or one nominal depth where the
//! sequence has none) and projected into the candidate camera; a pixel
//! counts when it lands inside the candidate's image in front of it and,
//! where the candidate has a depth image, is not hidden behind a nearer
//! surface there, and when the candidate sees it at a similar scale and from
//! a similar direction ([`MAX_DISTANCE_RATIO`], [`MAX_VIEW_ANGLE_DEG`]): a
//! wall seen from five times as far, or from the side, is in view but is
//! not the same picture, and no descriptor matches it.

use nalgebra::{Isometry3, Point3};

/// A pinhole camera (no distortion) and its image size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OverlapCamera {
    /// Focal length in x, pixels.
    pub fx: f64,
    /// Focal length in y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
}

/// Depth along the optical axis (metres) of one camera's view.
#[derive(Debug, Clone, PartialEq)]
pub enum SceneDepth {
    /// One depth for every pixel: a frustum overlap at a nominal distance,
    /// for sequences without depth images.
    Nominal(f64),
    /// A depth image sampled every `step` pixels (row-major, `cols` ×
    /// `rows` samples; 0 or non-finite where unknown).
    Sampled {
        /// Pixels between samples.
        step: usize,
        /// Samples per row.
        cols: usize,
        /// Rows of samples.
        rows: usize,
        /// The depths.
        depth: Vec<f32>,
    },
}

/// Relative difference between a projected point's depth and the
/// candidate's depth image above which the point is hidden there.
pub const OCCLUSION_TOLERANCE: f64 = 0.1;

impl SceneDepth {
    /// Samples a full-resolution depth image (`width` × `height`,
    /// row-major, metres) every `step` pixels.
    pub fn sample(depth: &[f32], width: usize, height: usize, step: usize) -> Self {
        let step = step.max(1);
        let cols = width.div_ceil(step);
        let rows = height.div_ceil(step);
        let mut sampled = Vec::with_capacity(cols * rows);
        for r in 0..rows {
            for c in 0..cols {
                sampled.push(
                    depth
                        .get(r * step * width + c * step)
                        .copied()
                        .unwrap_or(0.0),
                );
            }
        }
        Self::Sampled {
            step,
            cols,
            rows,
            depth: sampled,
        }
    }

    /// The depth at pixel (`u`, `v`): the nearest sample; `None` where unknown.
    pub fn at(&self, u: f64, v: f64) -> Option<f64> {
        match self {
            Self::Nominal(d) => Some(*d),
            Self::Sampled {
                step,
                cols,
                rows,
                depth,
            } => {
                let c = (u / *step as f64).round();
                let r = (v / *step as f64).round();
                if c < 0.0 || r < 0.0 || c >= *cols as f64 || r >= *rows as f64 {
                    return None;
                }
                let d = f64::from(depth[r as usize * cols + c as usize]);
                (d.is_finite() && d > 0.0).then_some(d)
            }
        }
    }
}

/// Largest ratio between the two cameras' distances to a point for it to
/// count: twice as far (or half) is a scale change a one-level SuperPoint
/// or the first levels of ORB's pyramid (1.2 per level) still match.
pub const MAX_DISTANCE_RATIO: f64 = 2.0;
/// Largest angle between the two cameras' rays to a point for it to count.
/// The EuRoC loop pair, a real revisit, is 37.5° apart.
pub const MAX_VIEW_ANGLE_DEG: f64 = 60.0;

/// Grid samples per image side used by [`view_overlap`] (`GRID` × `GRID`).
pub const GRID: usize = 24;

/// The fraction of the query's view (grid pixels with a known depth) that
/// the candidate camera sees. Poses are camera-to-world. 0 when the query
/// has no pixel with a known depth.
pub fn view_overlap(
    camera: &OverlapCamera,
    query_to_world: &Isometry3<f64>,
    query_depth: &SceneDepth,
    candidate_to_world: &Isometry3<f64>,
    candidate_depth: &SceneDepth,
) -> f64 {
    let query_to_candidate = candidate_to_world.inverse() * query_to_world;
    // The candidate's centre in the query's frame.
    let candidate_centre = query_to_candidate.inverse() * Point3::origin();
    let (w, h) = (camera.width as f64, camera.height as f64);
    let mut known = 0usize;
    let mut seen = 0usize;
    for gy in 0..GRID {
        for gx in 0..GRID {
            let u = (gx as f64 + 0.5) * w / GRID as f64;
            let v = (gy as f64 + 0.5) * h / GRID as f64;
            let Some(z) = query_depth.at(u, v) else {
                continue;
            };
            known += 1;
            let p = Point3::new(
                (u - camera.cx) / camera.fx * z,
                (v - camera.cy) / camera.fy * z,
                z,
            );
            let q = query_to_candidate * p;
            if q.z <= 0.0 {
                continue;
            }
            let uc = camera.fx * q.x / q.z + camera.cx;
            let vc = camera.fy * q.y / q.z + camera.cy;
            if uc < 0.0 || vc < 0.0 || uc >= w || vc >= h {
                continue;
            }
            let hidden = match candidate_depth {
                SceneDepth::Nominal(_) => false,
                sampled => sampled
                    .at(uc, vc)
                    .is_some_and(|dc| dc < q.z * (1.0 - OCCLUSION_TOLERANCE)),
            };
            // Distances and rays from both camera centres (query frame).
            let from_query = p.coords;
            let from_candidate = p - candidate_centre;
            let ratio = from_candidate.norm() / from_query.norm();
            let similar_scale = (1.0 / MAX_DISTANCE_RATIO..=MAX_DISTANCE_RATIO).contains(&ratio);
            let similar_direction =
                from_query.angle(&from_candidate) <= MAX_VIEW_ANGLE_DEG.to_radians();
            if !hidden && similar_scale && similar_direction {
                seen += 1;
            }
        }
    }
    if known == 0 {
        0.0
    } else {
        seen as f64 / known as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    const CAMERA: OverlapCamera = OverlapCamera {
        fx: 320.0,
        fy: 320.0,
        cx: 320.0,
        cy: 240.0,
        width: 640,
        height: 480,
    };

    fn pose(x: f64, yaw_deg: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(x, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), yaw_deg.to_radians()),
        )
    }

    #[test]
    fn the_same_pose_sees_everything_and_a_turned_back_camera_nothing() {
        let d = SceneDepth::Nominal(10.0);
        let same = view_overlap(&CAMERA, &pose(0.0, 0.0), &d, &pose(0.0, 0.0), &d);
        assert_eq!(same, 1.0);
        let back = view_overlap(&CAMERA, &pose(0.0, 0.0), &d, &pose(0.0, 180.0), &d);
        assert_eq!(back, 0.0);
    }

    #[test]
    fn a_sideways_shift_by_half_the_view_leaves_half_of_it() {
        // At 10 m the view is 2 × 10 × 320 / 320 = 20 m wide; a 10 m shift
        // to the right leaves the right half of the query's view.
        let d = SceneDepth::Nominal(10.0);
        let o = view_overlap(&CAMERA, &pose(0.0, 0.0), &d, &pose(10.0, 0.0), &d);
        assert!((o - 0.5).abs() < 1e-9, "{o}");
        // A turn of the field's half angle (atan(1) = 45°) about the
        // camera's centre also leaves half.
        let t = view_overlap(&CAMERA, &pose(0.0, 0.0), &d, &pose(0.0, -45.0), &d);
        assert!((t - 0.5).abs() < 0.05, "{t}");
    }

    #[test]
    fn a_view_from_far_away_or_from_the_side_does_not_count() {
        let d = SceneDepth::Nominal(10.0);
        let query = pose(0.0, 0.0);
        // Backed off 25 m along the axis: the whole view is in the picture,
        // 3.5 times as far at its centre and 2.4 times at its corners.
        let far = Isometry3::translation(0.0, 0.0, -25.0);
        assert_eq!(view_overlap(&CAMERA, &query, &d, &far, &d), 0.0);
        // Backed off 5 m: 1.5 times as far, every point counts.
        let near = Isometry3::translation(0.0, 0.0, -5.0);
        assert_eq!(view_overlap(&CAMERA, &query, &d, &near, &d), 1.0);
        // The centre of the view from the side, at the same distance: at
        // 30° all of it counts, at 70° only the part nearest the second
        // camera (rays within 60°), less than half.
        let from_side = |deg: f64| {
            let a = deg.to_radians();
            let side = Isometry3::from_parts(
                Translation3::new(-10.0 * a.sin(), 0.0, 10.0 - 10.0 * a.cos()),
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), a),
            );
            view_overlap(&CAMERA, &query, &d, &side, &d)
        };
        assert!(from_side(30.0) > 0.7, "{}", from_side(30.0));
        let o = from_side(70.0);
        assert!(o > 0.2 && o < 0.5, "{o}");
    }

    #[test]
    fn a_nearer_surface_in_the_candidate_hides_the_query_points() {
        let far = SceneDepth::sample(&vec![10.0; 640 * 480], 640, 480, 4);
        let wall = SceneDepth::sample(&vec![2.0; 640 * 480], 640, 480, 4);
        let query = pose(0.0, 0.0);
        let open = view_overlap(&CAMERA, &query, &far, &pose(0.0, 0.0), &far);
        assert_eq!(open, 1.0);
        let blocked = view_overlap(&CAMERA, &query, &far, &pose(0.0, 0.0), &wall);
        assert_eq!(blocked, 0.0);
        // Unknown depth in the query: nothing to compare.
        let none = SceneDepth::sample(&vec![0.0; 640 * 480], 640, 480, 4);
        assert_eq!(view_overlap(&CAMERA, &query, &none, &query, &far), 0.0);
    }
}
