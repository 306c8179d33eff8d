//! How far a start's pose may lie from where the camera was predicted to
//! be. On a repeated pattern (a façade's identical windows) descriptor
//! matching and PnP can land on another instance of the pattern, a period
//! away, and local-map tracking then finds plenty of inliers there too; the
//! camera cannot have moved there between two frames.

use nalgebra::Vector3;

use super::frame::Frame;
use crate::map::Map;
use crate::optim::{LieGroup, Se3};

/// How far another start's pose may lie from the motion model's, once the
/// motion model's pose holds the local map's inliers, unless it has more
/// than twice as many: one step of the constant velocity. ORB-SLAM3's
/// `Track` keeps an accepted motion-model pose; this tracker also tries
/// the reference keyframe when the prediction kept fewer than half its
/// matches, and on a repeated pattern (a façade's identical windows) that
/// start can land on another instance of the pattern, a period away, with
/// somewhat more inliers (1.02 to 1.80 times over 33 such frames of the
/// suite's repeated-texture RGB-D lap). The camera cannot have moved
/// there between frames. A pose within a step (the same place, turned or
/// refined) still replaces it by inliers, and so does one with more than
/// twice its inliers, where the motion model's pose was the wrong one (3.2
/// to 7.3 times on the turn in place, where the camera barely moves and
/// the right pose lay 5-94 cm away, and on the noisy lap with ORB).
#[derive(Debug, Clone, Copy)]
pub(crate) struct StepLimit {
    /// The motion model's camera centre (world).
    centre: Vector3<f64>,
    /// The constant velocity's translation, the camera's last step.
    pub(crate) step: f64,
    /// The motion model's local-map inliers.
    inliers: usize,
}

impl StepLimit {
    /// The limit around `frame`'s current pose and its `inliers`, from the
    /// tracker's velocity; `None` without one.
    pub(crate) fn around(frame: &Frame, inliers: usize, velocity: Option<&Se3>) -> Option<Self> {
        velocity.map(|v| Self {
            centre: frame.camera_center(),
            step: v.translation.norm(),
            inliers,
        })
    }

    /// How far `frame`'s camera centre lies from the motion model's.
    pub(crate) fn distance(&self, frame: &Frame) -> f64 {
        (frame.camera_center() - self.centre).norm()
    }

    /// Whether `frame`'s pose, with `inliers` local-map inliers, is a jump
    /// the motion model's pose is kept against: farther than a step from
    /// it, with at most twice its inliers.
    pub(crate) fn is_jump(&self, frame: &Frame, inliers: usize) -> bool {
        self.distance(frame) > self.step && inliers <= 2 * self.inliers
    }
}

/// A pose found around the rotation the images show may lie at most this
/// fraction of the scene's median depth from the prediction, when that is
/// more than a step (a camera turning in place barely moves).
const PREDICTION_DEPTH_FRACTION: f64 = 0.1;

/// How far a pose tracked from the motion model's search around the
/// images' rotation ([`super::motion::image_rotation_velocity`]: the
/// constant velocity's translation with the rotation the thumbnails show)
/// may lie from the constant velocity's prediction: one step, or a tenth
/// of the scene's median depth if that is more. That start changes only
/// the rotation; over the suite's standard set its poses either lay within
/// 0.36 of a step of the prediction (nine frames in seven runs, 0.01 to
/// 0.38 m off the truth's step) or 2.72 to 2.95 steps away (three frames
/// on the repeated-texture laps, each a façade period, 2.78 to 3.01 m
/// off), after a thumbnail rotation 7° off had let the search match the
/// windows one period along. ORB-SLAM3 has no such start.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PredictionLimit {
    /// The predicted camera centre (world).
    centre: Vector3<f64>,
    /// The constant velocity's translation, the camera's last step.
    step: f64,
}

impl PredictionLimit {
    /// The limit around the constant velocity's prediction from the last
    /// frame's pose; `None` without a velocity.
    pub(crate) fn new(last_pose_cw: &Se3, velocity: Option<&Se3>) -> Option<Self> {
        velocity.map(|v| Self {
            centre: v.compose(last_pose_cw).inverse().translation,
            step: v.translation.norm(),
        })
    }

    /// How far `frame`'s pose lies from the prediction, and how far it may
    /// (at `frame`'s matched points' median depth); `None` when it lies
    /// within the limit.
    pub(crate) fn exceeded(&self, frame: &Frame, map: &Map) -> Option<(f64, f64)> {
        let distance = (frame.camera_center() - self.centre).norm();
        let allowed = self
            .step
            .max(PREDICTION_DEPTH_FRACTION * median_depth(frame, map).unwrap_or(0.0));
        (distance > allowed).then_some((distance, allowed))
    }
}

/// The median depth of `frame`'s matched map points in its camera (ORB-SLAM3's
/// `ComputeSceneMedianDepth`); `None` without a point in front.
fn median_depth(frame: &Frame, map: &Map) -> Option<f64> {
    let mut depths: Vec<f64> = frame
        .map_points
        .iter()
        .flatten()
        .filter_map(|id| map.map_point(*id).ok())
        .map(|p| frame.pose_cw.transform_point(&p.position).z)
        .filter(|z| *z > 0.0)
        .collect();
    crate::stats::upper_median(&mut depths)
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::{PredictionLimit, StepLimit};
    use crate::map::Map;
    use crate::optim::{LieGroup, Se3};
    use crate::test_world::{pose_at, PointWorld};

    #[test]
    fn a_pose_a_period_away_is_a_jump_unless_it_has_twice_the_inliers() {
        let world = PointWorld::new(5, 200, (14.0, 5.0, 4.0, 40.0));
        // The motion model's pose: 1 m past the last frame (the step), 100 inliers.
        let motion_model_pose = pose_at(Vector3::new(0.0, 0.0, 1.0), 0.0);
        let (mut frame, _) = world.frame(1, &motion_model_pose, true);
        frame.pose_cw = motion_model_pose;
        let velocity = pose_at(Vector3::new(0.0, 0.0, 1.0), 0.0);
        let limit = StepLimit::around(&frame, 100, Some(&velocity));
        let Some(limit) = limit else {
            panic!("a velocity gives a limit");
        };
        assert!((limit.step - 1.0).abs() < 1e-12, "step {}", limit.step);
        // Another start 3 m back (a façade's period) with 180 inliers: a jump.
        frame.pose_cw = pose_at(Vector3::new(0.0, 0.0, -2.0), 0.0);
        assert!((limit.distance(&frame) - 3.0).abs() < 1e-9);
        assert!(limit.is_jump(&frame, 180));
        assert!(limit.is_jump(&frame, 200));
        // The same pose with more than twice the inliers replaces it.
        assert!(!limit.is_jump(&frame, 201));
        // A pose within a step (refined, or turned 10°) is no jump.
        frame.pose_cw = pose_at(Vector3::new(0.4, 0.0, 1.5), 10f64.to_radians());
        assert!(!limit.is_jump(&frame, 120));
        // Without a velocity there is no limit.
        assert!(StepLimit::around(&frame, 100, None).is_none());
    }

    #[test]
    fn a_pose_around_the_images_rotation_may_turn_but_not_jump_a_period() {
        // Points 4-12 m ahead (median depth about 8 m): a tenth of it is
        // under the 1 m step, so the step is the limit.
        let world = PointWorld::new(7, 300, (14.0, 5.0, 4.0, 12.0));
        let last_pose = Se3::identity();
        let velocity = pose_at(Vector3::new(0.0, 0.0, 1.0), 0.0);
        let mut map = Map::new();
        let (keyframe, _) = world.add_keyframe(&mut map, last_pose, true);
        let frame_at = |map: &mut Map, pose: Se3| {
            let (mut frame, view) = world.frame(1, &pose, true);
            for (slot, &point) in frame.map_points.iter_mut().zip(&view.point_of) {
                *slot = Some(world.add_point(map, point, keyframe));
            }
            frame.pose_cw = pose;
            frame
        };
        let Some(limit) = PredictionLimit::new(&last_pose, Some(&velocity)) else {
            panic!("a velocity gives a limit");
        };
        // Where the velocity puts the camera, turned 10°: within the limit.
        let turned = frame_at(&mut map, pose_at(Vector3::new(0.0, 0.0, 1.0), 0.17));
        assert_eq!(limit.exceeded(&turned, &map), None);
        // Refined 0.4 m off the prediction: within the step.
        let refined = frame_at(&mut map, pose_at(Vector3::new(0.3, 0.0, 1.25), 0.1));
        assert_eq!(limit.exceeded(&refined, &map), None);
        // A façade period (3 m) sideways: a jump, the step the limit.
        let aliased = frame_at(&mut map, pose_at(Vector3::new(3.0, 0.0, 1.0), 0.17));
        let Some((distance, allowed)) = limit.exceeded(&aliased, &map) else {
            panic!("3 m from the prediction is a jump");
        };
        assert!((distance - 3.0).abs() < 1e-9, "distance {distance}");
        assert!((allowed - 1.0).abs() < 1e-12, "allowed {allowed}");
        // Turning in place (a 1 cm step): 5 cm off the prediction is within
        // a tenth of the median depth, 0.5 to 1.2 m here.
        let creeping = pose_at(Vector3::new(0.0, 0.0, 0.01), 0.0);
        let Some(in_place) = PredictionLimit::new(&last_pose, Some(&creeping)) else {
            panic!("a velocity gives a limit");
        };
        let turning = frame_at(&mut map, pose_at(Vector3::new(0.05, 0.0, 0.01), 0.2));
        assert_eq!(in_place.exceeded(&turning, &map), None);
        let far = frame_at(&mut map, pose_at(Vector3::new(1.5, 0.0, 0.01), 0.2));
        let Some((_, allowed)) = in_place.exceeded(&far, &map) else {
            panic!("1.5 m is more than a tenth of the median depth");
        };
        assert!((0.5..1.2).contains(&allowed), "allowed {allowed}");
        // Without a velocity there is no limit.
        assert!(PredictionLimit::new(&last_pose, None).is_none());
    }
}
