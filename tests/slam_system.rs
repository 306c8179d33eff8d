//! The system layer on synthetic sequences with exact ground truth (ORB,
//! 480×360): a kidnapped camera resumes in a new atlas map without losing
//! a trajectory row, and tracking completes frames while local mapping's
//! BA is being solved, which the new stereo keyframes leave to finish.

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use common::synthetic_slam::{images, orb_slam, small_sequence};
use spslam::dataset::synthetic::{SceneName, SyntheticSequence};
use spslam::features::GrayImage;
use spslam::optim::{LieGroup, Se3};
use spslam::system::{SlamSystem, GAP_HORIZON_S};
use spslam::tracking::{
    TrackingMethod, TrackingState, RELOCALISATION_PATIENCE_S, YOUNG_MAP_KEYFRAMES,
};

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

/// Feeds the sequence's frames `inputs` in that order, as input frames
/// 0, 1, … at 10 fps (a kidnap or a jump is a jump in `inputs`).
fn process_inputs(slam: &mut SlamSystem, sequence: &SyntheticSequence, inputs: &[usize]) {
    for (k, &i) in inputs.iter().enumerate() {
        let (_, l, r) = images(sequence, i);
        ok(slam.process(k, k as f64 * 0.1, l.view(), r.view()));
    }
}

#[test]
fn a_kidnapped_camera_resumes_in_a_new_map_and_no_frame_is_dropped() {
    let sequence = small_sequence(SceneName::Loop, 232);
    let mut slam = orb_slam(&sequence);
    // 40 frames in order, then the camera is carried three quarters of the
    // way round the block and goes on from there.
    let inputs: Vec<usize> = (0..40).chain(160..200).collect();
    let kidnap = 40;
    process_inputs(&mut slam, &sequence, &inputs);
    ok(slam.finish());
    let records = slam.records();
    let trajectory = ok(slam.trajectory());
    assert_eq!(records.len(), inputs.len());
    assert_eq!(trajectory.len(), inputs.len(), "one row per input frame");

    let maps = slam.atlas().maps();
    let summary = ok(slam.summary());
    eprintln!("maps: {:?}", summary.maps);
    assert_eq!(maps.len(), 2, "a second map after the kidnapping");
    for r in &records[..kidnap] {
        assert_eq!(
            (r.map, r.state),
            (0, TrackingState::Ok),
            "frame {}",
            r.index
        );
    }
    // Relocalisation is given `RELOCALISATION_PATIENCE_S` (5 frames at 10
    // fps), then the next frame starts and initialises the new map.
    let patience = (RELOCALISATION_PATIENCE_S * 10.0).ceil() as usize;
    let second = maps[1].first_frame;
    eprintln!("lost at {kidnap}, new map from frame {second}");
    assert!(
        second > kidnap && second <= kidnap + patience + 1,
        "new map at {second}"
    );
    for r in &records[second..] {
        assert_eq!(
            (r.map, r.state),
            (1, TrackingState::Ok),
            "frame {}",
            r.index
        );
    }
    // The frames lost while relocalisation was tried saw the new place:
    // once the new map's first keyframe exists, each is localised in it
    // after the fact, so the new map's first pose is the first lost frame.
    let lost: Vec<_> = records[kidnap..second]
        .iter()
        .map(|r| (r.index, r.map, r.state, r.method))
        .collect();
    eprintln!("the frames of the loss now: {lost:?}");
    for r in &records[kidnap..second] {
        assert_eq!(
            (r.map, r.state, r.method),
            (1, TrackingState::Ok, TrackingMethod::AfterLoss),
            "frame {}",
            r.index
        );
    }
    assert_eq!(summary.localised_after_loss, second - kidnap);
    // The first frame after the kidnap found 33 local-map inliers from
    // the images' rotation at the old place, a wrong pose no second start
    // landed on (the rejected prediction's was 0.4 m and 1.7° away): it is
    // not given that pose (`tracking::corroborate`).
    assert_eq!(summary.corroborated, 0);
    // Anchoring: the new map's first pose carries on the last tracked
    // frame's velocity (frames 38 → 39, 0.1 s apart), the step turned by
    // the rotation the frame's images measured from the frame before
    // where they gave one: T_wc(40) = T_wc(39) · (R, t), with
    // exp(twist · 0.1) = (R_v, t) and R the measured R_pc, else R_v.
    assert_eq!(summary.maps[1].anchored_at_frame, Some(kidnap - 1));
    let last = trajectory[kidnap - 1].1;
    let twist = trajectory[kidnap - 2].1.inverse().compose(&last).log() / 0.1;
    let mut expected = last;
    for (k, (_, row)) in trajectory.iter().enumerate().take(kidnap + 1).skip(kidnap) {
        let within = |j: usize| ((j - (kidnap - 1)) as f64 * 0.1).min(GAP_HORIZON_S);
        let step = Se3::exp(&(twist * (within(k) - within(k - 1))));
        let rotation = records[k]
            .gap_rotation
            .map_or(step.rotation, |r_cp| r_cp.inverse());
        expected = expected.compose(&Se3::new(rotation, step.translation));
        let off = expected.inverse().compose(row).log().norm();
        assert!(off < 1e-9, "frame {k}: off the carried-on pose by {off}");
    }
    // In the new map the motion is right: the relative pose from its first
    // frame (localised after the fact) to the last matches the ground
    // truth within 2 % of the distance, and so does each late frame's
    // motion to the first keyframe (measured 1.0, 1.0, 1.0, 0.6 and 0.7 %
    // at 1 to 5 m; matched against that keyframe's points alone, before
    // the local map refined them, 0.9 to 4.8 %).
    let final_frame = inputs.len() - 1;
    let truth = |k: usize| Se3::from_isometry(&sequence.pose(inputs[k]));
    let mut errors = Vec::new();
    for k in kidnap..second {
        let estimated = trajectory[k].1.inverse().compose(&trajectory[second].1);
        let expected = truth(k).inverse().compose(&truth(second));
        let error = (estimated.translation - expected.translation).norm();
        let moved = expected.translation.norm();
        eprintln!("frame {k}: {moved:.3} m to the first keyframe, off by {error:.4} m");
        errors.push(error / moved);
    }
    assert!(errors.iter().all(|e| *e < 0.02), "{errors:?}");
    let estimated = trajectory[kidnap]
        .1
        .inverse()
        .compose(&trajectory[final_frame].1);
    let expected = truth(kidnap).inverse().compose(&truth(final_frame));
    let distance = expected.translation.norm();
    let error = (estimated.translation - expected.translation).norm();
    eprintln!("new map: {distance:.1} m travelled, relative error {error:.3} m");
    assert!(distance > 10.0);
    assert!(error < 0.02 * distance, "{error} m over {distance} m");
}

#[test]
fn a_camera_kidnapped_from_a_young_map_starts_the_new_map_on_the_next_frame() {
    // ORB-SLAM3's `Tracking::Track` waits in `RECENTLY_LOST` only in a map
    // of more than 10 keyframes; a younger map is given up at once. Here
    // the camera is carried off after 8 frames (8 keyframes): frame 8 is
    // lost, frame 9 tries the young map once and starts the new map
    // itself, where the 40-frame map above waits out the patience.
    let sequence = small_sequence(SceneName::Loop, 232);
    let mut slam = orb_slam(&sequence);
    let kidnap = 8;
    let inputs: Vec<usize> = (0..kidnap).chain(160..200).collect();
    process_inputs(&mut slam, &sequence, &inputs);
    ok(slam.finish());
    let records = slam.records();
    let maps = slam.atlas().maps();
    let keyframes_before = records[..kidnap].iter().filter(|r| r.keyframe).count();
    eprintln!(
        "{keyframes_before} keyframes before the kidnap; maps from frames {:?}",
        maps.iter().map(|m| m.first_frame).collect::<Vec<_>>()
    );
    assert!(keyframes_before <= YOUNG_MAP_KEYFRAMES);
    assert_eq!(maps.len(), 2, "a second map after the kidnapping");
    // Lost when it came; localised in the new map once that started.
    assert_eq!(
        (
            records[kidnap].map,
            records[kidnap].state,
            records[kidnap].method
        ),
        (1, TrackingState::Ok, TrackingMethod::AfterLoss)
    );
    assert_eq!(
        maps[1].first_frame,
        kidnap + 1,
        "the new map starts on the next frame"
    );
    for r in &records[kidnap + 1..] {
        assert_eq!(
            (r.map, r.state),
            (1, TrackingState::Ok),
            "frame {}",
            r.index
        );
    }
}

#[test]
fn a_blackout_carries_on_the_cameras_motion_and_then_relocalises_in_the_same_map() {
    // Down a straight street at a steady speed, six black frames: tracking
    // loses them, and their rows are the last velocity carried on, not the
    // last pose held (which would put them behind by the distance driven).
    // Measured: 0.85 % of the distance driven since the last tracked frame
    // (0.009 m after 1 m, 0.042 m after 5 m); the bound is 2 %.
    let sequence = small_sequence(SceneName::Straight, 60);
    let mut slam = orb_slam(&sequence);
    let black = 25..31;
    for i in 0..60 {
        let (t, l, r) = images(&sequence, i);
        if black.contains(&i) {
            let (w, h) = (l.width(), l.height());
            let dark = || ok(GrayImage::from_vec(vec![0; w * h], w, h));
            ok(slam.process(i, t, dark().view(), dark().view()));
        } else {
            ok(slam.process(i, t, l.view(), r.view()));
        }
    }
    ok(slam.finish());
    let records = slam.records();
    let trajectory = ok(slam.trajectory());
    let truth = |k: usize| Se3::from_isometry(&sequence.pose(k));
    let last_tracked = black.start - 1;
    assert_eq!(records[last_tracked].state, TrackingState::Ok);
    // The first frame with an image after the blackout tries the old map
    // before a new one is started: it relocalises there, becomes a
    // keyframe with its own stereo points, and every later frame is
    // tracked in the one map (the frame after it had tracked 48 inliers,
    // below the 50 a relocalisation needs, under ORB-SLAM3's one-second
    // keyframe wait).
    let after = black.end;
    assert_eq!(
        (
            records[after].state,
            records[after].method,
            records[after].keyframe
        ),
        (TrackingState::Ok, TrackingMethod::Relocalisation, true)
    );
    for r in &records[after..] {
        assert_eq!(
            (r.state, r.map),
            (TrackingState::Ok, 0),
            "frame {}",
            r.index
        );
    }
    assert_eq!(slam.atlas().maps().len(), 1, "no second map");
    // The motion since the last tracked frame, estimated against true.
    let since = |poses: &dyn Fn(usize) -> Se3, k: usize| {
        poses(last_tracked).inverse().compose(&poses(k)).translation
    };
    for k in black.clone() {
        assert_ne!(records[k].state, TrackingState::Ok, "frame {k}");
        let true_motion = since(&truth, k);
        let estimated = since(&|j| trajectory[j].1, k);
        let driven = true_motion.norm();
        let error = (estimated - true_motion).norm();
        eprintln!("frame {k}: {driven:.2} m since the last tracked frame, row off by {error:.3} m");
        assert!(
            error < 0.02 * driven,
            "frame {k}: {error} m off after {driven} m"
        );
    }
}

/// `image` blurred by three passes of a `(2r+1)`-pixel box (about a
/// Gaussian of σ = r), rows then columns.
fn box_blurred(image: &GrayImage, r: usize) -> GrayImage {
    let (w, h) = (image.width(), image.height());
    let mut v: Vec<f32> = image.as_slice().iter().map(|&p| f32::from(p)).collect();
    for _ in 0..3 {
        for (len, stride, count, step) in [(w, 1, h, w), (h, w, w, 1)] {
            let before = v.clone();
            for line in 0..count {
                for i in 0..len {
                    let (lo, hi) = (i.saturating_sub(r), (i + r).min(len - 1));
                    let sum: f32 = (lo..=hi).map(|j| before[line * step + j * stride]).sum();
                    v[line * step + i * stride] = sum / (hi - lo + 1) as f32;
                }
            }
        }
    }
    ok(GrayImage::from_vec(
        v.iter()
            .map(|&p| p.round().clamp(0.0, 255.0) as u8)
            .collect(),
        w,
        h,
    ))
}

#[test]
fn a_loss_in_a_turn_keeps_the_turn_the_images_show() {
    // The block's first corner turns about 11.5° a frame over frames
    // 21–28. Frames 21–25 are blurred until tracking loses them (a motion
    // blur that wipes the keypoints out); the last tracked frame, 20, was
    // still going straight, so its velocity alone would leave the turn out
    // of the lost rows. Their thumbnails still show the turn.
    let sequence = small_sequence(SceneName::Loop, 40);
    let mut slam = orb_slam(&sequence);
    let blurred = 21..26;
    for i in 0..40 {
        let (t, l, r) = images(&sequence, i);
        if blurred.contains(&i) {
            ok(slam.process(i, t, box_blurred(&l, 8).view(), box_blurred(&r, 8).view()));
        } else {
            ok(slam.process(i, t, l.view(), r.view()));
        }
    }
    ok(slam.finish());
    let records = slam.records();
    let trajectory = ok(slam.trajectory());
    let truth = |k: usize| Se3::from_isometry(&sequence.pose(k));
    let last_tracked = blurred.start - 1;
    assert_eq!(records[last_tracked].state, TrackingState::Ok);
    let turned = |poses: &dyn Fn(usize) -> Se3, k: usize| {
        poses(last_tracked).inverse().compose(&poses(k)).rotation
    };
    // (frame, angle turned since the last tracked frame, the row's error).
    let mut lost = Vec::new();
    for k in blurred.clone() {
        if records[k].state == TrackingState::Ok {
            continue;
        }
        let true_turn = turned(&truth, k);
        let estimated = turned(&|j| trajectory[j].1, k);
        let error = (true_turn.inverse() * estimated).angle().to_degrees();
        let angle = true_turn.angle().to_degrees();
        eprintln!(
            "frame {k}: turned {angle:.1}° since the last tracked frame, row off by {error:.2}°, measured step {:?}°",
            records[k].gap_rotation_deg
        );
        assert!(
            records[k].gap_rotation.is_some(),
            "frame {k}: no rotation measured"
        );
        lost.push((k, angle, error));
    }
    assert!(lost.len() >= 2, "only {lost:?} lost: the test needs a loss");
    // The velocity alone would leave the whole turn out; the thumbnails'
    // pure-rotation model takes the parallax of the camera's own 1 m a
    // frame for rotation. Measured: the rows off by 8–9 % of the turn;
    // the bound is 15 %.
    for (k, angle, error) in lost {
        assert!(
            error < 0.15 * angle,
            "frame {k}: {error}° off after {angle}°"
        );
    }
}

#[test]
fn tracking_goes_on_while_local_ba_is_solved_and_queued_stereo_keyframes_let_it_finish() {
    let sequence = small_sequence(SceneName::Straight, 80);
    let mut slam = orb_slam(&sequence);
    let (entered_tx, entered_rx) = mpsc::channel::<()>();
    let (release_tx, release_rx) = mpsc::channel::<()>();
    let entered_tx = Mutex::new(entered_tx);
    let release_rx = Mutex::new(release_rx);
    let held_once = AtomicBool::new(false);
    let released_by_test = Arc::new(AtomicBool::new(false));
    let released = Arc::clone(&released_by_test);
    // Holds the first BA solve (no lock is held there) until the test says
    // so, or 120 s pass.
    let hook = move || {
        if held_once.swap(true, Ordering::AcqRel) {
            return;
        }
        if let Ok(tx) = entered_tx.lock() {
            let _ = tx.send(());
        }
        if let Ok(rx) = release_rx.lock() {
            if rx.recv_timeout(Duration::from_secs(120)).is_ok() {
                released.store(true, Ordering::Release);
            }
        }
    };
    if let Some(mapper) = slam.mapper_mut() {
        mapper.set_before_solve(Some(Arc::new(hook)));
    }
    ok(slam.spawn_mapping_thread());
    let mut next = 0;
    let process = |slam: &mut spslam::system::SlamSystem, i: usize| {
        let (t, l, r) = images(&sequence, i);
        ok(slam.process(i, t, l.view(), r.view())).state
    };
    // Until local mapping is inside its first BA solve.
    loop {
        assert!(next < 40, "no local BA started in 40 frames");
        process(&mut slam, next);
        next += 1;
        if entered_rx.recv_timeout(Duration::from_millis(50)).is_ok() {
            break;
        }
    }
    let held_from = next;
    // While the solve is held, tracking completes frames and queues
    // keyframes (up to ORB-SLAM3's stereo queue of 3; a solve held much
    // longer starves tracking of new points, as it would in ORB-SLAM3).
    for _ in 0..4 {
        assert_eq!(process(&mut slam, next), TrackingState::Ok, "frame {next}");
        next += 1;
    }
    assert!(
        !released_by_test.load(Ordering::Acquire),
        "tracking waited for the held BA"
    );
    let inserted = slam.records()[held_from..]
        .iter()
        .filter(|r| r.keyframe)
        .count();
    eprintln!("held the BA from frame {held_from}; {inserted} keyframes inserted meanwhile");
    assert!(inserted > 0, "no keyframe queued while the BA was held");
    ok(release_tx.send(()));
    while next < sequence.len() {
        process(&mut slam, next);
        next += 1;
    }
    ok(slam.finish());
    assert!(released_by_test.load(Ordering::Acquire));
    // The queued keyframes did not abort the held BA (ORB-SLAM3's
    // InsertKeyFrame would have): stereo keyframes bring their own points,
    // and an aborted BA for every queued keyframe drifts a slow machine's
    // lap (tracking::keyframe::needs_keyframe). Only monocular tracking
    // interrupts it. No BA of the run was aborted.
    let aborted: Vec<usize> = slam
        .records()
        .iter()
        .filter(|r| r.mapping.as_ref().is_some_and(|m| m.bundle.aborted))
        .map(|r| r.index)
        .collect();
    assert!(aborted.is_empty(), "BAs aborted at frames {aborted:?}");
    let solved = slam
        .records()
        .iter()
        .filter(|r| {
            r.mapping
                .as_ref()
                .is_some_and(|m| m.bundle.local_keyframes > 0)
        })
        .count();
    assert!(solved > 0, "no local BA was solved");
    let lost: Vec<usize> = common::untracked(slam.records());
    assert!(lost.is_empty(), "lost frames {lost:?}");
}

#[test]
fn the_frame_lost_at_a_jump_back_is_localised_once_the_next_frame_relocalises() {
    // Round the block's first corner for 45 frames, then the camera jumps
    // back to where it was at frame 18, before the corner, and drives on.
    // The first frame there is lost (the motion model predicts the street
    // ahead); the next one relocalises in the map; the lost frame, kept,
    // is then matched against the keyframe the relocalisation found and
    // gets its pose after the fact, in the same map, against the ground
    // truth.
    let sequence = small_sequence(SceneName::Loop, 232);
    let mut slam = orb_slam(&sequence);
    let jump = 45;
    let inputs: Vec<usize> = (0..jump).chain(18..40).collect();
    process_inputs(&mut slam, &sequence, &inputs);
    ok(slam.finish());
    let records = slam.records();
    let summary = ok(slam.summary());
    let methods: Vec<_> = records[jump - 1..jump + 3]
        .iter()
        .map(|r| (r.index, r.map, r.state, r.method))
        .collect();
    eprintln!("around the jump: {methods:?}");
    assert_eq!(slam.atlas().maps().len(), 1, "no second map");
    assert_eq!(
        (records[jump].state, records[jump].method, records[jump].map),
        (TrackingState::Ok, TrackingMethod::AfterLoss, 0)
    );
    assert_eq!(records[jump + 1].method, TrackingMethod::Relocalisation);
    assert_eq!(summary.localised_after_loss, 1);
    let trajectory = ok(slam.trajectory());
    let truth = |k: usize| Se3::from_isometry(&sequence.pose(inputs[k]));
    // The late pose against the truth relative to frame 0, beside the
    // pose tracked live at the same place on the way out (frame 18).
    let relative =
        |poses: &dyn Fn(usize) -> Se3, k: usize| poses(0).inverse().compose(&poses(k)).translation;
    let off = |k: usize| (relative(&|j| trajectory[j].1, k) - relative(&truth, k)).norm();
    for k in [18, 19, 20, jump, jump + 1, jump + 2] {
        eprintln!("frame {k} (place {}): off by {:.4} m", inputs[k], off(k));
    }
    // Where the map itself puts that place (frame 18, tracked live on the
    // way out) is the best the late pose can do: measured 0.110 m off the
    // truth against frame 18's 0.107 m, the two estimates 0.039 m apart
    // (matched against the relocalised keyframe alone, before the local
    // map refined it: 0.260 m off the truth). Bounds: 0.06 m from frame
    // 18's estimate, and no more than 0.02 m further off the truth.
    let same_place = trajectory[18]
        .1
        .inverse()
        .compose(&trajectory[jump].1)
        .translation
        .norm();
    eprintln!("the late pose and frame 18's are {same_place:.4} m apart");
    assert!(same_place < 0.06, "{same_place} m from frame 18's pose");
    assert!(off(jump) < off(18) + 0.02, "{} m off", off(jump));
}
