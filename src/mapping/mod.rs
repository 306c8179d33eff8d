//! Local mapping (ORB-SLAM3's `LocalMapping`): for each new keyframe,
//! associate its points, cull recent points, triangulate new ones with its
//! covisible keyframes, fuse duplicates, run local bundle adjustment and
//! cull redundant keyframes.
//!
//! [`LocalMapper::process_keyframe`] works on the [`SharedMap`] as
//! snapshot → compute → apply for each step: it reads under the read lock
//! (tracking reads alongside), computes with no lock held where the work is
//! heavy (the BA solve), and writes the result under a short write lock,
//! skipping entities culled or fused in the meantime. The driver
//! ([`crate::system::SlamSystem`]) calls it inline or on its thread.

mod bundle;
mod bundle_problem;
mod fuse;
mod triangulate;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, RwLockReadGuard, RwLockWriteGuard};
use std::time::{Duration, Instant};

pub use bundle::{BundleSummary, MAX_FIXED_KEYFRAMES, MAX_LOCAL_KEYFRAMES};
pub(crate) use bundle_problem::build_map_bundle;
pub(crate) use fuse::{apply_fusion_candidates, plan_fusion_into};

use crate::camera::CameraRig;
use crate::error::{MapContext, SlamError};
use crate::map::{KeyFrameId, Map, MapPointId, PointCullingReport, SharedMap};
use bundle::{apply_bundle, snapshot_bundle, solve_bundle};
use fuse::{apply_fusion, plan_fusion};
use triangulate::{apply_new_points, plan_new_points};

/// Weighted observations a recent stereo point needs after two keyframes (ORB-SLAM3: 3).
const MIN_STEREO_OBSERVATIONS: usize = 3;
/// The same for a monocular point (ORB-SLAM3's `MapPointCulling`: 2).
const MIN_MONO_OBSERVATIONS: usize = 2;

/// What local mapping did for one keyframe.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct MappingSummary {
    /// Recent points erased (low found ratio or too few observations).
    pub points_culled: usize,
    /// Points created by triangulation.
    pub points_triangulated: usize,
    /// Points fused or observations added by fusion.
    pub fused: usize,
    /// The local BA.
    pub bundle: BundleSummary,
    /// Keyframes culled as redundant.
    pub keyframes_culled: usize,
    /// Fusion, BA and culling were left to the next keyframe, which
    /// tracking had already queued (ORB-SLAM3's `CheckNewKeyFrames`).
    pub skipped_for_queue: bool,
    /// Milliseconds spent, all steps.
    pub elapsed_ms: f64,
    /// Milliseconds per step.
    pub step_ms: MappingStepTimes,
}

/// Milliseconds spent in each local-mapping step for one keyframe.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct MappingStepTimes {
    /// Refreshing the keyframe's points, connections, culling recent points.
    pub process_ms: f64,
    /// Triangulation with the covisible keyframes.
    pub triangulation_ms: f64,
    /// Fusion of duplicates.
    pub fusion_ms: f64,
    /// Local bundle adjustment.
    pub bundle_ms: f64,
    /// Keyframe culling.
    pub culling_ms: f64,
}

/// Recomputes the descriptor, normal and distances of every point
/// `keyframe` observes (after it gained or fused observations).
pub(crate) fn refresh_observed_points(map: &mut Map, keyframe: KeyFrameId) {
    let observed: Vec<MapPointId> = map
        .keyframe(keyframe)
        .map(|k| k.observed_points().map(|(_, p)| p).collect())
        .unwrap_or_default();
    for p in observed {
        map.update_descriptor(p);
        map.update_normal_and_depth(p);
    }
}

/// A hook run just before the BA solve, with no lock held (tests hold the
/// solve there to show that tracking goes on meanwhile).
pub type SolveHook = Arc<dyn Fn() + Send + Sync>;

/// The local-mapping state: the recently created points under probation.
pub struct LocalMapper {
    rig: CameraRig,
    recent_points: Vec<MapPointId>,
    abort: Arc<AtomicBool>,
    before_solve: Option<SolveHook>,
    /// Run local bundle adjustment (on by default).
    pub bundle_adjustment: bool,
    /// Cull redundant keyframes (on by default).
    pub keyframe_culling: bool,
    /// Check the map's invariants after each keyframe's local mapping and
    /// fail with [`SlamError::MapInvariant`] (on in debug builds; tests
    /// switch it on). The check walks the whole map, so it runs once per
    /// keyframe unless [`Self::check_invariants_each_step`] asks for more.
    pub check_invariants: bool,
    /// With [`Self::check_invariants`], check after every step (keyframe
    /// processing, triangulation, fusion, BA, culling) instead of once per
    /// keyframe, so that a violation names the step that made it. Off by
    /// default: five whole-map walks per keyframe took 17 % of a 500-frame
    /// test run.
    pub check_invariants_each_step: bool,
    /// A test hook that reproduces a slow or busy machine: on the mapping
    /// thread, each keyframe waits (slowdown − 1) × the previous
    /// keyframe's processing time, 40 % of it before its processing starts
    /// and 60 % before its local BA ([`BEFORE_BUNDLE_SHARE`]; tracking's
    /// interrupt cuts the second part short, and the BA then does the
    /// share of its iterations the wait had reached, as a slow BA would:
    /// [`Self::set_bundle_share`]), so local mapping keeps up `slowdown`
    /// times more slowly. 1 (the default) is off; inline mapping ignores
    /// it.
    pub slowdown: f64,
    /// The slow-machine hook's wait before the next local BA (see
    /// [`Self::set_wait_before_bundle`]).
    wait_before_bundle: Duration,
    /// How long the last keyframe waited before its BA.
    waited_before_bundle: Duration,
    /// The share of its iterations the next keyframe's local BA gets (see
    /// [`Self::set_bundle_share`]); 1 outside the slow-machine hooks.
    bundle_share: f64,
}

/// The share of a keyframe's mapping time spent before its local BA
/// (processing, triangulation, fusion): SuperPoint + ANMS at 480×360,
/// 42 of 107 ms per keyframe (BA 65 ms). The slow-machine hooks split
/// their delay by it, so that an interrupted BA ends the delay early.
pub const BEFORE_BUNDLE_SHARE: f64 = 0.4;

impl std::fmt::Debug for LocalMapper {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LocalMapper")
            .field("recent_points", &self.recent_points.len())
            .field("bundle_adjustment", &self.bundle_adjustment)
            .field("keyframe_culling", &self.keyframe_culling)
            .field("check_invariants", &self.check_invariants)
            .field(
                "check_invariants_each_step",
                &self.check_invariants_each_step,
            )
            .field("slowdown", &self.slowdown)
            .field("wait_before_bundle", &self.wait_before_bundle)
            .finish_non_exhaustive()
    }
}

fn read(map: &SharedMap) -> Result<RwLockReadGuard<'_, Map>, SlamError> {
    map.read().map_err(|_| SlamError::PoisonedMap)
}

/// [`Map::check_invariants`], its violation named by the step that ran last.
fn check_map(map: &Map, stage: &'static str) -> Result<(), SlamError> {
    map.check_invariants()
        .map_err(|source| SlamError::MapInvariant { stage, source })
}

fn write(map: &SharedMap) -> Result<RwLockWriteGuard<'_, Map>, SlamError> {
    map.write().map_err(|_| SlamError::PoisonedMap)
}

impl LocalMapper {
    /// Observations a recent point needs to survive, by sensor.
    fn min_point_observations(&self) -> usize {
        if self.rig.sensor == crate::camera::Sensor::Monocular {
            MIN_MONO_OBSERVATIONS
        } else {
            MIN_STEREO_OBSERVATIONS
        }
    }

    /// A mapper for `rig`.
    pub fn new(rig: CameraRig) -> Self {
        Self {
            rig,
            recent_points: Vec::new(),
            abort: Arc::new(AtomicBool::new(false)),
            before_solve: None,
            bundle_adjustment: true,
            keyframe_culling: true,
            check_invariants: cfg!(debug_assertions),
            check_invariants_each_step: false,
            slowdown: 1.0,
            wait_before_bundle: Duration::ZERO,
            waited_before_bundle: Duration::ZERO,
            bundle_share: 1.0,
        }
    }

    /// The same switches, with no state (for a new map).
    pub fn fresh(&self) -> Self {
        Self {
            rig: self.rig,
            recent_points: Vec::new(),
            abort: Arc::clone(&self.abort),
            before_solve: self.before_solve.clone(),
            bundle_adjustment: self.bundle_adjustment,
            keyframe_culling: self.keyframe_culling,
            check_invariants: self.check_invariants,
            check_invariants_each_step: self.check_invariants_each_step,
            slowdown: self.slowdown,
            wait_before_bundle: Duration::ZERO,
            waited_before_bundle: Duration::ZERO,
            bundle_share: 1.0,
        }
    }

    /// The BA abort flag (ORB-SLAM3's `mbAbortBA`): raising it makes a
    /// running local BA return after its current LM iteration. The driver
    /// raises it when tracking asks (a monocular keyframe wanted while
    /// mapping is busy) and when it stops the mapping thread; the mapper
    /// lowers it after triangulation.
    pub fn abort_flag(&self) -> Arc<AtomicBool> {
        Arc::clone(&self.abort)
    }

    /// The slow-machine hook (see [`Self::slowdown`]): the next keyframe's
    /// local BA starts only after `wait`, a wait that ends early when
    /// tracking raises the abort flag, as a slow BA would be cut short
    /// (ORB-SLAM3's `InterruptBA`). It applies to the next keyframe only,
    /// and is dropped if that keyframe skips its BA.
    pub fn set_wait_before_bundle(&mut self, wait: Duration) {
        self.wait_before_bundle = wait;
    }

    /// The slow-machine hooks' interrupted BA: the next keyframe's local
    /// BA does only the first `share` (0–1) of its iterations, as a BA
    /// that a slow machine runs and tracking interrupts after that share
    /// of its time keeps the iterations it finished (ORB-SLAM3's
    /// `InterruptBA` stops g2o after its current iteration and the
    /// optimised state is applied). It applies to the next keyframe only.
    /// The lagged inline mapper sets it from the frame of the interrupt;
    /// on the thread the wait before the BA gives it
    /// ([`Self::set_wait_before_bundle`]).
    pub fn set_bundle_share(&mut self, share: f64) {
        self.bundle_share = share.clamp(0.0, 1.0);
    }

    /// How long the last keyframe waited before its BA (the hook's wait
    /// is not the mapper's own work).
    pub fn waited_before_bundle(&self) -> Duration {
        self.waited_before_bundle
    }

    /// Sleeps for the hook's wait before BA, in short slices, until it has
    /// passed or the abort flag is raised; returns the share of the wait
    /// that passed (1 without a wait).
    fn wait_before_bundle_unless_aborted(&mut self, wait: Duration) -> f64 {
        if wait.is_zero() {
            return 1.0;
        }
        let start = Instant::now();
        let end = start + wait;
        while !self.abort.load(Ordering::Acquire) {
            let now = Instant::now();
            if now >= end {
                break;
            }
            std::thread::sleep((end - now).min(Duration::from_millis(2)));
        }
        self.waited_before_bundle = start.elapsed();
        (self.waited_before_bundle.as_secs_f64() / wait.as_secs_f64()).min(1.0)
    }

    /// Runs `hook` before every BA solve, with no lock held.
    pub fn set_before_solve(&mut self, hook: Option<SolveHook>) {
        self.before_solve = hook;
    }

    /// The invariant check after one step, when asked for each step.
    fn checked(&self, map: &Map, stage: &'static str) -> Result<(), SlamError> {
        if self.check_invariants && self.check_invariants_each_step {
            check_map(map, stage)?;
        }
        Ok(())
    }

    /// The invariant check after a keyframe's local mapping, when not
    /// asked for each step.
    fn checked_keyframe(&self, map: &SharedMap) -> Result<(), SlamError> {
        if self.check_invariants && !self.check_invariants_each_step {
            check_map(&*read(map)?, "local mapping")?;
        }
        Ok(())
    }

    /// Runs every local-mapping step for `keyframe`, which tracking just
    /// inserted with the points in `created`. `more_keyframes_waiting`
    /// tells whether tracking has queued another keyframe: then, as
    /// ORB-SLAM3's `LocalMapping::Run`, fusion, BA and keyframe culling
    /// are left to the next keyframe.
    pub fn process_keyframe(
        &mut self,
        map: &SharedMap,
        keyframe: KeyFrameId,
        created: &[MapPointId],
        more_keyframes_waiting: &dyn Fn() -> bool,
    ) -> Result<MappingSummary, SlamError> {
        let summary = self.run_steps(map, keyframe, created, more_keyframes_waiting)?;
        self.checked_keyframe(map)?;
        Ok(summary)
    }

    /// [`Self::process_keyframe`]'s steps, in ORB-SLAM3's order.
    fn run_steps(
        &mut self,
        map: &SharedMap,
        keyframe: KeyFrameId,
        created: &[MapPointId],
        more_keyframes_waiting: &dyn Fn() -> bool,
    ) -> Result<MappingSummary, SlamError> {
        let start = Instant::now();
        self.waited_before_bundle = Duration::ZERO;
        // The slow hook's wait belongs to this keyframe's BA only: a
        // keyframe that skips its BA drops it.
        let wait_before_bundle = std::mem::take(&mut self.wait_before_bundle);
        let mut bundle_share = std::mem::replace(&mut self.bundle_share, 1.0);
        let mut summary = MappingSummary::default();
        let mut lap = Instant::now();
        let mut split = || {
            let ms = lap.elapsed().as_secs_f64() * 1e3;
            lap = Instant::now();
            ms
        };
        // Process the new keyframe: refresh its points, record the new
        // ones, connect it, cull recent points (one short write).
        {
            let mut map = write(map)?;
            if map.keyframe(keyframe).is_err() {
                return Ok(summary);
            }
            refresh_observed_points(&mut map, keyframe);
            self.recent_points.extend_from_slice(created);
            map.update_connections(keyframe);
            let min_observations = self.min_point_observations();
            let culled: PointCullingReport =
                map.cull_recent_points(&mut self.recent_points, keyframe, min_observations);
            summary.points_culled = culled.low_found_ratio + culled.too_few_observations;
            self.checked(&map, "keyframe processing")?;
        }
        summary.step_ms.process_ms = split();
        let planned = plan_new_points(&*read(map)?, keyframe, &self.rig);
        let triangulated = {
            let mut map = write(map)?;
            let created = apply_new_points(&mut map, planned)?;
            self.checked(&map, "triangulation")?;
            created
        };
        summary.points_triangulated = triangulated.len();
        self.recent_points.extend(triangulated);
        summary.step_ms.triangulation_ms = split();
        self.abort.store(false, Ordering::Release);
        if more_keyframes_waiting() {
            summary.skipped_for_queue = true;
            summary.elapsed_ms = start.elapsed().as_secs_f64() * 1e3;
            return Ok(summary);
        }
        let planned = plan_fusion(&*read(map)?, keyframe, &self.rig);
        {
            let mut map = write(map)?;
            summary.fused = apply_fusion(&mut map, keyframe, planned)?;
            self.checked(&map, "fusion")?;
        }
        summary.step_ms.fusion_ms = split();
        // The abort flag stays as tracking left it since triangulation: a
        // keyframe wanted during fusion stops the BA before it begins
        // (ORB-SLAM3 lowers `mbAbortBA` once, after `CreateNewMapPoints`).
        if more_keyframes_waiting() {
            summary.skipped_for_queue = true;
            summary.elapsed_ms = start.elapsed().as_secs_f64() * 1e3;
            return Ok(summary);
        }
        // The hook's wait stands for a slow BA: when tracking interrupts
        // it, the BA keeps the share of its iterations that the wait had
        // reached, and the flag that ended the wait has done its work.
        let waited = self.wait_before_bundle_unless_aborted(wait_before_bundle);
        if waited < 1.0 {
            bundle_share = bundle_share.min(waited);
            self.abort.store(false, Ordering::Release);
        }
        if self.bundle_adjustment {
            let snapshot = {
                let map = read(map)?;
                (map.keyframe_count() > 2)
                    .then(|| snapshot_bundle(&map, keyframe, &self.rig))
                    .flatten()
            };
            if let Some(snapshot) = snapshot {
                if let Some(hook) = &self.before_solve {
                    hook();
                }
                let solved = solve_bundle(snapshot, &self.abort, bundle_share)?;
                let mut map = write(map)?;
                summary.bundle = apply_bundle(&mut map, solved)?;
                self.checked(&map, "local bundle adjustment")?;
            }
        }
        summary.step_ms.bundle_ms = split();
        if self.keyframe_culling {
            let mut map = write(map)?;
            summary.keyframes_culled = self.cull_keyframes(&mut map, keyframe)?;
            self.checked(&map, "keyframe culling")?;
        }
        summary.step_ms.culling_ms = split();
        summary.elapsed_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(summary)
    }

    /// ORB-SLAM3's `KeyFrameCulling` over the keyframe's covisible ones.
    fn cull_keyframes(&self, map: &mut Map, keyframe: KeyFrameId) -> Result<usize, SlamError> {
        let candidates = map.best_covisible(keyframe, usize::MAX);
        // ORB-SLAM3's `KeyFrameCulling` counts only close stereo points,
        // and every point for monocular.
        let close_depth =
            (self.rig.sensor != crate::camera::Sensor::Monocular).then_some(self.rig.close_depth);
        let redundant = map.redundant_keyframes(&candidates, close_depth);
        let mut culled = 0;
        for kf in redundant {
            if kf != keyframe {
                map.erase_keyframe(kf).in_stage("keyframe culling")?;
                culled += 1;
            }
        }
        Ok(culled)
    }
}

#[cfg(test)]
mod stage_tests;
