"""Dense two-view correspondences with the known relative pose: rectification and semi-global matching.

Not the paper's scheme (§II-B-1 tracks sparse GFTT corners or matches SURF blobs); ours, for the scenes the
sparse schemes leave with too few points on the target (docs/sfm.md, "Dense matching"). The IMU gives the
relative pose, so both images can be rectified (OpenCV's stereoRectify: corresponding points then lie on the
same row) and matched for every pixel along that row with Hirschmüller's semi-global matching (OpenCV's
StereoSGBM). Each valid disparity is a correspondence, mapped back to the pixels of the original images and
triangulated like the sparse ones, so the gates and the per-point sigma stay the same.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from atr.regions import SearchRegion
from atr.sfm.config import SfmConfig
from atr.sfm.triangulation import fixation_depth_m, relative_camera_pose

# A window's margin around the regions' outlines, in matching blocks. Along the baseline two blocks keep
# every block that matches a region's pixel inside. Across it, semi-global matching's top-down path and its
# speckle filter see further: with two blocks a window at 100 m and 0 degrees kept 613 of the whole pair's
# 754 points in its region, with eight 678, with sixteen all; on tuning seeds 101-102 (T-72, every 5th
# scene, cylinders of 1.0 x the footprint) pooled F1 0.926 / 0.928 / 0.931 (the whole pair's) at
# 1.4-1.5 / 1.6-1.7 / 1.8-2.0 x the reference workload per scene (docs/sfm.md, "Matching only where the
# search looks").
WINDOW_MARGIN_ALONG_BLOCKS = 2.0
WINDOW_MARGIN_ACROSS_BLOCKS = 8.0
# A region's band of disparities reaches this many matching blocks beyond those of its outline and its
# ground, so a surface in the region (and its noise) lies inside the band, clear of its ends, where a
# disparity that truly lies beyond the band is clipped to.
BAND_MARGIN_BLOCKS = 1.0

REGIONS_OUTSIDE = "the search regions lie outside the images"

# ((x0, y0), (x1, y1)) of a full-size rectified image
_Window = tuple[tuple[int, int], tuple[int, int]]


def sgm_correspondences(
    gray_a: np.ndarray,
    gray_b: np.ndarray,
    K: np.ndarray,
    dist_coeffs: np.ndarray | None,
    T_world_cam_a: np.ndarray,
    T_world_cam_b: np.ndarray,
    config: SfmConfig,
    regions: Sequence[SearchRegion] = (),
) -> tuple[np.ndarray, np.ndarray, dict[str, int | float], str]:
    """Correspondences of a pixel grid of image a in image b, from the disparity of the rectified pair.

    Args:
        gray_a: (H, W) uint8 image at frame t.
        gray_b: (H, W) uint8 image at frame t + gap.
        K: (3, 3) camera matrix.
        dist_coeffs: the lens's distortion coefficients or None; rectification undistorts.
        T_world_cam_a: (4, 4) world-from-camera at frame t (OpenCV axes).
        T_world_cam_b: (4, 4) world-from-camera at frame t + gap.
        config: the sgm_* settings.
        regions: where to look (track-guided search, ``atr.tracking.guided_search``): only the window of
            the rectified pair that holds the regions' outlines in both images, widened along the baseline
            by the disparity search so that every pixel in it can find its partner, is rectified and
            matched. Empty: the whole pair.

    Returns:
        (pixels_a, pixels_b, stats, reason): (N, 2) float64 undistorted pixels in each image (so they are
        triangulated without undistortion), counters "keypoints" (grid pixels matched) and "tracked" (with a
        valid disparity), the matching "scale" and the "disparities" searched (at that scale), and an empty
        reason; or a reason and no pixels when the motion cannot be rectified (the baseline too close to the
        optical axis: the epipole lies in or near the image) or the regions lie outside both images. With
        regions, "window_fraction" is the share of the image's pixels the window holds.

    """
    T_ba = relative_camera_pose(T_world_cam_a, T_world_cam_b)
    stats: dict[str, int | float] = {"keypoints": 0, "tracked": 0}
    rotation_deg = _rectifying_rotation_deg(T_ba[:3, :3], T_ba[:3, 3])
    if rotation_deg > config.sgm_max_rectifying_rotation_deg:
        reason = (
            f"baseline {90.0 - rotation_deg:.1f} deg from the optical axis: rectifying would turn a camera "
            f"by {rotation_deg:.1f} deg > sgm_max_rectifying_rotation_deg "
            f"{config.sgm_max_rectifying_rotation_deg} (forward motion)"
        )
        return np.zeros((0, 2)), np.zeros((0, 2)), stats, reason
    dist = np.zeros(5) if dist_coeffs is None else np.asarray(dist_coeffs, np.float64)
    scale = matching_scale(K, T_world_cam_a, T_world_cam_b, config)
    rect = _stereo_rectify(K, dist, gray_a.shape[::-1], T_ba)
    stats["scale"] = scale
    window = None
    if regions and config.sgm_region_bands:
        bands = _region_bands(regions, T_world_cam_a, rect, scale, config)
        if bands is not None:
            return _band_correspondences(bands, rect, scale, gray_a, gray_b, K, dist, config, stats)
    if regions:
        box = _regions_box(regions, T_world_cam_a, rect, scale, config)
        if box is None:
            return np.zeros((0, 2)), np.zeros((0, 2)), stats, REGIONS_OUTSIDE
        # only pixels whose rays cross the regions can give their points: the search reaches the
        # nearest ground those pixels see, not the ground at the image's foot
        n_disparities = _disparities_to_search(
            rect, K, dist, T_world_cam_a, scale, config, box if config.sgm_window_ground else None
        )
        window = _widened(box, rect, n_disparities / scale, scale, config)
        (x0, y0), (x1, y1) = window
        stats["window_fraction"] = (x1 - x0) * (y1 - y0) / float(gray_a.size)
    else:
        n_disparities = _disparities_to_search(rect, K, dist, T_world_cam_a, scale, config)
    stats["disparities"] = n_disparities
    windows = None if window is None else (window, window)
    pair = _rectify_pair(gray_a, gray_b, K, dist, rect, scale, config.sgm_block_px, windows)
    # a window already holds the columns a whole pair is padded with (_widened)
    disparity = _semi_global_disparity(pair, n_disparities, config, pad=window is None)
    rows, cols, d, valid = _textured_grid(pair, disparity, config)
    stats["keypoints"] = int(d.size)
    stats["tracked"] = int(np.count_nonzero(valid))
    pixels_a, pixels_b = _original_pixels(pair, rows[valid], cols[valid], d[valid], K)
    return pixels_a, pixels_b, stats, ""


@dataclass(frozen=True)
class _Rectification:
    """How the pair is rectified (cv2.stereoRectify with the known pose) and put in the matcher's order.

    Attributes:
        R1, R2, P1, P2: the rectifying rotations and projections of cameras a and b.
        vertical: the baseline runs along the rectified images' columns: they are matched transposed.
        b_is_left: image b is the matcher's left image (the one whose points lie further along the
            baseline).
        image_size: (width, height) of the full-size images, pixels.

    """

    R1: np.ndarray
    R2: np.ndarray
    P1: np.ndarray
    P2: np.ndarray
    vertical: bool
    b_is_left: bool
    image_size: tuple[int, int]

    @property
    def baseline_axis(self) -> int:
        """The rectified pixel axis the baseline runs along: 0 (x) or 1 (y)."""
        return 1 if self.vertical else 0


@dataclass(frozen=True)
class _RectifiedPair:
    """The pair rectified and scaled for matching, as the matcher takes it: the left image is the one
    whose points lie further along the baseline, and the baseline runs along rows.

    Attributes:
        left, right: the rectified images at the matching scale (transposed when ``rect.vertical``).
        inside_left, inside_right: where each holds image content (not the rectification's border).
        rect: the rectification.
        scale: the matching scale.
        origin_left_px, origin_right_px: (x, y) of each matched window's corner in the full-size
            rectified images, pixels: the same window of both images, or a region's band (the right
            window shifted by the band's lowest disparity).

    """

    left: np.ndarray
    right: np.ndarray
    inside_left: np.ndarray
    inside_right: np.ndarray
    rect: _Rectification
    scale: float
    origin_left_px: tuple[int, int]
    origin_right_px: tuple[int, int]


def _stereo_rectify(
    K: np.ndarray, dist: np.ndarray, image_size: tuple[int, int], T_ba: np.ndarray
) -> _Rectification:
    """OpenCV's stereoRectify with the known pose, and the matcher's order and orientation."""
    R_ba, t_ba = T_ba[:3, :3], T_ba[:3, 3]
    R1, R2, P1, P2, _, _, _ = cv2.stereoRectify(
        K, dist, K, dist, image_size, R_ba, t_ba.reshape(3, 1), flags=cv2.CALIB_ZERO_DISPARITY
    )
    # stereoRectify puts the baseline along x or, for mostly vertical motion, along y; semi-global
    # matching searches along rows, so a vertical pair is matched transposed.
    vertical = abs(P2[1, 3]) > abs(P2[0, 3])
    b_is_left = P2[1 if vertical else 0, 3] > 0
    return _Rectification(R1, R2, P1, P2, vertical, b_is_left, image_size)


def _rectify_pair(
    gray_a: np.ndarray,
    gray_b: np.ndarray,
    K: np.ndarray,
    dist: np.ndarray,
    rect: _Rectification,
    scale: float,
    block: int,
    windows: tuple[_Window, _Window] | None = None,
) -> _RectifiedPair:
    """Rectify both images, or a window of each ((x0, y0), (x1, y1) of the full-size rectified images
    a and b), and put them in the matcher's order and orientation.
    """
    w, h = rect.image_size
    whole = ((0, 0), (w, h))
    window_a, window_b = windows or (whole, whole)
    (xa0, ya0), (xa1, ya1) = window_a
    (xb0, yb0), (xb1, yb1) = window_b
    rect_a, inside_a = _rectify(
        gray_a, K, dist, rect.R1, rect.P1, scale, block, (xa0, ya0, xa1, ya1)
    )
    rect_b, inside_b = _rectify(
        gray_b, K, dist, rect.R2, rect.P2, scale, block, (xb0, yb0, xb1, yb1)
    )
    if rect.vertical:
        rect_a, rect_b = rect_a.T.copy(), rect_b.T.copy()
        inside_a, inside_b = inside_a.T.copy(), inside_b.T.copy()
    if rect.b_is_left:
        return _RectifiedPair(
            rect_b, rect_a, inside_b, inside_a, rect, scale, window_b[0], window_a[0]
        )
    return _RectifiedPair(rect_a, rect_b, inside_a, inside_b, rect, scale, window_a[0], window_b[0])


def _regions_box(
    regions: Sequence[SearchRegion],
    T_world_cam_a: np.ndarray,
    rect: _Rectification,
    scale: float,
    config: SfmConfig,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The box of the full-size rectified images that holds every region's outline as both images see
    it (rectified rows agree) and a margin of matching blocks (``WINDOW_MARGIN_*_BLOCKS``): (low, high)
    (x, y) corners, or None when the regions lie outside the images.
    """
    outline_m = np.concatenate([r.outline_m() for r in regions])
    T_cam_world = np.linalg.inv(T_world_cam_a)
    in_rect = (outline_m @ T_cam_world[:3, :3].T + T_cam_world[:3, 3]) @ rect.R1.T
    size = np.asarray(rect.image_size, np.float64)
    if not np.all(in_rect[:, 2] > 0.0):  # a region reaches behind the camera: the whole pair
        return np.zeros(2), size
    homogeneous = np.c_[in_rect, np.ones(len(in_rect))]
    pixels = np.concatenate([_projected(homogeneous, P) for P in (rect.P1, rect.P2)])
    margin_px = np.full(2, WINDOW_MARGIN_ALONG_BLOCKS * config.sgm_block_px / scale)
    margin_px[1 - rect.baseline_axis] = WINDOW_MARGIN_ACROSS_BLOCKS * config.sgm_block_px / scale
    low, high = pixels.min(axis=0) - margin_px, pixels.max(axis=0) + margin_px
    if np.any(high <= 0.0) or np.any(low >= size):
        return None
    return np.maximum(low, 0.0), np.minimum(high, size)


def _widened(
    box: tuple[np.ndarray, np.ndarray],
    rect: _Rectification,
    disparity_px: float,
    scale: float,
    config: SfmConfig,
) -> tuple[tuple[int, int], tuple[int, int]]:
    """The window of the full-size rectified images to match for a regions' box: ((x0, y0), (x1, y1)).

    Towards where partners lie (lower coordinates along the baseline) it also holds the disparity
    search: a pixel of the box then has its partner inside the window, as a pixel of the whole pair
    has, so a nearer surface in the band is matched, not mistaken for one at the region's depth.
    Corners fall on the grid of matched pixels, so a window's pixels are the whole pair's.
    """
    low, high = box[0].copy(), box[1].copy()
    low[rect.baseline_axis] -= disparity_px
    align = max(1, round(config.sgm_step_px / scale))
    x0, y0 = (int(np.floor(v / align)) * align for v in low)
    x1, y1 = (int(np.ceil(v / align)) * align for v in high)
    return (x0, y0), (x1, y1)


@dataclass(frozen=True)
class _Band:
    """A region's window of the matcher's left image and the disparities its outline spans, in full-size
    rectified pixels of the matcher's orientation: ``u`` along the baseline, ``v`` across it; the window's
    corners on the grid of matched pixels.
    """

    u: tuple[int, int]
    v: tuple[int, int]
    disparity_px: tuple[float, float]

    def overlaps(self, other: _Band) -> bool:
        """Whether the two windows share a pixel."""
        return (
            self.u[0] < other.u[1]
            and other.u[0] < self.u[1]
            and self.v[0] < other.v[1]
            and other.v[0] < self.v[1]
        )

    def merged(self, other: _Band) -> _Band:
        """The band whose window holds both windows and whose disparities hold both bands'."""
        return _Band(
            (min(self.u[0], other.u[0]), max(self.u[1], other.u[1])),
            (min(self.v[0], other.v[0]), max(self.v[1], other.v[1])),
            (
                min(self.disparity_px[0], other.disparity_px[0]),
                max(self.disparity_px[1], other.disparity_px[1]),
            ),
        )


def _region_bands(
    regions: Sequence[SearchRegion],
    T_world_cam_a: np.ndarray,
    rect: _Rectification,
    scale: float,
    config: SfmConfig,
) -> list[_Band] | None:
    """Each region's band: the box of the matcher's left image that holds the region's outline, with a
    margin of matching blocks (``WINDOW_MARGIN_*_BLOCKS``), and the disparities of the outline and of
    the flat ground the box sees. Overlapping windows are merged, so no pixel is matched twice; regions
    outside the left image have no band. None when a region reaches behind the camera.
    """
    T_cam_world = np.linalg.inv(T_world_cam_a)
    axis = rect.baseline_axis
    size = np.asarray(rect.image_size, np.float64)
    margin_px = np.full(2, WINDOW_MARGIN_ACROSS_BLOCKS * config.sgm_block_px / scale)
    margin_px[axis] = WINDOW_MARGIN_ALONG_BLOCKS * config.sgm_block_px / scale
    align = max(1, round(config.sgm_step_px / scale))
    bands: list[_Band] = []
    for region in regions:
        in_rect = (region.outline_m() @ T_cam_world[:3, :3].T + T_cam_world[:3, 3]) @ rect.R1.T
        if not np.all(in_rect[:, 2] > 0.0):
            return None
        homogeneous = np.c_[in_rect, np.ones(len(in_rect))]
        pixels_a, pixels_b = _projected(homogeneous, rect.P1), _projected(homogeneous, rect.P2)
        left, right = (pixels_b, pixels_a) if rect.b_is_left else (pixels_a, pixels_b)
        disparity_px = left[:, axis] - right[:, axis]
        low = np.maximum(left.min(axis=0) - margin_px, 0.0)
        high = np.minimum(left.max(axis=0) + margin_px, size)
        if np.any(high <= low):
            continue
        u0, v0 = (int(np.floor(x / align)) * align for x in (low[axis], low[1 - axis]))
        u1, v1 = (int(np.ceil(x / align)) * align for x in (high[axis], high[1 - axis]))
        # The window sees more than the region: through its upper part what lies beyond it (at 0 deg
        # obliquity ground far behind, or none), below it the ground before it. The band reaches the
        # farthest and the nearest ground the window sees, so that is matched where it lies, not
        # mistaken for a surface in the region, nor pulling the region's disparities with it.
        corners_uv = np.array([[u0, v0], [u1, v0], [u0, v1], [u1, v1]], np.float64)
        corners_xy = corners_uv if axis == 0 else corners_uv[:, ::-1]
        ground_px = _ground_disparities_px(corners_xy, rect, T_world_cam_a, config.ground_z_m)
        farthest_px, nearest_px = max(0.0, ground_px.min()), max(0.0, ground_px.max())
        ground_margin = config.sgm_ground_margin
        band = _Band(
            (u0, u1),
            (v0, v1),
            (
                min(float(disparity_px.min()), farthest_px / ground_margin),
                max(float(disparity_px.max()), nearest_px * ground_margin),
            ),
        )
        # merge with every band it overlaps, and again with what the merged band now overlaps
        while overlapping := [b for b in bands if b.overlaps(band)]:
            for b in overlapping:
                bands.remove(b)
                band = band.merged(b)
        bands.append(band)
    return bands


def _band_correspondences(
    bands: Sequence[_Band],
    rect: _Rectification,
    scale: float,
    gray_a: np.ndarray,
    gray_b: np.ndarray,
    K: np.ndarray,
    dist: np.ndarray,
    config: SfmConfig,
    stats: dict[str, int | float],
) -> tuple[np.ndarray, np.ndarray, dict[str, int | float], str]:
    """``sgm_correspondences`` on each band alone: its window of the left image, and of the right image
    the window shifted by the band's lowest disparity, so semi-global matching searches only the band's
    disparities (``sfm.sgm_region_bands``). A disparity at either end of the band is clipped, not
    measured (the surface lies nearer or farther than the band reaches), and is dropped.
    """
    if not bands:
        return np.zeros((0, 2)), np.zeros((0, 2)), stats, REGIONS_OUTSIDE
    axis = rect.baseline_axis
    align = max(1, round(config.sgm_step_px / scale))
    margin_px = BAND_MARGIN_BLOCKS * config.sgm_block_px  # at the matching scale
    found_a, found_b = [], []
    stats.update(keypoints=0, tracked=0, disparities=0, window_fraction=0.0, bands=len(bands))
    for band in bands:
        low_px, high_px = band.disparity_px
        n_disparities = int(np.ceil(((high_px - low_px) * scale + 2 * margin_px) / 16.0)) * 16
        # the band centred on its disparities, its lowest on the grid of matched pixels
        base_px = low_px - 0.5 * (n_disparities / scale - (high_px - low_px))
        base_px = int(np.floor(base_px / align)) * align
        # the left window reaches as many columns further back as the matcher leaves unmatched
        pad_px = int(np.ceil(n_disparities / scale / align)) * align
        (u0, u1), (v0, v1) = band.u, band.v
        windows_uv = (
            ((u0 - pad_px, v0), (u1, v1)),
            ((u0 - pad_px - base_px, v0), (u1 - base_px, v1)),
        )
        left, right = (w if axis == 0 else (w[0][::-1], w[1][::-1]) for w in windows_uv)
        windows = (right, left) if rect.b_is_left else (left, right)
        pair = _rectify_pair(gray_a, gray_b, K, dist, rect, scale, config.sgm_block_px, windows)
        disparity = _semi_global_disparity(pair, n_disparities, config, pad=False)
        rows, cols, d, valid = _textured_grid(pair, disparity, config)
        valid &= (d >= 1.0) & (d < n_disparities - 1)
        pixels_a, pixels_b = _original_pixels(pair, rows[valid], cols[valid], d[valid], K)
        found_a.append(pixels_a)
        found_b.append(pixels_b)
        stats["keypoints"] += int(d.size)
        stats["tracked"] += int(np.count_nonzero(valid))
        stats["disparities"] = max(int(stats["disparities"]), n_disparities)
        stats["window_fraction"] += (u1 - u0 + pad_px) * (v1 - v0) / float(gray_a.size)
    return np.concatenate(found_a), np.concatenate(found_b), stats, ""


def _projected(homogeneous: np.ndarray, P: np.ndarray) -> np.ndarray:
    """(N, 2) pixels of (N, 4) homogeneous points under the (3, 4) projection P."""
    projected = homogeneous @ P.T
    return projected[:, :2] / projected[:, 2:]


def _disparities_to_search(
    rect: _Rectification,
    K: np.ndarray,
    dist: np.ndarray,
    T_world_cam_a: np.ndarray,
    scale: float,
    config: SfmConfig,
    box: tuple[np.ndarray, np.ndarray] | None = None,
) -> int:
    """How many disparities the matcher searches at the matching scale: a multiple of 16. With a
    box ((x, y) corners in the full-size rectified images), the ground its pixels see sets it, not the
    whole image's.
    """
    # A pixel whose true disparity lies beyond the search is not left unmatched but matched wrongly, too
    # far: at 0 deg obliquity the near ground then sinks metres below the target. So the search also
    # reaches the nearest flat ground the image sees; no disparity exceeds the image's width.
    if box is None:
        ground_px = ground_disparity_px(
            K, dist, T_world_cam_a, rect.R1, rect.P2, rect.image_size, config.ground_z_m
        )
    else:
        ground_px = _box_ground_disparity_px(box, rect, T_world_cam_a, config.ground_z_m)
    search_px = max(float(config.sgm_disparities_px), config.sgm_ground_margin * ground_px)
    width_px = (
        rect.image_size[rect.baseline_axis] * scale
    )  # along the baseline, at the matching scale
    return int(np.ceil(min(search_px * scale, width_px) / 16.0)) * 16


def _semi_global_disparity(
    pair: _RectifiedPair, n_disparities: int, config: SfmConfig, *, pad: bool = True
) -> np.ndarray:
    """Disparity of every pixel of the left image, float32 pixels at the matching scale (<= 0: none).
    Without ``pad`` the first n_disparities columns are left unmatched.
    """
    block = config.sgm_block_px
    sgm = cv2.StereoSGBM_create(
        minDisparity=0,
        numDisparities=n_disparities,
        blockSize=block,
        # smoothness penalties per block area; OpenCV's documented 8 and 32 bias a small target's
        # disparities towards its background (k_sgm_small_jump_penalty)
        P1=int(round(config.k_sgm_small_jump_penalty * block * block)),
        P2=int(round(config.k_sgm_large_jump_penalty * block * block)),
        uniquenessRatio=config.sgm_uniqueness_percent,
        speckleWindowSize=config.sgm_speckle_window_px,
        speckleRange=2,
        disp12MaxDiff=config.sgm_left_right_px,
        mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY,
    )
    # The matcher leaves the left image's first numDisparities columns unmatched (their partners would
    # lie left of the right image); padding both images by as many columns keeps the whole image.
    if not pad:
        return sgm.compute(pair.left, pair.right).astype(np.float32) / 16.0
    widths = ((0, 0), (n_disparities, 0))
    disparity = sgm.compute(np.pad(pair.left, widths), np.pad(pair.right, widths))
    return disparity[:, n_disparities:].astype(np.float32) / 16.0  # fixed point, 4 fractional bits


def _textured_grid(
    pair: _RectifiedPair, disparity: np.ndarray, config: SfmConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The grid of left pixels every ``sgm_step_px``: rows, columns, disparities, and which are valid
    (a disparity, texture in both images, inside both images).
    """
    block = config.sgm_block_px
    step = config.sgm_step_px
    rows, cols = np.mgrid[0 : disparity.shape[0] : step, 0 : disparity.shape[1] : step]
    d = disparity[rows, cols]
    valid = d > 0.0  # invalid pixels are marked below minDisparity
    # Semi-global matching fills flat regions (sky, a black frame) from their borders; a point needs
    # texture in both images, as a corner does.
    texture_left = _local_std(pair.left, block)
    texture_right = _local_std(pair.right, block)
    right_cols = np.clip(np.rint(cols - d).astype(np.int64), 0, pair.right.shape[1] - 1)
    valid &= texture_left[rows, cols] >= config.sgm_min_texture_grey
    valid &= texture_right[rows, right_cols] >= config.sgm_min_texture_grey
    valid &= pair.inside_left[rows, cols] & pair.inside_right[rows, right_cols]
    return rows, cols, d, valid


def _original_pixels(
    pair: _RectifiedPair, rows: np.ndarray, cols: np.ndarray, d: np.ndarray, K: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Matched grid pixels (scaled left image, row, column, disparity) as undistorted pixels of a and b."""
    s = pair.scale
    # pixel centres of the scaled image back in the rectified full-size image
    x_left = (cols + 0.5) / s - 0.5
    y = (rows + 0.5) / s - 0.5
    x_right = x_left - d / s
    in_left, in_right = np.c_[x_left, y], np.c_[x_right, y]
    rect = pair.rect
    if rect.vertical:
        in_left, in_right = in_left[:, ::-1], in_right[:, ::-1]
    # each window's corner in the rectified images
    in_left = in_left + np.asarray(pair.origin_left_px, np.float64)
    in_right = in_right + np.asarray(pair.origin_right_px, np.float64)
    rect_pixels_a, rect_pixels_b = (in_right, in_left) if rect.b_is_left else (in_left, in_right)
    return (
        _unrectify(rect_pixels_a, K, rect.R1, rect.P1),
        _unrectify(rect_pixels_b, K, rect.R2, rect.P2),
    )


def matching_scale(
    K: np.ndarray, T_world_cam_a: np.ndarray, T_world_cam_b: np.ndarray, config: SfmConfig
) -> float:
    """The scale at which the rectified pair is matched.

    One pixel of the scaled image spans ``sgm_pixel_footprint_m`` at the depth the two optical axes
    converge on; rounded to a multiple of ``sgm_scale_step``, at least one step and at most full size.
    ``sgm_scale`` when the footprint is None or the axes do not converge.
    """
    depth_m = fixation_depth_m(T_world_cam_a, T_world_cam_b)
    if config.sgm_pixel_footprint_m is None or depth_m is None:
        return config.sgm_scale
    focal_px = 0.5 * (K[0, 0] + K[1, 1])
    step = config.sgm_scale_step
    steps = round(depth_m / (focal_px * config.sgm_pixel_footprint_m) / step)
    return float(min(max(steps, 1) * step, 1.0))


def ground_disparity_px(
    K: np.ndarray,
    dist_coeffs: np.ndarray,
    T_world_cam_a: np.ndarray,
    R1: np.ndarray,
    P2: np.ndarray,
    image_size: tuple[int, int],
    ground_z_m: float,
) -> float:
    """The largest disparity, in full-size rectified pixels, of the flat ground z = ``ground_z_m`` that
    image a sees; 0 when it sees none.

    The inverse depth of a plane is affine in the (undistorted) pixel, so its largest disparity over the
    image lies at one of the image's corners.

    Args:
        K: (3, 3) camera matrix.
        dist_coeffs: the lens's distortion coefficients.
        T_world_cam_a: (4, 4) world-from-camera at image a (world z up).
        R1: (3, 3) rectifying rotation of camera a (cv2.stereoRectify).
        P2: (3, 4) rectified projection of camera b; its translation column holds f x baseline.
        image_size: (width, height) px.
        ground_z_m: height of the ground in the world frame, metres.

    """
    w, h = image_size
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], np.float64)
    normalised = cv2.undistortPoints(corners.reshape(-1, 1, 2), K, dist_coeffs).reshape(-1, 2)
    rays_cam = np.c_[normalised, np.ones(4)]  # camera z = 1
    return _largest_ground_disparity_px(rays_cam, T_world_cam_a, R1, P2, ground_z_m)


def _largest_ground_disparity_px(
    rays_cam: np.ndarray,
    T_world_cam_a: np.ndarray,
    R1: np.ndarray,
    P2: np.ndarray,
    ground_z_m: float,
) -> float:
    """The largest disparity, in full-size rectified pixels, at which rays (N, 3) of camera a (its
    frame) meet the ground z = ``ground_z_m``; 0 when none does in front of the camera.
    """
    rays_world_z = rays_cam @ T_world_cam_a[2, :3]
    height_m = T_world_cam_a[2, 3] - ground_z_m
    down = rays_world_z < 0.0
    if height_m <= 0.0 or not down.any():
        return 0.0
    to_ground = height_m / -rays_world_z[down]  # multiples of each ray
    depth_rect = (rays_cam[down] @ R1.T)[:, 2] * to_ground
    focal_baseline_px = float(np.abs(P2[:2, 3]).max())
    in_front = depth_rect > 0.0
    return float((focal_baseline_px / depth_rect[in_front]).max()) if in_front.any() else 0.0


def _box_ground_disparity_px(
    box: tuple[np.ndarray, np.ndarray],
    rect: _Rectification,
    T_world_cam_a: np.ndarray,
    ground_z_m: float,
) -> float:
    """The largest disparity, in full-size rectified pixels, of the flat ground z = ``ground_z_m``
    that camera a's rectified pixels in the box see; 0 when they see none.
    """
    (x0, y0), (x1, y1) = box
    corners = np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]], np.float64)
    return max(0.0, float(_ground_disparities_px(corners, rect, T_world_cam_a, ground_z_m).max()))


def _ground_disparities_px(
    corners_px: np.ndarray, rect: _Rectification, T_world_cam_a: np.ndarray, ground_z_m: float
) -> np.ndarray:
    """The disparity, in full-size rectified pixels, of the flat ground z = ``ground_z_m`` at each of
    camera a's rectified pixels (N, 2); <= 0 where the ray does not meet it. It is affine in the
    pixel (as ``ground_disparity_px`` uses), so over a box its least and largest lie at corners.
    """
    height_m = T_world_cam_a[2, 3] - ground_z_m
    if height_m <= 0.0:
        return np.zeros(len(corners_px))
    P1 = rect.P1
    rays_rect = np.c_[(corners_px - P1[:2, 2]) / np.diag(P1)[:2], np.ones(len(corners_px))]
    rays_world_z = rays_rect @ rect.R1 @ T_world_cam_a[2, :3]  # rectified z = 1
    # disparity = f * baseline / depth, and the ray meets the ground at depth height / -rays_world_z
    focal_baseline_px = float(np.abs(rect.P2[:2, 3]).max())
    return focal_baseline_px * -rays_world_z / height_m


def _local_std(gray: np.ndarray, block: int) -> np.ndarray:
    """Standard deviation of the grey levels in a block x block window around each pixel."""
    g = gray.astype(np.float32)
    mean = cv2.boxFilter(g, -1, (block, block))
    mean_sq = cv2.boxFilter(g * g, -1, (block, block))
    return np.sqrt(np.maximum(mean_sq - mean * mean, 0.0))


def _rectifying_rotation_deg(R_ba: np.ndarray, t_ba: np.ndarray) -> float:
    """The larger angle by which rectification turns either camera: 90 deg minus the baseline's angle
    to that camera's optical axis.
    """
    baseline_in_a = -R_ba.T @ t_ba  # camera b's centre in camera a's frame
    baseline_in_b = t_ba  # camera a's centre in camera b's frame
    worst = 0.0
    for v in (baseline_in_a, baseline_in_b):
        cos_axis = abs(v[2]) / max(float(np.linalg.norm(v)), 1e-300)
        worst = max(worst, 90.0 - float(np.degrees(np.arccos(np.clip(cos_axis, 0.0, 1.0)))))
    return worst


def _rectify(
    gray: np.ndarray,
    K: np.ndarray,
    dist: np.ndarray,
    R: np.ndarray,
    P: np.ndarray,
    scale: float,
    block: int,
    window: tuple[int, int, int, int],
) -> tuple[np.ndarray, np.ndarray]:
    """The window (x0, y0, x1, y1) of the rectified image at the matching scale, and where it holds image
    content (not the border the rectifying rotation leaves, whose edge would pass for texture).
    """
    h, w = gray.shape
    x0, y0, x1, y1 = window
    P_window = P.copy()  # the window's pixels are the rectified image's, shifted by its corner
    P_window[0, 2] -= x0
    P_window[1, 2] -= y0
    map_x, map_y = cv2.initUndistortRectifyMap(
        K, dist, R, P_window, (x1 - x0, y1 - y0), cv2.CV_32FC1
    )
    rectified = cv2.remap(gray, map_x, map_y, cv2.INTER_LINEAR)
    inside = (map_x >= 0) & (map_x <= w - 1) & (map_y >= 0) & (map_y <= h - 1)
    if scale != 1.0:
        rectified = cv2.resize(rectified, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        inside = cv2.resize(
            inside.astype(np.uint8), rectified.shape[::-1], interpolation=cv2.INTER_AREA
        )
        inside = inside == 1  # every full-size pixel under the scaled one is inside
    # a matching block touching the border sees its edge: keep a margin wider than the block
    margin = np.ones((2 * block + 1, 2 * block + 1), np.uint8)
    return rectified, cv2.erode(inside.astype(np.uint8), margin) == 1


def _unrectify(pixels: np.ndarray, K: np.ndarray, R: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Rectified pixels back to (undistorted) pixels of the original camera: K R^T P[:, :3]^-1."""
    if len(pixels) == 0:
        return np.zeros((0, 2))
    H = K @ R.T @ np.linalg.inv(P[:, :3])
    return cv2.perspectiveTransform(pixels.reshape(-1, 1, 2).astype(np.float64), H).reshape(-1, 2)
