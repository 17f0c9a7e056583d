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
def _frame_one(points, centre, idx, d2, radius, min_valid, out):
    n_all = idx.shape[0]
    vij = np.empty((n_all, 3))
    n = 0
    cov = np.zeros((3, 3))
    wsum = 0.0
    for t in range(n_all):
        q = points[idx[t]]
        if q[0] == centre[0] and q[1] == centre[1] and q[2] == centre[2]:
            continue
        for u in range(3):
            vij[n, u] = q[u] - centre[u]
        w = radius - np.sqrt(d2[t])
        for u in range(3):
            for v in range(3):
                cov[u, v] += w * vij[n, u] * vij[n, v]
        wsum += w
        n += 1
    if n < min_valid or not wsum > 0:
        return False
    cov /= wsum
    evals, evecs = np.linalg.eigh(cov)
    if not (np.isfinite(evals[0]) and np.isfinite(evals[1]) and np.isfinite(evals[2])):
        return False
    x = _disambiguate(vij, n, evecs[:, 2].copy())
    z = _disambiguate(vij, n, evecs[:, 0].copy())
    out[0] = x
    out[2] = z
    out[1, 0] = z[1] * x[2] - z[2] * x[1]
    out[1, 1] = z[2] * x[0] - z[0] * x[2]
    out[1, 2] = z[0] * x[1] - z[1] * x[0]
    return True


@numba.njit(cache=True, parallel=True)
def _frames(points, centres, offsets, indices, sq_dists, radius, min_valid):
    k = centres.shape[0]
    out = np.full((k, 3, 3), np.nan)
    for i in numba.prange(k):
        a = offsets[i]
        b = offsets[i + 1]
        if not (np.isfinite(centres[i, 0]) and np.isfinite(centres[i, 1]) and np.isfinite(centres[i, 2])):
            continue
        frame = np.empty((3, 3))
        if _frame_one(points, centres[i], indices[a:b], sq_dists[a:b], radius, min_valid, frame):
            out[i] = frame
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
    return _frames(points, centres, nb.offsets, nb.indices, nb.sq_dists, float(radius), int(min_valid))
