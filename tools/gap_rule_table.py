#!/usr/bin/env python3
"""A markdown table of each run's ATE with the poses across a tracking gap
held (the rule before commit 8ba5b74) and carried on at the last velocity
(the rule since), from the same run.

A run's rows differ between the two rules only by where a later map is
anchored and what a frame without a pose gets, so the held rows can be
rebuilt from the run's own trajectory and `report.json` (each frame's
state and map): a map's rows move rigidly so that its first tracked row
sits at the previous tracked row, and a frame without a pose repeats the
previous tracked row. Both trajectories are then evaluated by the same
binary (`spslam eval --json`) against the dataset's ground truth.

    python3 tools/gap_rule_table.py [--spslam BIN] RUN_DIR...

Only runs with a frame that was not tracked are listed (the rules agree
elsewhere). Needs numpy.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ab_runs_table import commit, ground_truth, machine  # noqa: E402


def quat_to_matrix(qx, qy, qz, qw):
    """The rotation matrix of a unit quaternion."""
    n = np.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    x, y, z, w = qx / n, qy / n, qz / n, qw / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix_to_quat(r):
    """A unit quaternion (x, y, z, w) of a rotation matrix."""
    t = np.trace(r)
    if t > 0:
        s = 2.0 * np.sqrt(t + 1.0)
        return ((r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s)
    i = int(np.argmax(np.diag(r)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
    q = [0.0, 0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (r[j, i] + r[i, j]) / s
    q[k] = (r[k, i] + r[i, k]) / s
    q[3] = (r[k, j] - r[j, k]) / s
    return tuple(q)


def read_rows(path):
    """(format, [(timestamp or None, 4x4 T_wc)]) of a KITTI or TUM file."""
    rows = []
    fmt = "kitti" if path.endswith("_kitti.txt") else "tum"
    with open(path, encoding="utf-8") as f:
        for line in f:
            v = line.split()
            if not v or v[0].startswith("#"):
                continue
            m = np.eye(4)
            if fmt == "kitti":
                m[:3, :] = np.array([float(x) for x in v]).reshape(3, 4)
                rows.append((None, m))
            else:
                t, tx, ty, tz, qx, qy, qz, qw = (float(x) for x in v)
                m[:3, :3] = quat_to_matrix(qx, qy, qz, qw)
                m[:3, 3] = (tx, ty, tz)
                rows.append((t, m))
    return fmt, rows


def write_rows(path, fmt, rows):
    """Writes rows in the format they were read in."""
    with open(path, "w", encoding="utf-8") as f:
        for t, m in rows:
            if fmt == "kitti":
                f.write(" ".join(f"{x:.9e}" for x in m[:3, :].reshape(-1)) + "\n")
            else:
                qx, qy, qz, qw = matrix_to_quat(m[:3, :3])
                tx, ty, tz = m[:3, 3]
                f.write(f"{t:.6f} {tx:.9f} {ty:.9f} {tz:.9f} {qx:.9f} {qy:.9f} {qz:.9f} {qw:.9f}\n")


def held_rows(frames, rows):
    """The rows the held rule gives: see the module's doc."""
    offsets = {}  # map -> T_held,carried
    held_prev = np.eye(4)
    out = []
    for frame, (t, carried) in zip(frames, rows):
        if frame["state"] == "Ok":
            m = frame["map"]
            if m not in offsets:
                offsets[m] = held_prev @ np.linalg.inv(carried)
            held_prev = offsets[m] @ carried
        out.append((t, held_prev.copy()))
    return out


def ate(spslam, gt, est, mono):
    """SE3 (Sim3 for monocular) ATE RMSE of `spslam eval --json`."""
    out = est + ".eval.json"
    subprocess.run(
        [spslam, "eval", "--gt", gt, "--est", est, "--json", out],
        check=True,
        capture_output=True,
        text=True,
    )
    with open(out, encoding="utf-8") as f:
        a = json.load(f)["ate"]
    os.remove(out)
    return a["sim3_rmse" if mono else "se3_rmse"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--spslam", default="target/release/spslam")
    parser.add_argument("runs", nargs="+")
    args = parser.parse_args()
    print(f"Commit {commit()}; machine: {machine()}. ATE RMSE (m): SE3, Sim3 for monocular runs.\n")
    print("| run | sensor | tracked | maps | ATE, gap held | ATE, gap carried on | change |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for run in args.runs:
        if not os.path.exists(os.path.join(run, "report.json")):
            continue
        with open(os.path.join(run, "report.json"), encoding="utf-8") as f:
            report = json.load(f)
        frames = report["frames"]
        if all(fr["state"] == "Ok" for fr in frames):
            continue
        est = next(
            os.path.join(run, n)
            for n in ("trajectory_kitti.txt", "trajectory_tum.txt")
            if os.path.exists(os.path.join(run, n))
        )
        fmt, rows = read_rows(est)
        if len(rows) != len(frames):
            sys.exit(f"error: {est} has {len(rows)} rows for {len(frames)} frames")
        gt = ground_truth(report["dataset"])
        mono = report["sensor"] == "mono"
        with tempfile.TemporaryDirectory() as tmp:
            held = os.path.join(tmp, os.path.basename(est))
            write_rows(held, fmt, held_rows(frames, rows))
            before = ate(args.spslam, gt, held, mono)
            after = ate(args.spslam, gt, est, mono)
        tracked = sum(fr["state"] == "Ok" for fr in frames)
        maps = len({fr["map"] for fr in frames})
        change = 100.0 * (after - before) / before if before > 0 else float("nan")
        print(
            f"| {os.path.basename(os.path.normpath(run))} | {report['sensor']} | {tracked}/{len(frames)} "
            f"| {maps} | {before:.4f} | {after:.4f} | {change:+.0f} % |"
        )


if __name__ == "__main__":
    main()
