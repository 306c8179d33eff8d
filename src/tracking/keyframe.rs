//! Keyframes from tracking: the stereo map initialisation, ORB-SLAM3's
//! keyframe decision for stereo, and keyframe insertion with new close points.

use crate::map::{KeyFrameId, Map, MapPointId, PointDescriptor};
use crate::optim::{LieGroup, Se3};

use super::frame::Frame;
use crate::camera::{CameraRig, Sensor};
use crate::error::{MapContext, SlamError};

/// Keypoints needed to initialise (ORB-SLAM3's `StereoInitialization`
/// tests `N > 500`, the keypoint count, not the stereo matches).
pub const MIN_INITIAL_KEYPOINTS: usize = 500;
/// Stereo points needed as well (spslam's guard: a map needs depths).
pub const MIN_INITIAL_STEREO_POINTS: usize = 100;

/// Creates a map point from keypoint `i`'s stereo depth, observed by `keyframe`.
fn point_from_stereo(
    map: &mut Map,
    keyframe: KeyFrameId,
    frame: &Frame,
    i: usize,
    rig: &CameraRig,
) -> Result<Option<MapPointId>, SlamError> {
    let (Some(position), Some(descriptor)) = (
        frame.unproject_world(i, rig),
        PointDescriptor::from_set(&frame.features.descriptors, i),
    ) else {
        return Ok(None);
    };
    let id = map
        .add_map_point(position, descriptor, keyframe)
        .in_stage("new stereo point")?;
    map.add_observation(id, keyframe, i)
        .in_stage("new stereo point")?;
    map.update_normal_and_depth(id);
    Ok(Some(id))
}

/// ORB-SLAM3's `StereoInitialization`: the first frame with more than 500
/// keypoints (and at least 100 stereo points) becomes a keyframe at the origin, with one point per stereo
/// keypoint (after the depth filter). `None` when the frame has too few.
pub(crate) fn initialise_map(
    frame: &mut Frame,
    map: &mut Map,
    rig: &CameraRig,
) -> Result<Option<KeyFrameId>, SlamError> {
    if frame.len() <= MIN_INITIAL_KEYPOINTS || frame.stereo_count() < MIN_INITIAL_STEREO_POINTS {
        return Ok(None);
    }
    let keyframe = map
        .add_keyframe(
            frame.index,
            frame.timestamp,
            frame.pose_cw,
            frame.measurements(),
        )
        .in_stage("initialisation")?;
    for i in 0..frame.len() {
        if frame.depth(i).is_some() {
            frame.map_points[i] = point_from_stereo(map, keyframe, frame, i, rig)?;
        }
    }
    frame.reference_keyframe = Some(keyframe);
    Ok(Some(keyframe))
}

/// What [`needs_keyframe`] looks at besides the frame.
#[derive(Debug, Clone, Copy)]
pub(crate) struct KeyFrameContext {
    /// The reference keyframe.
    pub reference: KeyFrameId,
    /// Frame index of the last keyframe.
    pub last_keyframe_frame: usize,
    /// Frame index of the last relocalisation.
    pub last_relocalisation_frame: Option<usize>,
    /// Map points matched as inliers in the frame.
    pub inliers: usize,
    /// What condition 2 compares with near the reference keyframe (see
    /// [`next_near_reference_count`]).
    pub near_reference_count: usize,
    /// Frames between keyframes at most (the frame rate).
    pub max_frames: usize,
    /// Keyframes local mapping has not finished (0: idle, ORB-SLAM3's
    /// `AcceptKeyFrames`).
    pub mapping_queue: usize,
    /// The camera's motion over the last frame (the motion model's
    /// velocity, `T_cw(now) · T_cw(last)⁻¹`), when known.
    pub velocity: Option<Se3>,
}

/// A busy local mapping still takes a keyframe while fewer than this many
/// wait (ORB-SLAM3, stereo: `KeyframesInQueue() < 3`).
const MAX_MAPPING_QUEUE: usize = 3;

/// What [`needs_keyframe`] decided for a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct KeyFrameDecision {
    /// The frame becomes a keyframe.
    pub insert: bool,
    /// Local mapping's BA should yield now (ORB-SLAM3's `InterruptBA`):
    /// a monocular keyframe was wanted while mapping was busy, and a
    /// monocular camera's new points come only from mapping.
    pub interrupt_mapping: bool,
}

/// ORB-SLAM3's `NeedNewKeyFrame` for stereo, RGB-D and monocular, with
/// four departures: condition 2's ratio counts against what the view of
/// the reference tracked while the camera stays near it (below); a keyframe wanted because tracking is weak
/// (condition 1c) is never refused for local mapping's queue; a monocular
/// camera has a condition 1c too (below); and ORB-SLAM3's close-point condition
/// (`bNeedToInsertClose`: fewer than 100 tracked close points, more than
/// 70 untracked) is also applied to the next frame as the motion model
/// predicts it, counting this frame's tracked close points that stay in
/// view ([`tracked_close_in_next_frame`]).
///
/// The first departure is for a camera that moves little between frames
/// (a handheld camera at 30 Hz). ORB-SLAM3's condition 2 compares the
/// frame's inliers with the reference keyframe's points seen by three
/// keyframes, and that count grows with the keyframe rate: once keyframes
/// come on most frames, every point is seen by three of them. SuperPoint
/// finds about half of a keyframe's points again in the next frame (as
/// ORB does), so on the 7-Scenes kitchen its inliers stayed under 0.75 of
/// the reference's 600–800 such points and 244 of 300 frames became
/// keyframes (ORB: 16). While the camera is near its reference (a
/// baseline under [`NEAR_BASELINE_RATIO`] of the reference's median scene
/// depth and under [`NEAR_ROTATION_DEG`] of rotation), the ratio is taken
/// of the fewer of those points and what this view gave: the keyframe's
/// own inliers when it was made (stereo, RGB-D), or the most a frame has
/// tracked with it (monocular; [`next_near_reference_count`] says why), so a
/// keyframe comes when tracking falls a quarter below what this view gave,
/// not below what the keyframe rate gave. Farther away ORB-SLAM3's rule is
/// kept as it is: the synthetic laps (10 Hz, 5–14 % of the depth a frame)
/// and KITTI (5–9 %) need their keyframes, and fewer made them drift
/// 10–60 % more; the kitchen moves 0.3–2.7 % of its depth from its
/// reference (10th–90th percentile). Measured with mapping inline
/// (EVALUATION.md, "The keyframe rate near the reference"): the kitchen
/// 244 → 56 keyframes (ORB 16 → 12) with a 6 % lower ATE, the kitchen in
/// monocular 245 → 91 with 22 more frames tracked; the laps and KITTI 06
/// unchanged. With the stereo and RGB-D near-reference count held at the
/// keyframe's own count (it was the peak of the frames since), the
/// kitchen 56 → 29 keyframes, ATE 0.0195 → 0.0241 m (ORB 0.0281 m;
/// EVALUATION.md, "The peak after a keyframe").
///
/// The look-ahead (the last departure) is for fast rotation. ORB-SLAM3 compares the
/// frame's inliers with the reference keyframe's points seen by three
/// keyframes; a keyframe made in mid-turn has few such points (its own
/// close points are new), so the frames after it look strong while every
/// point they track slides out at one side of the image. On the lap with a
/// turn in place (`spslam synth --scene loop --condition turn-in-place`,
/// RGB-D, 20° per frame at the fastest), frame 134 tracked 160 points, all
/// in the left quarter of the image, against a reference with 91 such
/// points: no keyframe, and frame 135 found none of them in view (lost,
/// then a new map). Counting the points still in view one frame ahead
/// catches that frame, and only then: the normal lap, KITTI 06 and the
/// 7-Scenes kitchen keep their keyframe counts within 12 % (EVALUATION.md,
/// "Fast rotation").
///
/// ORB-SLAM3 refuses every keyframe while three wait for local mapping.
/// A stereo or RGB-D keyframe does not need local mapping to help
/// tracking: it brings its own close points, made by tracking itself
/// ([`insert_keyframe`]). When mapping lags, the refusals starved tracking
/// of points at the turns of the demo lap. Measured on the 480×360 lap
/// (`spslam synth --scene loop --size 480x360 --focal 300`, stereo, one
/// level) with local mapping ten times slower than the 10 fps camera
/// (`spslam run --inline-mapping --mapping-lag 10`): SuperPoint + ANMS
/// tracked 197 of 232 frames in 8 maps with ORB-SLAM3's rule, 232 in one
/// map with this one and the last-frame fallback of
/// [`super::motion::track_last_frame`]; ORB 188 → 227.
///
/// A monocular camera gets its new points only from local mapping's
/// triangulation, and ORB-SLAM3 gives it a keyframe only when mapping is
/// idle (after `mMaxFrames` it interrupts the BA, and still inserts
/// nothing). With mapping five times slower than the camera
/// (`--mapping-lag 5`, the 640×480 demo lap) that was one keyframe per
/// whole mapping step, and SuperPoint + ANMS tracked 131 of 232 frames,
/// ORB 143. While mapping is busy, spslam counts every monocular keypoint
/// as close (it has no depth), so ORB-SLAM3's close-point condition reads
/// "fewer than 100 tracked points" and makes a weak monocular frame a
/// keyframe through condition 1c: 227 of 232 for both extractors. A
/// monocular keyframe wanted while mapping is busy interrupts the BA
/// ([`KeyFrameDecision::interrupt_mapping`]) when ORB-SLAM3's
/// `NeedNewKeyFrame` does: when condition 1a (`mMaxFrames` since the last
/// keyframe) or 1c (weak tracking) holds with condition 2. Until session
/// 43 spslam interrupted for every wanted keyframe; with ORB-SLAM3's
/// condition the 640×480 lap with mapping five times slower
/// (`--mapping-lag 5`) tracks 232 of 232 frames with SuperPoint + ANMS
/// (227 before; ORB 227 both ways) and the tests' 480×360 ORB lap loses 5
/// frames in 2 maps (15 in 4 before). Either way nearly every local BA
/// that runs under that lag is cut short (65 of 69 before, 41 of 42
/// after, SuperPoint + ANMS), and the monocular map's scale drifts
/// (EVALUATION.md, "Monocular maps merged in Sim(3)"). An idle mapper
/// keeps ORB-SLAM3's monocular
/// rule exactly. Stereo and RGB-D keyframes bring their own
/// close points and never interrupt: the BA that aborted for every queued
/// keyframe drifted an RGB-D lap 16× more (EVALUATION.md, "Local mapping
/// that lags").
pub(crate) fn needs_keyframe(
    frame: &Frame,
    map: &Map,
    rig: &CameraRig,
    ctx: &KeyFrameContext,
) -> KeyFrameDecision {
    let n_keyframes = map.keyframe_count();
    if let Some(reloc) = ctx.last_relocalisation_frame {
        // ORB-SLAM3's `NeedNewKeyFrame` inserts none within `mMaxFrames`
        // of a relocalisation. Stereo and RGB-D keyframes bring their own
        // close points, which a camera relocalised at the edge of the old
        // map needs at once (EVALUATION.md, "Relocalising in the old map
        // first after a blackout"); a monocular one keeps the wait.
        let wait = if rig.sensor.has_depth() {
            0
        } else {
            ctx.max_frames
        };
        if frame.index < reloc + wait && n_keyframes > ctx.max_frames {
            return KeyFrameDecision::default();
        }
    }
    // ORB-SLAM3 counts the reference's points seen by 3 keyframes (2 in a
    // map of two). A monocular point is born with 2 observations, so that
    // count leaves out every point of the last keyframe; through a turn
    // the keyframes then come too late (the synthetic block loop lost
    // tracking at its third corner). Monocular counts points seen twice.
    let min_observations = if n_keyframes <= 2 || rig.sensor == Sensor::Monocular {
        2
    } else {
        3
    };
    let reference_matches = map.keyframe(ctx.reference).map_or(0, |kf| {
        kf.observed_points()
            .filter(|(_, p)| {
                map.map_point(*p)
                    .is_ok_and(|p| p.observation_count() >= min_observations)
            })
            .count()
    });
    let mono = rig.sensor == Sensor::Monocular;
    // A monocular camera's close-point condition (spslam's departure, see
    // above) applies only while mapping is busy: an idle mapper keeps
    // ORB-SLAM3's monocular rule exactly.
    let close_condition_applies = !mono || ctx.mapping_queue > 0;
    let (mut tracked_close, mut untracked_close) = (0usize, 0usize);
    for i in (0..frame.len()).filter(|_| close_condition_applies) {
        if counts_as_close(frame, i, rig) {
            if frame.map_points[i].is_some() {
                tracked_close += 1;
            } else {
                untracked_close += 1;
            }
        }
    }
    // ORB-SLAM3's close-point condition, on this frame and (spslam's
    // addition) on the next one as the motion model predicts it; the
    // look-ahead is only computed where it can change the answer.
    let next_tracked_close = ctx
        .velocity
        .filter(|_| tracked_close >= MIN_TRACKED_CLOSE && untracked_close > MIN_UNTRACKED_CLOSE)
        .map(|velocity| tracked_close_in_next_frame(frame, map, rig, &velocity));
    let leaving = next_tracked_close.is_some_and(|n| n < MIN_TRACKED_CLOSE);
    let need_close =
        (tracked_close < MIN_TRACKED_CLOSE || leaving) && untracked_close > MIN_UNTRACKED_CLOSE;
    // ORB-SLAM3: monocular keyframes come when fewer than 90 % of the
    // reference's points are tracked.
    let ref_ratio = if mono {
        0.9
    } else if n_keyframes < 2 {
        0.4
    } else {
        0.75
    };
    let inliers = ctx.inliers as f64;
    let c1a = frame.index >= ctx.last_keyframe_frame + ctx.max_frames;
    let c1b = ctx.mapping_queue == 0;
    let c1c = inliers < reference_matches as f64 * 0.25 || need_close;
    let threshold = reference_matches as f64 * ref_ratio;
    // The near-reference count only lowers the threshold when it is under
    // the reference's count, so the camera's motion is only measured then.
    let threshold = if ctx.near_reference_count < reference_matches
        && near_reference(frame, map, ctx.reference)
    {
        threshold.min(ctx.near_reference_count as f64 * ref_ratio)
    } else {
        threshold
    };
    let c2 = (inliers < threshold || need_close) && ctx.inliers > 15;
    tracing::trace!(
        frame = frame.index,
        inliers = ctx.inliers,
        reference_matches,
        near_reference_count = ctx.near_reference_count,
        tracked_close,
        untracked_close,
        ?next_tracked_close,
        c1a,
        c1b,
        c1c,
        c2,
        "keyframe decision"
    );
    if !c2 {
        return KeyFrameDecision::default();
    }
    // Condition 1b (ORB-SLAM3's `mMinFrames` is 0): an idle mapper takes
    // every keyframe condition 2 asks for. A busy one takes a keyframe on
    // condition 1c (tracking is weak) always, and a stereo or RGB-D one on
    // condition 1a while fewer than three wait. A busy mapper's BA is
    // interrupted for a monocular camera on 1a or 1c, as ORB-SLAM3 does.
    KeyFrameDecision {
        insert: c1b || c1c || (!mono && c1a && ctx.mapping_queue < MAX_MAPPING_QUEUE),
        interrupt_mapping: mono && !c1b && (c1a || c1c),
    }
}

/// The count condition 2 compares with near the reference keyframe
/// ([`KeyFrameContext::near_reference_count`]) after a frame that tracked
/// `inliers` points with it: for a monocular camera the most inliers a
/// frame has tracked with this reference, for stereo and RGB-D the
/// keyframe's own inliers when it was made, not raised by later frames.
///
/// A stereo or RGB-D keyframe makes points of its own close keypoints
/// ([`insert_keyframe`]: 480–770 on the 7-Scenes kitchen with SuperPoint),
/// and the frames just after it, nearly the same image, find many of them
/// again: on the kitchen the count jumps from the keyframe's 240–300 to
/// 350–450 on the next frame, then falls by a quarter within two to four
/// frames while the camera moves under 1 % of its scene depth, as the
/// points SuperPoint does not detect again drop out. Against that spike the
/// rule made a keyframe every three to five frames (56 of 300). A
/// monocular keyframe makes no points (local mapping triangulates them
/// later), so its count rises as they come and the peak follows it: held
/// at the keyframe's own count, the monocular kitchen made fewer keyframes,
/// lost 23 more frames and started a second map.
pub(crate) fn next_near_reference_count(count: usize, inliers: usize, sensor: Sensor) -> usize {
    if sensor == Sensor::Monocular {
        count.max(inliers)
    } else {
        count
    }
}

/// The camera is near its reference keyframe while it has moved less
/// than this fraction of the reference's median scene depth…
const NEAR_BASELINE_RATIO: f64 = 0.04;
/// …and turned less than this many degrees.
const NEAR_ROTATION_DEG: f64 = 5.0;

/// Whether the camera is still near its reference keyframe: its baseline
/// from the reference over the reference's median scene depth (ORB-SLAM3's
/// `ComputeSceneMedianDepth`) is under [`NEAR_BASELINE_RATIO`] and its
/// rotation under [`NEAR_ROTATION_DEG`].
fn near_reference(frame: &Frame, map: &Map, reference: KeyFrameId) -> bool {
    let (Ok(kf), Ok(pose)) = (map.keyframe(reference), map.pose_cw_of(reference)) else {
        return false;
    };
    let mut depths: Vec<f64> = kf
        .observed_points()
        .filter_map(|(_, p)| map.map_point(p).ok())
        .map(|p| pose.transform_point(&p.position).z)
        .filter(|z| *z > 0.0)
        .collect();
    if depths.is_empty() {
        return false;
    }
    let middle = depths.len() / 2;
    let median_depth = *depths.select_nth_unstable_by(middle, f64::total_cmp).1;
    let relative = frame.pose_cw.compose(&pose.inverse());
    let baseline_ratio = relative.translation.norm() / median_depth;
    let rotation_deg = relative.rotation.angle().to_degrees();
    tracing::trace!(
        frame = frame.index,
        baseline_ratio,
        rotation_deg,
        "motion since the reference"
    );
    baseline_ratio < NEAR_BASELINE_RATIO && rotation_deg < NEAR_ROTATION_DEG
}

/// Whether keypoint `i` counts in ORB-SLAM3's close-point condition: a
/// stereo or RGB-D keypoint with a depth under `ThDepth`, and (spslam's
/// departure, applied while mapping is busy, see [`needs_keyframe`])
/// every monocular keypoint.
fn counts_as_close(frame: &Frame, i: usize, rig: &CameraRig) -> bool {
    rig.sensor == Sensor::Monocular || frame.depth(i).is_some_and(|d| d < rig.close_depth)
}

/// ORB-SLAM3's `bNeedToInsertClose`: a keyframe is needed when fewer than
/// this many close points are tracked…
const MIN_TRACKED_CLOSE: usize = 100;
/// …and more than this many close keypoints could become new points.
const MIN_UNTRACKED_CLOSE: usize = 70;

/// The frame's tracked close points that stay in view in the next frame
/// if the camera keeps its `velocity` (the motion model's prediction).
fn tracked_close_in_next_frame(frame: &Frame, map: &Map, rig: &CameraRig, velocity: &Se3) -> usize {
    let next = velocity.compose(&frame.pose_cw);
    (0..frame.len())
        .filter(|&i| counts_as_close(frame, i, rig))
        .filter_map(|i| frame.map_points[i].and_then(|p| map.resolve_point(p)))
        .filter_map(|id| map.map_point(id).ok())
        .filter(|p| {
            rig.project_in_image(&next.transform_point(&p.position))
                .is_some()
        })
        .count()
}

/// ORB-SLAM3's `CreateNewKeyFrame` for stereo: the frame becomes a
/// keyframe observing its matched points, and its close stereo keypoints
/// without a point get one (nearest first; at least 100 points in all).
/// Returns the keyframe and the points it created.
pub(crate) fn insert_keyframe(
    frame: &mut Frame,
    map: &mut Map,
    rig: &CameraRig,
) -> Result<(KeyFrameId, Vec<MapPointId>), SlamError> {
    let keyframe = map
        .add_keyframe(
            frame.index,
            frame.timestamp,
            frame.pose_cw,
            frame.measurements(),
        )
        .in_stage("new keyframe")?;
    for i in 0..frame.len() {
        let Some(point) = frame.map_points[i].and_then(|p| map.resolve_point(p)) else {
            frame.map_points[i] = None;
            continue;
        };
        if map
            .map_point(point)
            .is_ok_and(|p| p.observations().contains_key(&keyframe))
        {
            // Two keypoints matched to one point: keep the first.
            frame.map_points[i] = None;
            continue;
        }
        map.add_observation(point, keyframe, i)
            .in_stage("new keyframe")?;
        frame.map_points[i] = Some(point);
    }
    let mut by_depth: Vec<(f64, usize)> = (0..frame.len())
        .filter_map(|i| frame.depth(i).map(|d| (d, i)))
        .collect();
    by_depth.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut created = Vec::new();
    let mut counted = 0usize;
    for (depth, i) in by_depth {
        if frame.map_points[i].is_none() {
            if let Some(id) = point_from_stereo(map, keyframe, frame, i, rig)? {
                frame.map_points[i] = Some(id);
                created.push(id);
            }
        }
        counted += 1;
        if depth > rig.close_depth && counted > 100 {
            break;
        }
    }
    map.update_connections(keyframe);
    frame.reference_keyframe = Some(keyframe);
    Ok((keyframe, created))
}
