#!/usr/bin/env python3
"""Stereo same-row fraction: of the mutual L2 nearest-neighbour matches between
the left and right images of rectified stereo pairs, the share that lie within
+-2 px of the same row (a rectified pair's true matches all do).

Keypoints come from ``spslam extract`` with ORB-SLAM3's pyramid (8 levels,
scale 1.2; ``--features`` as the settings' ORBextractor.nFeatures), the
extractor the C ABI shim wraps. Several models can be compared on the same
pairs. Needs numpy (the tools' venv) and a built ``spslam``.

Usage::

    python tools/stereo_same_row.py --left DIR --right DIR [--every 10] \\
        --model NAME[=PATH] [--model ...] [--precision int8]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_homography import extract, mutual_nn  # noqa: E402

ROW_TOLERANCE_PX = 2.0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--left", required=True)
    ap.add_argument("--right", required=True)
    ap.add_argument("--every", type=int, default=10, help="use every N-th pair")
    ap.add_argument("--model", action="append", required=True)
    ap.add_argument("--precision", default="int8", choices=["int8", "fp32"])
    ap.add_argument("--features", type=int, default=2000)
    ap.add_argument("--label", default="")
    ap.add_argument("--spslam", default=os.path.join(os.path.dirname(__file__), "..", "target", "release", "spslam"))
    args = ap.parse_args(argv)
    names = sorted(f for f in os.listdir(args.left) if f.lower().endswith((".png", ".jpg")))[:: args.every]
    names = [n for n in names if os.path.exists(os.path.join(args.right, n))]
    if not names:
        print(f"stereo_same_row: error: no pairs with the same name in {args.left} and {args.right}", file=sys.stderr)
        return 1
    extra = ["--levels", "8", "--scale-factor", "1.2"]
    print(f"\nStereo same-row fraction: {args.label or args.left}; {len(names)} pairs, {args.precision}, "
          f"8 levels x 1.2, {args.features} keypoints, mutual L2 NN, |dy| <= {ROW_TOLERANCE_PX:g} px\n")
    print("| model | same-row fraction | mutual matches per pair |")
    print("|---|---|---|")
    for spec in args.model:
        name, path = spec.split("=", 1) if "=" in spec else (spec, None)
        with tempfile.TemporaryDirectory() as tmp:
            files = []
            for n in names:
                for side, d in (("l", args.left), ("r", args.right)):
                    link = os.path.join(tmp, f"{side}_{os.path.splitext(n)[0]}.png")
                    os.symlink(os.path.abspath(os.path.join(d, n)), link)
                    files.append(link)
            out = os.path.join(tmp, "out")
            os.makedirs(out)
            feats = extract(args.spslam, path, args.precision, files, out,
                            extra, features=args.features)
        same, total = 0, 0
        for i in range(len(names)):
            (kl, dl), (kr, dr) = feats[files[2 * i]], feats[files[2 * i + 1]]
            m = mutual_nn(dl, dr)
            same += int((np.abs(kl[m[:, 0], 1] - kr[m[:, 1], 1]) <= ROW_TOLERANCE_PX).sum())
            total += len(m)
        print(f"| {name} | {same / max(1, total):.3f} | {total / len(names):.0f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
