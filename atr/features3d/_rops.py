"""RoPS, Rotational Projection Statistics (Guo, Sohel, Bennamoun, Lu, Wan, IJCV 2013), as PCL 1.13 computes it.

No maintained Python library has RoPS, so it is written here (numba, parallel over keypoints). With a triangle
mesh it follows ``pcl::ROPSEstimation`` of PCL 1.13 step by step, in float32 like PCL, so that it gives PCL's
numbers (see docs/features3d_fpfh_rops_hod.md):

1. Local surface: the points strictly within the support radius R (FLANN's float32 test ``d² < R²``), and every
   triangle that touches one of them (in ascending triangle order).
2. LRF: each triangle contributes its scatter matrix (1/12)(Σ_i Σ_j v_i v_jᵀ + Σ_i v_i v_iᵀ), v_i = vertex -
   keypoint, weighted by |e1 × e2| (twice its area) × (R - |centroid - keypoint|)². x = eigenvector of the largest
   eigenvalue, z = of the smallest; each is flipped when the weighted sum Σ_t w_t/6 Σ_i v_i·axis is negative;
   y = z × x. (PCL 1.13 forgets to divide by the total area: a common scale, no effect on the frame.) The
   eigenvectors come from Eigen's general float32 ``EigenSolver``, as in PCL, replicated bit for bit in
   ``_eigen_f32``: an exact solver differs by ~1e-6, enough to move a point across a bin edge.
3. The local points, moved into the LRF, are rotated about x, then y, then z by θ = k·90°/(rotations+1) (float32
   accumulation, while θ < 90°). Each rotated cloud is projected on the xy, xz and yz planes; a
   partition_bins × partition_bins count matrix over the projection's bounding box (last bin closed), divided by
   the number of points, gives the central moments μ11, μ21, μ12, μ22 (bin coordinates 1..bins) and the Shannon
   entropy (natural log).
4. All 3 × rotations × 3 × 5 values are divided by their L1 norm (left as they are when it is below float32 eps).

For a bare point cloud (``triangles=None``) only step 2 changes (point-based variant): the scatter matrix is
Σ_q (R - |q - p|)² (q - p)(q - p)ᵀ over the local points, and the sign test uses the same weights. Each point
stands for a triangle of equal area at its own position; no triangulation is built (a local Delaunay per keypoint
costs far more than the descriptor itself, and ball pivoting needs normals and a global pass). This variant has no
PCL counterpart to match, so its frame comes from an exact float64 symmetric solver (``eigh``).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from atr.errors import ConfigError, InputError
from atr.features3d._eigen_f32 import eigen_solver_3x3
from atr.features3d._fpfh import (
    as_points,
    check_radius,
    keypoint_coordinates,
    pcl_squared_radius,
    radius_csr,
)

# Guo et al. 2013 / PCL defaults: 5 × 5 distribution matrices, 3 rotations about each LRF axis.
ROPS_PARTITION_BINS = 5
ROPS_ROTATIONS = 3
# Values per projection: μ11, μ21, μ12, μ22 and entropy (Guo et al. 2013 §3.2; PCL's order).
_STATS_PER_PROJECTION = 5
_AXES = 3
_PROJECTIONS = 3
# Fewer local points than this (keypoint included) give a NaN row: 3 rotations of a 5-point cloud is the
# least from which a frame and a bounding box are defined (same minimum as PCL's SHOT).
ROPS_MIN_POINTS = 5

_F0 = np.float32(0.0)
_F1 = np.float32(1.0)
_FLT_EPS = np.float32(np.finfo(np.float32).eps)
_FLT_MAX = np.float32(np.finfo(np.float32).max)
_ONE_TWELFTH = np.float32(1.0) / np.float32(12.0)
_ONE_THIRD = np.float32(1.0) / np.float32(3.0)
_ONE_SIXTH = np.float32(1.0) / np.float32(6.0)
# PCL: const float rad = M_PI / 180.0f (computed in double, stored as float).
_DEG2RAD = np.float32(math.pi / 180.0)


def rops_angles(rotations: int) -> np.ndarray:
    """Rotation angles in degrees, float32, exactly as PCL accumulates them (θ += step while θ < 90)."""
    step = np.float32(90.0) / np.float32(rotations + 1)
    angles = []
    theta = step
    while True:
        angles.append(theta)
        theta = np.float32(theta + step)
        if not theta < np.float32(90.0):
            break
    return np.array(angles, dtype=np.float32)


# ------------------------------------------------------------------------------------------------ kernels


@numba.njit(cache=True, inline="always")
def _dot3(ax, ay, az, bx, by, bz):
    # Eigen's unrolled 3-term reduction: x + (y + z).
    return ax * bx + (ay * by + az * bz)


@numba.njit(cache=True)
def _pcl_major_minor(m):
    """PCL 1.13's ROPSEstimation::computeEigenVectors: (ok, major axis, minor axis), float32.

    Eigen's float32 EigenSolver on the (not exactly symmetric) scatter matrix, replicated bit for bit: RoPS's bins
    move with 1e-6 changes of the frame, which is the distance between this solver and an exact one. The axes
    are the real parts of the eigenvectors of the largest and smallest real parts of the eigenvalues, ranked
    with PCL's three compare-and-swap steps (ties keep Eigen's order).
    """
    ok, re, _im, vre, _vim = eigen_solver_3x3(m)
    major = 0
    middle = 1
    minor = 2
    if re[major] < re[middle]:
        major, middle = middle, major
    if re[major] < re[minor]:
        major, minor = minor, major
    if re[middle] < re[minor]:
        middle, minor = minor, middle
    return ok, vre[:, major].copy(), vre[:, minor].copy()


@numba.njit(cache=True, error_model="numpy")
def _mesh_scatter(pts, tris, local_tris, fp, radius):
    """PCL 1.13's weighted scatter matrix of the local triangles, and each triangle's weight in the sign test.

    float32; not exactly symmetric, since PCL sums v_i v_jᵀ in its own order (the solver sees it as it is).
    """
    n_t = local_tris.shape[0]
    scatters = np.zeros((n_t, 3, 3), dtype=np.float32)
    area = np.zeros(n_t, dtype=np.float32)
    dist_w = np.zeros(n_t, dtype=np.float32)
    total_area = _F0
    v = np.zeros((3, 3), dtype=np.float32)
    for it in range(n_t):
        t = local_tris[it]
        a = tris[t, 0]
        b = tris[t, 1]
        c = tris[t, 2]
        e1x = pts[b, 0] - pts[a, 0]
        e1y = pts[b, 1] - pts[a, 1]
        e1z = pts[b, 2] - pts[a, 2]
        e2x = pts[c, 0] - pts[a, 0]
        e2y = pts[c, 1] - pts[a, 1]
        e2z = pts[c, 2] - pts[a, 2]
        cx = e1y * e2z - e1z * e2y
        cy = e1z * e2x - e1x * e2z
        cz = e1x * e2y - e1y * e2x
        ar = np.float32(math.sqrt(_dot3(cx, cy, cz, cx, cy, cz)))
        area[it] = ar
        total_area += ar
        gx = fp[0] - ((pts[a, 0] + pts[b, 0]) + pts[c, 0]) * _ONE_THIRD
        gy = fp[1] - ((pts[a, 1] + pts[b, 1]) + pts[c, 1]) * _ONE_THIRD
        gz = fp[2] - ((pts[a, 2] + pts[b, 2]) + pts[c, 2]) * _ONE_THIRD
        dd = radius - np.float32(math.sqrt(_dot3(gx, gy, gz, gx, gy, gz)))
        dist_w[it] = dd * dd
        for i in range(3):
            vid = tris[t, i]
            for d in range(3):
                v[i, d] = pts[vid, d] - fp[d]
        cur = np.zeros((3, 3), dtype=np.float32)
        for i in range(3):
            for r in range(3):
                for s in range(3):
                    cur[r, s] += v[i, r] * v[i, s]
            for j in range(3):
                for r in range(3):
                    for s in range(3):
                        cur[r, s] += v[i, r] * v[j, s]
        for r in range(3):
            for s in range(3):
                scatters[it, r, s] = _ONE_TWELFTH * cur[r, s]
    # PCL 1.13's inverted branch: the total area is used only when it is ~0, otherwise 1.
    if abs(total_area) < _FLT_EPS:
        area_scale = _F1 / total_area
    else:
        area_scale = _F1
    overall = np.zeros((3, 3), dtype=np.float32)
    total_w = np.zeros(n_t, dtype=np.float32)
    for it in range(n_t):
        factor = dist_w[it] * area[it] * area_scale
        for r in range(3):
            for s in range(3):
                overall[r, s] += factor * scatters[it, r, s]
        total_w[it] = factor * _ONE_SIXTH
    return overall, total_w


@numba.njit(cache=True)
def _lrf_mesh(pts, tris, local_tris, fp, radius):
    """PCL 1.13 RoPS LRF from the local triangles; rows x, y, z (float32) or all NaN."""
    overall, total_w = _mesh_scatter(pts, tris, local_tris, fp, radius)
    lrf = np.full((3, 3), np.nan, dtype=np.float32)
    if not np.all(np.isfinite(overall)):
        return lrf
    ok, x, z = _pcl_major_minor(overall)
    if not ok:
        return lrf
    h1 = _F0
    h3 = _F0
    for it in range(local_tris.shape[0]):
        t = local_tris[it]
        f1 = _F0
        f3 = _F0
        for i in range(3):
            vid = tris[t, i]
            vx = pts[vid, 0] - fp[0]
            vy = pts[vid, 1] - fp[1]
            vz = pts[vid, 2] - fp[2]
            f1 += _dot3(vx, vy, vz, x[0], x[1], x[2])
            f3 += _dot3(vx, vy, vz, z[0], z[1], z[2])
        h1 += total_w[it] * f1
        h3 += total_w[it] * f3
    if h1 < _F0:
        x = -x
    if h3 < _F0:
        z = -z
    lrf[0] = x
    lrf[1, 0] = z[1] * x[2] - z[2] * x[1]
    lrf[1, 1] = z[2] * x[0] - z[0] * x[2]
    lrf[1, 2] = z[0] * x[1] - z[1] * x[0]
    lrf[2] = z
    return lrf


@numba.njit(cache=True)
def _lrf_points(pts, local, fp, radius):
    """Point-based variant of the RoPS LRF (bare clouds); rows x, y, z (float32) or all NaN."""
    m = np.zeros((3, 3), dtype=np.float64)
    r = np.float64(radius)
    for q in local:
        d = pts[q].astype(np.float64) - fp.astype(np.float64)
        w = (r - math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])) ** 2
        for a in range(3):
            for b in range(3):
                m[a, b] += w * d[a] * d[b]
    lrf = np.full((3, 3), np.nan, dtype=np.float32)
    if not np.all(np.isfinite(m)) or m[0, 0] + m[1, 1] + m[2, 2] == 0.0:
        return lrf
    _vals, vecs = np.linalg.eigh(m)
    x = vecs[:, 2].copy()
    z = vecs[:, 0].copy()
    h1 = 0.0
    h3 = 0.0
    for q in local:
        d = pts[q].astype(np.float64) - fp.astype(np.float64)
        w = (r - math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])) ** 2
        h1 += w * (d[0] * x[0] + d[1] * x[1] + d[2] * x[2])
        h3 += w * (d[0] * z[0] + d[1] * z[1] + d[2] * z[2])
    if h1 < 0.0:
        x = -x
    if h3 < 0.0:
        z = -z
    y = np.cross(z, x)
    lrf[0] = x.astype(np.float32)
    lrf[1] = y.astype(np.float32)
    lrf[2] = z.astype(np.float32)
    return lrf


@numba.njit(cache=True)
def _rotation(axis, theta):
    """PCL's axis-angle matrix in float32 (theta in degrees)."""
    x = np.float32(1.0) if axis == 0 else _F0
    y = np.float32(1.0) if axis == 1 else _F0
    z = np.float32(1.0) if axis == 2 else _F0
    ang = theta * _DEG2RAD
    c = np.float32(math.cos(ang))
    s = np.float32(math.sin(ang))
    one_c = _F1 - c
    rot = np.empty((3, 3), dtype=np.float32)
    rot[0, 0] = c + one_c * x * x
    rot[0, 1] = one_c * x * y - s * z
    rot[0, 2] = one_c * x * z + s * y
    rot[1, 0] = one_c * y * x + s * z
    rot[1, 1] = c + one_c * y * y
    rot[1, 2] = one_c * y * z - s * x
    rot[2, 0] = one_c * z * x - s * y
    rot[2, 1] = one_c * z * y + s * x
    rot[2, 2] = c + one_c * z * z
    return rot


# IEEE division: a projection of zero extent (e.g. a flat, grid-aligned patch) gives inf/NaN bin
# coordinates, which go to bin 0 below, instead of numba's ZeroDivisionError.
@numba.njit(cache=True, error_model="numpy")
def _projection_stats(cloud, mn, mx, u, v, nbins, out, pos):
    """Distribution matrix of the (u, v) projection, then μ11, μ21, μ12, μ22 and entropy into out[pos:pos+5]."""
    n = cloud.shape[0]
    mat = np.zeros((nbins, nbins), dtype=np.float32)
    fb = np.float32(nbins)
    u_len = (mx[u] - mn[u]) / fb
    v_len = (mx[v] - mn[v]) / fb
    for p in range(n):
        ur = (cloud[p, u] - mn[u]) / u_len
        vr = (cloud[p, v] - mn[v]) / v_len
        row = int(ur) if np.isfinite(ur) else 0
        col = int(vr) if np.isfinite(vr) else 0
        row = min(row, nbins - 1)
        col = min(col, nbins - 1)
        mat[row, col] += _F1
    denom = np.float32(max(1, n))
    for i in range(nbins):
        for j in range(nbins):
            mat[i, j] = mat[i, j] / denom
    mean_i = _F0
    mean_j = _F0
    for i in range(nbins):
        for j in range(nbins):
            m = mat[i, j]
            mean_i += np.float32(i + 1) * m
            mean_j += np.float32(j + 1) * m
    m11 = _F0
    m21 = _F0
    m12 = _F0
    m22 = _F0
    entropy = _F0
    for i in range(nbins):
        fi = np.float32(i + 1) - mean_i
        for j in range(nbins):
            fj = np.float32(j + 1) - mean_j
            m = mat[i, j]
            if m > _F0:
                entropy -= m * np.float32(math.log(m))
            m11 += (fi * fj) * m
            m21 += ((fi * fi) * fj) * m
            m12 += (fi * (fj * fj)) * m
            m22 += ((fi * fi) * (fj * fj)) * m
    out[pos] = m11
    out[pos + 1] = m21
    out[pos + 2] = m12
    out[pos + 3] = m22
    out[pos + 4] = entropy


@numba.njit(cache=True, parallel=True)
def _rops_kernel(
    pts,
    kp,
    offsets,
    nbrs,
    r2,
    radius,
    use_mesh,
    tris,
    inc_off,
    inc_tri,
    angles,
    nbins,
    out_len,
    min_points,
):
    k_count = kp.shape[0]
    n_ang = angles.shape[0]
    full_len = _AXES * n_ang * _PROJECTIONS * _STATS_PER_PROJECTION
    out = np.full((k_count, out_len), np.nan, dtype=np.float32)
    for k in numba.prange(k_count):
        fp = kp[k]
        # Local points under FLANN's float32 strict test.
        cand = nbrs[offsets[k] : offsets[k + 1]]
        keep = np.zeros(cand.shape[0], dtype=np.bool_)
        for t in range(cand.shape[0]):
            q = cand[t]
            ex = fp[0] - pts[q, 0]
            ey = fp[1] - pts[q, 1]
            ez = fp[2] - pts[q, 2]
            keep[t] = (ex * ex + ey * ey) + ez * ez < r2
        local = cand[keep]
        n_loc = local.shape[0]
        if n_loc < min_points:
            continue
        if use_mesh:
            total = 0
            for q in local:
                total += inc_off[q + 1] - inc_off[q]
            if total == 0:
                continue
            buf = np.empty(total, dtype=np.int64)
            w = 0
            for q in local:
                for t in range(inc_off[q], inc_off[q + 1]):
                    buf[w] = inc_tri[t]
                    w += 1
            buf = np.sort(buf)
            n_u = 1
            for t in range(1, total):
                if buf[t] != buf[t - 1]:
                    n_u += 1
            local_tris = np.empty(n_u, dtype=np.int64)
            local_tris[0] = buf[0]
            w = 1
            for t in range(1, total):
                if buf[t] != buf[t - 1]:
                    local_tris[w] = buf[t]
                    w += 1
            lrf = _lrf_mesh(pts, tris, local_tris, fp, radius)
        else:
            lrf = _lrf_points(pts, local, fp, radius)
        if not np.all(np.isfinite(lrf)):
            continue
        # Local points in the LRF: lrf · (q - p).
        cloud = np.empty((n_loc, 3), dtype=np.float32)
        for t in range(n_loc):
            q = local[t]
            dx = pts[q, 0] - fp[0]
            dy = pts[q, 1] - fp[1]
            dz = pts[q, 2] - fp[2]
            for a in range(3):
                cloud[t, a] = _dot3(lrf[a, 0], lrf[a, 1], lrf[a, 2], dx, dy, dz)
        feature = np.empty(full_len, dtype=np.float32)
        rotated = np.empty((n_loc, 3), dtype=np.float32)
        mn = np.empty(3, dtype=np.float32)
        mx = np.empty(3, dtype=np.float32)
        pos = 0
        for axis in range(_AXES):
            for ia in range(n_ang):
                rot = _rotation(axis, angles[ia])
                for a in range(3):
                    mn[a] = _FLT_MAX
                    mx[a] = -_FLT_MAX
                for t in range(n_loc):
                    for a in range(3):
                        val = _dot3(
                            rot[a, 0], rot[a, 1], rot[a, 2], cloud[t, 0], cloud[t, 1], cloud[t, 2]
                        )
                        rotated[t, a] = val
                        mn[a] = min(mn[a], val)
                        mx[a] = max(mx[a], val)
                _projection_stats(rotated, mn, mx, 0, 1, nbins, feature, pos)
                _projection_stats(rotated, mn, mx, 0, 2, nbins, feature, pos + 5)
                _projection_stats(rotated, mn, mx, 1, 2, nbins, feature, pos + 10)
                pos += 15
        norm = _F0
        for t in range(full_len):
            norm += abs(feature[t])
        inv = _F1 if norm < _FLT_EPS else _F1 / norm
        for t in range(min(out_len, full_len)):
            out[k, t] = feature[t] * inv
    return out


# ------------------------------------------------------------------------------------------------ public


def _incidence(triangles: np.ndarray, n_points: int) -> tuple[np.ndarray, np.ndarray]:
    """For each vertex, the triangles that use it, in ascending triangle order (CSR)."""
    flat = triangles.reshape(-1)
    tri_of = np.repeat(np.arange(triangles.shape[0], dtype=np.int64), 3)
    order = np.argsort(flat, kind="stable")
    counts = np.bincount(flat, minlength=n_points)
    offsets = np.zeros(n_points + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    return offsets, np.ascontiguousarray(tri_of[order])


def rops(
    points: np.ndarray,
    keypoints: np.ndarray,
    radius: float,
    *,
    triangles: np.ndarray | None = None,
    partition_bins: int = ROPS_PARTITION_BINS,
    rotations: int = ROPS_ROTATIONS,
) -> np.ndarray:
    """Rotational Projection Statistics of each keypoint (PCL 1.13's ROPSEstimation with a mesh).

    Args:
        points: (N, 3) float, metres: the surface (mesh vertices when ``triangles`` is given).
        keypoints: (K,) int indices into ``points`` or (K, 3) float coordinates, metres.
        radius: support radius R, metres (> 0).
        triangles: (M, 3) int vertex indices (0-based) of the mesh, or None for the point-based LRF variant
            (module docstring). An empty (0, 3) array gives all-NaN rows (PCL gives no output).
        partition_bins: bins per side of each distribution matrix (>= 1; Guo et al.: 5).
        rotations: rotations about each LRF axis (>= 1; Guo et al.: 3).

    Returns:
        (K, 45 × rotations) float32 (135 with the defaults), L1-normalised. NaN rows for keypoints with fewer than
        ROPS_MIN_POINTS local points, no local triangle, or a non-finite position.

    Raises:
        InputError: bad shapes, keypoint or triangle indices out of range.
        InputError: radius not finite and > 0.
        ConfigError: partition_bins or rotations < 1 (PCL silently keeps its previous value).

    """
    r = check_radius(radius)
    if int(partition_bins) < 1:
        raise ConfigError(f"RoPS partition_bins {partition_bins} must be >= 1")
    if int(rotations) < 1:
        raise ConfigError(f"RoPS rotations {rotations} must be >= 1")
    nbins = int(partition_bins)
    n_rot = int(rotations)
    out_len = _AXES * n_rot * _PROJECTIONS * _STATS_PER_PROJECTION
    pts64 = as_points(points)
    kp64 = keypoint_coordinates(pts64, keypoints)
    k_count = kp64.shape[0]
    if k_count == 0:
        return np.empty((0, out_len), dtype=np.float32)
    if triangles is not None and np.asarray(triangles).size == 0:
        return np.full((k_count, out_len), np.nan, dtype=np.float32)
    pts = np.ascontiguousarray(pts64, dtype=np.float32)
    kp = np.ascontiguousarray(kp64, dtype=np.float32)
    tris, inc_off, inc_tri = _local_mesh(triangles, pts64)
    offsets, nbrs = radius_csr(pts, kp, r)
    return _rops_kernel(
        pts,
        kp,
        offsets,
        nbrs,
        pcl_squared_radius(r),
        np.float32(r),
        triangles is not None,
        tris,
        inc_off,
        inc_tri,
        rops_angles(n_rot),
        nbins,
        out_len,
        ROPS_MIN_POINTS,
    )


def _local_mesh(
    triangles: np.ndarray | None, pts64: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The checked triangles with finite vertices and each vertex's triangles (CSR offsets, ids).

    Empty arrays for the point-based variant (``triangles`` None).
    """
    n_points = pts64.shape[0]
    if triangles is None:
        return (
            np.zeros((0, 3), dtype=np.int64),
            np.zeros(n_points + 1, dtype=np.int64),
            np.zeros(0, dtype=np.int64),
        )
    tris = np.asarray(triangles)
    if tris.ndim != 2 or tris.shape[1] != 3 or not np.issubdtype(tris.dtype, np.integer):
        raise InputError(f"triangles shape {tris.shape} dtype {tris.dtype} must be (M, 3) integer")
    tris = np.ascontiguousarray(tris, dtype=np.int64)
    if tris.min() < 0 or tris.max() >= n_points:
        raise InputError(
            f"triangle vertex ids span [{tris.min()}, {tris.max()}], expected within [0, {n_points})"
        )
    finite_tri = np.isfinite(pts64[tris]).all(axis=(1, 2))
    tris = np.ascontiguousarray(tris[finite_tri])
    inc_off, inc_tri = _incidence(tris, n_points)
    return tris, inc_off, inc_tri
