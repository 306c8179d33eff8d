//! Local mapping on its own thread, as in ORB-SLAM3: tracking sends each
//! new keyframe through a channel, the thread runs
//! [`LocalMapper::process_keyframe`] under the shared map's write lock and
//! sends back what it did. No `unsafe`: the map is an `Arc<RwLock<Map>>`,
//! the queue an `mpsc` channel and the backlog an atomic counter.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;

use crate::map::{KeyFrameId, MapPointId, SharedMap};
use crate::tracking::SlamError;

use super::{LocalMapper, MappingSummary};

/// A keyframe for the thread, with the points tracking created with it.
struct MappingJob {
    keyframe: KeyFrameId,
    created: Vec<MapPointId>,
}

/// What the thread did with one keyframe.
#[derive(Debug)]
pub struct MappingResult {
    /// The keyframe processed.
    pub keyframe: KeyFrameId,
    /// Its summary, or the error that stopped local mapping.
    pub summary: Result<MappingSummary, SlamError>,
}

/// The local-mapping thread and its queue.
#[derive(Debug)]
pub struct MappingThread {
    jobs: Option<Sender<MappingJob>>,
    results: Receiver<MappingResult>,
    pending: Arc<AtomicUsize>,
    handle: Option<JoinHandle<LocalMapper>>,
}

fn run(
    mut mapper: LocalMapper,
    map: SharedMap,
    jobs: Receiver<MappingJob>,
    results: Sender<MappingResult>,
    pending: Arc<AtomicUsize>,
) -> LocalMapper {
    for job in jobs {
        let summary = match map.write() {
            Ok(mut map) => mapper.process_keyframe(&mut map, job.keyframe, &job.created),
            Err(_) => Err(SlamError::PoisonedMap),
        };
        let failed = summary.is_err();
        pending.fetch_sub(1, Ordering::AcqRel);
        let sent = results.send(MappingResult {
            keyframe: job.keyframe,
            summary,
        });
        if failed || sent.is_err() {
            break;
        }
    }
    mapper
}

impl MappingThread {
    /// Starts the thread with `mapper` working on `map`.
    pub fn spawn(mapper: LocalMapper, map: SharedMap) -> Result<Self, SlamError> {
        let (job_tx, job_rx) = mpsc::channel();
        let (result_tx, result_rx) = mpsc::channel();
        let pending = Arc::new(AtomicUsize::new(0));
        let counter = Arc::clone(&pending);
        let handle = std::thread::Builder::new()
            .name("local-mapping".into())
            .spawn(move || run(mapper, map, job_rx, result_tx, counter))
            .map_err(|e| SlamError::MappingThread {
                reason: format!("cannot start it: {e}"),
            })?;
        Ok(Self {
            jobs: Some(job_tx),
            results: result_rx,
            pending,
            handle: Some(handle),
        })
    }

    /// Keyframes sent and not yet processed (the one in progress included).
    pub fn pending(&self) -> usize {
        self.pending.load(Ordering::Acquire)
    }

    /// Queues a keyframe.
    pub fn submit(&self, keyframe: KeyFrameId, created: Vec<MapPointId>) -> Result<(), SlamError> {
        let stopped = || SlamError::MappingThread {
            reason: "it is no longer running (an earlier keyframe failed)".into(),
        };
        let jobs = self.jobs.as_ref().ok_or_else(stopped)?;
        self.pending.fetch_add(1, Ordering::AcqRel);
        jobs.send(MappingJob { keyframe, created }).map_err(|_| {
            self.pending.fetch_sub(1, Ordering::AcqRel);
            stopped()
        })
    }

    /// The results that arrived so far, without waiting.
    pub fn poll(&self) -> Vec<MappingResult> {
        self.results.try_iter().collect()
    }

    /// Waits for every queued keyframe, stops the thread and returns the
    /// mapper with the remaining results.
    pub fn finish(mut self) -> Result<(LocalMapper, Vec<MappingResult>), SlamError> {
        drop(self.jobs.take());
        let handle = self.handle.take().ok_or_else(|| SlamError::MappingThread {
            reason: "it was already stopped".into(),
        })?;
        let mapper = handle.join().map_err(|_| SlamError::MappingThread {
            reason: "it panicked".into(),
        })?;
        Ok((mapper, self.results.try_iter().collect()))
    }
}
