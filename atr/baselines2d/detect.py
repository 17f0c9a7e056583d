"""The 2D ATR pipeline (paper Fig. 3): features -> NNDR matches -> MSAC transform -> detection.

A template is recognised when the affine transform MSAC fits between its keypoints and the scene's keeps at
least `min_inliers` inliers; the template with most inliers gives the scene's one hypothesis. Its 3D position
(the paper's "T_error extended to 2D ATR", §III-C) is the ray through the transformed template reference point
(the target origin) intersected with the ground plane, using the known camera pose.
MSAC: OpenCV's USAC framework with MSAC scoring (`cv2.UsacParams.score = SCORE_METHOD_MSAC`), seeded.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import cv2
import numpy as np

from atr.baselines2d.config import Baseline2dConfig
from atr.baselines2d.features import detect_and_describe, match_nndr
from atr.baselines2d.templates import Template2d

_AFFINE_MIN_POINTS = 3  # an affine transform has 6 unknowns, 2 per correspondence


@dataclass(frozen=True)
class Detection2d:
    """A recognised target in an image.

    Attributes:
        target: template target name.
        T_world_target: (4, 4) float64 pose: the ground intersection as translation, identity rotation (2D ATR
            gives no 3D orientation).
        score: MSAC inliers of the winning template.
        template_azimuth_deg: azimuth step of the winning template.
        pixel: (2,) float64 the transformed template reference point in the scene, pixels.

    """

    target: str
    T_world_target: np.ndarray
    score: float
    template_azimuth_deg: float
    pixel: np.ndarray


@dataclass
class Result2d:
    """Output of `recognize_2d`: detections (best first) and stage times, milliseconds."""

    detections: list[Detection2d]
    stage_times_ms: dict[str, float] = field(default_factory=dict)


def ground_intersection(
    pixel: np.ndarray,
    K: np.ndarray,
    T_world_cam: np.ndarray,
    ground_z_m: float,
) -> np.ndarray | None:
    """World point where the ray through `pixel` meets the plane z = ground_z_m (None: never).

    Args:
        pixel: (2,) pixel coordinates (u, v).
        K: (3, 3) intrinsics.
        T_world_cam: (4, 4) world-from-camera pose (OpenCV axes).
        ground_z_m: plane height, metres.

    """
    ray_cam = np.linalg.solve(np.asarray(K, np.float64), np.array([pixel[0], pixel[1], 1.0]))
    ray = T_world_cam[:3, :3] @ ray_cam
    origin = T_world_cam[:3, 3]
    if ray[2] >= 0 or origin[2] <= ground_z_m:
        return None
    return origin + ray * (ground_z_m - origin[2]) / ray[2]


def _msac(
    params: cv2.UsacParams, src: np.ndarray, dst: np.ndarray
) -> tuple[np.ndarray | None, int]:
    if len(src) < _AFFINE_MIN_POINTS:
        return None, 0
    M, inliers = cv2.estimateAffine2D(src.astype(np.float32), dst.astype(np.float32), params=params)
    if M is None or inliers is None:
        return None, 0
    return M, int(inliers.sum())


def recognize_2d(
    image: np.ndarray,
    K: np.ndarray,
    T_world_cam: np.ndarray,
    templates: list[Template2d],
    pair: str,
    config: Baseline2dConfig,
    *,
    seed: int,
) -> Result2d:
    """Recognise the target in one image with the 2D templates (Fig. 3).

    Args:
        image: (H, W, 3) RGB uint8 scene image.
        K: (3, 3) intrinsics.
        T_world_cam: (4, 4) known camera pose, used only to place the detection in 3D.
        templates: templates described with `pair`.
        pair: Table IV combination ("2d-1" .. "2d-4").
        config: matching and acceptance thresholds.
        seed: seed of the MSAC sampler (same seed, same result).

    Returns:
        At most one detection (the template with most inliers, when it has enough).

    """
    t0 = time.perf_counter()
    scene = detect_and_describe(image, pair, config)
    t1 = time.perf_counter()
    params = cv2.UsacParams()
    params.score = cv2.SCORE_METHOD_MSAC
    params.sampler = cv2.SAMPLING_UNIFORM
    params.threshold = config.msac_max_distance_px
    params.maxIterations = config.msac_max_trials
    params.confidence = config.msac_confidence
    params.randomGeneratorState = int(seed) & 0x7FFFFFFF
    best: tuple[int, Template2d, np.ndarray] | None = None
    for template in templates:
        pairs = match_nndr(template.features, scene, config.nndr_ratio)
        M, inliers = _msac(params, template.features.xy_px[pairs[:, 0]], scene.xy_px[pairs[:, 1]])
        if M is not None and inliers >= config.min_inliers and (best is None or inliers > best[0]):
            best = (inliers, template, M)
    t2 = time.perf_counter()
    detections = []
    if best is not None:
        inliers, template, M = best
        pixel = M[:, :2] @ template.view.reference_px + M[:, 2]
        h, w = np.asarray(image).shape[:2]
        point = ground_intersection(pixel, K, T_world_cam, config.ground_height_m)
        if point is not None and 0 <= pixel[0] < w and 0 <= pixel[1] < h:
            T = np.eye(4)
            T[:3, 3] = point
            detections.append(
                Detection2d(
                    template.view.target, T, float(inliers), template.view.azimuth_deg, pixel
                )
            )
    return Result2d(
        detections,
        {
            "describe": 1e3 * (t1 - t0),
            "match": 1e3 * (t2 - t1),
            "total": 1e3 * (time.perf_counter() - t0),
        },
    )
