//! The tracking state machine: initialise, track (motion model, reference
//! keyframe, relocalisation), track the local map, decide on keyframes.

use std::sync::Arc;
use std::time::Instant;

use crate::map::{KeyFrameId, Map, MapPointId, SharedMap};
use crate::optim::{LieGroup, Se3};

use super::after_loss::{localise_lost_frames, lost_frames_kept, Resumption};
use super::between_views::{localise_between_views, InitialView};
use super::corroborate::{corroborated, StartPose};
use super::frame::Frame;
use super::gap_odometry::{measure_step, OdometryStep};
use super::keyframe::{
    initialise_map, insert_keyframe, needs_keyframe, next_near_reference_count, KeyFrameContext,
    KeyFrameDecision,
};
use super::late::LateLocalisation;
use super::local_map::{track_local_map, PointCounting};
pub use super::method::{TrackingMethod, TrackingState};
use super::mono_init::MonoInitialiser;
use super::motion::{
    image_rotation_velocity, track_last_frame, track_last_frame_unratioed,
    track_reference_keyframe, track_with_motion_model, MotionModelFit, MIN_POSE_INLIERS,
};
use super::relocalise::{relocalise_with, RelocalisationCandidates, MIN_RELOCALISATION_INLIERS};
use super::step_limit::{PredictionLimit, StepLimit};
use crate::camera::{CameraRig, Sensor};
use crate::error::{MapContext, SlamError};

/// The result of tracking one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackOutcome {
    /// The state after this frame.
    pub state: TrackingState,
    /// How the pose was found.
    pub method: TrackingMethod,
    /// Map points matched as inliers.
    pub inliers: usize,
    /// The keyframe made from this frame, with the points it created.
    pub new_keyframe: Option<(KeyFrameId, Vec<MapPointId>)>,
    /// The frame's pose relative to its reference keyframe (`T_c,ref`), when tracked.
    pub relative_pose: Option<(KeyFrameId, Se3)>,
    /// A monocular initialisation also made a keyframe of an earlier frame
    /// (its index): that frame now has a pose.
    pub earlier_keyframe: Option<(usize, KeyFrameId)>,
    /// The frames between a monocular initialisation's two views that
    /// were localised in the new map (see [`super::between_views`]).
    pub between_views: Vec<LateLocalisation>,
    /// The frames lost before this one that were localised once tracking
    /// resumed with it (see [`super::after_loss`]).
    pub after_loss: Vec<LateLocalisation>,
    /// For a frame tracking gave no pose, and the first frame of a new map:
    /// its motion from the input frame before it, measured by stereo
    /// odometry when the two frames' depths allow (see
    /// [`super::gap_odometry`]).
    pub gap_step: Option<OdometryStep>,
    /// A monocular keyframe was wanted while local mapping was busy: the
    /// caller interrupts mapping's local BA (ORB-SLAM3's `InterruptBA`), so
    /// its triangulation is done sooner (see the keyframe rule).
    pub interrupt_mapping: bool,
}

impl TrackOutcome {
    /// The state the frame's record gives: the tracker's state, except
    /// that a lost frame whose pose a second start corroborated
    /// ([`TrackingMethod::Corroborated`]) has a pose, so its record is Ok
    /// while tracking itself stays lost.
    pub fn record_state(&self) -> TrackingState {
        if self.method == TrackingMethod::Corroborated {
            TrackingState::Ok
        } else {
            self.state
        }
    }
}

/// Tracks frames against a map.
///
/// A clone is a snapshot of the tracking state (the last frame, the
/// motion, the current loss): a try at a frame that ends lost writes
/// nothing to the map but the points' visible and found counts (which
/// [`Self::set_point_counting`] turns off), so restoring the snapshot
/// undoes the try (the system's second look at a lost frame does).
#[derive(Debug, Clone)]
pub struct Tracker {
    rig: CameraRig,
    state: TrackingState,
    last_frame: Option<Frame>,
    /// The last frame's pose relative to its reference keyframe, to follow BA updates.
    last_relative: Option<(KeyFrameId, Se3)>,
    velocity: Option<Se3>,
    reference: Option<KeyFrameId>,
    /// The count condition 2 compares with near the reference keyframe
    /// (its own inliers when it was inserted; see [`next_near_reference_count`]).
    near_reference_count: Option<(KeyFrameId, usize)>,
    last_keyframe_frame: usize,
    last_relocalisation_frame: Option<usize>,
    /// Index of the first frame of the current loss.
    lost_since: Option<usize>,
    /// Whether the map the current loss happened in was young (see
    /// [`YOUNG_MAP_KEYFRAMES`]).
    lost_in_young_map: bool,
    /// Whether relocalisation was tried during the current loss on a frame
    /// with keypoints enough to succeed (see [`Self::should_start_new_map`]).
    relocalisation_tried: bool,
    max_frames: usize,
    /// Where relocalisation's keyframes come from; `None`: the newest ones.
    relocalisation_candidates: Option<Arc<dyn RelocalisationCandidates>>,
    /// Localisation only: no keyframe is inserted, no new map started.
    localisation_only: bool,
    /// The monocular initialiser's reference frame (monocular only).
    mono_init: MonoInitialiser,
    /// The newest frames of the current loss (and of a new map's wait for
    /// its first frame), oldest first: localised once tracking resumes
    /// (see [`super::after_loss`]).
    lost_frames: Vec<Frame>,
    /// Milliseconds the last `track` waited for the map's locks.
    lock_wait_ms: f64,
    /// The camera's motion per frame over the current gap (`T_c,p`): the
    /// velocity when it began, then each measured step; what the next
    /// gap frame's odometry predicts from.
    gap_velocity: Option<Se3>,
    /// Whether local-map tracking counts the points it sees and finds
    /// (`visible`, `found`); off for a frame's second try, whose first
    /// already counted (see [`Self::set_point_counting`]).
    counts_points: bool,
}

/// `frame`'s pose relative to `reference` (`T_c,ref`); `None` without one.
fn relative_to(
    frame: &Frame,
    reference: Option<KeyFrameId>,
    map: &Map,
) -> Result<Option<(KeyFrameId, Se3)>, SlamError> {
    let Some(reference) = reference else {
        return Ok(None);
    };
    let kf_pose = map.pose_cw_of(reference).in_stage("relative pose")?;
    Ok(Some((reference, frame.pose_cw.compose(&kf_pose.inverse()))))
}

/// A motion-model pose, refined with at least 10 inliers, that failed the
/// rule that a quarter of its matches be inliers
/// ([`MotionModelFit::is_accepted`](super::motion::MotionModelFit::is_accepted)):
/// where every other start fails, local-map tracking tries it last, and
/// its 30 inliers decide, as for any start. On a dim lap's corner
/// (`spslam synth --condition low-light`, RGB-D) the motion model kept 27
/// of 149 matches where the reference keyframe and the last frame gave
/// 15 and 0 local-map inliers.
#[derive(Debug, Clone)]
struct RejectedPrediction {
    pose_cw: Se3,
    map_points: Vec<Option<MapPointId>>,
    /// Its inliers after refinement.
    inliers: usize,
    /// Whether its rotation came from the images.
    from_images: bool,
}

/// A local-map tracking result against the inliers its start needs:
/// one that has them beats one that has not, then more inliers win.
#[derive(Debug, Clone, Copy)]
struct LocalMapScore {
    inliers: usize,
    needed: usize,
}

impl LocalMapScore {
    fn new(inliers: usize, needed: usize) -> Self {
        Self { inliers, needed }
    }

    fn key(&self) -> (bool, usize) {
        (self.inliers >= self.needed, self.inliers)
    }

    /// Whether this result is the better one.
    fn beats(&self, other: &Self) -> bool {
        self.key() > other.key()
    }
}

/// Where frame-to-frame tracking starts again when its first start left
/// too few local-map inliers.
#[derive(Debug, Clone)]
enum Start {
    /// Descriptor matching against the reference keyframe.
    ReferenceKeyFrame,
    /// Descriptor matching against the last frame.
    LastFrame,
    /// The motion model with the rotation measured from the images.
    ImageRotation,
    /// The motion model's rejected pose and matches.
    RejectedPrediction(RejectedPrediction),
    /// Mutual nearest neighbours against the last frame, no ratio test.
    MutualNearestNeighbours,
}

impl Start {
    /// The method reported when this start wins.
    fn method(&self) -> TrackingMethod {
        match self {
            Start::ReferenceKeyFrame => TrackingMethod::ReferenceKeyFrame,
            Start::LastFrame => TrackingMethod::LastFrame,
            Start::ImageRotation => TrackingMethod::ImageRotation,
            Start::RejectedPrediction(start) if start.from_images => TrackingMethod::ImageRotation,
            Start::RejectedPrediction(_) => TrackingMethod::MotionModel,
            Start::MutualNearestNeighbours => TrackingMethod::MutualNearestNeighbours,
        }
    }
}

/// Seconds of failed relocalisation after which tracking gives the map up
/// and starts a new one from the next frame that can initialise. ORB-SLAM3
/// waits 3 s in `RECENTLY_LOST` (stereo, no IMU), then resets a map of
/// fewer than 10 keyframes or creates a new one in the atlas. spslam never
/// resets: every map is kept (its frames stay in the trajectory), and it
/// gives up sooner, because a vehicle at 10 m/s is 30 m away after 3 s and
/// the old map can no longer be seen. A later loop closure can merge maps.
pub const RELOCALISATION_PATIENCE_S: f64 = 0.5;
/// The patience in frames, at least.
const MIN_PATIENCE_FRAMES: usize = 3;
/// A map with at most this many keyframes is young: a loss in it gets one
/// frame's patience. ORB-SLAM3's `Tracking::Track` waits in `RECENTLY_LOST`
/// only when the map holds more than 10 keyframes
/// (`pCurrentMap->KeyFramesInMap()>10`); a younger map goes straight to
/// `LOST`, and the next frame resets it and starts over. A young map
/// started on a blurred or dark frame holds few points, which the sharp
/// frames after it rarely find again: the patience would only lose them.
pub const YOUNG_MAP_KEYFRAMES: usize = 10;
/// The patience in frames after a loss in a young map: the next frame
/// tries the map once, then starts the new map itself.
const YOUNG_MAP_PATIENCE_FRAMES: usize = 1;

/// Inliers local-map tracking needs (ORB-SLAM3: 30, 50 just after relocalisation).
const MIN_LOCAL_MAP_INLIERS: usize = 30;

impl Tracker {
    /// A tracker for `rig`, not yet initialised.
    pub fn new(rig: CameraRig) -> Self {
        Self {
            rig,
            state: TrackingState::NotInitialised,
            last_frame: None,
            last_relative: None,
            velocity: None,
            reference: None,
            near_reference_count: None,
            last_keyframe_frame: 0,
            last_relocalisation_frame: None,
            lost_since: None,
            lost_in_young_map: false,
            relocalisation_tried: false,
            max_frames: rig.fps.round().max(1.0) as usize,
            relocalisation_candidates: None,
            localisation_only: false,
            lock_wait_ms: 0.0,
            mono_init: MonoInitialiser::default(),
            lost_frames: Vec::new(),
            gap_velocity: None,
            counts_points: true,
        }
    }

    /// Whether local-map tracking raises the map points' `visible` and
    /// `found` counts (on by default). The only write a try that ends
    /// lost makes to the map; a second try at the same frame turns it off,
    /// so that a frame counts once and a second try that fails leaves the
    /// map as the first left it.
    pub fn set_point_counting(&mut self, on: bool) {
        self.counts_points = on;
    }

    /// Localisation only (ORB-SLAM3's localization mode): tracking never
    /// inserts a keyframe or starts a new map; the map is only read.
    pub fn set_localisation_only(&mut self, on: bool) {
        self.localisation_only = on;
    }

    /// Whether tracking only localises (see [`Self::set_localisation_only`]).
    pub fn localisation_only(&self) -> bool {
        self.localisation_only
    }

    /// Starts lost in a map that already holds keyframes (a loaded map):
    /// the next frame relocalises against it instead of initialising.
    pub fn start_lost(&mut self) {
        let keep = self.fresh();
        *self = keep;
        self.state = TrackingState::Lost;
    }

    /// A new, uninitialised tracker for the same rig that keeps this one's
    /// relocalisation candidate source (a reset, a new map).
    pub fn fresh(&self) -> Self {
        let mut tracker = Self::new(self.rig);
        tracker.relocalisation_candidates = self.relocalisation_candidates.clone();
        tracker.localisation_only = self.localisation_only;
        tracker
    }

    /// A fresh tracker (see [`Self::fresh`]) for the new map started after
    /// a loss: it keeps the frames of the loss, which the new map's first
    /// keyframe localises (see [`super::after_loss`]).
    pub fn fresh_after_loss(&mut self) -> Self {
        let mut tracker = self.fresh();
        tracker.lost_frames = std::mem::take(&mut self.lost_frames);
        tracker.gap_velocity = self.gap_velocity;
        tracker
    }

    /// Keeps a frame that could not be tracked, dropping the oldest kept
    /// beyond [`lost_frames_kept`].
    fn keep_lost(&mut self, frame: Frame) {
        self.lost_frames.push(frame);
        let excess = self
            .lost_frames
            .len()
            .saturating_sub(lost_frames_kept(self.rig.fps));
        self.lost_frames.drain(..excess);
    }

    /// Localises the kept lost frames now that tracking resumed at
    /// `resumed`; the map is only read.
    fn localise_lost(
        &mut self,
        resumed: Resumption,
        map: &Map,
    ) -> Result<Vec<LateLocalisation>, SlamError> {
        let frames = std::mem::take(&mut self.lost_frames);
        if frames.is_empty() {
            return Ok(Vec::new());
        }
        localise_lost_frames(frames, resumed, map, &self.rig, MIN_LOCAL_MAP_INLIERS)
    }

    /// Where relocalisation gets the keyframes it tries: `Some(source)`
    /// asks it (best first, e.g. the loop-closing keyframe database);
    /// `None` (the default) tries the newest
    /// [`MAX_SCANNED_KEYFRAMES`](super::relocalise::MAX_SCANNED_KEYFRAMES)
    /// keyframes.
    pub fn set_relocalisation_candidates(
        &mut self,
        source: Option<Arc<dyn RelocalisationCandidates>>,
    ) {
        self.relocalisation_candidates = source;
    }

    /// Whether relocalisation asks a candidate source (see
    /// [`Self::set_relocalisation_candidates`]).
    pub fn has_relocalisation_candidates(&self) -> bool {
        self.relocalisation_candidates.is_some()
    }

    /// The current state.
    pub fn state(&self) -> TrackingState {
        self.state
    }

    /// The rig.
    pub fn rig(&self) -> &CameraRig {
        &self.rig
    }

    /// Tracks one frame, inserting a keyframe when needed. `mapping_queue`
    /// is how many keyframes local mapping has not finished (0: idle).
    ///
    /// Locking (see [`crate::map`]): everything but initialisation and
    /// keyframe insertion runs under the map's read lock, so local mapping's
    /// readers (snapshots) run alongside; the write lock is taken only to
    /// initialise the map or insert a keyframe, and released before return.
    pub fn track(
        &mut self,
        frame: Frame,
        map: &SharedMap,
        mapping_queue: usize,
    ) -> Result<TrackOutcome, SlamError> {
        self.lock_wait_ms = 0.0;
        let index = frame.index;
        if self.state == TrackingState::Ok {
            self.gap_velocity = self.velocity;
        }
        let mut outcome = if self.state == TrackingState::NotInitialised {
            let mut map = self.timed(|| map.write())?;
            self.initialise(frame, &mut map)?
        } else {
            self.track_in_map(frame, map, mapping_queue)?
        };
        if outcome.relative_pose.is_none() {
            // A frame without a pose is the newest kept lost frame (a
            // monocular initialiser keeps its own, which have no depth).
            let current = self.lost_frames.iter().rev().find(|f| f.index == index);
            outcome.gap_step = match current {
                Some(current) => self.measure_gap_step(current)?,
                None => None,
            };
            if let Some(step) = outcome.gap_step {
                self.gap_velocity = Some(step.pose_cp);
            }
        }
        Ok(outcome)
    }

    /// The motion of `current` from the input frame before it (the last
    /// tracked frame or the newest kept lost one), by stereo odometry;
    /// `None` for a monocular camera or without that frame.
    fn measure_gap_step(&self, current: &Frame) -> Result<Option<OdometryStep>, SlamError> {
        if self.rig.sensor == Sensor::Monocular || current.index == 0 {
            return Ok(None);
        }
        let wanted = current.index - 1;
        let previous = self
            .lost_frames
            .iter()
            .rev()
            .chain(self.last_frame.as_ref())
            .find(|f| f.index == wanted);
        let Some(previous) = previous else {
            return Ok(None);
        };
        let velocity = self.gap_velocity.as_ref();
        let prediction = image_rotation_velocity(current, previous, velocity).or(self.gap_velocity);
        measure_step(previous, current, &self.rig, prediction.as_ref())
    }

    /// [`Self::track`] once the map exists.
    fn track_in_map(
        &mut self,
        frame: Frame,
        map: &SharedMap,
        mapping_queue: usize,
    ) -> Result<TrackOutcome, SlamError> {
        let (frame, mut outcome, wants_keyframe) = {
            let map = self.timed(|| map.read())?;
            self.track_under_read_lock(frame, &map, mapping_queue)?
        };
        let Some(mut frame) = frame else {
            return Ok(outcome);
        };
        outcome.interrupt_mapping = wants_keyframe.interrupt_mapping && !self.localisation_only;
        if wants_keyframe.insert && !self.localisation_only {
            let mut map = self.timed(|| map.write())?;
            let (kf, created) = insert_keyframe(&mut frame, &mut map, &self.rig)?;
            self.reference = Some(kf);
            self.near_reference_count = Some((kf, outcome.inliers));
            self.last_keyframe_frame = frame.index;
            outcome.new_keyframe = Some((kf, created));
            outcome.relative_pose = Some((kf, Se3::identity()));
        }
        self.keep_last(frame, outcome.relative_pose);
        Ok(outcome)
    }

    /// Takes a map lock, adding the wait to [`Self::last_lock_wait_ms`].
    fn timed<G, E>(&mut self, lock: impl FnOnce() -> Result<G, E>) -> Result<G, SlamError> {
        let start = Instant::now();
        let guard = lock().map_err(|_| SlamError::PoisonedMap);
        self.lock_wait_ms += start.elapsed().as_secs_f64() * 1e3;
        guard
    }

    /// How long the last [`Self::track`] waited for the map's locks, in
    /// milliseconds (local mapping or loop detection held them).
    pub fn last_lock_wait_ms(&self) -> f64 {
        self.lock_wait_ms
    }

    /// Tracks `frame` against `map` (read only) and decides on a keyframe.
    /// Returns the frame when it was tracked (the caller inserts the
    /// keyframe, then keeps it as the last frame), the outcome, and whether
    /// a keyframe is wanted.
    fn track_under_read_lock(
        &mut self,
        mut frame: Frame,
        map: &Map,
        mapping_queue: usize,
    ) -> Result<(Option<Frame>, TrackOutcome, KeyFrameDecision), SlamError> {
        // The last frame follows its reference keyframe (moved by BA, or culled).
        if let (Some(last), Some((kf, rel))) = (self.last_frame.as_mut(), self.last_relative) {
            if let Ok(kf_pose) = map.pose_cw_of(kf) {
                last.pose_cw = rel.compose(&kf_pose);
            }
        }
        if let Some(reference) = self.reference {
            if map.keyframe(reference).is_err() {
                self.reference = map.keyframes().last().map(|k| k.id());
            }
        }
        let recently_relocalised = self
            .last_relocalisation_frame
            .is_some_and(|r| frame.index < r + self.max_frames);
        let (mut method, doubtful, rejected) = if self.state == TrackingState::Ok {
            self.track_frame_to_frame(&mut frame, map)?
        } else if self.relocalise(&mut frame, map)? {
            self.last_relocalisation_frame = Some(frame.index);
            (TrackingMethod::Relocalisation, false, None)
        } else {
            (TrackingMethod::None, false, None)
        };
        let mut inliers = 0;
        let mut corroborated_pose = None;
        if method != TrackingMethod::None {
            // A pose found away from the motion model's prediction (by a
            // relocalisation, or around the rotation the images show) needs
            // the inliers of a relocalisation, as do the frames just after
            // one: ORB-SLAM3's 50 in `TrackLocalMap`.
            let needed_for = |method: TrackingMethod| {
                let recovered = matches!(
                    method,
                    TrackingMethod::Relocalisation | TrackingMethod::ImageRotation
                );
                if recently_relocalised || recovered {
                    MIN_RELOCALISATION_INLIERS
                } else {
                    MIN_LOCAL_MAP_INLIERS
                }
            };
            inliers = self.track_local_map_logged(&mut frame, map, recently_relocalised)?;
            if method == TrackingMethod::ImageRotation && self.is_prediction_jump(&frame, map) {
                inliers = 0;
            }
            // Every start's pose, for a lost frame's corroboration: the
            // first one's is kept once another start is tried (a frame
            // tracked by its first start allocates nothing).
            let mut starts = Vec::new();
            // Another start, scored against the current pose by the inliers
            // each start needs.
            let this = &*self;
            let mut try_start = |frame: &mut Frame, alternative: &Start, method, inliers| {
                let jump_limit = (method == TrackingMethod::MotionModel
                    && inliers >= needed_for(method))
                .then(|| StepLimit::around(frame, inliers, this.velocity.as_ref()))
                .flatten();
                if starts.is_empty() {
                    starts.push(StartPose {
                        method,
                        pose_cw: frame.pose_cw,
                        inliers,
                    });
                }
                let current = LocalMapScore::new(inliers, needed_for(method));
                let needed = needed_for(alternative.method());
                this.try_instead(
                    frame,
                    map,
                    alternative,
                    (current, needed, jump_limit),
                    recently_relocalised,
                    &mut starts,
                )
            };
            if method == TrackingMethod::MotionModel && (inliers < needed_for(method) || doubtful) {
                // The prediction passed its own test but led the local map
                // astray, or kept fewer than half its matches (a turn
                // starting or ending): try the reference keyframe too and
                // keep the pose with more local-map inliers.
                let alternative = Start::ReferenceKeyFrame;
                if let Some(better) = try_start(&mut frame, &alternative, method, inliers)? {
                    (method, inliers) = (alternative.method(), better);
                }
            }
            if inliers < needed_for(method) && method != TrackingMethod::Relocalisation {
                // Tracking would be lost: try the last frame's points, the
                // view closest to this one, then the motion model's search
                // around the images' rotation, then the motion model's pose
                // that failed its quarter rule, and then the last frame's
                // points without the ratio test, before giving up.
                let mut alternatives = vec![Start::LastFrame, Start::ImageRotation];
                alternatives.extend(rejected.map(Start::RejectedPrediction));
                alternatives.push(Start::MutualNearestNeighbours);
                for alternative in alternatives {
                    if inliers >= needed_for(method) || method == alternative.method() {
                        continue;
                    }
                    if let Some(better) = try_start(&mut frame, &alternative, method, inliers)? {
                        (method, inliers) = (alternative.method(), better);
                    }
                }
            }
            let needed = needed_for(method);
            if inliers < needed {
                tracing::debug!(frame = frame.index, inliers, "local map tracking failed");
            }
            self.state = if inliers >= needed {
                TrackingState::Ok
            } else {
                TrackingState::Lost
            };
            if self.state == TrackingState::Lost
                && corroborated(
                    &frame,
                    (method, inliers),
                    MIN_LOCAL_MAP_INLIERS,
                    &starts,
                    map,
                    &self.rig,
                )
            {
                corroborated_pose = relative_to(&frame, frame.reference_keyframe, map)?;
            }
        } else {
            self.state = TrackingState::Lost;
        }
        if self.state != TrackingState::Ok {
            self.velocity = None;
            if self.lost_since.is_none() {
                self.lost_since = Some(frame.index);
                self.lost_in_young_map = map.keyframe_count() <= YOUNG_MAP_KEYFRAMES;
                self.relocalisation_tried = false;
            }
            let outcome = TrackOutcome {
                state: self.state,
                method: if corroborated_pose.is_some() {
                    TrackingMethod::Corroborated
                } else {
                    TrackingMethod::None
                },
                inliers,
                new_keyframe: None,
                relative_pose: corroborated_pose,
                earlier_keyframe: None,
                between_views: Vec::new(),
                after_loss: Vec::new(),
                gap_step: None,
                interrupt_mapping: false,
            };
            if corroborated_pose.is_none() {
                self.keep_lost(frame);
            }
            return Ok((None, outcome, KeyFrameDecision::default()));
        }
        self.lost_since = None;
        if let Some(reference) = frame.reference_keyframe {
            self.reference = Some(reference);
        }
        // After a relocalisation the last tracked frame lies before the
        // loss, so a velocity would span every frame lost: the next frame
        // tracks the reference keyframe instead, as in ORB-SLAM3's `Track`
        // (`mCurrentFrame.mnId < mnLastRelocFrameId + 2`).
        self.velocity = if method == TrackingMethod::Relocalisation {
            None
        } else {
            self.last_frame
                .as_ref()
                .map(|last| frame.pose_cw.compose(&last.pose_cw.inverse()))
        };
        // What condition 2 compares with near the reference: the
        // keyframe's own inliers when tracking made it, else (a reference
        // chosen by the local map or a relocalisation) the last frame's;
        // `next_near_reference_count` raises it for a monocular camera.
        let (wants_keyframe, near_reference_count) = match self.reference {
            None => (KeyFrameDecision::default(), None),
            Some(reference) => {
                let count = match self.near_reference_count {
                    Some((kf, count)) if kf == reference => count,
                    _ => self
                        .last_frame
                        .as_ref()
                        .map_or(inliers, |last| last.tracked_count()),
                };
                let ctx = KeyFrameContext {
                    reference,
                    near_reference_count: count,
                    last_keyframe_frame: self.last_keyframe_frame,
                    last_relocalisation_frame: self.last_relocalisation_frame,
                    inliers,
                    max_frames: self.max_frames,
                    mapping_queue,
                    velocity: self.velocity,
                };
                let decision = needs_keyframe(&frame, map, &self.rig, &ctx);
                let count = next_near_reference_count(count, inliers, self.rig.sensor);
                (decision, Some((reference, count)))
            }
        };
        self.near_reference_count = near_reference_count;
        let relative_pose = self.relative_to_reference(&frame, map)?;
        let after_loss = match frame.reference_keyframe {
            Some(keyframe) if method == TrackingMethod::Relocalisation => {
                let resumed = Resumption {
                    keyframe,
                    index: frame.index,
                    pose_cw: frame.pose_cw,
                };
                self.localise_lost(resumed, map)?
            }
            _ => {
                self.lost_frames.clear();
                Vec::new()
            }
        };
        let outcome = TrackOutcome {
            state: self.state,
            method,
            inliers,
            new_keyframe: None,
            relative_pose,
            earlier_keyframe: None,
            between_views: Vec::new(),
            after_loss,
            gap_step: None,
            interrupt_mapping: false,
        };
        Ok((Some(frame), outcome, wants_keyframe))
    }

    /// Tries to relocalise a lost frame in `map`, counting the try when the
    /// frame has keypoints enough to succeed (see
    /// [`Self::should_start_new_map`]).
    fn relocalise(&mut self, frame: &mut Frame, map: &Map) -> Result<bool, SlamError> {
        self.relocalisation_tried |= frame.len() >= MIN_RELOCALISATION_INLIERS;
        relocalise_with(
            frame,
            map,
            &self.rig,
            self.relocalisation_candidates.as_deref(),
            self.reference,
        )
    }

    /// Whether relocalisation has failed long enough that tracking should
    /// start a new map (see [`RELOCALISATION_PATIENCE_S`]) at frame `index`:
    /// the patience has run out, and relocalisation has been tried on at
    /// least one frame of the loss with keypoints enough to succeed
    /// ([`MIN_RELOCALISATION_INLIERS`]). Frames that cannot relocalise
    /// (black, blank, unreadable) are no evidence that the old map is out
    /// of reach, so after a blackout the first frame with an image tries
    /// the old map before a new one is started from it.
    pub fn should_start_new_map(&self, index: usize) -> bool {
        self.relocalisation_tried && self.patience_spent(index)
    }

    /// Whether the loss has outlasted the patience at frame `index`
    /// (whatever the frames were): with no relocalisation tried yet, the
    /// caller lets frame `index` try one and, when it fails, starts the new
    /// map from that same frame (see [`Self::should_start_new_map`]).
    pub fn patience_spent(&self, index: usize) -> bool {
        !self.localisation_only
            && self.state == TrackingState::Lost
            && self
                .lost_since
                .is_some_and(|since| index >= since + self.relocalisation_patience())
    }

    /// Frames of failed relocalisation before a new map is started: one
    /// after a loss in a young map ([`YOUNG_MAP_KEYFRAMES`]), else
    /// [`RELOCALISATION_PATIENCE_S`] of frames (at least 3).
    pub fn relocalisation_patience(&self) -> usize {
        if self.lost_in_young_map {
            return YOUNG_MAP_PATIENCE_FRAMES;
        }
        ((RELOCALISATION_PATIENCE_S * self.rig.fps).ceil() as usize).max(MIN_PATIENCE_FRAMES)
    }

    fn initialise(&mut self, mut frame: Frame, map: &mut Map) -> Result<TrackOutcome, SlamError> {
        let mut between_views = Vec::new();
        let (kf, earlier_keyframe) = if self.rig.sensor == Sensor::Monocular {
            match self.mono_init.offer(&mut frame, map, &self.rig)? {
                Some(init) => {
                    between_views = localise_between_views(
                        self.mono_init.take_between(),
                        InitialView {
                            keyframe: init.first,
                            index: init.first_frame,
                        },
                        InitialView {
                            keyframe: init.second,
                            index: frame.index,
                        },
                        map,
                        &self.rig,
                        MIN_LOCAL_MAP_INLIERS,
                    )?;
                    (Some(init.second), Some((init.first_frame, init.first)))
                }
                None => (None, None),
            }
        } else {
            (initialise_map(&mut frame, map, &self.rig)?, None)
        };
        let Some(kf) = kf else {
            if self.rig.sensor != Sensor::Monocular {
                // The monocular initialiser keeps its own frames.
                self.keep_lost(frame);
            }
            return Ok(TrackOutcome {
                state: TrackingState::NotInitialised,
                method: TrackingMethod::None,
                inliers: 0,
                new_keyframe: None,
                relative_pose: None,
                earlier_keyframe: None,
                between_views: Vec::new(),
                after_loss: Vec::new(),
                gap_step: None,
                interrupt_mapping: false,
            });
        };
        // The frames lost before the map's first view, localised in it.
        let resumed = match earlier_keyframe {
            Some((index, first)) => Resumption {
                keyframe: first,
                index,
                pose_cw: map.pose_cw_of(first).in_stage("initialisation")?,
            },
            None => Resumption {
                keyframe: kf,
                index: frame.index,
                pose_cw: frame.pose_cw,
            },
        };
        // The first frame of a map started after a loss: its motion from
        // the lost frame before it anchors the new map in the trajectory.
        let gap_step = if self.lost_frames.is_empty() {
            None
        } else {
            self.measure_gap_step(&frame)?
        };
        let after_loss = self.localise_lost(resumed, map)?;
        self.state = TrackingState::Ok;
        self.reference = Some(kf);
        self.last_keyframe_frame = frame.index;
        let inliers = frame.tracked_count();
        let created: Vec<MapPointId> = frame.map_points.iter().flatten().copied().collect();
        let relative_pose = Some((kf, Se3::identity()));
        self.keep_last(frame, relative_pose);
        Ok(TrackOutcome {
            state: self.state,
            method: TrackingMethod::Initialisation,
            inliers,
            new_keyframe: Some((kf, created)),
            relative_pose,
            earlier_keyframe,
            between_views,
            after_loss,
            gap_step,
            interrupt_mapping: false,
        })
    }

    /// Local-map tracking from the frame's current pose and matches; returns the inliers.
    fn track_local_map_logged(
        &self,
        frame: &mut Frame,
        map: &Map,
        recently_relocalised: bool,
    ) -> Result<usize, SlamError> {
        frame.reference_keyframe = self.reference;
        let outcome = track_local_map(
            frame,
            map,
            &self.rig,
            recently_relocalised,
            if self.counts_points {
                PointCounting::Count
            } else {
                PointCounting::ReadOnly
            },
        )?;
        tracing::debug!(
            frame = frame.index,
            inliers = outcome.inliers,
            visible = outcome.visible_points,
            local_keyframes = outcome.local_keyframes,
            "local map"
        );
        Ok(outcome.inliers)
    }

    /// Tracks the reference keyframe from the last frame's pose.
    fn track_reference(&self, frame: &mut Frame, map: &Map) -> Result<bool, SlamError> {
        let (Some(last), Some(reference)) = (self.last_frame.as_ref(), self.reference) else {
            return Ok(false);
        };
        track_reference_keyframe(frame, &last.pose_cw, reference, map, &self.rig)
    }

    /// Tracks `frame` again by `alternative` (the reference keyframe or
    /// the last frame) and its local map; keeps that pose and its
    /// matches, returning their local-map inliers, when they score better
    /// than the current pose's ([`LocalMapScore`]: a pose with the inliers
    /// its start needs beats one without, then more inliers win) and are
    /// not a jump from it ([`StepLimit::is_jump`]) when `jump_limit` is
    /// given, else restores the frame as it was.
    fn try_instead(
        &self,
        frame: &mut Frame,
        map: &Map,
        alternative: &Start,
        (current, needed, jump_limit): (LocalMapScore, usize, Option<StepLimit>),
        recently_relocalised: bool,
        starts: &mut Vec<StartPose>,
    ) -> Result<Option<usize>, SlamError> {
        let inliers = current.inliers;
        let kept = (
            frame.pose_cw,
            frame.map_points.clone(),
            frame.reference_keyframe,
        );
        let tracked = match alternative {
            Start::ReferenceKeyFrame => self.track_reference(frame, map)?,
            Start::LastFrame => self.track_last(frame, map)?,
            // As for the rejected prediction, local-map tracking decides.
            Start::ImageRotation => self
                .track_image_rotation(frame, map)?
                .is_some_and(|fit| fit.inliers >= MIN_POSE_INLIERS),
            Start::MutualNearestNeighbours => self.track_last_unratioed(frame, map)?,
            Start::RejectedPrediction(start) => {
                (frame.pose_cw, frame.map_points) = (start.pose_cw, start.map_points.clone());
                true
            }
        };
        let mut found = if tracked {
            self.track_local_map_logged(frame, map, recently_relocalised)?
        } else {
            0
        };
        if alternative.method() == TrackingMethod::ImageRotation
            && self.is_prediction_jump(frame, map)
        {
            found = 0;
        }
        if tracked {
            starts.push(StartPose {
                method: alternative.method(),
                pose_cw: frame.pose_cw,
                inliers: found,
            });
        }
        tracing::debug!(
            frame = frame.index,
            inliers,
            alternative = ?alternative.method(),
            alternative_inliers = found,
            "too few or doubtful local-map inliers: another start tried"
        );
        if LocalMapScore::new(found, needed).beats(&current) {
            match jump_limit {
                Some(limit) if limit.is_jump(frame, found) => tracing::debug!(
                    frame = frame.index,
                    alternative = ?alternative.method(),
                    alternative_inliers = found,
                    jump = limit.distance(frame),
                    step = limit.step,
                    "another start's pose kept out: a step away from the motion model's, without twice its inliers"
                ),
                _ => return Ok(Some(found)),
            }
        }
        (frame.pose_cw, frame.map_points, frame.reference_keyframe) = kept;
        Ok(None)
    }

    /// Whether `frame`'s pose, tracked from the search around the images'
    /// rotation, lies farther from the constant velocity's prediction than
    /// that start allows ([`PredictionLimit`]); such a pose counts as
    /// tracked by no inliers.
    fn is_prediction_jump(&self, frame: &Frame, map: &Map) -> bool {
        let limit = self
            .last_frame
            .as_ref()
            .and_then(|last| PredictionLimit::new(&last.pose_cw, self.velocity.as_ref()));
        let Some((distance, allowed)) = limit.and_then(|l| l.exceeded(frame, map)) else {
            return false;
        };
        tracing::debug!(
            frame = frame.index,
            distance,
            allowed,
            "the pose found around the images' rotation lies too far from the prediction"
        );
        true
    }

    /// The motion model's search around the rotation measured from the
    /// last frame's and this frame's images
    /// ([`image_rotation_velocity`]); `None` when there is none to try.
    fn track_image_rotation(
        &self,
        frame: &mut Frame,
        map: &Map,
    ) -> Result<Option<MotionModelFit>, SlamError> {
        let Some(last) = self.last_frame.as_ref() else {
            return Ok(None);
        };
        let Some(velocity) = image_rotation_velocity(frame, last, self.velocity.as_ref()) else {
            return Ok(None);
        };
        track_with_motion_model(frame, last, &velocity, map, &self.rig)
    }

    /// Tracks the last frame's points by descriptor, from its pose.
    fn track_last(&self, frame: &mut Frame, map: &Map) -> Result<bool, SlamError> {
        let Some(last) = self.last_frame.as_ref() else {
            return Ok(false);
        };
        track_last_frame(frame, last, map, &self.rig)
    }

    /// Tracks the last frame's points by mutual nearest neighbour (no ratio
    /// test) and PnP RANSAC.
    fn track_last_unratioed(&self, frame: &mut Frame, map: &Map) -> Result<bool, SlamError> {
        let Some(last) = self.last_frame.as_ref() else {
            return Ok(false);
        };
        track_last_frame_unratioed(frame, last, map, &self.rig)
    }

    /// Motion model when there is a velocity, else (or when it fails) the
    /// reference keyframe, else the last frame, else the motion model with
    /// the rotation measured from the images, else the last frame, else the motion model's
    /// pose that failed only its quarter rule. With the method: whether the
    /// motion model's fit is doubtful, and that rejected pose when the
    /// method is another one (local-map tracking may still try it).
    fn track_frame_to_frame(
        &mut self,
        frame: &mut Frame,
        map: &Map,
    ) -> Result<(TrackingMethod, bool, Option<RejectedPrediction>), SlamError> {
        let Some(last) = self.last_frame.as_ref() else {
            return Ok((TrackingMethod::None, false, None));
        };
        let mut rejected = None;
        if let Some(velocity) = self.velocity {
            if let Some(fit) = track_with_motion_model(frame, last, &velocity, map, &self.rig)? {
                if fit.is_accepted() {
                    return Ok((TrackingMethod::MotionModel, fit.is_doubtful(), None));
                }
                if fit.inliers >= MIN_POSE_INLIERS {
                    rejected = Some(RejectedPrediction {
                        pose_cw: frame.pose_cw,
                        map_points: frame.map_points.clone(),
                        inliers: fit.inliers,
                        from_images: false,
                    });
                }
            }
        }
        if self.track_reference(frame, map)? {
            return Ok((TrackingMethod::ReferenceKeyFrame, false, rejected));
        }
        if self.track_last(frame, map)? {
            return Ok((TrackingMethod::LastFrame, false, rejected));
        }
        // A turn the constant velocity missed, where descriptor matching
        // failed too (motion blur, a repeated texture): the motion model's
        // search again around the rotation the images show (not without
        // a velocity, as just after a relocalisation).
        let image_fit = match self.velocity {
            Some(_) => self.track_image_rotation(frame, map)?,
            None => None,
        };
        if let Some(fit) = image_fit {
            if fit.is_accepted() {
                return Ok((TrackingMethod::ImageRotation, fit.is_doubtful(), rejected));
            }
            // Of the two predictions that failed only their quarter rule,
            // local-map tracking may try the one with more inliers.
            if fit.inliers >= MIN_POSE_INLIERS.max(rejected.as_ref().map_or(0, |r| r.inliers + 1)) {
                rejected = Some(RejectedPrediction {
                    pose_cw: frame.pose_cw,
                    map_points: frame.map_points.clone(),
                    inliers: fit.inliers,
                    from_images: true,
                });
            }
        }
        if let Some(start) = rejected {
            let method = Start::RejectedPrediction(start.clone()).method();
            (frame.pose_cw, frame.map_points) = (start.pose_cw, start.map_points);
            return Ok((method, false, None));
        }
        if self.track_last_unratioed(frame, map)? {
            return Ok((TrackingMethod::MutualNearestNeighbours, false, None));
        }
        Ok((TrackingMethod::None, false, None))
    }

    /// `frame`'s pose relative to the tracker's reference keyframe.
    fn relative_to_reference(
        &self,
        frame: &Frame,
        map: &Map,
    ) -> Result<Option<(KeyFrameId, Se3)>, SlamError> {
        relative_to(frame, self.reference, map)
    }

    /// The map was scaled by `scale` (a monocular map merged into an older
    /// one in Sim(3)): the last frame's pose relative to its reference
    /// keyframe and the velocity keep their rotations and scale their
    /// translations, so the next frame's prediction lands in the new units.
    pub fn rescale(&mut self, scale: f64) {
        if let Some((_, rel)) = self.last_relative.as_mut() {
            rel.translation *= scale;
        }
        if let Some(velocity) = self.velocity.as_mut() {
            velocity.translation *= scale;
        }
    }

    /// The last tracked frame (an untracked frame is not kept).
    pub fn last_frame(&self) -> Option<&Frame> {
        self.last_frame.as_ref()
    }

    fn keep_last(&mut self, frame: Frame, relative: Option<(KeyFrameId, Se3)>) {
        // An untracked frame is dropped: the motion model restarts from
        // the last tracked one.
        if relative.is_some() {
            self.last_relative = relative;
            self.last_frame = Some(frame);
        }
    }
}
