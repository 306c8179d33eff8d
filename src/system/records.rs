//! What the system reports per frame, per map and for a whole run.

use nalgebra::UnitQuaternion;
use serde::Serialize;

use crate::map::{KeyFrameId, Map};
use crate::mapping::MappingSummary;
use crate::optim::{LieGroup, Se3};
use crate::tracking::{TrackingMethod, TrackingState};

use super::atlas::MapIndex;
use super::second_look::SecondLookOutcome;

/// Milliseconds per stage for one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct FrameTimings {
    /// Left and right extraction (in parallel), wall clock.
    pub extraction_ms: f64,
    /// Stereo matching.
    pub stereo_ms: f64,
    /// Tracking (all of it, keyframe insertion included).
    pub tracking_ms: f64,
    /// The part of `tracking_ms` spent waiting for the map's locks (held
    /// by local mapping or loop detection meanwhile).
    pub lock_wait_ms: f64,
    /// Local mapping (0 on frames without a new keyframe, and with local
    /// mapping on its thread, where it is reported under its keyframe's frame).
    pub mapping_ms: f64,
}

/// A tracked frame's pose, relative to a keyframe of one map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RelativePose {
    /// The atlas map it was tracked in.
    pub map: MapIndex,
    /// Its reference keyframe in that map.
    pub keyframe: KeyFrameId,
    /// `T_c,ref`.
    pub pose: Se3,
}

impl RelativePose {
    /// `T_map,c`: the camera's pose in its map now, through the reference
    /// keyframe's current pose (or, when it was culled, the keyframe that
    /// replaced it); `None` when `map` no longer reaches the keyframe. The
    /// one place a record becomes a pose in its map, for the trajectory's
    /// anchoring and a merge's handover.
    pub fn camera_in_map(&self, map: &Map) -> Option<Se3> {
        let keyframe_pose_cw = map.pose_cw_of(self.keyframe).ok()?;
        Some(self.pose.compose(&keyframe_pose_cw).inverse())
    }
}

/// What happened to one input frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameRecord {
    /// Index in the input sequence.
    pub index: usize,
    /// Timestamp, seconds.
    pub timestamp: f64,
    /// The atlas map that was active for it.
    pub map: MapIndex,
    /// Tracking state after the frame.
    pub state: TrackingState,
    /// How its pose was found.
    pub method: TrackingMethod,
    /// Map points matched as inliers.
    pub inliers: usize,
    /// Stereo keypoints.
    pub stereo_points: usize,
    /// Whether it became a keyframe.
    pub keyframe: bool,
    /// Why the frame could not be read, when it could not (it is then
    /// counted as lost and skipped).
    pub unreadable: Option<String>,
    /// The pose when tracked.
    #[serde(skip)]
    pub relative_pose: Option<RelativePose>,
    /// For a frame tracking gave no pose, or the first of a new map: the
    /// rotation `R_cp` from the previous input frame, measured from the
    /// two frames' thumbnails (the trajectory's rows over a gap turn by it).
    #[serde(skip)]
    pub gap_rotation: Option<UnitQuaternion<f64>>,
    /// That rotation's angle, degrees.
    pub gap_rotation_deg: Option<f64>,
    /// For a frame tracking gave no pose, or the first of a new map: its
    /// motion `T_c,p` from the previous input frame, measured by stereo
    /// odometry (the trajectory's rows over a gap follow it; it replaces
    /// `gap_rotation` there).
    #[serde(skip)]
    pub gap_step: Option<Se3>,
    /// That step's refined inliers.
    pub gap_step_inliers: Option<usize>,
    /// Time per stage.
    pub timings: FrameTimings,
    /// Local mapping's summary when it ran.
    pub mapping: Option<MappingSummary>,
    /// Whether the loop-closing thread was checking a keyframe (retrieval
    /// and candidate verification) when this frame's tracking started or
    /// ended: the frames whose tracking time shows what loop detection
    /// costs tracking (`tools/tracking_latency.py`).
    pub loop_check_running: bool,
    /// Whether the frame, lost on its first try, was extracted again on
    /// the second look's pyramid, and what that gave (`None`: no second
    /// look). Its timings include the second look's extraction.
    pub second_look: Option<SecondLookOutcome>,
}

/// One atlas map in a run's summary.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct MapSummary {
    /// Its index in the atlas.
    pub index: MapIndex,
    /// First input frame processed in it.
    pub first_frame: usize,
    /// Input frames processed while it was active (after a merge, the
    /// absorbed map's frames count for the map it was merged into).
    pub frames: usize,
    /// Frames tracked in it.
    pub tracked: usize,
    /// Live keyframes.
    pub keyframes: usize,
    /// Live map points.
    pub map_points: usize,
    /// For maps after the first: the input frame whose pose (the last one
    /// tracked before the map began) anchors the map's first pose in the
    /// trajectory, which is in the first map's frame: the map's first
    /// tracked frame sits where that frame's pose, carried on at its
    /// velocity over the gap, puts it (for at most
    /// [`crate::system::GAP_HORIZON_S`]).
    pub anchored_at_frame: Option<usize>,
    /// The map it was merged into, if loop closing merged it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub merged_into: Option<MapIndex>,
}

/// Totals over the frames processed so far.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SlamSummary {
    /// Frames processed.
    pub frames: usize,
    /// Frames with a tracked pose (initialisation included).
    pub tracked: usize,
    /// Frames processed while lost (tracking failures and unreadable frames).
    pub lost: usize,
    /// Of `lost`: frames that could not be read.
    pub unreadable: usize,
    /// Frames before initialisation (of the first map, or of a new map).
    pub not_initialised: usize,
    /// Relocalisations.
    pub relocalisations: usize,
    /// Of `tracked`: monocular frames between a two-view initialisation's
    /// views, localised once the map existed.
    pub between_initial_views: usize,
    /// Of `tracked`: frames lost when they came, localised once tracking
    /// resumed (in a new map, or after a relocalisation).
    pub localised_after_loss: usize,
    /// Of `tracked`: frames lost by tracking's rule whose pose a second
    /// start corroborated (tracking itself stayed lost).
    pub corroborated: usize,
    /// Of `tracked`: frames lost by tracking whose motion from the last
    /// tracked frame odometry measured, step by step (tracking itself
    /// stayed lost).
    pub by_odometry: usize,
    /// The second look's pyramid levels (`None`: lost frames get none).
    pub second_look_levels: Option<usize>,
    /// Frames given a second look (extracted again on a deeper pyramid
    /// after their first try was lost).
    pub second_looks: usize,
    /// Those tracked on the second look's features.
    pub tracked_on_second_look: usize,
    /// Keyframes inserted.
    pub keyframes_inserted: usize,
    /// Live keyframes in all maps.
    pub keyframes: usize,
    /// Live map points in all maps.
    pub map_points: usize,
    /// The atlas maps, oldest first.
    pub maps: Vec<MapSummary>,
    /// Mean time per stage, ms.
    pub mean_timings: FrameTimings,
}
