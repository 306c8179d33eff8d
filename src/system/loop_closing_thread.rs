//! Loop detection on its own thread (ORB-SLAM3's `LoopClosing::Run`): the
//! system sends every keyframe local mapping has processed, with the
//! active map and the older maps of the atlas; the thread checks it for a
//! loop or a merge ([`LoopClosingStage::detect_next`], read locks only)
//! and sends back what it found, so tracking and local mapping go on
//! meanwhile.
//!
//! Once it has found something to correct, it stops checking (it only
//! queues the keyframes that keep arriving) until the system takes the
//! stage back ([`LoopClosingThread::finish`]), corrects the map on its own
//! thread with local mapping paused, and starts a new thread on the stage,
//! which then checks the queued keyframes first.

use std::collections::BTreeMap;
use std::sync::mpsc::{self, Receiver, Sender};
use std::thread::JoinHandle;

use crate::camera::CameraRig;
use crate::error::SlamError;
use crate::map::{KeyFrameId, SharedMap};

use super::loop_closing_stage::{DetectStep, LoopClosingStage};

/// A keyframe to check, with the maps it is checked against.
struct LoopJob {
    keyframe: KeyFrameId,
    maps: AtlasView,
}

/// The active map and the older maps it may merge with (atlas index → map).
#[derive(Debug, Clone)]
pub(crate) struct AtlasView {
    /// The map the keyframes are in.
    pub(crate) active: SharedMap,
    /// The maps not merged yet, the active one excepted.
    pub(crate) others: BTreeMap<usize, SharedMap>,
}

/// What one check gave, with the maps it was made on.
#[derive(Debug)]
pub(crate) struct LoopFinding {
    /// The check's outcome.
    pub(crate) step: Result<DetectStep, SlamError>,
    /// The maps it used.
    pub(crate) maps: AtlasView,
}

impl LoopFinding {
    /// Whether the system must take the stage back: something to correct,
    /// or an error.
    pub(crate) fn needs_stage(&self) -> bool {
        !matches!(&self.step, Ok(step) if step.detection.is_none())
    }
}

/// The loop-detection thread.
#[derive(Debug)]
pub(crate) struct LoopClosingThread {
    jobs: Option<Sender<LoopJob>>,
    findings: Receiver<LoopFinding>,
    handle: Option<JoinHandle<LoopClosingStage>>,
}

fn run(
    mut stage: LoopClosingStage,
    rig: CameraRig,
    queued: AtlasView,
    jobs: Receiver<LoopJob>,
    findings: Sender<LoopFinding>,
) -> LoopClosingStage {
    // Keyframes queued before a correction are checked first, on the
    // maps as they are after it.
    let mut holding = false;
    while stage.has_queued() && !holding {
        let step = stage.detect_next(&queued.active, &queued.others, &rig);
        let finding = LoopFinding {
            step,
            maps: queued.clone(),
        };
        holding = finding.needs_stage();
        if findings.send(finding).is_err() {
            return stage;
        }
    }
    for job in jobs {
        stage.push(job.keyframe);
        if holding {
            continue;
        }
        let step = stage.detect_next(&job.maps.active, &job.maps.others, &rig);
        let finding = LoopFinding {
            step,
            maps: job.maps,
        };
        holding = finding.needs_stage();
        if findings.send(finding).is_err() {
            break;
        }
    }
    stage
}

impl LoopClosingThread {
    /// Starts the thread on `stage`; keyframes already queued in it are
    /// checked first, against `maps`.
    pub(crate) fn spawn(
        stage: LoopClosingStage,
        rig: CameraRig,
        maps: AtlasView,
    ) -> Result<Self, SlamError> {
        let (job_tx, job_rx) = mpsc::channel();
        let (finding_tx, finding_rx) = mpsc::channel();
        let handle = std::thread::Builder::new()
            .name("loop-closing".into())
            .spawn(move || run(stage, rig, maps, job_rx, finding_tx))
            .map_err(|e| SlamError::MappingThread {
                reason: format!("cannot start the loop-closing thread: {e}"),
            })?;
        Ok(Self {
            jobs: Some(job_tx),
            findings: finding_rx,
            handle: Some(handle),
        })
    }

    /// Queues a keyframe of `maps.active` for the check.
    pub(crate) fn submit(&self, keyframe: KeyFrameId, maps: AtlasView) -> Result<(), SlamError> {
        let stopped = || SlamError::MappingThread {
            reason: "the loop-closing thread is no longer running (it panicked)".into(),
        };
        let jobs = self.jobs.as_ref().ok_or_else(stopped)?;
        jobs.send(LoopJob { keyframe, maps }).map_err(|_| stopped())
    }

    /// The findings that arrived so far, without waiting. A thread that
    /// stopped by itself (it panicked) is an error.
    pub(crate) fn poll(&mut self) -> Result<Vec<LoopFinding>, SlamError> {
        let findings: Vec<LoopFinding> = self.findings.try_iter().collect();
        if self.handle.as_ref().is_some_and(|h| h.is_finished()) {
            return Err(SlamError::MappingThread {
                reason: "the loop-closing thread stopped unexpectedly (it panicked)".into(),
            });
        }
        Ok(findings)
    }

    /// Lets the thread check what it has received (unless it is holding
    /// for a correction), stops it and returns the stage, with the
    /// findings not polled yet.
    pub(crate) fn finish(mut self) -> Result<(LoopClosingStage, Vec<LoopFinding>), SlamError> {
        drop(self.jobs.take());
        let handle = self.handle.take().ok_or_else(|| SlamError::MappingThread {
            reason: "the loop-closing thread was already stopped".into(),
        })?;
        let stage = handle.join().map_err(|_| SlamError::MappingThread {
            reason: "the loop-closing thread panicked".into(),
        })?;
        Ok((stage, self.findings.try_iter().collect()))
    }
}
