"""Known-pose triangulation: exact geometry, gates, uncertainty, broken inputs."""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _poses import look_at  # noqa: E402

from atr.errors import ConfigError, InputError
from atr.sfm import SfmConfig, relative_camera_pose, triangulate_known_pose
from atr.sfm.triangulation import (
    epipolar_distances_px,
    fixation_depth_m,
    predict_on_fixation_plane,
    triangulate_linear,
)

K = np.array([[800.0, 0.0, 640.0], [0.0, 800.0, 480.0], [0.0, 0.0, 1.0]])


def project(points_world: np.ndarray, T_world_cam: np.ndarray) -> np.ndarray:
    T_cam_world = np.linalg.inv(T_world_cam)
    p = points_world @ T_cam_world[:3, :3].T + T_cam_world[:3, 3]
    uv = p @ K.T
    return uv[:, :2] / uv[:, 2:3]


@pytest.fixture
def cams(geo) -> tuple[np.ndarray, np.ndarray]:
    """Two oblique cameras ~50 m above the ground, 6 m apart, slightly rotated."""
    return geo.oblique_pair(0.2, 0.18, 0.05, [6.0, 1.0, 50.5])


def ground_points(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.c_[rng.uniform(-15, 15, n), rng.uniform(-25, 5, n), rng.uniform(0.0, 3.0, n)]


def test_relative_pose_is_eq1_identity(cams) -> None:
    T_a, T_b = cams
    T_ba = relative_camera_pose(T_a, T_b)
    np.testing.assert_allclose(T_b @ T_ba, T_a, atol=1e-12)


def test_exact_projections_triangulate_exactly(cams) -> None:
    T_a, T_b = cams
    X = ground_points(500, seed=1)
    cloud = triangulate_known_pose(project(X, T_a), project(X, T_b), K, T_a, T_b, SfmConfig())
    assert cloud.stats["triangulated"] == 500
    np.testing.assert_allclose(cloud.points_world_m, X, atol=1e-6)
    np.testing.assert_allclose(cloud.pixels, project(X, T_a), atol=1e-3)
    assert cloud.points_world_m.dtype == np.float64 and cloud.sigma_m.dtype == np.float32


def test_linear_triangulation_agrees_with_opencv_on_noisy_rays(cams) -> None:
    """OpenCV's triangulatePoints (homogeneous DLT, one SVD per point) is the reference."""
    T_a, T_b = cams
    X = ground_points(2000, seed=3)
    rng = np.random.default_rng(4)
    K_inv = np.linalg.inv(K)
    rays = []
    for T in (T_a, T_b):
        px = project(X, T) + rng.normal(0.0, 1.0, (len(X), 2))  # 1 px noise: rays that miss
        rays.append((np.c_[px, np.ones(len(X))] @ K_inv.T)[:, :2])
    T_ba = relative_camera_pose(T_a, T_b)
    ours = triangulate_linear(rays[0], rays[1], T_ba[:3, :3], T_ba[:3, 3])
    X_h = cv2.triangulatePoints(np.eye(3, 4), T_ba[:3], rays[0].T.copy(), rays[1].T.copy())
    opencv = (X_h[:3] / X_h[3]).T
    spread = np.linalg.norm(opencv - (X - T_a[:3, 3]) @ T_a[:3, :3], axis=1)  # error from the noise
    gap = np.linalg.norm(ours - opencv, axis=1)
    assert np.median(gap) < 0.02 * np.median(spread)
    assert np.percentile(gap, 99) < 0.1 * np.percentile(spread, 99)


def test_parallel_rays_triangulate_to_no_finite_point() -> None:
    ray = np.array([[0.1, -0.2]])
    X = triangulate_linear(ray, ray, np.eye(3), np.array([1.0, 0.0, 0.0]))
    assert not np.isfinite(X).all()


def test_sigma_matches_monte_carlo_spread(cams) -> None:
    """Predicted 1-sigma position error vs the spread under Gaussian pixel noise of pixel_sigma_px."""
    config = SfmConfig(max_relative_sigma=1.0)
    T_a, T_b = cams
    X = ground_points(200, seed=2)
    rng = np.random.default_rng(3)
    errors = []
    sigma = None
    for _ in range(60):
        pa = project(X, T_a) + rng.normal(0.0, config.pixel_sigma_px, (len(X), 2))
        pb = project(X, T_b) + rng.normal(0.0, config.pixel_sigma_px, (len(X), 2))
        cloud = triangulate_known_pose(
            pa, pb, K, T_a, T_b, SfmConfig(max_relative_sigma=1.0, k_max_reprojection=100.0)
        )
        assert len(cloud) == len(X)
        errors.append(np.linalg.norm(cloud.points_world_m - X, axis=1))
        sigma = cloud.sigma_m
    rms = np.sqrt(np.mean(np.square(errors), axis=0))
    ratio = np.median(rms / sigma)
    # sigma is the depth error, the dominant part: the RMS 3D error is close to it.
    assert 0.7 < ratio < 1.3, ratio


def test_points_behind_a_camera_are_rejected(cams) -> None:
    T_a, T_b = cams
    X = ground_points(50, seed=4)
    pa, pb = project(X, T_a), project(X, T_b)
    # Swap the order of the cameras' poses: the same pixels now meet behind the cameras or not at all.
    mirrored_b = T_b.copy()
    mirrored_b[:3, 3] = 2 * T_a[:3, 3] - T_b[:3, 3]
    cloud = triangulate_known_pose(pa, pb, K, T_a, mirrored_b, SfmConfig())
    assert len(cloud) == 0
    assert cloud.stats["rejected_behind"] + cloud.stats["rejected_reprojection"] == 50


def test_mismatched_correspondences_fail_the_reprojection_gate(cams) -> None:
    T_a, T_b = cams
    X = ground_points(100, seed=5)
    pa, pb = project(X, T_a), project(X, T_b)
    pb[:50] += np.array([0.0, 15.0])  # off the epipolar line by ~15 px
    cloud = triangulate_known_pose(pa, pb, K, T_a, T_b, SfmConfig())
    assert cloud.stats["triangulated"] == 50
    assert cloud.stats["rejected_reprojection"] >= 45


def test_low_parallax_points_are_rejected(cams) -> None:
    T_a, _ = cams
    T_b = T_a.copy()
    T_b[:3, 3] += [0.05, 0.0, 0.0]  # 5 cm baseline at ~50 m: parallax ~0.06 deg
    X = ground_points(100, seed=6)
    cloud = triangulate_known_pose(project(X, T_a), project(X, T_b), K, T_a, T_b, SfmConfig())
    assert len(cloud) == 0
    assert cloud.stats["rejected_parallax"] == 100
    assert "gates" in cloud.reason


def test_zero_baseline_gives_empty_cloud_with_reason(cams) -> None:
    T_a, _ = cams
    X = ground_points(20, seed=7)
    p = project(X, T_a)
    cloud = triangulate_known_pose(p, p, K, T_a, T_a.copy(), SfmConfig())
    assert len(cloud) == 0 and "baseline" in cloud.reason
    assert cloud.points_world_m.shape == (0, 3)


def test_too_few_correspondences_give_empty_cloud(cams) -> None:
    T_a, T_b = cams
    cloud = triangulate_known_pose(np.zeros((0, 2)), np.zeros((0, 2)), K, T_a, T_b, SfmConfig())
    assert len(cloud) == 0 and "correspondences" in cloud.reason


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda T: T.__setitem__((0, 3), np.nan), "non-finite"),
        (lambda T: T.__setitem__((3, 0), 1.0), "bottom row"),
        (lambda T: T.__setitem__((0, 0), 2.0), "rotation"),
    ],
)
def test_bad_pose_raises_input_error_naming_it(cams, mutate, message: str) -> None:
    T_a, T_b = cams
    mutate(T_b)
    p = np.zeros((10, 2))
    with pytest.raises(InputError, match=f"T_world_cam_b.*{message}|{message}"):
        triangulate_known_pose(p, p, K, T_a, T_b, SfmConfig())


def test_bad_intrinsics_and_pixels_raise(cams) -> None:
    T_a, T_b = cams
    p = np.zeros((10, 2))
    with pytest.raises(InputError, match="focal"):
        triangulate_known_pose(p, p, np.diag([0.0, 800.0, 1.0]), T_a, T_b, SfmConfig())
    with pytest.raises(InputError, match="pixels_a"):
        triangulate_known_pose(p, np.zeros((9, 2)), K, T_a, T_b, SfmConfig())


@pytest.mark.parametrize(
    "kwargs",
    [
        {"matcher": "orb"},
        {"gftt_min_quality": 0.0},
        {"klt_window_px": 10},
        {"surf_scale_levels": 2},
        {"surf_nndr": 1.5},
        {"pixel_sigma_px": -1.0},
        {"min_parallax_deg": 95.0},
        {"pair_gap_frames": 0},
        {"klt_aided_pyramid_levels": -1},
        {"ground_z_m": float("nan")},
        {"sgm_ground_margin": 0.0},
        {"max_sigma_vs_fixation": 0.0},
    ],
)
def test_config_refuses_bad_values(kwargs: dict) -> None:
    with pytest.raises(ConfigError, match=next(iter(kwargs))):
        SfmConfig(**kwargs)


def through_lens(
    points_world: np.ndarray, T_world_cam: np.ndarray, dist: np.ndarray | None
) -> np.ndarray:
    """Pixels of world points seen by a camera with K and the lens `dist` (None: a pinhole)."""
    T_cam_world = np.linalg.inv(T_world_cam)
    rvec, _ = cv2.Rodrigues(T_cam_world[:3, :3])
    lens = np.zeros(4) if dist is None else dist
    px, _ = cv2.projectPoints(points_world, rvec, T_cam_world[:3, 3], K, lens)
    return px.reshape(-1, 2)


def test_orbiting_cameras_fixate_their_centre() -> None:
    target = np.array([3.0, -2.0, 1.0])
    T_a = look_at(target + [100.0, 0.0, 4.0], target)
    T_b = look_at(target + [100.0 * np.cos(0.08), 100.0 * np.sin(0.08), 4.0], target)
    depth = fixation_depth_m(T_a, T_b)
    assert depth == pytest.approx(np.hypot(100.0, 4.0), rel=1e-9)
    # parallel axes fixate nothing, nor axes that pass closest behind a camera
    T_shifted = T_a.copy()
    T_shifted[:3, 3] += [0.0, 7.5, 0.0]
    assert fixation_depth_m(T_a, T_shifted) is None
    T_away = look_at(target + [100.0, 7.5, 4.0], target + [200.0, 15.0, 4.0])
    assert fixation_depth_m(T_a, T_away) is None
    # camera b aims 3 m above the target: the axes miss each other, and fixate a point only when
    # a miss that large is allowed
    T_over = look_at(
        target + [100.0 * np.cos(0.08), 100.0 * np.sin(0.08), 4.0], target + [0, 0, 3.0]
    )
    assert fixation_depth_m(T_a, T_over, max_miss_m=1.0) is None
    assert fixation_depth_m(T_a, T_over) is not None


def test_points_far_beyond_the_fixation_point_are_dropped() -> None:
    """The gate keeps what lies near and before the fixated target, and drops the far background."""
    target = np.array([0.0, 0.0, 0.0])
    T_a = look_at(target + [100.0, 0.0, 4.0], target)
    T_b = look_at(target + [100.0 * np.cos(0.075), 100.0 * np.sin(0.075), 4.0], target)
    # points along camera a's view of the target: 60 m from it to 300 m behind it
    rng = np.random.default_rng(7)
    depth_m = np.r_[rng.uniform(40.0, 100.0, 100), rng.uniform(120.0, 400.0, 100)]
    lateral = rng.uniform(-5.0, 5.0, (200, 2))
    X = (np.c_[lateral, depth_m]) @ T_a[:3, :3].T + T_a[:3, 3]
    pa, pb = project(X, T_a), project(X, T_b)
    loose = SfmConfig(max_relative_sigma=1.0, max_sigma_vs_fixation=None)
    everything = triangulate_known_pose(pa, pb, K, T_a, T_b, loose)
    assert len(everything) == 200
    gated = triangulate_known_pose(
        pa, pb, K, T_a, T_b, SfmConfig(max_relative_sigma=1.0, max_sigma_vs_fixation=1.3)
    )
    # sigma grows with the square of the range: 1.3 x the fixation point's sigma is ~1.14 x its depth
    kept_depth = (gated.points_world_m - T_a[:3, 3]) @ T_a[:3, 2]
    fixation_m = fixation_depth_m(T_a, T_b)
    assert kept_depth.max() < 1.2 * fixation_m
    assert np.count_nonzero(depth_m <= 1.05 * fixation_m) <= len(gated) < 200
    assert gated.stats["rejected_sigma"] == 200 - len(gated)
    assert gated.stats["fixation_sigma_m"] == pytest.approx(
        np.interp(fixation_m, np.sort(depth_m), everything.sigma_m[np.argsort(depth_m)]), rel=0.1
    )
    # a pair whose axes do not meet (a sideways step, both cameras looking the same way) has no
    # fixation point, and nothing is dropped for it
    T_side = T_a.copy()
    T_side[:3, 3] += 7.5 * T_a[:3, 0]
    side = triangulate_known_pose(
        pa, project(X, T_side), K, T_a, T_side, SfmConfig(max_relative_sigma=1.0)
    )
    assert len(side) == 200 and "fixation_sigma_m" not in side.stats


@pytest.mark.parametrize("dist", [None, np.array([-0.2, 0.05, 0.001, -0.001, 0.0])])
def test_points_on_the_fixation_plane_are_predicted_exactly(dist) -> None:
    target = np.array([0.0, 0.0, 1.0])
    T_a = look_at(np.array([50.0, 0.0, 4.0]), target)
    T_b = look_at(np.array([50.0 * np.cos(0.1), 50.0 * np.sin(0.1), 4.5]), target)
    depth = fixation_depth_m(T_a, T_b)
    # points on the plane facing camera a at the fixation depth, seen through the lens
    rng = np.random.default_rng(0)
    cam = np.c_[rng.uniform(-8.0, 8.0, (40, 2)), np.full(40, depth)]
    world = cam @ T_a[:3, :3].T + T_a[:3, 3]
    px_a, px_b = through_lens(world, T_a, dist), through_lens(world, T_b, dist)

    predicted, reaches = predict_on_fixation_plane(px_a, K, dist, T_a, T_b, -10.0)
    np.testing.assert_allclose(predicted, px_b, atol=1e-3)
    assert reaches.all()
    # raise the ground above the plane's lower part: pixels looking down at it now see foreground
    _, reaches = predict_on_fixation_plane(px_a, K, dist, T_a, T_b, 0.5)
    below = world[:, 2] < 0.5
    assert below.any() and not below.all()
    np.testing.assert_array_equal(reaches, ~below)


@pytest.mark.parametrize("dist", [None, np.array([-0.2, 0.05, 0.001, -0.001, 0.0])])
def test_epipolar_distance_is_zero_for_a_true_correspondence_and_grows_off_the_line(dist) -> None:
    target = np.array([0.0, 0.0, 1.0])
    T_a = look_at(np.array([50.0, 0.0, 4.0]), target)
    T_b = look_at(np.array([50.0 * np.cos(0.1), 50.0 * np.sin(0.1), 6.0]), target)
    rng = np.random.default_rng(1)
    world = np.c_[rng.uniform(-10.0, 10.0, (30, 2)), rng.uniform(0.0, 3.0, 30)]
    px_a, px_b = through_lens(world, T_a, dist), through_lens(world, T_b, dist)
    distances = epipolar_distances_px(px_a, px_b, K, dist, T_a, T_b)
    assert distances.shape == (30, 30)
    np.testing.assert_allclose(np.diag(distances), 0.0, atol=1e-3)
    # Other points of the same scene lie off each other's lines (depths differ).
    assert np.median(distances[~np.eye(30, dtype=bool)]) > 5.0
    if dist is None:
        # A pixel moved 3 px along the normal of its line (the line as OpenCV finds it from the
        # exact correspondences alone, an outside reference) is 3 px from our line.
        F, _ = cv2.findFundamentalMat(px_a, px_b, cv2.FM_8POINT)
        line = cv2.computeCorrespondEpilines(px_a[:1].reshape(-1, 1, 2), 1, F).reshape(3)
        moved = px_b[:1] + 3.0 * line[:2] / np.hypot(*line[:2])
        assert epipolar_distances_px(px_a[:1], moved, K, None, T_a, T_b)[0, 0] == pytest.approx(
            3.0, abs=1e-3
        )
