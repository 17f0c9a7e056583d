"""The SHOT local reference frame (Tombari, Salti, Di Stefano 2010), as PCL's SHOTLocalReferenceFrameEstimation.

No maintained Python library has it. For each feature point p and the neighbours q within R (points equal to p
excluded): M = Σ w (q-p)(q-p)ᵀ / Σ w with w = R - |q-p| (about p, not the centroid); x = major eigenvector,
z = minor eigenvector, each sign chosen so that most neighbours lie on its positive side (ties broken on the 5
neighbours around the median distance), y = z × x. Rows of the (3, 3) frame are x, y, z.
"""

from __future__ import annotations

import numba
import numpy as np

from atr.features3d._neighbours import Neighbourhoods

# PCL looks at this many neighbours around the median distance to break a sign tie.
_TIE_WINDOW = 5


@numba.njit(cache=True)
def _disambiguate(vij: np.ndarray, n: int, v: np.ndarray) -> np.ndarray:
    plus = 0
    for t in range(n):
        if vij[t, 0] * v[0] + vij[t, 1] * v[1] + vij[t, 2] * v[2] >= 0:
            plus += 1
    balance = 2 * plus - n
    if balance == 0:
        med = n // 2
        pos = 0
        for t in range(med - _TIE_WINDOW // 2, med + _TIE_WINDOW // 2 + 1):
            if vij[t, 0] * v[0] + vij[t, 1] * v[1] + vij[t, 2] * v[2] > 0:
                pos += 1
        if pos < _TIE_WINDOW // 2 + 1:
            return -v
        return v
    if balance < 0:
        return -v
    return v


@numba.njit(cache=True)
def _offsets_of(points, centre, idx, out):
    """Rows q - p of the valid neighbours (q != p), in neighbour order; returns their number."""
    n = 0
    for t in range(idx.shape[0]):
        q = points[idx[t]]
        if q[0] == centre[0] and q[1] == centre[1] and q[2] == centre[2]:
            continue
        for u in range(3):
            out[n, u] = q[u] - centre[u]
        n += 1
    return n


@numba.njit(cache=True, parallel=True)
def _weighted_covariances(points, centres, offsets, indices, sq_dists, radius, min_valid):
    k = centres.shape[0]
    cov = np.full((k, 3, 3), np.nan)
    for i in numba.prange(k):
        a = offsets[i]
        b = offsets[i + 1]
        vij = np.empty((b - a, 3))
        m = np.zeros((3, 3))
        wsum = 0.0
        n = 0
        for t in range(a, b):
            q = points[indices[t]]
            if q[0] == centres[i, 0] and q[1] == centres[i, 1] and q[2] == centres[i, 2]:
                continue
            w = radius - np.sqrt(sq_dists[t])
            for u in range(3):
                vij[n, u] = q[u] - centres[i, u]
            for u in range(3):
                for v in range(3):
                    m[u, v] += w * vij[n, u] * vij[n, v]
            wsum += w
            n += 1
        if n >= min_valid and wsum > 0:
            cov[i] = m / wsum
    return cov


@numba.njit(cache=True, parallel=True)
def _orient(points, centres, offsets, indices, axes_x, axes_z):
    k = centres.shape[0]
    out = np.full((k, 3, 3), np.nan)
    for i in numba.prange(k):
        if not (np.isfinite(axes_x[i]).all() and np.isfinite(axes_z[i]).all()):
            continue
        a = offsets[i]
        b = offsets[i + 1]
        vij = np.empty((b - a, 3))
        n = _offsets_of(points, centres[i], indices[a:b], vij)
        x = _disambiguate(vij, n, axes_x[i].copy())
        z = _disambiguate(vij, n, axes_z[i].copy())
        out[i, 0] = x
        out[i, 2] = z
        out[i, 1, 0] = z[1] * x[2] - z[2] * x[1]
        out[i, 1, 1] = z[2] * x[0] - z[0] * x[2]
        out[i, 1, 2] = z[0] * x[1] - z[1] * x[0]
    return out


def shot_frames(
    points: np.ndarray, centres: np.ndarray, nb: Neighbourhoods, radius: float, min_valid: int
) -> np.ndarray:
    """SHOT LRFs from precomputed, distance-sorted neighbourhoods.

    Args:
        points: (N, 3) float64 surface, metres.
        centres: (K, 3) float64 feature points, metres.
        nb: neighbourhoods of ``centres`` within ``radius``, sorted by distance.
        radius: LRF radius R, metres.
        min_valid: fewer neighbours (p itself excluded) give a NaN frame.

    Returns:
        (K, 3, 3) float64; rows x, y, z; NaN where undefined.

    """
    cov = _weighted_covariances(
        points, centres, nb.offsets, nb.indices, nb.sq_dists, float(radius), int(min_valid)
    )
    axes_x = np.full(centres.shape, np.nan)
    axes_z = np.full(centres.shape, np.nan)
    ok = np.isfinite(cov).all(axis=(1, 2))
    if ok.any():
        # Batched LAPACK outside numba: same solver for every point, and no slow numba linalg compile.
        evals, evecs = np.linalg.eigh(cov[ok])
        good = np.isfinite(evals).all(axis=1)
        idx = np.flatnonzero(ok)[good]
        axes_x[idx] = evecs[good, :, 2]
        axes_z[idx] = evecs[good, :, 0]
    return _orient(points, centres, nb.offsets, nb.indices, axes_x, axes_z)
