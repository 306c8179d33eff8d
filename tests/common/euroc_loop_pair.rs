//! The EuRoC V1_01_easy loop pair (`euroc/V1_01_easy_loop_pairs/`, the
//! frames of Kimera-VIO's loop-closure unit test) as a loop-closing map:
//! reading `pairs.txt`, rectifying, extracting and adding stereo keyframes
//! with their own map points.
//!
//! Shared by `tests/loop_pair_euroc.rs` and `benches/loop_verify.rs`
//! (included with `#[path]`), so it depends on nothing but the library: the
//! callers decide what a missing file means (a skip, a CI failure, a line
//! printed by a bench).
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use opencv::core::Mat;
use opencv::imgcodecs;
use opencv::prelude::*;
use spslam::camera::CameraRig;
use spslam::dataset::{CameraCalibration, StereoRectifier};
use spslam::eval::Trajectory;
use spslam::features::{GrayImage, SuperPointExtractor};
use spslam::map::{KeyFrameId, Map, PointDescriptor};
use spslam::optim::{LieGroup, Se3};
use spslam::settings::{SlamSettings, DEFAULT_SUPERPOINT_LEVELS};
use spslam::tracking::{Extractors, FrameBuilder, Frontend, SensorImages};

/// The pair folder under the shared data root.
pub const PAIR_DIR: &str = "euroc/V1_01_easy_loop_pairs";
/// OpenVINS's V1_01 ground truth, under the shared data root.
pub const OPENVINS_GT: &str =
    "euroc/V1_01_easy_first95/groundtruth_extra/V1_01_easy_openvins_tum.txt";
/// The files of the pair folder that must be there.
pub const PAIR_FILES: [&str; 5] = [
    "pairs.txt",
    "sensorLeft.yaml",
    "sensorRight.yaml",
    "left_img_0.png",
    "right_img_3.png",
];

/// The pair folder under `data_root`, or `Err` with what is missing.
pub fn pair_dir(data_root: &Path) -> Result<PathBuf, String> {
    let dir = data_root.join(PAIR_DIR);
    if PAIR_FILES.iter().all(|f| dir.join(f).is_file()) {
        Ok(dir)
    } else {
        Err(format!("the EuRoC loop pairs ({})", dir.display()))
    }
}

/// One line of `pairs.txt`.
#[derive(Debug, Clone)]
pub struct PairFrame {
    pub left: PathBuf,
    pub right: PathBuf,
    pub timestamp_ns: u64,
    /// `T_w_body` (Vicon ground truth).
    pub t_wb: Isometry3<f64>,
}

impl PairFrame {
    pub fn timestamp(&self) -> f64 {
        self.timestamp_ns as f64 * 1e-9
    }
}

/// Reads `pairs.txt`: role → frame.
pub fn read_pairs(dir: &Path) -> Vec<(String, PairFrame)> {
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

pub fn role<'a>(pairs: &'a [(String, PairFrame)], name: &str) -> &'a PairFrame {
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

/// The rectifier, the rig and `T_body_rect` (body ← rectified left camera).
pub struct EurocRig {
    pub rectifier: StereoRectifier,
    pub rig: CameraRig,
    pub settings: SlamSettings,
    pub t_body_rect: Isometry3<f64>,
}

impl EurocRig {
    /// Ground truth `T_q,m`: query camera ← match camera (rectified left
    /// cameras), from the two body poses `T_w_body`.
    pub fn relative(&self, t_wb_m: Isometry3<f64>, t_wb_q: Isometry3<f64>) -> Isometry3<f64> {
        (t_wb_q * self.t_body_rect).inverse() * (t_wb_m * self.t_body_rect)
    }
}

pub fn euroc_rig(dir: &Path) -> EurocRig {
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
    let rig = CameraRig::from_settings(&settings, w as usize, h as usize)
        .unwrap_or_else(|e| panic!("rig: {e}"));
    let r1 = rectifier.left_rotation();
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
pub fn load(rig: &EurocRig, f: &PairFrame) -> (GrayImage, GrayImage) {
    let pair = rig
        .rectifier
        .rectify(&read_gray(&f.left), &read_gray(&f.right))
        .unwrap_or_else(|e| panic!("rectifying {}: {e}", f.left.display()));
    let image = |m: &Mat| GrayImage::from_mat(m).unwrap_or_else(|e| panic!("{e}"));
    (image(&pair.left), image(&pair.right))
}

/// Two SuperPoint extractors (`spslam run`'s defaults for this rig, one
/// thread each) and the stereo matcher.
pub fn frontend(rig: &EurocRig) -> (Extractors, FrameBuilder) {
    let config = rig
        .settings
        .extractor
        .superpoint_config(DEFAULT_SUPERPOINT_LEVELS, 1);
    let sp = || {
        Box::new(
            SuperPointExtractor::new(config.clone())
                .unwrap_or_else(|e| panic!("cannot create the extractor: {e}")),
        )
    };
    Frontend::new(sp(), sp(), &rig.rig).into_parts()
}

/// Adds frame `f` as a keyframe at `pose_cw` with one new map point per
/// stereo keypoint (as stereo initialisation does). Returns the keyframe,
/// its keypoints and its new points.
pub fn add_stereo_keyframe(
    map: &mut Map,
    (extractors, matcher): &mut (Extractors, FrameBuilder),
    rig: &EurocRig,
    index: usize,
    f: &PairFrame,
    pose_cw: Se3,
) -> (KeyFrameId, usize, usize) {
    let (l, r) = load(rig, f);
    let images = SensorImages::Stereo {
        left: l.view(),
        right: r.view(),
    };
    let features = extractors
        .extract(index, images)
        .unwrap_or_else(|e| panic!("extraction: {e}"));
    let (mut frame, _) = matcher
        .build_frame(index, f.timestamp(), features, images, &rig.rig)
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

/// Where a drifted map would have the query keyframe: 3 m and 20° off
/// `truth` (`T_cw` of the query in the match keyframe's frame).
pub fn drifted_pose(truth: &Isometry3<f64>) -> Se3 {
    let drift = Isometry3::new(
        Vector3::new(2.0, -1.5, 1.5),
        Vector3::new(0.2, -0.1, 0.25).normalize() * 20f64.to_radians(),
    );
    Se3::from_isometry(&(drift * truth))
}

/// A keyframe added by [`add_stereo_keyframe`], with its counts.
#[derive(Debug, Clone, Copy)]
pub struct PairKeyframe {
    pub id: KeyFrameId,
    pub keypoints: usize,
    pub points: usize,
    pub pose_cw: Se3,
}

/// The loop map: keyframe A (`match1`) at the origin and keyframe B
/// (`query1`) at [`drifted_pose`] of `truth` (`T_q,m`), each with its own
/// stereo points and no point shared, so nothing but the loop check
/// relates them.
pub struct LoopPairMap {
    pub map: Map,
    pub a: PairKeyframe,
    pub b: PairKeyframe,
}

/// Builds the [`LoopPairMap`] with the frontend `fe`; keyframe indices 0
/// (A) and 1 (B).
pub fn build_loop_map(
    fe: &mut (Extractors, FrameBuilder),
    rig: &EurocRig,
    matched: &PairFrame,
    query: &PairFrame,
    truth: &Isometry3<f64>,
) -> LoopPairMap {
    let mut map = Map::new();
    let a = add_keyframe(&mut map, fe, rig, 0, matched, Se3::identity());
    let b = add_keyframe(&mut map, fe, rig, 1, query, drifted_pose(truth));
    LoopPairMap { map, a, b }
}

/// [`add_stereo_keyframe`] returning a [`PairKeyframe`].
pub fn add_keyframe(
    map: &mut Map,
    fe: &mut (Extractors, FrameBuilder),
    rig: &EurocRig,
    index: usize,
    f: &PairFrame,
    pose_cw: Se3,
) -> PairKeyframe {
    let (id, keypoints, points) = add_stereo_keyframe(map, fe, rig, index, f, pose_cw);
    PairKeyframe {
        id,
        keypoints,
        points,
        pose_cw,
    }
}

/// OpenVINS's body pose at a camera timestamp (its rows are at the camera
/// times, printed to 10 µs).
pub fn openvins_pose(gt: &Trajectory, timestamp_ns: u64) -> Isometry3<f64> {
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
pub fn pose_error(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> (f64, f64) {
    (
        (estimate.translation.vector - truth.translation.vector).norm(),
        angle_deg(&(estimate.rotation * truth.rotation.inverse())),
    )
}

/// Rotation angle of `r` in degrees.
pub fn angle_deg(r: &UnitQuaternion<f64>) -> f64 {
    r.angle().to_degrees()
}
