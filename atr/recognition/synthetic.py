"""Small synthetic vehicles and cluttered scenes for tests and benchmarks of the matcher.

These are stand-ins with the proportions of the paper's target and confusers (a T-72-like tank: hull,
turret, long gun; a 6x6 truck; a car), built from boxes and cylinders so that the matcher can be exercised
without the full simulator. Scenes are sampled surfaces seen from an aerial viewpoint (hidden point removal),
with optional Gaussian noise: LIDAR-like when dense, SfM-like when sparse.
"""

from __future__ import annotations

import math

import numpy as np
import open3d as o3d

from atr.recognition.template import hidden_point_removal, sample_mesh_surface

VIEW_RANGE_M = 50.0
"""Distance of a synthetic scene's viewpoint from the scene centre, metres (the paper's shortest range)."""
VIEW_ELEVATION_DEG = 30.0
"""Elevation of a synthetic scene's viewpoint above the horizon, degrees (90 = nadir)."""


def _box(
    size: tuple[float, float, float], centre: tuple[float, float, float]
) -> o3d.geometry.TriangleMesh:
    m = o3d.geometry.TriangleMesh.create_box(*size)
    m.translate(np.asarray(centre) - 0.5 * np.asarray(size))
    return m


def _cylinder(
    radius: float, height: float, centre: tuple[float, float, float], axis: str = "z"
) -> o3d.geometry.TriangleMesh:
    m = o3d.geometry.TriangleMesh.create_cylinder(radius, height, resolution=24, split=1)
    if axis == "x":
        m.rotate(
            o3d.geometry.get_rotation_matrix_from_xyz((0.0, math.pi / 2, 0.0)), center=(0, 0, 0)
        )
    elif axis == "y":
        m.rotate(
            o3d.geometry.get_rotation_matrix_from_xyz((math.pi / 2, 0.0, 0.0)), center=(0, 0, 0)
        )
    m.translate(centre)
    return m


def _merge(parts: list[o3d.geometry.TriangleMesh]) -> tuple[np.ndarray, np.ndarray]:
    out = o3d.geometry.TriangleMesh()
    for p in parts:
        out += p
    return np.asarray(out.vertices, np.float64), np.asarray(out.triangles, np.int64)


def tank_like() -> tuple[np.ndarray, np.ndarray]:
    """A T-72-like tank (hull 6.9 x 3.6 m, turret, 5 m gun, skirts), target frame: x forward, z up, ground z=0.

    Returns:
        vertices (V, 3) metres, triangles (M, 3).

    """
    parts = [
        _box((6.9, 3.4, 0.9), (0.0, 0.0, 0.95)),  # hull
        _box((6.6, 0.3, 0.6), (0.0, 1.75, 0.6)),  # tracks
        _box((6.6, 0.3, 0.6), (0.0, -1.75, 0.6)),
        _box((1.2, 1.2, 0.4), (-2.6, 0.9, 1.6)),  # engine deck boxes
        _box((0.8, 2.6, 0.3), (-3.2, 0.0, 1.5)),  # rear fuel drums
        _cylinder(1.3, 0.7, (0.4, 0.0, 1.75)),  # turret
        _box((0.5, 0.6, 0.3), (0.2, -0.7, 2.25)),  # commander cupola
        _cylinder(0.09, 5.0, (3.3, 0.0, 1.85), axis="x"),  # gun
        _box((0.9, 0.2, 0.5), (1.3, 0.9, 1.8)),  # searchlight / stowage
    ]
    for x in np.linspace(-2.8, 2.8, 6):  # road wheels
        parts.append(_cylinder(0.38, 0.15, (x, 1.95, 0.4), axis="y"))
        parts.append(_cylinder(0.38, 0.15, (x, -1.95, 0.4), axis="y"))
    return _merge(parts)


def truck_like() -> tuple[np.ndarray, np.ndarray]:
    """A 6x6-truck-like confuser (8 m long): cab, flat cargo box, six wheels."""
    parts = [
        _box((2.0, 2.5, 1.9), (3.0, 0.0, 1.95)),  # cab
        _box((5.2, 2.5, 2.2), (-0.8, 0.0, 2.2)),  # cargo box
        _box((7.8, 1.2, 0.4), (0.2, 0.0, 0.9)),  # chassis
    ]
    for x in (3.0, -0.6, -2.2):
        parts.append(_cylinder(0.55, 0.4, (x, 1.1, 0.55), axis="y"))
        parts.append(_cylinder(0.55, 0.4, (x, -1.1, 0.55), axis="y"))
    return _merge(parts)


def car_like() -> tuple[np.ndarray, np.ndarray]:
    """A car-like confuser (4.5 m long): body, cabin, four wheels."""
    parts = [_box((4.5, 1.8, 0.7), (0.0, 0.0, 0.65)), _box((2.3, 1.6, 0.6), (-0.3, 0.0, 1.3))]
    for x in (1.4, -1.4):
        parts.append(_cylinder(0.32, 0.2, (x, 0.85, 0.32), axis="y"))
        parts.append(_cylinder(0.32, 0.2, (x, -0.85, 0.32), axis="y"))
    return _merge(parts)


def pose(x_m: float, y_m: float, yaw_rad: float) -> np.ndarray:
    """World-from-target (4, 4) float64 for a vehicle on the ground at (x, y) with heading yaw."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = (x_m, y_m)
    return T


def clutter_meshes(rng: np.random.Generator, n: int, extent_m: float, keep_out_m: float) -> list:
    """Buildings (boxes) and trees (cylinder trunk + box crown) scattered outside a central keep-out disc."""
    meshes = []
    while len(meshes) < n:
        x, y = rng.uniform(-extent_m, extent_m, 2)
        if math.hypot(x, y) < keep_out_m:
            continue
        if rng.random() < 0.6:
            sx, sy, sz = rng.uniform(4, 10), rng.uniform(4, 10), rng.uniform(3, 8)
            meshes.append(_merge([_box((sx, sy, sz), (x, y, sz / 2))]))
        else:
            h = rng.uniform(3, 6)
            meshes.append(
                _merge([_cylinder(0.2, h, (x, y, h / 2)), _box((2.5, 2.5, 2.0), (x, y, h + 0.5))])
            )
    return meshes


def aerial_viewpoint_m(azimuth_deg: float) -> np.ndarray:
    """(3,) position an `aerial_scene` is seen from, metres: `VIEW_RANGE_M` from the scene centre,
    `VIEW_ELEVATION_DEG` above the horizon, at this azimuth (degrees, counter-clockwise from +x).
    """
    el, az = math.radians(VIEW_ELEVATION_DEG), math.radians(azimuth_deg)
    return VIEW_RANGE_M * np.array(
        [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)]
    )


def aerial_scene(
    vehicles: list[tuple[tuple[np.ndarray, np.ndarray], np.ndarray]],
    *,
    seed: int,
    n_clutter: int = 8,
    extent_m: float = 25.0,
    samples_per_m2: float = 100.0,
    noise_m: float = 0.0,
    azimuth_deg: float = 0.0,
) -> np.ndarray:
    """A scene point cloud: ground, clutter and vehicles, surface-sampled and seen from one aerial viewpoint.

    Args:
        vehicles: ((vertices, triangles), T_world_target) pairs.
        seed: seed for clutter layout, sampling and noise.
        n_clutter: buildings and trees.
        extent_m: half-size of the square ground patch, metres.
        samples_per_m2: surface sampling density before hidden point removal.
        noise_m: standard deviation of Gaussian noise added to every point, metres.
        azimuth_deg: viewpoint azimuth, degrees (the viewpoint is `aerial_viewpoint_m(azimuth_deg)`).

    Returns:
        (N, 3) float64 world points, metres.

    """
    rng = np.random.default_rng(seed)
    clouds = []
    ground = _merge([_box((2 * extent_m, 2 * extent_m, 0.1), (0.0, 0.0, -0.05))])
    keep_out = 8.0
    for (v, f), T in vehicles:
        vw = v @ T[:3, :3].T + T[:3, 3]
        clouds.append(
            sample_mesh_surface(vw, f, samples_per_m2, seed=int(rng.integers(1 << 31)))[0]
        )
    for v, f in [ground, *clutter_meshes(rng, n_clutter, extent_m, keep_out)]:
        clouds.append(sample_mesh_surface(v, f, samples_per_m2, seed=int(rng.integers(1 << 31)))[0])
    pts = np.concatenate(clouds)
    pts = pts[hidden_point_removal(pts, aerial_viewpoint_m(azimuth_deg)[None], 100.0)]
    if noise_m > 0:
        pts = pts + rng.normal(0.0, noise_m, pts.shape)
    return pts
