//! The SLAM driver (stereo, RGB-D or monocular, as the rig says): front
//! end, tracking and local mapping over the atlas. Local mapping runs
//! either inline, right after each new keyframe (deterministic: tests and
//! benchmarks), or on its own thread
//! ([`SlamSystem::spawn_mapping_thread`]) as in ORB-SLAM3, fed keyframes
//! through a channel while the next frame is extracted and tracked.

use std::collections::BTreeMap;
use std::time::Instant;

use crate::camera::CameraRig;
use crate::error::SlamError;
use crate::features::GrayImageView;
use crate::loop_closing::GlobalBaSummary;
use crate::map::{KeyFrameId, SharedMap};
use crate::mapping::{LocalMapper, MappingSummary};
use crate::optim::{LieGroup, Se3};
use crate::tracking::{
    Extractors, FrameBuilder, Frontend, LateLocalisation, SensorFeatures, SensorImages,
    TrackOutcome, Tracker, TrackingMethod, TrackingState,
};

use super::atlas::{Atlas, MapIndex};
use super::gap_motion::GapRotations;
use super::global_ba_thread::{GlobalBaHook, GlobalBaThread};
use super::lagged_mapping::{LaggedJob, LaggedMapping, LaggedStep};
use super::local_mapping_thread::{MappingJob, MappingResult, MappingThread, StoppedMapping};
use super::loop_closing_stage::{LoopClosingStage, LoopLog};
use super::loop_closing_thread::LoopClosingThread;
use super::odometry_chain::chain_odometry;
use super::records::{FrameRecord, FrameTimings, RelativePose};
use super::second_look::{SecondLook, SecondLookFrame, SecondLookOutcome};

/// Where loop detection runs: on the tracking thread between frames
/// (with inline mapping: deterministic), or on its own thread (with a
/// mapping thread).
#[derive(Debug)]
pub(super) enum LoopClosing {
    /// Between frames, on the caller's thread.
    Inline(Box<LoopClosingStage>),
    /// On the loop-closing thread.
    Thread(LoopClosingThread),
}

/// Where local mapping runs.
#[derive(Debug)]
pub(super) enum Mapping {
    /// On the tracking thread, right after each keyframe.
    Inline(LocalMapper),
    /// On its own thread; keyframe id → index of the record that made it.
    Thread {
        thread: MappingThread,
        waiting: BTreeMap<KeyFrameId, usize>,
    },
    /// Its thread stopped after its current keyframe for a correction
    /// ([`SlamSystem::pause_mapping`]); the system holds the mapper (with
    /// its switches) and the keyframes not started, so an error before
    /// [`SlamSystem::resume_mapping`] loses neither: the next frame, or
    /// [`SlamSystem::finish`], resumes it.
    Paused {
        stopped: StoppedMapping,
        waiting: BTreeMap<KeyFrameId, usize>,
    },
}

/// SLAM over a sequence of frames of one sensor (the rig's: rectified
/// stereo pairs, RGB-D images or monocular images).
///
/// Threads: tracking runs on the caller's thread, local mapping inline or
/// on its own thread. Loop closing ([`Self::enable_loop_closing`]) checks
/// every keyframe local mapping has processed, as ORB-SLAM3's
/// `LoopClosing`: on its own thread when local mapping has one, else on
/// the caller's thread between frames. A loop or merge is corrected on the
/// caller's thread between frames, with local mapping stopped after its
/// current keyframe, as ORB-SLAM3's `RequestStop`; the global BA that
/// follows runs on its own thread.
pub struct SlamSystem {
    pub(super) rig: CameraRig,
    extractors: Option<Extractors>,
    builder: FrameBuilder,
    pub(super) tracker: Tracker,
    pub(super) mapping: Mapping,
    /// Inline mapping that lags a fixed number of frames per keyframe.
    mapping_lag: Option<LaggedMapping>,
    pub(super) atlas: Atlas,
    pub(super) records: Vec<FrameRecord>,
    /// Rotations between consecutive frames measured over tracking gaps.
    gap_rotations: GapRotations,
    pub(super) loop_closing: Option<LoopClosing>,
    /// Keyframes processed by local mapping, not yet given to loop closing.
    pub(super) loop_inbox: Vec<KeyFrameId>,
    pub(super) loop_log: LoopLog,
    pub(super) global_ba: Option<GlobalBaThread>,
    pub(super) global_ba_runs: Vec<GlobalBaSummary>,
    pub(super) global_ba_hook: Option<GlobalBaHook>,
    /// A deeper pyramid's look at a frame tracking lost.
    second_look: Option<SecondLook>,
}

impl SlamSystem {
    /// A system with an empty atlas (one empty map), mapping inline.
    pub fn new(rig: CameraRig, frontend: Frontend) -> Self {
        let (extractors, builder) = frontend.into_parts();
        Self {
            rig,
            extractors: Some(extractors),
            builder,
            tracker: Tracker::new(rig),
            mapping: Mapping::Inline(LocalMapper::new(rig)),
            mapping_lag: None,
            atlas: Atlas::new(),
            records: Vec::new(),
            gap_rotations: GapRotations::default(),
            loop_closing: None,
            loop_inbox: Vec::new(),
            loop_log: LoopLog::default(),
            global_ba: None,
            global_ba_runs: Vec::new(),
            global_ba_hook: None,
            second_look: None,
        }
    }

    /// Gives a frame tracking lost a second look: its images extracted
    /// again by `second_look`'s extractors (a deeper pyramid) and tracked
    /// once more from the tracking state before the first try; `None`:
    /// lost frames stay lost. See [`SecondLook`].
    pub fn set_second_look(&mut self, second_look: Option<SecondLook>) {
        self.second_look = second_look;
    }

    /// The second look's pyramid levels, when lost frames get one.
    pub fn second_look_levels(&self) -> Option<usize> {
        self.second_look.as_ref().map(SecondLook::levels)
    }

    /// Restarts the local-mapping thread stopped by [`Self::pause_mapping`]
    /// on `map` (the corrected or merged map), with the keyframes it had
    /// not started queued again; one that no longer exists in `map` is
    /// dropped (its frame's record gets no mapping summary). A no-op
    /// unless mapping is paused.
    pub(super) fn resume_mapping(&mut self, map: &SharedMap) -> Result<(), SlamError> {
        if !matches!(self.mapping, Mapping::Paused { .. }) {
            return Ok(());
        }
        let placeholder = Mapping::Inline(LocalMapper::new(self.rig));
        let Mapping::Paused {
            stopped,
            mut waiting,
        } = std::mem::replace(&mut self.mapping, placeholder)
        else {
            return Ok(());
        };
        let StoppedMapping {
            mapper,
            unprocessed,
        } = stopped;
        let (alive, gone): (Vec<MappingJob>, Vec<MappingJob>) = {
            let m = map.read().map_err(|_| SlamError::PoisonedMap)?;
            unprocessed
                .into_iter()
                .partition(|job| m.keyframe(job.keyframe).is_ok())
        };
        for job in gone {
            tracing::warn!(keyframe = ?job.keyframe, "a queued keyframe gone after the correction was not mapped");
            waiting.remove(&job.keyframe);
        }
        let mut thread = MappingThread::spawn(mapper, map.clone())?;
        for job in alive {
            thread.submit(job.keyframe, job.created)?;
        }
        self.mapping = Mapping::Thread { thread, waiting };
        Ok(())
    }

    /// Resumes local mapping on the active map if an error left it paused.
    fn resume_if_paused(&mut self) -> Result<(), SlamError> {
        if matches!(self.mapping, Mapping::Paused { .. }) {
            tracing::warn!("local mapping was left paused by an error; resuming it");
            let map = self.atlas.active().map.clone();
            self.resume_mapping(&map)?;
        }
        Ok(())
    }

    /// Stops the local-mapping thread after its current keyframe
    /// (ORB-SLAM3's `RequestStop`; its results are filed) and holds it in
    /// [`Mapping::Paused`] until [`Self::resume_mapping`]. With mapping
    /// inline, the lagged keyframes are mapped now instead.
    pub(super) fn pause_mapping(&mut self) -> Result<(), SlamError> {
        let Mapping::Thread { .. } = self.mapping else {
            return self.drain_lagged_mapping();
        };
        let placeholder = Mapping::Inline(LocalMapper::new(self.rig));
        let Mapping::Thread {
            thread,
            mut waiting,
        } = std::mem::replace(&mut self.mapping, placeholder)
        else {
            return Ok(());
        };
        let (stopped, results) = thread.stop()?;
        let attached = self.attach(results, &mut waiting);
        self.mapping = Mapping::Paused { stopped, waiting };
        attached
    }

    /// The active map.
    pub fn map(&self) -> &SharedMap {
        &self.atlas.active().map
    }

    /// Every map made so far.
    pub fn atlas(&self) -> &Atlas {
        &self.atlas
    }

    /// The local mapper (to switch BA or culling off); `None` while it
    /// runs on its own thread.
    pub fn mapper_mut(&mut self) -> Option<&mut LocalMapper> {
        match &mut self.mapping {
            Mapping::Inline(mapper) => Some(mapper),
            Mapping::Thread { .. } | Mapping::Paused { .. } => None,
        }
    }

    /// Moves local mapping to its own thread (no-op when it already is).
    /// A failed spawn is an error, and mapping stays inline.
    pub fn spawn_mapping_thread(&mut self) -> Result<(), SlamError> {
        self.resume_if_paused()?;
        self.drain_lagged_mapping()?;
        self.mapping_lag = None;
        let Mapping::Inline(mapper) = &mut self.mapping else {
            return Ok(());
        };
        let keep = mapper.fresh();
        let mapper = std::mem::replace(mapper, keep);
        let thread = MappingThread::spawn(mapper, self.atlas.active().map.clone())?;
        self.mapping = Mapping::Thread {
            thread,
            waiting: BTreeMap::new(),
        };
        self.spawn_loop_closing_thread()
    }

    /// A deterministic slow machine for tests and the suite: inline local
    /// mapping finishes each keyframe `frames_per_keyframe` frames after
    /// its work began, keyframes queue meanwhile, and tracking sees the
    /// queue as it sees the mapping thread's backlog (see
    /// [`super::lagged_mapping`]). `None` maps each keyframe at once. A
    /// later [`Self::spawn_mapping_thread`] ends the lag.
    pub fn set_mapping_lag(&mut self, frames_per_keyframe: Option<usize>) -> Result<(), SlamError> {
        self.drain_lagged_mapping()?;
        self.mapping_lag = frames_per_keyframe.map(LaggedMapping::new);
        Ok(())
    }

    /// Maps the lagged keyframes due by frame `index`.
    fn map_due_keyframes(&mut self, index: usize) -> Result<(), SlamError> {
        let Some(lag) = self.mapping_lag.as_mut() else {
            return Ok(());
        };
        let due = lag.due(index);
        self.map_lagged(due)
    }

    /// Maps every lagged keyframe still queued.
    fn drain_lagged_mapping(&mut self) -> Result<(), SlamError> {
        let Some(lag) = self.mapping_lag.as_mut() else {
            return Ok(());
        };
        let queued = lag.drain();
        self.map_lagged(queued)
    }

    /// Monocular tracking at frame `index` wanted a keyframe while local
    /// mapping was busy: the mapper's local BA yields (ORB-SLAM3's
    /// `InterruptBA`).
    fn interrupt_mapping(&mut self, index: usize) {
        match &self.mapping {
            Mapping::Thread { thread, .. } => thread.interrupt_bundle_adjustment(),
            Mapping::Inline(_) => {
                if let Some(lag) = self.mapping_lag.as_mut() {
                    lag.interrupt(index);
                }
            }
            Mapping::Paused { .. } => {}
        }
    }

    /// Runs inline local mapping on lagged keyframes and files each
    /// summary under the frame that made the keyframe.
    fn map_lagged(&mut self, jobs: Vec<(LaggedJob, LaggedStep)>) -> Result<(), SlamError> {
        let Mapping::Inline(mapper) = &mut self.mapping else {
            return Ok(());
        };
        let map = self.atlas.active().map.clone();
        for (job, step) in jobs {
            // The mapper asks whether tracking queued another keyframe
            // after its triangulation and after its fusion; an interrupted
            // BA keeps the share of its iterations it had time for.
            let tracking_signals = || step == LaggedStep::LeftToNext;
            mapper.set_bundle_share(step.bundle_share());
            let summary =
                mapper.process_keyframe(&map, job.keyframe, &job.created, &tracking_signals)?;
            self.loop_inbox.push(job.keyframe);
            if let Some(record) = self.records.get_mut(job.record) {
                record.timings.mapping_ms = summary.elapsed_ms;
                record.mapping = Some(summary);
            }
        }
        Ok(())
    }

    /// Extracts a frame's features (a stereo pair's in parallel) without
    /// tracking them; see [`Self::process_features`].
    pub fn extract(
        &mut self,
        index: usize,
        images: SensorImages<'_>,
    ) -> Result<SensorFeatures, SlamError> {
        self.extractors
            .as_mut()
            .ok_or(SlamError::ExtractorsDetached { frame: index })?
            .extract(index, images)
    }

    /// Hands the extractors over (once; `None` afterwards), for a pipeline
    /// that extracts the next frame on its own thread while this one is
    /// tracked. From then on [`Self::process`] and [`Self::extract`] fail
    /// with [`SlamError::ExtractorsDetached`]; use [`Self::process_features`].
    pub fn detach_extractors(&mut self) -> Option<Extractors> {
        self.extractors.take()
    }

    /// Starts over: an empty atlas, tracking not initialised, no records
    /// (ORB-SLAM3's `Reset`). Local mapping stays where it runs and keeps
    /// its switches.
    pub fn reset(&mut self) -> Result<(), SlamError> {
        let threaded = !matches!(self.mapping, Mapping::Inline(_));
        self.finish()?;
        if let Mapping::Inline(mapper) = &mut self.mapping {
            *mapper = mapper.fresh();
        }
        self.atlas = Atlas::new();
        self.tracker = self.tracker.fresh();
        self.records.clear();
        self.loop_log = LoopLog::default();
        if let Some(stage) = self.inline_loop_stage() {
            stage.reset()?;
        }
        if threaded {
            self.spawn_mapping_thread()?;
        }
        Ok(())
    }

    /// Waits for local mapping to finish every queued keyframe and for
    /// loop closing to check them, brings both back inline, and applies
    /// the last global BA. Call before reading the final trajectory.
    pub fn finish(&mut self) -> Result<(), SlamError> {
        self.resume_if_paused()?;
        let Mapping::Thread { .. } = self.mapping else {
            self.drain_lagged_mapping()?;
            self.stop_loop_closing_thread()?;
            self.close_loops()?;
            return self.poll_global_ba(true);
        };
        let placeholder = Mapping::Inline(LocalMapper::new(self.rig));
        let Mapping::Thread {
            thread,
            mut waiting,
        } = std::mem::replace(&mut self.mapping, placeholder)
        else {
            return Ok(());
        };
        let (mapper, results) = thread.finish()?;
        self.mapping = Mapping::Inline(mapper);
        self.attach(results, &mut waiting)?;
        self.stop_loop_closing_thread()?;
        self.close_loops()?;
        self.poll_global_ba(true)
    }

    /// Files local mapping's results under the frames that made the keyframes.
    fn attach(
        &mut self,
        results: Vec<MappingResult>,
        waiting: &mut BTreeMap<KeyFrameId, usize>,
    ) -> Result<(), SlamError> {
        for result in results {
            let summary = result.summary?;
            self.loop_inbox.push(result.keyframe);
            if let Some(record) = waiting
                .remove(&result.keyframe)
                .and_then(|i| self.records.get_mut(i))
            {
                record.timings.mapping_ms = summary.elapsed_ms;
                record.mapping = Some(summary);
            }
        }
        Ok(())
    }

    fn poll_mapping(&mut self) -> Result<(), SlamError> {
        self.resume_if_paused()?;
        let Mapping::Thread { thread, waiting } = &mut self.mapping else {
            return Ok(());
        };
        let results = thread.poll()?;
        let mut waiting = std::mem::take(waiting);
        let attached = self.attach(results, &mut waiting);
        if let Mapping::Thread { waiting: w, .. } = &mut self.mapping {
            *w = waiting;
        }
        attached?;
        self.close_loops()?;
        self.poll_global_ba(false)
    }

    /// Gives the active map up and starts a new one from frame `index`:
    /// local mapping finishes the old map's queue, then works on the new
    /// map with fresh state; tracking starts uninitialised.
    fn start_new_map(&mut self, index: usize) -> Result<(), SlamError> {
        let threaded = !matches!(self.mapping, Mapping::Inline(_));
        self.finish()?;
        if let Mapping::Inline(mapper) = &mut self.mapping {
            *mapper = mapper.fresh();
        }
        let finished = self.atlas.active().index;
        let handover = self.handover(finished)?;
        let new_map = self.atlas.start_new_map(index);
        if let Some(stage) = self.inline_loop_stage() {
            stage.new_map(finished, handover)?;
        }
        tracing::info!(
            frame = index,
            map = new_map,
            "tracking lost for good: new map"
        );
        self.tracker = self.tracker.fresh_after_loss();
        if threaded {
            self.spawn_mapping_thread()?;
        }
        Ok(())
    }

    /// The camera rig it tracks with.
    pub fn rig(&self) -> &CameraRig {
        &self.rig
    }

    /// The extractor's name.
    pub fn extractor_name(&self) -> &str {
        self.builder.extractor_name()
    }

    /// The frames processed so far.
    pub fn records(&self) -> &[FrameRecord] {
        &self.records
    }

    /// Processes one rectified stereo pair (see [`Self::process_images`]).
    pub fn process(
        &mut self,
        index: usize,
        timestamp: f64,
        left: GrayImageView<'_>,
        right: GrayImageView<'_>,
    ) -> Result<&FrameRecord, SlamError> {
        self.process_images(index, timestamp, SensorImages::Stereo { left, right })
    }

    /// Processes one frame of the system's sensor.
    pub fn process_images(
        &mut self,
        index: usize,
        timestamp: f64,
        images: SensorImages<'_>,
    ) -> Result<&FrameRecord, SlamError> {
        let start = Instant::now();
        let features = self.extract(index, images)?;
        let extraction_ms = start.elapsed().as_secs_f64() * 1e3;
        self.process_features(index, timestamp, features, images, extraction_ms)
    }

    /// Records an input frame that could not be read (a missing or corrupt
    /// image): it counts as lost, its trajectory row carries on the last
    /// tracked pose and velocity (see [`super::GAP_HORIZON_S`]), and
    /// tracking goes on with the next frame.
    pub fn skip_unreadable(
        &mut self,
        index: usize,
        timestamp: f64,
        reason: String,
    ) -> &FrameRecord {
        let state = match self.tracker.state() {
            TrackingState::NotInitialised => TrackingState::NotInitialised,
            _ => TrackingState::Lost,
        };
        self.gap_rotations.next(None, false);
        self.records.push(FrameRecord {
            index,
            timestamp,
            map: self.atlas.active().index,
            state,
            method: TrackingMethod::None,
            inliers: 0,
            stereo_points: 0,
            keyframe: false,
            unreadable: Some(reason),
            relative_pose: None,
            gap_rotation: None,
            gap_rotation_deg: None,
            gap_step: None,
            gap_step_inliers: None,
            timings: FrameTimings::default(),
            mapping: None,
            loop_check_running: false,
            second_look: None,
        });
        let last = self.records.len() - 1;
        &self.records[last]
    }

    /// Processes a frame whose features were extracted already
    /// (benchmarks time everything but extraction this way);
    /// `extraction_ms` goes into the record.
    pub fn process_features(
        &mut self,
        index: usize,
        timestamp: f64,
        features: SensorFeatures,
        images: SensorImages<'_>,
        extraction_ms: f64,
    ) -> Result<&FrameRecord, SlamError> {
        self.poll_mapping()?;
        self.map_due_keyframes(index)?;
        let new_map_due = self.tracker.should_start_new_map(index);
        if new_map_due {
            self.start_new_map(index)?;
        }
        let (frame, stereo_ms) = self
            .builder
            .build_frame(index, timestamp, features, images, &self.rig)?;
        // A loss that outlasted the patience on frames that could not
        // relocalise (a blackout): this frame tries the old map first, and
        // starts the new one itself if that fails.
        let second_try =
            (!new_map_due && self.tracker.patience_spent(index)).then(|| frame.clone());
        let mut stereo_points = frame.stereo_count();
        let thumbnail = frame.thumbnail.clone();
        let queue = match &self.mapping {
            Mapping::Thread { thread, .. } => thread.pending(),
            Mapping::Paused { stopped, .. } => stopped.unprocessed.len(),
            Mapping::Inline(_) => self.mapping_lag.as_ref().map_or(0, LaggedMapping::pending),
        };
        if queue > 0 {
            tracing::debug!(frame = index, queue, "local mapping busy");
        }
        let active = self.atlas.active();
        let (mut map_index, mut map) = (active.index, active.map.clone());
        let loop_check_at_start = self.loop_check_running();
        let start = Instant::now();
        // The state a second look starts from (not on a frame that may
        // start a new map, nor before a map exists: those tries write).
        let before_first_try = (self.second_look.is_some()
            && second_try.is_none()
            && self.tracker.state() != TrackingState::NotInitialised)
            .then(|| self.tracker.clone());
        let mut outcome = self.tracker.track(frame, &map, queue)?;
        if let Some(frame) = second_try {
            if self.tracker.should_start_new_map(index) {
                self.start_new_map(index)?;
                let active = self.atlas.active();
                (map_index, map) = (active.index, active.map.clone());
                outcome = self.tracker.track(frame, &map, queue)?;
            }
        }
        let mut second_look = None;
        let mut second_look_ms = (0.0, 0.0);
        if let (None, Some(before)) = (&outcome.relative_pose, before_first_try) {
            if let Some(look) = self.look_again(index, timestamp, images, before, &map, queue)? {
                if look.outcome.relative_pose.is_some() {
                    // The second try's state stays; its outcome replaces the first's.
                    outcome = look.outcome;
                    stereo_points = look.stereo_points;
                    second_look = Some(SecondLookOutcome::Tracked);
                } else {
                    self.tracker = look.first_try;
                    second_look = Some(SecondLookOutcome::StillLost);
                }
                second_look_ms = (look.extraction_ms, look.stereo_ms);
            }
        }
        let tracking_ms = start.elapsed().as_secs_f64() * 1e3 - second_look_ms.0 - second_look_ms.1;
        if outcome.interrupt_mapping {
            self.interrupt_mapping(index);
        }
        let loop_check_running = loop_check_at_start || self.loop_check_running();
        let mut mapping: Option<MappingSummary> = None;
        if let Some((kf, created)) = &outcome.new_keyframe {
            match &mut self.mapping {
                Mapping::Inline(_) if self.mapping_lag.is_some() => {
                    if let Some(lag) = self.mapping_lag.as_mut() {
                        let job = LaggedJob {
                            keyframe: *kf,
                            created: created.clone(),
                            record: self.records.len(),
                        };
                        lag.submit(index, job);
                    }
                }
                Mapping::Inline(mapper) => {
                    mapping = Some(mapper.process_keyframe(&map, *kf, created, &|| false)?);
                    self.loop_inbox.push(*kf);
                }
                Mapping::Thread { thread, waiting } => {
                    thread.submit(*kf, created.clone())?;
                    waiting.insert(*kf, self.records.len());
                }
                Mapping::Paused { stopped, waiting } => {
                    stopped.unprocessed.push(MappingJob {
                        keyframe: *kf,
                        created: created.clone(),
                    });
                    waiting.insert(*kf, self.records.len());
                }
            }
        }
        if let Some((earlier, kf)) = outcome.earlier_keyframe {
            self.record_earlier_keyframe(earlier, map_index, kf);
        }
        for localised in &outcome.between_views {
            self.record_late(localised, map_index, TrackingMethod::BetweenInitialViews);
        }
        for localised in &outcome.after_loss {
            self.record_late(localised, map_index, TrackingMethod::AfterLoss);
        }
        let mapping_ms = mapping.as_ref().map_or(0.0, |m| m.elapsed_ms);
        let untracked =
            outcome.relative_pose.is_none() || outcome.method == TrackingMethod::Initialisation;
        let gap_rotation = self.gap_rotations.next(thumbnail, untracked);
        self.records.push(FrameRecord {
            index,
            timestamp,
            map: map_index,
            state: outcome.record_state(),
            method: outcome.method,
            inliers: outcome.inliers,
            stereo_points,
            keyframe: outcome.new_keyframe.is_some(),
            unreadable: None,
            relative_pose: outcome.relative_pose.map(|(keyframe, pose)| RelativePose {
                map: map_index,
                keyframe,
                pose,
            }),
            gap_rotation,
            gap_rotation_deg: gap_rotation.map(|r| r.angle().to_degrees()),
            gap_step: outcome.gap_step.map(|s| s.pose_cp),
            gap_step_inliers: outcome.gap_step.map(|s| s.inliers),
            timings: FrameTimings {
                extraction_ms: extraction_ms + second_look_ms.0,
                stereo_ms: stereo_ms + second_look_ms.1,
                tracking_ms,
                lock_wait_ms: self.tracker.last_lock_wait_ms(),
                mapping_ms,
            },
            mapping,
            loop_check_running,
            second_look,
        });
        let last = self.records.len() - 1;
        chain_odometry(&mut self.records, last);
        if matches!(self.mapping, Mapping::Inline(_)) {
            self.close_loops()?;
        }
        Ok(&self.records[last])
    }

    /// The second look at frame `index`, lost on its first try: its
    /// features on the second look's pyramid, tracked from `before` (the
    /// tracker as it was before the first try), which becomes the tracker;
    /// the first try's tracker is handed back. `None` when there is no
    /// second look or its extraction failed (warned): nothing changed.
    fn look_again(
        &mut self,
        index: usize,
        timestamp: f64,
        images: SensorImages<'_>,
        before: Tracker,
        map: &SharedMap,
        queue: usize,
    ) -> Result<Option<SecondTry>, SlamError> {
        let Some(look) = self.second_look.as_mut() else {
            return Ok(None);
        };
        let Some(SecondLookFrame {
            frame,
            extraction_ms,
            stereo_ms,
        }) = look.frame(index, timestamp, images, &self.rig)?
        else {
            return Ok(None);
        };
        let stereo_points = frame.stereo_count();
        let first_try = std::mem::replace(&mut self.tracker, before);
        // The first try counted the points it saw; this one does not.
        self.tracker.set_point_counting(false);
        let outcome = self.tracker.track(frame, map, queue);
        self.tracker.set_point_counting(true);
        let outcome = outcome?;
        tracing::debug!(
            frame = index,
            tracked = outcome.relative_pose.is_some(),
            inliers = outcome.inliers,
            "second look"
        );
        Ok(Some(SecondTry {
            outcome,
            first_try,
            stereo_points,
            extraction_ms,
            stereo_ms,
        }))
    }

    /// Whether the loop-closing thread is checking a keyframe now.
    fn loop_check_running(&self) -> bool {
        matches!(&self.loop_closing, Some(LoopClosing::Thread(thread)) if thread.is_checking())
    }

    /// A monocular initialisation made a keyframe of an earlier frame:
    /// its record gets that pose.
    fn record_earlier_keyframe(&mut self, index: usize, map: MapIndex, keyframe: KeyFrameId) {
        if let Some(record) = self.records.iter_mut().rev().find(|r| r.index == index) {
            record.state = TrackingState::Ok;
            record.method = TrackingMethod::Initialisation;
            record.keyframe = true;
            record.map = map;
            record.relative_pose = Some(RelativePose {
                map,
                keyframe,
                pose: Se3::identity(),
            });
        }
    }

    /// A frame was localised after the fact (between a monocular
    /// initialisation's two views, or lost before tracking resumed) in
    /// map `map`: its record gets that pose and `method`.
    fn record_late(&mut self, localised: &LateLocalisation, map: MapIndex, method: TrackingMethod) {
        let Some(at) = self
            .records
            .iter()
            .rposition(|r| r.index == localised.index)
        else {
            return;
        };
        if let Some(record) = self.records.get_mut(at) {
            record.state = TrackingState::Ok;
            record.method = method;
            record.inliers = localised.inliers;
            record.map = map;
            record.relative_pose = Some(RelativePose {
                map,
                keyframe: localised.keyframe,
                pose: localised.relative_pose,
            });
        }
        chain_odometry(&mut self.records, at);
    }

    /// The tracking state now.
    pub fn state(&self) -> TrackingState {
        self.tracker.state()
    }
}

/// A lost frame tracked again on the second look's features.
struct SecondTry {
    /// The second try's outcome.
    outcome: TrackOutcome,
    /// The tracker after the first try (restored when that one is kept).
    first_try: Tracker,
    /// The second look's stereo keypoints.
    stereo_points: usize,
    /// Its extraction and stereo matching, ms.
    extraction_ms: f64,
    stereo_ms: f64,
}
