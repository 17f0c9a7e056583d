"""The whole two-view SfM module of the paper (§II-B-1): correspondences, then known-pose triangulation."""

from __future__ import annotations

import time

import numpy as np

from atr.sfm.config import SfmConfig
from atr.sfm.correspondences import (
    as_gray_u8,
    check_same_size,
    gftt_klt_with_stats,
    surf_with_stats,
)
from atr.sfm.dense import sgm_correspondences
from atr.sfm.triangulation import (
    SfmCloud,
    epipolar_distances_px,
    predict_on_fixation_plane,
    triangulate_known_pose,
    undistort_pixels,
    validate_distortion,
    validate_intrinsics,
    validate_pose,
)


def reconstruct(
    image_a: np.ndarray,
    image_b: np.ndarray,
    K: np.ndarray,
    T_world_cam_a: np.ndarray,
    T_world_cam_b: np.ndarray,
    config: SfmConfig,
    dist_coeffs: np.ndarray | None = None,
) -> SfmCloud:
    """Reconstruct a sparse world-frame cloud from one frame pair and its known camera poses.

    Args:
        image_a: (H, W) or (H, W, 3) BGR uint8 (or float in [0, 1]) image at frame t.
        image_b: the image at frame t + gap, same size and camera.
        K: (3, 3) camera matrix (pixels).
        T_world_cam_a: (4, 4) world-from-camera (OpenCV axes) at frame t, from the IMU.
        T_world_cam_b: (4, 4) world-from-camera at frame t + gap.
        config: matcher choice and every threshold.
        dist_coeffs: the lens's OpenCV distortion coefficients; None or zeros for images that are
            already undistorted. Keypoints are found on the images as given and their pixels
            undistorted before triangulation.

    Returns:
        The cloud; stats hold the counts of each stage and "time_<stage>_s" wall times (seconds,
        diagnostics only). Empty with a reason for a zero-baseline pair or an image without
        usable keypoints.

    Raises:
        InputError: malformed or differently sized images, malformed K or dist_coeffs, non-finite or
            non-rigid poses.

    """
    gray_a = as_gray_u8(image_a, "image_a")
    gray_b = as_gray_u8(image_b, "image_b")
    check_same_size(gray_a, gray_b)
    K = validate_intrinsics(K)
    dist = validate_distortion(dist_coeffs)
    T_wa = validate_pose(T_world_cam_a, "T_world_cam_a")
    T_wb = validate_pose(T_world_cam_b, "T_world_cam_b")

    baseline_m = float(np.linalg.norm(T_wb[:3, 3] - T_wa[:3, 3]))
    if baseline_m < config.min_baseline_m:
        # Checked before matching: a hovering pair costs nothing.
        return SfmCloud.empty(
            f"zero baseline {baseline_m:.3g} m < min_baseline_m {config.min_baseline_m} m",
            {"baseline_m": baseline_m},
        )

    start = time.perf_counter()
    if config.matcher == "sgm":
        pixels_a, pixels_b, stats, reason = sgm_correspondences(
            gray_a, gray_b, K, dist, T_wa, T_wb, config
        )
        if reason:
            return SfmCloud.empty(reason, dict(stats))
        dist = None  # rectification undistorted the images: the pixels are ideal ones
    elif config.matcher == "surf":
        pixels_a, pixels_b, stats = surf_with_stats(
            gray_a,
            gray_b,
            config,
            epipolar=lambda kp_a, kp_b: epipolar_distances_px(kp_a, kp_b, K, dist, T_wa, T_wb),
        )
    else:
        pixels_a, pixels_b, stats = gftt_klt_with_stats(
            gray_a,
            gray_b,
            config,
            predict=lambda corners: predict_on_fixation_plane(
                corners, K, dist, T_wa, T_wb, config.ground_z_m
            ),
        )
    matched = time.perf_counter()
    all_stats: dict[str, float | int] = dict(stats)
    all_stats["time_correspondences_s"] = matched - start
    if stats["keypoints"] == 0:
        return SfmCloud.empty("no keypoints in image_a (black or featureless image?)", all_stats)
    if config.matcher == "sgm" and stats["tracked"] == 0:
        return SfmCloud.empty("no pixel with a valid disparity (featureless pair?)", all_stats)

    if dist is not None:
        pixels_a, pixels_b = (
            undistort_pixels(pixels_a, K, dist),
            undistort_pixels(pixels_b, K, dist),
        )
    cloud = triangulate_known_pose(pixels_a, pixels_b, K, T_wa, T_wb, config)
    all_stats.update(cloud.stats)
    all_stats["time_triangulation_s"] = time.perf_counter() - matched
    cloud.stats = all_stats
    return cloud
