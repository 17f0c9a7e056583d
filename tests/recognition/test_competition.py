"""The place competition: a place goes to the template that explains it, not to the larger one."""

from __future__ import annotations

import numpy as np

from atr.recognition import Candidate, CompetitionSettings, PointSet, compete_for_places

SETTINGS = CompetitionSettings(nms_m=2.0, overlap_m=0.1, ground_slab_m=0.1)


def box_surface(
    length_m: float, width_m: float, height_m: float, step_m: float = 0.1
) -> np.ndarray:
    """Points on the sides and top of a box standing on z = 0, centred on the origin in x and y."""
    g = np.arange(0.0, 1.0 + 1e-9, step_m / max(length_m, width_m, height_m))
    u, v = np.meshgrid(g, g)
    u, v = u.ravel(), v.ravel()
    hx, hy = length_m / 2, width_m / 2
    faces = [
        np.c_[(u - 0.5) * length_m, (v - 0.5) * width_m, np.full_like(u, height_m)],  # top
        np.c_[(u - 0.5) * length_m, np.full_like(u, -hy), v * height_m],
        np.c_[(u - 0.5) * length_m, np.full_like(u, hy), v * height_m],
        np.c_[np.full_like(u, -hx), (u - 0.5) * width_m, v * height_m],
        np.c_[np.full_like(u, hx), (u - 0.5) * width_m, v * height_m],
    ]
    return np.unique(np.round(np.concatenate(faces), 6), axis=0)


def candidate(target: str, model_m: np.ndarray, scene: PointSet, strength: float) -> Candidate:
    """The model at the identity pose, its support measured as verification would."""
    d, _ = scene.tree.query(model_m, distance_upper_bound=SETTINGS.overlap_m)
    return Candidate(
        target=target,
        model=PointSet(model_m),
        box_lo_m=model_m.min(0),
        box_hi_m=model_m.max(0),
        T_scene_model=np.eye(4),
        centre_m=model_m.mean(0),
        extent_m=float(np.linalg.norm(model_m.max(0) - model_m.min(0))),
        support=float(np.mean(np.isfinite(d))),
        strength=strength,
    )


TANK = box_surface(7.0, 3.5, 2.2)
CAR = box_surface(4.0, 1.8, 1.4)


def test_a_small_template_does_not_take_a_large_vehicle():
    """The car fits inside the tank's blob (its vertices are supported) but explains little of it."""
    scene = PointSet(TANK)
    car = candidate("car", CAR + [0, 0, 0.8], scene, strength=1000.0)  # the stronger by count
    tank = candidate("tank", TANK, scene, strength=10.0)
    winners = compete_for_places([car, tank], scene, SETTINGS)
    assert [i for i, _ in winners] == [1]
    assert winners[0][1] > 0.95


def test_a_large_template_does_not_take_a_small_vehicle():
    """The tank explains all of the car's vertices, but most of its own find no scene vertex."""
    scene = PointSet(CAR)
    tank = candidate("tank", TANK, scene, strength=1000.0)
    car = candidate("car", CAR, scene, strength=10.0)
    winners = compete_for_places([tank, car], scene, SETTINGS)
    assert [i for i, _ in winners] == [1]
    assert 0.0 <= winners[0][1] <= 1.0


def test_separate_places_each_keep_a_winner():
    """Two vehicles 20 m apart are two places; within a template the strongest pose enters."""
    far = np.array([20.0, 0.0, 0.0])
    scene = PointSet(np.concatenate([TANK, CAR + far]))
    shifted = TANK + [0.3, 0, 0]
    entries = [
        candidate("tank", TANK, scene, strength=500.0),
        candidate("tank", shifted, scene, strength=400.0),  # a weaker pose of the same template
        candidate("car", CAR + far, scene, strength=100.0),
    ]
    winners = compete_for_places(entries, scene, SETTINGS)
    assert [i for i, _ in winners] == [0, 2]


def test_an_empty_competition():
    assert compete_for_places([], PointSet(TANK), SETTINGS) == []
