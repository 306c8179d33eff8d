#!/usr/bin/env python3
"""Prints EVALUATION.md's table from the run folders of tools/run_evaluation.sh.

Reads each OUT/<sequence>_<variant>/report.json (and report.txt for the
drift line of older reports) and, for EuRoC, the trajectory's position
spread. Standard library only.
"""
import json
import math
import re
import sys
from pathlib import Path

SEQUENCES = [
    ("kitti", "KITTI 06 excerpt (51 frames, 59.9 m)"),
    ("euroc", "EuRoC V1_01 excerpt (95 frames, static)"),
    ("straight", "Synthetic straight (500 frames, 499 m)"),
    ("loop", "Synthetic loop (500 frames, 500 m, 2.2 laps)"),
    ("highway", "Synthetic highway (300 frames, 748 m)"),
]
VARIANTS = [("orb", "ORB"), ("sp_none", "SuperPoint"), ("sp_anms", "SuperPoint + ANMS")]


def drift(run: Path, report: dict):
    if report.get("drift"):
        d = report["drift"]
        return d["final_position_m"], d["percent"]
    text = (run / "report.txt").read_text()
    m = re.search(r"final-position drift ([0-9.]+) m over a ([0-9.]+) m path \(([0-9.]+) %\)", text)
    return (float(m.group(1)), float(m.group(3))) if m else None


def spread(run: Path):
    rows = [l.split() for l in (run / "trajectory_tum.txt").read_text().splitlines() if l and l[0] != "#"]
    pts = [tuple(map(float, r[1:4])) for r in rows]
    return max(math.dist(a, b) for a in pts for b in pts)


def main(out: Path):
    print("| Sequence | Extractor | Tracked | Keyframes | ATE SE3 (m) | Drift | Stereo + tracking + mapping (ms/frame) | Extraction (ms/frame) |")
    print("|---|---|---|---|---|---|---|---|")
    for key, title in SEQUENCES:
        for variant, label in VARIANTS:
            run = out / f"{key}_{variant}"
            if not (run / "report.json").exists():
                print(f"| {title} | {label} | not run | | | | | |")
                continue
            r = json.loads((run / "report.json").read_text())
            s, t = r["summary"], r["summary"]["mean_timings"]
            ev = r.get("evaluation")
            ate = f"{ev['ate']['se3_rmse']:.4f}" if ev else "n/a (collinear)"
            if key == "euroc":
                dr = f"spread {100 * spread(run):.2f} cm"
            else:
                d = drift(run, r)
                dr = f"{d[0]:.3f} m ({d[1]:.2f} %)" if d else "n/a"
            slam_ms = t["stereo_ms"] + t["tracking_ms"] + t["mapping_ms"]
            print(
                f"| {title} | {label} | {s['tracked']}/{s['frames']} | {s['keyframes_inserted']} | {ate} | {dr} "
                f"| {slam_ms:.1f} ({t['stereo_ms']:.1f} + {t['tracking_ms']:.1f} + {t['mapping_ms']:.1f}) | {t['extraction_ms']:.0f} |"
            )


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "out/evaluation"))
