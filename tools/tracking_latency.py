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
The first N frames (default 0) are left out. `lock_wait_ms` is the
part of a frame's tracking spent waiting for the map's locks: what loop
detection (or local mapping) holding them costs tracking, apart from
sharing the CPU; the last column is the p95 of each frame's time less
its lock wait (the frame's own work and the CPU it shared)."""
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
    median_all = statistics.median(everything)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    print(f"`{report['dataset']}`, {report['frames_processed']} frames, {report['inference']}, mapping {report['mapping']}; commit {commit}")
    print()
    wait = lambda r: r["timings"].get("lock_wait_ms", float("nan"))
    groups = (
        ("all tracked", frames),
        ("loop check running", [r for r in frames if r["loop_check_running"]]),
        ("no loop check", [r for r in frames if not r["loop_check_running"]]),
    )
    print("| frames | count | median (ms) | p95 (ms) | p95 / median of all | lock wait: median, p95, max (ms) | p95 less the lock wait (ms) |")
    print("|---|---:|---:|---:|---:|---|---:|")
    for name, group in groups:
        values = [ms(r) for r in group]
        if values:
            waits = [wait(r) for r in group]
            print(
                f"| {name} | {len(values)} | {statistics.median(values):.1f} | {percentile(values, 0.95):.1f} | "
                f"{percentile(values, 0.95) / median_all:.2f} | "
                f"{statistics.median(waits):.2f}, {percentile(waits, 0.95):.2f}, {max(waits):.1f} | "
                f"{percentile([ms(r) - wait(r) for r in group], 0.95):.1f} |"
            )
        else:
            print(f"| {name} | 0 | – | – | – | – | – |")


if __name__ == "__main__":
    main()
