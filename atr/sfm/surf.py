"""Our own SURF detector and descriptor (Bay, Ess, Tuytelaars, Van Gool, CVIU 2008).

Written here because OpenCV's wheels exclude SURF (non-free module) and no other well-kept library
ships it. The steps follow the paper:
- box-filter approximations of the Hessian's second derivatives on an integral image, normalised by the
  filter area; det(H) = Dxx Dyy - (0.9 Dxy)^2;
- octaves of filter sizes 9, 15, 21, ... (first size 3 (2^(o+1) + 1), increment 6 * 2^o), sampled
  every `initial_step * 2^o` pixels;
- 3x3x3 non-maximum suppression above the blob threshold, then sub-sample interpolation of
  (x, y, size) by a 3D quadratic fit;
- orientation: Haar responses (side 4s) at samples within radius 6s, Gaussian weighted, summed in a
  sliding 60 degree window; the longest sum vector gives the angle;
- descriptor: a 20s square window, rotated to the orientation, 4 x 4 subregions of 5 x 5 samples of
  Haar responses (side 2s), Gaussian weighted (sigma 3.3s), (sum dx, sum dy, sum |dx|, sum |dy|) per
  subregion, normalised to unit length (64 values).
Scale s = 1.2 L / 9 for a filter of side L pixels.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial import cKDTree

from atr.errors import InputError
from atr.sfm import _surf_kernels as kernels
from atr.sfm.config import SfmConfig

# Bay et al. 2008 §3.3: a 9x9 box filter approximates a Gaussian derivative of sigma 1.2.
_SCALE_PER_FILTER_SIZE = 1.2 / 9.0


def surf_filter_sizes(octave: int, levels: int) -> np.ndarray:
    """Box filter sides (px) of one octave (Bay et al. 2008 §4.1).

    Args:
        octave: 0-based octave index.
        levels: scale levels per octave.

    Returns:
        (levels,) int64 odd filter sides, e.g. 9, 15, 21, 27, ... for octave 0.

    """
    first = 3 * (2 ** (octave + 1) + 1)
    increment = 6 * 2**octave
    return first + increment * np.arange(levels, dtype=np.int64)


class Surf:
    """SURF keypoint detector and 64-D descriptor.

    Args:
        config: uses surf_octaves, surf_scale_levels, surf_blob_threshold, surf_initial_step_px,
            surf_max_keypoints and surf_upright.

    """

    def __init__(self, config: SfmConfig | None = None) -> None:
        self.config = config or SfmConfig()

    def detect(self, gray_float01: np.ndarray) -> np.ndarray:
        """Detect blob keypoints.

        Args:
            gray_float01: (H, W) float image with values in [0, 1].

        Returns:
            (N, 5) float64 rows (x, y, scale s, det(H) response, laplacian sign), strongest first,
            at most surf_max_keypoints rows (all when it is 0).

        Raises:
            InputError: not a 2-D finite image.

        """
        integral = self._integral(gray_float01)
        return self._detect(integral)

    def detect_and_compute(self, gray_float01: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Detect keypoints and describe them.

        Args:
            gray_float01: (H, W) float image with values in [0, 1].

        Returns:
            keypoints: (N, 4) float32 rows (x px, y px, scale s px, angle rad), strongest first.
            descriptors: (N, 64) float32 rows of unit length.

        Raises:
            InputError: not a 2-D finite image.

        """
        integral = self._integral(gray_float01)
        found = self._detect(integral)
        if found.shape[0] == 0:
            return np.zeros((0, 4), np.float32), np.zeros((0, 64), np.float32)
        angles, descriptors = kernels.describe(
            integral, found[:, :3].copy(), self.config.surf_upright
        )
        keypoints = np.c_[found[:, :3], angles].astype(np.float32)
        return keypoints, descriptors

    # Internals

    @staticmethod
    def _integral(gray_float01: np.ndarray) -> np.ndarray:
        img = np.asarray(gray_float01)
        if img.ndim != 2 or img.shape[0] < 1 or img.shape[1] < 1:
            raise InputError(f"SURF needs a 2-D grey image, got shape {img.shape}")
        img = img.astype(np.float32, copy=False)
        if not np.all(np.isfinite(img)):
            raise InputError("SURF image contains non-finite values")
        return cv2.integral(img, sdepth=cv2.CV_64F)

    def _detect(self, integral: np.ndarray) -> np.ndarray:
        cfg = self.config
        h, w = integral.shape[0] - 1, integral.shape[1] - 1
        found = []
        for octave in range(cfg.surf_octaves):
            sizes = surf_filter_sizes(octave, cfg.surf_scale_levels)
            step = cfg.surf_initial_step_px * 2**octave
            if sizes[-1] >= min(h, w) or (h + step - 1) // step < 3 or (w + step - 1) // step < 3:
                break  # this octave's largest filter no longer fits the image
            det, lap = kernels.hessian_layers(integral, sizes, step)
            found.append(kernels.find_extrema(det, lap, sizes, step, cfg.surf_blob_threshold))
        if not found:
            return np.zeros((0, 5), np.float64)
        points = np.concatenate(found)
        points[:, 2] *= _SCALE_PER_FILTER_SIZE
        points = points[np.argsort(-points[:, 3], kind="stable")]
        points = self._drop_duplicates(points)
        if cfg.surf_max_keypoints > 0:
            points = points[: cfg.surf_max_keypoints]
        return points

    def _drop_duplicates(self, points: np.ndarray) -> np.ndarray:
        """Keep the strongest of each group of same-blob detections (points sorted strongest first)."""
        cfg = self.config
        if cfg.k_surf_duplicate_radius <= 0.0 or points.shape[0] < 2:
            return points
        radius = cfg.k_surf_duplicate_radius * float(points[:, 2].max())
        pairs = cKDTree(points[:, :2]).query_pairs(radius, output_type="ndarray")
        if pairs.shape[0] == 0:
            return points
        i, j = np.sort(pairs, axis=1).T  # i < j: i is the stronger one
        dist = np.linalg.norm(points[i, :2] - points[j, :2], axis=1)
        ratio = points[j, 2] / points[i, 2]
        same = (
            (dist <= cfg.k_surf_duplicate_radius * np.minimum(points[i, 2], points[j, 2]))
            & (ratio < cfg.surf_duplicate_scale_ratio)
            & (ratio > 1.0 / cfg.surf_duplicate_scale_ratio)
        )
        keep = np.ones(points.shape[0], bool)
        # Visit pairs by the stronger index, so a dropped point never drops another one.
        for a, b in sorted(zip(i[same].tolist(), j[same].tolist())):
            if keep[a]:
                keep[b] = False
        return points[keep]
