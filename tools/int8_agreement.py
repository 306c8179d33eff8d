#!/usr/bin/env python3
"""How closely an int8 SuperPoint model follows the fp32 export -- one job.

Usage::

    python tools/int8_agreement.py --fp32 models/superpoint.onnx \
        --int8 models/superpoint_int8.onnx IMAGE [IMAGE ...] [--band 5]

Prints, per image, the mean cosine of the dense descriptors (interior beyond
the fold's border band of ``--band`` cells, and the whole frame) and the
correlation of the score maps in the interior: the figures of
``test_export.py``'s ``test_int8_close_to_fp32``.

The int8 kernels ONNX Runtime picks depend on the CPU (AVX-512 VNNI, AVX2,
...). To see another CPU's numbers on this one, run the same command under
QEMU's user-mode emulator, whose TCG CPU has AVX2 but no AVX-512::

    qemu-x86_64 -cpu max .deps/venv/bin/python tools/int8_agreement.py ...

(``apt-get install qemu-user``; about 100x slower, a minute per KITTI frame).
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np
import onnxruntime as ort

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import quantize_superpoint as qz  # noqa: E402


def border_distance(h: int, w: int) -> np.ndarray:
    """[h, w] array: distance of each element to the nearest edge (0 on the edge)."""
    y = np.minimum(np.arange(h), h - 1 - np.arange(h))[:, None]
    x = np.minimum(np.arange(w), w - 1 - np.arange(w))[None, :]
    return np.minimum(y, x)


def run(path: str, image: np.ndarray):
    """(scores [1,H,W], desc [1,256,H/8,W/8]) of the model at ``path``."""
    options = ort.SessionOptions()
    options.intra_op_num_threads = 2
    sess = ort.InferenceSession(path, options, providers=["CPUExecutionProvider"])
    return sess.run(["scores", "desc"], {"image": image.astype(np.float32)})


def agreement(fp32: str, int8: str, image: np.ndarray, band: int) -> dict:
    """Descriptor cosine (interior, whole) and interior score correlation."""
    s0, d0 = run(fp32, image)
    s1, d1 = run(int8, image)
    hc, wc = d0.shape[2:]
    cells = border_distance(hc, wc) >= band
    pixels = border_distance(8 * hc, 8 * wc) >= 8 * band
    cos = (d0 * d1).sum(axis=1)[0]
    return {
        "desc_cosine_interior": float(cos[cells].mean()),
        "desc_cosine_whole": float(cos.mean()),
        "scores_corr_interior": float(np.corrcoef(s0[0][pixels], s1[0][pixels])[0, 1]),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--fp32", required=True)
    ap.add_argument("--int8", required=True, action="append", help="an int8 model (repeat for several)")
    ap.add_argument("--band", type=int, default=5, help="border band in cells (default 5)")
    ap.add_argument("--crop", type=int, default=0,
                    help="use the central CROP x CROP pixels only (a multiple of 8; quicker under emulation)")
    ap.add_argument("images", nargs="+")
    args = ap.parse_args()
    for path in args.images:
        image = qz.read_gray(path)
        if args.crop:
            h, w = image.shape
            top, left = (h - args.crop) // 2, (w - args.crop) // 2
            image = image[top:top + args.crop, left:left + args.crop]
        image = image[None, None]
        for int8 in args.int8:
            a = agreement(args.fp32, int8, image, args.band)
            print(f"{os.path.basename(path)} {os.path.basename(int8)}: desc cosine interior "
                  f"{a['desc_cosine_interior']:.4f} whole {a['desc_cosine_whole']:.4f}, "
                  f"scores corr interior {a['scores_corr_interior']:.4f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
