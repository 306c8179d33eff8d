"""spslam.eval against evo 1.38.1's and the KITTI devkit's figures on evo's
test data (the figures tests/eval_evo.rs documents), and against
`spslam eval --json`."""

import json

import numpy as np
import pytest

import spslam
from conftest import run_cli


def sig4(actual, expected):
    assert actual == pytest.approx(expected, rel=5e-4), (actual, expected)


def test_kitti_00_against_evo_and_the_devkit(evo_data):
    gt, est = evo_data / "KITTI_00_gt.txt", evo_data / "KITTI_00_ORB.txt"
    sig4(spslam.eval.ate(gt, est, alignment="none")["stats"]["rmse"], 7.790289)
    sig4(spslam.eval.ate(gt, est)["stats"]["rmse"], 1.303450)
    sim3 = spslam.eval.ate(gt, est, alignment="sim3")
    sig4(sim3["stats"]["rmse"], 0.937709)
    sig4(sim3["scale"], 1.0046980764526638)
    sig4(spslam.eval.rpe(gt, est)["translation"]["rmse"], 0.028120)
    sig4(spslam.eval.rpe(gt, est)["rotation_deg"]["rmse"], 0.114974)
    m100 = spslam.eval.rpe(gt, est, delta=100, unit="meters")
    sig4(m100["translation"]["rmse"], 1.193976)
    sig4(m100["rotation_deg"]["rmse"], 0.728836)
    kitti = spslam.eval.kitti_metric(gt, est)
    assert kitti["segments"] == 3283
    sig4(kitti["t_err_pct"], 0.6997)
    sig4(kitti["r_err_deg_per_100m"], 0.2533)


def test_arrays_equal_files(evo_data):
    gt_file, est_file = evo_data / "KITTI_00_gt.txt", evo_data / "KITTI_00_ORB.txt"
    _, gt = spslam.eval.read_trajectory(gt_file)
    _, est = spslam.eval.read_trajectory(est_file)
    assert gt.shape == (4541, 4, 4)
    from_files = spslam.eval.ate(gt_file, est_file)
    from_arrays = spslam.eval.ate(gt, est)
    from_3x4 = spslam.eval.ate(gt[:, :3, :], est[:, :3, :])
    assert from_arrays == from_files == from_3x4
    assert spslam.eval.kitti_metric(gt, est) == spslam.eval.kitti_metric(gt_file, est_file)


def test_tum_files_are_associated_by_time(evo_data):
    gt, est = evo_data / "fr2_desk_groundtruth.txt", evo_data / "fr2_desk_ORB.txt"
    none = spslam.eval.ate(gt, est, alignment="none")
    assert none["stats"]["count"] == 2174
    sig4(none["stats"]["rmse"], 3.173994)
    sig4(spslam.eval.ate(gt, est)["stats"]["rmse"], 0.008119)
    sig4(spslam.eval.rpe(gt, est, delta=1, unit="meters")["translation"]["rmse"], 0.011672)
    # The same poses as (timestamps, poses) tuples.
    as_tuples = spslam.eval.ate(
        spslam.eval.read_trajectory(gt), spslam.eval.read_trajectory(est)
    )
    sig4(as_tuples["stats"]["rmse"], 0.008119)
    euroc = spslam.eval.ate(evo_data / "V102_groundtruth.csv", evo_data / "V102.txt")
    sig4(euroc["stats"]["rmse"], 0.091727)


def test_evaluate_equals_the_cli(evo_data, spslam_bin, tmp_path):
    gt, est = evo_data / "fr2_desk_groundtruth.txt", evo_data / "fr2_desk_ORB.txt"
    out = tmp_path / "eval.json"
    run_cli(spslam_bin, "eval", "--gt", gt, "--est", est, "--json", out)
    assert spslam.eval.evaluate(gt, est) == json.loads(out.read_text())


def test_bad_trajectories(tmp_path):
    poses = np.tile(np.eye(4), (10, 1, 1))
    poses[:, 0, 3] = np.arange(10)
    with pytest.raises(ValueError, match="differ in length"):
        spslam.eval.ate(poses, poses[:5])
    flipped = poses.copy()
    flipped[3, :3, :3] = -np.eye(3)
    with pytest.raises(ValueError, match="pose 3"):
        spslam.eval.ate(poses, flipped)
    with pytest.raises(ValueError, match="N×4×4"):
        spslam.eval.ate(poses, poses[:, :2, :])
    with pytest.raises(TypeError, match="float64"):
        spslam.eval.ate(poses, poses.astype(np.float32))
    with pytest.raises(ValueError, match="alignment"):
        spslam.eval.ate(poses, poses, alignment="affine")
    with pytest.raises(FileNotFoundError):
        spslam.eval.ate(tmp_path / "missing.txt", poses)
    bad = tmp_path / "bad.txt"
    bad.write_text("1 2 3\n")
    with pytest.raises(ValueError, match="columns"):
        spslam.eval.read_trajectory(bad)
    with pytest.raises(ValueError, match="timestamps for"):
        spslam.eval.ate((np.arange(3.0), poses), poses)
