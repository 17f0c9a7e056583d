"""Unique Shape Context (Tombari, Salti, Di Stefano, 3DOR 2010), as PCL's UniqueShapeContext.

3DSC's binning and weights (see ``_3dsc``) in the SHOT local reference frame instead of a normal plus a random
azimuth origin, so one descriptor per point and no azimuth rotations at matching time. No normals are used: the
local axis is the LRF's z. PCL's layout is 14 azimuth × 14 elevation × 10 radial = 1960 bins; the USC paper (and
the ATR paper's Table III) reuse 3DSC's 12 × 11 × 15 = 1980, available through the bin parameters.
"""

from __future__ import annotations

import numpy as np

from atr.errors import InputError
from atr.features3d._3dsc import _with_bins, shape_context_histograms
from atr.features3d._lrf import shot_frames
from atr.features3d._neighbours import RadiusSearch
from atr.features3d._shot import _check
from atr.features3d.config import USC_DEFAULT, ShapeContextConfig, ShotConfig


def usc(
    points: np.ndarray,
    keypoints: np.ndarray,
    radius: float,
    lrf_radius: float | None = None,
    minimal_radius: float | None = None,
    point_density_radius: float | None = None,
    azimuth_bins: int | None = None,
    elevation_bins: int | None = None,
    radial_bins: int | None = None,
    config: ShapeContextConfig = USC_DEFAULT,
) -> np.ndarray:
    """USC descriptors, (K, 1960) float32 by default; see ``atr.features3d.describe``.

    Args:
        points: (N, 3) surface, metres.
        keypoints: (K,) int indices into points.
        radius: support radius R, metres.
        lrf_radius: SHOT LRF radius, metres (default R).
        minimal_radius: first radial edge, metres (default config.k_minimal_radius · R).
        point_density_radius: metres (default config.k_point_density_radius · R).
        azimuth_bins, elevation_bins, radial_bins: override the config's bins (12, 11, 15 gives 1980).
        config: defaults of the above.

    """
    points, keypoints = _check(points, keypoints, radius)
    cfg = _with_bins(config, azimuth_bins, elevation_bins, radial_bins)
    lrf_r = radius if lrf_radius is None else float(lrf_radius)
    if not lrf_r > 0:
        raise InputError(f"lrf_radius {lrf_r} m must be > 0")
    r_min = cfg.k_minimal_radius * radius if minimal_radius is None else float(minimal_radius)
    r_dens = (
        cfg.k_point_density_radius * radius
        if point_density_radius is None
        else float(point_density_radius)
    )
    centres = points[keypoints]
    search = RadiusSearch(points, max(radius, lrf_r))
    nb = search.query(centres, radius=radius, sort=True)
    nb_lrf = nb if lrf_r == radius else search.query(centres, radius=lrf_r, sort=True)
    frames = shot_frames(points, centres, nb_lrf, lrf_r, ShotConfig().lrf_min_neighbours)
    return shape_context_histograms(points, centres, frames, nb, radius, r_min, r_dens, cfg)
