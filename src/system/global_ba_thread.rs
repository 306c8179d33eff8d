//! The global bundle adjustment's background thread (ORB-SLAM3's
//! `mpThreadGBA`): it snapshots the map, solves with no lock held, and
//! hands the solution back; the system applies it between frames with local
//! mapping paused. A new loop aborts it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use crate::camera::CameraRig;
use crate::error::SlamError;
use crate::loop_closing::{snapshot_global_ba, solve_global_ba, SolvedGlobalBa};
use crate::map::SharedMap;

use super::worker::Worker;

/// A hook run on the global BA's thread before the snapshot (tests plant a
/// panic or a delay there).
pub type GlobalBaHook = Arc<dyn Fn() + Send + Sync>;

/// What the global BA's thread returns.
type GlobalBaOutcome = Result<Option<SolvedGlobalBa>, SlamError>;

/// A running global BA.
#[derive(Debug)]
pub(crate) struct GlobalBaThread {
    /// The map it optimises.
    pub(crate) map: SharedMap,
    abort: Arc<AtomicBool>,
    worker: Worker<GlobalBaOutcome>,
}

/// Snapshot (read lock) and solve (no lock); `None` for a map too small.
pub(crate) fn run_global_ba(
    map: &SharedMap,
    rig: &CameraRig,
    abort: &AtomicBool,
    hook: Option<&GlobalBaHook>,
) -> GlobalBaOutcome {
    if let Some(hook) = hook {
        hook();
    }
    let snapshot = {
        let map = map.read().map_err(|_| SlamError::PoisonedMap)?;
        snapshot_global_ba(&map, rig)
    };
    snapshot.map(|s| solve_global_ba(s, abort)).transpose()
}

impl GlobalBaThread {
    /// Starts a global BA of `map` on its own thread.
    pub(crate) fn spawn(
        map: SharedMap,
        rig: CameraRig,
        hook: Option<GlobalBaHook>,
    ) -> Result<Self, SlamError> {
        let abort = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&abort);
        let shared = map.clone();
        let worker = Worker::spawn("global-ba", move || {
            run_global_ba(&shared, &rig, &flag, hook.as_ref())
        })?;
        Ok(Self { map, abort, worker })
    }

    /// Whether it has finished.
    pub(crate) fn is_finished(&self) -> bool {
        self.worker.is_finished()
    }

    /// Waits for it and returns its solution; its error, or its panic
    /// (as [`SlamError::Thread`] named `global-ba`), is the error.
    pub(crate) fn join(mut self) -> GlobalBaOutcome {
        self.worker.join()?
    }

    /// Aborts it (after its current iteration) and waits; the partial
    /// solution is dropped.
    pub(crate) fn abort(self) {
        self.abort.store(true, Ordering::Release);
        if let Err(e) = self.join() {
            tracing::warn!("the aborted global BA ended with an error: {e}");
        }
    }
}
