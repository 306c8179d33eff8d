//! Test fixture: a world of 3-D points with unique descriptors, seen
//! through an exact pinhole stereo rig. Stage tests of tracking and local
//! mapping build keyframes and frames from it, so every keypoint's true
//! point, depth and pose are known.

use nalgebra::{UnitQuaternion, Vector3};

use crate::camera::CameraRig;
use crate::dataset::synthetic::SplitMix64;
use crate::features::pyramid::ScaleTables;
use crate::features::{DescriptorSet, FrameFeatures, Keypoint, StageTimings};
use crate::map::{
    FrameMeasurements, KeyFrameId, Map, MapPointId, PointDescriptor, StereoMeasurement,
};
use crate::optim::reprojection::PinholeStereo;
use crate::optim::{LieGroup, Se3};
use crate::tracking::Frame;

/// Descriptor length (SuperPoint's).
pub(crate) const DIM: usize = 256;

/// Points with unit descriptors; random unit vectors in 256-D lie about
/// √2 apart, far beyond the matchers' thresholds.
pub(crate) struct PointWorld {
    pub points: Vec<Vector3<f64>>,
    pub descriptors: Vec<Vec<f32>>,
    pub rig: CameraRig,
    /// Pixels every stereo disparity reads short (a rig whose calibration
    /// is off by a small yaw between the cameras); 0 for an exact rig.
    pub disparity_offset: f64,
}

/// What a camera at some pose sees: per keypoint, the world point index.
pub(crate) struct View {
    pub keypoints: Vec<Keypoint>,
    pub descriptors: DescriptorSet,
    pub stereo: Vec<Option<StereoMeasurement>>,
    pub point_of: Vec<usize>,
}

/// A 640×480 rig, f = 400 px, 0.5 m baseline, close depth 20 m, 10 fps.
pub(crate) fn rig() -> CameraRig {
    let baseline = 0.5;
    CameraRig {
        sensor: crate::camera::Sensor::Stereo,
        camera: PinholeStereo::new(400.0, 400.0, 320.0, 240.0, 400.0 * baseline),
        baseline,
        width: 640,
        height: 480,
        close_depth: 20.0,
        far_points_stereo: false,
        max_depth: None,
        fps: 10.0,
    }
}

/// The pose `T_cw` of a camera at `position` looking along +z, turned by `yaw` about y.
pub(crate) fn pose_at(position: Vector3<f64>, yaw: f64) -> Se3 {
    let r = UnitQuaternion::from_euler_angles(0.0, yaw, 0.0);
    // T_wc = (r, position) → T_cw = (r⁻¹, −r⁻¹·position)
    let r_inv = r.inverse();
    Se3::new(r_inv, -(r_inv * position))
}

impl PointWorld {
    /// `n` points uniformly in the box `x ∈ [−w, w]`, `y ∈ [−h, h]`, `z ∈ [z0, z1]`.
    pub fn new(seed: u64, n: usize, (w, h, z0, z1): (f64, f64, f64, f64)) -> Self {
        let mut rng = SplitMix64::new(seed);
        let mut uniform = |a: f64, b: f64| a + (b - a) * rng.next_unit();
        let mut points = Vec::with_capacity(n);
        for _ in 0..n {
            points.push(Vector3::new(
                uniform(-w, w),
                uniform(-h, h),
                uniform(z0, z1),
            ));
        }
        let mut descriptors = Vec::with_capacity(n);
        for _ in 0..n {
            let mut d: Vec<f32> = (0..DIM).map(|_| uniform(-1.0, 1.0) as f32).collect();
            let norm = d.iter().map(|v| v * v).sum::<f32>().sqrt();
            d.iter_mut().for_each(|v| *v /= norm);
            descriptors.push(d);
        }
        Self {
            points,
            descriptors,
            rig: rig(),
            disparity_offset: 0.0,
        }
    }

    /// The keypoints of the points visible from `pose_cw` (in front, inside
    /// the image with a 10 px margin), with stereo when `stereo`, exactly
    /// projected (octave 0).
    pub fn view(&self, pose_cw: &Se3, stereo: bool) -> View {
        let c = &self.rig.camera;
        let mut keypoints = Vec::new();
        let mut data = Vec::new();
        let mut measurements = Vec::new();
        let mut point_of = Vec::new();
        for (i, p) in self.points.iter().enumerate() {
            let pc = pose_cw.transform_point(p);
            if pc.z < 0.5 {
                continue;
            }
            let u = c.fx * pc.x / pc.z + c.cx;
            let v = c.fy * pc.y / pc.z + c.cy;
            if u < 10.0 || v < 10.0 || u > 630.0 || v > 470.0 {
                continue;
            }
            keypoints.push(Keypoint {
                x: u as f32,
                y: v as f32,
                size: 8.0,
                angle: -1.0,
                response: 1.0,
                octave: 0,
            });
            data.extend_from_slice(&self.descriptors[i]);
            let disparity = c.bf / pc.z - self.disparity_offset;
            measurements.push(stereo.then_some(StereoMeasurement {
                right_u: (u - disparity) as f32,
                depth: (c.bf / disparity) as f32,
            }));
            point_of.push(i);
        }
        View {
            keypoints,
            descriptors: DescriptorSet::Float { dim: DIM, data },
            stereo: measurements,
            point_of,
        }
    }

    /// A keyframe at `pose_cw` in `map`, with the view's measurements.
    pub fn add_keyframe(&self, map: &mut Map, pose_cw: Se3, stereo: bool) -> (KeyFrameId, View) {
        let view = self.view(&pose_cw, stereo);
        let measurements = FrameMeasurements {
            keypoints: view.keypoints.clone(),
            descriptors: view.descriptors.clone(),
            stereo: view.stereo.clone(),
            scales: ScaleTables::new(1000, 1.2, 8),
            distance_thresholds: crate::features::DistanceThresholds::for_kind(
                view.descriptors.kind(),
            ),
        };
        let index = map.keyframe_count();
        let kf = map
            .add_keyframe(index, index as f64, pose_cw, measurements)
            .unwrap_or_else(|e| panic!("{e}"));
        (kf, view)
    }

    /// A map point at the true position of world point `i`.
    pub fn add_point(&self, map: &mut Map, i: usize, first: KeyFrameId) -> MapPointId {
        let descriptor = PointDescriptor::Float(self.descriptors[i].clone().into());
        map.add_map_point(self.points[i], descriptor, first)
            .unwrap_or_else(|e| panic!("{e}"))
    }

    /// A map of stereo keyframes along +z (0.4 m apart) in which every
    /// world point seen by a keyframe is a map point observed by every
    /// keyframe that sees it.
    pub fn keyframe_chain(&self, keyframes: usize) -> (Map, Vec<(KeyFrameId, View)>) {
        let mut map = Map::new();
        let mut kfs = Vec::new();
        for k in 0..keyframes {
            let pose = pose_at(Vector3::new(0.0, 0.0, 0.4 * k as f64), 0.0);
            kfs.push(self.add_keyframe(&mut map, pose, true));
        }
        let mut point_ids = std::collections::BTreeMap::new();
        for (kf, view) in &kfs {
            for (index, &p) in view.point_of.iter().enumerate() {
                let id = *point_ids
                    .entry(p)
                    .or_insert_with(|| self.add_point(&mut map, p, kfs[0].0));
                map.add_observation(id, *kf, index)
                    .unwrap_or_else(|e| panic!("{e}"));
            }
        }
        let ids: Vec<_> = map.map_points().map(|p| p.id()).collect();
        for id in ids {
            map.update_descriptor(id);
            map.update_normal_and_depth(id);
        }
        for (kf, _) in &kfs {
            map.update_connections(*kf);
        }
        (map, kfs)
    }

    /// A tracking frame seen from `pose_cw` (its pose left at identity).
    pub fn frame(&self, index: usize, pose_cw: &Se3, stereo: bool) -> (Frame, View) {
        let view = self.view(pose_cw, stereo);
        let features = FrameFeatures {
            keypoints: view.keypoints.clone(),
            descriptors: view.descriptors.clone(),
            timings: StageTimings::default(),
        };
        let frame = Frame::new(
            index,
            index as f64 / self.rig.fps,
            features,
            view.stereo.clone(),
            ScaleTables::new(1000, 1.2, 8),
            &self.rig,
        );
        (frame, view)
    }
}
