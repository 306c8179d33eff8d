//! How [`SlamSystem`] runs the global bundle adjustment after a loop
//! correction or a merge (ORB-SLAM3's `RunGlobalBundleAdjustment`): on its
//! own thread when local mapping has one, else inline; applied between
//! frames with local mapping stopped. A global BA that fails (an error or
//! a panic) is reported in [`SlamSystem::global_ba_runs`] and skipped: the
//! map keeps its corrected poses and the run goes on.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::AtomicBool;

use crate::error::SlamError;
use crate::loop_closing::{apply_global_ba, GlobalBaSummary, SolvedGlobalBa};
use crate::map::SharedMap;

use super::global_ba_thread::{run_global_ba, GlobalBaHook, GlobalBaThread};
use super::slam_system::Mapping;
use super::SlamSystem;

impl SlamSystem {
    /// The global BAs run after loop corrections (aborted and failed ones
    /// included).
    pub fn global_ba_runs(&self) -> &[GlobalBaSummary] {
        &self.global_ba_runs
    }

    /// Whether a global BA is under way on its thread (started, not yet
    /// applied).
    pub fn global_ba_running(&self) -> bool {
        self.global_ba.is_some()
    }

    /// Sets a hook run on the global BA's thread before its snapshot
    /// (tests plant a panic there to show that a failed global BA is
    /// reported and skipped); `None` removes it.
    pub fn set_before_global_ba(&mut self, hook: Option<GlobalBaHook>) {
        self.global_ba_hook = hook;
    }

    /// Starts a global BA of the active map now, as after a loop
    /// correction (a running one is aborted first): before saving a map,
    /// for example. With a mapping thread it runs on its own thread and is
    /// applied between later frames, or by [`Self::finish`].
    pub fn request_global_ba(&mut self) -> Result<(), SlamError> {
        self.abort_global_ba();
        let map = self.atlas.active().map.clone();
        self.start_global_ba(&map)
    }

    /// Aborts a running global BA (a new loop, a new map, a reset).
    pub(super) fn abort_global_ba(&mut self) {
        if let Some(running) = self.global_ba.take() {
            running.abort();
            self.global_ba_runs.push(GlobalBaSummary {
                aborted: true,
                ..GlobalBaSummary::default()
            });
        }
    }

    /// Starts the global BA after a correction: on its own thread when
    /// local mapping has one, else right here (deterministic runs).
    pub(super) fn start_global_ba(&mut self, map: &SharedMap) -> Result<(), SlamError> {
        if matches!(self.mapping, Mapping::Thread { .. }) {
            let hook = self.global_ba_hook.clone();
            self.global_ba = Some(GlobalBaThread::spawn(map.clone(), self.rig, hook)?);
            return Ok(());
        }
        let never = AtomicBool::new(false);
        let hook = self.global_ba_hook.as_ref();
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            run_global_ba(map, &self.rig, &never, hook)
        }))
        .unwrap_or_else(|payload| Err(SlamError::thread_panicked("global-ba", payload.as_ref())));
        self.apply_outcome(map, outcome)
    }

    /// Applies a finished global BA, or reports its failure and goes on.
    fn apply_outcome(
        &mut self,
        map: &SharedMap,
        outcome: Result<Option<SolvedGlobalBa>, SlamError>,
    ) -> Result<(), SlamError> {
        match outcome {
            Ok(Some(solved)) => self.apply_global_ba(map, solved),
            Ok(None) => Ok(()),
            Err(e) => {
                tracing::warn!("global BA failed and was skipped: {e}");
                self.global_ba_runs.push(GlobalBaSummary {
                    failure: Some(e.to_string()),
                    ..GlobalBaSummary::default()
                });
                Ok(())
            }
        }
    }

    /// Applies a solved global BA with local mapping stopped.
    fn apply_global_ba(
        &mut self,
        map: &SharedMap,
        solved: SolvedGlobalBa,
    ) -> Result<(), SlamError> {
        self.pause_mapping()?;
        let summary = {
            let mut m = map.write().map_err(|_| SlamError::PoisonedMap)?;
            apply_global_ba(&mut m, solved)
        };
        tracing::info!(
            keyframes = summary.keyframes,
            points = summary.points,
            propagated = summary.propagated_keyframes,
            solve_ms = summary.solve_ms,
            "global BA applied"
        );
        self.global_ba_runs.push(summary);
        self.resume_mapping(map)
    }

    /// Applies the background global BA when it has finished (or, with
    /// `wait`, waits for it).
    pub(super) fn poll_global_ba(&mut self, wait: bool) -> Result<(), SlamError> {
        let Some(running) = self.global_ba.take() else {
            return Ok(());
        };
        if !wait && !running.is_finished() {
            self.global_ba = Some(running);
            return Ok(());
        }
        let map = running.map.clone();
        let outcome = running.join();
        self.apply_outcome(&map, outcome)
    }
}
