"""REAL drone photos (Brighton Beach, DJI Phantom 3): SURF SfM with the pose from GPS and gimbal
attitude must triangulate the ground about 40 m below the camera."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from atr.io.dji import T_world_cam_from_meta, intrinsics_from_focal, read_dji_metadata
from atr.sfm import SfmConfig, reconstruct

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared"

IMAGES = SHARED / "data" / "brighton_beach_dji" / "images"
# FC300S: 1/2.3" sensor, 6.17 x 4.55 mm; the 16:9 photos span its full width.
SENSOR_WIDTH_MM = 6.17
# JPEG decoding at 1/4 scale: 4000 x 2250 -> 1000 x 562 (DCT-domain area downscaling).
REDUCTION = 4
# The pair: the return leg over the park's road crossing and lawns (flat ground, 13.5 m apart).
PAIR = ("DJI_0033.JPG", "DJI_0034.JPG")

pytestmark = pytest.mark.skipif(
    not IMAGES.is_dir(), reason=f"shared DJI photos not found at {IMAGES} (../shared absent)"
)


def load_pair():
    meta_a, meta_b = (read_dji_metadata(IMAGES / name) for name in PAIR)
    images = [cv2.imread(str(IMAGES / name), cv2.IMREAD_REDUCED_GRAYSCALE_4) for name in PAIR]
    h, w = images[0].shape
    assert (w, h) == (meta_a.width_px // REDUCTION, (meta_a.height_px + REDUCTION - 1) // REDUCTION)
    K = intrinsics_from_focal(meta_a.focal_length_mm, SENSOR_WIDTH_MM, w, h)
    T_a = T_world_cam_from_meta(meta_a, meta_a)
    T_b = T_world_cam_from_meta(meta_b, meta_a)
    return images, K, T_a, T_b


def fit_plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    centre = points.mean(axis=0)
    normal = np.linalg.svd(points - centre)[2][2]
    normal = normal if normal[2] > 0 else -normal
    return centre, normal, (points - centre) @ normal


def test_surf_cloud_is_a_ground_plane_40_m_below_the_camera() -> None:
    (img_a, img_b), K, T_a, T_b = load_pair()
    # The photos' attitude is good to a degree or two (gimbal yaw is logged in 0.1-1 deg steps):
    # at f = 585 px that is 10-20 px of epipolar error, so the reprojection gate is widened to 20 px.
    config = SfmConfig(matcher="surf", k_max_reprojection=40.0)
    cloud = reconstruct(img_a, img_b, K, T_a, T_b, config)
    assert cloud.reason == ""
    assert len(cloud) >= 50, cloud.stats
    centre, normal, residual = fit_plane(cloud.points_world_m)
    camera_height_above_plane = float((T_a[:3, 3] - centre) @ normal)
    tilt_deg = float(np.degrees(np.arccos(normal[2])))
    # 40 m flight height (barometer); GPS baseline errors of ~1 m over 13.5 m scale depth by ~8 %.
    assert 34.0 < camera_height_above_plane < 46.0, camera_height_above_plane
    # A lawn and a road: nearly level.
    assert tilt_deg < 10.0, tilt_deg
    assert np.median(np.abs(residual)) < 1.0
    # Nothing reconstructed above the camera or absurdly far below it.
    assert np.all(cloud.points_world_m[:, 2] < T_a[2, 3])


def test_reference_model_comparison_needs_laspy() -> None:
    pytest.importorskip("laspy", reason="model.laz needs laspy + lazrs, which are not installed")
    pytest.importorskip("lazrs", reason="model.laz needs laspy + lazrs, which are not installed")
    pytest.skip("laspy is available: the model.laz comparison is not written yet")
