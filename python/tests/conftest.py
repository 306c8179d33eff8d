"""Shared fixtures: the data folder (`SPSLAM_DATA`, else ../shared/data
beside the repository; missing data fails under CI=true and skips
elsewhere), the `spslam` binary the package is compared with, and image
reading (Pillow)."""

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

REPO = Path(__file__).resolve().parents[2]


def _missing(what):
    if os.environ.get("CI") == "true":
        pytest.fail(f"{what} is missing and CI=true: the test cannot run")
    pytest.skip(f"{what} is missing")


@pytest.fixture(scope="session")
def data_dir():
    root = Path(os.environ.get("SPSLAM_DATA") or REPO.parent / "shared" / "data")
    if not root.is_dir():
        _missing(f"the data folder {root}")
    return root


@pytest.fixture(scope="session")
def kitti06(data_dir):
    seq = data_dir / "kitti" / "sequences" / "06"
    if not (seq / "image_0").is_dir():
        _missing(f"the KITTI 06 excerpt {seq}")
    return seq


@pytest.fixture(scope="session")
def evo_data(data_dir):
    folder = data_dir / "trajectories" / "evo_test_data"
    if not folder.is_dir():
        _missing(f"evo's test data {folder}")
    return folder


@pytest.fixture(scope="session")
def spslam_bin():
    binary = Path(os.environ.get("SPSLAM_BIN") or REPO / "target" / "release" / "spslam")
    if not binary.is_file():
        _missing(f"the spslam binary {binary} (run `make build`)")
    return binary


def run_cli(binary, *args):
    """Runs the spslam CLI; fails the test with its output when it fails."""
    done = subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True)
    if done.returncode != 0:
        pytest.fail(f"spslam {' '.join(map(str, args))} failed:\n{done.stdout}\n{done.stderr}")
    return done


def gray(path):
    """An 8-bit gray image file as a NumPy array."""
    image = np.asarray(Image.open(path))
    assert image.dtype == np.uint8 and image.ndim == 2, f"{path} is not 8-bit gray"
    return image
