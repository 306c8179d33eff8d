#!/usr/bin/env python3
"""Side-by-side table of `spslam evaluate` outputs (one --out folder per
variant), for studies such as the local BA window in EVALUATION.md:

  tools/window_table.py NAME=OUT_DIR [NAME=OUT_DIR ...]

Prints one markdown row per case: ATE (m) or drift, keyframes, per variant,
with each variant's commit and machine from its summary.json."""
import json
import sys


def main():
    variants = [a.split("=", 1) for a in sys.argv[1:]]
    if not variants or any(len(v) != 2 for v in variants):
        raise SystemExit(__doc__)
    runs = {}
    for name, out in variants:
        with open(f"{out}/summary.json") as f:
            summary = json.load(f)
        for r in summary["runs"]:
            runs.setdefault(r["case"], {})[name] = r
    for name, out in variants:
        any_run = next((r[name] for r in runs.values() if name in r), None)
        if any_run:
            print(f"- {name}: `{out}`, commit {any_run['commit']}, {any_run['machine']}")
    print()
    print("| case | " + " | ".join(name for name, _ in variants) + " |")
    print("|---|" + "---|" * len(variants))
    for case in sorted(runs):
        cells = []
        for name, _ in variants:
            r = runs[case].get(name)
            if r is None or not r.get("complete"):
                cells.append("–")
            elif r.get("ate_m") is not None:
                cells.append(f"{r['ate_m']:.4f} m ({r['keyframes']} KF)")
            else:
                cells.append(f"drift {r['drift_percent']:.2f} % ({r['keyframes']} KF)")
        print(f"| {case} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
