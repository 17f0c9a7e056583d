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

# PCL FPFHEstimation default subdivisions of f1, f2, f3 (Rusu et al. 2009: 11 bins each, 33 values).
FPFH_BINS_PER_FEATURE = 11
FPFH_LENGTH = 3 * FPFH_BINS_PER_FEATURE
# PCL scales every SPFH increment and every final FPFH sub-histogram to a sum of 100 (percent).
_PERCENT = np.float32(100.0)
# Fewer points than this within the radius of a keypoint (itself included when it is a cloud point) give a NaN
# row: PCL describes any neighbourhood, but a histogram of 2-3 SPFHs is noise (package-wide minimum, as SHOT).
FPFH_MIN_NEIGHBOURS = 5
# Most cells the uniform search grid may have (int64 start table of 8 × 2^22 bytes); beyond it cells grow.
_MAX_GRID_CELLS = 1 << 22

_F0 = np.float32(0.0)
_F1 = np.float32(1.0)
# PCL: d_pi_ = 1.0f / (2.0f * float(M_PI)), a float32 that is promoted to double in the bin formula.
# Cosine gap beyond which acosf cannot round two values to the same float (2 ulp of acos(0) = π/2).
_ACOS_TIE = np.float32(4.0 * np.spacing(np.float32(math.pi / 2)))
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
    """Return ``radius`` as float, raising InputError (as the describe() contract) unless finite and > 0 (m)."""
    r = float(radius)
    if not (math.isfinite(r) and r > 0):
        raise InputError(f"support radius {radius} m must be a finite value > 0")
    return r


def pcl_squared_radius(radius: float) -> np.float32:
    """FLANN's squared search radius: float32(double(float32 radius)²), as PCL passes it."""
    r = float(np.float32(radius))
    return np.float32(r * r)


# ------------------------------------------------------------------------------------------------ search grid
#
# A uniform grid with cells >= the radius, points counting-sorted by cell, a dense start table: a query visits
# 9 runs of consecutive cells (the z runs are contiguous), no hashing, no binary search. It is faster than the
# package's general RadiusSearch for the many queries of FPFH, and it applies FLANN's exact float32 test
# (query - point, ((dx² + dy²) + dz²) < float32 r²) inside the loop.


class Grid:
    """Uniform search grid over float32 points (non-finite points are left out).

    Args:
        pts: (N, 3) float32, metres.
        radius: largest query radius, metres (> 0).

    """

    def __init__(self, pts: np.ndarray, radius: float) -> None:
        finite = np.isfinite(pts).all(axis=1)
        idx = np.flatnonzero(finite)
        if idx.size == 0:
            self.origin = np.zeros(3)
            self.cell = float(radius)
            self.dims = np.ones(3, dtype=np.int64)
            self.order = np.zeros(0, dtype=np.int64)
            self.starts = np.zeros(2, dtype=np.int64)
            return
        p = pts[idx].astype(np.float64)
        origin = p.min(axis=0)
        extent = p.max(axis=0) - origin
        cell = float(radius) * (1.0 + 1e-6)
        # Coarser cells when a fine grid would be too large (still correct: distances are tested).
        volume_cells = float(np.prod(extent / cell + 1.0))
        if volume_cells > _MAX_GRID_CELLS:
            cell *= (volume_cells / _MAX_GRID_CELLS) ** (1.0 / 3.0) * 1.01
        dims = (np.floor(extent / cell) + 1).astype(np.int64)
        order, starts = _counting_sort(p, idx.astype(np.int64), origin, cell, dims)
        self.origin = origin
        self.cell = cell
        self.dims = dims
        self.order = order
        self.starts = starts

    def args(self) -> tuple:
        """The arrays the numba kernels take."""
        return self.origin, self.cell, self.dims, self.order, self.starts


@numba.njit(cache=True)
def _counting_sort(p, idx, origin, cell, dims):
    """Point ids sorted by grid cell (stable) and the start of each cell in that order."""
    n = p.shape[0]
    n_cells = dims[0] * dims[1] * dims[2]
    keys = np.empty(n, dtype=np.int64)
    starts = np.zeros(n_cells + 1, dtype=np.int64)
    for i in range(n):
        cx = min(int(math.floor((p[i, 0] - origin[0]) / cell)), dims[0] - 1)
        cy = min(int(math.floor((p[i, 1] - origin[1]) / cell)), dims[1] - 1)
        cz = min(int(math.floor((p[i, 2] - origin[2]) / cell)), dims[2] - 1)
        keys[i] = (cx * dims[1] + cy) * dims[2] + cz
        starts[keys[i] + 1] += 1
    for c in range(n_cells):
        starts[c + 1] += starts[c]
    fill = starts[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for i in range(n):
        order[fill[keys[i]]] = idx[i]
        fill[keys[i]] += 1
    return order, starts


@numba.njit(cache=True)
def _cell_bounds(origin, cell, dims, qx, qy, qz):
    """Cell ranges (x0, x1, y0, y1, z0, z1) around q, inclusive; x0 > x1 when q is far outside or not finite."""
    if not (np.isfinite(qx) and np.isfinite(qy) and np.isfinite(qz)):
        return 1, 0, 0, -1, 0, -1
    fx = math.floor((np.float64(qx) - origin[0]) / cell)
    fy = math.floor((np.float64(qy) - origin[1]) / cell)
    fz = math.floor((np.float64(qz) - origin[2]) / cell)
    if fx < -1 or fy < -1 or fz < -1 or fx > dims[0] or fy > dims[1] or fz > dims[2]:
        return 1, 0, 0, -1, 0, -1
    cx, cy, cz = int(fx), int(fy), int(fz)
    return (
        max(cx - 1, 0),
        min(cx + 1, dims[0] - 1),
        max(cy - 1, 0),
        min(cy + 1, dims[1] - 1),
        max(cz - 1, 0),
        min(cz + 1, dims[2] - 1),
    )


@numba.njit(cache=True)
def _visit(origin, cell, dims, order, starts, pts, qx, qy, qz, r2, out, write):
    """Count (and, if ``write``, store in out) the points with float32 ((qx-px)² + (qy-py)²) + (qz-pz)² < r2."""
    x0, x1, y0, y1, z0, z1 = _cell_bounds(origin, cell, dims, qx, qy, qz)
    n = 0
    for ix in range(x0, x1 + 1):
        for iy in range(y0, y1 + 1):
            base = (ix * dims[1] + iy) * dims[2]
            for t in range(starts[base + z0], starts[base + z1 + 1]):
                j = order[t]
                ex = qx - pts[j, 0]
                ey = qy - pts[j, 1]
                ez = qz - pts[j, 2]
                if (ex * ex + ey * ey) + ez * ez < r2:
                    if write:
                        out[n] = j
                    n += 1
    return n


@numba.njit(cache=True, parallel=True)
def _grid_csr(origin, cell, dims, order, starts, pts, queries, r2):
    """Neighbour lists (CSR offsets, indices) of each query under PCL's float32 strict radius test."""
    k_count = queries.shape[0]
    counts = np.zeros(k_count, dtype=np.int64)
    empty = np.zeros(0, dtype=np.int64)
    for k in numba.prange(k_count):
        counts[k] = _visit(
            origin,
            cell,
            dims,
            order,
            starts,
            pts,
            queries[k, 0],
            queries[k, 1],
            queries[k, 2],
            r2,
            empty,
            False,
        )
    offsets = np.zeros(k_count + 1, dtype=np.int64)
    for k in range(k_count):
        offsets[k + 1] = offsets[k] + counts[k]
    nbrs = np.empty(offsets[k_count], dtype=np.int64)
    for k in numba.prange(k_count):
        _visit(
            origin,
            cell,
            dims,
            order,
            starts,
            pts,
            queries[k, 0],
            queries[k, 1],
            queries[k, 2],
            r2,
            nbrs[offsets[k] : offsets[k + 1]],
            True,
        )
    return offsets, nbrs


def radius_csr(pts: np.ndarray, queries: np.ndarray, radius: float, grid: Grid | None = None):
    """Neighbours of float32 ``queries`` in float32 ``pts`` strictly within ``radius`` (FLANN's float32 test).

    Returns:
        (offsets (K+1,), indices (M,)) int64 CSR arrays; a non-finite query has no neighbour.

    """
    g = grid if grid is not None else Grid(pts, radius)
    return _grid_csr(*g.args(), pts, queries, pcl_squared_radius(radius))


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
    # PCL compares acosf(|angle|); acos is decreasing with slope <= -1, so only cosines closer than 2 ulp of
    # acos(0) can tie after rounding: evaluate acos for those alone (acos is the costliest step here).
    a1 = abs(angle1)
    a2 = abs(angle2)
    if a2 - a1 > _ACOS_TIE:
        swap = True
    elif a1 - a2 > _ACOS_TIE:
        swap = False
    else:
        swap = np.float32(math.acos(a1)) > np.float32(math.acos(a2))
    if swap:
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
def _spfh_rows(origin, cell, dims, order, starts, pts, nrm, centres, r2, nbins):
    """SPFH (3 × nbins, float32) of each pts[centres[m]], its neighbours found on the fly in the grid."""
    m_count = centres.shape[0]
    out = np.zeros((m_count, 3 * nbins), dtype=np.float32)
    for m in numba.prange(m_count):
        p = centres[m]
        px, py, pz = pts[p, 0], pts[p, 1], pts[p, 2]
        counts = np.zeros(3 * nbins, dtype=np.int64)
        n_in = 0  # |N(p)|, the point itself included
        x0, x1, y0, y1, z0, z1 = _cell_bounds(origin, cell, dims, px, py, pz)
        for ix in range(x0, x1 + 1):
            for iy in range(y0, y1 + 1):
                base = (ix * dims[1] + iy) * dims[2]
                for t in range(starts[base + z0], starts[base + z1 + 1]):
                    q = order[t]
                    ex = px - pts[q, 0]
                    ey = py - pts[q, 1]
                    ez = pz - pts[q, 2]
                    if not ((ex * ex + ey * ey) + ez * ez < r2):
                        continue
                    n_in += 1
                    if q == p:
                        continue
                    ok, f1, f2, f3, _f4 = _pair_features_f32(
                        px,
                        py,
                        pz,
                        nrm[p, 0],
                        nrm[p, 1],
                        nrm[p, 2],
                        pts[q, 0],
                        pts[q, 1],
                        pts[q, 2],
                        nrm[q, 0],
                        nrm[q, 1],
                        nrm[q, 2],
                    )
                    if not ok:
                        continue
                    counts[_bin_angle(f1, nbins)] += 1
                    counts[nbins + _bin_cosine(f2, nbins)] += 1
                    counts[2 * nbins + _bin_cosine(f3, nbins)] += 1
        if n_in < 2:
            continue
        # PCL adds the float32 increment once per pair; repeated addition reproduces its rounding.
        incr = _PERCENT / np.float32(n_in - 1)
        for b in range(3 * nbins):
            v = _F0
            for _ in range(counts[b]):
                v += incr
            out[m, b] = v
    return out


@numba.njit(cache=True, parallel=True)
def _weight_spfh(kp, pts, offsets, nbrs, row_of, spfh, r2, nbins, min_neighbours):
    """FPFH rows: Σ SPFH(q)/d² over the keypoint's neighbours, each sub-histogram rescaled to 100."""
    k_count = kp.shape[0]
    out = np.full((k_count, 3 * nbins), np.nan, dtype=np.float32)
    for k in numba.prange(k_count):
        if offsets[k + 1] - offsets[k] < min_neighbours:
            continue
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
                pts[a, 0],
                pts[a, 1],
                pts[a, 2],
                nrm[a, 0],
                nrm[a, 1],
                nrm[a, 2],
                pts[b, 0],
                pts[b, 1],
                pts[b, 2],
                nrm[b, 0],
                nrm[b, 1],
                nrm[b, 2],
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
    _ok, f1, f2, f3, f4 = _pair_features_f32(
        a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2], d[0], d[1], d[2]
    )
    return float(f1), float(f2), float(f3), float(f4)


def pfh_histogram(
    points: np.ndarray, normals: np.ndarray, indices: np.ndarray, subdivisions: int = 5
) -> np.ndarray:
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
    pts = np.ascontiguousarray(as_points(points), dtype=np.float32)
    nrm = np.ascontiguousarray(as_points(normals, "normals"), dtype=np.float32)
    centres = np.ascontiguousarray(centres, dtype=np.int64)
    grid = Grid(pts, r)
    return _spfh_rows(*grid.args(), pts, nrm, centres, pcl_squared_radius(r), FPFH_BINS_PER_FEATURE)


def fpfh(
    points: np.ndarray, normals: np.ndarray, keypoints: np.ndarray, radius: float
) -> np.ndarray:
    """Fast Point Feature Histograms (33 values), PCL's FPFHEstimation conventions.

    Args:
        points: (N, 3) float, metres: the search surface.
        normals: (N, 3) float unit normals of ``points``. Points with a non-finite position or normal are left
            out of the surface.
        keypoints: (K,) int indices into ``points`` or (K, 3) float coordinates, metres.
        radius: neighbourhood radius of both the SPFH and the FPFH weighting, metres (> 0).

    Returns:
        (K, 33) float32: f1, f2, f3 sub-histograms (11 bins each), each summing to 100. A row is NaN when fewer
        than FPFH_MIN_NEIGHBOURS points lie within the radius, or no neighbour has a valid SPFH.

    Raises:
        InputError: bad array shapes or keypoint indices.
        InputError: radius not finite and > 0.

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
    grid = Grid(pts, r)
    kp_off, kp_nbrs = _grid_csr(*grid.args(), pts, kp, r2)
    # SPFH only for the points some keypoint needs.
    needed_mask = np.zeros(pts.shape[0], dtype=bool)
    needed_mask[kp_nbrs] = True
    needed = np.flatnonzero(needed_mask)
    row_of = np.full(pts.shape[0], -1, dtype=np.int64)
    row_of[needed] = np.arange(needed.shape[0])
    rows = _spfh_rows(*grid.args(), pts, nrm, needed, r2, FPFH_BINS_PER_FEATURE)
    return _weight_spfh(
        kp, pts, kp_off, kp_nbrs, row_of, rows, r2, FPFH_BINS_PER_FEATURE, FPFH_MIN_NEIGHBOURS
    )
