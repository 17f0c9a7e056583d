"""Numba kernels of our SURF (Bay et al. 2008): box sums, Hessian layers, extrema, orientation, descriptor.

Conventions: integral image ii of shape (H + 1, W + 1), float64, ii[r, c] = sum of img[:r, :c].
Pixel (row r, column c) has its centre at image coordinates (x = c, y = r).
"""

from __future__ import annotations

import math

import numba
import numpy as np

# Bay et al. 2008 §3.3: relative weight of Dxy in det(H) for box filters (0.9^2).
_DXY_WEIGHT = 0.81
# Bay et al. 2008 §4.1-4.2 geometry, in units of the keypoint scale s.
_ORI_RADIUS_S = 6  # orientation samples within a circle of radius 6s
_ORI_HAAR_S = 4  # Haar wavelet side 4s for orientation
_ORI_SIGMA_S = 2.5  # Gaussian weight of orientation samples (OpenSURF's 2.5s)
_ORI_WINDOW_RAD = math.pi / 3.0  # sliding orientation window of 60 degrees
_ORI_STEP_RAD = 0.15  # window positions every 0.15 rad
_DESC_SAMPLES = 20  # 20 x 20 samples over a 20s window
_DESC_SUB = 5  # 5 x 5 samples per subregion -> 4 x 4 subregions
_DESC_HAAR_S = 2  # Haar wavelet side 2s for the descriptor
_DESC_SIGMA_S = 3.3  # Gaussian weight of descriptor samples
_MAX_INTERP_OFFSET = 0.5  # an interpolated extremum further than half a sample belongs elsewhere


@numba.njit(cache=True, inline="always")
def _box_inside(ii, r0, c0, nr, nc):
    return ii[r0 + nr, c0 + nc] - ii[r0, c0 + nc] - ii[r0 + nr, c0] + ii[r0, c0]


@numba.njit(cache=True)
def _box_clamped(ii, r0, c0, nr, nc):
    h = ii.shape[0] - 1
    w = ii.shape[1] - 1
    r1 = min(r0 + nr, h)
    c1 = min(c0 + nc, w)
    r0 = max(r0, 0)
    c0 = max(c0, 0)
    if r1 <= r0 or c1 <= c0:
        return 0.0
    return ii[r1, c1] - ii[r0, c1] - ii[r1, c0] + ii[r0, c0]


@numba.njit(cache=True)
def hessian_layers(ii, sizes, step):
    """det(H) and sign of trace(H) on a grid of every `step` pixels, one layer per filter size.

    Positions whose largest filter would leave the image get det = 0 (never an extremum).
    """
    h = ii.shape[0] - 1
    w = ii.shape[1] - 1
    gh = (h + step - 1) // step
    gw = (w + step - 1) // step
    n_layers = sizes.shape[0]
    det = np.zeros((n_layers, gh, gw), np.float32)
    lap = np.zeros((n_layers, gh, gw), np.int8)
    for k in range(n_layers):
        size = sizes[k]
        lobe = size // 3
        half = (size - 1) // 2
        inv_area = 1.0 / (size * size)
        for gr in range(gh):
            r = gr * step
            if r - half < 0 or r + half >= h:
                continue
            for gc in range(gw):
                c = gc * step
                if c - half < 0 or c + half >= w:
                    continue
                dxx = _box_inside(
                    ii, r - lobe + 1, c - half, 2 * lobe - 1, size
                ) - 3.0 * _box_inside(ii, r - lobe + 1, c - lobe // 2, 2 * lobe - 1, lobe)
                dyy = _box_inside(
                    ii, r - half, c - lobe + 1, size, 2 * lobe - 1
                ) - 3.0 * _box_inside(ii, r - lobe // 2, c - lobe + 1, lobe, 2 * lobe - 1)
                dxy = (
                    _box_inside(ii, r - lobe, c + 1, lobe, lobe)
                    + _box_inside(ii, r + 1, c - lobe, lobe, lobe)
                    - _box_inside(ii, r - lobe, c - lobe, lobe, lobe)
                    - _box_inside(ii, r + 1, c + 1, lobe, lobe)
                )
                dxx *= inv_area
                dyy *= inv_area
                dxy *= inv_area
                det[k, gr, gc] = dxx * dyy - _DXY_WEIGHT * dxy * dxy
                lap[k, gr, gc] = 1 if dxx + dyy >= 0.0 else -1
    return det, lap


@numba.njit(cache=True)
def find_extrema(det, lap, sizes, step, threshold):
    """3x3x3 maxima of det(H) above threshold, refined by a 3D quadratic fit.

    Returns (M, 5) float64 rows: x, y, filter size (interpolated), det response, laplacian sign.
    """
    n_layers, gh, gw = det.shape
    out = np.empty((1024, 5), np.float64)
    n = 0
    size_inc = float(sizes[1] - sizes[0])
    for k in range(1, n_layers - 1):
        for r in range(1, gh - 1):
            for c in range(1, gw - 1):
                v = det[k, r, c]
                if v <= threshold:
                    continue
                is_max = True
                for dk in range(-1, 2):
                    for dr in range(-1, 2):
                        for dc in range(-1, 2):
                            if (dk != 0 or dr != 0 or dc != 0) and det[k + dk, r + dr, c + dc] >= v:
                                is_max = False
                                break
                        if not is_max:
                            break
                    if not is_max:
                        break
                if not is_max:
                    continue
                # A neighbour on the layer's zero border means the quadratic fit is meaningless.
                if det[k, r - 1, c] == 0.0 or det[k, r + 1, c] == 0.0:
                    continue
                if det[k, r, c - 1] == 0.0 or det[k, r, c + 1] == 0.0:
                    continue
                gx = 0.5 * (det[k, r, c + 1] - det[k, r, c - 1])
                gy = 0.5 * (det[k, r + 1, c] - det[k, r - 1, c])
                gs = 0.5 * (det[k + 1, r, c] - det[k - 1, r, c])
                hxx = det[k, r, c + 1] - 2.0 * v + det[k, r, c - 1]
                hyy = det[k, r + 1, c] - 2.0 * v + det[k, r - 1, c]
                hss = det[k + 1, r, c] - 2.0 * v + det[k - 1, r, c]
                hxy = 0.25 * (
                    det[k, r + 1, c + 1]
                    - det[k, r + 1, c - 1]
                    - det[k, r - 1, c + 1]
                    + det[k, r - 1, c - 1]
                )
                hxs = 0.25 * (
                    det[k + 1, r, c + 1]
                    - det[k + 1, r, c - 1]
                    - det[k - 1, r, c + 1]
                    + det[k - 1, r, c - 1]
                )
                hys = 0.25 * (
                    det[k + 1, r + 1, c]
                    - det[k + 1, r - 1, c]
                    - det[k - 1, r + 1, c]
                    + det[k - 1, r - 1, c]
                )
                H = np.array([[hxx, hxy, hxs], [hxy, hyy, hys], [hxs, hys, hss]])
                g = np.array([gx, gy, gs])
                if abs(np.linalg.det(H)) < 1e-30:
                    continue
                off = -np.linalg.solve(H, g)
                if (
                    abs(off[0]) >= _MAX_INTERP_OFFSET
                    or abs(off[1]) >= _MAX_INTERP_OFFSET
                    or abs(off[2]) >= _MAX_INTERP_OFFSET
                ):
                    continue
                if n == out.shape[0]:
                    bigger = np.empty((2 * n, 5), np.float64)
                    bigger[:n] = out
                    out = bigger
                out[n, 0] = (c + off[0]) * step
                out[n, 1] = (r + off[1]) * step
                out[n, 2] = sizes[k] + off[2] * size_inc
                out[n, 3] = v
                out[n, 4] = lap[k, r, c]
                n += 1
    return out[:n].copy()


@numba.njit(cache=True, inline="always")
def _haar_x(ii, r, c, side):
    half = side // 2
    return _box_clamped(ii, r - half, c, side, half) - _box_clamped(
        ii, r - half, c - half, side, half
    )


@numba.njit(cache=True, inline="always")
def _haar_y(ii, r, c, side):
    half = side // 2
    return _box_clamped(ii, r, c - half, half, side) - _box_clamped(
        ii, r - half, c - half, half, side
    )


@numba.njit(cache=True)
def _orientation(ii, x, y, s):
    n_max = (2 * _ORI_RADIUS_S + 1) ** 2
    rx = np.empty(n_max)
    ry = np.empty(n_max)
    ang = np.empty(n_max)
    side = max(2, int(round(_ORI_HAAR_S * s)))
    side += side % 2
    n = 0
    inv_two_sigma2 = 1.0 / (2.0 * _ORI_SIGMA_S * _ORI_SIGMA_S)
    for i in range(-_ORI_RADIUS_S, _ORI_RADIUS_S + 1):
        for j in range(-_ORI_RADIUS_S, _ORI_RADIUS_S + 1):
            if i * i + j * j >= _ORI_RADIUS_S * _ORI_RADIUS_S:
                continue
            weight = math.exp(-(i * i + j * j) * inv_two_sigma2)
            r = int(round(y + j * s))
            c = int(round(x + i * s))
            dx = weight * _haar_x(ii, r, c, side)
            dy = weight * _haar_y(ii, r, c, side)
            rx[n] = dx
            ry[n] = dy
            ang[n] = math.atan2(dy, dx)
            n += 1
    best = -1.0
    best_angle = 0.0
    a0 = -math.pi
    while a0 < math.pi:
        a1 = a0 + _ORI_WINDOW_RAD
        sx = 0.0
        sy = 0.0
        for m in range(n):
            a = ang[m]
            # The window may wrap past +pi.
            inside = (a0 <= a < a1) or (a1 > math.pi and a < a1 - 2.0 * math.pi)
            if inside:
                sx += rx[m]
                sy += ry[m]
        mag = sx * sx + sy * sy
        if mag > best:
            best = mag
            best_angle = math.atan2(sy, sx)
        a0 += _ORI_STEP_RAD
    return best_angle


@numba.njit(cache=True)
def describe(ii, keypoints, upright):
    """Orientation (unless upright) and the 64-D descriptor of each keypoint (x, y, s, _).

    Returns (angles (N,), descriptors (N, 64) float32, unit length).
    """
    n_kp = keypoints.shape[0]
    angles = np.zeros(n_kp)
    desc = np.zeros((n_kp, 64), np.float32)
    inv_two_sigma2 = 1.0 / (2.0 * _DESC_SIGMA_S * _DESC_SIGMA_S)
    for k in range(n_kp):
        x = keypoints[k, 0]
        y = keypoints[k, 1]
        s = keypoints[k, 2]
        theta = 0.0 if upright else _orientation(ii, x, y, s)
        angles[k] = theta
        co = math.cos(theta)
        si = math.sin(theta)
        side = max(2, int(round(_DESC_HAAR_S * s)))
        side += side % 2
        acc = np.zeros(64)
        for a in range(_DESC_SAMPLES):
            u = a + 0.5 - 0.5 * _DESC_SAMPLES  # in units of s
            for b in range(_DESC_SAMPLES):
                v = b + 0.5 - 0.5 * _DESC_SAMPLES
                px = x + s * (u * co - v * si)
                py = y + s * (u * si + v * co)
                r = int(round(py))
                c = int(round(px))
                dx = _haar_x(ii, r, c, side)
                dy = _haar_y(ii, r, c, side)
                weight = math.exp(-(u * u + v * v) * inv_two_sigma2)
                du = weight * (dx * co + dy * si)
                dv = weight * (-dx * si + dy * co)
                cell = 4 * ((b // _DESC_SUB) * 4 + a // _DESC_SUB)
                acc[cell] += du
                acc[cell + 1] += dv
                acc[cell + 2] += abs(du)
                acc[cell + 3] += abs(dv)
        norm = math.sqrt(np.sum(acc * acc))
        if norm > 0.0:
            for m in range(64):
                desc[k, m] = acc[m] / norm
    return angles, desc
