"""Worlds with any vehicle of the family as the target: deterministic, and the city is the seed's alone."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from atr.errors import InputError
from atr.sim import build_world, scenario
from atr.sim.scenarios import custom_scenario
from atr.sim.vehicles import m113, vehicle
from atr.sim.world import World


def world_digest(world: World) -> str:
    """Everything a built world holds, hashed (meshes, ground map, sun, orbit, vehicles)."""
    h = hashlib.sha256()
    for mesh in (world.static, world.target, world.target_local):
        for array in (mesh.vertices, mesh.triangles, mesh.material):
            h.update(array.tobytes())
    for array in (world.T_world_target, world.ground_rects, world.sun_dir):
        h.update(np.ascontiguousarray(array, np.float64).tobytes())
    o = world.orbit
    h.update(repr((o.center.tolist(), o.radius_m, o.height_m, o.rate_radps)).encode())
    h.update(repr((world.occluder_width_m, world.target_name, world.seed)).encode())
    h.update(repr([(v.name, v.position_m, v.yaw_rad, v.radius_m) for v in world.vehicles]).encode())
    return h.hexdigest()


@pytest.mark.parametrize(("number", "run", "seed"), [(1, 1, 0), (2, 3, 5), (3, 1, 2)])
def test_the_same_seed_builds_the_same_world(number, run, seed, small_cfg):
    sc = scenario(number, run)
    first = build_world(sc, seed, config=small_cfg)
    assert world_digest(first) == world_digest(build_world(sc, seed, config=small_cfg))
    assert world_digest(first) != world_digest(build_world(sc, seed + 1, config=small_cfg))
    # the default target is the T-72, and the world's own confusers stand in it
    assert first.target_name == "t72"
    assert first.target_local.vertices.tobytes() == vehicle("t72").vertices.tobytes()
    assert {v.name for v in first.vehicles} - {"car"} <= {"ifv", "truck6x6"}


def test_the_target_choice_leaves_the_seeds_city_as_it_is(small_cfg):
    """The target is drawn after nothing: streets, buildings, trees, cars and confusers are the same for
    every target (scenario 3 needs no occluder, whose width is tuned on the target's visibility)."""
    sc = scenario(3, 1)
    t72_world = build_world(sc, 2, config=small_cfg)
    leopard_world = build_world(sc, 2, target_name="leopard2", config=small_cfg)
    assert leopard_world.target_name == "leopard2"
    assert leopard_world.target_local.n_triangles == vehicle("leopard2").n_triangles
    assert leopard_world.static.vertices.tobytes() == t72_world.static.vertices.tobytes()
    assert leopard_world.static.material.tobytes() == t72_world.static.material.tobytes()
    np.testing.assert_array_equal(leopard_world.T_world_target, t72_world.T_world_target)
    np.testing.assert_array_equal(leopard_world.ground_rects, t72_world.ground_rects)
    assert leopard_world.vehicles == t72_world.vehicles


def test_a_confuser_that_is_the_target_leaves_the_world(small_cfg):
    sc = custom_scenario(50.0, 30.0, n_scenes=1)
    default = build_world(sc, 4, config=small_cfg)
    assert {"ifv", "truck6x6"} <= {v.name for v in default.vehicles}
    world = build_world(sc, 4, target_name="ifv", config=small_cfg)
    names = [v.name for v in world.vehicles]
    assert world.target_name == "ifv" and "ifv" not in names and "truck6x6" in names


def test_named_clutter_is_reported_by_its_name(small_cfg):
    sc = custom_scenario(50.0, 30.0, n_scenes=1)
    world = build_world(
        sc, 4, target_name="m1", clutter_meshes=[("t72", vehicle("t72")), m113()], config=small_cfg
    )
    names = {v.name for v in world.vehicles}
    assert world.target_name == "m1"
    assert {"t72", "clutter-1"} <= names
    target_xy = world.T_world_target[:2, 3]
    for v in world.vehicles:
        if v.name in ("t72", "clutter-1"):
            assert np.linalg.norm(np.asarray(v.position_m[:2]) - target_xy) >= 14.0


def test_an_unknown_target_name_is_refused(small_cfg):
    with pytest.raises(InputError, match="unknown vehicle 'tiger'.*leopard2"):
        build_world(
            custom_scenario(50.0, 30.0, n_scenes=1), 4, target_name="tiger", config=small_cfg
        )
