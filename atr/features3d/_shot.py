"""SHOT352, Signature of Histograms of OrienTations (Tombari, Salti, Di Stefano, ECCV 2010), as PCL's SHOTEstimation.

No maintained Python library has SHOT, so it is written here from the published description and the conventions
listed in the PCL oracle notes (docs/features3d.md):
- 32 volumes = 8 azimuth sectors × 2 shells (split at R/2) × 2 hemispheres of the local reference frame; each volume
  holds shape_bins + 1 = 11 slots of cos(n_q · z_LRF) (the 11th slot is reached only as a main slot).
- Quadrilinear interpolation, additive: the main bin gets (1-|δcos|) + radial + inclination + azimuth weights, each
  neighbouring bin its own fractional weight.
- The point itself (distance 0) and neighbours with a non-finite normal are skipped; fewer than 5 neighbours in
  the radius or an undefined LRF gives a NaN row; the row is L2-normalised.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from atr.errors import InputError
from atr.features3d._lrf import shot_frames
from atr.features3d._neighbours import RadiusSearch
from atr.features3d.config import ShotConfig

_N_VOLUMES = 32
_RAD_45 = math.pi / 4
_RAD_90 = math.pi / 2
_RAD_135 = 3 * math.pi / 4
_RAD_PI_7_8 = 7 * math.pi / 8
_TINY = 1e-30  # PCL zeroes LRF coordinates below this, so that sign tests on the axes are exact
_DIST_EPS = 1e-15


@numba.njit(cache=True)
def _volume_index(x: float, y: float, z: float, distance: float, half_radius: float) -> int:
    """Volume = 4·sector + 2·shell + hemisphere; sector k covers azimuth [-π + kπ/4, -π + (k+1)π/4)."""
    upper_y = (y > 0) or (y == 0.0 and x < 0)
    right_x = (x > 0) or (x == 0.0 and y > 0)
    quadrant = 2 * int(upper_y) + int(
        right_x != upper_y
    )  # 0: x<0,y<0 · 1: x>0,y<0 · 2: x>0,y>0 · 3: x<0,y>0
    index = 8 * quadrant
    if (x * y > 0) or (x == 0.0):
        if abs(x) < abs(y):
            index += 4
    elif abs(x) > abs(y):
        index += 4
    if z > 0:
        index += 1
    if distance > half_radius:
        index += 2
    return index


@numba.njit(cache=True)
def _shot_one(points, normals, centre, frame, idx, d2, radius, nr_bins, out):
    stride = nr_bins + 1
    r_half = radius / 2
    r_quarter = radius / 4
    r_3quarter = 3 * radius / 4
    for t in range(idx.shape[0]):
        j = idx[t]
        nq = normals[j]
        if not (np.isfinite(nq[0]) and np.isfinite(nq[1]) and np.isfinite(nq[2])):
            continue
        distance = math.sqrt(d2[t])
        if abs(distance) < _DIST_EPS:
            continue
        cosine = nq[0] * frame[2, 0] + nq[1] * frame[2, 1] + nq[2] * frame[2, 2]
        cosine = min(1.0, max(-1.0, cosine))
        bin_pos = (1.0 + cosine) * nr_bins / 2
        dx = points[j, 0] - centre[0]
        dy = points[j, 1] - centre[1]
        dz = points[j, 2] - centre[2]
        x = dx * frame[0, 0] + dy * frame[0, 1] + dz * frame[0, 2]
        y = dx * frame[1, 0] + dy * frame[1, 1] + dz * frame[1, 2]
        z = dx * frame[2, 0] + dy * frame[2, 1] + dz * frame[2, 2]
        if abs(x) < _TINY:
            x = 0.0
        if abs(y) < _TINY:
            y = 0.0
        if abs(z) < _TINY:
            z = 0.0
        vol = _volume_index(x, y, z, distance, r_half)
        slot = int(math.floor(bin_pos + 0.5))
        delta = bin_pos - slot
        main = vol * stride + slot
        weight = 1.0 - abs(delta)
        # cosine neighbour: wraps modulo nr_bins, so the extra slot nr_bins is never a neighbour
        if delta > 0:
            out[vol * stride + (slot + 1) % nr_bins] += delta
        else:
            out[vol * stride + (slot - 1 + nr_bins) % nr_bins] -= delta
        # radial neighbour (shell centres at R/4 and 3R/4, unit R/2)
        if distance > r_half:
            rd = (distance - r_3quarter) / r_half
            if distance > r_3quarter:
                weight += 1 - rd
            else:
                weight += 1 + rd
                out[(vol - 2) * stride + slot] -= rd
        else:
            rd = (distance - r_quarter) / r_half
            if distance < r_quarter:
                weight += 1 + rd
            else:
                weight += 1 - rd
                out[(vol + 2) * stride + slot] += rd
        # inclination neighbour (hemisphere centres at 45° and 135° from +z, unit 90°)
        inclination = math.acos(min(1.0, max(-1.0, z / distance)))
        if inclination > _RAD_90 or (abs(inclination - _RAD_90) < _TINY and z <= 0):
            idist = (inclination - _RAD_135) / _RAD_90
            if inclination > _RAD_135:
                weight += 1 - idist
            else:
                weight += 1 + idist
                out[(vol + 1) * stride + slot] -= idist
        else:
            idist = (inclination - _RAD_45) / _RAD_90
            if inclination < _RAD_45:
                weight += 1 + idist
            else:
                weight += 1 - idist
                out[(vol - 1) * stride + slot] += idist
        # azimuth neighbour (sector centres -7π/8 + kπ/4, unit π/4, circular)
        if y != 0.0 or x != 0.0:
            azimuth = math.atan2(y, x)
            sector = vol >> 2
            adist = (azimuth - (-_RAD_PI_7_8 + _RAD_45 * sector)) / _RAD_45
            adist = max(-0.5, min(adist, 0.5))
            if adist > 0:
                weight += 1 - adist
                out[((vol + 4) % _N_VOLUMES) * stride + slot] += adist
            else:
                weight += 1 + adist
                out[((vol - 4 + _N_VOLUMES) % _N_VOLUMES) * stride + slot] -= adist
        out[main] += weight
    norm = 0.0
    for u in range(out.shape[0]):
        norm += out[u] * out[u]
    norm = math.sqrt(norm)
    if norm > 0:
        for u in range(out.shape[0]):
            out[u] /= norm


@numba.njit(cache=True, parallel=True)
def _shot_all(
    points, normals, centres, frames, offsets, indices, sq_dists, radius, nr_bins, min_nb
):
    k = centres.shape[0]
    length = _N_VOLUMES * (nr_bins + 1)
    out = np.full((k, length), np.nan, dtype=np.float32)
    for i in numba.prange(k):
        a = offsets[i]
        b = offsets[i + 1]
        if b - a < min_nb or not np.isfinite(frames[i]).all():
            continue
        if not (
            np.isfinite(centres[i, 0]) and np.isfinite(centres[i, 1]) and np.isfinite(centres[i, 2])
        ):
            continue
        desc = np.zeros(length)
        _shot_one(
            points,
            normals,
            centres[i],
            frames[i],
            indices[a:b],
            sq_dists[a:b],
            radius,
            nr_bins,
            desc,
        )
        out[i] = desc.astype(np.float32)
    return out


def shot_lrf(
    points: np.ndarray, keypoints: np.ndarray, radius: float, config: ShotConfig = ShotConfig()
) -> np.ndarray:
    """SHOT local reference frames; see ``atr.features3d.shot_lrf``."""
    points, keypoints = _check(points, keypoints, radius)
    search = RadiusSearch(points, radius)
    centres = points[keypoints]
    nb = search.query(centres, sort=True)
    return shot_frames(points, centres, nb, radius, config.lrf_min_neighbours)


def shot(
    points: np.ndarray,
    normals: np.ndarray,
    keypoints: np.ndarray,
    radius: float,
    lrf_radius: float | None = None,
    lrf: np.ndarray | None = None,
    config: ShotConfig = ShotConfig(),
) -> np.ndarray:
    """SHOT descriptors, (K, 32·(shape_bins+1)) float32 (352 by default); see ``atr.features3d.describe``.

    Args:
        points: (N, 3) surface, metres.
        normals: (N, 3) unit normals of the surface points.
        keypoints: (K,) int indices into points.
        radius: support radius R, metres.
        lrf_radius: LRF radius, metres (default R).
        lrf: optional precomputed (K, 3, 3) frames (rows x, y, z), e.g. from ``shot_lrf``.
        config: SHOT settings.

    """
    points, keypoints = _check(points, keypoints, radius)
    if normals is None:
        raise InputError("SHOT needs normals; got None")
    normals = np.asarray(normals, dtype=np.float64)
    if normals.shape != points.shape:
        raise InputError(f"normals shape {normals.shape} must equal points shape {points.shape}")
    centres = points[keypoints]
    lrf_r = radius if lrf_radius is None else float(lrf_radius)
    if not lrf_r > 0:
        raise InputError(f"lrf_radius {lrf_r} m must be > 0")
    search = RadiusSearch(points, max(radius, lrf_r))
    nb = search.query(centres, radius=radius, sort=True)
    if lrf is None:
        nb_lrf = nb if lrf_r == radius else search.query(centres, radius=lrf_r, sort=True)
        frames = shot_frames(points, centres, nb_lrf, lrf_r, config.lrf_min_neighbours)
    else:
        frames = np.asarray(lrf, dtype=np.float64)
        if frames.shape != (keypoints.shape[0], 3, 3):
            raise InputError(f"lrf shape {frames.shape} must be ({keypoints.shape[0]}, 3, 3)")
    return _shot_all(
        points,
        normals,
        centres,
        np.ascontiguousarray(frames),
        nb.offsets,
        nb.indices,
        nb.sq_dists,
        float(radius),
        int(config.shape_bins),
        int(config.min_neighbours),
    )


def _check(
    points: np.ndarray, keypoints: np.ndarray, radius: float
) -> tuple[np.ndarray, np.ndarray]:
    points = np.ascontiguousarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(f"points shape {points.shape} must be (N, 3)")
    keypoints = np.asarray(keypoints)
    if keypoints.ndim != 1 or not np.issubdtype(keypoints.dtype, np.integer):
        raise InputError(
            f"keypoints must be a 1-D integer index array, got {keypoints.dtype} {keypoints.shape}"
        )
    if keypoints.size and (keypoints.min() < 0 or keypoints.max() >= points.shape[0]):
        raise InputError(
            f"keypoint indices span [{keypoints.min()}, {keypoints.max()}], expected [0, {points.shape[0] - 1}]"
        )
    if not (np.isfinite(radius) and radius > 0):
        raise InputError(f"support radius {radius} m must be > 0")
    return points, keypoints.astype(np.int64)
