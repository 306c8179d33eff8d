//! The metrics against evo 1.38.1 and the KITTI devkit on evo's test data.
//!
//! evo figures were produced in a throwaway venv (`python3 -m venv /tmp/evo &&
//! /tmp/evo/bin/pip install evo==1.38.1`), in `trajectories/evo_test_data`:
//!
//! ```text
//! evo_ape kitti KITTI_00_gt.txt KITTI_00_ORB.txt            # rmse 7.790289
//! evo_ape kitti KITTI_00_gt.txt KITTI_00_ORB.txt -a         # rmse 1.303450
//! evo_ape kitti KITTI_00_gt.txt KITTI_00_ORB.txt -as -v     # rmse 0.937709, scale 1.0046980764526638
//! evo_rpe kitti KITTI_00_gt.txt KITTI_00_ORB.txt --delta 1 --delta_unit f -r trans_part  # rmse 0.028120
//! evo_rpe kitti KITTI_00_gt.txt KITTI_00_ORB.txt --delta 1 --delta_unit f -r angle_deg   # rmse 0.114974
//! evo_rpe kitti KITTI_00_gt.txt KITTI_00_ORB.txt --delta 100 --delta_unit m -r trans_part # rmse 1.193976
//! evo_rpe kitti KITTI_00_gt.txt KITTI_00_ORB.txt --delta 100 --delta_unit m -r angle_deg  # rmse 0.728836
//! evo_ape tum fr2_desk_groundtruth.txt fr2_desk_ORB.txt      # rmse 3.173994 (2174 matches)
//! evo_ape tum fr2_desk_groundtruth.txt fr2_desk_ORB.txt -a   # rmse 0.008119
//! evo_ape tum fr2_desk_groundtruth.txt fr2_desk_ORB.txt -as -v  # rmse 0.006123, scale 0.9969698308032563
//! evo_rpe tum fr2_desk_groundtruth.txt fr2_desk_ORB.txt --delta 1 --delta_unit f -r trans_part  # rmse 0.003490
//! evo_rpe tum fr2_desk_groundtruth.txt fr2_desk_ORB.txt --delta 1 --delta_unit f -r angle_deg   # rmse 0.280519
//! evo_rpe tum fr2_desk_groundtruth.txt fr2_desk_ORB.txt --delta 1 --delta_unit m -r trans_part  # rmse 0.011672
//! evo_rpe tum fr2_desk_groundtruth.txt fr2_desk_ORB.txt --delta 1 --delta_unit m -r angle_deg   # rmse 0.687341
//! evo_ape euroc V102_groundtruth.csv V102.txt -v             # rmse 2.554174 (798 matches)
//! evo_ape euroc V102_groundtruth.csv V102.txt -a             # rmse 0.091727
//! evo_ape euroc V102_groundtruth.csv V102.txt -as -v         # rmse 0.083841, scale 0.9796982521745786
//! evo_rpe euroc V102_groundtruth.csv V102.txt --delta 1 --delta_unit f -r trans_part  # rmse 0.015077
//! evo_rpe euroc V102_groundtruth.csv V102.txt --delta 1 --delta_unit f -r angle_deg   # rmse 0.357616
//! ```
//!
//! (`evo_ape euroc` reads the ground truth as EuRoC csv and the estimate as TUM.)
//! The KITTI metric figures (3283 segments, 0.6997 %, 0.2533 deg/100m) are the devkit's.

mod common;

use common::{assert_sig4, evo_data};
use spslam::eval::{
    evaluate, read_euroc, read_kitti, read_tum, EvalOptions, EvalReport, Pairing, RpeDelta,
};

fn report(
    gt: &spslam::eval::Trajectory,
    est: &spslam::eval::Trajectory,
    pairing: Pairing,
    rpe: Vec<RpeDelta>,
) -> EvalReport {
    let options = EvalOptions {
        pairing,
        rpe_deltas: Some(rpe),
    };
    evaluate(gt, est, &options).expect("evaluation")
}

#[test]
fn kitti_00_orb_matches_devkit_and_evo() {
    let Some(dir) = evo_data("kitti_00_orb_matches_devkit_and_evo") else {
        return;
    };
    let gt = read_kitti(&dir.join("KITTI_00_gt.txt")).unwrap();
    let est = read_kitti(&dir.join("KITTI_00_ORB.txt")).unwrap();
    let r = report(
        &gt,
        &est,
        Pairing::ByIndex,
        vec![RpeDelta::Frames(1), RpeDelta::Meters(100.0)],
    );
    let k = r.kitti.as_ref().expect("KITTI metric");
    assert_eq!(k.segments, 3283);
    assert_sig4("t_err %", k.t_err_pct, 0.6997);
    assert_sig4("r_err deg/100m", k.r_err_deg_per_100m, 0.2533);
    assert_sig4("r_err deg/m", k.r_err_deg_per_m, 0.002533);
    assert_eq!(k.per_length.len(), 8);
    assert_eq!(k.per_length.iter().map(|l| l.segments).sum::<usize>(), 3283);
    assert_sig4("ATE none", r.ate.none_rmse, 7.790289);
    assert_sig4("ATE SE3", r.ate.se3_rmse, 1.303450);
    assert_sig4("ATE Sim3", r.ate.sim3_rmse, 0.937709);
    assert_sig4("Sim3 scale", r.ate.sim3_scale, 1.0046980764526638);
    let f1 = &r.rpe["frames_1"];
    assert_sig4("RPE f1 trans", f1.trans_rmse, 0.028120);
    assert_sig4("RPE f1 rot", f1.rot_rmse_deg, 0.114974);
    let m100 = &r.rpe["meters_100"];
    assert_sig4("RPE 100 m trans", m100.trans_rmse, 1.193976);
    assert_sig4("RPE 100 m rot", m100.rot_rmse_deg, 0.728836);
}

#[test]
fn tum_fr2_desk_orb_matches_evo() {
    let Some(dir) = evo_data("tum_fr2_desk_orb_matches_evo") else {
        return;
    };
    let gt = read_tum(&dir.join("fr2_desk_groundtruth.txt")).unwrap();
    let est = read_tum(&dir.join("fr2_desk_ORB.txt")).unwrap();
    let r = report(
        &gt,
        &est,
        Pairing::ByTimestamp {
            max_diff: 0.01,
            one_to_one: true,
        },
        vec![RpeDelta::Frames(1), RpeDelta::Meters(1.0)],
    );
    assert_eq!(r.matched_poses, 2174);
    assert!(
        r.kitti.is_none(),
        "18 m of ground truth holds no 100 m segment"
    );
    assert_sig4("ATE none", r.ate.none_rmse, 3.173994);
    assert_sig4("ATE SE3", r.ate.se3_rmse, 0.008119);
    assert_sig4("ATE Sim3", r.ate.sim3_rmse, 0.006123);
    assert_sig4("Sim3 scale", r.ate.sim3_scale, 0.9969698308032563);
    assert_sig4("RPE f1 trans", r.rpe["frames_1"].trans_rmse, 0.003490);
    assert_sig4("RPE f1 rot", r.rpe["frames_1"].rot_rmse_deg, 0.280519);
    assert_sig4("RPE 1 m trans", r.rpe["meters_1"].trans_rmse, 0.011672);
    assert_sig4("RPE 1 m rot", r.rpe["meters_1"].rot_rmse_deg, 0.687341);
}

#[test]
fn euroc_v102_matches_evo() {
    let Some(dir) = evo_data("euroc_v102_matches_evo") else {
        return;
    };
    let gt = read_euroc(&dir.join("V102_groundtruth.csv")).unwrap();
    let est = read_tum(&dir.join("V102.txt")).unwrap();
    // V102.txt repeats 4 timestamps; evo pairs each copy with the same ground-truth pose.
    let evo_rule = Pairing::ByTimestamp {
        max_diff: 0.01,
        one_to_one: false,
    };
    let r = report(&gt, &est, evo_rule, vec![RpeDelta::Frames(1)]);
    assert_eq!(r.matched_poses, 798);
    assert_sig4("ATE none", r.ate.none_rmse, 2.554174);
    assert_sig4("ATE SE3", r.ate.se3_rmse, 0.091727);
    assert_sig4("ATE Sim3", r.ate.sim3_rmse, 0.083841);
    assert_sig4("Sim3 scale", r.ate.sim3_scale, 0.9796982521745786);
    assert_sig4("RPE f1 trans", r.rpe["frames_1"].trans_rmse, 0.015077);
    assert_sig4("RPE f1 rot", r.rpe["frames_1"].rot_rmse_deg, 0.357616);

    // One to one (the default) drops the 4 repeats.
    let one_to_one = Pairing::ByTimestamp {
        max_diff: 0.01,
        one_to_one: true,
    };
    let r = report(&gt, &est, one_to_one, vec![RpeDelta::Frames(1)]);
    assert_eq!(r.matched_poses, 794);
    assert!((r.ate.se3_rmse - 0.091727).abs() < 1e-3);
}
