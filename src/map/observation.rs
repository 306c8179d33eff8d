//! The one policy that turns a keypoint's measurement into an observation
//! for pose optimisation, local and global BA and triangulation's
//! reprojection test (ORB-SLAM3 builds its edges the same way in
//! `Optimizer::PoseOptimization`, `LocalBundleAdjustment` and
//! `GlobalBundleAdjustemnt`, and tests new points so in
//! `LocalMapping::CreateNewMapPoints`):
//!
//! - a keypoint with a depth (a stereo match or an RGB-D depth: ORB-SLAM3's
//!   `mvuRight >= 0`) is a stereo observation `(u, v, u_right)`, near or
//!   far alike: a far point's right column still constrains its bearing,
//!   and its depth error is what the weight below allows;
//! - any other keypoint is a monocular observation `(u, v)`;
//! - the information weight is its octave's `1/σ²` (`mvInvLevelSigma2`);
//!   a keypoint whose octave the scale tables do not know gives none.
//!
//! Whether a *new* point is created from a close or a far stereo keypoint
//! (ORB-SLAM3's `mThDepth`) is tracking's and local mapping's decision;
//! once a keypoint is measured, this is how it counts.

use crate::features::pyramid::ScaleTables;
use crate::features::Keypoint;
use crate::optim::reprojection::Observation;

use super::keyframe::{FrameMeasurements, StereoMeasurement};

/// The observation a keypoint gives, with its stereo measurement (if any)
/// and the pyramid's scale tables (see the module's docs).
pub fn keypoint_observation(
    keypoint: &Keypoint,
    stereo: Option<StereoMeasurement>,
    scales: &ScaleTables,
) -> Option<Observation> {
    let octave = usize::try_from(keypoint.octave).ok()?;
    let information = f64::from(*scales.inv_level_sigma2.get(octave)?);
    let (u, v) = (f64::from(keypoint.x), f64::from(keypoint.y));
    Some(match stereo {
        Some(s) if s.depth > 0.0 => Observation::stereo(u, v, f64::from(s.right_u), information),
        _ => Observation::mono(u, v, information),
    })
}

impl FrameMeasurements {
    /// The observation keypoint `index` gives ([`keypoint_observation`]);
    /// `None` for an index out of range.
    pub fn observation(&self, index: usize) -> Option<Observation> {
        keypoint_observation(
            self.keypoints.get(index)?,
            self.stereo.get(index).copied().flatten(),
            &self.scales,
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

    #[test]
    fn a_depth_makes_a_stereo_observation_weighted_by_its_octave() {
        let scales = ScaleTables::new(1000, 1.2, 3);
        let stereo = StereoMeasurement {
            right_u: 90.0,
            depth: 40.0,
        };
        let obs = keypoint_observation(&keypoint(2), Some(stereo), &scales);
        let Some(obs) = obs else {
            panic!("no observation")
        };
        assert!(obs.is_stereo());
        assert!((obs.information - 1.0 / 1.2f64.powi(4)).abs() < 1e-6);
        // Far or near, a depth counts as stereo.
        let far = StereoMeasurement {
            right_u: 99.9,
            depth: 400.0,
        };
        assert!(
            keypoint_observation(&keypoint(0), Some(far), &scales).is_some_and(|o| o.is_stereo())
        );
    }

    #[test]
    fn no_depth_is_monocular_and_an_unknown_octave_gives_nothing() {
        let scales = ScaleTables::new(1000, 1.2, 3);
        let none = StereoMeasurement {
            right_u: -1.0,
            depth: 0.0,
        };
        assert!(keypoint_observation(&keypoint(1), None, &scales).is_some_and(|o| !o.is_stereo()));
        assert!(
            keypoint_observation(&keypoint(1), Some(none), &scales).is_some_and(|o| !o.is_stereo())
        );
        assert!(keypoint_observation(&keypoint(3), None, &scales).is_none());
        assert!(keypoint_observation(&keypoint(-1), None, &scales).is_none());
    }
}
