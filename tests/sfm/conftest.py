"""Fixtures of the SfM tests: camera geometry helpers and a textured ground plane rendered by homography
with exact poses. (pytest runs in importlib mode: tests reach these through fixtures.)"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared"

# World-from-camera rotation of a nadir camera: camera x = world x, camera y = world -y,
# camera z (forward) = world -z (down).
R_WORLD_NADIR = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


def rot_x(angle_rad: float) -> np.ndarray:
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_z(angle_rad: float) -> np.ndarray:
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def pose(R_world_cam: np.ndarray, centre_world: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R_world_cam
    T[:3, 3] = centre_world
    return T


def oblique_pair(
    tilt_a_rad: float, tilt_b_rad: float, yaw_b_rad: float, centre_b: list[float]
) -> tuple[np.ndarray, np.ndarray]:
    """Camera a 50 m above the origin, tilted from nadir; camera b at centre_b, tilted and turned."""
    T_a = pose(R_WORLD_NADIR @ rot_x(tilt_a_rad), np.array([0.0, 0.0, 50.0]))
    T_b = pose(rot_z(yaw_b_rad) @ R_WORLD_NADIR @ rot_x(tilt_b_rad), np.array(centre_b))
    return T_a, T_b


def noise_texture(shape: tuple[int, int], seed: int) -> np.ndarray:
    """Multi-scale blurred noise, uint8: corners and blobs at many scales, no periodicity."""
    rng = np.random.default_rng(seed)
    acc = np.zeros(shape, np.float32)
    for sigma in (1.0, 2.0, 4.0, 8.0):
        layer = cv2.GaussianBlur(rng.standard_normal(shape).astype(np.float32), (0, 0), sigma)
        acc += layer / layer.std()
    acc = (acc - acc.min()) / (acc.max() - acc.min())
    return (acc * 255).astype(np.uint8)


@dataclass
class PlaneScene:
    texture: np.ndarray  # uint8 texture laid on the plane z = 0
    texture_origin_m: tuple[float, float]  # world (x, y) of texture pixel (0, 0)
    texture_res_m: float  # metres per texture pixel
    K: np.ndarray
    size: tuple[int, int]  # (width, height) of rendered images

    def render(self, T_world_cam: np.ndarray) -> np.ndarray:
        T_cam_world = np.linalg.inv(T_world_cam)
        R, t = T_cam_world[:3, :3], T_cam_world[:3, 3]
        plane_to_image = self.K @ np.c_[R[:, 0], R[:, 1], t]
        x0, y0 = self.texture_origin_m
        texture_to_plane = np.array(
            [[self.texture_res_m, 0.0, x0], [0.0, self.texture_res_m, y0], [0.0, 0.0, 1.0]]
        )
        H = plane_to_image @ texture_to_plane
        return cv2.warpPerspective(self.texture, H, self.size, flags=cv2.INTER_LINEAR)


def make_plane_scene() -> PlaneScene:
    width, height, focal = 640, 480, 700.0
    K = np.array([[focal, 0.0, (width - 1) / 2], [0.0, focal, (height - 1) / 2], [0.0, 0.0, 1.0]])
    res = 0.04
    texture = noise_texture((2000, 2000), seed=7)
    return PlaneScene(texture, (-40.0, -40.0), res, K, (width, height))


@pytest.fixture(scope="session")
def plane_scene() -> PlaneScene:
    return make_plane_scene()


@pytest.fixture(scope="session")
def geo() -> SimpleNamespace:
    """Pose helpers: R_WORLD_NADIR, pose(R, centre), rot_x(rad), rot_z(rad), oblique_pair(...)."""
    return SimpleNamespace(
        R_WORLD_NADIR=R_WORLD_NADIR, pose=pose, rot_x=rot_x, rot_z=rot_z, oblique_pair=oblique_pair
    )
