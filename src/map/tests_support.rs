//! Small maps for the map module's unit tests.

use nalgebra::{UnitQuaternion, Vector3};

use crate::features::pyramid::ScaleTables;
use crate::features::{DescriptorSet, Keypoint};
use crate::optim::Se3;

use super::{FrameMeasurements, KeyFrameId, Map, PointDescriptor, StereoMeasurement};

/// Descriptor length of the test keyframes.
pub(crate) const DIM: usize = 2;

/// `n` keypoints, every other one with a stereo measurement.
pub(crate) fn measurements(n: usize) -> FrameMeasurements {
    measurements_with(n, true)
}

/// `n` keypoints, every other one with a stereo measurement when `stereo`
/// (none otherwise: a monocular keyframe).
pub(crate) fn measurements_with(n: usize, stereo: bool) -> FrameMeasurements {
    FrameMeasurements {
        keypoints: (0..n)
            .map(|i| Keypoint {
                x: i as f32 * 10.0,
                y: 0.0,
                size: 31.0,
                angle: 0.0,
                response: 1.0,
                octave: 0,
            })
            .collect(),
        descriptors: DescriptorSet::Float {
            dim: DIM,
            data: (0..n * DIM).map(|v| v as f32).collect(),
        },
        stereo: (0..n)
            .map(|i| {
                (stereo && i % 2 == 0).then_some(StereoMeasurement {
                    right_u: 0.0,
                    depth: 5.0,
                })
            })
            .collect(),
        scales: ScaleTables::new(1000, 1.2, 8),
        distance_thresholds: crate::features::DistanceThresholds::SUPERPOINT_L2,
    }
}

/// `keyframes` keyframes along x added to `map`, each sharing 20 points
/// with the previous one (keypoints 20..40 of keyframe k-1 and 0..20 of
/// keyframe k), connected: the spanning tree is a chain.
pub(crate) fn small_map(map: Map, keyframes: usize) -> Map {
    small_map_with(map, keyframes, true)
}

/// [`small_map`] with stereo measurements or (`stereo` false) none.
pub(crate) fn small_map_with(mut map: Map, keyframes: usize, stereo: bool) -> Map {
    let mut previous: Option<KeyFrameId> = None;
    for k in 0..keyframes {
        let pose = Se3::new(
            UnitQuaternion::identity(),
            Vector3::new(-(k as f64), 0.0, 0.0),
        );
        let Ok(kf) = map.add_keyframe(k, k as f64, pose, measurements_with(40, stereo)) else {
            panic!("keyframe {k}");
        };
        if let Some(prev) = previous {
            for i in 0..20 {
                let position = Vector3::new(k as f64 + i as f64 * 0.1, 0.0, 5.0);
                let descriptor = PointDescriptor::Float(vec![0.0; DIM].into());
                let added = map.add_map_point(position, descriptor, prev).and_then(|p| {
                    map.add_observation(p, prev, 20 + i)?;
                    map.add_observation(p, kf, i)
                });
                assert!(added.is_ok(), "{added:?}");
            }
        }
        map.update_connections(kf);
        previous = Some(kf);
    }
    map
}

/// A map with one keyframe (no points) at each pose `T_cw`, in order, and
/// their ids.
pub(crate) fn map_with_keyframes_at(poses: &[Se3]) -> (Map, Vec<KeyFrameId>) {
    let mut map = Map::new();
    let ids = poses
        .iter()
        .enumerate()
        .map(|(i, pose)| {
            map.add_keyframe(i, i as f64, *pose, measurements(4))
                .expect("valid test measurements")
        })
        .collect();
    (map, ids)
}
