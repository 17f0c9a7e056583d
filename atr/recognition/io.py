"""The matcher's file helpers: reading point clouds and meshes is `atr.io.geometry`'s (re-exported
here), and the cloud resolution PCL's examples use.
"""

from __future__ import annotations

import numpy as np

from atr.errors import InputError
from atr.io.geometry import CLOUD_SUFFIXES, MESH_SUFFIXES, Geometry, load_geometry

__all__ = ["CLOUD_SUFFIXES", "MESH_SUFFIXES", "Geometry", "load_geometry", "mean_spacing_m"]


def mean_spacing_m(points: np.ndarray) -> float:
    """Mean distance of each finite point to its nearest neighbour, metres (PCL's cloud resolution)."""
    from scipy.spatial import cKDTree

    pts = np.asarray(points, np.float64)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) < 2:
        raise InputError(f"cloud has {len(pts)} finite points; a spacing needs at least 2")
    d, _ = cKDTree(pts).query(pts, k=2)
    return float(d[:, 1].mean())
