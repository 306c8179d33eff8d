//! Tracking's decisions on frames built from a point world with known
//! answers: ORB-SLAM3's stereo keyframe rule as a truth table, the
//! monocular rule while mapping is busy, and
//! relocalisation from a known pose.

use nalgebra::Vector3;

use super::keyframe::{needs_keyframe, KeyFrameContext};
use super::relocalise::relocalise_with;
use crate::camera::{CameraRig, Sensor};
use crate::optim::LieGroup;
use crate::test_world::{pose_at, PointWorld};

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

/// The reference keyframe's points seen by at least `observations`
/// keyframes (what the keyframe rule compares the inliers with).
fn points_seen_by(
    map: &crate::map::Map,
    reference: crate::map::KeyFrameId,
    observations: usize,
) -> usize {
    ok(map.keyframe(reference))
        .observed_points()
        .filter(|(_, p)| {
            map.map_point(*p)
                .is_ok_and(|p| p.observation_count() >= observations)
        })
        .count()
}

#[test]
fn keyframe_decision_follows_orb_slam3_stereo_rule() {
    // Points from 4 to 40 m: about half closer than the rig's 20 m.
    let world = PointWorld::new(3, 900, (14.0, 5.0, 4.0, 40.0));
    let (map, kfs) = world.keyframe_chain(3);
    let reference = kfs[2].0;
    let reference_matches = points_seen_by(&map, reference, 3);
    assert!(reference_matches > 300, "{reference_matches}");
    let r = reference_matches as f64;
    // The frame: 0.2 m ahead of the reference keyframe.
    let (mut frame, view) = world.frame(30, &pose_at(Vector3::new(0.0, 0.0, 1.0), 0.0), true);
    let close: Vec<usize> = (0..frame.len())
        .filter(|&i| frame.depth(i).is_some_and(|d| d < world.rig.close_depth))
        .collect();
    assert!(close.len() > 200, "{} close keypoints", close.len());
    let _ = view;
    // tracked_close ≥ 100: no need for close points, unless `need_close`.
    let set_tracked_close = |frame: &mut super::Frame, tracked: usize| {
        frame.map_points.iter_mut().for_each(|p| *p = None);
        for &i in close.iter().take(tracked) {
            frame.map_points[i] = Some(crate::map::MapPointId(0));
        }
    };
    struct Row {
        name: &'static str,
        inliers: f64,
        need_close: bool,
        queue: usize,
        frames_since_keyframe: usize,
        expected: bool,
    }
    let rows = [
        Row {
            name: "many inliers, idle",
            inliers: 0.9,
            need_close: false,
            queue: 0,
            frames_since_keyframe: 1,
            expected: false,
        },
        Row {
            name: "fewer than 75 % inliers, idle",
            inliers: 0.6,
            need_close: false,
            queue: 0,
            frames_since_keyframe: 1,
            expected: true,
        },
        Row {
            name: "fewer than 75 % inliers, busy, recent keyframe",
            inliers: 0.6,
            need_close: false,
            queue: 1,
            frames_since_keyframe: 1,
            expected: false,
        },
        Row {
            name: "fewer than 75 % inliers, busy, a second since the last keyframe",
            inliers: 0.6,
            need_close: false,
            queue: 1,
            frames_since_keyframe: 10,
            expected: true,
        },
        Row {
            name: "fewer than 25 % inliers, busy (queue 2)",
            inliers: 0.2,
            need_close: false,
            queue: 2,
            frames_since_keyframe: 1,
            expected: true,
        },
        // spslam's departure: weak tracking (condition 1c) is never
        // refused for the queue; ORB-SLAM3 refuses it at 3.
        Row {
            name: "fewer than 25 % inliers, queue beyond full (5)",
            inliers: 0.2,
            need_close: false,
            queue: 5,
            frames_since_keyframe: 1,
            expected: true,
        },
        Row {
            name: "fewer than 75 % inliers (not weak), queue full (3), a second since the last keyframe",
            inliers: 0.6,
            need_close: false,
            queue: 3,
            frames_since_keyframe: 10,
            expected: false,
        },
        Row {
            name: "many inliers but close points untracked, busy",
            inliers: 0.9,
            need_close: true,
            queue: 1,
            frames_since_keyframe: 1,
            expected: true,
        },
        Row {
            name: "15 inliers or fewer",
            inliers: 15.0 / r,
            need_close: true,
            queue: 0,
            frames_since_keyframe: 20,
            expected: false,
        },
    ];
    for row in rows {
        set_tracked_close(&mut frame, if row.need_close { 50 } else { 150 });
        let ctx = KeyFrameContext {
            reference,
            last_keyframe_frame: frame.index - row.frames_since_keyframe,
            last_relocalisation_frame: None,
            inliers: (row.inliers * r).round() as usize,
            near_reference_count: usize::MAX,
            max_frames: 10,
            mapping_queue: row.queue,
            velocity: None,
        };
        assert_eq!(
            needs_keyframe(&frame, &map, &world.rig, &ctx).insert,
            row.expected,
            "{}",
            row.name
        );
    }
    // Just after a relocalisation in a map of more than `max_frames`
    // keyframes, no keyframe (ORB-SLAM3); a small map is exempt.
    set_tracked_close(&mut frame, 150);
    let ctx = KeyFrameContext {
        reference,
        last_keyframe_frame: frame.index - 1,
        last_relocalisation_frame: Some(frame.index - 2),
        inliers: (0.6 * r) as usize,
        near_reference_count: usize::MAX,
        max_frames: 10,
        mapping_queue: 0,
        velocity: None,
    };
    assert!(
        needs_keyframe(&frame, &map, &world.rig, &ctx).insert,
        "small map exempt"
    );
    // A stereo (or RGB-D) keyframe brings its own close points, which a
    // camera just relocalised at the old map's edge needs at once: it may
    // be inserted. A monocular one waits `max_frames`, as in ORB-SLAM3.
    let ctx = KeyFrameContext {
        max_frames: 2,
        last_relocalisation_frame: Some(frame.index - 1),
        ..ctx
    };
    assert!(
        needs_keyframe(&frame, &map, &world.rig, &ctx).insert,
        "recently relocalised, stereo"
    );
    let mono = CameraRig {
        sensor: Sensor::Monocular,
        ..world.rig
    };
    let long_ago = KeyFrameContext {
        last_relocalisation_frame: None,
        ..ctx
    };
    assert!(
        needs_keyframe(&frame, &map, &mono, &long_ago).insert,
        "monocular, no relocalisation"
    );
    assert!(
        !needs_keyframe(&frame, &map, &mono, &ctx).insert,
        "recently relocalised, monocular"
    );
}

#[test]
fn near_its_reference_the_ratio_counts_against_the_most_tracked() {
    // spslam's departure from ORB-SLAM3's condition 2: while the camera
    // stays near its reference keyframe (baseline under 4 % of the median
    // depth, under 5° of rotation), the frame's inliers are compared with
    // 0.75 × the fewer of the reference's well-observed points and the most
    // inliers a frame has tracked with this reference.
    let world = PointWorld::new(3, 900, (14.0, 5.0, 4.0, 40.0));
    let (map, kfs) = world.keyframe_chain(3);
    let reference = kfs[2].0; // at z = 0.8 m; median depth about 20 m
    let r = points_seen_by(&map, reference, 3) as f64;
    let decide = |position: Vector3<f64>, yaw: f64, peak: f64| {
        let pose = pose_at(position, yaw);
        let (mut frame, _) = world.frame(30, &pose, true);
        frame.pose_cw = pose;
        // 150 tracked close points: the close-point condition holds off.
        let close: Vec<usize> = (0..frame.len())
            .filter(|&i| frame.depth(i).is_some_and(|d| d < world.rig.close_depth))
            .collect();
        assert!(close.len() > 150, "{} close keypoints", close.len());
        frame.map_points.iter_mut().for_each(|p| *p = None);
        for &i in close.iter().take(150) {
            frame.map_points[i] = Some(crate::map::MapPointId(0));
        }
        let ctx = KeyFrameContext {
            reference,
            last_keyframe_frame: frame.index - 1,
            last_relocalisation_frame: None,
            inliers: (0.6 * r).round() as usize,
            near_reference_count: (peak * r).round() as usize,
            max_frames: 10,
            mapping_queue: 0,
            velocity: None,
        };
        needs_keyframe(&frame, &map, &world.rig, &ctx).insert
    };
    let near = Vector3::new(0.0, 0.0, 1.0);
    assert!(
        decide(near, 0.0, 1.0),
        "60 % of a peak as high as the reference's points"
    );
    assert!(
        !decide(near, 0.0, 0.7),
        "60 % ≥ 0.75 × a peak of 70 %: no keyframe"
    );
    assert!(decide(near, 0.0, 0.85), "60 % < 0.75 × a peak of 85 %");
    // Moved 1.2 m (6 % of the median depth) or turned 10°: ORB-SLAM3's rule.
    assert!(decide(Vector3::new(0.0, 0.0, 2.0), 0.0, 0.7), "moved away");
    assert!(decide(near, 10f64.to_radians(), 0.7), "turned");
}

#[test]
fn a_monocular_keyframe_wanted_while_mapping_is_busy_interrupts_its_ba_as_orb_slam3_does() {
    let world = PointWorld::new(3, 900, (14.0, 5.0, 4.0, 40.0));
    let (map, kfs) = world.keyframe_chain(3);
    let reference = kfs[2].0;
    let mut mono = world.rig;
    mono.sensor = crate::camera::Sensor::Monocular;
    // A monocular reference counts its points seen twice.
    let reference_matches = points_seen_by(&map, reference, 2);
    assert!(reference_matches > 300, "{reference_matches}");
    let r = reference_matches as f64;
    let (mut frame, _) = world.frame(30, &pose_at(Vector3::new(0.0, 0.0, 1.0), 0.0), false);
    assert!(frame.len() > 300, "{} keypoints", frame.len());
    let set_tracked = |frame: &mut super::Frame, tracked: usize| {
        frame.map_points.iter_mut().for_each(|p| *p = None);
        for p in frame.map_points.iter_mut().take(tracked) {
            *p = Some(crate::map::MapPointId(0));
        }
    };
    // (name, inliers / reference, tracked points, queue, frames since the
    // last keyframe (`max_frames` is 10), insert, interrupt)
    let rows = [
        (
            "idle, under 90 % of the reference: ORB-SLAM3's rule",
            0.5,
            200,
            0,
            1,
            true,
            false,
        ),
        (
            "idle, 50 points tracked but 95 % of the reference: ORB-SLAM3's rule",
            0.95,
            50,
            0,
            1,
            false,
            false,
        ),
        (
            "busy, under 90 %, a frame after the last keyframe: refused, the BA left to run (neither 1a nor 1c)",
            0.5,
            200,
            1,
            1,
            false,
            false,
        ),
        (
            "busy, under 90 %, max_frames after the last keyframe: refused, the BA interrupted (1a)",
            0.5,
            200,
            1,
            10,
            false,
            true,
        ),
        (
            "busy, fewer than 100 points tracked: condition 1c inserts, the BA interrupted",
            0.5,
            50,
            1,
            1,
            true,
            true,
        ),
        (
            "busy, 95 % of the reference and 200 points tracked: nothing",
            0.95,
            200,
            1,
            10,
            false,
            false,
        ),
    ];
    for (name, inliers, tracked, queue, since, insert, interrupt) in rows {
        set_tracked(&mut frame, tracked);
        let ctx = KeyFrameContext {
            reference,
            last_keyframe_frame: frame.index - since,
            last_relocalisation_frame: None,
            inliers: (inliers * r).round() as usize,
            near_reference_count: usize::MAX,
            max_frames: 10,
            mapping_queue: queue,
            velocity: None,
        };
        let decision = needs_keyframe(&frame, &map, &mono, &ctx);
        assert_eq!(
            (decision.insert, decision.interrupt_mapping),
            (insert, interrupt),
            "{name}"
        );
    }
    // Stereo keyframes bring their own points and never interrupt the BA:
    // a busy mapper, weak tracking, a full queue.
    let (stereo_frame, _) = world.frame(31, &pose_at(Vector3::new(0.0, 0.0, 1.0), 0.0), true);
    for queue in [1, 3, 5] {
        let ctx = KeyFrameContext {
            reference,
            last_keyframe_frame: stereo_frame.index - 1,
            last_relocalisation_frame: None,
            inliers: 20,
            near_reference_count: usize::MAX,
            max_frames: 10,
            mapping_queue: queue,
            velocity: None,
        };
        let decision = needs_keyframe(&stereo_frame, &map, &world.rig, &ctx);
        assert!(
            decision.insert && !decision.interrupt_mapping,
            "stereo, queue {queue}"
        );
    }
}

#[test]
fn tracked_points_about_to_leave_the_view_ask_for_a_keyframe() {
    // spslam's addition to ORB-SLAM3's close-point condition: it is
    // applied to the next frame as the motion model predicts it. In a fast
    // turn the tracked points slide out at one side (the turn-in-place lap
    // lost RGB-D tracking so: 160 inliers, then none in view).
    let world = PointWorld::new(3, 2000, (14.0, 5.0, 4.0, 40.0));
    let (mut map, kfs) = world.keyframe_chain(3);
    let reference = kfs[2].0;
    let pose = pose_at(Vector3::new(0.0, 0.0, 1.0), 0.0);
    let (mut frame, view) = world.frame(30, &pose, true);
    let close: Vec<usize> = (0..frame.len())
        .filter(|&i| frame.depth(i).is_some_and(|d| d < world.rig.close_depth))
        .collect();
    // 200 tracked close points spread over the image, the rest untracked:
    // ORB-SLAM3's condition holds off (≥ 100 tracked).
    let tracked: Vec<usize> = close
        .iter()
        .copied()
        .step_by((close.len() / 200).max(1))
        .take(200)
        .collect();
    assert!(
        tracked.len() == 200 && close.len() > 200 + 70,
        "{} close keypoints",
        close.len()
    );
    // Each tracked keypoint observes a map point at its true position.
    frame.pose_cw = pose;
    frame.map_points.iter_mut().for_each(|p| *p = None);
    for &i in &tracked {
        frame.map_points[i] = Some(world.add_point(&mut map, view.point_of[i], reference));
    }
    let ctx = |velocity| KeyFrameContext {
        reference,
        last_keyframe_frame: frame.index - 1,
        last_relocalisation_frame: None,
        // As many inliers as the reference has points: no ratio condition.
        inliers: 10_000,
        near_reference_count: usize::MAX,
        max_frames: 10,
        mapping_queue: 1,
        velocity,
    };
    assert!(
        !needs_keyframe(&frame, &map, &world.rig, &ctx(None)).insert,
        "no velocity: ORB-SLAM3's rule"
    );
    let still = crate::optim::Se3::identity();
    assert!(
        !needs_keyframe(&frame, &map, &world.rig, &ctx(Some(still))).insert,
        "a still camera keeps its points in view"
    );
    // Turning right by 50° per frame: most points leave the view.
    let turning = pose_at(Vector3::zeros(), 50f64.to_radians());
    assert!(
        needs_keyframe(&frame, &map, &world.rig, &ctx(Some(turning))).insert,
        "the points leave the view in the next frame"
    );
}

/// A frame 0.35 m sideways and 4° away from every keyframe of a chain of
/// five, relocalised from the identity pose (no prior): the world, its
/// map, the frame and its true pose.
fn relocalised_frame() -> (PointWorld, crate::map::Map, super::Frame, crate::optim::Se3) {
    let world = PointWorld::new(5, 1500, (15.0, 5.0, 4.0, 35.0));
    let (map, _) = world.keyframe_chain(5);
    let truth = pose_at(Vector3::new(0.35, -0.1, 1.3), 4f64.to_radians());
    let (mut frame, _) = world.frame(50, &truth, true);
    assert!(ok(relocalise_with(
        &mut frame, &map, &world.rig, None, None
    )));
    (world, map, frame, truth)
}

#[test]
fn relocalisation_recovers_a_known_pose() {
    let (_, _, frame, truth) = relocalised_frame();
    let error = frame.pose_cw.compose(&truth.inverse());
    let translation = error.translation.norm();
    let rotation = error.rotation.angle().to_degrees();
    println!("relocalised: {translation:.2e} m, {rotation:.2e} deg from the truth");
    assert!(translation < 0.01, "{translation} m");
    assert!(rotation < 0.1, "{rotation} deg");
    assert!(frame.tracked_count() >= super::MIN_RELOCALISATION_INLIERS);
}

#[test]
fn relocalisation_fails_where_the_map_was_never_seen() {
    let world = PointWorld::new(5, 1500, (15.0, 5.0, 4.0, 35.0));
    let (map, _) = world.keyframe_chain(5);
    // Other points, with other descriptors.
    let elsewhere = PointWorld::new(99, 1500, (15.0, 5.0, 4.0, 35.0));
    let (mut frame, _) = elsewhere.frame(50, &pose_at(Vector3::zeros(), 0.0), true);
    assert!(!ok(relocalise_with(
        &mut frame, &map, &world.rig, None, None
    )));
    assert_eq!(frame.tracked_count(), 0);
}

#[test]
fn a_lost_frames_pose_is_corroborated_only_by_another_start_landing_on_it() {
    use super::corroborate::{corroborated, StartPose};
    use super::TrackingMethod::{ImageRotation, ReferenceKeyFrame, Relocalisation};
    let (world, map, mut frame, truth) = relocalised_frame();
    frame.pose_cw = truth;
    let start = |method, pose_cw, inliers| StartPose {
        method,
        pose_cw,
        inliers,
    };
    // A second start 1 cm and 0.05° away lands on the same pose; one 0.4 m
    // and 1.7° away (the kidnapped camera's two starts) does not.
    let near = pose_at(Vector3::new(0.01, 0.0, 0.0), 0.05f64.to_radians()).compose(&truth);
    let far = pose_at(Vector3::new(0.4, 0.0, 0.0), 1.7f64.to_radians()).compose(&truth);
    // Local-map tracking's 30 inliers.
    let judge = |method, inliers, starts: &[StartPose]| {
        corroborated(&frame, (method, inliers), 30, starts, &map, &world.rig)
    };
    assert!(judge(
        ImageRotation,
        48,
        &[start(ReferenceKeyFrame, near, 24)]
    ));
    assert!(!judge(
        ImageRotation,
        48,
        &[start(ReferenceKeyFrame, far, 24)]
    ));
    // The pose needs local-map tracking's 30 inliers, the other start a
    // pose's 10; a start is not its own witness; a relocalisation's pose
    // is judged by relocalisation's own rule.
    assert!(!judge(
        ImageRotation,
        29,
        &[start(ReferenceKeyFrame, near, 24)]
    ));
    assert!(!judge(
        ImageRotation,
        48,
        &[start(ReferenceKeyFrame, near, 9)]
    ));
    assert!(!judge(ImageRotation, 48, &[start(ImageRotation, near, 48)]));
    assert!(!judge(
        Relocalisation,
        48,
        &[start(ReferenceKeyFrame, near, 24)]
    ));
}
