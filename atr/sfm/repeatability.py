"""Detector repeatability and matching score under a known homography (Mikolajczyk et al. 2005,
simplified to point distances), used to compare our SURF with OpenCV's SIFT.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


def map_points(H: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 3x3 homography to (N, 2) pixel coordinates; returns (N, 2) float64."""
    p = np.c_[np.asarray(points, np.float64), np.ones(len(points))] @ np.asarray(H, np.float64).T
    return p[:, :2] / p[:, 2:3]


@dataclass(frozen=True)
class HomographyPair:
    """Two images of one plane (or one view turned), related by a known homography.

    Attributes:
        H_b_a: (3, 3) homography taking image a pixels to image b pixels.
        size_a: (width, height) of image a, pixels.
        size_b: (width, height) of image b, pixels.

    """

    H_b_a: np.ndarray
    size_a: tuple[int, int]
    size_b: tuple[int, int]


def _common(
    points_a: np.ndarray, points_b: np.ndarray, pair: HomographyPair
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Keypoints of a mapped into b, which of them b sees, which keypoints of b a sees, and how many
    keypoints both images see.
    """
    mapped_a = map_points(pair.H_b_a, points_a)
    back_b = map_points(np.linalg.inv(pair.H_b_a), points_b)
    w_b, h_b = pair.size_b
    w_a, h_a = pair.size_a
    in_b = (
        (mapped_a[:, 0] >= 0)
        & (mapped_a[:, 0] < w_b)
        & (mapped_a[:, 1] >= 0)
        & (mapped_a[:, 1] < h_b)
    )
    in_a = (back_b[:, 0] >= 0) & (back_b[:, 0] < w_a) & (back_b[:, 1] >= 0) & (back_b[:, 1] < h_a)
    return mapped_a, in_b, in_a, min(int(in_b.sum()), int(in_a.sum()))


def repeatability(
    points_a: np.ndarray, points_b: np.ndarray, pair: HomographyPair, tolerance_px: float
) -> float:
    """Fraction of keypoints re-detected in the other image.

    Args:
        points_a: (Na, 2) keypoints in image a (pixels).
        points_b: (Nb, 2) keypoints in image b.
        pair: the homography from image a to image b and both image sizes.
        tolerance_px: a keypoint of a is repeated when one of b lies within this distance of its
            mapped position (pixels of image b).

    Returns:
        repeated / min(keypoints of a seen in b, keypoints of b seen in a); 0 when none is common.

    """
    mapped_a, in_b, in_a, n_common = _common(points_a, points_b, pair)
    if n_common == 0:
        return 0.0
    distance, _ = cKDTree(np.asarray(points_b)[in_a]).query(mapped_a[in_b], k=1)
    return min(float(np.count_nonzero(distance <= tolerance_px)) / n_common, 1.0)


def matching_score(
    points_a: np.ndarray,
    points_b: np.ndarray,
    matches: tuple[np.ndarray, np.ndarray],
    pair: HomographyPair,
    tolerance_px: float,
) -> tuple[float, float]:
    """Correct matches over common keypoints, and the precision of the matches.

    Args:
        points_a: (Na, 2) keypoints in image a (pixels).
        points_b: (Nb, 2) keypoints in image b.
        matches: (index_a, index_b), (M,) indices of the matched keypoints in each image.
        pair: the homography from image a to image b and both image sizes.
        tolerance_px: a match is correct when the mapped keypoint of a is this close to its partner.

    Returns:
        (matching score = correct / min(common keypoints), precision = correct / M).

    """
    index_a, index_b = matches
    mapped_a, _, _, n_common = _common(points_a, points_b, pair)
    if len(index_a) == 0 or n_common == 0:
        return 0.0, 0.0
    error = np.linalg.norm(mapped_a[index_a] - np.asarray(points_b)[index_b], axis=1)
    correct = int(np.count_nonzero(error <= tolerance_px))
    return correct / n_common, correct / len(index_a)
