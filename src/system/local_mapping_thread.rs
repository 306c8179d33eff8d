//! Local mapping on its own thread, as in ORB-SLAM3: tracking sends each
//! new keyframe through a channel and raises the BA abort flag; the thread
//! runs [`LocalMapper::process_keyframe`] (snapshot → compute → apply, so
//! tracking keeps reading the map meanwhile) and sends back what it did.
//! No `unsafe`: the map is an `Arc<RwLock<Map>>`, the queue an `mpsc`
//! channel and the backlog an atomic counter.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::error::SlamError;
use crate::map::{KeyFrameId, MapPointId, SharedMap};
use crate::mapping::{LocalMapper, MappingSummary};

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
    abort: Arc<AtomicBool>,
    handle: Option<JoinHandle<LocalMapper>>,
}

fn run(
    mut mapper: LocalMapper,
    map: SharedMap,
    jobs: Receiver<MappingJob>,
    results: Sender<MappingResult>,
    pending: Arc<AtomicUsize>,
) -> LocalMapper {
    // `pending` counts the job in progress: more than one means tracking
    // has queued another keyframe.
    let waiting = || pending.load(Ordering::Acquire) > 1;
    let mut previous = Duration::ZERO;
    for job in jobs {
        if mapper.slowdown > 1.0 {
            // The slow-machine hook: wait before the work, so that its
            // results (new points, culled keyframes) come late.
            let wait =
                Duration::try_from_secs_f64(previous.as_secs_f64() * (mapper.slowdown - 1.0));
            std::thread::sleep(wait.unwrap_or(Duration::from_secs(1)));
        }
        let started = Instant::now();
        let summary = mapper.process_keyframe(&map, job.keyframe, &job.created, &waiting);
        previous = started.elapsed();
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

/// The message of a thread's panic payload.
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "no message".into())
}

impl MappingThread {
    /// Starts the thread with `mapper` working on `map`. A failed spawn is
    /// [`SlamError::MappingThread`].
    pub fn spawn(mapper: LocalMapper, map: SharedMap) -> Result<Self, SlamError> {
        let (job_tx, job_rx) = mpsc::channel();
        let (result_tx, result_rx) = mpsc::channel();
        let pending = Arc::new(AtomicUsize::new(0));
        let counter = Arc::clone(&pending);
        let abort = mapper.abort_flag();
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
            abort,
            handle: Some(handle),
        })
    }

    /// Keyframes sent and not yet processed (the one in progress included).
    pub fn pending(&self) -> usize {
        self.pending.load(Ordering::Acquire)
    }

    /// Queues a keyframe and raises the BA abort flag, so a running local
    /// BA yields to it (ORB-SLAM3's `InsertKeyFrame`).
    pub fn submit(&self, keyframe: KeyFrameId, created: Vec<MapPointId>) -> Result<(), SlamError> {
        let stopped = || SlamError::MappingThread {
            reason: "it is no longer running (an earlier keyframe failed or it panicked)".into(),
        };
        let jobs = self.jobs.as_ref().ok_or_else(stopped)?;
        self.pending.fetch_add(1, Ordering::AcqRel);
        self.abort.store(true, Ordering::Release);
        jobs.send(MappingJob { keyframe, created }).map_err(|_| {
            self.pending.fetch_sub(1, Ordering::AcqRel);
            stopped()
        })
    }

    /// The results that arrived so far, without waiting. A thread that
    /// stopped without reporting an error (it panicked) is an error here.
    pub fn poll(&mut self) -> Result<Vec<MappingResult>, SlamError> {
        let results: Vec<MappingResult> = self.results.try_iter().collect();
        let reported_error = results.iter().any(|r| r.summary.is_err());
        let stopped = self.handle.as_ref().is_some_and(|h| h.is_finished());
        if stopped && !reported_error {
            return Err(self.join_failure());
        }
        Ok(results)
    }

    /// Joins a thread that stopped by itself and says why.
    fn join_failure(&mut self) -> SlamError {
        let reason = match self.handle.take().map(JoinHandle::join) {
            Some(Err(payload)) => format!("it panicked: {}", panic_message(payload.as_ref())),
            Some(Ok(_)) => "it stopped unexpectedly".into(),
            None => "it was already stopped".into(),
        };
        SlamError::MappingThread { reason }
    }

    /// Waits for every queued keyframe, stops the thread and returns the
    /// mapper with the remaining results.
    pub fn finish(mut self) -> Result<(LocalMapper, Vec<MappingResult>), SlamError> {
        drop(self.jobs.take());
        let handle = self.handle.take().ok_or_else(|| SlamError::MappingThread {
            reason: "it was already stopped".into(),
        })?;
        let mapper = handle.join().map_err(|payload| SlamError::MappingThread {
            reason: format!("it panicked: {}", panic_message(payload.as_ref())),
        })?;
        Ok((mapper, self.results.try_iter().collect()))
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use std::time::{Duration, Instant};

    use super::MappingThread;
    use crate::error::SlamError;
    use crate::mapping::LocalMapper;
    use crate::test_world::PointWorld;

    #[test]
    fn a_panicking_mapping_thread_is_an_error_the_caller_sees() {
        let world = PointWorld::new(21, 600, (12.0, 4.0, 4.0, 30.0));
        let (map, keyframes) = world.keyframe_chain(3);
        let mut mapper = LocalMapper::new(world.rig);
        mapper.set_before_solve(Some(Arc::new(|| {
            panic!("planted panic before the BA solve")
        })));
        let mut thread =
            MappingThread::spawn(mapper, map.into_shared()).unwrap_or_else(|e| panic!("{e}"));
        thread
            .submit(keyframes[2].0, Vec::new())
            .unwrap_or_else(|e| panic!("{e}"));
        let deadline = Instant::now() + Duration::from_secs(60);
        let error = loop {
            match thread.poll() {
                Err(e) => break e,
                Ok(results) => assert!(results.is_empty(), "the keyframe was mapped"),
            }
            assert!(Instant::now() < deadline, "the panic was never reported");
            std::thread::sleep(Duration::from_millis(10));
        };
        assert!(
            matches!(&error, SlamError::MappingThread { reason } if reason.contains("planted panic")),
            "{error}"
        );
        // Later keyframes are refused, not silently dropped.
        assert!(thread.submit(keyframes[1].0, Vec::new()).is_err());
    }
}
