"""Shared fixtures: a reduced-resolution simulator configuration and one built world."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from atr.sim import SimConfig, build_world, scenario
from atr.sim.mesh import Mesh, box, merge, pose, rot_z
from atr.sim.scenarios import custom_scenario
from atr.sim.trajectory import make_orbit
from atr.sim.vehicles import t72
from atr.sim.world import World

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _poses import look_at  # noqa: E402, F401  (the sim tests import it from here)


@pytest.fixture(scope="session")
def small_cfg() -> SimConfig:
    """320x240 images with the same field of view as the default camera; small LIDAR grid."""
    return SimConfig(width_px=320, height_px=240, focal_px=500.0, lidar_grid=64, target_samples=400)


@pytest.fixture(scope="session")
def world_s1r3(small_cfg):
    return build_world(scenario(1, 3), 0, config=small_cfg)


def toy_world(static_parts: list[Mesh], cfg: SimConfig, target: Mesh | None = None) -> World:
    """A hand-made world: flat ground plus the given parts, a T-72 at the origin heading +x."""
    ground = box((400.0, 400.0, 1.0), (0.0, 0.0, -0.5), 0)
    tl = target if target is not None else t72()
    T = pose(rot_z(0.0), (0.0, 0.0, 0.0))
    orbit = make_orbit(custom_scenario(50.0, 30.0, 4), np.zeros(3), np.random.default_rng(0), cfg)
    return World(
        seed=1,
        static=merge([ground] + static_parts),
        target=tl.transformed(T),
        target_name="t72",
        T_world_target=T,
        target_local=tl,
        ground_rects=np.zeros((0, 8)),
        sun_dir=np.array([0.3, 0.2, 0.93]) / np.linalg.norm([0.3, 0.2, 0.93]),
        orbit=orbit,
        occluder_width_m=0.0,
    )
