//! Local mapping on its own thread, as in ORB-SLAM3: tracking sends each
//! new keyframe through a channel (and raises the BA abort flag when a
//! monocular keyframe is wanted while mapping is busy); the thread
//! runs [`LocalMapper::process_keyframe`] (snapshot → compute → apply, so
//! tracking keeps reading the map meanwhile) and sends back what it did.
//! No `unsafe`: the map is an `Arc<RwLock<Map>>`, the queue an `mpsc`
//! channel and the backlog an atomic counter.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::error::SlamError;
use crate::map::{KeyFrameId, MapPointId, SharedMap};
use crate::mapping::{LocalMapper, MappingSummary, BEFORE_BUNDLE_SHARE};

use super::worker::Worker;

/// The thread's name, in its errors.
const NAME: &str = "local-mapping";

/// A keyframe for the thread, with the points tracking created with it.
#[derive(Debug, Clone)]
pub(crate) struct MappingJob {
    /// The new keyframe.
    pub(crate) keyframe: KeyFrameId,
    /// The points tracking created with it.
    pub(crate) created: Vec<MapPointId>,
}

/// What the thread did with one keyframe.
#[derive(Debug)]
pub struct MappingResult {
    /// The keyframe processed.
    pub keyframe: KeyFrameId,
    /// Its summary, or the error that stopped local mapping.
    pub summary: Result<MappingSummary, SlamError>,
}

/// Local mapping stopped after its current keyframe
/// ([`MappingThread::stop`]): the mapper with its switches, and the
/// keyframes it had not started, in order.
#[derive(Debug)]
pub(crate) struct StoppedMapping {
    /// The mapper, as the thread left it.
    pub(crate) mapper: LocalMapper,
    /// Queued keyframes not processed yet.
    pub(crate) unprocessed: Vec<MappingJob>,
}

/// The local-mapping thread and its queue.
#[derive(Debug)]
pub struct MappingThread {
    jobs: Option<Sender<MappingJob>>,
    results: Receiver<MappingResult>,
    pending: Arc<AtomicUsize>,
    abort: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    worker: Worker<StoppedMapping>,
}

/// The thread's body: maps each job until the queue closes, an error
/// stops it, or a stop is requested (checked between keyframes).
fn run(
    mut mapper: LocalMapper,
    map: SharedMap,
    jobs: Receiver<MappingJob>,
    results: Sender<MappingResult>,
    pending: Arc<AtomicUsize>,
    stop: Arc<AtomicBool>,
) -> StoppedMapping {
    // `pending` counts the job in progress: more than one means tracking
    // has queued another keyframe.
    let waiting = || pending.load(Ordering::Acquire) > 1;
    let mut previous = Duration::ZERO;
    let mut unprocessed = Vec::new();
    while let Ok(job) = jobs.recv() {
        if stop.load(Ordering::Acquire) {
            unprocessed.push(job);
            unprocessed.extend(jobs.try_iter());
            break;
        }
        if mapper.slowdown > 1.0 {
            // The slow-machine hook: wait, so that the work's results (new
            // points, culled keyframes) come late; the part of the wait
            // that stands for a slow BA comes before the BA and ends when
            // tracking interrupts it.
            let wait =
                Duration::try_from_secs_f64(previous.as_secs_f64() * (mapper.slowdown - 1.0))
                    .unwrap_or(Duration::from_secs(1));
            std::thread::sleep(wait.mul_f64(BEFORE_BUNDLE_SHARE));
            mapper.set_wait_before_bundle(wait.mul_f64(1.0 - BEFORE_BUNDLE_SHARE));
        }
        let started = Instant::now();
        let summary = mapper.process_keyframe(&map, job.keyframe, &job.created, &waiting);
        previous = started
            .elapsed()
            .saturating_sub(mapper.waited_before_bundle());
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
    StoppedMapping {
        mapper,
        unprocessed,
    }
}

impl MappingThread {
    /// Starts the thread with `mapper` working on `map`. A failed spawn is
    /// [`SlamError::Thread`].
    pub fn spawn(mapper: LocalMapper, map: SharedMap) -> Result<Self, SlamError> {
        let (job_tx, job_rx) = mpsc::channel();
        let (result_tx, result_rx) = mpsc::channel();
        let pending = Arc::new(AtomicUsize::new(0));
        let counter = Arc::clone(&pending);
        let stop = Arc::new(AtomicBool::new(false));
        let stop_flag = Arc::clone(&stop);
        let abort = mapper.abort_flag();
        let worker = Worker::spawn(NAME, move || {
            run(mapper, map, job_rx, result_tx, counter, stop_flag)
        })?;
        Ok(Self {
            jobs: Some(job_tx),
            results: result_rx,
            pending,
            abort,
            stop,
            worker,
        })
    }

    /// Keyframes sent and not yet processed (the one in progress included).
    pub fn pending(&self) -> usize {
        self.pending.load(Ordering::Acquire)
    }

    /// Raises the BA abort flag (ORB-SLAM3's `InterruptBA`): tracking wants
    /// a monocular keyframe while the mapper is busy, so a running or
    /// coming local BA of the keyframe in service stops.
    pub fn interrupt_bundle_adjustment(&self) {
        self.abort.store(true, Ordering::Release);
    }

    /// Queues a keyframe. Unlike ORB-SLAM3's `InsertKeyFrame`, it leaves a
    /// running local BA alone: tracking interrupts it where it needs to
    /// ([`Self::interrupt_bundle_adjustment`]); the mapper still skips the
    /// BA of a keyframe with another queued behind it before its BA begins.
    /// A thread that has stopped is an error with the reason it stopped
    /// (its panic's message), or saying that an earlier keyframe failed.
    pub fn submit(
        &mut self,
        keyframe: KeyFrameId,
        created: Vec<MapPointId>,
    ) -> Result<(), SlamError> {
        self.pending.fetch_add(1, Ordering::AcqRel);
        let sent = match self.jobs.as_ref() {
            Some(jobs) => jobs.send(MappingJob { keyframe, created }).is_ok(),
            None => false,
        };
        if sent {
            return Ok(());
        }
        self.pending.fetch_sub(1, Ordering::AcqRel);
        Err(match self.worker.join() {
            Ok(_) => self
                .worker
                .error("it is no longer running (an earlier keyframe failed)"),
            Err(e) => e,
        })
    }

    /// The results that arrived so far, without waiting. A thread that
    /// stopped without reporting an error (it panicked) is an error here.
    pub fn poll(&mut self) -> Result<Vec<MappingResult>, SlamError> {
        let results: Vec<MappingResult> = self.results.try_iter().collect();
        let reported_error = results.iter().any(|r| r.summary.is_err());
        if self.worker.is_finished() && !reported_error {
            return Err(match self.worker.join() {
                Ok(_) => self.worker.error("it stopped unexpectedly"),
                Err(e) => e,
            });
        }
        Ok(results)
    }

    /// Waits for every queued keyframe, stops the thread and returns the
    /// mapper with the remaining results.
    pub fn finish(self) -> Result<(LocalMapper, Vec<MappingResult>), SlamError> {
        let (stopped, results) = self.close()?;
        Ok((stopped.mapper, results))
    }

    /// ORB-SLAM3's `RequestStop`: the thread finishes the keyframe in
    /// progress (its local BA told to abort) and stops; the keyframes it
    /// had not started come back, to be queued again on resuming.
    pub(crate) fn stop(self) -> Result<(StoppedMapping, Vec<MappingResult>), SlamError> {
        self.stop.store(true, Ordering::Release);
        self.abort.store(true, Ordering::Release);
        self.close()
    }

    /// Closes the queue and joins the thread.
    fn close(mut self) -> Result<(StoppedMapping, Vec<MappingResult>), SlamError> {
        drop(self.jobs.take());
        let stopped = self.worker.join()?;
        Ok((stopped, self.results.try_iter().collect()))
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
            matches!(&error, SlamError::Thread { name: "local-mapping", reason } if reason.contains("planted panic")),
            "{error}"
        );
        // Later keyframes are refused, not silently dropped.
        assert!(thread.submit(keyframes[1].0, Vec::new()).is_err());
    }

    #[test]
    fn a_stop_finishes_the_current_keyframe_and_returns_the_unstarted_ones() {
        let world = PointWorld::new(21, 600, (12.0, 4.0, 4.0, 30.0));
        let (map, keyframes) = world.keyframe_chain(3);
        let mut mapper = LocalMapper::new(world.rig);
        mapper.keyframe_culling = false;
        let (started_tx, started_rx) = std::sync::mpsc::channel();
        let started_tx = std::sync::Mutex::new(started_tx);
        mapper.set_before_solve(Some(Arc::new(move || {
            if let Ok(tx) = started_tx.lock() {
                let _ = tx.send(());
            }
            // Long enough for the test to request the stop meanwhile.
            std::thread::sleep(Duration::from_millis(300));
        })));
        let mut thread =
            MappingThread::spawn(mapper, map.into_shared()).unwrap_or_else(|e| panic!("{e}"));
        // Alone in the queue, the first keyframe gets its BA (a keyframe
        // with others waiting skips it); the rest arrive during that BA.
        thread
            .submit(keyframes[2].0, Vec::new())
            .unwrap_or_else(|e| panic!("{e}"));
        started_rx
            .recv_timeout(Duration::from_secs(60))
            .unwrap_or_else(|e| panic!("the first keyframe never reached its BA: {e}"));
        for (kf, _) in keyframes[..2].iter().rev() {
            thread
                .submit(*kf, Vec::new())
                .unwrap_or_else(|e| panic!("{e}"));
        }
        let (stopped, results) = thread.stop().unwrap_or_else(|e| panic!("{e}"));
        let done: Vec<_> = results.iter().map(|r| r.keyframe).collect();
        let left: Vec<_> = stopped.unprocessed.iter().map(|j| j.keyframe).collect();
        assert_eq!(
            done,
            vec![keyframes[2].0],
            "the keyframe in progress is finished"
        );
        assert!(results[0].summary.is_ok());
        assert_eq!(
            left,
            vec![keyframes[1].0, keyframes[0].0],
            "the rest wait, in order"
        );
        // The mapper keeps its switches.
        assert!(!stopped.mapper.keyframe_culling);
    }
}
