"""A recording of `spslam run --rerun` read back with rerun's own reader
(rerun-sdk from PyPI): its entities and their counts against the run's
report.json.

    python tools/test_rerun_recording.py RUN_DIR   # RUN_DIR: --out of a run made with --rerun RUN_DIR/run.rrd

Checks: one camera pose, image, keypoint set and scalar per tracked frame
(less the frames the viewer dropped, from the run's stderr line); the
last copy of the points holds the map's points; one frustum entity per
live keyframe; the estimated trajectory holds every frame; the ground
truth is there when the run had one.
"""

import json
import re
import sys
from collections import Counter, defaultdict
from pathlib import Path

from rerun.experimental import RrdReader


def fail(message):
    print(f"FAIL: {message}")
    sys.exit(1)


def main(run_dir):
    report = json.loads((run_dir / "report.json").read_text())
    log = (run_dir / "stderr.txt").read_text()
    found = re.search(r"viewer: (\d+) frames and (\d+) copies of the map logged; (\d+) dropped", log)
    if not found:
        fail("the run's stderr has no viewer line")
    frames_logged, maps_logged, dropped = map(int, found.groups())
    summary = report["summary"]
    frames = len(report["frames"])
    tracked = sum(1 for f in report["frames"] if f["state"] == "Ok")

    rows = Counter()
    last_batch = {}
    keyframe_entities = set()
    for chunk in RrdReader(run_dir / "run.rrd").stream():
        path = chunk.entity_path
        if chunk.is_static:
            rows[(path, "static")] += chunk.num_rows
            last_batch[(path, "static")] = chunk.to_record_batch()
            continue
        rows[path] += chunk.num_rows
        last_batch[path] = chunk.to_record_batch()
        if "/keyframes/" in path:
            keyframe_entities.add(path)

    def column_length(key, suffix):
        batch = last_batch[key]
        name = next(n for n in batch.schema.names if n.endswith(suffix))
        return len(batch.column(name)[batch.num_rows - 1])

    checks = []

    def check(name, actual, expected, at_most=None):
        """`actual` must equal `expected`, or lie in [expected, at_most]."""
        checks.append((name, actual, expected, expected if at_most is None else at_most))

    check("frames handed to the viewer", frames_logged + dropped, frames)
    check("camera poses", rows["/world/camera"], tracked - dropped, tracked)
    check("images", rows["/world/camera/image"], frames_logged)
    check("keypoint sets", rows["/world/camera/image/keypoints"], frames_logged)
    for scalar in ("tracking/inliers", "timings/extraction_ms", "timings/tracking_ms"):
        check(scalar, rows["/" + scalar], frames_logged)
    check("copies of the map", rows["/world/trajectory/estimate"], maps_logged)
    maps = defaultdict(int)
    for key in last_batch:
        if isinstance(key, str) and key.startswith("/world/maps/") and key.endswith("/points"):
            maps[key] = column_length(key, "Points3D:positions")
    check("map points (last copy)", sum(maps.values()), summary["map_points"])
    # Keyframes culled before a copy was taken never show; culled ones that
    # did show are cleared but keep their entity.
    check("keyframe frusta", len(keyframe_entities), summary["keyframes"], summary["keyframes_inserted"])
    strips = last_batch["/world/trajectory/estimate"]
    column = next(n for n in strips.schema.names if n.endswith("LineStrips3D:strips"))
    last_strips = strips.column(column)[strips.num_rows - 1]
    check("trajectory strips (last copy)", len(last_strips), 1)
    check("trajectory positions (last copy)", len(last_strips[0]), frames)
    if report.get("evaluation", {}).get("ate") is not None:
        check("ground truth", rows[("/world/trajectory/ground_truth", "static")], 1)
    bad = [c for c in checks if not c[2] <= c[1] <= c[3]]
    for name, actual, low, high in checks:
        expected = f"{low}" if low == high else f"{low} to {high}"
        print(f"{'ok  ' if low <= actual <= high else 'FAIL'} {name}: {actual} (expected {expected})")
    if bad:
        sys.exit(1)
    print(f"recording {run_dir / 'run.rrd'}: {len(checks)} checks passed")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
