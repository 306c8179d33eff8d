//! Relocalisation candidates from the loop-closing keyframe database, as
//! ORB-SLAM3's `KeyFrameDatabase::DetectRelocalizationCandidates`: the lost
//! frame's global descriptor (VLAD of its float descriptors) queries the
//! database that loop detection fills, with nothing excluded, and the best
//! keyframes live in the map are tried by tracking's relocalisation.
//!
//! The database is shared with [`LoopDetector`](super::LoopDetector)
//! ([`SharedKeyframeDatabase`]); it is locked for the query alone, never
//! while tracking matches descriptors: the frame's descriptor is computed
//! before the lock, the candidates are checked against the map after it.

use std::collections::HashSet;
use std::sync::Arc;

use crate::error::SlamError;
use crate::map::{KeyFrameId, Map};
use crate::place::{GlobalDescriptor, QueryOptions};
use crate::tracking::{Frame, RelocalisationCandidates};

use super::detector::{float_rows, read_database, SharedKeyframeDatabase};

/// Candidates a relocalisation query returns, at most.
///
/// ORB-SLAM3's `DetectRelocalizationCandidates` returns every keyframe
/// whose covisibility group scores at least 0.75 of the best group, which
/// is usually a handful, and `Relocalization` tries each. The database
/// here returns the best distinct group representatives; 5 covers the
/// same ground (the current place and a revisit or two, each a group)
/// while bounding the brute-force matching a lost frame costs: each
/// candidate is a descriptor matching against its points and a PnP RANSAC.
pub const RELOCALISATION_CANDIDATES: usize = 5;

/// Covisible keyframes per group in the query (ORB-SLAM3:
/// `GetBestCovisibilityKeyFrames(10)`).
const RELOCALISATION_GROUP_SIZE: usize = 10;

/// Relocalisation candidates from the shared keyframe database (see the
/// module's docs). Set on the tracker by
/// [`SlamSystem::enable_loop_closing`](crate::system::SlamSystem::enable_loop_closing).
pub struct DatabaseRelocaliser {
    descriptor: Arc<dyn GlobalDescriptor>,
    database: SharedKeyframeDatabase,
    n_best: usize,
}

impl std::fmt::Debug for DatabaseRelocaliser {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DatabaseRelocaliser")
            .field("descriptor_dim", &self.descriptor.dim())
            .field("n_best", &self.n_best)
            .finish()
    }
}

impl DatabaseRelocaliser {
    /// Candidates from `database` (the one [`LoopDetector`](super::LoopDetector)
    /// fills: [`shared_database`](super::LoopDetector::shared_database)),
    /// with `descriptor`, the global descriptor its keyframes were
    /// described with; [`RELOCALISATION_CANDIDATES`] per query.
    pub fn new(descriptor: Arc<dyn GlobalDescriptor>, database: SharedKeyframeDatabase) -> Self {
        Self {
            descriptor,
            database,
            n_best: RELOCALISATION_CANDIDATES,
        }
    }

    /// The same with at most `n_best` candidates per query (at least 1).
    pub fn with_candidates(mut self, n_best: usize) -> Self {
        self.n_best = n_best.max(1);
        self
    }

    /// Keyframes in the database now; a poisoned lock is
    /// [`SlamError::PoisonedKeyframeDatabase`].
    pub fn database_len(&self) -> Result<usize, SlamError> {
        Ok(read_database(&self.database)?.len())
    }

    /// The frame's global descriptor; `None` without float descriptors
    /// (an ORB frame: no VLAD codebook applies) or when it fails (warned).
    fn describe(&self, frame: &Frame) -> Option<Vec<f32>> {
        let rows = float_rows(&frame.features.descriptors)?;
        if rows.len() % self.descriptor.local_dim() != 0 {
            tracing::warn!(
                frame = frame.index,
                values = rows.len(),
                local_dim = self.descriptor.local_dim(),
                "relocalisation: the frame's descriptors do not fit the global descriptor"
            );
            return None;
        }
        match self.descriptor.compute_flat(rows) {
            Ok(d) => Some(d),
            Err(e) => {
                tracing::warn!(frame = frame.index, error = %e, "relocalisation: global descriptor failed");
                None
            }
        }
    }
}

impl RelocalisationCandidates for DatabaseRelocaliser {
    /// The database's best keyframes for the frame, live in `map`, best
    /// first; empty when the descriptor or the query fails (warned) or
    /// nothing in the database resembles the frame. `None` (scan the
    /// newest keyframes instead) for a frame without float descriptors and
    /// while the database is empty (the map's first keyframes not yet
    /// through loop detection, or a map begun before loop closing was on).
    fn candidates(&self, frame: &Frame, map: &Map) -> Option<Vec<KeyFrameId>> {
        float_rows(&frame.features.descriptors)?;
        match self.database_len() {
            Ok(0) => return None,
            Ok(_) => {}
            Err(e) => {
                // Loop detection, which shares the lock, reports it as the
                // run's error; here the newest keyframes are scanned instead.
                tracing::error!(frame = frame.index, error = %e, "relocalisation: keyframe database unusable");
                return None;
            }
        }
        let Some(descriptor) = self.describe(frame) else {
            return Some(Vec::new());
        };
        let options = QueryOptions {
            n_best: self.n_best,
            group_size: RELOCALISATION_GROUP_SIZE,
            ..QueryOptions::default()
        };
        let Ok(database) = read_database(&self.database) else {
            tracing::error!(
                frame = frame.index,
                "relocalisation: the keyframe database's lock is poisoned"
            );
            return None;
        };
        let found = database.query(
            &descriptor,
            &HashSet::new(),
            |k| map.best_covisible(k, RELOCALISATION_GROUP_SIZE),
            &options,
        );
        let found = match found {
            Ok(found) => found,
            Err(e) => {
                tracing::warn!(frame = frame.index, error = %e, "relocalisation: keyframe database query failed");
                return Some(Vec::new());
            }
        };
        tracing::debug!(
            frame = frame.index,
            candidates = ?found.iter().map(|c| (c.keyframe.0, c.score)).collect::<Vec<_>>(),
            "relocalisation: database query"
        );
        Some(
            found
                .into_iter()
                .map(|c| c.keyframe)
                .filter(|&k| map.keyframe(k).is_ok())
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::CameraRig;
    use crate::loop_closing::{LoopDetector, LoopThresholds};
    use crate::place::PlaceError;
    use crate::settings::SlamSettings;
    use crate::tracking::Tracker;

    /// A 4-value descriptor from rows of 2 (enough to fill a database).
    struct Fixed;

    impl GlobalDescriptor for Fixed {
        fn local_dim(&self) -> usize {
            2
        }
        fn dim(&self) -> usize {
            4
        }
        fn compute_flat(&self, _: &[f32]) -> Result<Vec<f32>, PlaceError> {
            Ok(vec![0.5; 4])
        }
    }

    #[test]
    fn a_new_map_empties_the_shared_database_in_place() {
        let mut detector = LoopDetector::new(Arc::new(Fixed), LoopThresholds::default())
            .unwrap_or_else(|e| panic!("{e}"));
        let relocaliser = DatabaseRelocaliser::new(Arc::new(Fixed), detector.shared_database());
        crate::loop_closing::detector::write_database(&detector.shared_database())
            .unwrap_or_else(|e| panic!("{e}"))
            .insert(KeyFrameId(3), &[0.5; 4])
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(relocaliser.database_len().ok(), Some(1));
        detector.clear().unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            relocaliser.database_len().ok(),
            Some(0),
            "the relocaliser holds a stale database"
        );
        crate::loop_closing::detector::write_database(&detector.shared_database())
            .unwrap_or_else(|e| panic!("{e}"))
            .insert(KeyFrameId(0), &[0.5; 4])
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(relocaliser.database_len().ok(), Some(1));
    }

    #[test]
    fn a_fresh_tracker_keeps_its_candidate_source() {
        let settings = SlamSettings::rectified_stereo(400.0, 400.0, 320.0, 240.0, 0.1);
        let rig = CameraRig::from_settings(&settings, 640, 480).unwrap_or_else(|e| panic!("{e}"));
        let mut tracker = Tracker::new(rig);
        assert!(!tracker.has_relocalisation_candidates());
        let detector = LoopDetector::new(Arc::new(Fixed), LoopThresholds::default())
            .unwrap_or_else(|e| panic!("{e}"));
        let relocaliser = DatabaseRelocaliser::new(Arc::new(Fixed), detector.shared_database());
        tracker.set_relocalisation_candidates(Some(Arc::new(relocaliser)));
        assert!(tracker.fresh().has_relocalisation_candidates());
        tracker.set_relocalisation_candidates(None);
        assert!(!tracker.fresh().has_relocalisation_candidates());
    }
}
