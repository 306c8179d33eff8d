//! The loop correction against a known answer: a loop side at the true
//! scale, and a query side whose map is the true one moved by a
//! similarity (yaw, shift and scale 1.3, as monocular drift leaves it). A
//! monocular (Sim(3)) correction puts the query side back where it is; the
//! SE(3) one cannot undo the scale.

use std::collections::BTreeMap;

use nalgebra::{UnitQuaternion, Vector3};

use super::correct::correct_loop;
use super::detector::AcceptedLoop;
use crate::camera::{CameraRig, Sensor};
use crate::map::{KeyFrameId, Map, MapPointId};
use crate::optim::{LieGroup, Se3, Sim3};
use crate::test_world::{pose_at, rig, PointWorld};

/// The drift of the query side: true world → query map.
fn drift() -> Sim3 {
    Sim3::new(
        UnitQuaternion::from_euler_angles(0.0, 0.09, 0.0),
        Vector3::new(1.0, 0.2, 0.5),
        1.3,
    )
}

struct LoopScene {
    map: Map,
    accepted: AcceptedLoop,
    /// True `T_cw` of the query-side keyframes.
    truth: Vec<(KeyFrameId, Se3)>,
    /// Query-side points and their true positions.
    points: Vec<(MapPointId, Vector3<f64>)>,
}

fn loop_scene() -> LoopScene {
    let world = PointWorld::new(11, 600, (8.0, 3.0, 4.0, 12.0));
    let mut map = Map::new();
    // The loop side, true.
    let (a, a_view) = world.add_keyframe(&mut map, pose_at(Vector3::zeros(), 0.0), false);
    let mut loop_point = BTreeMap::new();
    for (index, &p) in a_view.point_of.iter().enumerate() {
        let id = world.add_point(&mut map, p, a);
        ok(map.add_observation(id, a, index));
        loop_point.insert(p, id);
    }
    // The query side, seen from true poses, stored drifted.
    let d = drift();
    let true_poses = [
        pose_at(Vector3::new(0.3, 0.0, 0.2), 0.02),
        pose_at(Vector3::new(0.6, 0.0, 0.4), 0.04),
        pose_at(Vector3::new(0.9, 0.0, 0.6), 0.06),
    ];
    let mut kfs = Vec::new();
    for t in &true_poses {
        let (kf, view) = world.add_keyframe(&mut map, *t, false);
        let drifted = Sim3::from_se3(t).compose(&d.inverse()).to_se3_unscaled();
        ok(map.keyframe_mut(kf).map(|k| k.set_pose_cw(drifted)));
        kfs.push((kf, view));
    }
    let mut own = BTreeMap::new();
    let mut points = Vec::new();
    for (kf, view) in &kfs {
        for (index, &p) in view.point_of.iter().enumerate() {
            let id = *own.entry(p).or_insert_with(|| {
                let id = world.add_point(&mut map, p, kfs[0].0);
                let truth = world.points[p];
                if let Ok(point) = map.map_point_mut(id) {
                    point.position = d.transform_point(&truth);
                }
                points.push((id, truth));
                id
            });
            ok(map.add_observation(id, *kf, index));
        }
    }
    let ids: Vec<_> = map.map_points().map(|p| p.id()).collect();
    for id in ids {
        map.update_normal_and_depth(id);
    }
    for kf in std::iter::once(a).chain(kfs.iter().map(|(k, _)| *k)) {
        map.update_connections(kf);
    }
    let (query, query_view) = &kfs[0];
    let accepted = AcceptedLoop {
        query: *query,
        candidate: a,
        group: vec![a],
        pose_cw: true_poses[0],
        matches: query_view
            .point_of
            .iter()
            .map(|p| loop_point.get(p).copied())
            .collect(),
        inliers: 100,
        confirmations: 3,
    };
    LoopScene {
        map,
        accepted,
        truth: kfs.iter().map(|(k, _)| *k).zip(true_poses).collect(),
        points,
    }
}

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

/// Largest camera-centre error and median error of the query side's
/// points that were not fused into the loop side's, after correcting with
/// `rig`.
fn corrected_errors(rig: &CameraRig) -> (f64, f64) {
    let mut scene = loop_scene();
    ok(correct_loop(&mut scene.map, &scene.accepted, rig));
    let centre = |t: &Se3| t.inverse().translation;
    let pose_error = scene
        .truth
        .iter()
        .map(|(k, t)| {
            let estimate = ok(scene.map.pose_cw_of(*k));
            (centre(&estimate) - centre(t)).norm()
        })
        .fold(0.0, f64::max);
    let mut point_errors: Vec<f64> = scene
        .points
        .iter()
        .filter(|(id, _)| scene.map.resolve_point(*id) == Some(*id))
        .filter_map(|(id, truth)| Some((scene.map.map_point(*id).ok()?.position - truth).norm()))
        .collect();
    assert!(
        point_errors.len() >= 20,
        "{} unfused points",
        point_errors.len()
    );
    point_errors.sort_by(f64::total_cmp);
    let median = point_errors
        .get(point_errors.len() / 2)
        .copied()
        .unwrap_or(f64::INFINITY);
    (pose_error, median)
}

#[test]
fn a_monocular_loop_is_corrected_in_sim3_and_recovers_the_scale() {
    let mono = CameraRig {
        sensor: Sensor::Monocular,
        ..rig()
    };
    let (pose_error, point_error) = corrected_errors(&mono);
    let (se3_pose_error, se3_point_error) = corrected_errors(&rig());
    eprintln!(
        "Sim(3): keyframes within {pose_error:.2e} m, points {point_error:.2e} m (median); \
         SE(3) on the same map: {se3_pose_error:.3} m, {se3_point_error:.3} m"
    );
    assert!(pose_error < 1e-6, "keyframe error {pose_error}");
    assert!(point_error < 1e-6, "point error {point_error}");
    assert!(se3_pose_error > 0.05 && se3_point_error > 0.5);
}
