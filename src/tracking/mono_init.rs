//! Monocular initialisation: ORB-SLAM3's `Tracking::MonocularInitialization`
//! and `CreateInitialMapMonocular`. A reference frame is kept; each later
//! frame is matched to it in a 100-px window (`SearchForInitialization`),
//! and two views with enough matches are reconstructed (homography or
//! fundamental matrix, [`crate::geometry::two_view`]). The map starts with
//! both frames as keyframes and the triangulated points, scaled so that
//! the first keyframe's median point depth is 1 (the scale is arbitrary).

use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};
use crate::geometry::two_view::{reconstruct_two_views, TwoViewParams, TwoViewReconstruction};
use crate::map::{KeyFrameId, Map, MapPointId, PointDescriptor};
use crate::matching::{match_temporal, Match, TemporalParams};
use crate::optim::{LieGroup, Se3};

use super::frame::Frame;

/// Keypoints a frame needs to start or continue an initialisation
/// (ORB-SLAM3: `mCurrentFrame.mvKeys.size() > 100`).
pub const MIN_MONO_INIT_KEYPOINTS: usize = 100;
/// Matches the two views need (ORB-SLAM3: `nmatches < 100` resets).
pub const MIN_MONO_INIT_MATCHES: usize = 100;
/// Points the first keyframe pair must share (ORB-SLAM3's
/// `CreateInitialMapMonocular` resets below 50 tracked points).
const MIN_INITIAL_POINTS: usize = 50;

/// The map made by a successful initialisation.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct MonoInitialMap {
    /// The reference frame's keyframe (at the origin).
    pub first: KeyFrameId,
    /// The reference frame's index in the input.
    pub first_frame: usize,
    /// The current frame's keyframe.
    pub second: KeyFrameId,
    /// The points created.
    pub points: Vec<MapPointId>,
}

/// Seconds of frames between the two views kept for localisation once the
/// map exists (see [`super::between_views`]); older ones are dropped.
const KEPT_BETWEEN_VIEWS_S: f64 = 2.0;
/// Frames between the two views kept, at least.
const MIN_KEPT_BETWEEN_VIEWS: usize = 10;
/// Frames between the two views kept, at most (a fast camera's 2 s would
/// hold hundreds of frames' descriptors).
const MAX_KEPT_BETWEEN_VIEWS: usize = 60;

/// The monocular initialiser's state: the reference frame, where its
/// keypoints were last matched (ORB-SLAM3's `mvbPrevMatched`), and the
/// frames offered since the reference that did not initialise.
#[derive(Debug, Clone, Default)]
pub(crate) struct MonoInitialiser {
    reference: Option<Frame>,
    last_positions: Vec<(f32, f32)>,
    between: Vec<Frame>,
}

impl MonoInitialiser {
    /// Offers a frame: it becomes the reference, or is matched against it
    /// and, when the two views reconstruct, the initial map is built in
    /// `map` (both keyframes, the points) and `frame` gets its pose and
    /// points. `None` while waiting.
    pub fn offer(
        &mut self,
        frame: &mut Frame,
        map: &mut Map,
        rig: &CameraRig,
    ) -> Result<Option<MonoInitialMap>, SlamError> {
        let Some(reference) = self.reference.as_ref() else {
            self.restart(frame);
            return Ok(None);
        };
        if frame.len() <= MIN_MONO_INIT_KEYPOINTS {
            self.reference = None;
            self.between.clear();
            return Ok(None);
        }
        let thresholds = frame.distance_thresholds;
        let params = TemporalParams {
            window: 100.0,
            octave_tolerance: 0,
            ratio: Some(0.9),
            max_distance: thresholds.low,
            check_orientation: true,
        };
        let matches = match_temporal(
            &reference.features,
            &frame.features,
            &frame.grid,
            Some(&self.last_positions),
            params,
        )
        .in_stage("monocular initialisation")?;
        tracing::debug!(
            frame = frame.index,
            reference = reference.index,
            matches = matches.len(),
            "monocular initialisation"
        );
        if matches.len() < MIN_MONO_INIT_MATCHES {
            // ORB-SLAM3 starts over from the next frame.
            self.reference = None;
            self.between.clear();
            return Ok(None);
        }
        for m in &matches {
            if let (Some(last), Some(kp)) = (
                self.last_positions.get_mut(m.query),
                frame.features.keypoints.get(m.train),
            ) {
                *last = (kp.x, kp.y);
            }
        }
        let camera = rig.intrinsics();
        let pixel = |f: &Frame, i: usize| {
            f.features
                .keypoints
                .get(i)
                .map(|kp| nalgebra::Point2::new(f64::from(kp.x), f64::from(kp.y)))
        };
        let pairs: Vec<_> = matches
            .iter()
            .filter_map(|m| Some((pixel(reference, m.query)?, pixel(frame, m.train)?)))
            .collect();
        let reconstruction = match reconstruct_two_views(&camera, &pairs, &TwoViewParams::default())
        {
            Ok(r) => r,
            Err(why) => {
                tracing::debug!(frame = frame.index, %why, "two views not reconstructed");
                self.keep_between(frame, rig);
                return Ok(None);
            }
        };
        tracing::info!(
            frame = frame.index,
            reference = reference.index,
            model = ?reconstruction.model,
            parallax_deg = reconstruction.parallax_deg,
            points = reconstruction.triangulated,
            "monocular map initialised"
        );
        let Some(reference) = self.reference.take() else {
            return Ok(None);
        };
        let built = build_initial_map(reference, frame, &matches, &reconstruction, map)?;
        if built.is_none() {
            // Too few points: ORB-SLAM3 starts over from the next frame.
            self.between.clear();
        }
        Ok(built)
    }

    /// The frames offered since the reference that did not initialise,
    /// oldest first (emptied: the caller localises them once the map
    /// exists).
    pub fn take_between(&mut self) -> Vec<Frame> {
        std::mem::take(&mut self.between)
    }

    /// Keeps `frame` as one between the views, dropping the oldest beyond
    /// [`KEPT_BETWEEN_VIEWS_S`] of frames.
    fn keep_between(&mut self, frame: &Frame, rig: &CameraRig) {
        let cap = ((KEPT_BETWEEN_VIEWS_S * rig.fps).ceil() as usize)
            .clamp(MIN_KEPT_BETWEEN_VIEWS, MAX_KEPT_BETWEEN_VIEWS);
        if self.between.len() >= cap {
            self.between.remove(0);
        }
        self.between.push(frame.clone());
    }

    fn restart(&mut self, frame: &Frame) {
        self.between.clear();
        if frame.len() > MIN_MONO_INIT_KEYPOINTS {
            self.last_positions = frame
                .features
                .keypoints
                .iter()
                .map(|k| (k.x, k.y))
                .collect();
            self.reference = Some(frame.clone());
        }
    }
}

/// ORB-SLAM3's `CreateInitialMapMonocular` (without its global BA, which
/// local mapping's first BA stands in for): two keyframes, one point per
/// triangulated match, the scale set by the first keyframe's median depth.
fn build_initial_map(
    mut reference: Frame,
    frame: &mut Frame,
    matches: &[Match],
    reconstruction: &TwoViewReconstruction,
    map: &mut Map,
) -> Result<Option<MonoInitialMap>, SlamError> {
    let mut depths: Vec<f64> = reconstruction
        .points
        .iter()
        .flatten()
        .map(|p| p.z)
        .collect();
    if depths.len() < MIN_INITIAL_POINTS {
        return Ok(None);
    }
    let Some(median) = crate::stats::upper_median(&mut depths) else {
        return Ok(None);
    };
    if !(median.is_finite() && median > 0.0) {
        return Ok(None);
    }
    let scale = 1.0 / median;
    reference.pose_cw = Se3::identity();
    let pose_21 = Se3::new(
        reconstruction.pose_21.rotation,
        reconstruction.pose_21.translation * scale,
    );
    frame.pose_cw = pose_21;
    let first = map
        .add_keyframe(
            reference.index,
            reference.timestamp,
            reference.pose_cw,
            reference.measurements(),
        )
        .in_stage("monocular initialisation")?;
    let second = map
        .add_keyframe(
            frame.index,
            frame.timestamp,
            frame.pose_cw,
            frame.measurements(),
        )
        .in_stage("monocular initialisation")?;
    let mut points = Vec::new();
    for (m, point) in matches.iter().zip(&reconstruction.points) {
        let Some(point) = point else { continue };
        let Some(descriptor) = PointDescriptor::from_set(&reference.features.descriptors, m.query)
        else {
            continue;
        };
        let id = map
            .add_map_point(point * scale, descriptor, first)
            .in_stage("monocular initialisation")?;
        map.add_observation(id, first, m.query)
            .in_stage("monocular initialisation")?;
        map.add_observation(id, second, m.train)
            .in_stage("monocular initialisation")?;
        map.update_normal_and_depth(id);
        if let Some(slot) = frame.map_points.get_mut(m.train) {
            *slot = Some(id);
        }
        points.push(id);
    }
    map.update_connections(first);
    map.update_connections(second);
    frame.reference_keyframe = Some(second);
    Ok(Some(MonoInitialMap {
        first,
        first_frame: reference.index,
        second,
        points,
    }))
}
