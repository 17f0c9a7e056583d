"""Dense correspondences of the pair rectified with the known pose (atr.sfm.dense), on the textured plane."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _poses import look_at  # noqa: E402

from atr.errors import ConfigError
from atr.regions import SearchRegion, points_in_regions
from atr.sfm import SfmConfig, reconstruct
from atr.sfm.correspondences import as_gray_u8
from atr.sfm.dense import sgm_correspondences

# Half size for every pair, as these tests' thresholds were set; the scale chosen from the range has
# its own test below.
SGM = SfmConfig(matcher="sgm", sgm_pixel_footprint_m=None)


def true_pixel_in_b(scene, pixels_a, T_a, T_b) -> np.ndarray:
    """Where a pixel of image a lands in image b, through the plane z = 0."""
    rays = np.c_[pixels_a, np.ones(len(pixels_a))] @ np.linalg.inv(scene.K).T @ T_a[:3, :3].T
    X = T_a[:3, 3] + rays * (-T_a[2, 3] / rays[:, 2])[:, None]
    T_bw = np.linalg.inv(T_b)
    uv = (X @ T_bw[:3, :3].T + T_bw[:3, 3]) @ scene.K.T
    return uv[:, :2] / uv[:, 2:3]


def oblique_pose(geo, centre: np.ndarray, yaw_rad: float = 0.0) -> np.ndarray:
    return geo.pose(geo.rot_z(yaw_rad) @ geo.R_WORLD_NADIR @ geo.rot_x(0.25), centre)


# Camera b's offset from camera a (50 m above the plane): sideways either way, along the image's
# columns (rectified into vertical stereo), and a little of everything at once.
MOTIONS = {
    "right": np.array([4.0, 0.0, 0.0]),
    "left": np.array([-4.0, 0.0, 0.0]),
    "down the image": np.array([0.0, 4.0, 0.0]),
    "up the image": np.array([0.0, -4.0, 0.0]),
    "oblique": np.array([3.0, -2.0, 0.4]),
}


def moved_pair(geo, motion: str) -> tuple[np.ndarray, np.ndarray]:
    """Camera a 50 m above the plane, looking obliquely; camera b moved by MOTIONS[motion]."""
    T_a = oblique_pose(geo, np.array([0.0, 0.0, 50.0]))
    return T_a, oblique_pose(geo, T_a[:3, 3] + MOTIONS[motion], yaw_rad=0.02)


@pytest.mark.parametrize("motion", sorted(MOTIONS))
def test_correspondences_follow_the_plane_whichever_way_the_camera_moves(
    geo, plane_scene, motion: str
) -> None:
    T_a, T_b = moved_pair(geo, motion)
    gray_a = as_gray_u8(plane_scene.render(T_a), "a")
    gray_b = as_gray_u8(plane_scene.render(T_b), "b")
    pa, pb, stats, reason = sgm_correspondences(gray_a, gray_b, plane_scene.K, None, T_a, T_b, SGM)
    assert reason == ""
    # most of the grid matches (the plane fills both images but for the border strips)
    assert stats["keypoints"] == 320 * 240 // 4
    assert len(pa) == stats["tracked"] > 0.5 * stats["keypoints"]
    err = np.linalg.norm(pb - true_pixel_in_b(plane_scene, pa, T_a, T_b), axis=1)
    assert np.median(err) < 0.5, np.median(err)
    assert np.mean(err < 2.0) > 0.97
    # ... and the points of the whole module lie on the plane
    cloud = reconstruct(
        plane_scene.render(T_a), plane_scene.render(T_b), plane_scene.K, T_a, T_b, SGM
    )
    assert len(cloud) > 0.5 * stats["keypoints"]
    assert np.median(np.abs(cloud.points_world_m[:, 2])) < 0.35  # ~0.3 px at 0.9 m/px


def test_motion_along_the_view_axis_gives_an_empty_cloud_with_the_reason(geo, plane_scene) -> None:
    T_a = oblique_pose(geo, np.array([0.0, 0.0, 50.0]))
    forward = T_a[:3, 2]  # the optical axis in the world
    T_b = oblique_pose(geo, T_a[:3, 3] + 4.0 * forward + np.array([0.5, 0.0, 0.0]))
    cloud = reconstruct(
        plane_scene.render(T_a), plane_scene.render(T_b), plane_scene.K, T_a, T_b, SGM
    )
    assert len(cloud) == 0
    assert "forward motion" in cloud.reason and "sgm_max_rectifying_rotation_deg" in cloud.reason
    # the sparse scheme has no such limit
    assert (
        len(
            reconstruct(
                plane_scene.render(T_a),
                plane_scene.render(T_b),
                plane_scene.K,
                T_a,
                T_b,
                SfmConfig(),
            )
        )
        > 0
    )


def test_a_coarser_grid_gives_fewer_points_of_the_same_surface(geo, plane_scene) -> None:
    T_a = oblique_pose(geo, np.array([0.0, 0.0, 50.0]))
    T_b = oblique_pose(geo, np.array([4.0, 0.5, 50.3]), yaw_rad=0.03)
    img_a, img_b = plane_scene.render(T_a), plane_scene.render(T_b)
    fine = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, SGM)
    coarse = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, replace(SGM, sgm_step_px=4))
    assert 3.0 < len(fine) / len(coarse) < 5.0  # a 4 x sparser grid
    full_size = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, replace(SGM, sgm_scale=1.0))
    assert len(full_size) > 3.0 * len(fine)
    for cloud in (coarse, full_size):
        assert np.median(np.abs(cloud.points_world_m[:, 2])) < 0.35  # ~0.3 px at 0.9 m/px


@pytest.mark.parametrize(("depth_m", "scale"), [(17.5, 0.25), (35.0, 0.5), (70.0, 1.0)])
def test_the_matching_scale_keeps_the_pixel_footprint_at_the_fixation_depth(
    geo, plane_scene, depth_m: float, scale: float
) -> None:
    # an orbit-like pair 60 deg above the horizon, both axes through the origin at depth_m
    up, back = depth_m * np.sin(np.deg2rad(60.0)), depth_m * np.cos(np.deg2rad(60.0))
    centre_a = np.array([0.0, -back, up])
    T_a = look_at(centre_a, np.zeros(3))
    T_b = look_at(centre_a + [0.075 * depth_m, 0.0, 0.0], np.zeros(3))
    gray_a = as_gray_u8(plane_scene.render(T_a), "a")
    gray_b = as_gray_u8(plane_scene.render(T_b), "b")
    # one pixel spans sgm_pixel_footprint_m = 0.1 m (f = 700 px), rounded to eighths
    config = SfmConfig(matcher="sgm", sgm_scale_step=0.125)
    pa, pb, stats, reason = sgm_correspondences(
        gray_a, gray_b, plane_scene.K, None, T_a, T_b, config
    )
    assert reason == ""
    assert stats["scale"] == scale
    w, h = plane_scene.size
    assert stats["keypoints"] == np.ceil(w * scale / 2) * np.ceil(h * scale / 2)
    assert len(pa) > 0.5 * stats["keypoints"]
    err = np.linalg.norm(pb - true_pixel_in_b(plane_scene, pa, T_a, T_b), axis=1)
    assert np.median(err) < 0.5 / scale, np.median(err)  # ~0.3 px of the scaled image

    # without a fixation depth (parallel axes), or with the footprint unset: sgm_scale
    T_b_parallel = geo.pose(T_a[:3, :3], centre_a + [0.075 * depth_m, 0.0, 0.0])
    gray_b_parallel = as_gray_u8(plane_scene.render(T_b_parallel), "b")
    for T_b_, gray_b_, config_ in (
        (T_b_parallel, gray_b_parallel, config),
        (T_b, gray_b, replace(config, sgm_pixel_footprint_m=None, sgm_scale=0.375)),
    ):
        stats_ = sgm_correspondences(gray_a, gray_b_, plane_scene.K, None, T_a, T_b_, config_)[2]
        assert stats_["scale"] == config_.sgm_scale


def test_the_search_reaches_the_nearest_ground_the_image_sees(plane_scene) -> None:
    # a camera 25 deg above the horizon, 20 m from the point it looks at: the image's foot sees the
    # ground at ~13 m, nearer than the (deliberately short) minimum search reaches
    distance_m = 20.0
    centre_a = np.array([0.0, -distance_m * np.cos(0.436), distance_m * np.sin(0.436)])
    T_a = look_at(centre_a, np.zeros(3))
    T_b = look_at(centre_a + [0.075 * distance_m, 0.0, 0.0], np.zeros(3))
    gray_a = as_gray_u8(plane_scene.render(T_a), "a")
    gray_b = as_gray_u8(plane_scene.render(T_b), "b")
    short = replace(SGM, sgm_disparities_px=16)
    pa, pb, stats, reason = sgm_correspondences(
        gray_a, gray_b, plane_scene.K, None, T_a, T_b, short
    )
    assert reason == ""
    err = np.linalg.norm(pb - true_pixel_in_b(plane_scene, pa, T_a, T_b), axis=1)
    assert len(pa) > 0.5 * stats["keypoints"]
    assert np.median(err) < 0.5, np.median(err)
    assert np.mean(err < 2.0) > 0.95
    # the foot of the image, where the disparity is largest, is matched too
    assert pa[:, 1].max() > 0.9 * plane_scene.size[1]

    # a ground believed far below asks for no more than the minimum search: most pixels then lie
    # beyond it, and are not left unmatched but matched wrongly
    far_ground = replace(short, ground_z_m=-1000.0)
    pa_, pb_, stats_, _ = sgm_correspondences(
        gray_a, gray_b, plane_scene.K, None, T_a, T_b, far_ground
    )
    assert stats_["disparities"] < stats["disparities"]
    err_ = np.linalg.norm(pb_ - true_pixel_in_b(plane_scene, pa_, T_a, T_b), axis=1)
    assert len(pa_) > 0.5 * stats_["keypoints"]
    assert np.sum(err_ < 2.0) < 0.5 * len(pa_)


@pytest.mark.parametrize(("small", "large"), [(8.0, 8.0), (8.0, 2.0)])
def test_a_large_jump_penalty_not_above_the_small_one_is_refused(
    small: float, large: float
) -> None:
    with pytest.raises(ConfigError, match="k_sgm_large_jump_penalty"):
        SfmConfig(k_sgm_small_jump_penalty=small, k_sgm_large_jump_penalty=large)


def _where_the_axis_meets_the_plane(T_a: np.ndarray) -> np.ndarray:
    axis = T_a[:3, 2]
    return (T_a[:3, 3] + axis * (-T_a[2, 3] / axis[2]))[:2]


@pytest.mark.parametrize("motion", sorted(MOTIONS))
def test_a_search_region_matches_its_window_as_the_whole_pair_does(
    geo, plane_scene, motion: str
) -> None:
    T_a, T_b = moved_pair(geo, motion)
    img_a, img_b = plane_scene.render(T_a), plane_scene.render(T_b)
    region = SearchRegion(_where_the_axis_meets_the_plane(T_a), 4.0, -0.5, 1.0)
    whole = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, SGM)
    band = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, SGM, regions=[region])
    assert band.reason == ""
    assert band.stats["window_fraction"] < 0.7  # the window, not the pair, was matched
    _assert_the_region_s_points_are_the_whole_pair_s(whole, band, region)


def _assert_the_region_s_points_are_the_whole_pair_s(whole, cloud, region: SearchRegion) -> None:
    """The same grid pixels, matched alike (within 1 cm), each once."""
    inside_whole = whole.points_world_m[points_in_regions(whole.points_world_m, [region])]
    inside = cloud.points_world_m[points_in_regions(cloud.points_world_m, [region])]
    assert len(inside_whole) > 100
    gap_m, _ = cKDTree(inside_whole).query(inside)
    missed_m, _ = cKDTree(inside).query(inside_whole)
    assert np.mean(gap_m < 0.01) > 0.95
    assert np.mean(missed_m < 0.01) > 0.95
    assert len(np.unique(inside.round(6), axis=0)) == len(inside)


def test_a_search_region_outside_the_images_gives_an_empty_cloud_with_the_reason(
    geo, plane_scene
) -> None:
    T_a, T_b = moved_pair(geo, "right")
    far = SearchRegion(_where_the_axis_meets_the_plane(T_a) + 500.0, 6.0, -0.5, 1.0)
    img_a, img_b = plane_scene.render(T_a), plane_scene.render(T_b)
    cloud = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, SGM, regions=[far])
    assert len(cloud) == 0
    assert "outside the images" in cloud.reason


def test_a_window_searches_as_far_as_the_ground_its_region_sees(plane_scene) -> None:
    # the camera of the nearest-ground test: the image's foot sees the ground at ~13 m, the region
    # around the point it looks at ~20 m away, so the window needs a shorter search than the pair
    distance_m = 20.0
    centre_a = np.array([0.0, -distance_m * np.cos(0.436), distance_m * np.sin(0.436)])
    T_a = look_at(centre_a, np.zeros(3))
    T_b = look_at(centre_a + [0.075 * distance_m, 0.0, 0.0], np.zeros(3))
    img_a, img_b = plane_scene.render(T_a), plane_scene.render(T_b)
    short = replace(SGM, sgm_disparities_px=16, sgm_region_bands=False)
    region = SearchRegion(np.zeros(2), 1.5, -0.5, 1.0)
    whole = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, short)
    band = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, short, regions=[region])
    assert band.stats["disparities"] < whole.stats["disparities"]
    heights = {}
    for name, cloud in (("whole", whole), ("band", band)):
        inside = cloud.points_world_m[points_in_regions(cloud.points_world_m, [region])]
        heights[name] = np.abs(inside[:, 2])  # above or below the plane, metres
    assert len(heights["band"]) > 0.9 * len(heights["whole"]) > 100
    # on the plane as closely as the whole pair's
    assert np.median(heights["band"]) < 1.2 * np.median(heights["whole"]), heights
    assert np.mean(heights["band"] < 0.1) > 0.95
    # without the rule the window searches what the whole pair does
    image_ground = replace(short, sgm_window_ground=False)
    band_ = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, image_ground, regions=[region])
    assert band_.stats["disparities"] == whole.stats["disparities"]


def test_each_region_is_matched_in_its_own_band_of_disparities(geo, plane_scene) -> None:
    T_a, T_b = moved_pair(geo, "oblique")
    img_a, img_b = plane_scene.render(T_a), plane_scene.render(T_b)
    centre = _where_the_axis_meets_the_plane(T_a)
    # two regions well apart: one window would hold both and the ground between them
    regions = [SearchRegion(centre + offset, 3.0, -0.5, 1.0) for offset in ([-9.0, 0], [9.0, 0])]
    whole = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, SGM)
    one_window = replace(SGM, sgm_region_bands=False)
    window = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, one_window, regions=regions)
    bands = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, SGM, regions=regions)
    assert bands.reason == ""
    assert bands.stats["bands"] == 2
    assert bands.stats["window_fraction"] < 0.6 * window.stats["window_fraction"]
    assert bands.stats["disparities"] < 0.5 * window.stats["disparities"]
    for region in regions:
        _assert_the_region_s_points_are_the_whole_pair_s(whole, bands, region)


@pytest.mark.parametrize("motion", ["right", "down the image", "oblique"])
def test_a_band_reaches_the_ground_its_window_sees_beyond_the_region(
    geo, plane_scene, motion: str
) -> None:
    # a region 20 m above the plane: every ray through it sees the ground behind it, beyond the
    # disparities of the region's own outline
    T_a, T_b = moved_pair(geo, motion)
    img_a, img_b = plane_scene.render(T_a), plane_scene.render(T_b)
    region = SearchRegion(_where_the_axis_meets_the_plane(T_a), 4.0, 18.0, 22.0)
    cloud = reconstruct(img_a, img_b, plane_scene.K, T_a, T_b, SGM, regions=[region])
    assert len(cloud) > 1000
    # the ground is matched where it lies, not mistaken for a surface in the band
    assert np.mean(np.abs(cloud.points_world_m[:, 2]) < 1.0) > 0.99
