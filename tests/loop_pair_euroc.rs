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
//!   [`StereoSlam`] with loop closing on (thresholds loosened so that the
//!   check really runs, from the second keyframe on, and one verification
//!   would be accepted) runs over them in time order (query2 first) and
//!   must report no loop: the second keyframe tracked the first and shares
//!   its points, so the first is in the covisible neighbourhood the
//!   detector excludes.
//!
//! Missing data or models fail under `CI=true` and skip elsewhere.

mod common;

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use nalgebra::{Isometry3, Matrix3, Quaternion, Translation3, UnitQuaternion, Vector3};
use opencv::calib3d;
use opencv::core::{Mat, Rect, Size};
use opencv::imgcodecs;
use opencv::prelude::*;
use spslam::camera::StereoRig;
use spslam::dataset::{CameraCalibration, StereoRectifier};
use spslam::eval::{read_tum, Trajectory};
use spslam::features::GrayImage;
use spslam::loop_closing::{verify_candidate, LoopDetector, LoopThresholds, Verification};
use spslam::map::{KeyFrameId, Map, PointDescriptor};
use spslam::optim::{LieGroup, Se3};
use spslam::place::{default_codebook_path, Codebook};
use spslam::settings::{SlamSettings, DEFAULT_SUPERPOINT_LEVELS};
use spslam::system::StereoSlam;
use spslam::tracking::{StereoExtractors, StereoFrontend, StereoMatcher};

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
/// OpenVINS's V1_01 ground truth, under the shared data root.
const OPENVINS_GT: &str = "euroc/V1_01_easy_first95/groundtruth_extra/V1_01_easy_openvins_tum.txt";

/// One line of `pairs.txt`.
#[derive(Debug, Clone)]
struct PairFrame {
    left: PathBuf,
    right: PathBuf,
    timestamp_ns: u64,
    /// `T_w_body` (Vicon ground truth).
    t_wb: Isometry3<f64>,
}

impl PairFrame {
    fn timestamp(&self) -> f64 {
        self.timestamp_ns as f64 * 1e-9
    }
}

/// The pair folder, or `None` after [`common::missing`].
fn pair_dir(test: &str) -> Option<PathBuf> {
    let dir = common::shared_data_root().join("euroc/V1_01_easy_loop_pairs");
    let needed = [
        "pairs.txt",
        "sensorLeft.yaml",
        "sensorRight.yaml",
        "left_img_0.png",
        "right_img_3.png",
    ];
    if needed.iter().all(|f| dir.join(f).is_file()) {
        Some(dir)
    } else {
        common::missing(test, &format!("the EuRoC loop pairs ({})", dir.display()));
        None
    }
}

/// Reads `pairs.txt`: role → frame.
fn read_pairs(dir: &Path) -> Vec<(String, PairFrame)> {
    let path = dir.join("pairs.txt");
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let f: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(
            f.len(),
            11,
            "{}:{}: expected 11 fields, got {}",
            path.display(),
            n + 1,
            f.len()
        );
        let num = |i: usize| -> f64 {
            f[i].parse()
                .unwrap_or_else(|e| panic!("{}:{}: `{}`: {e}", path.display(), n + 1, f[i]))
        };
        let timestamp_ns = f[3]
            .parse()
            .unwrap_or_else(|e| panic!("{}:{}: `{}`: {e}", path.display(), n + 1, f[3]));
        let rotation =
            UnitQuaternion::from_quaternion(Quaternion::new(num(10), num(7), num(8), num(9)));
        let t_wb = Isometry3::from_parts(Translation3::new(num(4), num(5), num(6)), rotation);
        out.push((
            f[0].to_string(),
            PairFrame {
                left: dir.join(f[1]),
                right: dir.join(f[2]),
                timestamp_ns,
                t_wb,
            },
        ));
    }
    out
}

fn role<'a>(pairs: &'a [(String, PairFrame)], name: &str) -> &'a PairFrame {
    pairs
        .iter()
        .find(|(r, _)| r == name)
        .map(|(_, f)| f)
        .unwrap_or_else(|| panic!("pairs.txt has no `{name}` line"))
}

fn read_gray(path: &Path) -> Mat {
    let text = path
        .to_str()
        .unwrap_or_else(|| panic!("non-UTF-8 path {}", path.display()));
    let m = imgcodecs::imread(text, imgcodecs::IMREAD_GRAYSCALE)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(!m.empty(), "{}: could not be decoded", path.display());
    m
}

/// OpenCV's rectification rotation `R1` of the left camera (points in raw
/// cam0 → points in the rectified left camera), computed with exactly the
/// arguments [`StereoRectifier::from_euroc`] uses (it keeps `R1` to itself).
/// Also returns the rectified `fx` and baseline to check that the two agree.
fn left_rectification_rotation(
    cam0: &CameraCalibration,
    cam1: &CameraCalibration,
) -> (Matrix3<f64>, f64, f64) {
    let cv = |e: opencv::Error| -> ! { panic!("OpenCV: {e}") };
    let mat3 = |m: &Matrix3<f64>| {
        Mat::from_slice_2d(&[
            [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
            [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
            [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
        ])
        .unwrap_or_else(|e| cv(e))
    };
    let t_bs1_inv = cam1
        .t_bs
        .try_inverse()
        .unwrap_or_else(|| panic!("cam1 T_BS is singular"));
    let t_c1_c0 = t_bs1_inv * cam0.t_bs;
    let r: Matrix3<f64> = t_c1_c0.fixed_view::<3, 3>(0, 0).into_owned();
    let t = t_c1_c0.fixed_view::<3, 1>(0, 3).into_owned();
    let size = Size::new(cam0.width as i32, cam0.height as i32);
    let d0 = Mat::from_slice_2d(&[cam0.distortion]).unwrap_or_else(|e| cv(e));
    let d1 = Mat::from_slice_2d(&[cam1.distortion]).unwrap_or_else(|e| cv(e));
    let t_cv = Mat::from_slice_2d(&[[t.x], [t.y], [t.z]]).unwrap_or_else(|e| cv(e));
    let (mut r0, mut r1, mut p0, mut p1, mut q) = (
        Mat::default(),
        Mat::default(),
        Mat::default(),
        Mat::default(),
        Mat::default(),
    );
    let (mut roi0, mut roi1) = (Rect::default(), Rect::default());
    calib3d::stereo_rectify(
        &mat3(&cam0.camera_matrix()),
        &d0,
        &mat3(&cam1.camera_matrix()),
        &d1,
        size,
        &mat3(&r),
        &t_cv,
        &mut r0,
        &mut r1,
        &mut p0,
        &mut p1,
        &mut q,
        calib3d::CALIB_ZERO_DISPARITY,
        0.0,
        size,
        Some(&mut roi0),
        Some(&mut roi1),
    )
    .unwrap_or_else(|e| cv(e));
    let at = |m: &Mat, r: i32, c: i32| *m.at_2d::<f64>(r, c).unwrap_or_else(|e| cv(e));
    let mut rot = Matrix3::zeros();
    for i in 0..3 {
        for j in 0..3 {
            rot[(i, j)] = at(&r0, i as i32, j as i32);
        }
    }
    let fx = at(&p0, 0, 0);
    let baseline = -at(&p1, 0, 3) / at(&p1, 0, 0);
    (rot, fx, baseline)
}

/// The rectifier, the rig and `T_body_rect` (body ← rectified left camera).
struct EurocRig {
    rectifier: StereoRectifier,
    rig: StereoRig,
    settings: SlamSettings,
    t_body_rect: Isometry3<f64>,
}

fn euroc_rig(dir: &Path) -> EurocRig {
    let calib = |name: &str| {
        let path = dir.join(name);
        CameraCalibration::from_sensor_yaml(&path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    };
    let (cam0, cam1) = (calib("sensorLeft.yaml"), calib("sensorRight.yaml"));
    let rectifier =
        StereoRectifier::from_euroc(&cam0, &cam1).unwrap_or_else(|e| panic!("rectification: {e}"));
    let mut settings = SlamSettings::rectified_stereo(
        rectifier.fx(),
        rectifier.fy(),
        rectifier.cx(),
        rectifier.cy(),
        rectifier.baseline(),
    );
    settings.camera.fps = 20.0;
    let (w, h) = rectifier.image_size();
    let rig = StereoRig::from_settings(&settings, w as usize, h as usize)
        .unwrap_or_else(|e| panic!("rig: {e}"));
    let (r1, fx, baseline) = left_rectification_rotation(&cam0, &cam1);
    assert!(
        (fx - rectifier.fx()).abs() < 1e-9 && (baseline - rectifier.baseline()).abs() < 1e-12,
        "the recomputed rectification (fx {fx}, b {baseline}) differs from the library's \
         (fx {}, b {})",
        rectifier.fx(),
        rectifier.baseline()
    );
    let t_body_cam0 = Se3::from_matrix(&cam0.t_bs).to_isometry();
    // p_rect = R1 · p_cam0, so T_cam0_rect = [R1ᵀ | 0].
    let t_cam0_rect = Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_matrix(&r1.transpose()),
    );
    let angle = UnitQuaternion::from_matrix(&r1).angle().to_degrees();
    eprintln!(
        "rectified: fx {:.3} fy {:.3} cx {:.3} cy {:.3} baseline {:.5} m, R1 turns cam0 by {angle:.3}°",
        rectifier.fx(),
        rectifier.fy(),
        rectifier.cx(),
        rectifier.cy(),
        rectifier.baseline()
    );
    EurocRig {
        rectifier,
        rig,
        settings,
        t_body_rect: t_body_cam0 * t_cam0_rect,
    }
}

/// The rectified pair of a frame.
fn load(rig: &EurocRig, f: &PairFrame) -> (GrayImage, GrayImage) {
    let pair = rig
        .rectifier
        .rectify(&read_gray(&f.left), &read_gray(&f.right))
        .unwrap_or_else(|e| panic!("rectifying {}: {e}", f.left.display()));
    let image = |m: &Mat| GrayImage::from_mat(m).unwrap_or_else(|e| panic!("{e}"));
    (image(&pair.left), image(&pair.right))
}

fn frontend(rig: &EurocRig) -> (StereoExtractors, StereoMatcher) {
    let config = rig
        .settings
        .extractor
        .superpoint_config(DEFAULT_SUPERPOINT_LEVELS, 1);
    let sp = || Box::new(common::extractor(config.clone()));
    StereoFrontend::new(sp(), sp(), &rig.rig).into_parts()
}

/// Adds frame `f` as a keyframe at `pose_cw` with one new map point per
/// stereo keypoint (as stereo initialisation does).
fn add_stereo_keyframe(
    map: &mut Map,
    (extractors, matcher): &mut (StereoExtractors, StereoMatcher),
    rig: &EurocRig,
    index: usize,
    f: &PairFrame,
    pose_cw: Se3,
) -> (KeyFrameId, usize, usize) {
    let (l, r) = load(rig, f);
    let features = extractors
        .extract(index, l.view(), r.view())
        .unwrap_or_else(|e| panic!("extraction: {e}"));
    let (mut frame, _) = matcher
        .match_frame(
            index,
            f.timestamp(),
            features,
            (l.view(), r.view()),
            &rig.rig,
        )
        .unwrap_or_else(|e| panic!("stereo matching: {e}"));
    frame.pose_cw = pose_cw;
    let kf = map
        .add_keyframe(index, f.timestamp(), pose_cw, frame.measurements())
        .unwrap_or_else(|e| panic!("add_keyframe: {e}"));
    let mut points = 0;
    for i in 0..frame.len() {
        let (Some(position), Some(descriptor)) = (
            frame.unproject_world(i, &rig.rig),
            PointDescriptor::from_set(&frame.features.descriptors, i),
        ) else {
            continue;
        };
        let id = map
            .add_map_point(position, descriptor, kf)
            .unwrap_or_else(|e| panic!("add_map_point: {e}"));
        map.add_observation(id, kf, i)
            .unwrap_or_else(|e| panic!("add_observation: {e}"));
        map.update_descriptor(id);
        map.update_normal_and_depth(id);
        points += 1;
    }
    map.update_connections(kf);
    (kf, frame.len(), points)
}

/// OpenVINS's body pose at a camera timestamp (its rows are at the camera
/// times, printed to 10 µs).
fn openvins_pose(gt: &Trajectory, timestamp_ns: u64) -> Isometry3<f64> {
    let t = timestamp_ns as f64 * 1e-9;
    let (i, dt) = gt
        .timestamps
        .iter()
        .enumerate()
        .map(|(i, s)| (i, (s - t).abs()))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or_else(|| panic!("{OPENVINS_GT} is empty"));
    assert!(
        dt < 1e-4,
        "{OPENVINS_GT} has no pose within 0.1 ms of {t:.6} s ({dt} s away)"
    );
    gt.poses[i]
}

/// Translation (metres) and rotation (degrees) between two relative poses.
fn pose_error(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> (f64, f64) {
    (
        (estimate.translation.vector - truth.translation.vector).norm(),
        angle_deg(&(estimate.rotation * truth.rotation.inverse())),
    )
}

/// Rotation angle of `r` in degrees.
fn angle_deg(r: &UnitQuaternion<f64>) -> f64 {
    r.angle().to_degrees()
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
    let relative = |t_wb_m: Isometry3<f64>, t_wb_q: Isometry3<f64>| {
        (t_wb_q * rig.t_body_rect).inverse() * (t_wb_m * rig.t_body_rect)
    };
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

    let mut fe = frontend(&rig);
    let mut map = Map::new();
    let (a, a_keypoints, a_points) =
        add_stereo_keyframe(&mut map, &mut fe, &rig, 0, matched, Se3::identity());
    // B where a drifted map would have it: 3 m and 20° off the truth.
    let drift = Isometry3::new(
        Vector3::new(2.0, -1.5, 1.5),
        Vector3::new(0.2, -0.1, 0.25).normalize() * 20f64.to_radians(),
    );
    let b_pose = Se3::from_isometry(&(drift * truth));
    let (b, b_keypoints, b_points) = add_stereo_keyframe(&mut map, &mut fe, &rig, 1, query, b_pose);
    eprintln!(
        "keyframe A (match1): {a_keypoints} keypoints, {a_points} stereo points; \
         keyframe B (query1): {b_keypoints} keypoints, {b_points} stereo points; \
         B placed {:.2} m / {:.1}° off the truth",
        (b_pose.translation - truth.translation.vector).norm(),
        angle_deg(&(b_pose.rotation * truth.rotation.inverse()))
    );
    assert!(
        map.best_covisible(a, 10).is_empty(),
        "A and B must share no point"
    );

    let th = LoopThresholds::default();
    let verification = verify_candidate(&map, b, a, &rig.rig, &th)
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
    let config = rig
        .settings
        .extractor
        .superpoint_config(DEFAULT_SUPERPOINT_LEVELS, 1);
    let codebook_path = default_codebook_path();
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
    let mut slam = StereoSlam::new(rig.rig, StereoFrontend::new(sp(), sp(), &rig.rig));
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
