"""Run by tools/python_wheel.sh with the system's copies of the wheel's grafted
libraries hidden: the installed package must still import and extract, and
the OpenCV it loads must be the wheel's own copy."""

import numpy as np

import spslam

rows, cols = np.mgrid[0:240, 0:320]
image = ((np.sin(rows / 7.0) * np.cos(cols / 5.0) + 1.0) * 120).astype(np.uint8)
features = spslam.Extractor(features=200).extract(image)
with open("/proc/self/maps", encoding="utf-8") as maps_file:
    maps = maps_file.read()
if "/usr/lib/x86_64-linux-gnu/libopencv" in maps:
    raise SystemExit("error: the system's OpenCV was loaded, not the wheel's")
if "spslam.libs/libopencv_core" not in maps:
    raise SystemExit("error: the wheel's OpenCV (spslam.libs/libopencv_core) was not loaded")
if len(features.keypoints) == 0:
    raise SystemExit("error: no keypoints on the test pattern")
print(f"self-contained: {len(features.keypoints)} keypoints, OpenCV from spslam.libs")
