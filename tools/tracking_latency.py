#!/usr/bin/env python3
"""Tracking's frame time while loop detection checks a keyframe, from a
`spslam run` report (BENCHMARKS.md 'Tracking while a loop is verified'):

  tools/tracking_latency.py RUN_DIR/report.json [--skip N]

Tracking time is stereo matching + tracking (`timings.stereo_ms +
timings.tracking_ms`, as `benches/slam.rs` counts it; extraction and
local mapping run elsewhere). Frames are split by `loop_check_running`
(the loop-closing thread was retrieving or verifying candidates when the
frame's tracking started or ended). The target: the 95th percentile of
the frames tracked during a check within 1.5x the median of all frames.
The first N frames (default 0) are left out."""
import argparse
import json
import statistics
import subprocess


def percentile(values, q):
    values = sorted(values)
    return values[round((len(values) - 1) * q)]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("report")
    parser.add_argument("--skip", type=int, default=0)
    args = parser.parse_args()
    with open(args.report) as f:
        report = json.load(f)
    frames = [
        r for r in report["frames"][args.skip:] if r["state"] == "Ok" and r.get("unreadable") is None
    ]
    if not frames or "loop_check_running" not in frames[0]:
        raise SystemExit(f"{args.report}: no tracked frames with `loop_check_running` (an older spslam?)")
    ms = lambda r: r["timings"]["stereo_ms"] + r["timings"]["tracking_ms"]
    everything = [ms(r) for r in frames]
    during = [ms(r) for r in frames if r["loop_check_running"]]
    outside = [ms(r) for r in frames if not r["loop_check_running"]]
    median_all = statistics.median(everything)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    print(f"`{report['dataset']}`, {report['frames_processed']} frames, {report['inference']}, mapping {report['mapping']}; commit {commit}")
    print()
    print("| frames | count | median (ms) | p95 (ms) | p95 / median of all |")
    print("|---|---:|---:|---:|---:|")
    for name, values in (("all tracked", everything), ("loop check running", during), ("no loop check", outside)):
        if values:
            print(
                f"| {name} | {len(values)} | {statistics.median(values):.1f} | {percentile(values, 0.95):.1f} | "
                f"{percentile(values, 0.95) / median_all:.2f} |"
            )
        else:
            print(f"| {name} | 0 | – | – | – |")


if __name__ == "__main__":
    main()
