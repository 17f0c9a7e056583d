"""SHOT352 and the SHOT LRF against PCL's own expected values on bun0.pcd (oracle notes §3, §4)."""

import numpy as np
import pytest

from atr.errors import InputError
from atr.features3d import describe, shot_lrf

ALL = np.arange(397)


def test_shot_lrf_matches_pcl(bun0, oracles):
    o = oracles["shot_lrf"]
    frames = shot_lrf(bun0, ALL, o["radius"])
    for point, expected in o["expected"].items():
        np.testing.assert_allclose(
            frames[int(point)], expected, atol=o["tol"], err_msg=f"point {point}"
        )
    assert np.isnan(frames[o["nan_point"]]).all()


def test_shot_lrf_is_orthonormal_and_right_handed(bun0):
    frames = shot_lrf(bun0, ALL, 0.02)
    ok = np.isfinite(frames).all(axis=(1, 2))
    assert ok.sum() > 300
    f = frames[ok]
    np.testing.assert_allclose(
        f @ f.transpose(0, 2, 1), np.broadcast_to(np.eye(3), f.shape), atol=1e-9
    )
    np.testing.assert_allclose(np.linalg.det(f), 1.0, atol=1e-9)


def test_shot352_matches_pcl(bun0, bun0_normals, oracles):
    o = oracles["shot352"]
    desc = describe("shot", bun0, bun0_normals, ALL, o["radius"])
    assert desc.shape == (397, 352) and desc.dtype == np.float32
    row = desc[o["point"]]
    for b, v in o["expected"].items():
        assert row[int(b)] == pytest.approx(v, abs=o["tol"]), f"bin {b}"
    finite = np.isfinite(desc).all(axis=1)
    np.testing.assert_allclose(np.linalg.norm(desc[finite], axis=1), 1.0, atol=1e-5)


def test_shot_precomputed_lrf_gives_identical_descriptors(bun0, bun0_normals):
    frames = shot_lrf(bun0, ALL, 0.04)
    a = describe("shot", bun0, bun0_normals, ALL, 0.04)
    b = describe("shot", bun0, bun0_normals, ALL, 0.04, lrf=frames)
    np.testing.assert_array_equal(a, b)


def test_shot_lrf_radius_changes_frames_only_where_given(bun0, bun0_normals):
    a = describe("shot", bun0, bun0_normals, ALL, 0.04, lrf_radius=0.04)
    b = describe("shot", bun0, bun0_normals, ALL, 0.04, lrf_radius=0.02)
    np.testing.assert_array_equal(a, describe("shot", bun0, bun0_normals, ALL, 0.04))
    assert not np.allclose(a, b, equal_nan=True)


def test_shot_needs_normals(bun0):
    with pytest.raises(InputError, match="normals"):
        describe("shot", bun0, None, ALL[:3], 0.04)
