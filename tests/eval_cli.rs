//! `spslam eval` on KITTI_00: JSON keys and values, and the plots.

mod common;

use std::process::Command;

use common::{assert_sig4, evo_data};

#[test]
fn eval_kitti_00_writes_json_and_plots() {
    let Some(dir) = evo_data("eval_kitti_00_writes_json_and_plots") else {
        return;
    };
    let out = std::env::temp_dir().join(format!("spslam_eval_cli_{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    let json = out.join("kitti00.json");
    let plot = out.join("kitti00.png");
    let output = Command::new(env!("CARGO_BIN_EXE_spslam"))
        .arg("eval")
        .arg("--gt")
        .arg(dir.join("KITTI_00_gt.txt"))
        .arg("--est")
        .arg(dir.join("KITTI_00_ORB.txt"))
        .arg("--json")
        .arg(&json)
        .arg("--plot")
        .arg(&plot)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(stdout.contains("3283 segments"), "{stdout}");
    // KITTI's camera frame (y down) is drawn from above: x–z.
    assert!(stdout.contains("(xz plane)"), "{stdout}");

    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let num = |p: &str| {
        v.pointer(p)
            .and_then(serde_json::Value::as_f64)
            .unwrap_or_else(|| panic!("missing {p} in {v}"))
    };
    assert_eq!(num("/kitti/segments"), 3283.0);
    assert_sig4("t_err", num("/kitti/t_err_pct"), 0.6997);
    assert_sig4("r_err/m", num("/kitti/r_err_deg_per_m"), 0.002533);
    assert_sig4("r_err/100m", num("/kitti/r_err_deg_per_100m"), 0.2533);
    assert_eq!(
        v.pointer("/kitti/per_length")
            .and_then(|p| p.as_array())
            .map(Vec::len),
        Some(8)
    );
    assert_sig4("ATE none", num("/ate/none_rmse"), 7.790289);
    assert_sig4("ATE SE3", num("/ate/se3_rmse"), 1.303450);
    assert_sig4("ATE Sim3", num("/ate/sim3_rmse"), 0.937709);
    assert_sig4("scale", num("/ate/sim3_scale"), 1.0046980764526638);
    assert_sig4("RPE f1 t", num("/rpe/frames_1/trans_rmse"), 0.028120);
    assert_sig4("RPE f1 r", num("/rpe/frames_1/rot_rmse_deg"), 0.114974);
    assert_sig4("RPE 100 m t", num("/rpe/meters_100/trans_rmse"), 1.193976);

    for png in [plot.clone(), out.join("kitti00_errors.png")] {
        let bytes = std::fs::read(&png).unwrap_or_else(|e| panic!("{}: {e}", png.display()));
        assert!(
            bytes.len() > 1000 && bytes.starts_with(b"\x89PNG"),
            "{}",
            png.display()
        );
    }
    // The plane can be chosen.
    let side = out.join("side.png");
    let output = Command::new(env!("CARGO_BIN_EXE_spslam"))
        .arg("eval")
        .arg("--gt")
        .arg(dir.join("KITTI_00_gt.txt"))
        .arg("--est")
        .arg(dir.join("KITTI_00_ORB.txt"))
        .arg("--plot")
        .arg(&side)
        .args(["--plot-plane", "yz"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success() && stdout.contains("(yz plane)"),
        "{stdout}"
    );
    assert!(side.exists());
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn eval_reports_a_bad_file() {
    let out = std::env::temp_dir().join(format!("spslam_eval_cli_bad_{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    let bad = out.join("bad.txt");
    std::fs::write(&bad, "0 0 0 0 0 0 0 1\n1 0 0 nan? 0 0 0 1\n").unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_spslam"))
        .args(["eval", "--gt"])
        .arg(&bad)
        .arg("--est")
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("bad.txt:2"), "{stderr}");
    std::fs::remove_dir_all(&out).ok();
}
