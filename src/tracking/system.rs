//! The stereo SLAM driver: front end, tracking and local mapping over one
//! shared map. Local mapping runs on the calling thread right after each
//! new keyframe; it only needs the [`SharedMap`], so it can move to its own
//! thread (fed a channel of keyframe ids) without changing the steps.

use std::time::Instant;

use crate::features::GrayImageView;
use crate::map::{KeyFrameId, Map, SharedMap};
use crate::mapping::{LocalMapper, MappingSummary};
use crate::optim::{LieGroup, Se3};

use super::error::SlamError;
use super::frontend::StereoFrontend;
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

/// Stereo SLAM over a sequence of rectified pairs.
pub struct StereoSlam {
    rig: StereoRig,
    frontend: StereoFrontend,
    tracker: Tracker,
    mapper: LocalMapper,
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
            mapper: LocalMapper::new(rig),
            map: Map::new().into_shared(),
            records: Vec::new(),
        }
    }

    /// The shared map.
    pub fn map(&self) -> &SharedMap {
        &self.map
    }

    /// The local mapper (to switch BA or culling off).
    pub fn mapper_mut(&mut self) -> &mut LocalMapper {
        &mut self.mapper
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
        let (frame, frontend) = self
            .frontend
            .build_frame(index, timestamp, left, right, &self.rig)?;
        let stereo_points = frame.stereo_count();
        let mut map = self.map.write().map_err(|_| SlamError::PoisonedMap)?;
        let start = Instant::now();
        let outcome = self.tracker.track(frame, &mut map, true)?;
        let tracking_ms = start.elapsed().as_secs_f64() * 1e3;
        let mut mapping = None;
        if let Some((kf, created)) = &outcome.new_keyframe {
            mapping = Some(self.mapper.process_keyframe(&mut map, *kf, created)?);
        }
        drop(map);
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
                extraction_ms: frontend.extraction_ms,
                stereo_ms: frontend.stereo_ms,
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
