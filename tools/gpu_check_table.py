#!/usr/bin/env python3
"""Markdown table of `gpu_check` logs (examples/gpu_check.rs).

    python3 tools/gpu_check_table.py [--model NAME] "LABEL=docs/gpu_check/x.log" ...

Each LABEL (everything before the last `=`) names how the log's runs were configured (for example "one
session, EXHAUSTIVE"); a log's `=== VARIABLE=VALUE ... gpu_check ...`
headers (tools/gpu_check_offline/run_on_device.sh), when present, add the
run's variables to the label, and its `GPU memory: peak N MiB` line fills
the memory column of the run's rows. fp32 rows only (int8 is not checked
on CUDA; gpu_check's docs say why).
"""
import re
import sys

RESULT = re.compile(
    r"^(?P<model>\w+) (?P<precision>fp32|int8), (?P<levels>\d+) level\(s\), (?P<size>\d+x\d+): "
    r".*?(?P<found>[\d.]+) % of CPU keypoints found by the GPU.*?descriptor cosine (?P<cosine>[\d.]+)"
)
TIMING = re.compile(
    r"GPU: (?P<total>[\d.]+) ms/frame = (?P<fps>[\d.]+) frames/s \(network (?P<net>[\d.]+) ms, "
    r"CPU stages (?P<cpu_stages>[\d.]+) ms\), (?P<frames>\d+) frames; CPU: (?P<cpu>[\d.]+) ms/frame"
)
HEADER = re.compile(r"^=== (?P<environment>.*?) ?gpu_check ")
MEMORY = re.compile(r"GPU memory: peak (?P<peak>\d+) MiB above idle")


def short(environment):
    """`SPSLAM_CUDA_CONV_SEARCH=heuristic X=1` -> `CONV_SEARCH=heuristic, X=1`."""
    return ", ".join(a.removeprefix("SPSLAM_CUDA_") for a in environment.split())


def rows(label, path):
    environment, result, run = "", None, []
    for line in open(path, encoding="utf-8"):
        if m := HEADER.match(line):
            yield from run
            environment, run = short(m.group("environment")), []
        elif m := RESULT.match(line):
            result = m.groupdict()
        elif (m := TIMING.search(line)) and result:
            if result["precision"] == "fp32":
                name = ", ".join(part for part in (label, environment) if part)
                run.append({"label": name, "memory": "–", **result, **m.groupdict()})
            result = None
        elif m := MEMORY.search(line):
            for r in run:
                r["memory"] = f"{m.group('peak')} MiB"
    yield from run


def main(args):
    model = None
    if args[:1] == ["--model"] and len(args) >= 2:
        model, args = args[1], args[2:]
    if not args or any("=" not in a for a in args):
        sys.exit(__doc__)
    print("| build, settings | model | levels | per frame | frames/s | network | CPU stages | CPU (same process) | GPU memory (peak of the run) | keypoints found / cosine |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for arg in args:
        label, path = arg.rsplit("=", 1)
        for r in rows(label, path):
            if model and r["model"] != model:
                continue
            print(
                f"| {r['label']} | {r['model']} | {r['levels']} | {r['total']} ms | {r['fps']} | {r['net']} ms"
                f" | {r['cpu_stages']} ms | {r['cpu']} ms | {r['memory']} | {r['found']} % / {r['cosine']} |"
            )


if __name__ == "__main__":
    main(sys.argv[1:])
