//! New map points by triangulation between a new keyframe and its best
//! covisible keyframes (ORB-SLAM3's `CreateNewMapPoints`, stereo-aware),
//! matching unmatched keypoints along epipolar lines.

use std::sync::Arc;

use nalgebra::{Matrix3, Matrix4, Vector3};

use crate::camera::{CameraRig, Sensor};
use crate::error::{MapContext, SlamError};
use crate::features::DescriptorSet;
use crate::map::{FrameMeasurements, KeyFrameId, Map, MapPointId, PointDescriptor};
use crate::matching::BestTwo;
use crate::optim::lie::hat;
use crate::optim::{LieGroup, Se3};

/// Neighbours triangulated against (ORB-SLAM3: 10 for stereo).
const NEIGHBOURS: usize = 10;
/// Monocular keyframes triangulate against more (ORB-SLAM3: `nn = 30`).
const NEIGHBOURS_MONOCULAR: usize = 30;
/// Ratio test for triangulation matches (ORB-SLAM3: 0.6).
const RATIO: f32 = 0.6;

/// One keyframe's data needed here, copied out of the map.
struct View {
    id: KeyFrameId,
    pose: Se3,
    center: Vector3<f64>,
    /// Shared with the keyframe (no copy of its descriptors).
    measurements: Arc<FrameMeasurements>,
    unmatched: Vec<usize>,
}

fn view(map: &Map, id: KeyFrameId) -> Option<View> {
    let kf = map.keyframe(id).ok()?;
    let unmatched = (0..kf.measurements.len())
        .filter(|i| kf.map_point(*i).is_none())
        .collect();
    Some(View {
        id,
        pose: kf.pose_cw(),
        center: kf.camera_center(),
        measurements: Arc::clone(&kf.measurements),
        unmatched,
    })
}

impl View {
    fn pixel(&self, i: usize) -> (f64, f64) {
        let kp = &self.measurements.keypoints[i];
        (f64::from(kp.x), f64::from(kp.y))
    }
    fn octave(&self, i: usize) -> usize {
        self.measurements.keypoints[i].octave.max(0) as usize
    }
    fn sigma2(&self, i: usize) -> f64 {
        f64::from(
            self.measurements
                .scales
                .level_sigma2
                .get(self.octave(i))
                .copied()
                .unwrap_or(1.0),
        )
    }
    fn scale(&self, i: usize) -> f64 {
        f64::from(
            self.measurements
                .scales
                .scale_factors
                .get(self.octave(i))
                .copied()
                .unwrap_or(1.0),
        )
    }
    fn depth(&self, i: usize) -> Option<f64> {
        self.measurements.stereo[i]
            .map(|s| f64::from(s.depth))
            .filter(|d| *d > 0.0)
    }
}

/// `F21`: maps a pixel of view 1 to its epipolar line in view 2.
fn fundamental(v1: &View, v2: &View, rig: &CameraRig) -> Matrix3<f64> {
    let rel = v2.pose.compose(&v1.pose.inverse());
    let e = hat(&rel.translation) * rel.rotation_matrix();
    let k_inv = rig.intrinsics().k_inverse();
    k_inv.transpose() * e * k_inv
}

/// Matches unmatched keypoints of `v1` to unmatched ones of `v2` near their
/// epipolar lines (descriptor TH_LOW, ratio 0.6, one match per keypoint).
fn epipolar_matches(v1: &View, v2: &View, rig: &CameraRig) -> Vec<(usize, usize)> {
    let f21 = fundamental(v1, v2, rig);
    let d1 = &v1.measurements.descriptors;
    let d2: &DescriptorSet = &v2.measurements.descriptors;
    let threshold = v1.measurements.distance_thresholds.low;
    // v2's candidates as flat rows (the inner loop runs n1 × n2 times).
    struct Candidate {
        u: f64,
        v: f64,
        octave: i64,
        line_threshold: f64,
        index: usize,
    }
    let candidates: Vec<Candidate> = v2
        .unmatched
        .iter()
        .map(|&i2| {
            let (u, v) = v2.pixel(i2);
            Candidate {
                u,
                v,
                octave: v2.octave(i2) as i64,
                line_threshold: 3.84 * v2.sigma2(i2),
                index: i2,
            }
        })
        .collect();
    let mut owner: Vec<Option<(usize, f32)>> = vec![None; v2.measurements.len()];
    for &i1 in &v1.unmatched {
        let (u1, w1) = v1.pixel(i1);
        let octave1 = v1.octave(i1) as i64;
        let line = f21 * Vector3::new(u1, w1, 1.0);
        let norm2 = line.x * line.x + line.y * line.y;
        if norm2 <= 0.0 {
            continue;
        }
        let mut best = BestTwo::default();
        for c in &candidates {
            let num = line.x * c.u + line.y * c.v + line.z;
            if num * num > c.line_threshold * norm2 || (octave1 - c.octave).abs() > 1 {
                continue;
            }
            if let Some(d) = d1.distance(i1, d2, c.index) {
                best.offer(c.index, d);
            }
        }
        if let Some((i2, d)) = best.accept(threshold, Some(RATIO)) {
            if owner[i2].is_none_or(|(_, od)| d < od) {
                owner[i2] = Some((i1, d));
            }
        }
    }
    owner
        .iter()
        .enumerate()
        .filter_map(|(i2, o)| o.map(|(i1, _)| (i1, i2)))
        .collect()
}

/// Linear (DLT) triangulation from normalised coordinates.
fn triangulate(p1: &Se3, x1: (f64, f64), p2: &Se3, x2: (f64, f64)) -> Option<Vector3<f64>> {
    let m1 = p1.to_matrix();
    let m2 = p2.to_matrix();
    let mut a = Matrix4::zeros();
    a.set_row(0, &(m1.row(2) * x1.0 - m1.row(0)));
    a.set_row(1, &(m1.row(2) * x1.1 - m1.row(1)));
    a.set_row(2, &(m2.row(2) * x2.0 - m2.row(0)));
    a.set_row(3, &(m2.row(2) * x2.1 - m2.row(1)));
    let svd = a.svd(false, true);
    let v_t = svd.v_t?;
    let (min_index, _) = svd
        .singular_values
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    let x = v_t.row(min_index);
    if x[3].abs() < 1e-12 {
        return None;
    }
    Some(Vector3::new(x[0] / x[3], x[1] / x[3], x[2] / x[3]))
}

/// The reprojection test of a new point in one view (χ² at 95 %, ORB-SLAM3's
/// `CreateNewMapPoints`): the keypoint counts as the one measurement policy
/// says ([`FrameMeasurements::observation`]: stereo with a depth, else
/// monocular), with that observation's threshold and weight.
fn reprojects_well(view: &View, i: usize, x: &Vector3<f64>, rig: &CameraRig) -> bool {
    let pc = view.pose.transform_point(x);
    if pc.z <= 0.0 {
        return false;
    }
    let predicted = rig.camera.project_stereo(&pc);
    view.measurements
        .observation(i, rig.stereo_depth_limit())
        .is_some_and(|obs| obs.accepts_prediction(&predicted))
}

/// The world point for a match, or `None` when a check fails.
fn point_for_match(
    v1: &View,
    i1: usize,
    v2: &View,
    i2: usize,
    rig: &CameraRig,
    scale_factor: f64,
) -> Option<Vector3<f64>> {
    let c = &rig.camera;
    let norm = |(u, v): (f64, f64)| ((u - c.cx) / c.fx, (v - c.cy) / c.fy);
    let (n1, n2) = (norm(v1.pixel(i1)), norm(v2.pixel(i2)));
    let ray1 = v1.pose.rotation.inverse() * Vector3::new(n1.0, n1.1, 1.0);
    let ray2 = v2.pose.rotation.inverse() * Vector3::new(n2.0, n2.1, 1.0);
    let cos_rays = ray1.dot(&ray2) / (ray1.norm() * ray2.norm());
    let stereo_cos =
        |d: Option<f64>| d.map_or(2.0, |d| (2.0 * (rig.baseline / 2.0).atan2(d)).cos());
    let (cos1, cos2) = (stereo_cos(v1.depth(i1)), stereo_cos(v2.depth(i2)));
    let cos_stereo = cos1.min(cos2);
    let has_stereo = v1.depth(i1).is_some() || v2.depth(i2).is_some();
    let x = if cos_rays < cos_stereo && cos_rays > 0.0 && (has_stereo || cos_rays < 0.9998) {
        triangulate(&v1.pose, n1, &v2.pose, n2)?
    } else if v1.depth(i1).is_some() && cos1 < cos2 {
        let (u, v) = v1.pixel(i1);
        v1.pose
            .inverse()
            .transform_point(&rig.unproject(u, v, v1.depth(i1)?))
    } else if v2.depth(i2).is_some() && cos2 < cos1 {
        let (u, v) = v2.pixel(i2);
        v2.pose
            .inverse()
            .transform_point(&rig.unproject(u, v, v2.depth(i2)?))
    } else {
        return None;
    };
    if !reprojects_well(v1, i1, &x, rig) || !reprojects_well(v2, i2, &x, rig) {
        return None;
    }
    let (dist1, dist2) = ((x - v1.center).norm(), (x - v2.center).norm());
    if dist1 == 0.0 || dist2 == 0.0 {
        return None;
    }
    let ratio_dist = dist2 / dist1;
    let ratio_octave = v1.scale(i1) / v2.scale(i2);
    let factor = 1.5 * scale_factor;
    if ratio_dist * factor < ratio_octave || ratio_dist > ratio_octave * factor {
        return None;
    }
    Some(x)
}

/// A point triangulated from a snapshot, not yet in the map.
pub(crate) struct NewPoint {
    /// The new keyframe and its keypoint.
    first: (KeyFrameId, usize),
    /// The neighbour and its keypoint.
    second: (KeyFrameId, usize),
    position: Vector3<f64>,
    descriptor: PointDescriptor,
}

/// Compute: triangulates the new keyframe's free keypoints against its best
/// covisible keyframes (read only).
pub(crate) fn plan_new_points(map: &Map, keyframe: KeyFrameId, rig: &CameraRig) -> Vec<NewPoint> {
    let Some(mut v1) = view(map, keyframe) else {
        return Vec::new();
    };
    let scale_factor = f64::from(
        v1.measurements
            .scales
            .scale_factors
            .get(1)
            .copied()
            .unwrap_or(1.2),
    );
    let mut planned = Vec::new();
    let neighbours = if rig.sensor == Sensor::Monocular {
        NEIGHBOURS_MONOCULAR
    } else {
        NEIGHBOURS
    };
    for neighbour in map.best_covisible(keyframe, neighbours) {
        let Some(v2) = view(map, neighbour) else {
            continue;
        };
        let baseline = (v2.center - v1.center).norm();
        if rig.sensor == Sensor::Monocular {
            // ORB-SLAM3's `CreateNewMapPoints`: a monocular pair needs a
            // baseline of 1 % of the neighbour's median scene depth.
            let median_depth = map.median_scene_depth(neighbour);
            if median_depth.is_none_or(|d| baseline / d < 0.01) {
                continue;
            }
        } else if baseline < rig.baseline {
            continue;
        }
        let mut used = Vec::new();
        for (i1, i2) in epipolar_matches(&v1, &v2, rig) {
            let Some(position) = point_for_match(&v1, i1, &v2, i2, rig, scale_factor) else {
                continue;
            };
            let Some(descriptor) = PointDescriptor::from_set(&v1.measurements.descriptors, i1)
            else {
                continue;
            };
            used.push(i1);
            planned.push(NewPoint {
                first: (v1.id, i1),
                second: (v2.id, i2),
                position,
                descriptor,
            });
        }
        // Keypoints matched now are no longer free in the new keyframe.
        used.sort_unstable();
        v1.unmatched.retain(|i| used.binary_search(i).is_err());
    }
    planned
}

/// Apply: adds the planned points whose two keypoints are still free in
/// live keyframes (local mapping may have culled one since the snapshot);
/// returns the points created.
pub(crate) fn apply_new_points(
    map: &mut Map,
    planned: Vec<NewPoint>,
) -> Result<Vec<MapPointId>, SlamError> {
    let free = |map: &Map, (kf, i): (KeyFrameId, usize)| {
        map.keyframe(kf)
            .is_ok_and(|k| i < k.measurements.len() && k.map_point(i).is_none())
    };
    let mut created = Vec::new();
    for p in planned {
        if !free(map, p.first) || !free(map, p.second) {
            continue;
        }
        let id = map
            .add_map_point(p.position, p.descriptor, p.first.0)
            .in_stage("triangulation")?;
        map.add_observation(id, p.first.0, p.first.1)
            .in_stage("triangulation")?;
        map.add_observation(id, p.second.0, p.second.1)
            .in_stage("triangulation")?;
        map.update_descriptor(id);
        map.update_normal_and_depth(id);
        created.push(id);
    }
    Ok(created)
}
