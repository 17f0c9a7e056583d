"""DJI photo metadata reader and the pose it implies, checked against the dataset's documentation."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from atr.errors import InputError
from atr.io.dji import (
    R_world_cam_from_gimbal,
    enu_from_geodetic,
    intrinsics_from_focal,
    read_dji_metadata,
)

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared"
IMAGES = SHARED / "data" / "brighton_beach_dji" / "images"
needs_photos = pytest.mark.skipif(
    not IMAGES.is_dir(), reason=f"shared DJI photos absent at {IMAGES}"
)


@needs_photos
def test_metadata_matches_the_dataset_description() -> None:
    # SOURCE.md: FC300S, 3.61 mm, 4000x2250, ~40 m relative altitude, ~46.84 N 91.99 W, nadir gimbal.
    for path in sorted(IMAGES.glob("DJI_*.JPG")):
        meta = read_dji_metadata(path)
        assert meta.model == "FC300S"
        assert meta.focal_length_mm == pytest.approx(3.61)
        assert (meta.width_px, meta.height_px) == (4000, 2250)
        assert meta.latitude_deg == pytest.approx(46.84, abs=0.01)
        assert meta.longitude_deg == pytest.approx(-91.99, abs=0.01)
        assert 35.0 < meta.relative_altitude_m < 45.0
        assert meta.gimbal_pitch_deg == pytest.approx(-89.9, abs=0.5)
        assert -180.0 <= meta.gimbal_yaw_deg <= 180.0


def test_enu_of_small_offsets_matches_the_earth_radii() -> None:
    lat0 = 46.84
    e2 = 6.69437999014e-3
    a = 6378137.0
    s2 = math.sin(math.radians(lat0)) ** 2
    meridian = a * (1 - e2) / (1 - e2 * s2) ** 1.5
    normal = a / math.sqrt(1 - e2 * s2)
    d = 1e-4
    north = enu_from_geodetic(lat0 + d, -92.0, 0.0, lat0, -92.0, 0.0)
    east = enu_from_geodetic(lat0, -92.0 + d, 0.0, lat0, -92.0, 0.0)
    up = enu_from_geodetic(lat0, -92.0, 10.0, lat0, -92.0, 0.0)
    np.testing.assert_allclose(north, [0, meridian * math.radians(d), 0], atol=1e-3)
    np.testing.assert_allclose(
        east, [normal * math.cos(math.radians(lat0)) * math.radians(d), 0, 0], atol=1e-3
    )
    np.testing.assert_allclose(up, [0, 0, 10.0], atol=1e-6)


def test_gimbal_attitude_to_camera_axes() -> None:
    # Nadir, heading north: image right = east, image down = south, optical axis = down.
    R = R_world_cam_from_gimbal(0.0, -90.0, 0.0)
    np.testing.assert_allclose(R, [[1, 0, 0], [0, -1, 0], [0, 0, -1]], atol=1e-12)
    # Nadir, heading east: image up points east, image right points south.
    R = R_world_cam_from_gimbal(90.0, -90.0, 0.0)
    np.testing.assert_allclose(R[:, 0], [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(R[:, 1], [-1, 0, 0], atol=1e-12)
    # Level, heading north: looking north with the image upright.
    R = R_world_cam_from_gimbal(0.0, 0.0, 0.0)
    np.testing.assert_allclose(R, [[1, 0, 0], [0, 0, 1], [0, -1, 0]], atol=1e-12)
    assert np.linalg.det(R_world_cam_from_gimbal(37.0, -61.0, 4.0)) == pytest.approx(1.0)


def test_intrinsics_from_the_fc300s_focal_length() -> None:
    K = intrinsics_from_focal(3.61, 6.17, 4000, 2250)
    # Diagonal field of view of the 4:3 frame is DJI's quoted 94 deg.
    half_diag_px = 0.5 * math.hypot(4000, 3000)
    assert math.degrees(2 * math.atan(half_diag_px / K[0, 0])) == pytest.approx(94.0, abs=1.0)
    with pytest.raises(InputError, match="focal"):
        intrinsics_from_focal(0.0, 6.17, 4000, 2250)


def test_non_jpeg_and_missing_file_raise_input_error(tmp_path: Path) -> None:
    bogus = tmp_path / "x.jpg"
    bogus.write_bytes(b"not a jpeg")
    with pytest.raises(InputError, match="not a JPEG"):
        read_dji_metadata(bogus)
    with pytest.raises(InputError, match="cannot read"):
        read_dji_metadata(tmp_path / "missing.jpg")
    no_exif = tmp_path / "plain.jpg"
    no_exif.write_bytes(b"\xff\xd8\xff\xd9")
    with pytest.raises(InputError, match="EXIF"):
        read_dji_metadata(no_exif)
