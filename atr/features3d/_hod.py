"""HoD and HoD-S, Histograms of Distances (Kechagias-Stamatis & Aouf, ICRA 2016; Kechagias-Stamatis et al. 2017).

The authors published no code, so the descriptor is defined here from their description ("point-pair L2-norm
distance distributions of the vertices within V, encoded in a coarse and a fine manner; HoD-S involves only the
coarse component", paper §III-B e, Table III: 240 / 40 values). Every choice is in
docs/features3d_fpfh_rops_hod.md; in short:

- support V: the cloud points strictly within R of the keypoint (the keypoint itself included when it is a cloud
  point);
- every unordered pair {a, b} ⊂ V, a ≠ b, gives d = |a - b| / (2R) ∈ [0, 1) (2R bounds every distance in V);
- fine part: a 200-bin histogram of d over [0, 1]; coarse part: a 40-bin histogram over [0, 1], i.e. the fine
  bins summed in groups of 5;
- each part divided by the number of pairs (each sums to 1), so the descriptor does not depend on point density;
- HoD = coarse ‖ fine (240 values), HoD-S = coarse (40 values).

Distances are computed in float64 from the input coordinates (float32 would move pairs across the 200 fine bin
edges under a mere rotation). Only distances enter, so the descriptor is invariant to any rotation and translation by construction (no LRF, no
normals). O(|V|²) per keypoint; numba, parallel over keypoints.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from atr.features3d._fpfh import (
    as_points,
    check_radius,
    keypoint_coordinates,
    pcl_squared_radius,
    radius_csr,
)

# Table III of the paper: HoD 240 = coarse 40 + fine 200; HoD-S = the coarse 40 alone.
HOD_COARSE_BINS = 40
HOD_FINE_BINS = 200
# Fewer support points than this give a NaN row: 3 points give only 3 distances, too few for a histogram
# (same minimum as the other descriptors of this package).
HOD_MIN_POINTS = 5


@numba.njit(cache=True, parallel=True)
def _hod_kernel(pts, pts64, kp, offsets, nbrs, r2, radius, coarse, fine, min_points):
    k_count = kp.shape[0]
    length = coarse + fine
    out = np.full((k_count, length), np.nan, dtype=np.float32)
    inv_diam = 1.0 / (2.0 * radius)
    for k in numba.prange(k_count):
        cand = nbrs[offsets[k] : offsets[k + 1]]
        keep = np.zeros(cand.shape[0], dtype=np.bool_)
        for t in range(cand.shape[0]):
            q = cand[t]
            ex = kp[k, 0] - pts[q, 0]
            ey = kp[k, 1] - pts[q, 1]
            ez = kp[k, 2] - pts[q, 2]
            keep[t] = (ex * ex + ey * ey) + ez * ez < r2
        local = cand[keep]
        n = local.shape[0]
        if n < min_points:
            continue
        loc = np.empty((n, 3), dtype=np.float64)
        for t in range(n):
            for a in range(3):
                loc[t, a] = pts64[local[t], a]
        # One histogram at the finest resolution; the coarse one sums groups of fine bins (exact when, as
        # here, fine is a multiple of coarse; HoD-S bins the distances at the coarse resolution directly).
        res = fine if fine > 0 else coarse
        hist = np.zeros(res, dtype=np.int64)
        for i in range(n):
            for j in range(i):
                dx = loc[i, 0] - loc[j, 0]
                dy = loc[i, 1] - loc[j, 1]
                dz = loc[i, 2] - loc[j, 2]
                d = math.sqrt(dx * dx + dy * dy + dz * dz) * inv_diam
                hist[min(int(d * res), res - 1)] += 1
        n_pairs = n * (n - 1) // 2
        group = res // coarse
        for b in range(coarse):
            c = 0
            for g in range(b * group, (b + 1) * group):
                c += hist[g]
            out[k, b] = c / n_pairs
        for b in range(fine):
            out[k, coarse + b] = hist[b] / n_pairs
    return out


def hod(
    points: np.ndarray, keypoints: np.ndarray, radius: float, *, short: bool = False
) -> np.ndarray:
    """Histogram of Distances (HoD, 240 values) or its short form (HoD-S, 40 values).

    Args:
        points: (N, 3) float, metres. Non-finite points are ignored.
        keypoints: (K,) int indices into ``points`` or (K, 3) float coordinates, metres.
        radius: support radius R, metres (> 0).
        short: True for HoD-S (the coarse 40 bins only).

    Returns:
        (K, 240) or (K, 40) float32: coarse histogram (40 bins over pair distances [0, 2R]) then, for HoD, the
        fine one (200 bins); each part sums to 1. NaN rows for keypoints with fewer than HOD_MIN_POINTS support
        points or a non-finite position.

    Raises:
        InputError: bad shapes or keypoint indices.
        InputError: radius not finite and > 0.

    """
    r = check_radius(radius)
    pts64 = as_points(points)
    kp64 = keypoint_coordinates(pts64, keypoints)
    fine = 0 if short else HOD_FINE_BINS
    if kp64.shape[0] == 0:
        return np.empty((0, HOD_COARSE_BINS + fine), dtype=np.float32)
    pts = np.ascontiguousarray(pts64, dtype=np.float32)
    kp = np.ascontiguousarray(kp64, dtype=np.float32)
    offsets, nbrs = radius_csr(pts, kp, r)
    return _hod_kernel(
        pts,
        pts64,
        kp,
        offsets,
        nbrs,
        pcl_squared_radius(r),
        r,
        HOD_COARSE_BINS,
        fine,
        HOD_MIN_POINTS,
    )
