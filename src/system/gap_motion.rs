//! Poses across a tracking gap: the camera carried on at the velocity it
//! last had, for at most [`GAP_HORIZON_S`], turned as its images show.
//!
//! A lost frame has no pose of its own, and a map started after a loss has
//! no tie to the one before. Holding the last pose over the gap puts every
//! lost frame, and the new map's whole frame, behind the camera by the
//! distance it travelled meanwhile (at a corner, also turned by the angle
//! it turned): the frozen anchor is known to be wrong by the motion since.
//! The constant-velocity model is the estimate tracking itself predicts
//! each frame with (ORB-SLAM3's `Tracking::Track`: `mVelocity`, the last
//! frame-to-frame motion), carried over the gap's timestamps; beyond
//! [`GAP_HORIZON_S`] the camera centre is held where the model left it.
//!
//! The images of a lost frame still measure how the camera turned since
//! the frame before ([`GapRotations`], from the frames' thumbnails): where
//! that rotation is known it replaces the velocity's for that step, so a
//! loss in a turn (motion blur at a corner) does not leave the turn out of
//! the lost rows and of the next map's anchor.

use std::sync::Arc;

use nalgebra::{UnitQuaternion, Vector6};

use crate::optim::{LieGroup, Se3};
use crate::tracking::{estimate_rotation, SmallBlurryImage};

/// The longest time, in seconds, the last velocity is carried over a gap.
///
/// One second: ten frames of KITTI, thirty of a Kinect, twice tracking's
/// [`crate::tracking::RELOCALISATION_PATIENCE_S`]. ORB-SLAM3 keeps a lost
/// map "recently lost" for 5 s, but it predicts through that time only
/// with an IMU; a camera's own velocity is trusted for less.
pub const GAP_HORIZON_S: f64 = 1.0;

/// The camera's last tracked pose and velocity, in the trajectory's world
/// frame, and its poses over the gap after it.
#[derive(Debug, Clone, Default)]
pub(super) struct GapMotion {
    /// `(timestamp, T_wc)` of the last tracked frame.
    last: Option<(f64, Se3)>,
    /// The body-frame twist per second between the last two tracked
    /// frames; `None` when they were over [`GAP_HORIZON_S`] apart, out of
    /// order, or only one frame has been tracked.
    twist_per_s: Option<Vector6<f64>>,
    /// `(timestamp, T_wc)` of the last frame of the gap so far.
    coasted: Option<(f64, Se3)>,
}

impl GapMotion {
    /// Records a tracked frame's pose `T_wc` at `timestamp`; a gap since
    /// the last one is over.
    pub(super) fn tracked(&mut self, timestamp: f64, pose_wc: Se3) {
        self.twist_per_s = self.last.and_then(|(t0, p0)| {
            let dt = timestamp - t0;
            (dt > 0.0 && dt <= GAP_HORIZON_S).then(|| p0.inverse().compose(&pose_wc).log() / dt)
        });
        self.last = Some((timestamp, pose_wc));
        self.coasted = None;
    }

    /// `T_wc` of the next frame of a gap, at `timestamp`, given the
    /// rotation `R_cp` its images measured from the frame before (`None`:
    /// not measured): the step from the gap's previous frame (or the last
    /// tracked one) moves the camera centre as the last velocity did, for
    /// at most [`GAP_HORIZON_S`] after the last tracked frame, and turns it
    /// by the measured rotation, or else (within the horizon) by the
    /// velocity's. The last pose when no velocity is known; the identity
    /// before any frame was tracked. Without measured rotations this is the
    /// last pose carried on at the last twist, exactly.
    pub(super) fn coast(
        &mut self,
        timestamp: f64,
        measured_rotation_cp: Option<UnitQuaternion<f64>>,
    ) -> Se3 {
        let Some((t_last, p_last)) = self.last else {
            return Se3::identity();
        };
        let (t_prev, p_prev) = self.coasted.unwrap_or((t_last, p_last));
        let within = |t: f64| t.clamp(t_last, t_last + GAP_HORIZON_S);
        let dt = (within(timestamp) - within(t_prev)).max(0.0);
        let step = match self.twist_per_s {
            Some(twist) => Se3::exp(&(twist * dt)),
            None => Se3::identity(),
        };
        let rotation = measured_rotation_cp.map_or(step.rotation, |r_cp| r_cp.inverse());
        let pose = p_prev.compose(&Se3::new(rotation, step.translation));
        if timestamp >= t_prev {
            self.coasted = Some((timestamp, pose));
        }
        pose
    }
}

impl GapMotion {
    /// `T_wc` of the next frame of a gap, at `timestamp`, whose motion
    /// from the gap's previous frame (or the last tracked one) was
    /// measured: `T_c,p` by odometry (see `crate::tracking`'s gap
    /// odometry). Unlike [`Self::coast`] it has no horizon: the step is
    /// measured, not assumed. The identity before any frame was tracked.
    pub(super) fn step(&mut self, timestamp: f64, pose_cp: &Se3) -> Se3 {
        let Some((t_last, p_last)) = self.last else {
            return Se3::identity();
        };
        let (_, p_prev) = self.coasted.unwrap_or((t_last, p_last));
        let pose = p_prev.compose(&pose_cp.inverse());
        self.coasted = Some((timestamp, pose));
        pose
    }

    /// The next gap frame's `T_wc`: [`Self::step`] when its motion was
    /// measured, else [`Self::coast`] with the rotation its images gave.
    pub(super) fn next_gap_pose(
        &mut self,
        timestamp: f64,
        measured_step_cp: Option<&Se3>,
        measured_rotation_cp: Option<UnitQuaternion<f64>>,
    ) -> Se3 {
        match measured_step_cp {
            Some(step) => self.step(timestamp, step),
            None => self.coast(timestamp, measured_rotation_cp),
        }
    }
}

/// The correlation two consecutive frames' aligned thumbnails need for
/// their rotation to be used: an alignment that failed. It is no test of
/// the same place: on the synthetic block, consecutive frames at 1 m a
/// frame align at 0.89–0.92 and views of two other streets at 0.85–0.87
/// (a kidnap's rows then turn by the small rotation such views give:
/// 1.7° in `tests/slam_system.rs`'s kidnap).
const MIN_GAP_CORRELATION: f64 = 0.8;

/// The rotation between consecutive input frames, measured from their
/// thumbnails ([`estimate_rotation`]) for the frames tracking gave no pose
/// and the first frame of a new map: the rotation [`GapMotion::coast`]
/// turns the camera by.
#[derive(Debug, Clone, Default)]
pub(super) struct GapRotations {
    /// The previous input frame's thumbnail (`None` after an unreadable
    /// or flat frame).
    previous: Option<Arc<SmallBlurryImage>>,
    /// The last rotation measured, where the next search starts.
    last_step: Option<UnitQuaternion<f64>>,
}

impl GapRotations {
    /// Takes this frame's thumbnail; when `measure`, returns `R_cp` from
    /// the previous frame's, if the images give one.
    pub(super) fn next(
        &mut self,
        thumbnail: Option<Arc<SmallBlurryImage>>,
        measure: bool,
    ) -> Option<UnitQuaternion<f64>> {
        let previous = std::mem::replace(&mut self.previous, thumbnail);
        if !measure {
            self.last_step = None;
            return None;
        }
        let start = self.last_step.unwrap_or_else(UnitQuaternion::identity);
        let found = match (previous.as_deref(), self.previous.as_deref()) {
            (Some(a), Some(b)) => estimate_rotation(a, b, &start)
                .filter(|r| r.correlation >= MIN_GAP_CORRELATION)
                .map(|r| r.rotation),
            _ => None,
        };
        self.last_step = found;
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// A camera on a circle at a constant twist: 1 m/s forward, 0.2 rad/s yaw.
    fn on_circle(t: f64) -> Se3 {
        let twist = Vector6::new(0.0, 0.2, 0.0, 0.0, 0.0, 1.0);
        Se3::exp(&(twist * t))
    }

    fn distance(a: &Se3, b: &Se3) -> f64 {
        a.inverse().compose(b).log().norm()
    }

    #[test]
    fn a_constant_twist_is_carried_exactly_across_the_gap() {
        let mut motion = GapMotion::default();
        motion.tracked(0.0, on_circle(0.0));
        motion.tracked(0.1, on_circle(0.1));
        for t in [0.1, 0.35, 0.8, 1.1] {
            let error = distance(&motion.coast(t, None), &on_circle(t));
            assert!(error < 1e-12, "t {t}: {error}");
        }
    }

    #[test]
    fn measured_steps_chain_from_the_last_tracked_pose_without_a_horizon() {
        let mut motion = GapMotion::default();
        assert_eq!(motion.step(0.0, &on_circle(0.1)), Se3::identity());
        motion.tracked(0.0, on_circle(0.0));
        motion.tracked(0.1, on_circle(0.1));
        // The true steps T_c,p of a camera that stops turning and goes
        // sideways: nothing the velocity would predict.
        let sideways =
            |t: f64| on_circle(0.1).compose(&Se3::exp(&Vector6::new(t, 0.0, 0.0, 0.0, 0.0, 0.0)));
        let mut previous = on_circle(0.1);
        for k in 1..=30 {
            let t = 0.1 + 0.1 * f64::from(k);
            let truth = sideways(t - 0.1);
            let step_cp = truth.inverse().compose(&previous);
            let pose = motion.next_gap_pose(t, Some(&step_cp), None);
            assert!(distance(&pose, &truth) < 1e-9, "frame {k}");
            previous = truth;
        }
        // A frame without a step coasts from the last stepped pose.
        let coasted = motion.next_gap_pose(3.2, None, None);
        assert!(distance(&coasted, &previous) < 1e-12);
    }

    #[test]
    fn beyond_the_horizon_the_pose_is_held() {
        let mut motion = GapMotion::default();
        motion.tracked(0.0, on_circle(0.0));
        motion.tracked(0.1, on_circle(0.1));
        let at_horizon = on_circle(0.1 + GAP_HORIZON_S);
        assert!(distance(&motion.coast(0.1 + GAP_HORIZON_S, None), &at_horizon) < 1e-12);
        assert!(distance(&motion.coast(30.0, None), &at_horizon) < 1e-12);
        let mut motion = GapMotion::default();
        motion.tracked(0.0, on_circle(0.0));
        motion.tracked(0.1, on_circle(0.1));
        // Before the last tracked frame nothing is extrapolated backwards.
        assert!(distance(&motion.coast(0.05, None), &on_circle(0.1)) < 1e-12);
    }

    #[test]
    fn a_turn_the_images_measured_replaces_the_velocitys_rotation() {
        // Straight at 1 m/s, then lost while turning 10° a frame (0.1 s).
        let straight = |t: f64| Se3::exp(&(Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 1.0) * t));
        let mut motion = GapMotion::default();
        motion.tracked(0.0, straight(0.0));
        motion.tracked(0.1, straight(0.1));
        let turn = UnitQuaternion::from_euler_angles(0.0, 10f64.to_radians(), 0.0);
        let mut truth = straight(0.1);
        for k in 1..=4 {
            let t = 0.1 + 0.1 * f64::from(k);
            // The camera moves 0.1 m along its optical axis and turns by
            // R_pc = turn⁻¹ (its images measure R_cp = turn).
            truth = truth.compose(&Se3::new(turn.inverse(), Vector3::new(0.0, 0.0, 0.1)));
            let pose = motion.coast(t, Some(turn));
            assert!(distance(&pose, &truth) < 1e-9, "frame {k}");
        }
        // A frame with no measurement carries the velocity's rotation (none).
        truth = truth.compose(&Se3::new(
            UnitQuaternion::identity(),
            Vector3::new(0.0, 0.0, 0.1),
        ));
        assert!(distance(&motion.coast(0.6, None), &truth) < 1e-9);
        // Tracked again: the next gap starts from there.
        motion.tracked(0.7, straight(0.7));
        assert!(distance(&motion.coast(0.7, None), &straight(0.7)) < 1e-12);
    }

    #[test]
    fn without_a_velocity_the_last_pose_is_held() {
        let mut motion = GapMotion::default();
        assert_eq!(motion.coast(3.0, None), Se3::identity());
        motion.tracked(0.0, on_circle(0.0));
        motion.tracked(2.0, on_circle(2.0)); // too far apart for a velocity
        assert!(distance(&motion.coast(2.5, None), &on_circle(2.0)) < 1e-12);
        motion.tracked(2.0, on_circle(2.1)); // the same timestamp twice
        assert!(distance(&motion.coast(2.5, None), &on_circle(2.1)) < 1e-12);
    }
}
