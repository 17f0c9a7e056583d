"""2D ATR baseline (Fig. 3, Table IV): every pair finds a template pasted into a scene with a known similarity
transform, the ground ray lands where geometry says, results repeat with the seed, bad input is refused;
templates come from the configured run, a spread keypoint cap keeps a weak target's keypoints, scaled
templates are the stated sizes."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from atr.baselines2d import (
    PAIRS,
    Baseline2dConfig,
    Template2d,
    TemplateView,
    cap_keypoints,
    crop_template_views,
    describe_templates,
    detect_and_describe,
    ground_intersection,
    recognize_2d,
    viewing_azimuth_deg,
)
from atr.baselines2d import templates as templates_module
from atr.errors import ConfigError, InputError
from atr.sim.config import SimConfig
from atr.sim.scenarios import scenario

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


# ------------------------------------------------------------------ template run, keypoint cap, scales


def test_default_templates_come_from_the_30_degree_run():
    config = Baseline2dConfig()
    assert scenario(config.template_scenario, config.template_run).obliquity_deg == 30.0
    assert config.template_scales == (1.0,)  # the paper's single-scale template
    assert config.max_keypoints is None  # no cap, as MATLAB


@pytest.mark.parametrize("run", [1, 3])
def test_templates_are_cropped_from_the_configured_run(run, monkeypatch):
    seen = []

    class StopError(Exception):
        pass

    def build_world(sc, *args, **kwargs):
        seen.append((sc.scenario, sc.run))
        raise StopError

    monkeypatch.setattr(templates_module, "build_world", build_world)
    with pytest.raises(StopError):
        crop_template_views(0, SimConfig(), Baseline2dConfig(template_run=run))
    assert seen == [(1, run)]


def _keypoints(xy_px: np.ndarray, response: np.ndarray) -> list[cv2.KeyPoint]:
    return [
        cv2.KeyPoint(float(x), float(y), 3.0, -1.0, float(r))
        for (x, y), r in zip(xy_px, response, strict=True)
    ]


def test_grid_spread_cap_keeps_a_weak_targets_keypoints():
    # 2,000 strong background corners over a 640x480 image, 200 weak ones on a 64x64 "target" that
    # hides the background behind it (four 32 px cells)
    rng = np.random.default_rng(0)
    background = rng.uniform([0, 0], [640, 480], (3000, 2))
    hidden = (background >= [320, 192]).all(1) & (background < [384, 256]).all(1)
    background = background[~hidden][:2000]
    target = rng.uniform([320, 192], [384, 256], (200, 2))
    keypoints = _keypoints(
        np.vstack([background, target]),
        np.concatenate([rng.uniform(50, 100, 2000), rng.uniform(1, 10, 200)]),
    )

    def on_target(kept):
        return sum(320 <= k.pt[0] < 384 and 192 <= k.pt[1] < 256 for k in kept)

    strongest = cap_keypoints(keypoints, 600, None, (480, 640))
    spread = cap_keypoints(keypoints, 600, 32, (480, 640))
    assert len(strongest) == len(spread) == 600
    assert on_target(strongest) == 0
    # 300 cells share a 600 cap: each of the target's four keeps at least its two strongest
    assert on_target(spread) >= 8
    assert len(cap_keypoints(keypoints, None, None, (480, 640))) == len(keypoints)


def test_no_cap_keeps_every_detection(scene_and_view):
    scene, _, _ = scene_and_view
    uncapped = detect_and_describe(scene, "2d-3", Baseline2dConfig(max_keypoints=None))
    capped = detect_and_describe(scene, "2d-3", Baseline2dConfig(max_keypoints=100))
    assert len(capped.xy_px) <= 100 < len(uncapped.xy_px)


@pytest.mark.parametrize("pair", ["2d-1", "2d-3"])
def test_spread_cap_keeps_a_faint_targets_keypoints_in_a_real_image(pair):
    # a faint textured 96x96 "target" in a bright textured scene: the image's strongest corners are
    # all in the background, a spread cap still keeps some on the target
    scene = textured((480, 640), 4)
    scene[192:288, 288:384] = textured((96, 96), 5)[:, :, :] // 6

    def on_target(config):
        xy = detect_and_describe(scene, pair, config).xy_px
        return int(((xy >= [300, 204]) & (xy < [372, 276])).all(1).sum())

    strongest = on_target(Baseline2dConfig(max_keypoints=1200, keypoint_grid_cell_px=None))
    spread = on_target(Baseline2dConfig(max_keypoints=1200, keypoint_grid_cell_px=32))
    assert strongest <= 2 and spread >= 10


@pytest.fixture(scope="module")
def scaled_views():
    sim = SimConfig(width_px=320, height_px=240, focal_px=500.0)  # small frames: a fast render
    config = Baseline2dConfig(n_templates=2, template_scales=(1.0, 0.5, 0.25))
    return crop_template_views(3, sim, config), config


def test_scaled_templates_are_the_stated_sizes(scaled_views):
    views, config = scaled_views
    assert [v.scale for v in views] == list(config.template_scales) * (len(views) // 3)
    for k in range(0, len(views), 3):
        full = views[k]
        h, w = full.image.shape[:2]
        assert full.keep_box_px is None
        for view in views[k + 1 : k + 3]:
            assert view.azimuth_deg == full.azimuth_deg and view.frame == full.frame
            x0, y0, x1, y1 = view.keep_box_px
            # the target's box (the x1 crop) shrunk by the scale, within a pixel of rounding
            assert abs((x1 - x0) - view.scale * (w - 1)) <= 1.0
            assert abs((y1 - y0) - view.scale * (h - 1)) <= 1.0
            # the target origin sits at the same place relative to the shrunk box
            assert np.allclose(
                view.reference_px - [x0, y0], view.scale * full.reference_px, atol=1.0
            )


@pytest.mark.parametrize("pair", ["2d-1", "2d-3"])
def test_scaled_templates_keep_keypoints_on_the_target_only(pair, scaled_views):
    views, config = scaled_views
    described = describe_templates(views, pair, config)
    for template in described:
        if template.view.keep_box_px is None:
            continue
        x0, y0, x1, y1 = template.view.keep_box_px
        xy = template.features.xy_px
        assert ((xy >= [x0, y0]) & (xy <= [x1, y1])).all()
    # the context lets the x0.5 views keep keypoints (a bare x0.5 crop of a 65 px box keeps few)
    assert all(len(t.features.xy_px) > 0 for t in described if t.view.scale == 0.5)


def test_bad_template_scales_are_refused():
    for scales in [(), (1.0, 1.0), (0.0,), (2.0,)]:
        with pytest.raises(ConfigError):
            Baseline2dConfig(template_scales=scales)


def test_cached_crops_follow_the_template_settings_only():
    from atr.evaluation.experiment import _view_fields

    config = Baseline2dConfig()
    assert _view_fields(replace(config, min_inliers=20, max_keypoints=5)) == _view_fields(config)
    for changed in (
        replace(config, template_run=1),
        replace(config, template_scales=(1.0, 0.5)),
        replace(config, crop_margin_frac=0.2),
    ):
        assert _view_fields(changed) != _view_fields(config)
