//! Whether a loop's correction can be drift: the last stage of a loop
//! candidate's check.
//!
//! A loop corrects the drift accumulated since the camera last saw the
//! place, and drift grows with the way travelled. A candidate that passes
//! every geometric stage but asks the query keyframe to move further than
//! the way travelled since the candidate could explain is a look-alike, not
//! a revisit: repeated texture registers a keyframe against the same
//! pattern elsewhere with as many inliers as a true loop (the standard set's
//! `loop_repeated_rgbd_sp_anms` closed a 22.6 m, 90° "loop" after 26 m of
//! travel with 124 inliers; EVALUATION.md, "A plausibility gate for loop
//! corrections"). ORB-SLAM3 has the same kind of gate where its map can
//! judge one: for inertial maps `LoopClosing::Run` rejects a loop ("BAD
//! LOOP") whose correction turns the gravity direction by more than
//! 0.008 rad or the yaw by more than 0.349 rad (20°). A visual map has no
//! gravity; the way travelled is what bounds its drift.
//!
//! A monocular map's correction is judged by its rotation only: its scale
//! drifts, so a true loop's translation can be of the order of the way
//! travelled, but a rotation is the same at any scale.

use crate::camera::CameraRig;
use crate::map::{KeyFrameId, Map};
use crate::optim::{LieGroup, Se3};

use super::thresholds::LoopThresholds;

/// Camera-centre distance (metres) and rotation angle (degrees) between
/// two poses `T_cw`.
pub fn pose_difference(a: &Se3, b: &Se3) -> (f64, f64) {
    let (ca, cb) = (a.inverse().translation, b.inverse().translation);
    let angle = a.rotation.angle_to(&b.rotation).to_degrees();
    ((ca - cb).norm(), angle)
}

/// The way the camera travelled from a loop candidate to the query, along
/// the map's live keyframes in id (creation) order, and the scene's depth
/// at the query.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Travel {
    /// Summed distance between consecutive keyframes' camera centres
    /// (metres; culled keyframes shorten it a little).
    pub path_m: f64,
    /// Summed rotation between consecutive keyframes (degrees).
    pub turned_deg: f64,
    /// The query keyframe's median scene depth (metres; 0 without points).
    pub scene_depth_m: f64,
    /// Whether the map's lengths are metres (stereo, RGB-D); a monocular
    /// map's are not, and its correction's translation is not judged.
    #[serde(default = "metric_by_default")]
    pub metric: bool,
}

/// Records written before [`Travel::metric`] existed were all metric.
fn metric_by_default() -> bool {
    true
}

/// The way travelled from keyframe `from` to keyframe `to` in `map`, a
/// map with a metric scale (`None` when either is not a live keyframe of
/// it).
pub fn travel_between(map: &Map, from: KeyFrameId, to: KeyFrameId) -> Option<Travel> {
    map.keyframe(from).ok()?;
    map.keyframe(to).ok()?;
    let (first, last) = (from.min(to), from.max(to));
    let mut path_m = 0.0;
    let mut turned_deg = 0.0;
    let mut previous: Option<Se3> = None;
    for keyframe in map.keyframes().filter(|k| (first..=last).contains(&k.id())) {
        let pose = keyframe.pose_cw();
        if let Some(previous) = previous {
            let (metres, degrees) = pose_difference(&previous, &pose);
            path_m += metres;
            turned_deg += degrees;
        }
        previous = Some(pose);
    }
    Some(Travel {
        path_m,
        turned_deg,
        scene_depth_m: map.median_scene_depth(to).unwrap_or(0.0),
        metric: true,
    })
}

/// What a loop check judges the correction of `candidate` for `query` by
/// (the one place that decides how loops are judged): the way travelled
/// between them in `map`, metric for a rig with depth; a monocular rig's
/// scale drifts, so only its turns count (see the module's docs).
pub fn loop_travel(
    map: &Map,
    candidate: KeyFrameId,
    query: KeyFrameId,
    rig: &CameraRig,
) -> Option<Travel> {
    let travel = travel_between(map, candidate, query)?;
    Some(Travel {
        metric: rig.sensor.has_depth(),
        ..travel
    })
}

/// A candidate's correction next to the way travelled since the candidate:
/// what the check's last stage judges ([`LoopDrift::excess`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LoopDrift {
    /// How far the correction moves the query's camera centre (metres).
    pub correction_m: f64,
    /// How far it turns the query (degrees).
    pub correction_deg: f64,
    /// The way travelled since the candidate.
    pub travel: Travel,
}

impl LoopDrift {
    /// The correction from the query's pose `before_cw` to the check's
    /// `after_cw`, after `travel`.
    pub fn measure(travel: Travel, before_cw: &Se3, after_cw: &Se3) -> Self {
        let (correction_m, correction_deg) = pose_difference(before_cw, after_cw);
        Self {
            correction_m,
            correction_deg,
            travel,
        }
    }

    /// The largest correction drift explains under `th`: metres and
    /// degrees, each the larger of a floor and
    /// [`LoopThresholds::max_drift_ratio`] of the way travelled (path,
    /// turn). The translation's floor is
    /// [`LoopThresholds::drift_floor_depths`] of the scene's depth, the
    /// rotation's [`LoopThresholds::drift_floor_deg`]; a map without a
    /// metric scale allows any translation.
    pub fn allowed(&self, th: &LoopThresholds) -> (f64, f64) {
        let t = &self.travel;
        let metres = if t.metric {
            (th.drift_floor_depths * t.scene_depth_m).max(th.max_drift_ratio * t.path_m)
        } else {
            f64::INFINITY
        };
        (
            metres,
            th.drift_floor_deg.max(th.max_drift_ratio * t.turned_deg),
        )
    }

    /// How many times over what drift explains the correction is (its
    /// worse part, translation or rotation): above 1, the correction is
    /// not drift.
    pub fn excess(&self, th: &LoopThresholds) -> f64 {
        let (metres, degrees) = self.allowed(th);
        let ratio = |value: f64, allowed: f64| {
            if allowed > 0.0 {
                value / allowed
            } else if value > 0.0 {
                f64::INFINITY
            } else {
                0.0
            }
        };
        ratio(self.correction_m, metres).max(ratio(self.correction_deg, degrees))
    }

    /// The correction as a fraction of the path travelled (the quantity
    /// [`LoopThresholds::max_drift_ratio`] bounds; infinite without a path).
    pub fn path_ratio(&self) -> f64 {
        if self.travel.path_m > 0.0 {
            self.correction_m / self.travel.path_m
        } else {
            f64::INFINITY
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{UnitQuaternion, Vector3};

    use super::*;

    fn travel(path_m: f64, turned_deg: f64, scene_depth_m: f64) -> Travel {
        Travel {
            path_m,
            turned_deg,
            scene_depth_m,
            metric: true,
        }
    }

    fn pose_at(x: f64, yaw_deg: f64) -> Se3 {
        // T_cw of a camera at (x, 0, 0) turned by yaw about y.
        let rotation = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), yaw_deg.to_radians());
        Se3::new(rotation, Vector3::new(x, 0.0, 0.0)).inverse()
    }

    #[test]
    fn the_correction_is_measured_at_the_camera_centre() {
        let drift = LoopDrift::measure(
            travel(100.0, 0.0, 10.0),
            &pose_at(0.0, 0.0),
            &pose_at(2.0, 30.0),
        );
        assert!((drift.correction_m - 2.0).abs() < 1e-12);
        assert!((drift.correction_deg - 30.0).abs() < 1e-9);
        assert!((drift.path_ratio() - 0.02).abs() < 1e-12);
    }

    #[test]
    fn drift_explains_a_small_fraction_of_the_way_travelled_and_no_more() {
        let th = LoopThresholds::default();
        let ratio = th.max_drift_ratio;
        // 200 m of path, 360° of turns, 10 m deep scene.
        let way = travel(200.0, 360.0, 10.0);
        let at = |m: f64, deg: f64| LoopDrift::measure(way, &pose_at(0.0, 0.0), &pose_at(m, deg));
        let (metres, degrees) = at(0.0, 0.0).allowed(&th);
        assert!((metres - ratio * 200.0).abs() < 1e-12);
        assert!((degrees - th.drift_floor_deg.max(ratio * 360.0)).abs() < 1e-12);
        // Just inside and just outside, in translation and in rotation.
        assert!(at(0.99 * metres, 0.0).excess(&th) < 1.0);
        assert!(at(1.01 * metres, 0.0).excess(&th) > 1.0);
        assert!(at(0.0, 0.99 * degrees).excess(&th) < 1.0);
        assert!(at(0.0, 1.01 * degrees).excess(&th) > 1.0);
    }

    #[test]
    fn a_short_way_is_judged_by_the_floors() {
        let th = LoopThresholds::default();
        // A turn in place: no path, 5 m deep scene.
        let way = travel(0.0, 90.0, 5.0);
        let drift = LoopDrift::measure(way, &pose_at(0.0, 0.0), &pose_at(0.0, 0.0));
        let (metres, degrees) = drift.allowed(&th);
        assert!((metres - th.drift_floor_depths * 5.0).abs() < 1e-12);
        assert!((degrees - th.drift_floor_deg).abs() < 1e-12);
        assert_eq!(drift.excess(&th), 0.0);
        // Nothing to go by (no path, no depth): any move is too much.
        let blind = LoopDrift::measure(
            travel(0.0, 0.0, 0.0),
            &pose_at(0.0, 0.0),
            &pose_at(0.1, 0.0),
        );
        assert!(blind.excess(&th).is_infinite());
    }

    #[test]
    fn the_way_is_summed_over_the_keyframes_between_in_id_order() {
        use crate::map::tests_support::map_with_keyframes_at;
        // Keyframes at x = 0, 1, 3, 6 (turning 10° each step).
        let centres = [0.0, 1.0, 3.0, 6.0];
        let poses: Vec<Se3> = centres
            .iter()
            .enumerate()
            .map(|(i, x)| pose_at(*x, 10.0 * i as f64))
            .collect();
        let (map, ids) = map_with_keyframes_at(&poses);
        let way = travel_between(&map, ids[3], ids[1]).expect("live keyframes");
        assert!((way.path_m - 5.0).abs() < 1e-9);
        assert!((way.turned_deg - 20.0).abs() < 1e-9);
        let whole = travel_between(&map, ids[0], ids[3]).expect("live keyframes");
        assert!((whole.path_m - 6.0).abs() < 1e-9);
        assert!(travel_between(&map, ids[0], KeyFrameId(999)).is_none());
    }

    #[test]
    fn a_monocular_correction_is_judged_by_its_rotation_only() {
        let th = LoopThresholds::default();
        let way = Travel {
            metric: false,
            ..travel(26.0, 90.0, 8.0)
        };
        // Any translation (the scale drifts)…
        let moved = LoopDrift::measure(way, &pose_at(0.0, 0.0), &pose_at(500.0, 5.0));
        assert!(moved.excess(&th) < 1.0);
        // …but not a quarter turn after one corner.
        let turned = LoopDrift::measure(way, &pose_at(0.0, 0.0), &pose_at(0.0, 90.0));
        assert!(turned.excess(&th) > 1.0);
    }
}
