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
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::Arc;

use crate::camera::CameraRig;
use crate::error::SlamError;
use crate::map::{KeyFrameId, SharedMap};

use super::loop_closing_stage::{DetectStep, LoopClosingStage};
use super::worker::Worker;

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
    worker: Worker<LoopClosingStage>,
    /// Set while the thread checks a keyframe (for the frame records).
    checking: Arc<AtomicBool>,
}

/// The channels and the flag the thread's body works with.
struct Links {
    jobs: Receiver<LoopJob>,
    findings: Sender<LoopFinding>,
    checking: Arc<AtomicBool>,
}

/// One check of the stage's next keyframe, with `checking` set meanwhile.
fn check_next(
    stage: &mut LoopClosingStage,
    maps: &AtlasView,
    rig: &CameraRig,
    checking: &AtomicBool,
) -> Result<DetectStep, SlamError> {
    checking.store(true, Ordering::Relaxed);
    let step = stage.detect_next(&maps.active, &maps.others, rig);
    checking.store(false, Ordering::Relaxed);
    step
}

fn run(
    mut stage: LoopClosingStage,
    rig: CameraRig,
    queued: AtlasView,
    links: Links,
) -> LoopClosingStage {
    let Links {
        jobs,
        findings,
        checking,
    } = links;
    // Keyframes queued before a correction are checked first, on the
    // maps as they are after it.
    let mut holding = false;
    while stage.has_queued() && !holding {
        let step = check_next(&mut stage, &queued, &rig, &checking);
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
        let step = check_next(&mut stage, &job.maps, &rig, &checking);
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
        let checking = Arc::new(AtomicBool::new(false));
        let links = Links {
            jobs: job_rx,
            findings: finding_tx,
            checking: Arc::clone(&checking),
        };
        let worker = Worker::spawn("loop-closing", move || run(stage, rig, maps, links))?;
        Ok(Self {
            jobs: Some(job_tx),
            findings: finding_rx,
            worker,
            checking,
        })
    }

    /// Whether the thread is checking a keyframe (retrieval and candidate
    /// verification) right now.
    pub(crate) fn is_checking(&self) -> bool {
        self.checking.load(Ordering::Relaxed)
    }

    /// Queues a keyframe of `maps.active` for the check. A thread that has
    /// stopped is an error with the reason it stopped (its panic's message).
    pub(crate) fn submit(
        &mut self,
        keyframe: KeyFrameId,
        maps: AtlasView,
    ) -> Result<(), SlamError> {
        let sent = match self.jobs.as_ref() {
            Some(jobs) => jobs.send(LoopJob { keyframe, maps }).is_ok(),
            None => false,
        };
        if sent {
            return Ok(());
        }
        Err(match self.worker.join() {
            Ok(_) => self.worker.error("it is no longer running"),
            Err(e) => e,
        })
    }

    /// The findings that arrived so far, without waiting. A thread that
    /// stopped by itself (it panicked) is an error with its message.
    pub(crate) fn poll(&mut self) -> Result<Vec<LoopFinding>, SlamError> {
        let findings: Vec<LoopFinding> = self.findings.try_iter().collect();
        if self.worker.is_finished() {
            return Err(match self.worker.join() {
                Ok(_) => self.worker.error("it stopped unexpectedly"),
                Err(e) => e,
            });
        }
        Ok(findings)
    }

    /// Lets the thread check what it has received (unless it is holding
    /// for a correction), stops it and returns the stage, with the
    /// findings not polled yet.
    pub(crate) fn finish(mut self) -> Result<(LoopClosingStage, Vec<LoopFinding>), SlamError> {
        drop(self.jobs.take());
        let stage = self.worker.join()?;
        Ok((stage, self.findings.try_iter().collect()))
    }
}
