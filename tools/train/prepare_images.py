#!/usr/bin/env python3
"""Prepare the training photographs: gray, resized, cropped to multiples of 8, one JPEG each.

Reads every image under ``--src`` (recursively; ``.jpg``, ``.jpeg``, ``.png``,
``.bmp``), converts it to gray, scales it so that its long side is at most
``--max-side`` and it still holds a ``--crop`` training crop, crops it to
multiples of 8 pixels and writes ``<out>/NNNN.jpg`` plus ``<out>/index.tsv``
(new name, source path relative to ``--src``, size). Sorted by path, so the
numbering is the same on every machine. The images stay outside the
repository (``../shared/data/train_images`` is research-use only).
"""

from __future__ import annotations

import argparse
import os
import sys

from PIL import Image

EXTENSIONS = (".jpg", ".jpeg", ".png", ".bmp")


def target_size(w: int, h: int, max_side: int, crop_h: int, crop_w: int):
    """(w, h) after scaling: long side <= max_side, and each side holds the crop (in either orientation)."""
    s = min(1.0, max_side / max(w, h))
    short, long_ = min(crop_h, crop_w), max(crop_h, crop_w)
    need = max(short / (min(w, h) * s), long_ / (max(w, h) * s), 1.0)
    s *= need
    return max(8, int(round(w * s)) // 8 * 8), max(8, int(round(h * s)) // 8 * 8)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--src", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--max-side", type=int, default=640)
    ap.add_argument("--crop", default="240x320", help="HxW of a training crop")
    ap.add_argument("--quality", type=int, default=95)
    args = ap.parse_args(argv)
    crop_h, crop_w = (int(v) for v in args.crop.lower().split("x"))
    paths = []
    for root, _, files in os.walk(args.src):
        paths += [os.path.join(root, f) for f in files if f.lower().endswith(EXTENSIONS)]
    paths.sort()
    if not paths:
        print(f"prepare_images: error: no images under {args.src}", file=sys.stderr)
        return 1
    os.makedirs(args.out, exist_ok=True)
    rows = []
    for i, p in enumerate(paths):
        try:
            with Image.open(p) as im:
                g = im.convert("L")
        except OSError as e:
            print(f"prepare_images: skipping {p}: {e}", file=sys.stderr)
            continue
        w, h = target_size(g.width, g.height, args.max_side, crop_h, crop_w)
        s = max(w / g.width, h / g.height)
        g = g.resize((int(round(g.width * s)) or 1, int(round(g.height * s)) or 1), Image.LANCZOS)
        g = g.crop((0, 0, w, h))
        name = f"{len(rows):04d}.jpg"
        g.save(os.path.join(args.out, name), quality=args.quality)
        rows.append(f"{name}\t{os.path.relpath(p, args.src)}\t{w}x{h}")
    with open(os.path.join(args.out, "index.tsv"), "w") as f:
        f.write("\n".join(rows) + "\n")
    print(f"prepare_images: {len(rows)} images -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
