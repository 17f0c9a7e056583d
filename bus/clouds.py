"""PointClouds on the wire: full float32, or a compact form for a thin radio link.

The compact form sends only the points the matcher uses and 8 bytes a point instead of 16. The matcher's
first step keeps one point per voxel of the template resolution (`uniform_subsample`, idempotent: the
matcher's own pass over the thinned cloud keeps every point, in the same order), so the air drops the rest:
a dense SfM cloud shrinks several times, a sparse one hardly. Positions are quantised to uint16 per axis, for an
error of at most half a step, step being the cloud's extent / 65535 per axis: 3.8 mm over a 500 m scene, far
below SfM's centimetre-to-decimetre noise. The per-point sigma goes as float16, a relative error of at most
2^-11 (0.05 %), far below how well SfM knows its own uncertainty. Both forms decode to the same float32
positions through `cloud_points`, so consumers never see the difference.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from atr.recognition.steps import uniform_subsample

_LEVELS = 65535
# float16's largest value, 65 km: a larger sigma says no more (nothing is known of the point)
_SIGMA_MAX_M = float(np.finfo(np.float16).max)


def compact_points(points_m: np.ndarray) -> dict[str, np.ndarray]:
    """The PointCloud fields `points_q`, `origin_m`, `step_m` that encode (N, 3) `points_m`."""
    points = np.asarray(points_m, np.float64).reshape(-1, 3)
    origin = points.min(axis=0) if len(points) else np.zeros(3)
    extent = points.max(axis=0) - origin if len(points) else np.zeros(3)
    step = np.where(extent > 0, extent / _LEVELS, 1.0)
    codes = np.rint((points - origin) / step).clip(0, _LEVELS).astype(np.uint16)
    return {"points_q": codes, "origin_m": origin, "step_m": step}


def compact_cloud(
    points_m: np.ndarray, sigma_m: np.ndarray, leaf_m: float
) -> dict[str, np.ndarray]:
    """The compact PointCloud fields for finite (N, 3) `points_m` and their (N,) `sigma_m`: one point per
    voxel of edge `leaf_m` (the matcher's subsampling), positions as `compact_points`, sigma as float16.
    """
    keep = uniform_subsample(np.asarray(points_m, np.float64), leaf_m)
    sigma = np.clip(np.asarray(sigma_m, np.float64)[keep], 0.0, _SIGMA_MAX_M).astype(np.float16)
    return compact_points(np.asarray(points_m)[keep]) | {"sigma_m": sigma}


def cloud_points(message: dict[str, Any]) -> np.ndarray:
    """The (N, 3) float32 world positions of a PointCloud message, whichever form it carries."""
    if "points_m" in message:
        return np.asarray(message["points_m"], np.float32)
    points = message["origin_m"] + message["points_q"].astype(np.float64) * message["step_m"]
    return points.astype(np.float32)
