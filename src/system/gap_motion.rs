//! Poses across a tracking gap: the camera carried on at the velocity it
//! last had, for at most [`GAP_HORIZON_S`].
//!
//! A lost frame has no pose of its own, and a map started after a loss has
//! no tie to the one before. Holding the last pose over the gap puts every
//! lost frame, and the new map's whole frame, behind the camera by the
//! distance it travelled meanwhile (at a corner, also turned by the angle
//! it turned): the frozen anchor is known to be wrong by the motion since.
//! The constant-velocity model is the estimate tracking itself predicts
//! each frame with (ORB-SLAM3's `Tracking::Track`: `mVelocity`, the last
//! frame-to-frame motion), carried over the gap's timestamps; beyond
//! [`GAP_HORIZON_S`] the pose is held where the model left it.

use nalgebra::Vector6;

use crate::optim::{LieGroup, Se3};

/// The longest time, in seconds, the last velocity is carried over a gap.
///
/// One second: ten frames of KITTI, thirty of a Kinect, twice tracking's
/// [`crate::tracking::RELOCALISATION_PATIENCE_S`]. ORB-SLAM3 keeps a lost
/// map "recently lost" for 5 s, but it predicts through that time only
/// with an IMU; a camera's own velocity is trusted for less.
pub const GAP_HORIZON_S: f64 = 1.0;

/// The camera's last tracked pose and velocity, in the trajectory's world
/// frame, and its pose predicted at a later time.
#[derive(Debug, Clone, Default)]
pub(super) struct GapMotion {
    /// `(timestamp, T_wc)` of the last tracked frame.
    last: Option<(f64, Se3)>,
    /// The body-frame twist per second between the last two tracked
    /// frames; `None` when they were over [`GAP_HORIZON_S`] apart, out of
    /// order, or only one frame has been tracked.
    twist_per_s: Option<Vector6<f64>>,
}

impl GapMotion {
    /// Records a tracked frame's pose `T_wc` at `timestamp`.
    pub(super) fn tracked(&mut self, timestamp: f64, pose_wc: Se3) {
        self.twist_per_s = self.last.and_then(|(t0, p0)| {
            let dt = timestamp - t0;
            (dt > 0.0 && dt <= GAP_HORIZON_S).then(|| p0.inverse().compose(&pose_wc).log() / dt)
        });
        self.last = Some((timestamp, pose_wc));
    }

    /// `T_wc` at `timestamp`: the last tracked pose carried on at the last
    /// velocity for up to [`GAP_HORIZON_S`] after it; the last pose when
    /// no velocity is known; the identity before any frame was tracked.
    pub(super) fn predict(&self, timestamp: f64) -> Se3 {
        match (self.last, self.twist_per_s) {
            (Some((t0, p0)), Some(twist)) => {
                let dt = (timestamp - t0).clamp(0.0, GAP_HORIZON_S);
                p0.compose(&Se3::exp(&(twist * dt)))
            }
            (Some((_, p0)), None) => p0,
            (None, _) => Se3::identity(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
            let error = distance(&motion.predict(t), &on_circle(t));
            assert!(error < 1e-12, "t {t}: {error}");
        }
    }

    #[test]
    fn beyond_the_horizon_the_pose_is_held() {
        let mut motion = GapMotion::default();
        motion.tracked(0.0, on_circle(0.0));
        motion.tracked(0.1, on_circle(0.1));
        let at_horizon = on_circle(0.1 + GAP_HORIZON_S);
        assert!(distance(&motion.predict(0.1 + GAP_HORIZON_S), &at_horizon) < 1e-12);
        assert!(distance(&motion.predict(30.0), &at_horizon) < 1e-12);
        // Before the last tracked frame nothing is extrapolated backwards.
        assert!(distance(&motion.predict(0.05), &on_circle(0.1)) < 1e-12);
    }

    #[test]
    fn without_a_velocity_the_last_pose_is_held() {
        let mut motion = GapMotion::default();
        assert_eq!(motion.predict(3.0), Se3::identity());
        motion.tracked(0.0, on_circle(0.0));
        motion.tracked(2.0, on_circle(2.0)); // too far apart for a velocity
        assert!(distance(&motion.predict(2.5), &on_circle(2.0)) < 1e-12);
        motion.tracked(2.0, on_circle(2.1)); // the same timestamp twice
        assert!(distance(&motion.predict(2.5), &on_circle(2.1)) < 1e-12);
    }
}
