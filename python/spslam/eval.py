"""Trajectory metrics, identical to ``spslam eval`` (evo's APE/RPE, the
KITTI odometry devkit's metric).

A trajectory argument is a file's path (KITTI, TUM or EuRoC; detected), an
N×4×4 (or N×3×4) ``float64`` array of camera-to-world poses, or a
``(timestamps, poses)`` tuple. Poses pair by index unless both sides carry
timestamps (TUM/EuRoC files, tuples); then, like evo, by the nearest stamps
within ``max_diff`` seconds.
"""

from ._spslam import ate, evaluate, kitti_metric, read_trajectory, rpe

__all__ = ["ate", "evaluate", "kitti_metric", "read_trajectory", "rpe"]
