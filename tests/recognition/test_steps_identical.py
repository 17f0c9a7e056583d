"""The compiled matcher steps return exactly what their numpy predecessors returned.

The matcher's determinism contract (same input and seed -> byte-identical detections) survived the
move of the hot loops to numba: each reference below is the former numpy implementation, kept here
only as the oracle, and each test compares bit for bit on inputs chosen to hit ties, signed zeros,
NaN rows, degenerate samples and the edges of the heading window.
"""

import numba
import numpy as np
import pytest

from atr.errors import InputError
from atr.recognition import (
    Correspondences,
    RansacSettings,
    RecognitionConfig,
    _kernels,
    descriptor_sq_distances,
    height_above_ground,
    knndr_from_distances,
    lowest_per_cell,
    ransac_per_group,
    rigid_transform,
)
from atr.recognition.matcher import _match_views

# ------------------------------------------------------------------------------ references


def reference_ground_grid(points, cell_m):
    """The former dense raster of each cell's lowest z (inf where empty), its origin, each point's cell."""
    ij = np.floor(points[:, :2] / cell_m).astype(np.int64)
    origin = ij.min(axis=0)
    ij -= origin
    grid = np.full(tuple(int(x) for x in ij.max(axis=0) + 1), np.inf)
    np.minimum.at(grid, (ij[:, 0], ij[:, 1]), points[:, 2])
    return ij, grid, origin


def reference_height_above_ground(points, cell_m, window_m, percentile):
    from scipy import ndimage

    ij, grid, _ = reference_ground_grid(points, cell_m)
    size = 2 * max(1, int(round(window_m / cell_m))) + 1
    ground = ndimage.percentile_filter(grid, percentile, size=size, mode="constant", cval=np.inf)
    fallback = ndimage.minimum_filter(grid, size=size, mode="constant", cval=np.inf)
    ground = np.where(np.isfinite(ground), ground, fallback)
    return points[:, 2] - ground[ij[:, 0], ij[:, 1]]


def reference_lowest_per_cell(points, cell_m):
    _, grid, origin = reference_ground_grid(points, cell_m)
    filled = np.argwhere(np.isfinite(grid))
    return (filled + origin + 0.5) * cell_m, grid[filled[:, 0], filled[:, 1]]


def reference_knndr(d2, k, ratio, max_correspondences=None):
    empty = Correspondences(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    if d2.ndim != 2 or d2.shape[0] == 0 or d2.shape[1] < 2:
        return empty
    row_ok = np.isfinite(d2).any(axis=1)
    col_ok = np.isfinite(d2).any(axis=0)
    s_ok, m_ok = np.flatnonzero(row_ok), np.flatnonzero(col_ok)
    if len(s_ok) == 0 or len(m_ok) < 2:
        return empty
    if len(s_ok) < d2.shape[0] or len(m_ok) < d2.shape[1]:
        d2 = d2[np.ix_(s_ok, m_ok)]
    kk = min(k, d2.shape[1])
    part = np.argpartition(d2, kk - 1, axis=1)[:, :kk]
    pd = np.take_along_axis(d2, part, axis=1)
    order = np.lexsort((part, pd), axis=1)
    nn = np.take_along_axis(part, order, axis=1)
    dist = np.sqrt(np.take_along_axis(pd, order, axis=1).astype(np.float64))
    keep = dist[:, :-1] < ratio * dist[:, -1:]
    rows, cols = np.nonzero(keep)
    sc, mo, di = s_ok[rows], m_ok[nn[rows, cols]], dist[rows, cols]
    o = np.lexsort((mo, sc, di))
    if max_correspondences is not None:
        o = o[:max_correspondences]
    return Correspondences(sc[o].astype(np.int64), mo[o].astype(np.int64), di[o])


def reference_hough(
    scene_keypoints,
    scene_heights,
    model_keypoints,
    corr,
    *,
    cell_m,
    yaw_bin_rad,
    height_tol_m,
    min_size,
    max_groups=None,
    yaw_centre_rad=None,
    yaw_half_width_rad=float(np.pi),
):
    if len(corr) < min_size:
        return []
    s = np.asarray(scene_keypoints, np.float64)[corr.scene]
    hs = np.asarray(scene_heights, np.float64)[corr.scene]
    m = np.asarray(model_keypoints, np.float64)[corr.model]
    ok = np.flatnonzero(np.abs(hs - m[:, 2]) <= height_tol_m)
    if len(ok) < min_size:
        return []
    n_bins = max(1, int(round(2 * np.pi / yaw_bin_rad)))
    centres = (np.arange(n_bins) + 0.5) * (2 * np.pi / n_bins)
    if yaw_centre_rad is None:
        ci = np.repeat(ok, n_bins)
        bi = np.tile(np.arange(n_bins), len(ok))
    else:
        diff = np.angle(np.exp(1j * (centres[None, :] - np.asarray(yaw_centre_rad)[ok, None])))
        rows, bi = np.nonzero(np.abs(diff) <= yaw_half_width_rad + 0.5 * (2 * np.pi / n_bins))
        ci = ok[rows]
    if len(ci) == 0:
        return []
    c, sn = np.cos(centres[bi]), np.sin(centres[bi])
    tx = s[ci, 0] - (c * m[ci, 0] - sn * m[ci, 1])
    ty = s[ci, 1] - (sn * m[ci, 0] + c * m[ci, 1])
    gx = np.floor(tx / cell_m).astype(np.int64)
    gy = np.floor(ty / cell_m).astype(np.int64)
    gx -= gx.min()
    gy -= gy.min()
    ny = int(gy.max()) + 3
    nx = int(gx.max()) + 3
    key = (bi * nx + gx) * ny + gy
    pair = np.unique(key * len(corr) + ci)
    cell_keys, counts = np.unique(pair // len(corr), return_counts=True)
    order = np.lexsort((cell_keys, -counts))
    groups = []
    used_cells = []
    for o in order:
        if counts[o] < min_size or (max_groups is not None and len(groups) >= max_groups):
            break
        k = int(cell_keys[o])
        b, rest = divmod(k, nx * ny)
        x, y = divmod(rest, ny)
        if any(
            min(abs(b - ub), n_bins - abs(b - ub)) <= 1 and abs(x - ux) <= 1 and abs(y - uy) <= 1
            for ub, ux, uy in used_cells
        ):
            continue
        used_cells.append((b, x, y))
        db = np.abs(bi - b)
        near = (np.minimum(db, n_bins - db) <= 1) & (np.abs(gx - x) <= 1) & (np.abs(gy - y) <= 1)
        members = np.unique(ci[near])
        if len(members) >= min_size:
            groups.append(members.astype(np.int64))
    groups.sort(key=lambda g: -len(g))
    return groups


@numba.njit
def _reference_ransac_counts(R, t, m, s, inlier2):
    n_it, n = R.shape[0], m.shape[0]
    counts = np.zeros(n_it, np.int64)
    for i in range(n_it):
        c = 0
        for j in range(n):
            d2 = 0.0
            for a in range(3):
                p = R[i, a, 0] * m[j, 0] + R[i, a, 1] * m[j, 1] + R[i, a, 2] * m[j, 2] + t[i, a]
                d2 += (p - s[j, a]) ** 2
            if d2 < inlier2:
                c += 1
        counts[i] = c
    return counts


def reference_kabsch(m, s, idx):
    """Kabsch on each sample of 3: centroids (K, 1, 3), cross-covariances, their SVD, R and t."""
    ms, ss = m[idx], s[idx]
    mc, sc = ms.mean(1, keepdims=True), ss.mean(1, keepdims=True)
    H = np.einsum("ikj,ikl->ijl", ms - mc, ss - sc)
    U, _, Vt = np.linalg.svd(H)
    det = np.linalg.det(np.einsum("ikj,ilk->ijl", Vt, U))
    Vt_fix = Vt.copy()
    Vt_fix[:, 2, :] *= np.where(det < 0, -1.0, 1.0)[:, None]
    R = np.einsum("ikj,ilk->ijl", Vt_fix, U)
    t = sc[:, 0, :] - np.einsum("ijk,ik->ij", R, mc[:, 0, :])
    return mc, sc, H, U, Vt, R, t


def reference_ransac(scene_keypoints, model_keypoints, corr, group, iterations, inlier_m, rng):
    s = np.asarray(scene_keypoints[corr.scene[group]], np.float64)
    m = np.asarray(model_keypoints[corr.model[group]], np.float64)
    n = len(group)
    if n < 3:
        return None
    idx = rng.integers(0, n, size=(iterations, 3))
    ok = (idx[:, 0] != idx[:, 1]) & (idx[:, 0] != idx[:, 2]) & (idx[:, 1] != idx[:, 2])
    idx = idx[ok]
    if len(idx) == 0:
        return None
    *_, R, t = reference_kabsch(m, s, idx)
    counts = _reference_ransac_counts(
        np.ascontiguousarray(R), np.ascontiguousarray(t), m, s, float(inlier_m) ** 2
    )
    best = int(np.argmax(counts))
    if counts[best] < 3:
        return None
    mask = np.sum(((m @ R[best].T + t[best]) - s) ** 2, axis=1) < inlier_m**2
    T = rigid_transform(m[mask], s[mask])
    final = np.sum(((m @ T[:3, :3].T + T[:3, 3]) - s) ** 2, axis=1) < inlier_m**2
    return (T, int(max(final.sum(), counts[best])), n)


def reference_match_views(scene_desc, model_desc, views, view_el, keypoints_of_ring, config):
    out = [
        Correspondences(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)) for _ in views
    ]
    view_el_arr = np.asarray(view_el, np.float64)
    for ring, rows in keypoints_of_ring.items():
        in_ring = np.flatnonzero(view_el_arr == ring)
        if len(rows) == 0 or len(in_ring) == 0:
            continue
        cols = np.concatenate([np.arange(views[v][1].start, views[v][1].stop) for v in in_ring])
        owner = np.concatenate([np.full(views[v][1].stop - views[v][1].start, v) for v in in_ring])
        d2 = descriptor_sq_distances(scene_desc[rows], model_desc[cols])
        if config.knn_across_views:
            c = reference_knndr(d2, config.knndr_k, config.knndr_ratio)
            for v in in_ring:
                sel = np.flatnonzero(owner[c.model] == v)
                out[v] = Correspondences(
                    rows[c.scene[sel]], cols[c.model[sel]] - views[v][1].start, c.distance[sel]
                )
        else:
            start = 0
            for v in in_ring:
                n = views[v][1].stop - views[v][1].start
                c = reference_knndr(
                    d2[:, start : start + n],
                    config.knndr_k,
                    config.knndr_ratio,
                    config.max_correspondences,
                )
                out[v] = Correspondences(rows[c.scene], c.model, c.distance)
                start += n
    return out


# ------------------------------------------------------------------------------ helpers


def _same_array(a, b):
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def _same_corr(a, b):
    return all(_same_array(getattr(a, f), getattr(b, f)) for f in ("scene", "model", "distance"))


def _distance_matrices(rng):
    """Squared-distance matrices as the matcher makes them, plus ties, NaN and inf rows/columns."""
    out = []
    for trial in range(60):
        n_s, n_m = int(rng.integers(1, 60)), int(rng.integers(1, 90))
        if trial % 3 == 0:  # coarse integer distances: many exact ties around the k-th
            d2 = rng.integers(0, 6, (n_s, n_m)).astype(np.float32)
        else:
            d2 = rng.random((n_s, n_m), np.float32) * 4
        if trial % 4 == 1:
            d2[rng.random(n_s) < 0.3] = np.nan  # NaN scene descriptors
        if trial % 5 == 2:
            d2[:, rng.random(n_m) < 0.3] = np.nan  # NaN model descriptors
        if trial % 7 == 3:
            d2[rng.random((n_s, n_m)) < 0.05] = np.inf
        if trial % 11 == 4:
            d2[rng.random((n_s, n_m)) < 0.2] = -0.0
        out.append(d2 if trial % 6 else d2.astype(np.float64))
    return out


# ------------------------------------------------------------------------------ sorting


def test_radix_argsort_is_numpys_stable_argsort_for_keys_and_distances():
    """The radix sort that orders Hough votes and kNNDR correspondences is np.argsort(kind="stable")."""
    rng = np.random.default_rng(7)
    for n in (0, 1, 2, 5, 1000, 30_000):
        for top in (1, 3, 2**11, 2**11 + 1, 450_000, 2**40, 2**62):  # 0, 1, 1, 2, 2, 4 and 6 passes
            keys = rng.integers(0, top, n)
            got = _kernels.stable_argsort_nonnegative(keys)
            assert np.array_equal(got, np.argsort(keys, kind="stable"))
        # distances as knndr_from_distances passes them: ties, signed zeros, subnormals, inf
        dist = np.sqrt(rng.integers(0, 50, n).astype(np.float32).astype(np.float64))
        dist[rng.random(n) < 0.1] = -0.0
        dist[rng.random(n) < 0.05] = 5e-324
        dist[rng.random(n) < 0.05] = np.inf
        got = _kernels.stable_argsort_nonnegative((dist + 0.0).view(np.int64))
        assert np.array_equal(got, np.argsort(dist, kind="stable"))


def test_radix_argsort_refuses_negative_keys():
    with pytest.raises(ValueError, match="keys >= 0"):
        _kernels.stable_argsort_nonnegative(np.array([3, -1, 2], np.int64))


# ------------------------------------------------------------------------------ kNNDR


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # 0 x inf
@pytest.mark.parametrize("k", [1, 2, 3, 10, 200])
@pytest.mark.parametrize("ratio", [1.0, 0.9, 0.5, 0.0, -1.0])
def test_knndr_matches_the_numpy_reference(k, ratio):
    rng = np.random.default_rng(100 + k)
    for d2 in _distance_matrices(rng):
        for cap in (None, 7):
            got = knndr_from_distances(d2, k, ratio, cap)
            assert _same_corr(got, reference_knndr(d2, k, ratio, cap))
    # column slices of a larger matrix, as the matcher passes each template view
    d2 = rng.random((50, 120), np.float32)
    for start, stop in ((0, 30), (30, 31), (31, 120)):
        view = d2[:, start:stop]
        assert _same_corr(
            knndr_from_distances(view, k, ratio, 20), reference_knndr(view, k, ratio, 20)
        )


def test_knndr_rejects_ratios_above_one_and_k_below_one():
    d2 = np.ones((3, 4), np.float32)
    with pytest.raises(InputError):
        knndr_from_distances(d2, 10, 1.5)
    with pytest.raises(InputError):
        knndr_from_distances(d2, 0, 0.9)


@pytest.mark.parametrize("across", [False, True])
def test_match_views_matches_the_numpy_reference(across):
    """Per-view and across-view kNNDR over elevation rings, with NaN scene descriptors."""
    rng = np.random.default_rng(11)
    scene = rng.random((150, 352), np.float32)
    scene[rng.random(150) < 0.1] = np.nan
    sizes = rng.integers(20, 60, 12)
    model = rng.random((int(sizes.sum()), 352), np.float32)
    bounds = np.concatenate([[0], np.cumsum(sizes)])
    views = [(slice(0, 1), slice(int(a), int(b))) for a, b in zip(bounds[:-1], bounds[1:])]
    config = RecognitionConfig(knn_across_views=across, max_correspondences=500)
    interleaved = rng.choice([10.0, 30.0], 150)
    for view_el, keypoints_of_ring in (
        ([10.0] * 12, {10.0: np.arange(150)}),  # one ring: every row and view, consecutive
        (  # two rings, rows interleaved
            [10.0] * 6 + [30.0] * 6,
            {r: np.flatnonzero(interleaved == r) for r in (10.0, 30.0)},
        ),
        ([10.0, 30.0] * 6, {10.0: np.arange(70), 30.0: np.arange(70, 150)}),  # views interleaved
        ([10.0, 30.0] * 6, {10.0: np.arange(100), 30.0: np.arange(50, 150)}),  # rows in both
    ):
        got = _match_views(scene, model, views, view_el, keypoints_of_ring, config)
        want = reference_match_views(scene, model, views, view_el, keypoints_of_ring, config)
        assert len(got) == len(want) == len(views)
        assert all(_same_corr(g, w) for g, w in zip(got, want, strict=True))
        assert sum(len(w) for w in want) > 100


# ------------------------------------------------------------------------------ upright Hough


def _hough_case(rng, n_corr, spread_m):
    n_s, n_m = 150, 120
    scene = np.c_[rng.uniform(-spread_m, spread_m, (n_s, 2)), rng.uniform(0, 3, n_s)]
    model = np.c_[rng.uniform(-3.5, 3.5, (n_m, 2)), rng.uniform(0, 3, n_m)]
    heights = scene[:, 2] + rng.normal(0, 0.2, n_s)
    corr = Correspondences(
        rng.integers(0, n_s, n_corr), rng.integers(0, n_m, n_corr), np.sort(rng.random(n_corr))
    )
    # half of them from one true pose, so that real peaks exist
    yaw, shift = rng.uniform(0, 2 * np.pi), rng.uniform(-5, 5, 2)
    c, s = np.cos(yaw), np.sin(yaw)
    true = rng.random(n_corr) < 0.5
    mk = model[corr.model[true]]
    scene[corr.scene[true], :2] = (mk[:, :2] @ np.array([[c, s], [-s, c]])) + shift
    scene[corr.scene[true], 2] = mk[:, 2]
    heights[corr.scene[true]] = mk[:, 2]
    return scene, heights, model, corr


def test_upright_hough_matches_the_numpy_reference(hough):
    rng = np.random.default_rng(7)
    n_checked = 0
    for trial in range(120):
        scene, heights, model, corr = _hough_case(
            rng, int(rng.integers(0, 400)), float(rng.choice([3.0, 30.0]))
        )
        kw = {
            "cell_m": float(rng.choice([0.3, 0.9, 2.0])),
            "yaw_bin_rad": float(np.radians(rng.choice([10.0, 45.0, 120.0, 200.0, 400.0]))),
            "height_tol_m": float(rng.choice([0.2, 0.45, 5.0])),
            "min_size": int(rng.choice([0, 1, 3, 5])),
            "max_groups": [None, 0, 1, 10][trial % 4],
        }
        if trial % 3:
            to_cam = rng.uniform(-np.pi, np.pi, len(corr))
            kw["yaw_centre_rad"] = to_cam - np.radians(rng.choice([0.0, 15.0, 90.0]))
            kw["yaw_half_width_rad"] = float(rng.choice([0.3, np.pi / 12 + 0.1, np.pi]))
        got = hough(scene, heights, model, corr, **kw)
        want = reference_hough(scene, heights, model, corr, **kw)
        assert len(got) == len(want)
        assert all(_same_array(g, w) for g, w in zip(got, want, strict=True))
        n_checked += len(want)
    assert n_checked > 100  # the cases do form groups


def test_upright_hough_heading_window_edges_match_the_numpy_reference(hough):
    """Headings exactly at, just inside and just outside the window edge; huge and NaN headings."""
    rng = np.random.default_rng(8)
    n_bins = 36
    bin_rad = 2 * np.pi / n_bins
    half = np.pi / 12 + np.radians(5.0)
    limit = half + 0.5 * bin_rad
    centres = (np.arange(n_bins) + 0.5) * bin_rad
    scene, heights, model, corr = _hough_case(rng, 600, 3.0)
    b = rng.integers(0, n_bins, len(corr))
    yaw = centres[b] + rng.choice([-1, 1], len(corr)) * limit
    yaw += rng.choice([0.0, 1e-16, -1e-16, 1e-12, -1e-12, 1e-10], len(corr)) * rng.choice([0, 1, 2])
    yaw += 2 * np.pi * rng.integers(-3, 4, len(corr))
    yaw[::50] = 1e7
    yaw[1::50] = np.nan
    kw = {"cell_m": 0.9, "yaw_bin_rad": bin_rad, "height_tol_m": 0.45, "min_size": 3}
    got = hough(scene, heights, model, corr, yaw_centre_rad=yaw, yaw_half_width_rad=half, **kw)
    want = reference_hough(
        scene, heights, model, corr, yaw_centre_rad=yaw, yaw_half_width_rad=half, **kw
    )
    assert len(got) == len(want) > 0
    assert all(_same_array(g, w) for g, w in zip(got, want, strict=True))


# ------------------------------------------------------------------------------ RANSAC


def _ransac_cases(rng):
    for trial in range(80):
        n = int(rng.integers(0, 200))
        model = rng.normal(size=(n, 3)) * float(rng.choice([0.1, 2.0, 50.0]))
        if trial % 4 == 1:  # a coarse grid: exact cancellations, zero and signed-zero coordinates
            model = rng.integers(-2, 3, (n, 3)) * 0.3
            model[rng.random((n, 3)) < 0.2] = -0.0
        if trial % 4 == 2 and n:  # repeated and collinear points: degenerate samples
            model[: n // 2] = model[0]
            model[n // 2 :, 1:] = 0.0
        T = np.eye(4)
        T[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        T[:3, 3] = rng.uniform(-20, 20, 3)
        scene = model @ T[:3, :3].T + T[:3, 3] + rng.normal(0, 0.05, (n, 3))
        outliers = rng.random(n) < rng.uniform(0, 0.9)
        scene[outliers] = rng.uniform(-20, 20, (int(outliers.sum()), 3))
        corr = Correspondences(np.arange(n), np.arange(n), np.zeros(n))
        group = np.flatnonzero(rng.random(n) < 0.8)
        iterations = int(rng.choice([1, 3, 50, 1000]))
        inlier_m = float(rng.choice([0.001, 0.1, 0.3]))
        yield scene, model, corr, group, iterations, inlier_m, int(rng.integers(1 << 30))


def test_ransac_matches_the_numpy_reference_and_draws_the_same_samples():
    rng = np.random.default_rng(9)
    n_found = 0
    for scene, model, corr, group, iterations, inlier_m, seed in _ransac_cases(rng):
        g_new, g_ref = np.random.default_rng(seed), np.random.default_rng(seed)
        settings = RansacSettings(iterations, inlier_m)
        got = ransac_per_group(scene, model, corr, group, settings, g_new)
        want = reference_ransac(scene, model, corr, group, iterations, inlier_m, g_ref)
        assert g_new.bit_generator.state == g_ref.bit_generator.state
        if want is None:
            assert got is None
            continue
        n_found += 1
        assert _same_array(got.T_scene_model, want[0])
        assert (got.inliers, got.group_size) == want[1:]
        assert type(got.inliers) is int
    assert n_found > 20  # the cases do find poses


def _sample_cases(rng):
    """40 (model, scene, samples) triples: random spreads, and grids with signed zeros."""
    for trial in range(40):
        n, n_samples = int(rng.integers(3, 100)), int(rng.integers(1, 500))
        m = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-3, 3)
        s = rng.normal(size=(n, 3)) * 10
        if trial % 2:  # a grid with signed zeros: the order of the sums decides the zeros' signs
            m = rng.integers(-2, 3, (n, 3)) * 0.3
            s = rng.integers(-2, 3, (n, 3)).astype(float)
            m[rng.random((n, 3)) < 0.3] = -0.0
            s[rng.random((n, 3)) < 0.3] = -0.0
        yield m, s, rng.integers(0, n, (n_samples, 3))


def test_kabsch_kernels_reproduce_numpys_intermediates_including_signed_zeros():
    """Centroids, cross-covariances, rotations and translations equal numpy's bit for bit."""
    rng = np.random.default_rng(10)
    for m, s, idx in _sample_cases(rng):
        mc, sc, H, U, Vt, R, t = reference_kabsch(m, s, idx)
        mc2, sc2, H2 = _kernels.sample_cross_covariances(m, s, idx)
        R2, t2 = _kernels.kabsch_poses(U, Vt, mc2, sc2)
        for got, want in ((mc2, mc[:, 0]), (sc2, sc[:, 0]), (H2, H), (R2, R), (t2, t)):
            assert got.tobytes() == np.ascontiguousarray(want).tobytes()


def test_upright_sample_kernel_reproduces_numpys_headings_including_signed_zeros():
    """Centroids and headings of the upright RANSAC samples equal the numpy form's bit for bit."""
    rng = np.random.default_rng(11)
    for m, s, idx in _sample_cases(rng):
        ms, ss = m[idx], s[idx]
        mc, sc = ms.mean(axis=1), ss.mean(axis=1)
        a, b = (ms - mc[:, None])[..., :2], (ss - sc[:, None])[..., :2]
        dot = np.sum(a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1], axis=-1)
        cross = np.sum(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0], axis=-1)

        mc2, sc2, dot2, cross2 = _kernels.sample_upright_sums(m, s, idx)
        for got, want in ((mc2, mc), (sc2, sc), (dot2, dot), (cross2, cross)):
            assert got.tobytes() == np.ascontiguousarray(want).tobytes()
        yaw, yaw2 = np.arctan2(cross, dot), np.arctan2(cross2, dot2)
        assert yaw.tobytes() == yaw2.tobytes()


@pytest.mark.parametrize("percentile", [0.0, 20.0, 50.0, 99.0, 100.0])
@pytest.mark.parametrize("window_m", [1.5, 4.5, 7.0])
def test_ground_on_occupied_cells_equals_the_dense_raster(percentile, window_m):
    """Dense, sparse and clustered clouds, negative coordinates, ties: the same values bit for bit."""
    rng = np.random.default_rng(int(percentile * 10 + window_m * 100))
    terrain = np.c_[rng.uniform(-30, 10, (3000, 2)), rng.normal(0, 0.3, 3000)]
    roof = np.c_[rng.uniform(-5, 5, (400, 2)), np.full(400, 2.0)]  # tied z values
    sparse = np.c_[rng.uniform(-200, 150, (60, 2)), rng.normal(0, 2, 60)]
    for pts in (terrain, np.r_[terrain, roof, sparse], sparse, terrain[:1]):
        np.testing.assert_array_equal(
            height_above_ground(pts, 1.5, window_m, percentile),
            reference_height_above_ground(pts, 1.5, window_m, percentile),
        )
        for got, want in zip(lowest_per_cell(pts, 1.5), reference_lowest_per_cell(pts, 1.5)):
            np.testing.assert_array_equal(got, want)
