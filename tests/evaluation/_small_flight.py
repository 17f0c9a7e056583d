"""The small flight the evaluation tests share: scenario 1 run 4 (45 deg) with FPFH on a 640x480 camera with half
the focal length and one target template. The acceptance thresholds are loosened so that these frames give several
detections (most of them false): comparisons must cover non-empty detections, not only empty ones."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _small_camera import SMALL_CAMERA  # noqa: E402

SMALL_FLIGHT = [
    "eval",
    "--scenario",
    "1",
    "--run",
    "4",
    "--pipeline",
    "gftt-sfm",
    "--descriptor",
    "fpfh",
    *SMALL_CAMERA,
    "--set",
    "recognition.min_overlap=0.05",
    "--set",
    "recognition.min_overlap_vertices=3",
    "--set",
    "recognition.max_clutter=1.0",
    "--set",
    "recognition.min_group_size=3",
]
