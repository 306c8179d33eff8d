"""spslam: SuperPoint-SLAM3 in Rust, for Python.

- :class:`Extractor`: SuperPoint keypoints and 256-float descriptors spread
  by ANMS (``extract(image)`` on a NumPy ``uint8`` image);
- :func:`match`: the L2 (or Hamming) brute-force matcher with the ratio test
  and the mutual check;
- :class:`System`: stereo, RGB-D and monocular SLAM, shaped like the
  ``orbslam3-python`` bindings;
- :mod:`spslam.eval`: evo's ATE/RPE and the KITTI devkit's metric.

ONNX Runtime's library comes from the ``onnxruntime`` package (found here
without importing it) unless ``ORT_DYLIB_PATH`` names one; the models come
with the wheel unless ``SPSLAM_MODELS_DIR`` names another folder.
"""

import os
from importlib.util import find_spec
from pathlib import Path


def _onnxruntime_library():
    """The ``libonnxruntime.so.*`` shipped in the ``onnxruntime`` wheel."""
    spec = find_spec("onnxruntime")
    if spec is None or not spec.submodule_search_locations:
        return None
    for location in spec.submodule_search_locations:
        found = sorted((Path(location) / "capi").glob("libonnxruntime.so.*"))
        if found:
            return found[-1]
    return None


def _prepare_environment():
    models = Path(__file__).resolve().parent / "models"
    if models.is_dir() and not os.environ.get("SPSLAM_MODELS_DIR"):
        os.environ["SPSLAM_MODELS_DIR"] = str(models)
    if not os.environ.get("ORT_DYLIB_PATH"):
        library = _onnxruntime_library()
        if library is not None:
            os.environ["ORT_DYLIB_PATH"] = str(library)


_prepare_environment()

from ._spslam import (  # noqa: E402
    Extractor,
    Features,
    SpslamError,
    System,
    __version__,
)
from ._spslam import match  # noqa: E402
from . import eval  # noqa: E402,F401

__all__ = ["Extractor", "Features", "SpslamError", "System", "match", "eval", "__version__"]
