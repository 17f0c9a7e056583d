"""Unique Shape Context (Tombari, Salti, Di Stefano, 3DOR 2010), as PCL's UniqueShapeContext.

3DSC's binning and weights (see ``_3dsc``) in the SHOT local reference frame instead of a normal plus a random
azimuth origin, so one descriptor per point and no azimuth rotations at matching time. No normals are used: the
local axis is the LRF's z. PCL's layout is 14 azimuth × 14 elevation × 10 radial = 1960 bins; the USC paper (and
the ATR paper's Table III) reuse 3DSC's 12 × 11 × 15 = 1980, available through the bin parameters.
"""

from __future__ import annotations

import numpy as np

from atr.errors import InputError
from atr.features3d._3dsc import resolve_params, shape_context_histograms
from atr.features3d._lrf import shot_frames
from atr.features3d._neighbours import RadiusSearch
from atr.features3d._shot import _check
from atr.features3d.config import USC_DEFAULT, ShapeContextConfig, ShotConfig, UscParams


def usc(
    points: np.ndarray,
    keypoints: np.ndarray,
    radius: float,
    params: UscParams = UscParams(),
    config: ShapeContextConfig = USC_DEFAULT,
) -> np.ndarray:
    """USC descriptors, (K, 1960) float32 by default (12, 11, 15 bins give the paper's 1980):
    ``describe("usc", ...)``, whose keywords fill ``params`` (None fields take ``config``'s defaults,
    the LRF radius R).
    """
    points, keypoints = _check(points, keypoints, radius)
    lrf_r = radius if params.lrf_radius is None else float(params.lrf_radius)
    if not lrf_r > 0:
        raise InputError(f"lrf_radius {lrf_r} m must be > 0")
    radii, cfg = resolve_params(radius, params, config)
    centres = points[keypoints]
    search = RadiusSearch(points, max(radius, lrf_r))
    nb = search.query(centres, radius=radius, sort=True)
    nb_lrf = nb if lrf_r == radius else search.query(centres, radius=lrf_r, sort=True)
    frames = shot_frames(points, centres, nb_lrf, lrf_r, ShotConfig().lrf_min_neighbours)
    return shape_context_histograms(points, centres, frames, nb, radii, cfg)
