"""FPFH (Rusu, Blodow, Beetz, ICRA 2009) and the PFH pair features, with PCL's conventions.

Open3D has an FPFH (``compute_fpfh_feature``), but not PCL's: it adds the query point's own SPFH after the
normalisation (each sub-histogram then sums to 200, not 100) and works in double precision. The descriptors of
this package follow PCL 1.13 (``pcl::FPFHEstimation``, ``pcl::computePairFeatures``), so this module has its own
numba implementation. It reproduces PCL's float32 arithmetic where that decides a histogram bin:

- pair features in float32, with Eigen's SSE reduction order for a 4-vector dot product ((x+z)+y);
- bin positions in double (PCL adds ``M_PI`` and ``1.0``, both double, to the float features);
- histogram increments 100/(n-1) and the 1/d² weights accumulated in float32;
- the neighbour test of FLANN: float32 squared distance, strictly less than the float32 squared radius.

Conventions (spec: pcl-descriptor-oracles.md §7-§8, docs/features3d_fpfh_rops_hod.md):
- neighbours N(p) = surface points strictly within the radius, the point itself included;
- SPFH(p): three 11-bin histograms of f1, f2, f3 over the pairs (p, q), q ≠ p, each adding 100/(|N(p)|-1);
- FPFH(k) = Σ_{q ∈ N(k), d²≠0} SPFH(q) / d²(k, q), the keypoint's own SPFH not added, then each of the three
  sub-histograms rescaled to sum to 100.

Keypoints are indices into ``points`` or (K, 3) coordinates: FPFH only needs the keypoint's position, since its
own SPFH is not used.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from atr.errors import ConfigError, InputError
from atr.features3d._neighbours import RadiusSearch

# PCL FPFHEstimation default subdivisions of f1, f2, f3 (Rusu et al. 2009: 11 bins each, 33 values).
FPFH_BINS_PER_FEATURE = 11
FPFH_LENGTH = 3 * FPFH_BINS_PER_FEATURE
# PCL scales every SPFH increment and every final FPFH sub-histogram to a sum of 100 (percent).
_PERCENT = np.float32(100.0)
# The grid is built a hair wider than the radius; the kernels then apply PCL's exact float32 "d² < r²" test.
_GRID_MARGIN = 1.0 + 1e-6

_F0 = np.float32(0.0)
_F1 = np.float32(1.0)
# PCL: d_pi_ = 1.0f / (2.0f * float(M_PI)), a float32 that is promoted to double in the bin formula.
_D_PI = float(np.float32(1.0) / (np.float32(2.0) * np.float32(math.pi)))


# ------------------------------------------------------------------------------------------------ inputs


def as_points(points: np.ndarray, name: str = "points") -> np.ndarray:
    """Validate an (N, 3) array and return it as contiguous float64."""
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name} shape {arr.shape} must be (N, 3)")
    return np.ascontiguousarray(arr)


def keypoint_coordinates(points: np.ndarray, keypoints: np.ndarray) -> np.ndarray:
    """Keypoints as (K, 3) float64 coordinates.

    Args:
        points: (N, 3) float64 cloud, metres.
        keypoints: (K,) integer indices into ``points``, or (K, 3) float coordinates, metres.

    Returns:
        (K, 3) float64 coordinates (may contain non-finite rows, which are described as NaN).

    Raises:
        InputError: wrong shape, or an index outside [0, N).
    """
    kp = np.asarray(keypoints)
    if kp.ndim == 1 and (kp.size == 0 or np.issubdtype(kp.dtype, np.integer)):
        idx = kp.astype(np.int64)
        if idx.size and (idx.min() < 0 or idx.max() >= points.shape[0]):
            raise InputError(
                f"keypoint indices span [{idx.min()}, {idx.max()}], expected within [0, {points.shape[0]})"
            )
        return np.ascontiguousarray(points[idx])
    if kp.ndim == 2 and kp.shape[1] == 3:
        return np.ascontiguousarray(kp, dtype=np.float64)
    raise InputError(
        f"keypoints shape {kp.shape} dtype {kp.dtype}: expected (K,) integer indices or (K, 3) coordinates"
    )


def check_radius(radius: float) -> float:
    """Return ``radius`` as float, raising ConfigError unless it is finite and > 0 (metres)."""
    r = float(radius)
    if not (math.isfinite(r) and r > 0):
        raise ConfigError(f"support radius {radius} m must be a finite value > 0")
    return r


def pcl_squared_radius(radius: float) -> np.float32:
    """FLANN's squared search radius: float32(double(float32 radius)²), as PCL passes it."""
    r = float(np.float32(radius))
    return np.float32(r * r)


# ------------------------------------------------------------------------------------------------ kernels


@numba.njit(cache=True, inline="always")
def _dot4(ax, ay, az, bx, by, bz):
    # Eigen's SSE horizontal sum of a Vector4f with w = 0: (x + z) + (y + w).
    return (ax * bx + az * bz) + ay * by


@numba.njit(cache=True)
def _pair_features_f32(p1x, p1y, p1z, n1x, n1y, n1z, p2x, p2y, p2z, n2x, n2y, n2z):
    """PCL's computePairFeatures in float32: (ok, f1, f2, f3, f4)."""
    dx = p2x - p1x
    dy = p2y - p1y
    dz = p2z - p1z
    f4 = np.float32(math.sqrt(_dot4(dx, dy, dz, dx, dy, dz)))
    if f4 == _F0:
        return False, _F0, _F0, _F0, _F0
    angle1 = _dot4(n1x, n1y, n1z, dx, dy, dz) / f4
    angle2 = _dot4(n2x, n2y, n2z, dx, dy, dz) / f4
    # The source point is the one whose normal makes the smaller angle with the line (same pair, same frame).
    if math.acos(abs(angle1)) > math.acos(abs(angle2)):
        ux, uy, uz = n2x, n2y, n2z
        tx, ty, tz = n1x, n1y, n1z
        dx = -dx
        dy = -dy
        dz = -dz
        f3 = -angle2
    else:
        ux, uy, uz = n1x, n1y, n1z
        tx, ty, tz = n2x, n2y, n2z
        f3 = angle1
    # Darboux frame u = n_src, v = d × u / |d × u|, w = u × v.
    vx = dy * uz - dz * uy
    vy = dz * ux - dx * uz
    vz = dx * uy - dy * ux
    v_norm = np.float32(math.sqrt(_dot4(vx, vy, vz, vx, vy, vz)))
    if v_norm == _F0:
        return False, _F0, _F0, _F0, _F0
    vx = vx / v_norm
    vy = vy / v_norm
    vz = vz / v_norm
    wx = uy * vz - uz * vy
    wy = uz * vx - ux * vz
    wz = ux * vy - uy * vx
    f2 = _dot4(vx, vy, vz, tx, ty, tz)
    f1 = np.float32(math.atan2(_dot4(wx, wy, wz, tx, ty, tz), _dot4(ux, uy, uz, tx, ty, tz)))
    return True, f1, f2, f3, f4


@numba.njit(cache=True, inline="always")
def _bin_angle(f1, nbins):
    h = int(math.floor(nbins * ((np.float64(f1) + math.pi) * _D_PI)))
    return min(max(h, 0), nbins - 1)


@numba.njit(cache=True, inline="always")
def _bin_cosine(f, nbins):
    h = int(math.floor(nbins * ((np.float64(f) + 1.0) * 0.5)))
    return min(max(h, 0), nbins - 1)


@numba.njit(cache=True, parallel=True)
def _spfh_rows(pts, nrm, centres, offsets, nbrs, r2, nbins):
    """SPFH (3 × nbins, float32) of pts[centres[m]] over its neighbour list m (filtered by d² < r2)."""
    m_count = centres.shape[0]
    out = np.zeros((m_count, 3 * nbins), dtype=np.float32)
    for m in numba.prange(m_count):
        p = centres[m]
        px, py, pz = pts[p, 0], pts[p, 1], pts[p, 2]
        # Neighbour count |N(p)| under PCL's strict float32 test (the point itself included).
        n_in = 0
        for t in range(offsets[m], offsets[m + 1]):
            q = nbrs[t]
            ex = pts[q, 0] - px
            ey = pts[q, 1] - py
            ez = pts[q, 2] - pz
            if (ex * ex + ey * ey) + ez * ez < r2:
                n_in += 1
        if n_in < 2:
            continue
        incr = _PERCENT / np.float32(n_in - 1)
        for t in range(offsets[m], offsets[m + 1]):
            q = nbrs[t]
            if q == p:
                continue
            ex = pts[q, 0] - px
            ey = pts[q, 1] - py
            ez = pts[q, 2] - pz
            if not ((ex * ex + ey * ey) + ez * ez < r2):
                continue
            ok, f1, f2, f3, _f4 = _pair_features_f32(
                px, py, pz, nrm[p, 0], nrm[p, 1], nrm[p, 2],
                pts[q, 0], pts[q, 1], pts[q, 2], nrm[q, 0], nrm[q, 1], nrm[q, 2],
            )
            if not ok:
                continue
            out[m, _bin_angle(f1, nbins)] += incr
            out[m, nbins + _bin_cosine(f2, nbins)] += incr
            out[m, 2 * nbins + _bin_cosine(f3, nbins)] += incr
    return out


@numba.njit(cache=True, parallel=True)
def _weight_spfh(kp, pts, offsets, nbrs, row_of, spfh, r2, nbins):
    """FPFH rows: Σ SPFH(q)/d² over the keypoint's neighbours, each sub-histogram rescaled to 100."""
    k_count = kp.shape[0]
    out = np.full((k_count, 3 * nbins), np.nan, dtype=np.float32)
    for k in numba.prange(k_count):
        acc = np.zeros(3 * nbins, dtype=np.float32)
        sums = np.zeros(3, dtype=np.float32)
        for t in range(offsets[k], offsets[k + 1]):
            q = nbrs[t]
            ex = pts[q, 0] - kp[k, 0]
            ey = pts[q, 1] - kp[k, 1]
            ez = pts[q, 2] - kp[k, 2]
            d2 = (ex * ex + ey * ey) + ez * ez
            if not (d2 < r2) or d2 == _F0:
                continue
            w = _F1 / d2
            row = row_of[q]
            for f in range(3):
                for b in range(f * nbins, (f + 1) * nbins):
                    val = spfh[row, b] * w
                    sums[f] += val
                    acc[b] += val
        if sums[0] == _F0 or sums[1] == _F0 or sums[2] == _F0:
            continue  # no neighbour with a valid SPFH: not describable (PCL would output zeros)
        for f in range(3):
            scale = _PERCENT / sums[f]
            for b in range(f * nbins, (f + 1) * nbins):
                out[k, b] = acc[b] * scale
    return out


@numba.njit(cache=True)
def _pfh_histogram_kernel(pts, nrm, idx, nr_split):
    """PCL's computePointPFHSignature over the ordered list ``idx`` (pairs j < i, float32 accumulation)."""
    n = idx.shape[0]
    hist = np.zeros(nr_split**3, dtype=np.float32)
    if n < 2:
        return hist
    incr = _PERCENT / np.float32(n * (n - 1) // 2)
    for i in range(n):
        a = idx[i]
        for j in range(i):
            b = idx[j]
            # PCL adds every pair, a rejected pair with its zero features included.
            _ok, f1, f2, f3, _f4 = _pair_features_f32(
                pts[a, 0], pts[a, 1], pts[a, 2], nrm[a, 0], nrm[a, 1], nrm[a, 2],
                pts[b, 0], pts[b, 1], pts[b, 2], nrm[b, 0], nrm[b, 1], nrm[b, 2],
            )
            h = (
                _bin_angle(f1, nr_split)
                + nr_split * _bin_cosine(f2, nr_split)
                + nr_split * nr_split * _bin_cosine(f3, nr_split)
            )
            hist[h] += incr
    return hist


# ------------------------------------------------------------------------------------------------ public


def pfh_pair_features(p1, n1, p2, n2) -> tuple[float, float, float, float]:
    """PCL's ``computePairFeatures`` for one pair of oriented points (float32 arithmetic, as PCL).

    Args:
        p1, n1: position (metres) and unit normal of the first point, 3 floats each.
        p2, n2: position and unit normal of the second point.

    Returns:
        (f1, f2, f3, f4): f1 = angle of the target normal in the Darboux (u, w) plane, radians in [-π, π];
        f2 = v·n_tgt and f3 = u·d̂ (cosines in [-1, 1]); f4 = |p2 - p1|, metres. All four are 0 when the
        points coincide or the line is parallel to the source normal (PCL then rejects the pair).
    """
    a = np.asarray(p1, dtype=np.float32).reshape(3)
    b = np.asarray(n1, dtype=np.float32).reshape(3)
    c = np.asarray(p2, dtype=np.float32).reshape(3)
    d = np.asarray(n2, dtype=np.float32).reshape(3)
    _ok, f1, f2, f3, f4 = _pair_features_f32(a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2], d[0], d[1], d[2])
    return float(f1), float(f2), float(f3), float(f4)


def pfh_histogram(points: np.ndarray, normals: np.ndarray, indices: np.ndarray, subdivisions: int = 5) -> np.ndarray:
    """PFH signature of an ordered neighbourhood, as PCL's ``computePointPFHSignature``.

    Args:
        points: (N, 3) float, metres.
        normals: (N, 3) float unit normals.
        indices: (n,) int, the neighbourhood in PCL's order (pairs (i, j) with j < i).
        subdivisions: bins per feature (PCL default 5 → 125 bins).

    Returns:
        (subdivisions³,) float32 histogram summing to 100.
    """
    pts = np.ascontiguousarray(as_points(points), dtype=np.float32)
    nrm = np.ascontiguousarray(as_points(normals, "normals"), dtype=np.float32)
    if int(subdivisions) < 1:
        raise ConfigError(f"PFH subdivisions {subdivisions} must be >= 1")
    return _pfh_histogram_kernel(pts, nrm, np.asarray(indices, dtype=np.int64), int(subdivisions))


def spfh(points: np.ndarray, normals: np.ndarray, centres: np.ndarray, radius: float) -> np.ndarray:
    """SPFH rows (PCL's ``computePointSPFHSignature``) of points[centres], neighbours within ``radius``.

    Args:
        points: (N, 3) float, metres.
        normals: (N, 3) float unit normals.
        centres: (M,) int indices into points.
        radius: metres, > 0.

    Returns:
        (M, 33) float32: f1, f2, f3 histograms, each summing to 100 (0 when the point has no neighbour).
    """
    r = check_radius(radius)
    pts64 = as_points(points)
    pts = np.ascontiguousarray(pts64, dtype=np.float32)
    nrm = np.ascontiguousarray(as_points(normals, "normals"), dtype=np.float32)
    centres = np.asarray(centres, dtype=np.int64)
    grid = RadiusSearch(pts.astype(np.float64), r * _GRID_MARGIN)
    nb = grid.query(pts.astype(np.float64)[centres], sort=False)
    return _spfh_rows(pts, nrm, centres, nb.offsets, nb.indices, pcl_squared_radius(r), FPFH_BINS_PER_FEATURE)


def fpfh(points: np.ndarray, normals: np.ndarray, keypoints: np.ndarray, radius: float) -> np.ndarray:
    """Fast Point Feature Histograms (33 values), PCL's FPFHEstimation conventions.

    Args:
        points: (N, 3) float, metres: the search surface.
        normals: (N, 3) float unit normals of ``points``. Points with a non-finite position or normal are left
            out of the surface.
        keypoints: (K,) int indices into ``points`` or (K, 3) float coordinates, metres.
        radius: neighbourhood radius of both the SPFH and the FPFH weighting, metres (> 0).

    Returns:
        (K, 33) float32: f1, f2, f3 sub-histograms (11 bins each), each summing to 100. A row is NaN when the
        keypoint has no neighbour (other than itself) with a valid SPFH.

    Raises:
        InputError: bad array shapes or keypoint indices.
        ConfigError: radius not finite and > 0.
    """
    r = check_radius(radius)
    pts64 = as_points(points)
    if normals is None:
        raise InputError("FPFH needs normals: got None")
    nrm64 = as_points(normals, "normals")
    if nrm64.shape[0] != pts64.shape[0]:
        raise InputError(f"normals has {nrm64.shape[0]} rows, points has {pts64.shape[0]}")
    kp64 = keypoint_coordinates(pts64, keypoints)
    k_count = kp64.shape[0]
    if k_count == 0:
        return np.empty((0, FPFH_LENGTH), dtype=np.float32)

    valid = np.isfinite(pts64).all(axis=1) & np.isfinite(nrm64).all(axis=1)
    surface = np.flatnonzero(valid)
    pts = np.ascontiguousarray(pts64[surface], dtype=np.float32)
    nrm = np.ascontiguousarray(nrm64[surface], dtype=np.float32)
    kp = np.ascontiguousarray(kp64, dtype=np.float32)
    if pts.shape[0] == 0:
        return np.full((k_count, FPFH_LENGTH), np.nan, dtype=np.float32)

    r2 = pcl_squared_radius(r)
    grid = RadiusSearch(pts.astype(np.float64), r * _GRID_MARGIN)
    kp_nb = grid.query(kp.astype(np.float64), sort=False)
    # SPFH only for the points some keypoint needs.
    needed_mask = np.zeros(pts.shape[0], dtype=bool)
    needed_mask[kp_nb.indices] = True
    needed = np.flatnonzero(needed_mask)
    row_of = np.full(pts.shape[0], -1, dtype=np.int64)
    row_of[needed] = np.arange(needed.shape[0])
    sp_nb = grid.query(pts[needed].astype(np.float64), sort=False)
    rows = _spfh_rows(pts, nrm, needed, sp_nb.offsets, sp_nb.indices, r2, FPFH_BINS_PER_FEATURE)
    return _weight_spfh(kp, pts, kp_nb.offsets, kp_nb.indices, row_of, rows, r2, FPFH_BINS_PER_FEATURE)
