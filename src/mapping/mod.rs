//! Local mapping (ORB-SLAM3's `LocalMapping`): for each new keyframe,
//! associate its points, cull recent points, triangulate new ones with its
//! covisible keyframes, fuse duplicates, run local bundle adjustment and
//! cull redundant keyframes.
//!
//! [`LocalMapper::process_keyframe`] runs every step on a `&mut Map`; the
//! driver ([`crate::tracking::StereoSlam`]) calls it after each keyframe,
//! holding the shared map's write lock, either inline or on the
//! [`MappingThread`].

mod bundle;
mod fuse;
mod triangulate;
mod worker;

use std::time::Instant;

pub use bundle::{local_bundle_adjustment_around, BundleSummary};
pub use fuse::fuse_with_neighbours;
pub use triangulate::create_new_points;
pub use worker::{MappingResult, MappingThread};

use crate::map::{KeyFrameId, Map, MapPointId, PointCullingReport};
use crate::tracking::{SlamError, StereoRig};

/// Weighted observations a recent stereo point needs after two keyframes (ORB-SLAM3: 3).
const MIN_STEREO_OBSERVATIONS: usize = 3;

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

/// The local-mapping state: the recently created points under probation.
#[derive(Debug)]
pub struct LocalMapper {
    rig: StereoRig,
    recent_points: Vec<MapPointId>,
    /// Run local bundle adjustment (on by default).
    pub bundle_adjustment: bool,
    /// Cull redundant keyframes (on by default).
    pub keyframe_culling: bool,
}

impl LocalMapper {
    /// A mapper for `rig`.
    pub fn new(rig: StereoRig) -> Self {
        Self {
            rig,
            recent_points: Vec::new(),
            bundle_adjustment: true,
            keyframe_culling: true,
        }
    }

    /// Runs every local-mapping step for `keyframe`, which tracking just
    /// inserted with the points in `created`.
    pub fn process_keyframe(
        &mut self,
        map: &mut Map,
        keyframe: KeyFrameId,
        created: &[MapPointId],
    ) -> Result<MappingSummary, SlamError> {
        let start = Instant::now();
        let mut summary = MappingSummary::default();
        if map.keyframe(keyframe).is_err() {
            return Ok(summary);
        }
        // Process the new keyframe: refresh its points, record the new ones.
        let observed: Vec<MapPointId> = map
            .keyframe(keyframe)
            .map(|k| k.observed_points().map(|(_, p)| p).collect())
            .unwrap_or_default();
        for p in observed {
            map.update_descriptor(p);
            map.update_normal_and_depth(p);
        }
        self.recent_points.extend_from_slice(created);
        map.update_connections(keyframe);
        let culled: PointCullingReport =
            map.cull_recent_points(&mut self.recent_points, keyframe, MIN_STEREO_OBSERVATIONS);
        summary.points_culled = culled.low_found_ratio + culled.too_few_observations;
        let mut lap = Instant::now();
        let mut split = || {
            let ms = lap.elapsed().as_secs_f64() * 1e3;
            lap = Instant::now();
            ms
        };
        summary.step_ms.process_ms = start.elapsed().as_secs_f64() * 1e3;
        let triangulated = create_new_points(map, keyframe, &self.rig)?;
        summary.points_triangulated = triangulated.len();
        self.recent_points.extend(triangulated);
        summary.step_ms.triangulation_ms = split();
        summary.fused = fuse_with_neighbours(map, keyframe, &self.rig)?;
        summary.step_ms.fusion_ms = split();
        if self.bundle_adjustment && map.keyframe_count() > 2 {
            summary.bundle = local_bundle_adjustment_around(map, keyframe, &self.rig)?;
        }
        summary.step_ms.bundle_ms = split();
        if self.keyframe_culling {
            summary.keyframes_culled = self.cull_keyframes(map, keyframe)?;
        }
        summary.step_ms.culling_ms = split();
        summary.elapsed_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(summary)
    }

    /// ORB-SLAM3's `KeyFrameCulling` over the keyframe's covisible ones.
    fn cull_keyframes(&self, map: &mut Map, keyframe: KeyFrameId) -> Result<usize, SlamError> {
        let candidates = map.best_covisible(keyframe, usize::MAX);
        let redundant = map.redundant_keyframes(&candidates, Some(self.rig.close_depth));
        let mut culled = 0;
        for kf in redundant {
            if kf != keyframe {
                crate::tracking::MapContext::in_stage(map.erase_keyframe(kf), "keyframe culling")?;
                culled += 1;
            }
        }
        Ok(culled)
    }
}
