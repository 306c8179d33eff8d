"""Writes a synthetic 640x480 gray test image (binary PGM) for `make demo`
when the real data is not available: random rectangles, discs and a
checkerboard on a smooth gradient, from a fixed seed.

Usage: python tools/make_test_image.py OUT.png   (the file is PGM whatever its name says:
OpenCV reads it by content)
"""
import sys

import numpy as np


def make_image(width=640, height=480, seed=7):
    """Returns a uint8 [height, width] image with corners, edges and blobs."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:height, 0:width]
    img = 60 + 80 * xx / width + 40 * yy / height
    for _ in range(40):
        x0, y0 = rng.integers(0, width - 60), rng.integers(0, height - 60)
        w, h = rng.integers(15, 80), rng.integers(15, 80)
        img[y0:y0 + h, x0:x0 + w] = rng.integers(0, 255)
    for _ in range(30):
        cx, cy, r = rng.integers(0, width), rng.integers(0, height), rng.integers(5, 30)
        img[(xx - cx) ** 2 + (yy - cy) ** 2 < r * r] = rng.integers(0, 255)
    board = ((xx // 16 + yy // 16) % 2) * 200 + 25
    img[300:420, 40:240] = board[300:420, 40:240]
    img += rng.normal(0, 3, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: make_test_image.py OUT")
    img = make_image()
    with open(sys.argv[1], "wb") as f:
        f.write(b"P5\n%d %d\n255\n" % (img.shape[1], img.shape[0]))
        f.write(img.tobytes())


if __name__ == "__main__":
    main()
