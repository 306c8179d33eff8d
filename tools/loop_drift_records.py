#!/usr/bin/env python3
"""The loop candidates that reached the drift stage, as a markdown table.

Reads every run under a suite folder (`spslam evaluate --out OUT`: runs in
OUT/runs/NAME) whose `report.json` holds recorded loop checks (`spslam run
--record-loop-stages`) and prints one row per candidate that passed every
count stage of the check and was judged by the drift stage (a loop in a map
with a metric scale): the correction it asked for, the way travelled since
the candidate, the correction over the path, what drift allows there at the
default thresholds, the verdict and the ground truth's. Candidates of merges
(no way travelled) carry no drift record and are left out; a monocular run's
translation is not judged (allowed: inf).

    python3 tools/loop_drift_records.py --suite out/suite --prefix loopcheck_
"""

import argparse
import json
import os
import sys

# LoopThresholds::default() (src/loop_closing/thresholds.rs).
MAX_DRIFT_RATIO = 0.1
DRIFT_FLOOR_DEPTHS = 0.1
DRIFT_FLOOR_DEG = 20.0


def allowed(travel):
    """What drift explains after `travel`: (metres, degrees); any translation
    for a map without a metric scale (monocular)."""
    metres = float("inf")
    if travel.get("metric", True):
        metres = max(
            DRIFT_FLOOR_DEPTHS * travel["scene_depth_m"], MAX_DRIFT_RATIO * travel["path_m"]
        )
    return (metres, max(DRIFT_FLOOR_DEG, MAX_DRIFT_RATIO * travel["turned_deg"]))


def rows(suite, prefix):
    """(run, candidate) for every judged candidate, in run-name order."""
    base = os.path.join(suite, "runs")
    for name in sorted(os.listdir(base)):
        path = os.path.join(base, name, "report.json")
        if not name.startswith(prefix) or not os.path.isfile(path):
            continue
        with open(path, encoding="utf-8") as f:
            report = json.load(f)
        for c in report.get("loop_candidates", []):
            if c["counts"].get("drift") and c.get("rejected_at") in (None, "drift"):
                yield name, c


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", required=True, help="the evaluate output folder")
    parser.add_argument("--prefix", default="", help="only runs whose name starts so")
    args = parser.parse_args()
    print(
        "| Run | Query → candidate frame | Inliers | Correction (m, °) | Path (m), turned (°) "
        "| Correction / path | Allowed (m, °) | Verdict | Truth |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    found = 0
    for name, c in rows(args.suite, args.prefix):
        d = c["counts"]["drift"]
        t = d["travel"]
        metres, degrees = allowed(t)
        ratio = d["correction_m"] / t["path_m"] if t["path_m"] > 0 else float("inf")
        verdict = "stopped (drift)" if c.get("rejected_at") == "drift" else "passes"
        print(
            f"| {name} | {c['query_frame']} → {c['candidate_frame']} "
            f"| {c['counts']['reprojection_inliers']} "
            f"| {d['correction_m']:.2f}, {d['correction_deg']:.1f} "
            f"| {t['path_m']:.0f}, {t['turned_deg']:.0f} | {ratio:.4f} "
            f"| {metres:.2f}, {degrees:.0f} | {verdict} | {c.get('truth') or 'not judged'} |"
        )
        found += 1
    if found == 0:
        print("no candidate reached the drift stage", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
