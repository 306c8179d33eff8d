"""spslam.System against `spslam run --inline-mapping` on KITTI 06, the
map file round trip, and the system's input checks."""

import numpy as np
import pytest

import spslam
from conftest import REPO, gray, run_cli

SETTINGS = REPO / "settings" / "KITTI04-12.yaml"


def frames(seq, count=None):
    times = [float(line) for line in (seq / "times.txt").read_text().split()]
    for i, t in enumerate(times[:count]):
        left = gray(seq / "image_0" / f"{i:06d}.png")
        right = gray(seq / "image_1" / f"{i:06d}.png")
        yield left, right, t


@pytest.fixture(scope="module")
def kitti_run(kitti06, tmp_path_factory):
    """The whole excerpt through System (inline mapping), its map saved."""
    system = spslam.System(SETTINGS, "stereo", inline_mapping=True)
    poses = [system.track_stereo(left, right, t) for left, right, t in frames(kitti06)]
    system.shutdown()
    map_file = tmp_path_factory.mktemp("map") / "kitti06.spmap"
    saved = system.save_map(map_file)
    return system, poses, map_file, saved


def test_kitti_run_equals_the_cli(kitti06, kitti_run, spslam_bin, tmp_path):
    system, poses, _, _ = kitti_run
    run_cli(
        spslam_bin, "run", "--dataset", f"kitti:{kitti06}", "--settings", SETTINGS,
        "--inline-mapping", "--out", tmp_path,
    )
    cli = np.loadtxt(tmp_path / "trajectory_kitti.txt").reshape(-1, 3, 4)
    stamps, trajectory = system.trajectory()
    assert trajectory.shape == (51, 4, 4) and len(stamps) == 51
    assert all(p is not None for p in poses), "every frame tracked"
    # The file holds 10 significant digits.
    np.testing.assert_allclose(trajectory[:, :3, :], cli, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(trajectory[:, 3, :], np.tile([0, 0, 0, 1], (51, 1)))
    # The pose returned per frame is that frame's pose when it was tracked;
    # later bundle adjustments move it by millimetres at most.
    live = np.stack(poses)
    assert np.abs(live[:, :3, 3] - trajectory[:, :3, 3]).max() < 0.05
    assert system.frames == 51


def test_metrics_of_the_run(kitti_run, data_dir):
    system, _, _, _ = kitti_run
    _, trajectory = system.trajectory()
    gt = data_dir / "kitti" / "poses" / "06.txt"
    result = spslam.eval.ate(gt, trajectory)
    # tests/slam_kitti.rs bounds the same run (ATE SE3 0.0775 m measured).
    assert 0.01 < result["stats"]["rmse"] < 0.10
    assert result["stats"]["count"] == 51


def test_saved_map_relocalises(kitti06, kitti_run):
    _, _, map_file, saved = kitti_run
    keyframes, points, size = saved
    assert keyframes > 10 and points > 1000 and size == map_file.stat().st_size
    # The map's first frames, 50 m from its last keyframes: found through
    # place recognition (the codebook indexes the loaded keyframes).
    system = spslam.System(SETTINGS, "stereo", inline_mapping=True)
    system.load_map(map_file, localize=True)
    tracked = [system.track_stereo(l, r, t) is not None for l, r, t in frames(kitti06, 3)]
    assert all(tracked)
    _, trajectory = system.trajectory()
    _, mapped = kitti_run[0].trajectory()
    assert np.abs(trajectory[:, :3, 3] - mapped[:3, :3, 3]).max() < 0.05
    system.shutdown()


def test_input_checks(kitti06, tmp_path):
    with pytest.raises(FileNotFoundError):
        spslam.System(tmp_path / "missing.yaml")
    with pytest.raises(ValueError, match="sensor"):
        spslam.System(SETTINGS, "lidar")
    with pytest.raises(ValueError, match="extractor"):
        spslam.System(SETTINGS, extractor="sift")
    system = spslam.System(SETTINGS, "stereo", inline_mapping=True, loop_closing=False)
    left, right, t = next(frames(kitti06, 1))
    with pytest.raises(ValueError, match="track_stereo"):
        system.track_monocular(left, t)
    with pytest.raises(TypeError, match="uint8"):
        system.track_stereo(left.astype(np.float32), right, t)
    assert system.track_stereo(left, right, t) is not None
    with pytest.raises(ValueError, match="started on"):
        system.track_stereo(left[:200], right[:200], t + 0.1)
    with pytest.raises(ValueError, match="timestamp"):
        system.track_stereo(left, right, float("nan"))
    with pytest.raises(spslam.SpslamError, match="before the first frame"):
        system.load_map(tmp_path / "any.spmap")
    system.shutdown()
    with pytest.raises(spslam.SpslamError, match="shut down"):
        system.track_stereo(left, right, t + 0.2)
    with pytest.raises(FileNotFoundError):
        spslam.System(SETTINGS).load_map(tmp_path / "missing.spmap")


def test_the_example_script_runs(kitti06, data_dir, tmp_path):
    import subprocess
    import sys

    out = tmp_path / "trajectory.txt"
    done = subprocess.run(
        [
            sys.executable, str(REPO / "python" / "examples" / "kitti_stereo.py"),
            str(kitti06), str(SETTINGS), "--gt", str(data_dir / "kitti" / "poses" / "06.txt"),
            "--out", str(out), "--frames", "8",
        ],
        capture_output=True, text=True,
    )
    assert done.returncode == 0, done.stderr
    assert "8 frames, 0 not tracked" in done.stdout
    assert "ATE (SE3-aligned)" in done.stdout
    assert np.loadtxt(out).shape == (8, 12)
