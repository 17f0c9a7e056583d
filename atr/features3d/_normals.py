"""Surface normals by least-squares plane fit, oriented toward a viewpoint (PCL's NormalEstimation).

Open3D estimates normals too, but it orients them differently (no viewpoint flip by default, its own eigen
solver conventions) and does not report fewer-than-3-neighbour points as NaN, so PCL-conformant normals are
computed here: the neighbourhood covariance about its centroid (float64), the eigenvector of the smallest
eigenvalue, flipped so that (viewpoint - p)·n >= 0; curvature = λmin / (λ0 + λ1 + λ2).
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.spatial import cKDTree

from atr.errors import ConfigError, InputError
from atr.features3d._neighbours import Neighbourhoods, RadiusSearch
from atr.features3d.config import NormalConfig


@numba.njit(cache=True, parallel=True)
def _covariances(points, offsets, indices, min_neighbours):
    k = offsets.shape[0] - 1
    cov = np.full((k, 3, 3), np.nan)
    for i in numba.prange(k):
        a = offsets[i]
        b = offsets[i + 1]
        n = b - a
        if n < min_neighbours:
            continue
        c = np.zeros(3)
        for t in range(a, b):
            for u in range(3):
                c[u] += points[indices[t], u]
        c /= n
        m = np.zeros((3, 3))
        for t in range(a, b):
            d = points[indices[t]] - c
            for u in range(3):
                for v in range(3):
                    m[u, v] += d[u] * d[v]
        cov[i] = m / n
    return cov


def _plane_fit(
    points: np.ndarray, nb: Neighbourhoods, min_neighbours: int
) -> tuple[np.ndarray, np.ndarray]:
    cov = _covariances(points, nb.offsets, nb.indices, min_neighbours)
    normals = np.full((cov.shape[0], 3), np.nan)
    curvature = np.full(cov.shape[0], np.nan)
    ok = np.isfinite(cov).all(axis=(1, 2))
    if ok.any():
        w, v = np.linalg.eigh(cov[ok])
        normals[ok] = v[:, :, 0]
        total = w.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            curvature[ok] = np.where(total > 0, w[:, 0] / total, 0.0)
    return normals, curvature


def estimate_normals_and_curvature(
    points: np.ndarray,
    k: int | None = None,
    radius: float | None = None,
    viewpoint: tuple[float, float, float] | np.ndarray = (0.0, 0.0, 0.0),
    config: NormalConfig = NormalConfig(),
) -> tuple[np.ndarray, np.ndarray]:
    """Normals and surface variation of every point; see ``atr.features3d.estimate_normals``.

    Returns:
        normals (N, 3) float64 unit vectors (NaN rows where < config.min_neighbours neighbours), and
        curvature (N,) float64 = λmin / Σλ (NaN likewise).

    """
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(f"points shape {points.shape} must be (N, 3)")
    if k is not None and radius is not None:
        raise ConfigError(f"give k ({k}) or radius ({radius} m), not both")
    if k is None and radius is None:
        k = config.k_neighbours
    vp = np.asarray(viewpoint, dtype=np.float64).reshape(3)
    if not np.isfinite(vp).all():
        raise InputError(f"viewpoint {vp} must be finite")
    n = points.shape[0]
    finite = np.isfinite(points).all(axis=1)
    if radius is not None:
        if not radius > 0:
            raise ConfigError(f"normal radius {radius} m must be > 0")
        nb = RadiusSearch(points, radius).query(points, sort=False)
    else:
        assert k is not None
        if k < 3:
            raise ConfigError(f"k {k} must be >= 3 for a plane fit")
        idx_f = np.flatnonzero(finite)
        kk = min(k, idx_f.shape[0])
        if kk == 0:
            nb = Neighbourhoods(np.zeros(n + 1, dtype=np.int64), np.empty(0, np.int64), np.empty(0))
        else:
            _, nn = cKDTree(points[idx_f]).query(points[idx_f], k=kk)
            nn = idx_f[np.asarray(nn).reshape(idx_f.shape[0], kk)]
            counts = np.zeros(n, dtype=np.int64)
            counts[idx_f] = kk
            offsets = np.concatenate([[0], np.cumsum(counts)])
            indices = nn.reshape(-1).astype(np.int64)  # rows of idx_f are in index order
            nb = Neighbourhoods(offsets, indices, np.empty(0))
    normals, curvature = _plane_fit(points, nb, config.min_neighbours)
    normals[~finite] = np.nan
    curvature[~finite] = np.nan
    flip = np.einsum("ij,ij->i", vp - points, normals) < 0
    normals[flip] *= -1.0
    return normals, curvature
