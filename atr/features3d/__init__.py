"""3D local descriptors of the ATR pipeline (paper Table III): SHOT, USC, 3DSC, FPFH, RoPS, HoD, HoD-S.

Public surface (a contract used by tools outside the package):
- ``describe(name, points, normals, keypoints, radius, **params)``: one entry point for all seven descriptors;
- ``estimate_normals(points, k=None, radius=None, viewpoint=(0, 0, 0))``;
- ``shot_lrf(points, keypoints, radius)``: the SHOT local reference frame;
- ``DESCRIPTOR_LENGTHS``, ``DESCRIPTOR_NAMES``, ``description_radius`` (the ρ·r table of §III-B).

Conventions follow PCL (see docs/features3d.md): radius neighbourhoods include the keypoint itself, a keypoint
that cannot be described gets a NaN row.
"""

from __future__ import annotations

import importlib
from dataclasses import fields
from typing import Any

import numpy as np

from atr.errors import ConfigError, InputError
from atr.features3d._normals import estimate_normals_and_curvature
from atr.features3d.config import (
    DESCRIPTION_RADII,
    DESCRIPTOR_LENGTHS,
    DESCRIPTOR_NAMES,
    NormalConfig,
    ShapeContext3dParams,
    ShapeContextParams,
    ShotConfig,
    UscParams,
    description_radius,
)

__all__ = [
    "DESCRIPTION_RADII",
    "DESCRIPTOR_LENGTHS",
    "DESCRIPTOR_NAMES",
    "describe",
    "description_radius",
    "estimate_normals",
    "is_available",
    "shot_lrf",
]

# name -> (module, function, uses normals). Modules are imported on first use: the FPFH, RoPS and HoD modules
# are written separately and may be absent from a checkout.
_DISPATCH: dict[str, tuple[str, str, bool]] = {
    "shot": ("atr.features3d._shot", "shot", True),
    "usc": ("atr.features3d._usc", "usc", False),
    "3dsc": ("atr.features3d._3dsc", "shape_context_3d", True),
    "fpfh": ("atr.features3d._fpfh", "fpfh", True),
    "rops": ("atr.features3d._rops", "rops", False),
    "hod": ("atr.features3d._hod", "hod", False),
    "hod-s": ("atr.features3d._hod", "hod", False),
}

# Descriptors whose PCL parameters travel as one typed object: describe() builds it from its keywords.
_PARAMS: dict[str, type[ShapeContextParams]] = {"usc": UscParams, "3dsc": ShapeContext3dParams}


def estimate_normals(
    points: np.ndarray,
    k: int | None = None,
    radius: float | None = None,
    viewpoint: tuple[float, float, float] | np.ndarray = (0.0, 0.0, 0.0),
) -> np.ndarray:
    """Normals by least-squares plane fit, flipped toward a viewpoint (PCL's NormalEstimation).

    Args:
        points: (N, 3) float, metres. Non-finite points get NaN normals and are never neighbours.
        k: plane fit on the k nearest neighbours, the point itself included. With neither k nor radius, k = 6
            (paper §II-B-2).
        radius: plane fit on the neighbours within this radius, metres (PCL conformance). Not with k.
        viewpoint: (3,) metres; each normal n at p is flipped if (viewpoint - p)·n < 0.

    Returns:
        (N, 3) float64 unit normals; NaN rows where fewer than 3 neighbours.

    Raises:
        ConfigError: both k and radius given, k < 3, or radius <= 0.
        InputError: points not (N, 3), or viewpoint not finite.

    """
    normals, _ = estimate_normals_and_curvature(
        points, k=k, radius=radius, viewpoint=viewpoint, config=NormalConfig()
    )
    return normals


def shot_lrf(points: np.ndarray, keypoints: np.ndarray, radius: float) -> np.ndarray:
    """SHOT local reference frames (Tombari et al. 2010; PCL's SHOTLocalReferenceFrameEstimation).

    Args:
        points: (N, 3) float, metres: the surface.
        keypoints: (K,) int indices into points.
        radius: LRF radius, metres (> 0).

    Returns:
        (K, 3, 3) float64, rows = x, y, z axes in the cloud frame; NaN where fewer than 5 neighbours other than
        the point itself.

    Raises:
        InputError: bad shapes, indices out of range, radius <= 0.

    """
    from atr.features3d._shot import shot_lrf as _shot_lrf

    return _shot_lrf(points, keypoints, radius, ShotConfig())


def is_available(name: str) -> bool:
    """True if the module implementing descriptor ``name`` is present in this checkout."""
    if name not in _DISPATCH:
        raise ConfigError(f"descriptor {name!r} is not one of {DESCRIPTOR_NAMES}")
    try:
        importlib.import_module(_DISPATCH[name][0])
    except ModuleNotFoundError:
        return False
    return True


def describe(
    name: str,
    points: np.ndarray,
    normals: np.ndarray | None,
    keypoints: np.ndarray,
    radius: float,
    **params: Any,
) -> np.ndarray:
    """Describe keypoints of a cloud with one of the seven local descriptors.

    Args:
        name: "shot", "usc", "3dsc", "fpfh", "rops", "hod" or "hod-s".
        points: (N, 3) float, metres: the search surface.
        normals: (N, 3) unit normals of ``points`` (SHOT, 3DSC, FPFH need them); may be None for the others.
        keypoints: (K,) int indices into points.
        radius: description (support) radius R, metres; see ``description_radius``.
        **params: descriptor parameters with PCL's meaning and names:
            shot: lrf_radius (m, default R), lrf ((K, 3, 3) precomputed frames).
            usc: lrf_radius (m, default R), minimal_radius (m, default R/10), point_density_radius (m, default
                R/5), azimuth_bins, elevation_bins, radial_bins (default 14, 14, 10).
            3dsc: minimal_radius, point_density_radius (as USC), seed (int, default 12345: PCL's mt19937 seed of
                the random x axis), x_axis ("random" = released PCL, "farthest" = PCL master), azimuth_bins,
                elevation_bins, radial_bins (default 12, 11, 15).
            rops: triangles ((M, 3) vertex indices), partition_bins (5), rotations (3).

    Returns:
        (K, length) float32; a NaN row for a keypoint that cannot be described (too few neighbours, undefined
        frame, non-finite point or normal).

    Raises:
        ConfigError: unknown name or parameter, or the descriptor's module is not installed.
        InputError: bad shapes, indices out of range, radius <= 0, missing normals where needed.

    """
    if name not in _DISPATCH:
        raise ConfigError(f"descriptor {name!r} is not one of {DESCRIPTOR_NAMES}")
    module_name, func_name, needs_normals = _DISPATCH[name]
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name != module_name:
            raise
        raise ConfigError(
            f"descriptor {name!r} is not implemented in this checkout ({module_name})"
        ) from exc
    func = getattr(module, func_name)
    if needs_normals and normals is None:
        raise InputError(f"descriptor {name!r} needs normals; got None")
    keypoints = np.asarray(keypoints)
    if name in _PARAMS:
        params = {"params": _typed_params(name, params)}
    if name in ("hod", "hod-s"):
        out = func(points, keypoints, radius, short=(name == "hod-s"), **params)
    elif needs_normals:
        out = func(points, normals, keypoints, radius, **params)
    else:
        out = func(points, keypoints, radius, **params)
    return np.asarray(out, dtype=np.float32)


def _typed_params(name: str, params: dict[str, Any]) -> ShapeContextParams:
    """The params object of descriptor ``name`` from describe()'s keywords."""
    cls = _PARAMS[name]
    names = [f.name for f in fields(cls)]
    unknown = sorted(set(params) - set(names))
    if unknown:
        raise ConfigError(
            f"descriptor {name!r} has no parameter {unknown}; expected some of {names}"
        )
    return cls(**params)
