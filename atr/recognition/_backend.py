"""Adapters to the project's descriptor and normal code, with Open3D stand-ins while it is absent.

``atr.features3d`` is the project's home of the 3D descriptors. When it cannot be imported, FPFH falls back
to Open3D's implementation (the only descriptor Open3D has) and normals to Open3D's k-NN plane fit.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from atr.errors import ConfigError

try:  # the project's own descriptors, when they have landed
    from atr import features3d as _features3d

    _HAVE_FEATURES3D = hasattr(_features3d, "describe")
except ImportError:  # pragma: no cover - depends on the checkout
    _features3d = None
    _HAVE_FEATURES3D = False


def have_descriptor(name: str) -> bool:
    """Whether descriptor ``name`` can be computed in this installation."""
    return _HAVE_FEATURES3D or name == "fpfh"


def describe(
    name: str,
    points: np.ndarray,
    normals: np.ndarray,
    keypoints: np.ndarray,
    radius: float,
) -> np.ndarray:
    """Describe ``points[keypoints]`` (int indices) on the surface ``points``.

    Returns (K, L) float32, NaN rows where not describable.
    """
    keypoints = np.asarray(keypoints, np.int64)
    if _HAVE_FEATURES3D:
        return np.asarray(
            _features3d.describe(name, points, normals, keypoints, radius), dtype=np.float32
        )
    if name != "fpfh":
        raise ConfigError(
            f"descriptor {name!r} needs atr.features3d, which is not available; only 'fpfh' works without it"
        )
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, np.float64)))
    cloud.normals = o3d.utility.Vector3dVector(np.asarray(normals, np.float64))
    feat = o3d.pipelines.registration.compute_fpfh_feature(
        cloud, o3d.geometry.KDTreeSearchParamRadius(float(radius))
    )
    data = np.asarray(feat.data, dtype=np.float32).T
    out = data[keypoints]
    tree = cKDTree(points)
    counts = np.array([len(n) for n in tree.query_ball_point(points[keypoints], radius)])
    out[counts < 2] = np.nan
    return out


def estimate_normals(points: np.ndarray, k: int, viewpoint: np.ndarray | None) -> np.ndarray:
    """Unit normals (N, 3) float64 from a plane fit on the k nearest neighbours.

    Oriented towards ``viewpoint`` (3,) metres; when None, towards +z (up in the world frame).
    """
    pts = np.asarray(points, np.float64)
    if _HAVE_FEATURES3D and hasattr(_features3d, "estimate_normals"):
        vp = (0.0, 0.0, 0.0) if viewpoint is None else tuple(float(v) for v in viewpoint)
        normals = np.asarray(_features3d.estimate_normals(pts, k=k, viewpoint=vp), np.float64)
    else:
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
        cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(int(k)))
        normals = np.asarray(cloud.normals, np.float64).copy()
    normals = np.nan_to_num(normals, nan=0.0)
    if viewpoint is None:
        flip = normals[:, 2] < 0
    else:
        flip = np.einsum("ij,ij->i", normals, np.asarray(viewpoint, np.float64) - pts) < 0
    normals[flip] *= -1.0
    return normals
