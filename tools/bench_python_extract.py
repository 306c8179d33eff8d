"""Extraction through the Python package, timed around the call, for the
comparison with criterion's `extractor/<frame>/end_to_end_kdtree` (the same
settings: 1000 keypoints, one level, ANMS k-d tree, int8, the default model).

    python tools/bench_python_extract.py IMAGE [--runs 60] [--warm-up 5]

Prints the median, the mean and the interquartile range in milliseconds, and
the part of each call outside the Rust extractor (image in, arrays out).
Run it with the venv the wheel is installed in (`make test-python-package`
leaves one in .deps/venv-wheel-test).
"""

import argparse
import statistics
import time

import numpy as np
from PIL import Image

import spslam


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("image")
    parser.add_argument("--runs", type=int, default=60)
    parser.add_argument("--warm-up", type=int, default=5)
    args = parser.parse_args()
    image = np.asarray(Image.open(args.image))
    extractor = spslam.Extractor(1000, anms="kdtree", levels=1, precision="int8")
    for _ in range(args.warm_up):
        extractor.extract(image)
    times, inside = [], []
    for _ in range(args.runs):
        start = time.perf_counter()
        features = extractor.extract(image)
        times.append((time.perf_counter() - start) * 1e3)
        inside.append(features.timings["total"])
    quartiles = statistics.quantiles(times, n=4)
    print(
        f"{args.image}: {image.shape[1]}x{image.shape[0]}, {args.runs} runs: "
        f"median {statistics.median(times):.2f} ms, mean {statistics.mean(times):.2f} ms, "
        f"IQR {quartiles[0]:.2f}-{quartiles[2]:.2f} ms; the extractor's own total "
        f"(timings['total']) median {statistics.median(inside):.2f} ms; the binding's share "
        f"(call minus own total) median {statistics.median(t - i for t, i in zip(times, inside)):.3f} ms"
    )


if __name__ == "__main__":
    main()
