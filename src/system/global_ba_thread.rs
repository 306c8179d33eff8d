//! The global bundle adjustment's background thread (ORB-SLAM3's
//! `mpThreadGBA`): it snapshots the map, solves with no lock held, and
//! hands the solution back; the system applies it between frames with local
//! mapping paused. A new loop aborts it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

use crate::camera::CameraRig;
use crate::error::SlamError;
use crate::loop_closing::{snapshot_global_ba, solve_global_ba, SolvedGlobalBa};
use crate::map::SharedMap;

/// A running global BA.
#[derive(Debug)]
pub(crate) struct GlobalBaThread {
    /// The map it optimises.
    pub(crate) map: SharedMap,
    abort: Arc<AtomicBool>,
    handle: JoinHandle<Result<Option<SolvedGlobalBa>, SlamError>>,
}

/// Snapshot (read lock) and solve (no lock); `None` for a map too small.
pub(crate) fn run_global_ba(
    map: &SharedMap,
    rig: &CameraRig,
    abort: &AtomicBool,
) -> Result<Option<SolvedGlobalBa>, SlamError> {
    let snapshot = {
        let map = map.read().map_err(|_| SlamError::PoisonedMap)?;
        snapshot_global_ba(&map, rig)
    };
    snapshot.map(|s| solve_global_ba(s, abort)).transpose()
}

impl GlobalBaThread {
    /// Starts a global BA of `map` on its own thread.
    pub(crate) fn spawn(map: SharedMap, rig: CameraRig) -> Result<Self, SlamError> {
        let abort = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&abort);
        let shared = map.clone();
        let handle = std::thread::Builder::new()
            .name("global-ba".into())
            .spawn(move || run_global_ba(&shared, &rig, &flag))
            .map_err(|e| SlamError::MappingThread {
                reason: format!("cannot start the global BA thread: {e}"),
            })?;
        Ok(Self { map, abort, handle })
    }

    /// Whether it has finished.
    pub(crate) fn is_finished(&self) -> bool {
        self.handle.is_finished()
    }

    /// Waits for it and returns its solution.
    pub(crate) fn join(self) -> Result<Option<SolvedGlobalBa>, SlamError> {
        self.handle.join().map_err(|_| SlamError::MappingThread {
            reason: "the global BA thread panicked".into(),
        })?
    }

    /// Aborts it (after its current iteration) and waits; the partial
    /// solution is dropped.
    pub(crate) fn abort(self) {
        self.abort.store(true, Ordering::Release);
        if self.join().is_err() {
            tracing::warn!("the aborted global BA ended with an error");
        }
    }
}
