"""Stereo SLAM on a KITTI odometry sequence folder with the spslam package.

    python kitti_stereo.py SEQUENCE_DIR SETTINGS.yaml [--gt POSES.txt] [--out trajectory.txt] [--frames N]

SEQUENCE_DIR holds image_0/, image_1/ and times.txt (KITTI's layout);
SETTINGS.yaml is an ORB-SLAM3 settings file (settings/KITTI04-12.yaml in
the repository for sequences 04-12). Writes the trajectory in KITTI's
format and, given the ground truth, prints evo's ATE and the KITTI metric.
Needs Pillow to read the PNGs (`pip install pillow`).
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

import spslam


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sequence", type=Path)
    parser.add_argument("settings", type=Path)
    parser.add_argument("--gt", type=Path, help="KITTI ground-truth poses of the sequence")
    parser.add_argument("--out", type=Path, default=Path("trajectory_kitti.txt"))
    parser.add_argument("--frames", type=int, help="stop after this many frames")
    args = parser.parse_args()

    times = np.loadtxt(args.sequence / "times.txt", ndmin=1)[: args.frames]
    started = time.perf_counter()
    lost = 0
    with spslam.System(args.settings, "stereo") as system:
        for i, t in enumerate(times):
            left = np.asarray(Image.open(args.sequence / "image_0" / f"{i:06d}.png").convert("L"))
            right = np.asarray(Image.open(args.sequence / "image_1" / f"{i:06d}.png").convert("L"))
            pose = system.track_stereo(left, right, float(t))
            lost += pose is None
            print(f"\rframe {i + 1}/{len(times)}, {system.tracking_state}", end="", file=sys.stderr)
    print(file=sys.stderr)
    seconds = time.perf_counter() - started
    _, poses = system.trajectory()
    np.savetxt(args.out, poses[:, :3, :].reshape(len(poses), 12), fmt="%.9e")
    print(f"{len(times)} frames, {lost} not tracked, {1e3 * seconds / len(times):.0f} ms per frame; wrote {args.out}")
    if args.gt is not None:
        _, gt = spslam.eval.read_trajectory(args.gt)
        gt = gt[: len(poses)]
        ate = spslam.eval.ate(gt, poses)["stats"]["rmse"]
        print(f"ATE (SE3-aligned) {ate:.4f} m")
        kitti = spslam.eval.kitti_metric(gt, poses)
        if kitti is not None:
            print(f"KITTI: {kitti['t_err_pct']:.3f} %, {kitti['r_err_deg_per_100m']:.3f} deg/100 m")


if __name__ == "__main__":
    main()
