//! `spslam extract` end to end: the JSON it writes, the picture, and its errors.

mod common;

use std::process::Command;

fn spslam() -> Command {
    Command::new(env!("CARGO_BIN_EXE_spslam"))
}

#[test]
fn extract_writes_json_and_a_picture() {
    let Some(data) = common::setup("extract_writes_json_and_a_picture") else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("spslam-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (json, png) = (dir.join("f.json"), dir.join("kp.png"));
    let image = data.join("kitti/sequences/06/image_0/000003.png");
    let out = spslam()
        .args([
            "extract",
            image.to_str().unwrap(),
            "--features",
            "500",
            "--anms",
            "ssc",
            "--json",
        ])
        .arg(&json)
        .arg("--draw")
        .arg(&png)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("500 keypoints") && stdout.contains("inference"),
        "{stdout}"
    );
    let value: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let kps = value["keypoints"].as_array().unwrap();
    let descs = value["descriptors"].as_array().unwrap();
    assert_eq!(kps.len(), 500);
    assert_eq!(descs.len(), 500);
    assert_eq!(descs[0].as_array().unwrap().len(), 256);
    for key in ["x", "y", "size", "angle", "response", "octave"] {
        assert!(kps[0].get(key).is_some(), "keypoint lacks {key}");
    }
    for key in [
        "preprocess",
        "inference",
        "decode_nms",
        "anms",
        "descriptors",
        "total",
    ] {
        assert!(
            value["timing_ms"][key].as_f64().is_some(),
            "timing_ms lacks {key}"
        );
    }
    let picture = std::fs::metadata(&png).unwrap();
    assert!(picture.len() > 10_000);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_arguments_fail_with_a_message() {
    let out = spslam()
        .args(["extract", "/nonexistent/a.png"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("error:"), "{stderr}");

    let out = spslam()
        .args(["extract", "x.png", "--anms", "fast"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("kdtree"));

    let out = spslam()
        .args(["extract", "x.png", "--features", "0"])
        .output()
        .unwrap();
    assert!(!out.status.success());

    // The phase-excess rule takes 0 (off) or a share above 1.
    let out = spslam()
        .args(["extract", "x.png", "--max-phase-share", "0.5"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("max_phase_share") && stderr.contains("0 (off) or a number > 1"),
        "{stderr}"
    );
}
