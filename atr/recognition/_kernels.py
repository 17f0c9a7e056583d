"""Compiled hot loops of the matcher's steps (``atr.recognition.steps``).

Each kernel returns, bit for bit, what the numpy code it replaced returned (that code is kept as the
oracle in tests/recognition/test_steps_identical.py): floating-point results come from the same
operations in the same order (numba neither reassociates nor fuses them without ``fastmath``), so
the matcher's detections, a determinism contract, did not change. numpy keeps what cannot be
reproduced that way: the batched SVD, and trigonometry where a comparison could go either way.
"""

from __future__ import annotations

import numba
import numpy as np

# ------------------------------------------------------------------------------ kNNDR matching


@numba.njit(cache=True)
def finite_columns(d2: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Indices of the columns holding any finite entry (rows are read until every column has one)."""
    n_rows, n_cols = d2.shape
    ok = np.zeros(n_cols, np.bool_)
    n_ok = 0
    for i in range(n_rows):
        for j in range(n_cols):
            if not ok[j] and np.isfinite(d2[i, j]):
                ok[j] = True
                n_ok += 1
        if n_ok == n_cols:
            break
    return np.flatnonzero(ok)


@numba.njit(cache=True)
def knndr_keep(
    d2: np.ndarray, d_k: np.ndarray, k: int, ratio: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Entries of a squared-distance matrix kept by the kNNDR rule, given each row's k-th smallest.

    Entry (i, j) is kept when sqrt(d2[i, j]) < ratio sqrt(d_k[i]). With ratio <= 1 it is then
    strictly below the k-th smallest d_k[i], so it is one of the row's k nearest however ties at d_k
    are broken, and a row keeps at most k - 1 entries.

    Returns:
        rows, columns and distances (float64 sqrt of the entry) of the kept entries, ordered by row,
        then column.

    """
    n_rows, n_cols = d2.shape
    cap = n_rows * max(k - 1, 0)
    out_rows = np.empty(cap, np.int64)
    out_cols = np.empty(cap, np.int64)
    out_dist = np.empty(cap, np.float64)
    n_out = 0
    for i in range(n_rows):
        kth = d_k[i]
        limit = ratio * np.sqrt(np.float64(kth))
        row_start = n_out
        for j in range(n_cols):
            if d2[i, j] < kth:  # implied by the rule, and cheaper to test
                dist = np.sqrt(np.float64(d2[i, j]))
                if dist < limit:
                    if n_out - row_start == k - 1:
                        raise ValueError("d_k is not the k-th smallest entry of its row")
                    out_rows[n_out] = i
                    out_cols[n_out] = j
                    out_dist[n_out] = dist
                    n_out += 1
    return out_rows[:n_out], out_cols[:n_out], out_dist[:n_out]


_RADIX_BITS = 11  # 2,048 buckets: two passes sort the Hough accumulator's keys


@numba.njit(cache=True)
def stable_argsort_nonnegative(keys: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """``np.argsort(keys, kind="stable")`` for non-negative int64 keys, by LSD radix sort.

    Non-negative float64 values sort like their bit patterns read as int64 (``x.view(np.int64)``, with
    -0.0 made +0.0 first), so distances go through here too. Passes run only over the bits the largest
    key uses; each pass is stable, so equal keys keep their index order.

    Raises:
        ValueError: a key is negative.

    """
    n = keys.shape[0]
    order = np.arange(n)
    if n < 2:
        return order
    if keys.min() < 0:
        raise ValueError("stable_argsort_nonnegative needs keys >= 0")
    bits = 0
    top = keys.max()
    while top > 0:
        bits += 1
        top >>= 1
    buckets = 1 << _RADIX_BITS
    mask = buckets - 1
    other = np.empty(n, np.int64)
    start = np.empty(buckets + 1, np.int64)
    for shift in range(0, bits, _RADIX_BITS):
        start[:] = 0
        for i in range(n):
            start[((keys[order[i]] >> shift) & mask) + 1] += 1
        for d in range(buckets):
            start[d + 1] += start[d]
        for i in range(n):
            d = (keys[order[i]] >> shift) & mask
            other[start[d]] = order[i]
            start[d] += 1
        order, other = other, order
    return order


# ------------------------------------------------------------------------------ upright Hough grouping


_TWO_PI = 2 * np.pi
_WINDOW_MARGIN_RAD = 1e-9  # far above the ~1e-13 rad error of the arithmetic wrap below
_WINDOW_RANGE_RAD = 1e3  # differences up to this size wrap with that accuracy


@numba.njit(cache=True)
def yaw_window(
    yaw: np.ndarray, centres: np.ndarray, limit: float
) -> np.ndarray:  # pragma: no cover
    """Whether each heading-bin centre lies within ``limit`` of each expected heading, on the circle.

    The rule is |angle(exp(1j (centre - yaw)))| <= limit with numpy's complex exp and arctan2, which
    cost more than the rest of the grouping; here the difference is wrapped arithmetically instead.
    Where that could decide otherwise (within a margin of the limit, huge or NaN differences) the
    entry is -1 and the caller evaluates the numpy rule.

    Returns:
        (len(yaw), len(centres)) int8: 1 inside, 0 outside, -1 undecided.

    """
    out = np.empty((yaw.shape[0], centres.shape[0]), np.int8)
    for r in range(yaw.shape[0]):
        for b in range(centres.shape[0]):
            x = centres[b] - yaw[r]
            if not abs(x) < _WINDOW_RANGE_RAD:  # also NaN
                out[r, b] = -1
                continue
            d = abs(x - _TWO_PI * np.round(x / _TWO_PI))
            if d < limit - _WINDOW_MARGIN_RAD:
                out[r, b] = 1
            elif d > limit + _WINDOW_MARGIN_RAD:
                out[r, b] = 0
            else:
                out[r, b] = -1
    return out


@numba.njit(cache=True)
def hough_votes(
    s: np.ndarray,
    m: np.ndarray,
    rows: np.ndarray,
    window: np.ndarray,
    cos_bin: np.ndarray,
    sin_bin: np.ndarray,
    cell_m: float,
) -> tuple[np.ndarray, np.ndarray, int, int]:  # pragma: no cover - compiled
    """Votes of correspondences in an upright-pose (heading bin, x cell, y cell) accumulator.

    Correspondence c = ``rows[r]`` votes in every heading bin b with ``window[r, b]``, for the cell
    (x, y) of the target origin s_xy - R(b) m_xy, cells counted from the smallest x and y voted for.

    Returns:
        per vote the correspondence and the cell's key (b nx + x) ny + y, which orders cells by
        (b, x, y); and nx, ny.

    """
    n_votes = 0
    for r in range(window.shape[0]):
        for b in range(window.shape[1]):
            n_votes += window[r, b] != 0
    ci = np.empty(n_votes, np.int64)
    bi = np.empty(n_votes, np.int64)
    gx = np.empty(n_votes, np.int64)
    gy = np.empty(n_votes, np.int64)
    v = 0
    for r in range(window.shape[0]):
        c = rows[r]
        for b in range(window.shape[1]):
            if window[r, b] == 0:
                continue
            tx = s[c, 0] - (cos_bin[b] * m[c, 0] - sin_bin[b] * m[c, 1])
            ty = s[c, 1] - (sin_bin[b] * m[c, 0] + cos_bin[b] * m[c, 1])
            ci[v] = c
            bi[v] = b
            gx[v] = np.int64(np.floor(tx / cell_m))
            gy[v] = np.int64(np.floor(ty / cell_m))
            v += 1
    if n_votes == 0:
        return ci, bi, 0, 0
    gx -= gx.min()
    gy -= gy.min()
    nx, ny = gx.max() + 1, gy.max() + 1
    return ci, (bi * nx + gx) * ny + gy, nx, ny


@numba.njit(cache=True)
def count_runs(
    sorted_keys: np.ndarray, min_count: int
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover
    """Distinct values of a sorted array that occur at least ``min_count`` times, and their counts."""
    n = sorted_keys.shape[0]
    keys = np.empty(n, np.int64)
    counts = np.empty(n, np.int64)
    k = 0
    start = 0
    for i in range(1, n + 1):
        if i == n or sorted_keys[i] != sorted_keys[start]:
            if i - start >= min_count:
                keys[k] = sorted_keys[start]
                counts[k] = i - start
                k += 1
            start = i
    return keys[:k], counts[:k]


@numba.njit(cache=True)
def claim_hough_groups(
    cell: np.ndarray,
    ci: np.ndarray,
    peaks: np.ndarray,
    n_bins: int,
    nx: int,
    ny: int,
    n_corr: int,
    min_size: int,
    max_groups: int,
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Groups of the accumulator's peaks, strongest peak first.

    Votes come sorted by ``cell`` (keys as from ``hough_votes``), with their correspondences ``ci``.
    A peak (bin, x, y) whose 3 x 3 x 3 neighbourhood (bins on the circle) touches an earlier peak's
    is skipped; otherwise its group is every correspondence voting in that neighbourhood (ascending,
    each once). Stops after ``max_groups`` groups (< 0: no limit).

    Returns:
        the groups' members one after the other, and each group's size.

    """
    members = np.empty(0, np.int64)
    sizes = np.empty(0, np.int64)
    in_group = np.zeros(n_corr, np.bool_)
    found = np.empty(ci.shape[0], np.int64)
    claimed = np.empty((peaks.shape[0], 3), np.int64)
    n_claimed = 0
    for p in range(peaks.shape[0]):
        if max_groups >= 0 and sizes.shape[0] >= max_groups:
            break
        b, rest = divmod(peaks[p], nx * ny)
        x, y = divmod(rest, ny)
        clash = False
        for q in range(n_claimed):
            d = abs(b - claimed[q, 0])
            if (
                min(d, n_bins - d) <= 1
                and abs(x - claimed[q, 1]) <= 1
                and abs(y - claimed[q, 2]) <= 1
            ):
                clash = True
                break
        if clash:
            continue
        claimed[n_claimed, 0] = b
        claimed[n_claimed, 1] = x
        claimed[n_claimed, 2] = y
        n_claimed += 1
        # The neighbourhood's votes: per bin and x, one run of keys (y - 1 .. y + 1) in ``cell``.
        # With fewer than 3 bins a bin comes twice, which adds nobody twice.
        n_found = 0
        for db in range(-1, 2):
            bb = (b + db) % n_bins
            for xx in range(max(x - 1, 0), min(x + 2, nx)):
                base = (bb * nx + xx) * ny
                lo = np.searchsorted(cell, base + max(y - 1, 0))
                hi = np.searchsorted(cell, base + min(y + 1, ny - 1), side="right")
                for v in range(lo, hi):
                    if not in_group[ci[v]]:
                        in_group[ci[v]] = True
                        found[n_found] = ci[v]
                        n_found += 1
        group = np.sort(found[:n_found])
        in_group[group] = False
        if group.shape[0] >= min_size:
            members = np.concatenate((members, group))
            sizes = np.append(sizes, group.shape[0])
    return members, sizes


# ------------------------------------------------------------------------------ RANSAC on a group


@numba.njit(cache=True)
def _sample_centroids(
    m: np.ndarray, s: np.ndarray, samples: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """(I, 3) model and scene centroids of each sample, summed in index order from 0.0 as numpy's mean."""
    n_samples, k_pts = samples.shape
    mc = np.empty((n_samples, 3))
    sc = np.empty((n_samples, 3))
    for i in range(n_samples):
        for a in range(3):
            msum = 0.0
            ssum = 0.0
            for k in range(k_pts):
                msum += m[samples[i, k], a]
                ssum += s[samples[i, k], a]
            mc[i, a] = msum / k_pts
            sc[i, a] = ssum / k_pts
    return mc, sc


@numba.njit(cache=True)
def sample_upright_sums(
    m: np.ndarray, s: np.ndarray, samples: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Centroids and the 2D Procrustes sums of each sample of correspondences (model m -> scene s).

    The heading turning sample i's centred model points onto its scene points is
    arctan2(cross[i], dot[i]) (``steps.upright_rigid_transform``). Sums run in index order from 0.0, as
    numpy's mean over the sample axis and its sum over a sample's points do, so the headings are
    bit-identical to the numpy form's.

    Returns:
        (I, 3) model centroids, (I, 3) scene centroids, (I,) sum of a.b and (I,) sum of a x b over the
        sample's horizontal centred coordinates.

    """
    n_samples, k_pts = samples.shape
    mc, sc = _sample_centroids(m, s, samples)
    dot = np.empty(n_samples)
    cross = np.empty(n_samples)
    for i in range(n_samples):
        d = 0.0
        c = 0.0
        for k in range(k_pts):
            a0 = m[samples[i, k], 0] - mc[i, 0]
            a1 = m[samples[i, k], 1] - mc[i, 1]
            b0 = s[samples[i, k], 0] - sc[i, 0]
            b1 = s[samples[i, k], 1] - sc[i, 1]
            d += a0 * b0 + a1 * b1
            c += a0 * b1 - a1 * b0
        dot[i] = d
        cross[i] = c
    return mc, sc, dot, cross


@numba.njit(cache=True)
def sample_cross_covariances(
    m: np.ndarray, s: np.ndarray, samples: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Centroids and Kabsch cross-covariance of each sample of correspondences (model m -> scene s).

    Sample i is the correspondences ``samples[i]`` (3 of them). Sums run in index order from 0.0, as
    numpy's mean over the sample axis and einsum("ikj,ikl->ijl") do.

    Returns:
        (I, 3) model centroids, (I, 3) scene centroids, (I, 3, 3) H = sum_k (m_k - mc)^T (s_k - sc).

    """
    n_samples, k_pts = samples.shape
    mc, sc = _sample_centroids(m, s, samples)
    H = np.empty((n_samples, 3, 3))
    for i in range(n_samples):
        for j in range(3):
            for col in range(3):
                acc = 0.0
                for k in range(k_pts):
                    acc += (m[samples[i, k], j] - mc[i, j]) * (s[samples[i, k], col] - sc[i, col])
                H[i, j, col] = acc
    return mc, sc, H


@numba.njit(cache=True)
def _det3(a: np.ndarray) -> float:  # pragma: no cover - compiled
    return (
        a[0, 0] * (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1])
        - a[0, 1] * (a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0])
        + a[0, 2] * (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0])
    )


@numba.njit(cache=True)
def kabsch_poses(
    U: np.ndarray, Vt: np.ndarray, mc: np.ndarray, sc: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Rotations R = V D U^T and translations t = sc - R mc from the SVDs H = U S Vt.

    D = diag(1, 1, sign det(V U^T)) avoids reflections. U and V are orthogonal to rounding, so
    det(V) det(U) is +-1 within ~1e-15 and has the sign of any accurate det(V U^T).
    Sums run in index order from 0.0, as numpy's einsum does.

    Returns:
        (I, 3, 3) rotations, (I, 3) translations.

    """
    n = U.shape[0]
    R = np.empty((n, 3, 3))
    t = np.empty((n, 3))
    for i in range(n):
        flip = -1.0 if _det3(Vt[i]) * _det3(U[i]) < 0 else 1.0
        for j in range(3):
            for col in range(3):
                acc = 0.0
                for k in range(3):
                    v = Vt[i, k, j] * flip if k == 2 else Vt[i, k, j]
                    acc += v * U[i, col, k]
                R[i, j, col] = acc
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += R[i, j, k] * mc[i, k]
            t[i, j] = sc[i, j] - acc
    return R, t


@numba.njit(cache=True)
def most_inliers(
    R: np.ndarray, t: np.ndarray, m: np.ndarray, s: np.ndarray, inlier2: float
) -> tuple[int, int]:  # pragma: no cover - compiled
    """The candidate transform (R[i], t[i]) with most inliers m -> s (squared residual < inlier2).

    Sequential on purpose: counting the candidates in parallel took RANSAC from 52 to 43 ms per scene
    idle but from 46 to 108 ms with one other busy process on the two cores (docs/performance/matcher.md).

    Returns:
        the first candidate with most inliers and its inlier count (-1, -1 without candidates).

    """
    # one contiguous array per coordinate, so that the loop over correspondences vectorises
    mx, my, mz = m[:, 0].copy(), m[:, 1].copy(), m[:, 2].copy()
    sx, sy, sz = s[:, 0].copy(), s[:, 1].copy(), s[:, 2].copy()
    best, best_count = -1, -1
    for i in range(R.shape[0]):
        r00, r01, r02, t0 = R[i, 0, 0], R[i, 0, 1], R[i, 0, 2], t[i, 0]
        r10, r11, r12, t1 = R[i, 1, 0], R[i, 1, 1], R[i, 1, 2], t[i, 1]
        r20, r21, r22, t2 = R[i, 2, 0], R[i, 2, 1], R[i, 2, 2], t[i, 2]
        count = 0
        for j in range(m.shape[0]):
            d2 = 0.0
            d2 += (r00 * mx[j] + r01 * my[j] + r02 * mz[j] + t0 - sx[j]) ** 2
            d2 += (r10 * mx[j] + r11 * my[j] + r12 * mz[j] + t1 - sy[j]) ** 2
            d2 += (r20 * mx[j] + r21 * my[j] + r22 * mz[j] + t2 - sz[j]) ** 2
            count += d2 < inlier2
        if count > best_count:
            best, best_count = i, count
    return best, best_count
