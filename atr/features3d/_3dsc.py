"""3D Shape Context (Frome, Huber, Kolluri, Bülow, Malik, ECCV 2004), as PCL's ShapeContext3DEstimation.

No maintained Python library has 3DSC, so it is written here, with the shape-context binning shared with USC:
- the support sphere of radius R around p is cut into azimuth × elevation × log-radial bins about a local axis
  (the normal n at p); the log-spaced radial edges start at minimal_radius (edges stored in float32 as PCL does);
- each neighbour q ≠ p adds 1 / (ρ(q) · V^(1/3)) to its bin, ρ(q) = number of surface points within
  point_density_radius of q (q included) and V the bin's volume;
- a value on an edge goes to the lower bin (PCL's "first edge >= value"); the flattened index is
  azimuth·(E·J) + elevation·J + radial (radial fastest).

The azimuth origin (x axis) of released PCL (1.13 … 1.15.1) is random: one mt19937 seeded with 12345, three
float uniforms per described point, in keypoint order, made orthogonal to n. ``x_axis="random"`` reproduces that
sequence bit for bit (so a descriptor depends on which keypoints come before it: describe all keypoints of a
cloud in one call). ``x_axis="farthest"`` is PCL master's deterministic axis: the farthest neighbour projected on
the tangent plane. Frome et al. remove the azimuth ambiguity at matching time by comparing the L azimuthal
rotations of a descriptor (``azimuth_rotations``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from atr.errors import ConfigError, InputError
from atr.features3d._neighbours import Neighbourhoods, RadiusSearch
from atr.features3d._shot import _check
from atr.features3d.config import (
    SC3D_DEFAULT,
    ShapeContext3dParams,
    ShapeContextConfig,
    ShapeContextParams,
)

_TANGENT_EPS = 1e-6  # PCL master: below this norm the projected farthest neighbour cannot define x


def bin_edges(
    radius: float, minimal_radius: float, config: ShapeContextConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Radial, elevation and azimuth edges and the per-bin weight 1 / V^(1/3).

    Returns:
        radial (J+1,) metres, elevation (E+1,) degrees, azimuth (L+1,) degrees, all float32 values held in
        float64; inv_cbrt_volume (L·E·J,) float64 in the flattened bin order.

    """
    J, E, L = config.radial_bins, config.elevation_bins, config.azimuth_bins
    j = np.arange(J + 1, dtype=np.float64)
    radial = np.exp(np.log(minimal_radius) + (j / J) * np.log(radius / minimal_radius)).astype(
        np.float32
    )
    elevation = (np.arange(E + 1) * (180.0 / E)).astype(np.float32)
    azimuth = (np.arange(L + 1) * (360.0 / L)).astype(np.float32)
    r = radial.astype(np.float64)
    d_r = (r[1:] ** 3 - r[:-1] ** 3) / 3.0
    th = np.deg2rad(elevation.astype(np.float64))
    d_th = np.cos(th[:-1]) - np.cos(th[1:])
    d_phi = np.deg2rad(float(azimuth[1]) - float(azimuth[0]))
    volume = d_phi * d_th[:, None] * d_r[None, :]  # (E, J)
    inv = np.tile((1.0 / np.cbrt(volume)).reshape(-1), L)
    return r, elevation.astype(np.float64), azimuth.astype(np.float64), inv


@numba.njit(cache=True)
def _lower_bin(edges: np.ndarray, value: float) -> int:
    """Index of the first edge >= value, searched from edge 1, minus 1; the last bin when beyond the last edge."""
    n = edges.shape[0] - 1
    for t in range(1, n + 1):
        if value <= edges[t]:
            return t - 1
    return n - 1


@numba.njit(cache=True, parallel=True)
def _shape_context_all(
    points,
    centres,
    frames,
    offsets,
    indices,
    sq_dists,
    density,
    r_edges,
    th_edges,
    phi_edges,
    inv_vol,
    n_el,
    n_rad,
    min_nb,
):
    k = centres.shape[0]
    length = inv_vol.shape[0]
    out = np.full((k, length), np.nan, dtype=np.float32)
    for i in numba.prange(k):
        a = offsets[i]
        b = offsets[i + 1]
        if b - a < min_nb or not np.isfinite(frames[i]).all():
            continue
        p = centres[i]
        if not (np.isfinite(p[0]) and np.isfinite(p[1]) and np.isfinite(p[2])):
            continue
        xa = frames[i, 0]
        nz = frames[i, 2]
        desc = np.zeros(length)
        for t in range(a, b):
            if sq_dists[t] == 0.0:
                continue
            q = points[indices[t]]
            v = q - p
            r = math.sqrt(sq_dists[t])
            vn = v[0] * nz[0] + v[1] * nz[1] + v[2] * nz[2]
            proj = v - vn * nz
            pn = math.sqrt(proj[0] ** 2 + proj[1] ** 2 + proj[2] ** 2)
            if pn > 0:
                proj = proj / pn
            cx = xa[1] * proj[2] - xa[2] * proj[1]
            cy = xa[2] * proj[0] - xa[0] * proj[2]
            cz = xa[0] * proj[1] - xa[1] * proj[0]
            phi = math.degrees(
                math.atan2(
                    math.sqrt(cx * cx + cy * cy + cz * cz),
                    xa[0] * proj[0] + xa[1] * proj[1] + xa[2] * proj[2],
                )
            )
            if cx * nz[0] + cy * nz[1] + cz * nz[2] < 0:
                phi = 360.0 - phi
            theta = math.degrees(math.acos(min(1.0, max(-1.0, vn / r))))
            jr = _lower_bin(r_edges, r)
            ke = _lower_bin(th_edges, theta)
            la = _lower_bin(phi_edges, phi)
            rho = density[indices[t]]
            if rho <= 0:
                continue
            idx = la * n_el * n_rad + ke * n_rad + jr
            desc[idx] += inv_vol[idx] / rho
        out[i] = desc.astype(np.float32)
    return out


@dataclass(frozen=True)
class ShapeContextRadii:
    """The radii of a shape-context histogram, metres.

    Attributes:
        radius: support radius R, the last radial edge.
        minimal_radius: first radial edge, in (0, R).
        point_density_radius: radius of the local density ρ(q) that weights each neighbour (> 0).

    """

    radius: float
    minimal_radius: float
    point_density_radius: float

    def __post_init__(self) -> None:
        if not 0 < self.minimal_radius < self.radius:
            raise ConfigError(
                f"minimal_radius {self.minimal_radius} m must be in (0, {self.radius}) m"
            )
        if not self.point_density_radius > 0:
            raise ConfigError(f"point_density_radius {self.point_density_radius} m must be > 0")


def resolve_params(
    radius: float, params: ShapeContextParams, config: ShapeContextConfig
) -> tuple[ShapeContextRadii, ShapeContextConfig]:
    """The radii and bins of one call: each parameter given in ``params``, else the config's default.

    Args:
        radius: support radius R, metres.
        params: per-call overrides (None fields take the config's).
        config: bins and the default radii as fractions of R.

    Returns:
        (radii in metres, the config with the bins overridden).

    Raises:
        ConfigError: minimal radius not in (0, R), density radius not > 0, or a bin count < 1.

    """
    cfg = _with_bins(config, params.azimuth_bins, params.elevation_bins, params.radial_bins)
    r_min = (
        cfg.k_minimal_radius * radius
        if params.minimal_radius is None
        else float(params.minimal_radius)
    )
    r_dens = (
        cfg.k_point_density_radius * radius
        if params.point_density_radius is None
        else float(params.point_density_radius)
    )
    return ShapeContextRadii(radius, r_min, r_dens), cfg


def shape_context_histograms(
    points: np.ndarray,
    centres: np.ndarray,
    frames: np.ndarray,
    nb: Neighbourhoods,
    radii: ShapeContextRadii,
    config: ShapeContextConfig,
) -> np.ndarray:
    """Shape-context histograms of 3DSC/USC for given frames (rows x, ·, z = the local axis).

    Args:
        points: (N, 3) float64 surface, metres.
        centres: (K, 3) float64 feature points, metres.
        frames: (K, 3, 3) float64; rows 0 and 2 are used (x and z); a non-finite frame gives a NaN row.
        nb: neighbourhoods of the centres within ``radii.radius``.
        radii: support, minimal and point-density radii, metres.
        config: bins and minimum neighbour count.

    Returns:
        (K, L·E·J) float32.

    """
    r_e, th_e, phi_e, inv = bin_edges(radii.radius, radii.minimal_radius, config)
    density = np.zeros(points.shape[0], dtype=np.float64)
    used = np.unique(nb.indices)
    if used.size:
        density[used] = RadiusSearch(points, radii.point_density_radius).count(points[used])
    return _shape_context_all(
        points,
        centres,
        np.ascontiguousarray(frames, dtype=np.float64),
        nb.offsets,
        nb.indices,
        nb.sq_dists,
        density,
        r_e,
        th_e,
        phi_e,
        inv,
        config.elevation_bins,
        config.radial_bins,
        config.min_neighbours,
    )


def _mt19937_uniforms(seed: int, count: int) -> np.ndarray:
    """``count`` floats of std::uniform_real_distribution<float>(0, 1) over std::mt19937(seed) (libstdc++)."""
    bitgen = np.random.MT19937()
    bitgen._legacy_seeding(seed)  # std::mt19937's seeding, not numpy's SeedSequence
    raw = bitgen.random_raw(count).astype(np.uint32)
    u = (raw.astype(np.float32) / np.float32(2.0**32)).astype(np.float32)
    return np.minimum(u, np.nextafter(np.float32(1), np.float32(0)))


def _random_x_axes(normals_k: np.ndarray, drawn: np.ndarray, seed: int) -> np.ndarray:
    x = np.full(normals_k.shape, np.nan)
    u = _mt19937_uniforms(seed, 3 * int(drawn.sum())).reshape(-1, 3).astype(np.float64)
    n = normals_k[drawn]
    # Make the draw orthogonal to n by solving for the component along the first non-zero normal axis (z, y, x).
    for axis, others in ((2, (0, 1)), (1, (0, 2)), (0, (1, 2))):
        sel = n[:, axis] != 0
        if axis == 1:
            sel &= n[:, 2] == 0
        elif axis == 0:
            sel &= (n[:, 2] == 0) & (n[:, 1] == 0)
        a, b = others
        u[sel, axis] = -(n[sel, a] * u[sel, a] + n[sel, b] * u[sel, b]) / n[sel, axis]
    x[drawn] = u / np.linalg.norm(u, axis=1, keepdims=True)
    return x


def _farthest_x_axes(
    points: np.ndarray, centres: np.ndarray, normals_k: np.ndarray, nb: Neighbourhoods
) -> np.ndarray:
    x = np.full(centres.shape, np.nan)
    counts = nb.counts()
    for i in np.flatnonzero(counts > 0):
        a, b = nb.offsets[i], nb.offsets[i + 1]
        d2 = nb.sq_dists[a:b]
        far = nb.indices[a + int(np.argmax(d2))]
        n = normals_k[i]
        for v in (points[far] - centres[i], np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):
            t = v - (v @ n) * n
            norm = np.linalg.norm(t)
            if norm >= _TANGENT_EPS:
                x[i] = t / norm
                break
    return x


def shape_context_3d(
    points: np.ndarray,
    normals: np.ndarray,
    keypoints: np.ndarray,
    radius: float,
    params: ShapeContext3dParams = ShapeContext3dParams(),
    config: ShapeContextConfig = SC3D_DEFAULT,
) -> np.ndarray:
    """3DSC descriptors, (K, 1980) float32 by default: ``describe("3dsc", ...)``, whose keywords fill
    ``params`` (None fields take ``config``'s defaults). The normal at a keypoint is its local axis.
    """
    points, keypoints = _check(points, keypoints, radius)
    if normals is None:
        raise InputError("3DSC needs normals; got None")
    normals = np.asarray(normals, dtype=np.float64)
    if normals.shape != points.shape:
        raise InputError(f"normals shape {normals.shape} must equal points shape {points.shape}")
    radii, cfg = resolve_params(radius, params, config)
    centres = points[keypoints]
    nb = RadiusSearch(points, radius).query(centres, sort=True)
    n_k = normals[keypoints]
    finite_n = np.isfinite(n_k).all(axis=1) & np.isfinite(centres).all(axis=1)
    # PCL draws for every point with at least one neighbour and a finite normal, described or not.
    drawn = finite_n & (nb.counts() > 0)
    if params.x_axis == "random":
        x = _random_x_axes(n_k, drawn, cfg.seed if params.seed is None else int(params.seed))
    else:
        x = _farthest_x_axes(points, centres, n_k, nb)
    frames = np.stack([x, np.cross(n_k, x), n_k], axis=1)
    return shape_context_histograms(points, centres, frames, nb, radii, cfg)


def azimuth_rotations(
    descriptors: np.ndarray, azimuth_bins: int = SC3D_DEFAULT.azimuth_bins
) -> np.ndarray:
    """All cyclic azimuth shifts of shape-context descriptors (Frome et al.'s L rotations for matching).

    Args:
        descriptors: (K, L·E·J) float.
        azimuth_bins: L.

    Returns:
        (L, K, L·E·J): entry s is each descriptor rotated by s azimuth sectors.

    """
    d = np.asarray(descriptors)
    k, length = d.shape
    if length % azimuth_bins:
        raise InputError(
            f"descriptor length {length} is not a multiple of {azimuth_bins} azimuth bins"
        )
    blocks = d.reshape(k, azimuth_bins, -1)
    return np.stack([np.roll(blocks, s, axis=1).reshape(k, length) for s in range(azimuth_bins)])


def _with_bins(
    config: ShapeContextConfig, az: int | None, el: int | None, rad: int | None
) -> ShapeContextConfig:
    return ShapeContextConfig(
        azimuth_bins=config.azimuth_bins if az is None else int(az),
        elevation_bins=config.elevation_bins if el is None else int(el),
        radial_bins=config.radial_bins if rad is None else int(rad),
        k_minimal_radius=config.k_minimal_radius,
        k_point_density_radius=config.k_point_density_radius,
        min_neighbours=config.min_neighbours,
        seed=config.seed,
    )
