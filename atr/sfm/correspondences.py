"""Two-view keypoint correspondences (paper §II-B-1): GFTT + KLT, and SURF + NNDR.

GFTT, KLT and the brute-force matcher are OpenCV's; SURF is ours (atr.sfm.surf), since OpenCV's
wheels exclude it.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from atr.errors import InputError
from atr.sfm.config import SfmConfig
from atr.sfm.surf import Surf

# Correspondence pairs: (N, 2) float32 pixels in image a, (N, 2) float32 pixels in image b.
Correspondences = tuple[np.ndarray, np.ndarray]


def as_gray_u8(image: np.ndarray, name: str) -> np.ndarray:
    """Grey uint8 view of an image.

    Args:
        image: (H, W) or (H, W, 3) (BGR) uint8, or float in [0, 1].
        name: argument name for error messages.

    Returns:
        (H, W) uint8.

    Raises:
        InputError: empty, wrong rank or channel count, non-finite values.

    """
    img = np.asarray(image)
    if img.ndim == 3 and img.shape[2] == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    elif img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.ndim != 2 or img.size == 0:
        raise InputError(
            f"{name} has shape {np.asarray(image).shape}, expected (H, W) or (H, W, 3)"
        )
    if img.dtype == np.uint8:
        return np.ascontiguousarray(img)
    if not np.issubdtype(img.dtype, np.floating):
        raise InputError(f"{name} has dtype {img.dtype}, expected uint8 or float in [0, 1]")
    if not np.all(np.isfinite(img)):
        raise InputError(f"{name} contains non-finite values")
    return np.clip(np.rint(img * 255.0), 0, 255).astype(np.uint8)


def check_same_size(image_a: np.ndarray, image_b: np.ndarray) -> None:
    """Raise InputError unless both images have the same height and width."""
    if image_a.shape[:2] != image_b.shape[:2]:
        raise InputError(
            f"image sizes differ: image_a {image_a.shape[:2]} vs image_b {image_b.shape[:2]} "
            "(both frames must come from the same camera)"
        )


def gftt_klt_correspondences(
    image_a: np.ndarray, image_b: np.ndarray, config: SfmConfig
) -> Correspondences:
    """GFTT corners in image a tracked into image b by pyramidal KLT with a forward-backward check
    (§II-B-1): the pixels of ``gftt_klt_with_stats`` without its counters.
    """
    return gftt_klt_with_stats(image_a, image_b, config)[:2]


def gftt_klt_with_stats(
    image_a: np.ndarray,
    image_b: np.ndarray,
    config: SfmConfig,
    predict: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray] | None] | None = None,
) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """GFTT corners in image a tracked into image b by pyramidal KLT with a forward-backward check.

    Args:
        image_a: (H, W) or (H, W, 3) uint8 (or float in [0, 1]) first image.
        image_b: the second image, same size.
        config: GFTT and KLT settings (§II-B-1).
        predict: maps corners of image a to their predicted pixels in image b and a mask of the
            corners the prediction holds for (``predict_on_fixation_plane`` with the known poses), or
            to None. Given, it is called with the corners the paper's tracker loses, and those the
            mask keeps are tracked again by a shallow KLT started at the prediction
            (``klt_aided_pyramid_levels``), counted in "tracked_aided".

    Returns:
        (N, 2) float32 pixels in image a, (N, 2) float32 pixels in image b (N may be 0: a black or
        featureless image), and the counters keypoints, tracked, rejected_forward_backward,
        tracked_aided.

    Raises:
        InputError: malformed images or different sizes.

    """
    gray_a = as_gray_u8(image_a, "image_a")
    gray_b = as_gray_u8(image_b, "image_b")
    check_same_size(gray_a, gray_b)
    corners = detect_gftt(gray_a, config)
    stats = {
        "keypoints": int(corners.shape[0]),
        "tracked": 0,
        "rejected_forward_backward": 0,
        "tracked_aided": 0,
    }
    if corners.shape[0] == 0:
        return _no_pairs() + (stats,)

    # OpenCV's Python binding takes images here, not prebuilt pyramids; it stops adding levels
    # once a level is smaller than the window, so 13 levels is an upper bound.
    tracked, fb_ok, pixels_b = _klt_forward_backward(
        gray_a, gray_b, corners, config.klt_pyramid_levels, config
    )
    good = tracked & fb_ok
    stats["tracked"] = int(np.count_nonzero(good))
    stats["rejected_forward_backward"] = int(np.count_nonzero(tracked & ~fb_ok))

    lost = np.flatnonzero(~good)
    prediction = None
    if predict is not None and config.klt_aided_pyramid_levels and len(lost):
        prediction = predict(corners[lost])
    if prediction is not None:
        predicted_b, holds = prediction
        retry = lost[holds]
        if len(retry):
            tracked_r, fb_ok_r, pixels_r = _klt_forward_backward(
                gray_a,
                gray_b,
                corners[retry],
                config.klt_aided_pyramid_levels,
                config,
                guess_b=predicted_b[holds],
            )
            found = retry[tracked_r & fb_ok_r]
            pixels_b[found] = pixels_r[tracked_r & fb_ok_r]
            good[found] = True
            stats["tracked_aided"] = int(len(found))
    return (
        np.ascontiguousarray(corners[good], np.float32),
        np.ascontiguousarray(pixels_b[good], np.float32),
        stats,
    )


def _klt_forward_backward(
    gray_a: np.ndarray,
    gray_b: np.ndarray,
    corners: np.ndarray,
    levels: int,
    config: SfmConfig,
    guess_b: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pyramidal KLT from a to b and back (Kalal et al.'s forward-backward check).

    Returns:
        (N,) tracked both ways and inside image b, (N,) forward-backward error within the gate, and
        (N, 2) float32 pixels in image b. With ``guess_b`` both passes start from it (the backward one
        from the same displacement reversed) instead of from the corner's own position.

    """
    window = (config.klt_window_px, config.klt_window_px)
    criteria = (
        cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS,
        config.klt_iterations,
        config.klt_epsilon_px,
    )
    p0 = corners.reshape(-1, 1, 2).astype(np.float32)
    flags, start_b, start_a = 0, None, None
    if guess_b is not None:
        flags = cv2.OPTFLOW_USE_INITIAL_FLOW
        start_b = guess_b.reshape(-1, 1, 2).astype(np.float32)
    p1, status_fw, _ = cv2.calcOpticalFlowPyrLK(
        gray_a,
        gray_b,
        p0,
        start_b,
        winSize=window,
        maxLevel=levels - 1,
        criteria=criteria,
        flags=flags,
    )
    if guess_b is not None:
        start_a = (p1 - (start_b - p0)).astype(np.float32)
    p0_back, status_bw, _ = cv2.calcOpticalFlowPyrLK(
        gray_b,
        gray_a,
        p1,
        start_a,
        winSize=window,
        maxLevel=levels - 1,
        criteria=criteria,
        flags=flags,
    )
    fb_error = np.linalg.norm((p0_back - p0).reshape(-1, 2), axis=1)
    h, w = gray_b.shape
    p1f = p1.reshape(-1, 2)
    inside = (p1f[:, 0] >= 0) & (p1f[:, 0] <= w - 1) & (p1f[:, 1] >= 0) & (p1f[:, 1] <= h - 1)
    tracked = (status_fw.ravel() == 1) & (status_bw.ravel() == 1) & inside
    return tracked, fb_error <= config.klt_max_forward_backward_px, p1f.copy()


def detect_gftt(gray_u8: np.ndarray, config: SfmConfig) -> np.ndarray:
    """Shi-Tomasi corners after the 3x3 Gaussian pre-filter (§II-B-1).

    Args:
        gray_u8: (H, W) uint8.
        config: gftt_* settings.

    Returns:
        (N, 2) float32 pixel coordinates (x, y), strongest first; N = 0 on a flat image.

    """
    k = config.gftt_filter_size_px
    smoothed = cv2.GaussianBlur(gray_u8, (k, k), 0) if k > 1 else gray_u8
    corners = cv2.goodFeaturesToTrack(
        smoothed,
        maxCorners=config.gftt_max_corners,
        qualityLevel=config.gftt_min_quality,
        minDistance=config.gftt_min_distance_px,
        blockSize=config.gftt_block_size_px,
    )
    if corners is None:
        return np.zeros((0, 2), np.float32)
    return corners.reshape(-1, 2).astype(np.float32)


def surf_correspondences(
    image_a: np.ndarray, image_b: np.ndarray, config: SfmConfig
) -> Correspondences:
    """SURF keypoints in both images matched by the nearest-neighbour distance ratio (§II-B-1): the
    pixels of ``surf_with_stats`` without its counters.
    """
    return surf_with_stats(image_a, image_b, config)[:2]


def surf_with_stats(
    image_a: np.ndarray,
    image_b: np.ndarray,
    config: SfmConfig,
    epipolar: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """SURF keypoints in both images matched by the nearest-neighbour distance ratio (§II-B-1).

    Args:
        image_a: (H, W) or (H, W, 3) uint8 (or float in [0, 1]) first image.
        image_b: the second image, same size.
        config: surf_* settings and surf_nndr.
        epipolar: maps keypoints of a and b to their (Na, Nb) epipolar distances in pixels
            (``epipolar_distances_px`` with the known poses), or None. Given, and with
            ``surf_epipolar_guided``, NNDR compares only the keypoints of b within the triangulation's
            reprojection gate of each epipolar line, and a pair must pass it from both sides.

    Returns:
        (N, 2) float32 pixels in image a, (N, 2) float32 pixels in image b (N may be 0), and the
        counters keypoints (image a), keypoints_b, tracked (= matched).

    Raises:
        InputError: malformed images or different sizes.

    """
    gray_a = as_gray_u8(image_a, "image_a")
    gray_b = as_gray_u8(image_b, "image_b")
    check_same_size(gray_a, gray_b)
    surf = Surf(config)
    kp_a, desc_a = surf.detect_and_compute(gray_a.astype(np.float32) / 255.0)
    kp_b, desc_b = surf.detect_and_compute(gray_b.astype(np.float32) / 255.0)
    stats = {"keypoints": int(kp_a.shape[0]), "keypoints_b": int(kp_b.shape[0]), "tracked": 0}
    if kp_a.shape[0] == 0 or kp_b.shape[0] < 2:
        return _no_pairs() + (stats,)
    if epipolar is not None and config.surf_epipolar_guided:
        # Only candidates the triangulation could keep compete: a wrong candidate off the line can
        # no longer make the right one fail the ratio test. With fewer rivals a wrong candidate on
        # the line passes more easily too, so the test must hold both ways.
        near = epipolar(kp_a[:, :2], kp_b[:, :2]) <= config.max_reprojection_px
        near_a, near_b = np.divmod(np.flatnonzero(near), near.shape[1])  # 8x faster than nonzero
        index_a, index_b = match_nndr_both_ways(desc_a, desc_b, config.surf_nndr, (near_a, near_b))
    else:
        index_a, index_b = match_nndr(desc_a, desc_b, config.surf_nndr)
    stats["tracked"] = int(index_a.shape[0])
    return kp_a[index_a, :2].copy(), kp_b[index_b, :2].copy(), stats


def match_nndr(
    descriptors_a: np.ndarray,
    descriptors_b: np.ndarray,
    ratio: float,
    candidates: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Nearest-neighbour distance ratio matching (Mikolajczyk & Schmid 2005), one-to-one.

    A descriptor of a matches its nearest neighbour in b when that is closer than `ratio` times the
    second nearest; when several descriptors of a pick the same one of b, only the closest is kept.

    Args:
        descriptors_a: (Na, D) float32.
        descriptors_b: (Nb, D) float32, Nb >= 2.
        ratio: NNDR threshold in (0, 1].
        candidates: (K,) indices into a and (K,) indices into b, the pairs that may match (e.g. those
            near the epipolar line), sorted by index into a; None allows all. A descriptor of a with
            fewer than two candidates has no ratio and matches nothing.

    Returns:
        (M,) int64 indices into a and (M,) int64 indices into b, sorted by index into a.

    """
    desc_a = np.asarray(descriptors_a, np.float32)
    desc_b = np.asarray(descriptors_b, np.float32)
    if candidates is None:
        knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(desc_a, desc_b, k=2)
        rows = np.array(
            [
                (m[0].queryIdx, m[0].trainIdx, m[0].distance, m[1].distance)
                for m in knn
                if len(m) == 2
            ],
            dtype=np.float64,
        ).reshape(-1, 4)
    else:
        cand_a, cand_b = (np.asarray(c, np.int64) for c in candidates)
        distance = np.linalg.norm(desc_a[cand_a] - desc_b[cand_b], axis=1)
        rows = _two_nearest(cand_a, cand_b, distance)
    return _ratio_one_to_one(rows, ratio)


def match_nndr_both_ways(
    descriptors_a: np.ndarray,
    descriptors_b: np.ndarray,
    ratio: float,
    candidates: tuple[np.ndarray, np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    """The pairs that ``match_nndr`` keeps from a to b and from b to a, among the same candidates.

    Returns:
        (M,) int64 indices into a and (M,) int64 indices into b, sorted by index into a.

    """
    cand_a, cand_b = (np.asarray(c, np.int64) for c in candidates)
    distance = np.linalg.norm(
        np.asarray(descriptors_a, np.float32)[cand_a]
        - np.asarray(descriptors_b, np.float32)[cand_b],
        axis=1,
    )
    index_a, index_b = _ratio_one_to_one(_two_nearest(cand_a, cand_b, distance), ratio)
    back_b, back_a = _ratio_one_to_one(_two_nearest(cand_b, cand_a, distance), ratio)
    n_b = len(descriptors_b)
    both = np.isin(index_a * n_b + index_b, back_a * n_b + back_b)
    return index_a[both], index_b[both]


def _two_nearest(query: np.ndarray, train: np.ndarray, distance: np.ndarray) -> np.ndarray:
    """(query, nearest train, its distance, second distance) for each query with two or more
    candidates among the (query, train, distance) triples.

    Distances only for the candidate pairs, a few per keypoint along its epipolar line, instead of a
    brute-force search over all of b behind a mask. Equal distances go to the candidate that comes
    first, the lower index when the pairs come sorted by the other index, as OpenCV breaks them.
    """
    if len(query) == 0:
        return np.zeros((0, 4))
    # one stable sort on query, then distance: query x 2^k is exact and leaves the distance's bits
    span = 2.0 ** np.ceil(np.log2(float(distance.max()) + 1.0))
    order = np.argsort(query * span + distance, kind="stable")
    q, t, d = query[order], train[order], distance[order]
    first = np.flatnonzero(np.r_[True, q[1:] != q[:-1]])
    first = first[np.r_[first[1:], len(q)] - first >= 2]
    return np.c_[q[first], t[first], d[first], d[first + 1]].astype(np.float64)


def _ratio_one_to_one(rows: np.ndarray, ratio: float) -> tuple[np.ndarray, np.ndarray]:
    passed = rows[rows[:, 2] < ratio * rows[:, 3]]
    # One-to-one: for each b keep the closest a (ties broken by lower index a, deterministic).
    order = np.lexsort((passed[:, 0], passed[:, 2]))
    passed = passed[order]
    _, first = np.unique(passed[:, 1], return_index=True)
    passed = passed[np.sort(first)]
    passed = passed[np.argsort(passed[:, 0], kind="stable")]
    return passed[:, 0].astype(np.int64), passed[:, 1].astype(np.int64)


def _no_pairs() -> tuple[np.ndarray, np.ndarray]:
    return np.zeros((0, 2), np.float32), np.zeros((0, 2), np.float32)
