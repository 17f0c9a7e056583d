"""The whole two-view SfM module of the paper (§II-B-1): correspondences, then known-pose triangulation."""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from atr.regions import SearchRegion
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
    regions: Sequence[SearchRegion] = (),
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
        regions: where to look (track-guided search): dense matching (``sgm``) matches only the image
            window that holds them; the sparse matchers search the whole pair. Empty: the whole pair.

    Returns:
        The cloud; stats hold the counts of each stage and "time_<stage>_s" wall times (seconds,
        diagnostics only). Empty with a reason for a zero-baseline pair or an image without
        usable keypoints.

    Raises:
        InputError: malformed or differently sized images, malformed K or dist_coeffs, non-finite or
            non-rigid poses.

    """
    pair = _PosedPair.validated(image_a, image_b, K, T_world_cam_a, T_world_cam_b, dist_coeffs)
    baseline_m = float(np.linalg.norm(pair.T_wb[:3, 3] - pair.T_wa[:3, 3]))
    if baseline_m < config.min_baseline_m:
        # Checked before matching: a hovering pair costs nothing.
        return SfmCloud.empty(
            f"zero baseline {baseline_m:.3g} m < min_baseline_m {config.min_baseline_m} m",
            {"baseline_m": baseline_m},
        )

    start = time.perf_counter()
    pixels_a, pixels_b, stats, reason = _correspondences(pair, config, regions)
    if reason:
        return SfmCloud.empty(reason, dict(stats))
    matched = time.perf_counter()
    all_stats: dict[str, float | int] = dict(stats)
    all_stats["time_correspondences_s"] = matched - start
    if stats["keypoints"] == 0:
        return SfmCloud.empty("no keypoints in image_a (black or featureless image?)", all_stats)
    if config.matcher == "sgm" and stats["tracked"] == 0:
        return SfmCloud.empty("no pixel with a valid disparity (featureless pair?)", all_stats)

    # SGM's rectification undistorted the images: its pixels are ideal ones.
    dist = None if config.matcher == "sgm" else pair.dist
    if dist is not None:
        pixels_a, pixels_b = (
            undistort_pixels(pixels_a, pair.K, dist),
            undistort_pixels(pixels_b, pair.K, dist),
        )
    cloud = triangulate_known_pose(pixels_a, pixels_b, pair.K, pair.T_wa, pair.T_wb, config)
    all_stats.update(cloud.stats)
    all_stats["time_triangulation_s"] = time.perf_counter() - matched
    cloud.stats = all_stats
    return cloud


@dataclass(frozen=True)
class _PosedPair:
    """A validated frame pair: grey images, the camera and its known poses (``reconstruct``'s inputs)."""

    gray_a: np.ndarray
    gray_b: np.ndarray
    K: np.ndarray
    dist: np.ndarray | None
    T_wa: np.ndarray
    T_wb: np.ndarray

    @classmethod
    def validated(
        cls,
        image_a: np.ndarray,
        image_b: np.ndarray,
        K: np.ndarray,
        T_world_cam_a: np.ndarray,
        T_world_cam_b: np.ndarray,
        dist_coeffs: np.ndarray | None,
    ) -> _PosedPair:
        """The pair from ``reconstruct``'s arguments; InputError names the first bad one."""
        gray_a = as_gray_u8(image_a, "image_a")
        gray_b = as_gray_u8(image_b, "image_b")
        check_same_size(gray_a, gray_b)
        return cls(
            gray_a,
            gray_b,
            validate_intrinsics(K),
            validate_distortion(dist_coeffs),
            validate_pose(T_world_cam_a, "T_world_cam_a"),
            validate_pose(T_world_cam_b, "T_world_cam_b"),
        )


def _correspondences(
    pair: _PosedPair, config: SfmConfig, regions: Sequence[SearchRegion]
) -> tuple[np.ndarray, np.ndarray, Mapping[str, int | float], str]:
    """The pair's correspondences by the configured matcher: pixels in a and b, counters, and why
    there are none (empty when the matcher ran).
    """
    K, dist, T_wa, T_wb = pair.K, pair.dist, pair.T_wa, pair.T_wb
    if config.matcher == "sgm":
        return sgm_correspondences(pair.gray_a, pair.gray_b, K, dist, T_wa, T_wb, config, regions)
    if config.matcher == "surf":
        pixels_a, pixels_b, stats = surf_with_stats(
            pair.gray_a,
            pair.gray_b,
            config,
            epipolar=lambda kp_a, kp_b: epipolar_distances_px(kp_a, kp_b, K, dist, T_wa, T_wb),
        )
    else:
        pixels_a, pixels_b, stats = gftt_klt_with_stats(
            pair.gray_a,
            pair.gray_b,
            config,
            predict=lambda corners: predict_on_fixation_plane(
                corners, K, dist, T_wa, T_wb, config.ground_z_m
            ),
        )
    return pixels_a, pixels_b, stats, ""
