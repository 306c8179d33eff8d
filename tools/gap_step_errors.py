#!/usr/bin/env python3
"""The odometry steps of `spslam run` reports against a synthetic scene's truth.

A lost stereo or RGB-D frame's step from the frame before it is measured by
odometry (`src/tracking/gap_odometry.rs`; `gap_step_inliers` in a frame's
record) and a frame joined by steps to a posed frame gets its pose along the
chain (method `Odometry`). For every frame with a measured step whose frame
or predecessor was posed that way, this prints the error of the trajectory's
step against the ground truth, grouped by the step's inliers, so that a
bound on the inliers can be judged by what it lets through:

    python3 tools/gap_step_errors.py --runs out/suite/runs --buckets 21,30

`--runs` is a folder of run folders (`spslam evaluate`'s `runs/`, or
folders written by `spslam run --out`), each with its `report.json`; the
truth is the file of the run's dataset (`ab_runs_table.ground_truth`:
a synthetic scene's `poses/00.txt`, a TUM sequence's `groundtruth.txt`).
Trajectory and truth are read the same way: a KITTI file row by row (one
row per frame), a TUM file by timestamp. A step between two frames posed by different chains (one
forwards, one backwards) holds the mismatch of the two chains, not one
measured step; such steps are in the counts and show as the largest errors.

With `--second-look` the rows are instead the frames tracked on the second
look (`second_look` "tracked" in a frame's record, `src/system/second_look.rs`):
each one's step from the frame before against the truth, grouped by the
frame's inliers.
"""

import argparse
import json
import math
import os
import statistics
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ab_runs_table import commit, ground_truth, machine  # noqa: E402


def quat_pose(x, y, z, qx, qy, qz, qw):
    """A 3×4 pose from a TUM row's translation and unit quaternion."""
    r = [
        [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
        [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
        [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)],
    ]
    return [r[0] + [x], r[1] + [y], r[2] + [z]]


def inverse(t):
    rt = [[t[j][i] for j in range(3)] for i in range(3)]
    ti = [-sum(rt[i][j] * t[j][3] for j in range(3)) for i in range(3)]
    return [rt[i] + [ti[i]] for i in range(3)]


def compose(a, b):
    return [
        [sum(a[i][k] * b[k][j] for k in range(3)) + (a[i][3] if j == 3 else 0.0) for j in range(4)]
        for i in range(3)
    ]


def size(t):
    """Translation (m) and rotation angle (degrees) of a pose."""
    metres = math.sqrt(sum(t[i][3] ** 2 for i in range(3)))
    c = max(-1.0, min(1.0, (t[0][0] + t[1][1] + t[2][2] - 1.0) / 2.0))
    return metres, math.degrees(math.acos(c))


def poses_by_frame(path, frames):
    """Frame index -> pose (3×4) of a trajectory file: KITTI rows (12 numbers,
    one row per frame) or TUM rows (8 numbers, matched to the frames by
    timestamp)."""
    with open(path, encoding="utf-8") as f:
        rows = [[float(x) for x in line.split()] for line in f
                if line.strip() and not line.startswith("#")]
    if rows and len(rows[0]) == 12:
        if len(rows) != len(frames):
            sys.exit(f"{path}: {len(rows)} rows for {len(frames)} frames")
        return {i: [v[0:4], v[4:8], v[8:12]] for i, v in enumerate(rows)}
    by_time = {round(f["timestamp"], 3): f["index"] for f in frames}
    return {by_time[round(v[0], 3)]: quat_pose(*v[1:8])
            for v in rows if round(v[0], 3) in by_time}


def step_errors(run, second_look=False):
    """(inliers, metres, degrees, frame) for each chained step of one run,
    or with `second_look` for each frame tracked on the second look (its
    step from the frame before, bucketed by the frame's inliers)."""
    with open(os.path.join(run, "report.json"), encoding="utf-8") as f:
        report = json.load(f)
    frames = report["frames"]
    estimate = next(
        os.path.join(run, n)
        for n in ("trajectory_kitti.txt", "trajectory_tum.txt")
        if os.path.exists(os.path.join(run, n))
    )
    poses = poses_by_frame(estimate, frames)
    truth = poses_by_frame(ground_truth(report["dataset"]), frames)
    out = []
    for f in frames:
        j = f["index"]
        if second_look:
            inliers = f["inliers"] if f.get("second_look") == "tracked" else None
        else:
            inliers = f.get("gap_step_inliers")
        if inliers is None or j == 0 or not {j - 1, j} <= poses.keys() & truth.keys():
            continue
        if not second_look and "Odometry" not in (frames[j - 1]["method"], f["method"]):
            continue
        estimated = compose(inverse(poses[j - 1]), poses[j])
        true = compose(inverse(truth[j - 1]), truth[j])
        metres, degrees = size(compose(inverse(true), estimated))
        out.append((inliers, metres, degrees, j))
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", required=True, action="append", help="an evaluate runs/ folder")
    parser.add_argument("--buckets", default="21,30", help="inlier bucket edges")
    parser.add_argument("--second-look", action="store_true",
                        help="the frames tracked on the second look instead of the chained steps")
    args = parser.parse_args()
    edges = [int(x) for x in args.buckets.split(",")]
    buckets = {}
    for folder in args.runs:
        for name in sorted(os.listdir(folder)):
            run = os.path.join(folder, name)
            if not os.path.isfile(os.path.join(run, "report.json")):
                continue
            for inliers, metres, degrees, j in step_errors(run, args.second_look):
                low = max((e for e in edges if e <= inliers), default=None)
                if low is not None:
                    buckets.setdefault(low, []).append((metres, degrees, f"{name}:{j}"))
    print(f"Generated by tools/gap_step_errors.py from the runs in {', '.join(args.runs)}; "
          f"table written at commit {commit()} on {machine()}.")
    print()
    what = "frame inliers | frames" if args.second_look else "step inliers | steps"
    print(f"| {what} | median error | 90th percentile | largest (run:frame) |")
    print("|---|---|---|---|---|")
    for low in sorted(buckets):
        i = edges.index(low)
        high = edges[i + 1] - 1 if i + 1 < len(edges) else None
        label = f"{low}–{high}" if high else f"{low} or more"
        steps = buckets[low]
        metres = sorted(s[0] for s in steps)
        degrees = sorted(s[1] for s in steps)
        p90 = lambda v: v[min(len(v) - 1, int(0.9 * len(v)))]
        worst = max(steps)
        print(
            f"| {label} | {len(steps)} | {statistics.median(metres):.3f} m, "
            f"{statistics.median(degrees):.2f}° | {p90(metres):.3f} m, {p90(degrees):.2f}° | "
            f"{worst[0]:.3f} m, {worst[1]:.2f}° ({worst[2]}) |"
        )


if __name__ == "__main__":
    main()
