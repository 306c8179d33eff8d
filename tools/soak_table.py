#!/usr/bin/env python3
"""The soak run's figures (EVALUATION.md 'Soak'), from a `spslam run
--memory-log` output folder (memory.csv, report.json):

  tools/soak_table.py RUN_DIR [--write EVALUATION.md] [--plot-to PNG]

Prints a markdown block: the run (commit, machine), tracking, loops, and
the resident memory (RSS) and map size after the first 100 frames, the
first lap and every 1,000 frames; the RSS growth over the last half of the run
(the issue's bound: within 5 % once the map stops growing). With --write,
replaces the block between `<!-- soak: begin -->` and `<!-- soak: end -->`
in that file; with --plot-to, copies memory.png there."""
import argparse
import csv
import json
import platform
import shutil
import subprocess

FRAMES_PER_LAP = 232


def machine() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return f"{line.split(':', 1)[1].strip()}, {subprocess.check_output(['nproc']).decode().strip()} cores"
    except OSError:
        pass
    return platform.processor() or platform.machine()


def commit(run_dir: str) -> str:
    """The commit the run was made with (tools/soak.sh writes it), else HEAD's."""
    try:
        return open(f"{run_dir}/commit.txt").read().strip()
    except OSError:
        pass
    try:
        return subprocess.check_output(["git", "rev-parse", "--short", "HEAD"]).decode().strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def at(rows, frame):
    """The last sample at or before `frame`."""
    best = rows[0]
    for r in rows:
        if r["frame"] <= frame:
            best = r
    return best


def block(run_dir: str) -> str:
    with open(f"{run_dir}/memory.csv") as f:
        rows = [
            {k: (float(v) if k.endswith(("_mib", "_ms")) else int(v)) for k, v in r.items()}
            for r in csv.DictReader(f)
        ]
    with open(f"{run_dir}/report.json") as f:
        report = json.load(f)
    if not rows:
        raise SystemExit(f"{run_dir}/memory.csv has no samples")
    last = rows[-1]
    half = last["frame"] // 2
    tail = [r for r in rows if r["frame"] >= half]
    start = at(rows, half)
    rss_tail_max = max(r["rss_mib"] for r in tail)
    rss_tail_min = min(r["rss_mib"] for r in tail)
    growth = 100.0 * (last["rss_mib"] - start["rss_mib"]) / start["rss_mib"]
    spread = 100.0 * (rss_tail_max - rss_tail_min) / rss_tail_min
    summary = report["summary"]
    ate = ((report.get("evaluation") or {}).get("ate") or {}).get("se3_rmse")
    lap = at(rows, FRAMES_PER_LAP + 100 - FRAMES_PER_LAP % 100)
    lines = [
        f"- commit {commit(run_dir)}, {machine()}; `{report['dataset']}`, {report['sensor']}, "
        f"{report['extractor']}, {report['inference']}, mapping {report['mapping']}; "
        f"{report['frames_processed']} of {report['frames_total']} frames ({report['end']}), "
        f"{report['wall_ms_per_frame']:.0f} ms per frame",
        f"- tracking: {json.dumps({k: summary[k] for k in ('tracked', 'lost', 'relocalisations') if k in summary})}; "
        f"loops closed {len(report.get('loops') or [])}, merges {len(report.get('merges') or [])}, "
        f"global BAs {len(report.get('global_ba') or [])}"
        + (f"; ATE (SE3) {ate:.3f} m over {(report['evaluation'] or {}).get('path_length_m', 0):.0f} m" if ate is not None else ""),
        "",
        "| frames | RSS (MiB) | keyframes | map points | maps |",
        "|---:|---:|---:|---:|---:|",
    ]
    picked = [rows[0], lap, start, last] + [r for r in rows if r["frame"] % 1000 == 0]
    for r in sorted({r["frame"]: r for r in picked}.values(), key=lambda r: r["frame"]):
        lines.append(
            f"| {r['frame']} | {r['rss_mib']:.0f} | {r['keyframes']} | {r['map_points']} | {r['maps']} |"
        )
    lines += [
        "",
        f"- last {last['frame'] - start['frame']} frames: RSS {start['rss_mib']:.0f} → {last['rss_mib']:.0f} MiB "
        f"({growth:+.1f} %), spread {spread:.1f} % (min {rss_tail_min:.0f}, max {rss_tail_max:.0f}); "
        f"keyframes {start['keyframes']} → {last['keyframes']}, map points {start['map_points']} → {last['map_points']}",
    ]
    steady = tail
    if last["frame"] == report["frames_total"] and len(tail) > 2:
        # After the last frame the extraction stage has ended and freed its
        # networks: that sample is the run's end, not its steady state.
        steady = tail[:-1]
        lines.append(
            f"- without the sample after the last frame (the extraction stage had ended and freed its "
            f"networks: RSS {last['rss_mib']:.0f} MiB): RSS {spread_of(steady, 'rss_mib')}; "
            f"keyframes {min(r['keyframes'] for r in steady)}–{max(r['keyframes'] for r in steady)}"
        )
    if "heap_in_use_mib" in last:
        # The columns of `--memory-log` since session 33: what the resident
        # memory is made of, and whether a global BA's working set is in it.
        quiet = [r for r in steady if not r["global_ba_running"]]
        busy = len(steady) - len(quiet)
        lines.append(
            f"- those {len(steady)} samples: the allocator's live heap {spread_of(steady, 'heap_in_use_mib')}, "
            f"freed heap held {min(r['heap_free_held_mib'] for r in steady):.0f}–{max(r['heap_free_held_mib'] for r in steady):.0f} MiB; "
            f"{busy} taken while a global BA ran; the {len(quiet)} others: RSS {spread_of(quiet, 'rss_mib')}"
        )
    if "heap_release_ms" in last:
        times = sorted(r["heap_release_ms"] for r in rows if r["heap_release_ms"] > 0)
        if times:
            lines.append(
                f"- freed heap handed back (every 100 frames and after each global BA): "
                f"median {times[len(times) // 2]:.1f} ms, max {times[-1]:.1f} ms per 100 frames"
            )
    return "\n".join(lines)


def spread_of(rows, key):
    """`spread X % (min, max)` of one column over rows."""
    if not rows:
        return "no samples"
    lo, hi = min(r[key] for r in rows), max(r[key] for r in rows)
    return f"spread {100.0 * (hi - lo) / lo:.1f} % ({lo:.0f}–{hi:.0f} MiB)"


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir")
    parser.add_argument("--write", help="a markdown file with the soak markers")
    parser.add_argument("--plot-to", help="copy memory.png here")
    args = parser.parse_args()
    text = block(args.run_dir)
    print(text)
    if args.write:
        begin, end = "<!-- soak: begin -->", "<!-- soak: end -->"
        doc = open(args.write).read()
        if begin not in doc or end not in doc:
            raise SystemExit(f"{args.write} has no {begin} ... {end} block")
        head, rest = doc.split(begin, 1)
        _, tail = rest.split(end, 1)
        open(args.write, "w").write(f"{head}{begin}\n{text}\n{end}{tail}")
    if args.plot_to:
        shutil.copyfile(f"{args.run_dir}/memory.png", args.plot_to)


if __name__ == "__main__":
    main()
