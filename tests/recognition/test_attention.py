"""Attention: the cue keeps every vehicle-sized blob of the height band and drops what no vehicle can be."""

from __future__ import annotations

import math

import numpy as np
import pytest

from atr.recognition.attention import (
    AttentionSizes,
    largest_footprint_m,
    vehicle_blobs,
    vehicle_places,
)

SIZES = AttentionSizes(cell_m=0.6, top_m=3.5, footprint_m=1.5 * (7.0 + 3.6))


def box_points(
    rng: np.random.Generator, centre_xy, size_xyz, n: int, yaw: float = 0.0
) -> np.ndarray:
    """Points filling a box standing on the ground (z from 0 up to its height)."""
    local = rng.uniform(-0.5, 0.5, (n, 3)) * size_xyz + [0, 0, size_xyz[2] / 2]
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return local @ R.T + [*centre_xy, 0.0]


def cue(points: np.ndarray) -> np.ndarray:
    height = points[:, 2]
    band = (height >= 0.45) & (height <= 2.9)
    return vehicle_blobs(points, height, band, SIZES)


def test_a_vehicle_beside_a_building_is_kept_and_the_building_is_not():
    rng = np.random.default_rng(0)
    vehicle = box_points(rng, (0.0, 0.0), (7.0, 3.6, 2.3), 3000, yaw=0.6)
    building = box_points(rng, (0.0, 9.0), (20.0, 12.0, 8.0), 30000)  # 1 m from the vehicle's side
    wall = box_points(rng, (0.0, -20.0), (40.0, 0.4, 1.8), 4000)  # low, but no vehicle is 40 m long
    points = np.vstack([vehicle, building, wall])
    kept = cue(points)
    n_v, n_b = len(vehicle), len(building)
    band = (points[:, 2] >= 0.45) & (points[:, 2] <= 2.9)
    assert kept[:n_v][band[:n_v]].mean() > 0.95
    assert kept[n_v : n_v + n_b].mean() < 0.05  # only its edge next to the vehicle's blob
    assert not kept[n_v + n_b :].any()


def test_two_vehicles_parked_side_by_side_are_both_kept():
    rng = np.random.default_rng(1)
    pair = np.vstack(
        [box_points(rng, (0.0, y), (7.0, 3.6, 2.3), 3000, yaw=0.3) for y in (0.0, 4.2)]
    )
    band = (pair[:, 2] >= 0.45) & (pair[:, 2] <= 2.9)
    assert cue(pair)[band].all()


def test_nothing_in_the_band_nothing_kept():
    rng = np.random.default_rng(2)
    flat = box_points(rng, (0.0, 0.0), (10.0, 10.0, 0.3), 500)
    assert not cue(flat).any()
    assert cue(np.zeros((0, 3))).shape == (0,)


@pytest.mark.parametrize("yaw", [0.0, 0.4, math.pi / 4, 1.2])
def test_the_footprint_bound_holds_at_every_heading(yaw):
    rng = np.random.default_rng(3)
    model = box_points(rng, (0.0, 0.0), (7.0, 3.6, 2.3), 4000)
    turned = box_points(rng, (0.0, 0.0), (7.0, 3.6, 2.3), 4000, yaw=yaw)
    span = turned[:, :2].max(axis=0) - turned[:, :2].min(axis=0)
    assert np.hypot(*span) <= largest_footprint_m(model) + 1e-9


def places(points: np.ndarray, min_points: int = 20):
    height = points[:, 2]
    band = (height >= 0.45) & (height <= 2.9)
    return vehicle_places(points, height, band, SIZES, min_points)


@pytest.mark.parametrize("yaw", [0.0, 0.5, 2.0])
def test_each_vehicle_is_one_place_with_its_centre_and_its_long_axis(yaw):
    rng = np.random.default_rng(4)
    vehicle = box_points(rng, (3.0, -2.0), (7.0, 3.6, 2.3), 3000, yaw=yaw)
    car = box_points(rng, (3.0, 15.0), (4.5, 1.8, 1.5), 800, yaw=0.0)
    building = box_points(rng, (-30.0, 0.0), (20.0, 12.0, 8.0), 30000)
    found = places(np.vstack([vehicle, car, building]))
    assert len(found) == 2
    by_y = sorted(found, key=lambda p: p.centre_m[1])
    assert np.allclose(by_y[0].centre_m[:2], (3.0, -2.0), atol=0.2)
    assert np.allclose(by_y[1].centre_m[:2], (3.0, 15.0), atol=0.2)
    # the long axis, either way along it
    assert abs(math.sin(by_y[0].axis_yaw_rad - yaw)) < 0.1
    assert abs(math.sin(by_y[1].axis_yaw_rad)) < 0.1
    assert set(by_y[0].idx) <= set(range(len(vehicle)))


def test_a_blob_smaller_than_the_fewest_vertices_is_no_place():
    rng = np.random.default_rng(5)
    post = box_points(rng, (0.0, 0.0), (0.3, 0.3, 1.5), 15)
    assert places(post, min_points=20) == []
    assert len(places(post, min_points=5)) == 1
    assert places(np.zeros((0, 3))) == []
