#!/usr/bin/env python3
"""Markdown table of `gpu_check` logs (examples/gpu_check.rs).

    python3 tools/gpu_check_table.py "LABEL=docs/gpu_check/x.log" ...

Each LABEL names how the log's runs were configured (for example "one
session, EXHAUSTIVE"); a log's `=== SPSLAM_CUDA_CONV_SEARCH=S ...` headers,
when present, add the search to the label. fp32 rows only (int8 is not
checked on CUDA; gpu_check's docs say why).
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
HEADER = re.compile(r"^=== SPSLAM_CUDA_CONV_SEARCH=(\w+)")


def rows(label, path):
    search, result = None, None
    for line in open(path, encoding="utf-8"):
        if m := HEADER.match(line):
            search = m.group(1).upper()
        elif m := RESULT.match(line):
            result = m.groupdict()
        elif (m := TIMING.search(line)) and result:
            if result["precision"] == "fp32":
                yield {"label": label + (f", {search}" if search else ""), **result, **m.groupdict()}
            result = None


def main(args):
    if not args or any("=" not in a for a in args):
        sys.exit(__doc__)
    print("| sessions, cuDNN search | model | levels | per frame | frames/s | network | CPU stages | CPU (same process) | keypoints found / cosine |")
    print("|---|---|---|---|---|---|---|---|---|")
    for arg in args:
        label, path = arg.split("=", 1)
        for r in rows(label, path):
            print(
                f"| {r['label']} | {r['model']} | {r['levels']} | {r['total']} ms | {r['fps']} | {r['net']} ms"
                f" | {r['cpu_stages']} ms | {r['cpu']} ms | {r['found']} % / {r['cosine']} |"
            )


if __name__ == "__main__":
    main(sys.argv[1:])
