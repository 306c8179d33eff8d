//! The one policy that turns a keypoint's measurement into an observation
//! for pose optimisation, local and global BA and triangulation's
//! reprojection test (ORB-SLAM3 builds its edges the same way in
//! `Optimizer::PoseOptimization`, `LocalBundleAdjustment` and
//! `GlobalBundleAdjustemnt`, and tests new points so in
//! `LocalMapping::CreateNewMapPoints`):
//!
//! - a keypoint with a *close* depth (a stereo match or an RGB-D depth,
//!   ORB-SLAM3's `mvuRight >= 0`, closer than the rig's close depth
//!   `mThDepth`) is a stereo observation `(u, v, u_right)` (every depth
//!   with `Stereo.farPointsStereo: 1`, as in ORB-SLAM3);
//! - any other keypoint, far ones included, is a monocular observation
//!   `(u, v)`;
//! - the information weight is its octave's `1/σ²` (`mvInvLevelSigma2`);
//!   a keypoint whose octave the scale tables do not know gives none.
//!
//! Far keypoints differ from ORB-SLAM3, which gives every keypoint with a
//! right column a stereo edge. ORB-SLAM2's paper says why far points
//! should not carry scale: "far keypoints provide accurate rotation
//! information but weaker scale and translation information". A depth
//! beyond `mThDepth` baselines hangs on a few pixels of disparity, so a
//! constant disparity offset of the rig (a calibration's residual yaw
//! between the cameras) turns into a scale error that grows with every
//! far observation. On the KITTI 06 excerpt a +0.1 px disparity offset
//! removes the whole 0.4 % scale error that ORB-SLAM3 itself shows there,
//! and monocular far observations remove most of it (EVALUATION.md, "Far
//! keypoints with their bearing only"). Their bearing still counts.
//!
//! Whether a *new* point is created from a close or a far stereo keypoint
//! is tracking's and local mapping's decision; once a keypoint is
//! measured, this is how it counts.

use crate::features::pyramid::ScaleTables;
use crate::features::Keypoint;
use crate::optim::reprojection::Observation;

use super::keyframe::{FrameMeasurements, StereoMeasurement};

/// The observation a keypoint gives, with its stereo measurement (if any),
/// the pyramid's scale tables and the depth below which a depth counts
/// (the rig's close depth, ORB-SLAM3's `mThDepth`, in metres: see the
/// module's docs; infinite where every depth counts): `CameraRig::stereo_depth_limit`.
pub fn keypoint_observation(
    keypoint: &Keypoint,
    stereo: Option<StereoMeasurement>,
    scales: &ScaleTables,
    stereo_depth_limit: f64,
) -> Option<Observation> {
    let octave = usize::try_from(keypoint.octave).ok()?;
    let information = f64::from(*scales.inv_level_sigma2.get(octave)?);
    let (u, v) = (f64::from(keypoint.x), f64::from(keypoint.y));
    Some(match stereo {
        Some(s) if s.depth > 0.0 && f64::from(s.depth) < stereo_depth_limit => {
            Observation::stereo(u, v, f64::from(s.right_u), information)
        }
        _ => Observation::mono(u, v, information),
    })
}

impl FrameMeasurements {
    /// The observation keypoint `index` gives with the rig's stereo depth
    /// limit ([`keypoint_observation`]); `None` for an index out of range.
    pub fn observation(&self, index: usize, stereo_depth_limit: f64) -> Option<Observation> {
        keypoint_observation(
            self.keypoints.get(index)?,
            self.stereo.get(index).copied().flatten(),
            &self.scales,
            stereo_depth_limit,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::keypoint_observation;
    use crate::features::pyramid::ScaleTables;
    use crate::features::Keypoint;
    use crate::map::StereoMeasurement;

    fn keypoint(octave: i32) -> Keypoint {
        Keypoint {
            x: 100.0,
            y: 50.0,
            size: 31.0,
            angle: 0.0,
            response: 1.0,
            octave,
        }
    }

    /// KITTI's rig: 0.537 m baseline × ThDepth 40.
    const CLOSE_DEPTH: f64 = 21.5;

    #[test]
    fn a_close_depth_makes_a_stereo_observation_weighted_by_its_octave() {
        let scales = ScaleTables::new(1000, 1.2, 3);
        let stereo = StereoMeasurement {
            right_u: 90.0,
            depth: 20.0,
        };
        let obs = keypoint_observation(&keypoint(2), Some(stereo), &scales, CLOSE_DEPTH);
        let Some(obs) = obs else {
            panic!("no observation")
        };
        assert!(obs.is_stereo());
        assert!((obs.information - 1.0 / 1.2f64.powi(4)).abs() < 1e-6);
    }

    /// A far depth keeps the bearing only, with the same weight; the same
    /// depth counts as stereo for a rig whose close depth lies beyond it.
    #[test]
    fn a_far_depth_makes_a_monocular_observation() {
        let scales = ScaleTables::new(1000, 1.2, 3);
        let far = StereoMeasurement {
            right_u: 99.9,
            depth: 40.0,
        };
        let obs = keypoint_observation(&keypoint(1), Some(far), &scales, CLOSE_DEPTH);
        let Some(obs) = obs else {
            panic!("no observation")
        };
        assert!(!obs.is_stereo());
        assert!((obs.information - 1.0 / 1.2f64.powi(2)).abs() < 1e-6);
        let at_limit = StereoMeasurement {
            right_u: 99.0,
            depth: CLOSE_DEPTH as f32,
        };
        assert!(
            keypoint_observation(&keypoint(0), Some(at_limit), &scales, CLOSE_DEPTH)
                .is_some_and(|o| !o.is_stereo())
        );
        assert!(keypoint_observation(&keypoint(0), Some(far), &scales, 50.0)
            .is_some_and(|o| o.is_stereo()));
    }

    #[test]
    fn no_depth_is_monocular_and_an_unknown_octave_gives_nothing() {
        let scales = ScaleTables::new(1000, 1.2, 3);
        let none = StereoMeasurement {
            right_u: -1.0,
            depth: 0.0,
        };
        assert!(
            keypoint_observation(&keypoint(1), None, &scales, CLOSE_DEPTH)
                .is_some_and(|o| !o.is_stereo())
        );
        assert!(
            keypoint_observation(&keypoint(1), Some(none), &scales, CLOSE_DEPTH)
                .is_some_and(|o| !o.is_stereo())
        );
        assert!(keypoint_observation(&keypoint(3), None, &scales, CLOSE_DEPTH).is_none());
        assert!(keypoint_observation(&keypoint(-1), None, &scales, CLOSE_DEPTH).is_none());
    }
}
