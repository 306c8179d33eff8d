#!/usr/bin/env python3
"""Prints EVALUATION.md's pyramid-level table from tools/run_levels.sh's runs.

Reads OUT/<sequence>_<precision>_l<levels>/report.json. Standard library only.
"""
import json
import math
import sys
from pathlib import Path


def spread(run: Path):
    """The largest distance between two estimated positions (m)."""
    rows = [l.split() for l in (run / "trajectory_tum.txt").read_text().splitlines() if l and l[0] != "#"]
    pts = [tuple(map(float, r[1:4])) for r in rows]
    return max(math.dist(a, b) for a in pts for b in pts)

SEQUENCES = [
    ("kitti", "KITTI 06 excerpt (51 frames)"),
    ("euroc", "EuRoC V1_01 excerpt (95 frames, static)"),
    ("highway", "Synthetic highway (100 frames, 640x480)"),
]


def main(out: Path):
    print("| Sequence | Precision | Levels | Tracked | Keyframes | ATE SE3 (m) | Drift | Extraction (ms/frame) | Wall (ms/frame) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for key, title in SEQUENCES:
        for precision in ("fp32", "int8"):
            for levels in (1, 2, 4, 8):
                run = out / f"{key}_{precision}_l{levels}"
                if not (run / "report.json").exists():
                    continue
                r = json.loads((run / "report.json").read_text())
                s, t = r["summary"], r["summary"]["mean_timings"]
                ev = r.get("evaluation")
                ate = f"{ev['ate']['se3_rmse']:.4f}" if ev else "n/a (collinear)"
                if key == "euroc":
                    dr = f"spread {100 * spread(run):.2f} cm"
                elif r.get("drift"):
                    dr = f"{r['drift']['final_position_m']:.3f} m ({r['drift']['percent']:.2f} %)"
                else:
                    dr = "n/a"
                wall = r.get("wall_ms_per_frame", float("nan"))
                print(
                    f"| {title} | {precision} | {levels} | {s['tracked']}/{s['frames']} | {s['keyframes_inserted']} "
                    f"| {ate} | {dr} | {t['extraction_ms']:.0f} | {wall:.0f} |"
                )


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "out/levels"))
