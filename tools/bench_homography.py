#!/usr/bin/env python3
"""Homography benchmark for SuperPoint models, through spslam's own extractor.

Each image is warped by ``--pairs`` seeded random homographies (rotation up to
+-20 deg, scale 0.8-1.2, strong perspective, a translation that keeps most of
the image) with a photometric change (gain, gamma, Gaussian noise). Both views
go through ``spslam extract`` with the model under test (int8 or fp32, one
level, 1000 keypoints, ANMS: the product's defaults), and each pair is scored:

* repeatability@3 px (SuperPoint's definition): keypoints of either view that
  have one of the other view within 3 px after the true warp, over the
  keypoints that land inside the other view;
* mutual nearest-neighbour matches by L2 distance, and their mean matching
  accuracy MMA@1/3/5 px (share of matches whose true reprojection error is
  within the threshold);
* homography accuracy: a RANSAC homography (3 px) from the matches, correct
  when the image corners it maps lie within 3 px of the true ones on average.

The warps and photometric changes are drawn from ``--seed`` and the image's
index only, so every model sees the same pairs. Prints a markdown table and
writes ``--json``. Needs numpy and Pillow (the tools' venv) and a built
``spslam``.

Usage::

    python tools/bench_homography.py --images DIR_OR_FILES... \\
        --model NAME=PATH [--model NAME=PATH ...] [--precision int8] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass

import numpy as np
from PIL import Image

EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
THRESHOLDS = (1.0, 3.0, 5.0)
REPEAT_PX = 3.0
HOMOGRAPHY_PX = 3.0


@dataclass
class Pair:
    """One benchmark pair: the source image, its warp and the true homography (warped -> source)."""

    name: str
    source_index: int
    source: np.ndarray
    warped: np.ndarray
    h: np.ndarray


def list_images(specs):
    """Image files from files and folders (folders: sorted, not recursive)."""
    out = []
    for s in specs:
        if os.path.isdir(s):
            out += sorted(os.path.join(s, f) for f in os.listdir(s) if f.lower().endswith(EXTENSIONS))
        elif os.path.isfile(s):
            out.append(s)
        else:
            raise FileNotFoundError(f"no image or folder at {s}")
    if not out:
        raise FileNotFoundError("no images found in " + ", ".join(specs))
    return out


def load_gray(path: str, max_side: int) -> np.ndarray:
    with Image.open(path) as im:
        g = im.convert("L")
    s = min(1.0, max_side / max(g.size))
    if s < 1.0:
        g = g.resize((max(8, round(g.width * s)), max(8, round(g.height * s))), Image.LANCZOS)
    return np.asarray(g, dtype=np.float32) / 255.0


def dlt(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """H with dst ~ H src from N >= 4 correspondences (normalised DLT)."""
    def norm(p):
        c = p.mean(0)
        s = math.sqrt(2) / max(1e-9, np.sqrt(((p - c) ** 2).sum(1)).mean())
        t = np.array([[s, 0, -s * c[0]], [0, s, -s * c[1]], [0, 0, 1]])
        return (np.c_[p, np.ones(len(p))] @ t.T)[:, :2], t
    ps, ts = norm(src)
    pd, td = norm(dst)
    rows = []
    for (x, y), (u, v) in zip(ps, pd):
        rows.append([x, y, 1, 0, 0, 0, -u * x, -u * y, -u])
        rows.append([0, 0, 0, x, y, 1, -v * x, -v * y, -v])
    _, _, vt = np.linalg.svd(np.asarray(rows))
    h = np.linalg.inv(td) @ vt[-1].reshape(3, 3) @ ts
    return h / h[2, 2] if abs(h[2, 2]) > 1e-12 else h


def apply_h(h: np.ndarray, p: np.ndarray) -> np.ndarray:
    q = np.c_[p, np.ones(len(p))] @ h.T
    with np.errstate(divide="ignore", invalid="ignore"):
        return q[:, :2] / q[:, 2:3]


def random_homography(rng: np.random.Generator, w: int, h: int) -> np.ndarray:
    """Warped -> source homography: the image's corners moved by rotation, scale, perspective, shift."""
    angle = math.radians(rng.uniform(-20, 20))
    scale = rng.uniform(0.8, 1.2)
    c = np.array([w / 2, h / 2])
    corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], float)
    persp = rng.uniform(-0.15, 0.15, size=(4, 2)) * np.array([w, h])
    rot = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    moved = ((corners - c) @ rot.T) / scale + c + persp + rng.uniform(-0.05, 0.05, 2) * np.array([w, h])
    return dlt(corners, moved)


def warp_image(img: np.ndarray, hmat: np.ndarray) -> np.ndarray:
    """Bilinear backward warp (pixel centres at integer coordinates), zero outside."""
    hh, ww = img.shape
    ys, xs = np.mgrid[0:hh, 0:ww]
    src = apply_h(hmat, np.c_[xs.ravel(), ys.ravel()].astype(float))
    x, y = src[:, 0], src[:, 1]
    ok = (x >= 0) & (y >= 0) & (x <= ww - 1) & (y <= hh - 1)
    x0 = np.clip(np.floor(x).astype(int), 0, ww - 2)
    y0 = np.clip(np.floor(y).astype(int), 0, hh - 2)
    fx, fy = np.clip(x - x0, 0, 1), np.clip(y - y0, 0, 1)
    v = (img[y0, x0] * (1 - fx) * (1 - fy) + img[y0, x0 + 1] * fx * (1 - fy)
         + img[y0 + 1, x0] * (1 - fx) * fy + img[y0 + 1, x0 + 1] * fx * fy)
    return np.where(ok, v, 0.0).reshape(hh, ww)


def photometric(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    gain, gamma, noise = rng.uniform(0.6, 1.4), rng.uniform(0.7, 1.4), rng.uniform(0.0, 0.02)
    out = np.clip(img, 0, 1) ** gamma * gain + rng.normal(0, noise, img.shape)
    return np.clip(out, 0, 1)


def make_pairs(paths, n_pairs: int, seed: int, max_side: int):
    pairs = []
    for i, p in enumerate(paths):
        img = load_gray(p, max_side)
        for k in range(n_pairs):
            rng = np.random.default_rng([seed, i, k])
            hm = random_homography(rng, img.shape[1], img.shape[0])
            pairs.append(Pair(f"{os.path.basename(p)}#{k}", i, img, photometric(warp_image(img, hm), rng), hm))
    return pairs


def extract(spslam: str, model, precision: str, files, out_dir: str, extra, features: int = 1000):
    """Run `spslam extract` once over all files (one level unless ``extra`` says otherwise);
    return {file: (xy [N,2], desc [N,D])}."""
    if "--levels" not in extra:
        extra = ["--levels", "1", *extra]
    cmd = [spslam, "extract", *files, "--json", os.path.join(out_dir, "f.json"),
           "--precision", precision, "--features", str(features), *extra]
    if model is not None:
        cmd += ["--model", model]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"spslam extract failed ({r.returncode}): {r.stderr.strip()[-2000:]}")
    feats = {}
    for f in files:
        stem = os.path.splitext(os.path.basename(f))[0]
        path = os.path.join(out_dir, f"f_{stem}.json") if len(files) > 1 else os.path.join(out_dir, "f.json")
        with open(path) as fh:
            j = json.load(fh)
        xy = np.array([[k["x"], k["y"]] for k in j["keypoints"]], np.float32).reshape(-1, 2)
        d = np.array(j["descriptors"], np.float32).reshape(len(xy), -1)
        feats[f] = (xy, d)
    return feats


def mutual_nn(d1: np.ndarray, d2: np.ndarray) -> np.ndarray:
    if len(d1) == 0 or len(d2) == 0:
        return np.zeros((0, 2), int)
    dist = (d1 * d1).sum(1)[:, None] + (d2 * d2).sum(1)[None, :] - 2 * d1 @ d2.T
    a = dist.argmin(1)
    b = dist.argmin(0)
    i = np.arange(len(d1))
    keep = b[a] == i
    return np.c_[i[keep], a[keep]]


def ransac_homography(p1, p2, rng, iters=2000, thr=HOMOGRAPHY_PX):
    """H with p2 ~ H p1 by RANSAC (4-point samples), refit on the inliers; None when < 4 matches."""
    if len(p1) < 4:
        return None
    best = None
    for _ in range(iters):
        s = rng.choice(len(p1), 4, replace=False)
        try:
            h = dlt(p1[s], p2[s])
        except np.linalg.LinAlgError:
            continue
        err = np.linalg.norm(apply_h(h, p1) - p2, axis=1)
        inl = np.nan_to_num(err, nan=1e9) < thr
        if best is None or inl.sum() > best.sum():
            best = inl
    if best is None or best.sum() < 4:
        return None
    return dlt(p1[best], p2[best])


def score_pair(pair: Pair, f1, f2, seed: int):
    """The pair's metrics: keypoints of the source (1) against the warped view (2)."""
    (k1, d1), (k2, d2) = f1, f2
    hh, ww = pair.source.shape
    h21 = pair.h                      # warped -> source
    h12 = np.linalg.inv(pair.h)       # source -> warped
    k1w = apply_h(h12, k1)
    k2s = apply_h(h21, k2)
    inside1 = (k1w[:, 0] >= 0) & (k1w[:, 0] <= ww - 1) & (k1w[:, 1] >= 0) & (k1w[:, 1] <= hh - 1)
    inside2 = (k2s[:, 0] >= 0) & (k2s[:, 0] <= ww - 1) & (k2s[:, 1] >= 0) & (k2s[:, 1] <= hh - 1)
    rep = float("nan")
    if inside1.any() and inside2.any():
        dd = np.linalg.norm(k1w[inside1][:, None] - k2[inside2][None], axis=2)
        rep = ((dd.min(1) <= REPEAT_PX).sum() + (dd.min(0) <= REPEAT_PX).sum()) / (inside1.sum() + inside2.sum())
    m = mutual_nn(d1, d2)
    err = np.linalg.norm(k1w[m[:, 0]] - k2[m[:, 1]], axis=1) if len(m) else np.zeros(0)
    mma = {t: float((err <= t).mean()) if len(err) else 0.0 for t in THRESHOLDS}
    h_est = ransac_homography(k1[m[:, 0]].astype(float), k2[m[:, 1]].astype(float),
                              np.random.default_rng(seed)) if len(m) else None
    corners = np.array([[0, 0], [ww - 1, 0], [ww - 1, hh - 1], [0, hh - 1]], float)
    if h_est is None:
        h_ok = False
    else:
        ce = np.linalg.norm(apply_h(h_est, corners) - apply_h(h12, corners), axis=1).mean()
        h_ok = bool(np.isfinite(ce) and ce <= HOMOGRAPHY_PX)
    return {"pair": pair.name, "keypoints": [int(len(k1)), int(len(k2))], "repeatability_3px": float(rep),
            "matches": int(len(m)), "correct_3px": int((err <= 3).sum()),
            **{f"mma_{int(t)}px": v for t, v in mma.items()}, "homography_ok": h_ok}


def summarise(rows):
    def mean(key):
        v = [r[key] for r in rows if not (isinstance(r[key], float) and math.isnan(r[key]))]
        return float(np.mean(v)) if v else float("nan")
    return {"pairs": len(rows), "mma_1px": mean("mma_1px"), "mma_3px": mean("mma_3px"),
            "mma_5px": mean("mma_5px"), "repeatability_3px": mean("repeatability_3px"),
            "matches": mean("matches"), "correct_3px": mean("correct_3px"),
            "homography_3px": float(np.mean([r["homography_ok"] for r in rows]))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--images", nargs="+", required=True, help="image files or folders")
    ap.add_argument("--model", action="append", required=True,
                    help="NAME=PATH of an ONNX model, or NAME alone for spslam's default model of --precision (repeat)")
    ap.add_argument("--precision", default="int8", choices=["int8", "fp32"],
                    help="must match the models (int8 models are quantised graphs)")
    ap.add_argument("--pairs", type=int, default=3, help="warps per image")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-side", type=int, default=640)
    ap.add_argument("--spslam", default=os.path.join(os.path.dirname(__file__), "..", "target", "release", "spslam"))
    ap.add_argument("--no-periodic-filter", action="store_true")
    ap.add_argument("--json", help="write per-pair rows and the summary here")
    ap.add_argument("--label", default="", help="name of the image set, for the table")
    args = ap.parse_args(argv)
    try:
        models = [m.split("=", 1) if "=" in m else [m, None] for m in args.model]
        missing = [m for m in models if m[1] is not None and not os.path.isfile(m[1])]
        if missing:
            raise FileNotFoundError("no model file at " + ", ".join(m[1] for m in missing))
        if not os.path.isfile(args.spslam):
            raise FileNotFoundError(f"spslam not built at {args.spslam} (cargo build --release)")
        paths = list_images(args.images)
        pairs = make_pairs(paths, args.pairs, args.seed, args.max_side)
    except (OSError, ValueError) as e:
        print(f"bench_homography: error: {e}", file=sys.stderr)
        return 1
    extra = ["--no-periodic-filter"] if args.no_periodic_filter else []
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        def save(img, f):
            Image.fromarray(np.round(img * 255).astype(np.uint8)).save(f)
            return f

        # Each source image is extracted once, however many warps it has.
        sources = {p.source_index: p.source for p in pairs}
        source_files = {i: save(img, os.path.join(tmp, f"src{i:04d}.png")) for i, img in sources.items()}
        warped_files = [save(p.warped, os.path.join(tmp, f"warp{i:04d}.png")) for i, p in enumerate(pairs)]
        files = list(source_files.values()) + warped_files
        for name, path in models:
            out = os.path.join(tmp, "out_" + name)
            os.makedirs(out)
            try:
                feats = extract(args.spslam, path, args.precision, files, out, extra)
            except RuntimeError as e:
                print(f"bench_homography: error: model {name}: {e}", file=sys.stderr)
                return 1
            rows = [score_pair(p, feats[source_files[p.source_index]], feats[warped_files[i]], args.seed + i)
                    for i, p in enumerate(pairs)]
            results[name] = {"summary": summarise(rows), "pairs": rows}
    label = args.label or ", ".join(args.images)
    print(f"\nHomography benchmark: {label}; {len(paths)} images x {args.pairs} warps = {len(pairs)} pairs, "
          f"seed {args.seed}, {args.precision}, 1 level, 1000 keypoints, ANMS"
          f"{', periodic filter off' if args.no_periodic_filter else ''}\n")
    print("| model | MMA@1 | MMA@3 | MMA@5 | rep@3 | matches | correct@3 | H@3px |")
    print("|---|---|---|---|---|---|---|---|")
    for name, r in results.items():
        s = r["summary"]
        print(f"| {name} | {s['mma_1px']:.3f} | {s['mma_3px']:.3f} | {s['mma_5px']:.3f} | "
              f"{s['repeatability_3px']:.3f} | {s['matches']:.0f} | {s['correct_3px']:.0f} | {s['homography_3px']:.3f} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"images": paths, "seed": args.seed, "pairs_per_image": args.pairs,
                       "precision": args.precision, "models": results}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
