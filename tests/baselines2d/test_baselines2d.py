"""2D ATR baseline (Fig. 3, Table IV): every pair finds a template pasted into a scene with a known similarity
transform, the ground ray lands where geometry says, results repeat with the seed, bad input is refused."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from atr.baselines2d import (
    PAIRS,
    Baseline2dConfig,
    Template2d,
    TemplateView,
    describe_templates,
    detect_and_describe,
    ground_intersection,
    recognize_2d,
    viewing_azimuth_deg,
)
from atr.errors import ConfigError, InputError

K = np.array([[500.0, 0.0, 319.5], [0.0, 500.0, 239.5], [0.0, 0.0, 1.0]])


def looking_down(height_m: float) -> np.ndarray:
    """Camera above the origin, optical axis down (-z), image x along world x."""
    T = np.eye(4)
    T[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    T[2, 3] = height_m
    return T


def textured(shape: tuple[int, int], seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = np.zeros(shape, np.float32)
    for _ in range(250):
        c = (int(rng.integers(0, shape[1])), int(rng.integers(0, shape[0])))
        cv2.circle(img, c, int(rng.integers(2, 12)), float(rng.uniform(0.1, 1.0)), -1)
        p = rng.integers(0, [shape[1], shape[0]], size=(2, 2))
        cv2.rectangle(
            img, tuple(map(int, p[0])), tuple(map(int, p[1])), float(rng.uniform(0, 1)), 2
        )
    img = cv2.GaussianBlur(img, (3, 3), 0.8)
    return np.repeat((255 * img).clip(0, 255).astype(np.uint8)[:, :, None], 3, axis=2)


@pytest.fixture(scope="module")
def scene_and_view():
    patch = textured((120, 160), 1)
    view = TemplateView("t72", 0.0, 0.0, 0, patch, np.array([80.0, 60.0]))
    scene = textured((480, 640), 2) // 3
    angle, scale, offset = 10.0, 1.1, np.array([300.0, 200.0])
    M = cv2.getRotationMatrix2D((0.0, 0.0), angle, scale)
    M[:, 2] = offset
    warped = cv2.warpAffine(patch, M, (640, 480))
    mask = cv2.warpAffine(np.full(patch.shape[:2], 255, np.uint8), M, (640, 480)) > 0
    scene[mask] = warped[mask]
    expected = M[:, :2] @ view.reference_px + M[:, 2]
    return scene, view, expected


@pytest.mark.parametrize("pair", sorted(PAIRS))
def test_each_pair_finds_a_pasted_template(pair, scene_and_view):
    scene, view, expected = scene_and_view
    config = Baseline2dConfig()
    templates = describe_templates([view], pair, config)
    result = recognize_2d(scene, K, looking_down(50.0), templates, pair, config, seed=3)
    assert len(result.detections) == 1, pair
    detection = result.detections[0]
    assert np.linalg.norm(detection.pixel - expected) < 3.0
    point = ground_intersection(detection.pixel, K, looking_down(50.0), 0.0)
    assert np.allclose(detection.T_world_target[:3, 3], point)


def test_nothing_found_in_an_unrelated_image(scene_and_view):
    _, view, _ = scene_and_view
    config = Baseline2dConfig()
    templates = describe_templates([view], "2d-1", config)
    result = recognize_2d(
        textured((480, 640), 7), K, looking_down(50.0), templates, "2d-1", config, seed=3
    )
    assert result.detections == []


def test_same_seed_same_result(scene_and_view):
    scene, view, _ = scene_and_view
    config = Baseline2dConfig()
    templates = describe_templates([view], "2d-3", config)
    a = recognize_2d(scene, K, looking_down(50.0), templates, "2d-3", config, seed=11)
    b = recognize_2d(scene, K, looking_down(50.0), templates, "2d-3", config, seed=11)
    assert [d.pixel.tolist() for d in a.detections] == [d.pixel.tolist() for d in b.detections]


def test_ground_intersection_geometry():
    T = looking_down(20.0)
    assert np.allclose(ground_intersection(np.array([319.5, 239.5]), K, T, 0.0), [0.0, 0.0, 0.0])
    # 100 px right of the principal point at focal 500 px from 20 m: 4 m along world x
    assert np.allclose(ground_intersection(np.array([419.5, 239.5]), K, T, 0.0), [4.0, 0.0, 0.0])
    assert np.allclose(ground_intersection(np.array([319.5, 239.5]), K, T, 2.0), [0.0, 0.0, 2.0])
    up = T.copy()
    up[:3, :3] = np.eye(3)  # looking up: the ray never meets the ground
    assert ground_intersection(np.array([319.5, 239.5]), K, up, 0.0) is None


def test_viewing_azimuth_in_target_frame():
    T = np.eye(4)
    assert viewing_azimuth_deg(T, [10.0, 0.0, 5.0]) == pytest.approx(0.0)
    assert viewing_azimuth_deg(T, [0.0, 10.0, 5.0]) == pytest.approx(90.0)
    T[:3, :3] = np.array(
        [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    )  # target faces world +y
    assert viewing_azimuth_deg(T, [0.0, 10.0, 5.0]) == pytest.approx(0.0)


def test_bad_inputs():
    with pytest.raises(InputError):
        detect_and_describe(np.zeros((4, 4), np.uint8), "2d-1", Baseline2dConfig())
    with pytest.raises(InputError):
        detect_and_describe(np.zeros((100, 100), np.float64), "2d-1", Baseline2dConfig())
    with pytest.raises(ConfigError):
        detect_and_describe(np.zeros((100, 100), np.uint8), "2d-9", Baseline2dConfig())
    with pytest.raises(ConfigError):
        Baseline2dConfig(min_inliers=2)
    black = detect_and_describe(np.zeros((100, 100), np.uint8), "2d-4", Baseline2dConfig())
    assert len(black.xy_px) == 0
    empty = [
        Template2d(
            TemplateView("t72", 0.0, 0.0, 0, np.zeros((20, 20, 3), np.uint8), np.zeros(2)), black
        )
    ]
    assert (
        recognize_2d(
            np.zeros((100, 100, 3), np.uint8),
            K,
            looking_down(5.0),
            empty,
            "2d-4",
            Baseline2dConfig(),
            seed=0,
        ).detections
        == []
    )
