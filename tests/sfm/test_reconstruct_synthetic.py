"""The whole two-view module on rendered images of a textured ground plane with exact poses."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from atr.errors import InputError
from atr.sfm import SfmConfig, gftt_klt_correspondences, reconstruct, surf_correspondences


@pytest.fixture
def pair(geo) -> tuple[np.ndarray, np.ndarray]:
    """Two oblique views 50 m above the plane, 4 m apart, slightly rotated."""
    return geo.oblique_pair(0.25, 0.22, 0.03, [4.0, 0.5, 50.3])


def true_pixel_in_b(scene, pixels_a, T_a, T_b) -> np.ndarray:
    """Where a pixel of image a lands in image b, through the plane z = 0."""
    K_inv = np.linalg.inv(scene.K)
    rays = np.c_[pixels_a, np.ones(len(pixels_a))] @ K_inv.T @ T_a[:3, :3].T
    depth = -T_a[2, 3] / rays[:, 2]
    X = T_a[:3, 3] + rays * depth[:, None]
    T_bw = np.linalg.inv(T_b)
    p = X @ T_bw[:3, :3].T + T_bw[:3, 3]
    uv = p @ scene.K.T
    return uv[:, :2] / uv[:, 2:3]


@pytest.mark.parametrize("matcher", ["gftt", "surf"])
def test_correspondences_follow_the_plane_homography(pair, plane_scene, matcher: str) -> None:
    T_a, T_b = pair
    img_a, img_b = plane_scene.render(T_a), plane_scene.render(T_b)
    find = gftt_klt_correspondences if matcher == "gftt" else surf_correspondences
    pa, pb = find(img_a, img_b, SfmConfig(matcher=matcher))
    assert pa.dtype == np.float32 and pb.shape == pa.shape
    assert len(pa) > (1000 if matcher == "gftt" else 100)
    err = np.linalg.norm(pb - true_pixel_in_b(plane_scene, pa, T_a, T_b), axis=1)
    assert np.median(err) < 0.3
    assert np.mean(err < 2.0) > (0.99 if matcher == "gftt" else 0.9)


# Median height error on the plane, 50 m range, 4 m baseline (0.9 m of depth per pixel of disparity):
# KLT and SURF localise to ~0.1 px; semi-global matching at half size to ~0.3 px of the full image.
PLANE_MEDIAN_M = {"gftt": 0.15, "surf": 0.15, "sgm": 0.35}


@pytest.mark.parametrize("matcher", ["gftt", "surf", "sgm"])
def test_reconstructed_points_lie_on_the_plane(pair, plane_scene, matcher: str) -> None:
    T_a, T_b = pair
    img_a, img_b = plane_scene.render(T_a), plane_scene.render(T_b)
    cloud = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, SfmConfig(matcher=matcher))
    assert cloud.reason == ""
    z = cloud.points_world_m[:, 2]
    assert len(cloud) > (1000 if matcher == "gftt" else 100)
    assert np.median(np.abs(z)) < PLANE_MEDIAN_M[matcher]
    # The predicted sigma is honest: errors beyond 4 sigma are rare.
    assert np.mean(np.abs(z) > 4 * cloud.sigma_m) < 0.05
    assert cloud.stats["triangulated"] == len(cloud)
    tracked = cloud.stats["tracked"] + cloud.stats.get("tracked_aided", 0)
    assert cloud.stats["keypoints"] >= tracked >= len(cloud)


# A wide-angle lens's barrel distortion: 37 px at the image corners of the 640x480 plane scene.
BARREL = np.array([-0.25, 0.08, 0.0005, -0.0003, 0.0])


def through_lens(image: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """The pinhole image as a lens with `dist` would have taken it (OpenCV's model)."""
    h, w = image.shape[:2]
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    grid = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-12)
    pinhole = cv2.undistortPoints(grid, K, dist, None, None, K, criteria).reshape(h, w, 2)
    return cv2.remap(image, pinhole.astype(np.float32), None, cv2.INTER_LINEAR)


@pytest.mark.parametrize("matcher", ["gftt", "surf", "sgm"])
def test_a_distorted_lens_is_corrected_before_triangulation(
    pair, plane_scene, matcher: str
) -> None:
    T_a, T_b = pair
    K = plane_scene.K
    img_a = through_lens(plane_scene.render(T_a), K, BARREL)
    img_b = through_lens(plane_scene.render(T_b), K, BARREL)
    config = SfmConfig(matcher=matcher)
    corrected = reconstruct(img_a, img_b, K, T_a, T_b, config, dist_coeffs=BARREL)
    ignored = reconstruct(img_a, img_b, K, T_a, T_b, config)
    assert len(corrected) > (1000 if matcher == "gftt" else 100)
    assert np.median(np.abs(corrected.points_world_m[:, 2])) < PLANE_MEDIAN_M[matcher]  # as pinhole
    # Treating the lens as a pinhole bends the plane: the same tracks land 0.7-1.4 m off it.
    assert np.median(np.abs(ignored.points_world_m[:, 2])) > 0.3
    # No distortion given, or all zeros, is the pinhole path itself.
    pinhole = reconstruct(img_a, img_b, K, T_a, T_b, config, dist_coeffs=np.zeros(5))
    assert pinhole.points_world_m.tobytes() == ignored.points_world_m.tobytes()


def test_reconstruct_is_deterministic(pair, plane_scene) -> None:
    T_a, T_b = pair
    img_a, img_b = plane_scene.render(T_a), plane_scene.render(T_b)
    for matcher in ("gftt", "surf", "sgm"):
        one = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, SfmConfig(matcher=matcher))
        two = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, SfmConfig(matcher=matcher))
        assert one.points_world_m.tobytes() == two.points_world_m.tobytes()
        assert one.sigma_m.tobytes() == two.sigma_m.tobytes()


@pytest.mark.parametrize("matcher", ["gftt", "surf", "sgm"])
@pytest.mark.parametrize("fill", [0, 128])
def test_black_or_featureless_image_gives_empty_cloud(
    pair, plane_scene, matcher: str, fill: int
) -> None:
    T_a, T_b = pair
    flat = np.full((480, 640), fill, np.uint8)
    cloud = reconstruct(
        flat, plane_scene.render(T_b), plane_scene.K, T_a, T_b, SfmConfig(matcher=matcher)
    )
    assert len(cloud) == 0 and cloud.reason
    cloud = reconstruct(
        plane_scene.render(T_a), flat, plane_scene.K, T_a, T_b, SfmConfig(matcher=matcher)
    )
    assert len(cloud) == 0 and cloud.reason


def test_zero_baseline_pair_gives_empty_cloud(pair, plane_scene) -> None:
    T_a, _ = pair
    img = plane_scene.render(T_a)
    cloud = reconstruct(img, img, plane_scene.K, T_a, T_a, SfmConfig())
    assert len(cloud) == 0 and "baseline" in cloud.reason


def test_bad_images_raise_input_error(pair, plane_scene) -> None:
    T_a, T_b = pair
    img = plane_scene.render(T_a)
    with pytest.raises(InputError, match="sizes differ"):
        reconstruct(img, img[:-1], plane_scene.K, T_a, T_b, SfmConfig())
    with pytest.raises(InputError, match="shape"):
        reconstruct(np.zeros((0, 0), np.uint8), img, plane_scene.K, T_a, T_b, SfmConfig())
    bad = img.astype(np.float32) / 255
    bad[0, 0] = np.nan
    with pytest.raises(InputError, match="non-finite"):
        reconstruct(bad, img, plane_scene.K, T_a, T_b, SfmConfig())
    T_nan = T_b.copy()
    T_nan[1, 1] = np.inf
    with pytest.raises(InputError, match="T_world_cam_b"):
        reconstruct(img, img, plane_scene.K, T_a, T_nan, SfmConfig())
    with pytest.raises(InputError, match="3 coefficients"):
        reconstruct(img, img, plane_scene.K, T_a, T_b, SfmConfig(), dist_coeffs=np.ones(3))
    with pytest.raises(InputError, match="3 coefficients"):  # zeros too: the vector is malformed
        reconstruct(img, img, plane_scene.K, T_a, T_b, SfmConfig(), dist_coeffs=np.zeros(3))
    with pytest.raises(InputError, match="non-finite"):
        reconstruct(img, img, plane_scene.K, T_a, T_b, SfmConfig(), dist_coeffs=BARREL + np.nan)


def test_guided_surf_matches_a_pattern_that_repeats_off_the_epipolar_lines(
    pair, plane_scene
) -> None:
    """Rows of texture repeated along the ground's y axis: each blob has a twin in image b that NNDR
    cannot tell apart, but the twin lies off the epipolar line of the (sideways) camera motion."""
    T_a, T_b = pair
    band = plane_scene.texture[:100]
    scene = dataclasses.replace(plane_scene, texture=np.tile(band, (20, 1)))
    img_a, img_b = scene.render(T_a), scene.render(T_b)
    plain = reconstruct(
        img_a, img_b, scene.K, T_a, T_b, SfmConfig(matcher="surf", surf_epipolar_guided=False)
    )
    guided = reconstruct(img_a, img_b, scene.K, T_a, T_b, SfmConfig(matcher="surf"))
    assert guided.stats["tracked"] > 3 * plain.stats["tracked"], (plain.stats, guided.stats)
    assert len(guided) > 100
    assert np.median(np.abs(guided.points_world_m[:, 2])) < 0.15
    assert np.mean(np.abs(guided.points_world_m[:, 2]) < 1.0) > 0.95
