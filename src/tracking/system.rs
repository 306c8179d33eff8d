//! The stereo SLAM driver: front end, tracking and local mapping over one
//! shared map. Local mapping runs either inline, right after each new
//! keyframe (deterministic: tests and benchmarks), or on its own thread
//! ([`StereoSlam::spawn_mapping_thread`]) as in ORB-SLAM3, fed keyframes
//! through a channel while the next frame is extracted and tracked.

use std::collections::BTreeMap;
use std::time::Instant;

use crate::features::GrayImageView;
use crate::map::{KeyFrameId, Map, SharedMap};
use crate::mapping::{LocalMapper, MappingResult, MappingSummary, MappingThread};
use crate::optim::{LieGroup, Se3};

use super::error::SlamError;
use super::frontend::{StereoFeatures, StereoFrontend};
use super::rig::StereoRig;
use super::tracker::{Tracker, TrackingMethod, TrackingState};

/// Milliseconds per stage for one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct FrameTimings {
    /// Left and right extraction (in parallel), wall clock.
    pub extraction_ms: f64,
    /// Stereo matching.
    pub stereo_ms: f64,
    /// Tracking (all of it, keyframe insertion included).
    pub tracking_ms: f64,
    /// Local mapping (0 on frames without a new keyframe).
    pub mapping_ms: f64,
}

/// What happened to one frame.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FrameRecord {
    /// Index in the input sequence.
    pub index: usize,
    /// Timestamp, seconds.
    pub timestamp: f64,
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
    /// `(reference keyframe, T_c,ref)` when tracked.
    #[serde(skip)]
    pub relative_pose: Option<(KeyFrameId, Se3)>,
    /// Time per stage.
    pub timings: FrameTimings,
    /// Local mapping's summary when it ran.
    pub mapping: Option<MappingSummary>,
}

/// Totals over the frames processed so far.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct SlamSummary {
    /// Frames processed.
    pub frames: usize,
    /// Frames with a tracked pose (initialisation included).
    pub tracked: usize,
    /// Frames processed while lost (tracking failures).
    pub lost: usize,
    /// Frames before initialisation.
    pub not_initialised: usize,
    /// Relocalisations.
    pub relocalisations: usize,
    /// Keyframes inserted.
    pub keyframes_inserted: usize,
    /// Live keyframes in the map.
    pub keyframes: usize,
    /// Live map points.
    pub map_points: usize,
    /// Mean time per stage, ms.
    pub mean_timings: FrameTimings,
}

/// Where local mapping runs.
#[derive(Debug)]
enum Mapping {
    /// On the tracking thread, right after each keyframe.
    Inline(LocalMapper),
    /// On its own thread; keyframe id → index of the record that made it.
    Thread {
        thread: MappingThread,
        waiting: BTreeMap<KeyFrameId, usize>,
    },
    /// Between the two (only while switching).
    Switching,
}

/// Stereo SLAM over a sequence of rectified pairs.
pub struct StereoSlam {
    rig: StereoRig,
    frontend: StereoFrontend,
    tracker: Tracker,
    mapping: Mapping,
    map: SharedMap,
    records: Vec<FrameRecord>,
}

impl StereoSlam {
    /// A system with an empty map.
    pub fn new(rig: StereoRig, frontend: StereoFrontend) -> Self {
        Self {
            rig,
            frontend,
            tracker: Tracker::new(rig),
            mapping: Mapping::Inline(LocalMapper::new(rig)),
            map: Map::new().into_shared(),
            records: Vec::new(),
        }
    }

    /// The shared map.
    pub fn map(&self) -> &SharedMap {
        &self.map
    }

    /// The local mapper (to switch BA or culling off); `None` while it
    /// runs on its own thread.
    pub fn mapper_mut(&mut self) -> Option<&mut LocalMapper> {
        match &mut self.mapping {
            Mapping::Inline(mapper) => Some(mapper),
            _ => None,
        }
    }

    /// Moves local mapping to its own thread (no-op when it already is).
    pub fn spawn_mapping_thread(&mut self) -> Result<(), SlamError> {
        if let Mapping::Inline(_) = self.mapping {
            let Mapping::Inline(mapper) = std::mem::replace(&mut self.mapping, Mapping::Switching)
            else {
                return Ok(());
            };
            let thread = MappingThread::spawn(mapper, self.map.clone())?;
            self.mapping = Mapping::Thread {
                thread,
                waiting: BTreeMap::new(),
            };
        }
        Ok(())
    }

    /// Extracts a stereo pair's features (left and right in parallel)
    /// without tracking them; see [`Self::process_features`].
    pub fn extract(
        &mut self,
        index: usize,
        left: GrayImageView<'_>,
        right: GrayImageView<'_>,
    ) -> Result<StereoFeatures, SlamError> {
        self.frontend.extract(index, left, right)
    }

    /// Starts over: an empty map, tracking not initialised, no records
    /// (ORB-SLAM3's `Reset`). Local mapping stays where it runs and keeps
    /// its switches.
    pub fn reset(&mut self) -> Result<(), SlamError> {
        let threaded = matches!(self.mapping, Mapping::Thread { .. });
        self.finish()?;
        if let Mapping::Inline(mapper) = &mut self.mapping {
            let mut fresh = LocalMapper::new(self.rig);
            fresh.bundle_adjustment = mapper.bundle_adjustment;
            fresh.keyframe_culling = mapper.keyframe_culling;
            *mapper = fresh;
        }
        *self.map.write().map_err(|_| SlamError::PoisonedMap)? = Map::new();
        self.tracker = Tracker::new(self.rig);
        self.records.clear();
        if threaded {
            self.spawn_mapping_thread()?;
        }
        Ok(())
    }

    /// Waits for local mapping to finish every queued keyframe and brings
    /// it back inline. Call before reading the final trajectory.
    pub fn finish(&mut self) -> Result<(), SlamError> {
        if let Mapping::Thread { .. } = self.mapping {
            let Mapping::Thread { thread, waiting } =
                std::mem::replace(&mut self.mapping, Mapping::Switching)
            else {
                return Ok(());
            };
            let (mapper, results) = thread.finish()?;
            self.mapping = Mapping::Inline(mapper);
            let mut waiting = waiting;
            self.attach(results, &mut waiting)?;
        }
        Ok(())
    }

    /// Files local mapping's results under the frames that made the keyframes.
    fn attach(
        &mut self,
        results: Vec<MappingResult>,
        waiting: &mut BTreeMap<KeyFrameId, usize>,
    ) -> Result<(), SlamError> {
        for result in results {
            let summary = result.summary?;
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
        let (results, mut waiting) = match &mut self.mapping {
            Mapping::Thread { thread, waiting } => (thread.poll(), std::mem::take(waiting)),
            _ => return Ok(()),
        };
        let attached = self.attach(results, &mut waiting);
        if let Mapping::Thread { waiting: w, .. } = &mut self.mapping {
            *w = waiting;
        }
        attached
    }

    /// The extractor's name.
    pub fn extractor_name(&self) -> &str {
        self.frontend.extractor_name()
    }

    /// The frames processed so far.
    pub fn records(&self) -> &[FrameRecord] {
        &self.records
    }

    /// Processes one rectified stereo pair.
    pub fn process(
        &mut self,
        index: usize,
        timestamp: f64,
        left: GrayImageView<'_>,
        right: GrayImageView<'_>,
    ) -> Result<&FrameRecord, SlamError> {
        let start = Instant::now();
        let features = self.frontend.extract(index, left, right)?;
        let extraction_ms = start.elapsed().as_secs_f64() * 1e3;
        self.process_features(index, timestamp, features, left, right, extraction_ms)
    }

    /// Processes a stereo pair whose features were extracted already
    /// (benchmarks time everything but extraction this way);
    /// `extraction_ms` goes into the record.
    pub fn process_features(
        &mut self,
        index: usize,
        timestamp: f64,
        features: StereoFeatures,
        left: GrayImageView<'_>,
        right: GrayImageView<'_>,
        extraction_ms: f64,
    ) -> Result<&FrameRecord, SlamError> {
        self.poll_mapping()?;
        let (frame, stereo_ms) = self
            .frontend
            .match_frame(index, timestamp, features, left, right, &self.rig)?;
        let stereo_points = frame.stereo_count();
        let queue = match &self.mapping {
            Mapping::Thread { thread, .. } => thread.pending(),
            _ => 0,
        };
        if queue > 0 {
            tracing::debug!(frame = index, queue, "local mapping busy");
        }
        let mut map = self.map.write().map_err(|_| SlamError::PoisonedMap)?;
        let start = Instant::now();
        let outcome = self.tracker.track(frame, &mut map, queue)?;
        let tracking_ms = start.elapsed().as_secs_f64() * 1e3;
        let mut mapping = None;
        if let Some((kf, created)) = &outcome.new_keyframe {
            match &mut self.mapping {
                Mapping::Inline(mapper) => {
                    mapping = Some(mapper.process_keyframe(&mut map, *kf, created)?);
                }
                Mapping::Thread { thread, waiting } => {
                    drop(map);
                    thread.submit(*kf, created.clone())?;
                    waiting.insert(*kf, self.records.len());
                }
                Mapping::Switching => {}
            }
        } else {
            drop(map);
        }
        let mapping_ms = mapping.as_ref().map_or(0.0, |m| m.elapsed_ms);
        self.records.push(FrameRecord {
            index,
            timestamp,
            state: outcome.state,
            method: outcome.method,
            inliers: outcome.inliers,
            stereo_points,
            keyframe: outcome.new_keyframe.is_some(),
            relative_pose: outcome.relative_pose,
            timings: FrameTimings {
                extraction_ms,
                stereo_ms,
                tracking_ms,
                mapping_ms,
            },
            mapping,
        });
        let last = self.records.len() - 1;
        Ok(&self.records[last])
    }

    /// The tracking state now.
    pub fn state(&self) -> TrackingState {
        self.tracker.state()
    }

    /// Every processed frame's camera-to-world pose `T_wc`, from its
    /// reference keyframe's current pose. A frame without a pose (before
    /// initialisation, or lost) repeats the previous pose (identity at first).
    pub fn trajectory(&self) -> Result<Vec<(f64, Se3)>, SlamError> {
        let map = self.map.read().map_err(|_| SlamError::PoisonedMap)?;
        let mut previous = Se3::identity();
        let mut out = Vec::with_capacity(self.records.len());
        for record in &self.records {
            if let Some((kf, relative)) = record.relative_pose {
                if let Ok(kf_pose) = map.pose_cw_of(kf) {
                    previous = relative.compose(&kf_pose).inverse();
                }
            }
            out.push((record.timestamp, previous));
        }
        Ok(out)
    }

    /// The live keyframes' `(timestamp, T_wc)`, in creation order.
    pub fn keyframe_trajectory(&self) -> Result<Vec<(f64, Se3)>, SlamError> {
        let map = self.map.read().map_err(|_| SlamError::PoisonedMap)?;
        Ok(map
            .keyframes()
            .map(|kf| (kf.timestamp, kf.pose_wc()))
            .collect())
    }

    /// Totals so far.
    pub fn summary(&self) -> Result<SlamSummary, SlamError> {
        let map = self.map.read().map_err(|_| SlamError::PoisonedMap)?;
        let mut s = SlamSummary {
            frames: self.records.len(),
            keyframes: map.keyframe_count(),
            map_points: map.map_point_count(),
            ..SlamSummary::default()
        };
        let mut sum = FrameTimings::default();
        for r in &self.records {
            match r.state {
                TrackingState::Ok => s.tracked += 1,
                TrackingState::Lost => s.lost += 1,
                TrackingState::NotInitialised => s.not_initialised += 1,
            }
            s.relocalisations += usize::from(r.method == TrackingMethod::Relocalisation);
            s.keyframes_inserted += usize::from(r.keyframe);
            sum.extraction_ms += r.timings.extraction_ms;
            sum.stereo_ms += r.timings.stereo_ms;
            sum.tracking_ms += r.timings.tracking_ms;
            sum.mapping_ms += r.timings.mapping_ms;
        }
        let n = self.records.len().max(1) as f64;
        s.mean_timings = FrameTimings {
            extraction_ms: sum.extraction_ms / n,
            stereo_ms: sum.stereo_ms / n,
            tracking_ms: sum.tracking_ms / n,
            mapping_ms: sum.mapping_ms / n,
        };
        Ok(s)
    }
}
