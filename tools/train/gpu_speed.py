#!/usr/bin/env python3
"""Frame rate of SuperPoint networks on a GPU through PyTorch (not ONNX Runtime).

For each weights file: one gray image of ``--size`` (KITTI's 1226x370 by
default, padded to a multiple of 8 as spslam pads it), batch 1, the network
plus what the ONNX model adds (softmax, depth-to-space, descriptor
normalisation), in fp32 (TF32 off), TF32, fp16 and bf16 autocast, eager and
replayed as a CUDA graph. Each figure is the median of ``--reps`` timed runs
after ``--warmup`` untimed ones, timed with CUDA events. Prints a Markdown
table and writes JSON with ``--json``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys

import torch
import torch.nn.functional as F

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from model import build_student  # noqa: E402


def full_forward(net, x):
    logits, desc = net(x)
    scores = F.pixel_shuffle(F.softmax(logits.float(), dim=1)[:, :-1], 8)
    return scores, F.normalize(desc.float(), dim=1)


def time_ms(fn, reps: int, warmup: int):
    for _ in range(warmup):
        fn()
    torch.cuda.synchronize()
    times = []
    for _ in range(reps):
        a, b = torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)
        a.record()
        fn()
        b.record()
        b.synchronize()
        times.append(a.elapsed_time(b))
    return statistics.median(times)


def measure(net, h: int, w: int, mode: str, graph: bool, reps: int, warmup: int) -> float:
    torch.backends.cuda.matmul.allow_tf32 = mode != "fp32"
    torch.backends.cudnn.allow_tf32 = mode != "fp32"
    dtype = {"fp16": torch.float16, "bf16": torch.bfloat16}.get(mode)
    x = torch.rand(1, 1, h, w, device="cuda")

    def step():
        with torch.no_grad(), torch.autocast("cuda", dtype=dtype or torch.float16, enabled=dtype is not None,
                                         cache_enabled=False):
            return full_forward(net, x)
    if not graph:
        return time_ms(step, reps, warmup)
    s = torch.cuda.Stream()
    s.wait_stream(torch.cuda.current_stream())
    with torch.cuda.stream(s):
        for _ in range(3):
            step()
    torch.cuda.current_stream().wait_stream(s)
    g = torch.cuda.CUDAGraph()
    with torch.cuda.graph(g):
        step()
    return time_ms(g.replay, reps, warmup)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", action="append", required=True, help="NAME=WEIGHTS.pth (repeatable)")
    ap.add_argument("--size", default="1226x370", help="WxH of the image")
    ap.add_argument("--reps", type=int, default=200)
    ap.add_argument("--warmup", type=int, default=30)
    ap.add_argument("--json", default="")
    args = ap.parse_args(argv)
    if not torch.cuda.is_available():
        raise SystemExit("gpu_speed: PyTorch sees no CUDA device")
    torch.backends.cudnn.benchmark = True
    w, h = (int(v) for v in args.size.lower().split("x"))
    hp, wp = (h + 7) // 8 * 8, (w + 7) // 8 * 8
    rows = []
    for spec in args.model:
        name, path = spec.split("=", 1)
        net = build_student(path).cuda().eval().to(memory_format=torch.channels_last)
        for mode in ("fp32", "tf32", "fp16", "bf16"):
            for graph in (False, True):
                try:
                    ms = measure(net, hp, wp, mode, graph, args.reps, args.warmup)
                except RuntimeError as e:  # report and go on: one mode's failure must not hide the others
                    print(f"{name:12s} {mode:5s} graph={graph!s:5s} failed: {e}", flush=True)
                    continue
                rows.append({"model": name, "mode": mode, "cuda_graph": graph, "ms": round(ms, 3),
                             "fps": round(1000 / ms, 1)})
                print(f"{name:12s} {mode:5s} graph={graph!s:5s} {ms:7.3f} ms  {1000 / ms:7.1f} fps", flush=True)
    info = {"gpu": torch.cuda.get_device_name(), "torch": torch.__version__, "cudnn": torch.backends.cudnn.version(),
            "image": f"{w}x{h} padded to {wp}x{hp}", "batch": 1, "reps": args.reps, "rows": rows}
    print(f"\n{info['gpu']}, torch {info['torch']}, cuDNN {info['cudnn']}, {info['image']}, batch 1, "
          f"median of {args.reps}\n")
    print("| model | precision | CUDA graph | ms | frames/s |\n|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['model']} | {r['mode']} | {'yes' if r['cuda_graph'] else 'no'} | {r['ms']:.2f} | {r['fps']:.0f} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(info, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
