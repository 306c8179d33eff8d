//! A lost frame's motion from the input frame before it, measured by
//! stereo (or depth) odometry.
//!
//! When a frame cannot be tracked against the map, its images still say
//! how the camera moved since the frame before. With a depth per keypoint
//! (stereo or RGB-D), the previous frame's keypoints are 3-D points
//! in its camera; searched around where the predicted motion projects them
//! (or, failing that, matched by descriptor over the whole image and put
//! through PnP RANSAC) they give this frame's pose relative to that
//! camera, refined with this frame's own stereo observations. This is ORB-SLAM3's visual
//! odometry (`Tracking::UpdateLastFrame`'s temporary points from the last
//! frame's depths, used in localisation mode when too few map points are
//! found: `mbVO`), without the map. Where the previous frame's depths give
//! no step, this frame's depths are searched in the previous frame and the
//! step inverted (ORB-SLAM3 looks one way only): an RGB-D frame that looks
//! beyond the sensor's range has few depths, its neighbour many. It helps
//! where the map cannot: in a fast turn with motion blur, consecutive
//! blurred frames share their blur and match each other far better than
//! the sharp keyframes before the turn.
//!
//! The step is measured only; the map is not changed and tracking stays
//! lost (relocalisation is tried on the frame as before). The run's
//! records chain the steps (`crate::system`): a lost frame joined by
//! steps to a frame with a pose, before or after it, gets its pose that
//! way, and a map started after a loss is anchored where the measured
//! motion puts its first frame instead of where the last velocity would.
//! A step needs [`MIN_STEP_INLIERS`] refined inliers: it changes only the
//! frame's record, like the frames localised after a loss.

use nalgebra::Vector3;

use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};
use crate::matching::{
    match_brute_force_spaced, search_by_projection_filtered, CandidateFilter, MatchParams,
    ProjectedPoint, ProjectionParams, TrainLayout,
};
use crate::optim::pose_only::{optimise_pose, PoseCorrespondence, PoseOnlyConfig};
use crate::optim::{LieGroup, Se3};

use super::frame::Frame;
use super::motion::octave_within;
use super::pose::frame_observation;
use super::relocalise::{pnp_ransac_points, PNP_RANSAC_ITERATIONS};

/// Refined inliers a step needs: ORB-SLAM3's acceptance of a visual
/// odometry pose, "more than 20" (`TrackWithMotionModel` in localisation
/// mode: `return nmatches>20`, the matches to the last frame's temporary
/// points and map points left after `PoseOptimization`). A step is
/// measured between two consecutive frames, not against a map that may
/// hold stale points, so it takes the odometry bound rather than
/// local-map tracking's 30. Measured on the blurred laps (session 50,
/// `EVALUATION.md`): 30 left chains broken by steps of 21–29 inliers at
/// the lap's corners; those steps are about twice as far off the truth
/// as steps of 30–49 (90th percentile 0.24–0.40 m against 0.22 m on 1 m
/// steps), which costs some laps ATE where a new map hangs from one.
pub const MIN_STEP_INLIERS: usize = 21;

/// Lowe's ratio for the two frames' descriptors: ORB-SLAM3's
/// relocalisation ratio (0.75 in `Relocalization`'s `SearchByBoW`).
const STEP_MATCH_RATIO: f32 = 0.75;

/// A frame's motion from the frame before it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryStep {
    /// `T_c,p`: the previous frame's camera to this frame's.
    pub pose_cp: Se3,
    /// Refined inliers.
    pub inliers: usize,
}

/// The motion from `previous` to `current` (`T_c,p`), measured from the
/// keypoints with a depth of either frame: first `previous`'s 3-D points
/// found in `current` (ORB-SLAM3's odometry from the last frame), then, when
/// that gives no step, `current`'s 3-D points found in `previous` and the
/// step inverted. The two frames of a step need not see depth alike: in an
/// RGB-D turn the camera may look down a street beyond the sensor's range
/// on one frame and at a near façade on the next, and the step is the same
/// rigid motion whichever frame's depths measure it. `None` when neither
/// direction gives [`MIN_STEP_INLIERS`] refined inliers.
pub(crate) fn measure_step(
    previous: &Frame,
    current: &Frame,
    rig: &CameraRig,
    prediction: Option<&Se3>,
) -> Result<Option<OdometryStep>, SlamError> {
    if let Some(step) = step_from_depths_of(previous, current, rig, prediction)? {
        return Ok(Some(step));
    }
    let reverse_prediction = prediction.map(Se3::inverse);
    let reverse = step_from_depths_of(current, previous, rig, reverse_prediction.as_ref())?;
    Ok(reverse.map(|step| OdometryStep {
        pose_cp: step.pose_cp.inverse(),
        inliers: step.inliers,
    }))
}

/// The motion from `previous` to `current` (`T_c,p`) when their keypoints
/// with a depth in `previous` give a pose with [`MIN_STEP_INLIERS`]
/// refined inliers; `None` otherwise (too few matches, no RANSAC pose).
///
/// With a `prediction` of the step (the last velocity, turned by the
/// rotation the two frames' thumbnails show), the points are first
/// searched around their predicted projections ([`guided_step`]: ORB-SLAM3's
/// `SearchByProjection` of the last frame's points); where that leaves too
/// few inliers, by descriptor over the whole image and PnP RANSAC
/// ([`matched_step`]). The guided search is what finds the first frame of
/// a blurred turn: against the sharp frame before it, few descriptors pass
/// a ratio test over the whole image, but most lie where the prediction
/// puts them.
fn step_from_depths_of(
    previous: &Frame,
    current: &Frame,
    rig: &CameraRig,
    prediction: Option<&Se3>,
) -> Result<Option<OdometryStep>, SlamError> {
    // The previous frame's keypoints with a depth, and their points in its camera.
    let (rows, points): (Vec<usize>, Vec<Vector3<f64>>) = (0..previous.len())
        .filter_map(|i| {
            let kp = previous.features.keypoints.get(i)?;
            let depth = previous.depth(i)?;
            Some((i, rig.unproject(f64::from(kp.x), f64::from(kp.y), depth)))
        })
        .unzip();
    if rows.len() < MIN_STEP_INLIERS {
        return Ok(None);
    }
    if let Some(predicted) = prediction {
        let guided = guided_step(previous, current, rig, (&rows, &points), predicted)?;
        if guided.is_some() {
            return Ok(guided);
        }
    }
    matched_step(previous, current, rig, (&rows, &points))
}

/// The step from the previous frame's points (`rows`, with `points` their
/// positions in its camera) matched by descriptor over the whole image
/// (ratio and mutual check, the rival test beyond the descriptor cell as
/// in tracking's descriptor matching), a PnP RANSAC pose, then refined.
fn matched_step(
    previous: &Frame,
    current: &Frame,
    rig: &CameraRig,
    (rows, points): (&[usize], &[Vector3<f64>]),
) -> Result<Option<OdometryStep>, SlamError> {
    let mut keep = vec![false; previous.len()];
    for &i in rows {
        keep[i] = true;
    }
    let mut train = previous.features.descriptors.clone();
    train.retain_rows(|i| keep[i]);
    let cell = previous.descriptor_cell.unwrap_or(0.0);
    let (positions, rival_distances): (Vec<[f32; 2]>, Vec<f32>) = rows
        .iter()
        .filter_map(|&i| previous.features.keypoints.get(i))
        .map(|kp| {
            let scale = previous.scales.scale_at(kp.octave).unwrap_or(1.0);
            ([kp.x, kp.y], cell * scale)
        })
        .unzip();
    let layout = (cell > 0.0).then_some(TrainLayout {
        positions: &positions,
        min_rival_distance: &rival_distances,
    });
    let matches = match_brute_force_spaced(
        &current.features.descriptors,
        &train,
        MatchParams {
            ratio: Some(STEP_MATCH_RATIO),
            max_distance: current.distance_thresholds.high,
            mutual: true,
        },
        layout,
    )
    .in_stage("odometry matching")?;
    if matches.len() < MIN_STEP_INLIERS {
        return Ok(accepted(
            None,
            (current, previous),
            matches.len(),
            "descriptors",
        ));
    }
    // (point in the previous camera, this frame's keypoint index)
    let pairs: Vec<(Vector3<f64>, usize)> = matches
        .iter()
        .filter_map(|m| Some((*points.get(m.train)?, m.query)))
        .collect();
    let correspondences: Vec<(Vector3<f64>, [f32; 2])> = pairs
        .iter()
        .filter_map(|&(p, i)| {
            let kp = current.features.keypoints.get(i)?;
            Some((p, [kp.x, kp.y]))
        })
        .collect();
    let Some(start) = pnp_ransac_points(&correspondences, rig, PNP_RANSAC_ITERATIONS)? else {
        return Ok(None);
    };
    if start.inliers() < MIN_STEP_INLIERS {
        return Ok(None);
    }
    let limit = rig.stereo_depth_limit();
    let refined: Vec<PoseCorrespondence> = start
        .inlier_matches
        .iter()
        .filter_map(|&k| {
            let &(point, i) = pairs.get(k)?;
            Some(PoseCorrespondence {
                point,
                observation: frame_observation(current, i, limit)?,
            })
        })
        .collect();
    let step = refine_step(&start.pose_cw, &refined, rig)?;
    Ok(accepted(
        step,
        (current, previous),
        matches.len(),
        "descriptors",
    ))
}

/// A refined step when it has [`MIN_STEP_INLIERS`], logged with how it
/// was found (`by`: `"projection"` or `"descriptors"`) from `matches`.
fn accepted(
    step: Option<OdometryStep>,
    (current, previous): (&Frame, &Frame),
    matches: usize,
    by: &'static str,
) -> Option<OdometryStep> {
    tracing::debug!(
        frame = current.index,
        previous = previous.index,
        matches,
        inliers = step.map(|s| s.inliers),
        by,
        "gap odometry"
    );
    step.filter(|s| s.inliers >= MIN_STEP_INLIERS)
}

/// The search window around a predicted projection, level-0 pixels at
/// octave 0: ORB-SLAM3's motion-model window for monocular and RGB-D
/// cameras (`th = 15`), wider than its stereo one (7) because the
/// prediction over a gap is rougher; doubled when it finds too few.
const GUIDED_RADIUS: f32 = 15.0;
/// The ratio of the guided search (ORB-SLAM3's `SearchByProjection` of
/// the last frame: 0.9).
const GUIDED_RATIO: f32 = 0.9;

/// The step from the previous frame's points (`rows`, with `points` their
/// positions in its camera) searched around their projections at the
/// `predicted` step, then refined; `None` without enough inliers.
fn guided_step(
    previous: &Frame,
    current: &Frame,
    rig: &CameraRig,
    (rows, points): (&[usize], &[Vector3<f64>]),
    predicted: &Se3,
) -> Result<Option<OdometryStep>, SlamError> {
    let mut projected = Vec::with_capacity(rows.len());
    let mut sources = Vec::with_capacity(rows.len());
    for (&i, point) in rows.iter().zip(points) {
        let Some(uvr) = rig.project_in_image(&predicted.transform_point(point)) else {
            continue;
        };
        let (Some(kp), Some(descriptor)) = (
            previous.features.keypoints.get(i),
            previous.features.descriptors.row(i),
        ) else {
            continue;
        };
        projected.push(ProjectedPoint {
            u: uvr.x as f32,
            v: uvr.y as f32,
            predicted_octave: octave_within(kp.octave, current),
            descriptor,
            u_right: None,
        });
        sources.push(*point);
    }
    let mut matches = Vec::new();
    for radius in [GUIDED_RADIUS, 2.0 * GUIDED_RADIUS] {
        matches = search_by_projection_filtered(
            &projected,
            &current.features,
            &current.grid,
            &current.scales.scale_factors,
            ProjectionParams {
                radius,
                octaves_below: 1,
                octaves_above: 1,
                ratio: Some(GUIDED_RATIO),
                max_distance: current.distance_thresholds.high,
                min_rival_distance: current.descriptor_cell.unwrap_or(0.0),
            },
            CandidateFilter::default(),
        )
        .in_stage("odometry search by projection")?;
        if matches.len() >= MIN_STEP_INLIERS {
            break;
        }
    }
    let limit = rig.stereo_depth_limit();
    let correspondences: Vec<PoseCorrespondence> = matches
        .iter()
        .filter_map(|m| {
            Some(PoseCorrespondence {
                point: *sources.get(m.query)?,
                observation: frame_observation(current, m.train, limit)?,
            })
        })
        .collect();
    let step = if correspondences.len() >= MIN_STEP_INLIERS {
        refine_step(predicted, &correspondences, rig)?
    } else {
        None
    };
    Ok(accepted(
        step,
        (current, previous),
        matches.len(),
        "projection",
    ))
}

/// Pose-only refinement of a step from `start` (ORB-SLAM3's
/// `PoseOptimization`); `None` with too few correspondences to run it.
fn refine_step(
    start: &Se3,
    correspondences: &[PoseCorrespondence],
    rig: &CameraRig,
) -> Result<Option<OdometryStep>, SlamError> {
    let config = PoseOnlyConfig::default();
    if correspondences.len() < config.min_correspondences {
        return Ok(None);
    }
    let result = optimise_pose(&rig.camera, start, correspondences, &config)
        .in_stage("odometry pose refinement")?;
    Ok(Some(OdometryStep {
        pose_cp: result.pose,
        inliers: result.inlier_count,
    }))
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::{measure_step, OdometryStep, MIN_STEP_INLIERS};
    use crate::optim::{LieGroup, Se3};
    use crate::test_world::{pose_at, PointWorld};

    /// The step between two stereo frames 1 m and 3° apart that see the
    /// same `n` points (every one inside both images), predicted 0.2 m and
    /// 1° off, with the true step.
    fn step_over(n: usize) -> (Option<OdometryStep>, Se3) {
        step_with_depths(n, (true, true))
    }

    /// [`step_over`] with a depth per keypoint in the previous frame, the
    /// current one, both or neither (`depths`).
    fn step_with_depths(n: usize, depths: (bool, bool)) -> (Option<OdometryStep>, Se3) {
        let world = PointWorld::new(11, n, (3.0, 2.0, 8.0, 12.0));
        let first = pose_at(Vector3::zeros(), 0.0);
        let second = pose_at(Vector3::new(0.1, 0.0, 1.0), 3f64.to_radians());
        let (previous, seen_first) = world.frame(0, &first, depths.0);
        let (current, seen_second) = world.frame(1, &second, depths.1);
        assert_eq!(
            (seen_first.point_of.len(), seen_second.point_of.len()),
            (n, n)
        );
        let truth = second.compose(&first.inverse());
        let off = pose_at(Vector3::new(0.2, 0.0, 0.0), 1f64.to_radians());
        let predicted = off.compose(&truth);
        let step = measure_step(&previous, &current, &world.rig, Some(&predicted))
            .unwrap_or_else(|e| panic!("{e}"));
        (step, truth)
    }

    #[test]
    fn a_step_needs_more_than_twenty_inliers_as_orb_slam3_odometry() {
        assert_eq!(MIN_STEP_INLIERS, 21);
        let (step, truth) = step_over(MIN_STEP_INLIERS);
        let step = step.expect("21 points seen by both frames give a step");
        assert_eq!(step.inliers, MIN_STEP_INLIERS);
        let error = truth.inverse().compose(&step.pose_cp);
        let (metres, radians) = (error.translation.norm(), error.rotation.angle());
        assert!(
            metres < 1e-3 && radians < 1e-4,
            "{metres} m, {radians} rad off"
        );
        let (step, _) = step_over(MIN_STEP_INLIERS - 1);
        assert_eq!(step, None, "20 points give no step");
    }

    /// The same rigid motion whichever frame's depths measure it: with none
    /// in the previous frame (a view beyond the depth sensor's range), the
    /// current frame's points found in the previous one give the step, to
    /// the same precision as the forward direction; with depths in neither
    /// frame there is no step.
    #[test]
    fn a_step_is_measured_from_the_current_frames_depths_when_the_previous_has_none() {
        for depths in [(true, true), (false, true)] {
            let (step, truth) = step_with_depths(60, depths);
            let step = step.unwrap_or_else(|| panic!("a step with depths {depths:?}"));
            // Measured: 60 forwards, 44 backwards (the guided search's
            // first window holds 44 of the points at this prediction).
            assert!(
                step.inliers >= 40,
                "depths {depths:?}: {} inliers of 60",
                step.inliers
            );
            let error = truth.inverse().compose(&step.pose_cp);
            let (metres, radians) = (error.translation.norm(), error.rotation.angle());
            assert!(
                metres < 1e-3 && radians < 1e-4,
                "depths {depths:?}: {metres} m, {radians} rad off"
            );
        }
        assert_eq!(step_with_depths(60, (false, false)).0, None);
    }
}
