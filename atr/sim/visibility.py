"""Target visibility by ray casting: which share of the target's surface a camera sees.

visible_fraction = (target surface samples seen from the camera, inside the image) / (samples the
camera would see with every other object removed). It is 1 for a target in the open and fully in the
frame, 0 behind a building, and in between when partly hidden or partly outside the image.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d

from atr.sim.config import SimConfig
from atr.sim.mesh import Mesh

# a surface sample counts as seen if the first hit lies within this of it (plus 1e-4 x range)
_EPS_M = 0.03


def raycasting_scene(meshes: list[Mesh]) -> tuple[o3d.t.geometry.RaycastingScene, list[int]]:
    """An Open3D RaycastingScene with one geometry per mesh; returns the scene and geometry ids."""
    scene = o3d.t.geometry.RaycastingScene()
    ids = []
    for m in meshes:
        ids.append(
            scene.add_triangles(
                o3d.core.Tensor(m.vertices.astype(np.float32)),
                o3d.core.Tensor(m.triangles.astype(np.uint32)),
            )
        )
    return scene, ids


def target_samples(target_local: Mesh, T_world_target: np.ndarray, n: int) -> np.ndarray:
    """(n, 3) fixed surface samples of the target in the world frame (seeded by n only)."""
    pts = target_local.sample_surface(n, np.random.default_rng([n, 0x7A46]))
    return pts @ T_world_target[:3, :3].T + T_world_target[:3, 3]


def first_hit_reaches(
    scene: o3d.t.geometry.RaycastingScene, origins: np.ndarray, points: np.ndarray
) -> np.ndarray:
    """Whether the first surface along each ray origin -> point is the point itself.

    Args:
        origins: (F, 3) ray origins, metres; points: (F, S, 3) or (S, 3) targets, metres.

    Returns:
        (F, S) bool.

    """
    F = origins.shape[0]
    pts = np.broadcast_to(points, (F,) + points.shape[-2:])
    d = pts - origins[:, None, :]
    dist = np.linalg.norm(d, axis=-1)
    dirs = d / np.maximum(dist, 1e-9)[..., None]
    rays = np.concatenate([np.broadcast_to(origins[:, None, :], d.shape), dirs], axis=-1)
    ans = scene.cast_rays(o3d.core.Tensor(rays.reshape(-1, 6).astype(np.float32)))
    t = ans["t_hit"].numpy().reshape(dist.shape)
    return t >= dist - (_EPS_M + 1e-4 * dist)


def target_visibility_rays(
    static: Mesh,
    target_world: Mesh,
    target_local: Mesh,
    T_world_target: np.ndarray,
    cams: np.ndarray,
    cfg: SimConfig,
    n_samples: int | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Visibility of the target samples from camera centres, ignoring the image frame.

    Args:
        cams: (F, 3) camera centres, metres.

    Returns:
        sample points (S, 3); seen (F, S) bool: seen in the full scene; self_vis (F, S) bool: seen
        with
        the target alone. The visible fraction of frame f is seen[f].sum() / self_vis[f].sum().

    """
    pts = target_samples(target_local, T_world_target, n_samples or cfg.target_samples)
    full, _ = raycasting_scene([static, target_world])
    alone, _ = raycasting_scene([target_world])
    self_vis = first_hit_reaches(alone, cams, pts)
    seen = first_hit_reaches(full, cams, pts) & self_vis
    return pts, seen, self_vis
