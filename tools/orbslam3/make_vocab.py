#!/usr/bin/env python3
"""Build a small DBoW2 vocabulary in ORB-SLAM3's text format (ORBvoc.txt layout).

The real ORBvoc.txt (UZ-SLAMLab/ORB_SLAM3, Vocabulary/ORBvoc.txt.tar.gz) is not
shipped by any registry package we found (orbslam3-python, pyorbslam3,
python-orb-slam3, pywrapped-orbslam3 all lack it; pyorbslam3 downloads it from
GitHub at run time, which is not reachable here). ORB-SLAM3 cannot start
without a vocabulary, so this script trains a substitute: hierarchical k-means
(k-means++ seeding, majority-vote bit means as DBoW2's FORB::meanValue) on
OpenCV ORB descriptors of the given images, TF-IDF weights, L1 scoring.

File format read by TemplatedVocabulary::loadFromTextFile:
  line 1: "k L scoring weighting"   (scoring 0 = L1_NORM, weighting 0 = TF_IDF)
  then one line per node (root excluded), parents before children:
  "parent_id is_leaf d0 d1 ... d31 weight"  (32 descriptor bytes as integers)
The file must not end with a newline: the loader's `while(!f.eof())` loop
would otherwise add an empty node.

Caveat: a vocabulary trained on the sequence it is then run on is optimistic
for place recognition; for 51 frames of tracking (no loop) it only feeds
Frame::ComputeBoW / SearchByBoW (reference-keyframe tracking, relocalisation).

Usage:
  python make_vocab.py --out voc.txt DIR_OR_GLOB [...]   (PNG images)
"""
import argparse
import glob
import math
import os
import sys
import time

import numpy as np


def orb_descriptors(paths, nfeatures):
    import cv2

    # ORB-SLAM3-like settings: 1.2 scale, 8 levels, FAST threshold 20.
    orb = cv2.ORB_create(nfeatures, 1.2, 8, 31, 0, 2, cv2.ORB_HARRIS_SCORE, 31, 20)
    per_image = []
    for p in paths:
        im = cv2.imread(p, cv2.IMREAD_GRAYSCALE)
        if im is None:
            raise SystemExit(f"cannot read {p}")
        _, d = orb.detectAndCompute(im, None)
        if d is not None and len(d):
            per_image.append(d)
    return per_image


def hamming_to_centers(bits, centers_bits):
    """bits: (n,256) float32 0/1; centers_bits: (c,256). Returns (n,c)."""
    a = bits.sum(1, keepdims=True)
    b = centers_bits.sum(1)[None, :]
    return a + b - 2.0 * bits @ centers_bits.T


def kmeanspp(bits, k, rng):
    n = bits.shape[0]
    idx = [int(rng.integers(n))]
    d = hamming_to_centers(bits, bits[idx]).min(1)
    for _ in range(1, k):
        w = d * d
        s = w.sum()
        if s <= 0:
            break
        i = int(rng.choice(n, p=w / s))
        idx.append(i)
        d = np.minimum(d, hamming_to_centers(bits, bits[[i]])[:, 0])
    return bits[idx].copy()


def kmeans(bits, k, rng, iters=10):
    centers = kmeanspp(bits, k, rng)
    assign = None
    for _ in range(iters):
        new_assign = hamming_to_centers(bits, centers).argmin(1)
        if assign is not None and np.array_equal(new_assign, assign):
            break
        assign = new_assign
        for c in range(centers.shape[0]):
            m = assign == c
            if m.any():
                # DBoW2 FORB::meanValue: bit set when at least half the members have it
                centers[c] = (bits[m].mean(0) >= 0.5).astype(np.float32)
    return centers, assign


def build(per_image, k, L, seed):
    rng = np.random.default_rng(seed)
    desc = np.concatenate(per_image)
    bits = np.unpackbits(desc, axis=1).astype(np.float32)
    # nodes: list of [parent, bits(256,) or None, is_leaf]
    nodes = [[-1, None, False]]
    # BFS: (node_id, member indices, level)
    queue = [(0, np.arange(len(desc)), 0)]
    leaf_members = {}
    while queue:
        nid, members, level = queue.pop(0)
        sub = bits[members]
        if len(members) <= k:
            # as DBoW2: each descriptor becomes its own child
            centers = sub.copy()
            assign = np.arange(len(members))
        else:
            centers, assign = kmeans(sub, k, rng)
        for c in range(centers.shape[0]):
            m = members[assign == c]
            if len(m) == 0:
                continue
            cid = len(nodes)
            leaf = level + 1 >= L or len(m) <= 1
            nodes.append([nid, centers[c], leaf])
            if leaf:
                leaf_members[cid] = m
            else:
                queue.append((cid, m, level + 1))
    # TF-IDF: idf = ln(N / n_i), n_i = images with a descriptor in word i
    img_of = np.concatenate([np.full(len(d), i) for i, d in enumerate(per_image)])
    N = len(per_image)
    weights = {}
    for cid, m in leaf_members.items():
        ni = len(np.unique(img_of[m]))
        weights[cid] = math.log(N / ni) if ni else 0.0
    return nodes, weights


def write(path, nodes, weights, k, L):
    lines = [f"{k} {L} 0 0"]
    for cid in range(1, len(nodes)):
        parent, cbits, leaf = nodes[cid]
        d = np.packbits(cbits.astype(np.uint8))
        w = weights.get(cid, 0.0) if leaf else 0.0
        lines.append(f"{parent} {1 if leaf else 0} " + " ".join(str(int(x)) for x in d) + f" {w:.6f}")
    with open(path, "w") as f:
        f.write("\n".join(lines))  # no trailing newline (see module docstring)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("inputs", nargs="+", help="image files, globs or folders of PNGs")
    ap.add_argument("--out", required=True)
    ap.add_argument("--k", type=int, default=10)
    ap.add_argument("--L", type=int, default=5)
    ap.add_argument("--nfeatures", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    paths = []
    for x in a.inputs:
        if os.path.isdir(x):
            paths += sorted(glob.glob(os.path.join(x, "*.png")))
        else:
            paths += sorted(glob.glob(x))
    if not paths:
        raise SystemExit("no images")
    t0 = time.time()
    per_image = orb_descriptors(paths, a.nfeatures)
    n = sum(len(d) for d in per_image)
    nodes, weights = build(per_image, a.k, a.L, a.seed)
    write(a.out, nodes, weights, a.k, a.L)
    print(f"{a.out}: {len(paths)} images, {n} descriptors, {len(nodes) - 1} nodes, "
          f"{len(weights)} words, k={a.k} L={a.L}, {time.time() - t0:.1f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
