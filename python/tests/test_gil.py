"""The GIL is released while Rust works: another Python thread keeps running
during extraction and tracking.

No clock is asserted on. A watcher thread counts how often it runs Python
code (sleeping a millisecond between counts) while a worker thread is inside
one call. Had the call kept the GIL, the watcher could not run at all until
it returned: at most a count or two, taken before the worker entered the
call. The calls here take 100-300 ms on a 2-core machine (more when it is
busy, and the count grows with them), so a released GIL gives well over a
hundred counts; the bound, 20, leaves room for a slow scheduler.
"""

import re
import threading
import time

import numpy as np

import spslam
from conftest import gray
from test_system import SETTINGS

MIN_COUNTS_WHILE_RELEASED = 20


def counts_while(call):
    """How many times a watcher thread ran while `call()` ran in a worker."""
    inside = threading.Event()
    finished = threading.Event()
    result = {}

    def worker():
        inside.set()
        result["value"] = call()
        finished.set()

    thread = threading.Thread(target=worker)
    thread.start()
    inside.wait()
    counts = 0
    while not finished.is_set():
        counts += 1
        time.sleep(0.001)
    thread.join()
    return counts, result["value"]


def test_extraction_releases_the_gil(kitti06):
    image = gray(kitti06 / "image_0" / "000000.png")
    extractor = spslam.Extractor(1000, levels=4)
    counts, features = counts_while(lambda: extractor.extract(image))
    assert len(features.keypoints) > 500
    assert counts >= MIN_COUNTS_WHILE_RELEASED, f"the watcher ran {counts} times during extraction"


def test_tracking_releases_the_gil(kitti06):
    left = gray(kitti06 / "image_0" / "000000.png")
    right = gray(kitti06 / "image_1" / "000000.png")
    with spslam.System(SETTINGS, "stereo", inline_mapping=True) as system:
        counts, pose = counts_while(lambda: system.track_stereo(left, right, 0.0))
    assert pose is not None and np.allclose(pose, np.eye(4))
    assert counts >= MIN_COUNTS_WHILE_RELEASED, f"the watcher ran {counts} times during tracking"


def test_matching_releases_the_gil():
    rng = np.random.default_rng(7)
    descriptors = rng.normal(size=(2, 3000, 256)).astype(np.float32)
    descriptors /= np.linalg.norm(descriptors, axis=2, keepdims=True)
    counts, (pairs, _) = counts_while(lambda: spslam.match(descriptors[0], descriptors[1], ratio=None, mutual=False))
    assert len(pairs) > 0
    assert counts >= MIN_COUNTS_WHILE_RELEASED, f"the watcher ran {counts} times during matching"


def test_the_watcher_stops_while_a_call_keeps_the_gil():
    """The control: `re`'s matcher keeps the GIL, and catastrophic
    backtracking (2^24 paths) keeps it for a while; the watcher then runs
    only while the worker is still on its way into the call (once or twice
    on a quiet machine, 5 times once with CI's tests and a fuzzer sharing
    two cores), below the bound that the other tests call released. The
    pattern is compiled beforehand, so the worker has little Python to run
    before the call."""
    pattern = re.compile(r"(a+)+$")
    subject = "a" * 24 + "b"
    counts, matched = counts_while(lambda: pattern.match(subject))
    assert matched is None
    assert counts < MIN_COUNTS_WHILE_RELEASED, f"the watcher ran {counts} times"
