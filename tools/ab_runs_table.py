#!/usr/bin/env python3
"""A side-by-side markdown table of sets of `spslam run` reports.

Each set is a folder holding one sub-folder per run with its `report.json`
(`spslam run --out SET/NAME`, or `spslam evaluate --out SET`, whose runs lie
in SET/runs/NAME). Runs are paired by name; a run missing from one set shows
as a dash. Each cell: tracked/frames, maps left unmerged, keyframes
inserted, ATE RMSE (SE3; Sim3 for monocular runs), loops, merges.

    python3 tools/ab_runs_table.py --a out/ab/A --b out/ab/B \
        --label-a "plain ratio test" --label-b "rivals beyond the cell"

A third set (`--c`, `--label-c`) adds a column, and any number more
(`--set LABEL=FOLDER`, repeated; with them `--a` and `--b` may be left
out); `--changed-only` keeps the runs whose cells differ between the sets
(the ATE compared to the digit). `--scale-drift` adds a monocular run's
scale drift (`report.json`'s `scale_drift.ratio`), `--time` its wall
time per frame and `--posed-late` how many of its tracked frames were
localised after a loss or posed by odometry to each cell.
"""

import argparse
import json
import os
import platform
import subprocess
import sys


def reports(folder):
    """Run name -> report path, for every run under `folder` (or its runs/)."""
    found = {}
    for base in (folder, os.path.join(folder, "runs")):
        if not os.path.isdir(base):
            continue
        for name in sorted(os.listdir(base)):
            path = os.path.join(base, name, "report.json")
            if os.path.isfile(path):
                found[name] = path
    return found


def cell(path, scale_drift=False, time=False, posed_late=False):
    """One run's cell, or a dash when it did not finish."""
    if path is None:
        return "–"
    with open(path, encoding="utf-8") as f:
        r = json.load(f)
    s = r["summary"]
    maps = s["maps"] if isinstance(s["maps"], int) else sum(
        1 for m in s["maps"] if m.get("merged_into") is None
    )
    mono = r.get("sensor") == "mono"
    ate = (r.get("evaluation") or {}).get("ate") or {}
    value = ate.get("sim3_rmse" if mono else "se3_rmse")
    ate_text = "no ATE" if value is None else f"{value:.4f} m {'Sim3' if mono else 'SE3'}"
    extra = ""
    ratio = (r.get("scale_drift") or {}).get("ratio")
    if scale_drift and ratio is not None:
        extra += f", scale drift {100.0 * (ratio - 1.0):+.1f} %"
    if time and r.get("wall_ms_per_frame") is not None:
        extra += f", {r['wall_ms_per_frame']:.0f} ms"
    if posed_late:
        extra += (f" ({s.get('localised_after_loss', 0)} after a loss,"
                  f" {s.get('by_odometry', 0)} by odometry)")
    return (
        f"{s['tracked']}/{s['frames']}, {maps} map{'s' if maps != 1 else ''}, "
        f"{s['keyframes_inserted']} KF, {ate_text}, "
        f"{len(r.get('loops') or [])} loops, {len(r.get('merges') or [])} merges{extra}"
    )


def machine():
    """The CPU's model name and whether it has AVX-512 VNNI."""
    model, vnni = platform.processor() or "unknown CPU", False
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name") and model in ("", "unknown CPU"):
                    model = line.split(":", 1)[1].strip()
                if line.startswith("flags"):
                    vnni = "avx512_vnni" in line.split()
    except OSError:
        pass
    return f"{model}, {os.cpu_count()} cores, {'AVX-512 VNNI' if vnni else 'AVX2, no VNNI'}"


def commit():
    """The working tree's commit (with +dirty when it has changes)."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short=12", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            capture_output=True, text=True, check=True,
        ).stdout.strip()
        return head + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def ground_truth(dataset):
    """The ground-truth file of a run's dataset argument."""
    kind, _, path = dataset.partition(":")
    if kind == "synth":
        return os.path.join(path, "poses", "00.txt")
    if kind == "kitti":
        seq = os.path.basename(os.path.normpath(path))
        return os.path.join(path, "..", "..", "poses", f"{seq}.txt")
    if kind == "tum":
        return os.path.join(path, "groundtruth.txt")
    sys.exit(f"error: no ground truth known for dataset {dataset!r}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--a", help="the first set's folder")
    parser.add_argument("--b", help="the second set's folder")
    parser.add_argument("--label-a", default="A")
    parser.add_argument("--label-b", default="B")
    parser.add_argument("--c", help="a third set's folder")
    parser.add_argument("--label-c", default="C")
    parser.add_argument("--set", action="append", default=[], metavar="LABEL=FOLDER",
                        help="one more set, after --a, --b and --c (repeatable)")
    parser.add_argument("--changed-only", action="store_true",
                        help="only the runs whose cells differ between the sets")
    parser.add_argument("--common-only", action="store_true",
                        help="only the runs every set has")
    parser.add_argument("--scale-drift", action="store_true",
                        help="add a monocular run's scale drift to its cell")
    parser.add_argument("--time", action="store_true",
                        help="add the wall time per frame to each cell")
    parser.add_argument("--posed-late", action="store_true",
                        help="add how many tracked frames were localised after a loss "
                             "and how many posed by odometry")
    args = parser.parse_args()
    pairs = [(args.label_a, args.a), (args.label_b, args.b), (args.label_c, args.c)]
    for item in args.set:
        label, sep, folder = item.rpartition("=")
        if not sep or not label or not folder:
            sys.exit(f"error: --set {item!r}: give LABEL=FOLDER")
        pairs.append((label, folder))
    pairs = [(label, folder) for label, folder in pairs if folder]
    if not pairs:
        sys.exit("error: give a set (--a, or --set LABEL=FOLDER; two or more side by side)")
    labels = [label for label, _ in pairs]
    folders = [folder for _, folder in pairs]
    sets = [reports(f) for f in folders]
    names = sorted(set().union(*sets))
    if not names:
        sys.exit(f"error: no report.json under {' or '.join(folders)}")
    print(f"Generated by tools/ab_runs_table.py from the reports in {', '.join(folders)}; "
          f"table written at commit {commit()} on {machine()}.\n")
    print("| run | " + " | ".join(labels) + " |")
    print("|---" * (len(labels) + 1) + "|")
    for name in names:
        cells = [cell(found.get(name), args.scale_drift, args.time, args.posed_late)
                 for found in sets]
        if args.changed_only and len(set(cells)) == 1:
            continue
        if args.common_only and any(name not in found for found in sets):
            continue
        print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
