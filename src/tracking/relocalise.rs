//! Relocalisation: descriptor matches against keyframes' points, a PnP
//! RANSAC pose (OpenCV), then pose-only refinement.
//!
//! The keyframes tried come from a [`RelocalisationCandidates`] source when
//! the tracker has one (the place-recognition database of loop closing,
//! as ORB-SLAM3's `KeyFrameDatabase::DetectRelocalizationCandidates`), else
//! from a scan of the [`MAX_SCANNED_KEYFRAMES`] newest keyframes.

use std::collections::BTreeSet;

use opencv::core::{Mat, Point2f, Point3f, Vector};
use opencv::prelude::*;

use nalgebra::{Rotation3, UnitQuaternion, Vector3};

use crate::map::{KeyFrameId, Map, MapPointId};
use crate::optim::Se3;

use super::frame::Frame;
use super::pose::refine_pose;
use super::search::{
    keyframe_points_in_view, match_descriptors_in_view, match_projected, visible_in_frame,
    VisiblePoint,
};
use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};

/// Keyframes tried, newest first, without a candidate source.
pub const MAX_SCANNED_KEYFRAMES: usize = 30;
/// Inliers needed to accept a relocalisation (ORB-SLAM3: 50).
pub const MIN_RELOCALISATION_INLIERS: usize = 50;

/// Where relocalisation gets the keyframes to try: a place-recognition
/// query by the lost frame's appearance (ORB-SLAM3's
/// `DetectRelocalizationCandidates`). Tracking knows only this seam; the
/// implementation lives with the database (see
/// `crate::loop_closing::DatabaseRelocaliser`).
pub trait RelocalisationCandidates: Send + Sync + std::fmt::Debug {
    /// Keyframes of `map` that may see what `frame` sees, best first.
    /// `Some` list is all relocalisation tries: an empty one (nothing
    /// similar, or a failed query, which the implementation reports
    /// itself) makes it fail on this frame. `None` means the source cannot
    /// judge this frame (say binary descriptors, or nothing stored yet):
    /// relocalisation scans the newest keyframes instead. Called under the
    /// map's read lock.
    fn candidates(&self, frame: &Frame, map: &Map) -> Option<Vec<KeyFrameId>>;
}

/// The [`MAX_SCANNED_KEYFRAMES`] newest keyframes of `map`, newest first.
fn newest_keyframes(map: &Map) -> Vec<KeyFrameId> {
    let ids: Vec<KeyFrameId> = map.keyframes().map(|kf| kf.id()).collect();
    ids.into_iter().rev().take(MAX_SCANNED_KEYFRAMES).collect()
}

/// A RANSAC pose and the matches that agree with it.
#[derive(Debug, Clone)]
pub(crate) struct PnpPose {
    /// The frame's pose `T_cw`.
    pub pose_cw: Se3,
    /// Which of the matches given are RANSAC inliers (indices into them).
    pub inlier_matches: Vec<usize>,
}

impl PnpPose {
    /// RANSAC inliers.
    pub fn inliers(&self) -> usize {
        self.inlier_matches.len()
    }

    /// Starts `frame` from this pose with only the RANSAC inliers among
    /// `matches` as its map points, as ORB-SLAM3's `Relocalization` does
    /// before `PoseOptimization`: refined from the outliers too, a pose
    /// of 54 inliers among 157 matches kept 1 (the low-texture lap's
    /// first corner).
    pub fn start(&self, frame: &mut Frame, matches: &[(usize, MapPointId)]) {
        frame.pose_cw = self.pose_cw;
        frame.map_points.iter_mut().for_each(|p| *p = None);
        for &m in &self.inlier_matches {
            if let Some(&(i, p)) = matches.get(m) {
                if let Some(slot) = frame.map_points.get_mut(i) {
                    *slot = Some(p);
                }
            }
        }
    }
}

/// ORB-SLAM3's RANSAC iterations for relocalisation (`PnPsolver::
/// SetRansacParameters(0.99, 10, 300, …)`).
pub(crate) const PNP_RANSAC_ITERATIONS: i32 = 300;

/// A pose from 3-D/2-D matches by OpenCV's `solvePnPRansac` (EPnP inside
/// RANSAC, at most `iterations`, 4 px threshold at level 0); `None` when
/// it fails or fewer than 10 matches agree.
pub(crate) fn pnp_ransac(
    frame: &Frame,
    map: &Map,
    matches: &[(usize, MapPointId)],
    rig: &CameraRig,
    iterations: i32,
) -> Result<Option<PnpPose>, SlamError> {
    let mut correspondences = Vec::with_capacity(matches.len());
    let mut used = Vec::with_capacity(matches.len());
    for (m, (i, id)) in matches.iter().enumerate() {
        let (Ok(p), Some(kp)) = (map.map_point(*id), frame.features.keypoints.get(*i)) else {
            continue;
        };
        correspondences.push((p.position, [kp.x, kp.y]));
        used.push(m);
    }
    let Some(mut pose) = pnp_ransac_points(&correspondences, rig, iterations)? else {
        return Ok(None);
    };
    pose.inlier_matches = pose
        .inlier_matches
        .iter()
        .filter_map(|&k| used.get(k).copied())
        .collect();
    Ok(Some(pose))
}

/// [`pnp_ransac`] on plain correspondences: a point (in the frame the pose
/// maps from) and the pixel that sees it. The pose's inlier indices are
/// into `correspondences`.
pub(crate) fn pnp_ransac_points(
    correspondences: &[(Vector3<f64>, [f32; 2])],
    rig: &CameraRig,
    iterations: i32,
) -> Result<Option<PnpPose>, SlamError> {
    if correspondences.len() < 6 {
        return Ok(None);
    }
    let mut object = Vector::<Point3f>::with_capacity(correspondences.len());
    let mut image = Vector::<Point2f>::with_capacity(correspondences.len());
    for (p, [u, v]) in correspondences {
        object.push(Point3f::new(p.x as f32, p.y as f32, p.z as f32));
        image.push(Point2f::new(*u, *v));
    }
    let c = &rig.camera;
    let k = Mat::from_slice_2d(&[[c.fx, 0.0, c.cx], [0.0, c.fy, c.cy], [0.0, 0.0, 1.0]])
        .in_stage("relocalisation camera matrix")?;
    let mut rvec = Mat::default();
    let mut tvec = Mat::default();
    let mut inliers = Vector::<i32>::new();
    let found = opencv::calib3d::solve_pnp_ransac(
        &object,
        &image,
        &k,
        &Mat::default(),
        &mut rvec,
        &mut tvec,
        false,
        iterations,
        4.0,
        0.99,
        &mut inliers,
        opencv::calib3d::SOLVEPNP_EPNP,
    )
    .in_stage("solvePnPRansac")?;
    if !found || inliers.len() < 10 {
        return Ok(None);
    }
    let r = |m: &Mat, i: i32| m.at::<f64>(i).copied().in_stage("PnP result");
    let axis = Vector3::new(r(&rvec, 0)?, r(&rvec, 1)?, r(&rvec, 2)?);
    let t = Vector3::new(r(&tvec, 0)?, r(&tvec, 1)?, r(&tvec, 2)?);
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::new(axis));
    let inlier_matches = inliers
        .iter()
        .filter_map(|k| usize::try_from(k).ok())
        .filter(|&k| k < correspondences.len())
        .collect();
    Ok(Some(PnpPose {
        pose_cw: Se3::new(rotation, t),
        inlier_matches,
    }))
}

/// Searches the keyframe's points not yet matched around their projections
/// at the frame's pose and refines again (ORB-SLAM3's second chance: window
/// 10, then 3 when 30–49 inliers remain). Returns the inliers.
fn widen_by_projection(
    frame: &mut Frame,
    map: &Map,
    keyframe: KeyFrameId,
    rig: &CameraRig,
    mut inliers: usize,
) -> Result<usize, SlamError> {
    for (radius, at_least) in [(10.0, 10), (3.0, 30)] {
        if inliers < at_least || inliers >= MIN_RELOCALISATION_INLIERS {
            break;
        }
        let found: BTreeSet<MapPointId> = frame.map_points.iter().flatten().copied().collect();
        let Ok(kf) = map.keyframe(keyframe) else {
            break;
        };
        let visible: Vec<VisiblePoint> = kf
            .observed_points()
            .filter(|(_, p)| !found.contains(p))
            .filter_map(|(_, p)| visible_in_frame(map, p, frame, rig))
            .collect();
        let added = match_projected(frame, map, &visible, radius, (1, 1), None)?;
        if inliers + added >= MIN_RELOCALISATION_INLIERS {
            inliers = refine_pose(frame, map, rig)?;
        }
    }
    Ok(inliers)
}

/// Keyframes tried before the database's: the keyframe tracking was lost
/// from and its best covisible ones.
pub const NEAR_RELOCALISATION_KEYFRAMES: usize = 5;

/// ORB-SLAM3's `Relocalization`: tries the keyframes `source` gives
/// (best first) when there is one and it judges the frame, else the
/// [`MAX_SCANNED_KEYFRAMES`] newest ones; accepts the first pose with at
/// least 50 inliers. spslam tries the neighbourhood of `lost_from`
/// (the reference keyframe when tracking was lost, and its
/// [`NEAR_RELOCALISATION_KEYFRAMES`] best covisible keyframes) first: a
/// camera lost for a few frames is most likely still there, and where
/// façades repeat, a place the database ranks higher may look the same.
/// On the repeated-texture lap (`spslam synth --condition
/// repeated-texture`, stereo) the camera lost at frame 89 in a corner
/// was relocalised at frame 91 into the lap's first corner, 67 m away,
/// with 198 inliers. A kidnapped camera (`--condition jump-back`) finds
/// nothing near and relocalises by the database as before.
pub(crate) fn relocalise_with(
    frame: &mut Frame,
    map: &Map,
    rig: &CameraRig,
    source: Option<&dyn RelocalisationCandidates>,
    lost_from: Option<KeyFrameId>,
) -> Result<bool, SlamError> {
    let mut candidates: Vec<KeyFrameId> = lost_from
        .filter(|&kf| map.keyframe(kf).is_ok())
        .map(|kf| {
            std::iter::once(kf)
                .chain(map.best_covisible(kf, NEAR_RELOCALISATION_KEYFRAMES))
                .collect()
        })
        .unwrap_or_default();
    match source.and_then(|s| s.candidates(frame, map)) {
        Some(found) => candidates.extend(found),
        None => candidates.extend(newest_keyframes(map)),
    }
    relocalise_among(frame, map, rig, &candidates)
}

/// Tries `candidates` in order (a keyframe no longer in the map, or named
/// twice, is skipped): descriptor matches with its points, PnP RANSAC,
/// pose-only refinement, and a search by projection when 10–49 inliers
/// remain; accepts the first pose with at least 50 inliers.
fn relocalise_among(
    frame: &mut Frame,
    map: &Map,
    rig: &CameraRig,
    candidates: &[KeyFrameId],
) -> Result<bool, SlamError> {
    let mut tried = BTreeSet::new();
    for &kf in candidates {
        if !tried.insert(kf) {
            continue;
        }
        let Ok(keyframe) = map.keyframe(kf) else {
            continue;
        };
        let points = keyframe_points_in_view(keyframe);
        let matches = match_descriptors_in_view(frame, map, &points, 0.75)?;
        if matches.len() < 15 {
            tracing::trace!(
                frame = frame.index,
                keyframe = kf.0,
                matches = matches.len(),
                "relocalisation: too few matches"
            );
            continue;
        }
        let Some(pose) = pnp_ransac(frame, map, &matches, rig, PNP_RANSAC_ITERATIONS)? else {
            tracing::trace!(
                frame = frame.index,
                keyframe = kf.0,
                matches = matches.len(),
                "relocalisation: PnP failed"
            );
            continue;
        };
        pose.start(frame, &matches);
        let mut inliers = refine_pose(frame, map, rig)?;
        if (10..MIN_RELOCALISATION_INLIERS).contains(&inliers) {
            inliers = widen_by_projection(frame, map, kf, rig, inliers)?;
        }
        tracing::trace!(
            frame = frame.index,
            keyframe = kf.0,
            matches = matches.len(),
            inliers,
            "relocalisation: refined"
        );
        if inliers >= MIN_RELOCALISATION_INLIERS {
            frame.reference_keyframe = Some(kf);
            return Ok(true);
        }
    }
    frame.map_points.iter_mut().for_each(|p| *p = None);
    Ok(false)
}
