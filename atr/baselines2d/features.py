"""The four detector/descriptor pairs of Table IV: OpenCV's GFTT, FAST, FREAK, BRISK, and our SURF.

OpenCV's contrib wheel has FREAK (cv2.xfeatures2d) and BRISK (cv2.BRISK_create in OpenCV 5's main module, or
xfeatures2d); SURF is non-free and absent, so #2 uses `atr.sfm.Surf` (Bay et al. 2008, six scale levels).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from atr.baselines2d.config import PAIRS, Baseline2dConfig
from atr.errors import ConfigError, InputError
from atr.sfm.config import SfmConfig


@dataclass(frozen=True)
class Features2d:
    """Keypoints and descriptors of one image.

    Attributes:
        xy_px: (N, 2) float32 keypoint positions, pixels.
        descriptors: (N, L) uint8 (binary: FREAK, BRISK) or float32 (SURF).
        binary: descriptors compare by Hamming distance (else L2).

    """

    xy_px: np.ndarray
    descriptors: np.ndarray
    binary: bool

    @property
    def nbytes(self) -> int:
        """Storage of keypoint positions and descriptors, bytes."""
        return int(self.xy_px.nbytes + self.descriptors.nbytes)


def _brisk() -> cv2.Feature2D:
    if hasattr(cv2, "BRISK_create"):
        return cv2.BRISK_create()
    return cv2.xfeatures2d.BRISK_create()


def _as_gray_u8(image: np.ndarray) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim == 3 and img.shape[2] == 3:
        img = cv2.cvtColor(np.ascontiguousarray(img, np.uint8), cv2.COLOR_RGB2GRAY)
    if img.ndim != 2 or img.dtype != np.uint8 or min(img.shape) < 8:
        raise InputError(
            f"image must be (H, W) or (H, W, 3) uint8 of at least 8x8 px; "
            f"got {img.dtype} {img.shape}"
        )
    return np.ascontiguousarray(img)


def cap_keypoints(
    keypoints: Sequence[cv2.KeyPoint],
    max_keypoints: int | None,
    grid_cell_px: int | None,
    image_shape: tuple[int, ...],
) -> list[cv2.KeyPoint]:
    """The keypoints a cap keeps, strongest first within each rank.

    Args:
        keypoints: detected keypoints.
        max_keypoints: how many to keep (None: all).
        grid_cell_px: side of the grid cells the cap is spread over, pixels (None: the strongest of the
            whole image). Spread, every cell keeps its strongest before any cell keeps its second, so a
            small target keeps its share of the cap even when the background's corners are stronger.
        image_shape: (H, W, ...) shape of the image, pixels.

    Returns:
        At most `max_keypoints` keypoints; ties are broken by position, so the kept subset never depends
        on OpenCV's internal order.

    """
    ordered = sorted(keypoints, key=lambda k: (-k.response, k.pt[1], k.pt[0]))
    if max_keypoints is None or len(ordered) <= max_keypoints:
        return ordered
    if grid_cell_px is None:
        return ordered[:max_keypoints]
    columns = -(-int(image_shape[1]) // grid_cell_px)
    rank_in_cell: dict[int, int] = {}
    ranks = []
    for k in ordered:
        cell = int(k.pt[1]) // grid_cell_px * columns + int(k.pt[0]) // grid_cell_px
        ranks.append(rank_in_cell.get(cell, 0))
        rank_in_cell[cell] = ranks[-1] + 1
    keep = sorted(range(len(ordered)), key=lambda i: (ranks[i], i))[:max_keypoints]
    return [ordered[i] for i in sorted(keep)]


def detect_and_describe(image: np.ndarray, pair: str, config: Baseline2dConfig) -> Features2d:
    """Detect and describe keypoints with one Table IV combination.

    Args:
        image: (H, W, 3) RGB or (H, W) grey uint8 image.
        pair: pipeline name "2d-1" .. "2d-4" (`PAIRS`).
        config: detector thresholds and the keypoint cap.

    Returns:
        The image's features (possibly empty).

    Raises:
        ConfigError: unknown pair.
        InputError: not an 8-bit image.

    """
    if pair not in PAIRS:
        raise ConfigError(f"2D pair {pair!r} must be one of {sorted(PAIRS)}")
    gray = _as_gray_u8(image)
    detector, descriptor = PAIRS[pair]
    if detector == "surf":
        sfm = SfmConfig(
            surf_max_keypoints=config.max_keypoints or 0,  # SfmConfig's 0: all
            surf_blob_threshold=config.surf_blob_threshold,
        )
        from atr.sfm import Surf  # numba kernels load only for this pair

        keypoints, desc = Surf(sfm).detect_and_compute(gray.astype(np.float32) / 255.0)
        return Features2d(
            np.ascontiguousarray(keypoints[:, :2], np.float32),
            np.ascontiguousarray(desc, np.float32),
            binary=False,
        )
    if detector == "gftt":
        gftt = cv2.GFTTDetector_create(
            maxCorners=0 if config.keypoint_grid_cell_px else config.max_keypoints or 0,  # 0: all
            qualityLevel=config.gftt_min_quality,
            minDistance=1.0,
            blockSize=config.gftt_filter_size_px,
            gradientSize=config.gftt_filter_size_px,
        )
        keypoints = gftt.detect(gray)
    else:
        fast = cv2.FastFeatureDetector_create(
            threshold=config.fast_threshold, nonmaxSuppression=True
        )
        keypoints = fast.detect(gray)
    keypoints = cap_keypoints(
        keypoints, config.max_keypoints, config.keypoint_grid_cell_px, gray.shape
    )
    # FREAK and BRISK need a scale for their sampling pattern; GFTT/FAST points carry the detector window.
    extractor = cv2.xfeatures2d.FREAK_create() if descriptor == "freak" else _brisk()
    keypoints, desc = extractor.compute(gray, keypoints)
    if desc is None or not keypoints:
        return Features2d(np.zeros((0, 2), np.float32), np.zeros((0, 64), np.uint8), binary=True)
    xy = np.array([k.pt for k in keypoints], np.float32)
    return Features2d(xy, np.ascontiguousarray(desc, np.uint8), binary=True)


def match_nndr(query: Features2d, train: Features2d, ratio: float) -> np.ndarray:
    """Nearest-neighbour distance ratio matching (Lowe 2004; §III-B threshold 0.8).

    Args:
        query: features matched from (the template).
        train: features matched into (the scene).
        ratio: a match is kept when its distance is below ratio x the second-nearest distance.

    Returns:
        (M, 2) int64 index pairs (query index, train index).

    """
    if len(query.xy_px) == 0 or len(train.xy_px) < 2:
        return np.zeros((0, 2), np.int64)
    matcher = cv2.BFMatcher(cv2.NORM_HAMMING if query.binary else cv2.NORM_L2)
    pairs = [
        (m[0].queryIdx, m[0].trainIdx)
        for m in matcher.knnMatch(query.descriptors, train.descriptors, k=2)
        if len(m) == 2 and m[0].distance < ratio * m[1].distance
    ]
    return np.array(pairs, np.int64).reshape(-1, 2)
