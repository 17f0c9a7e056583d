"""Normals against PCL's test_normal_estimation.cpp expectations (oracle notes §2)."""

import numpy as np
import pytest

from atr.errors import ConfigError
from atr.features3d import estimate_normals
from atr.features3d._normals import estimate_normals_and_curvature


def test_radius_normals_match_pcl(bun0, oracles):
    o = oracles["normals"]["radius_0.04"]
    normals = estimate_normals(bun0, radius=o["radius"])
    for point, expected in o["expected"].items():
        np.testing.assert_allclose(
            normals[int(point)], expected, atol=o["tol"], err_msg=f"point {point}"
        )


@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.0), (100.0, 100.0, 100.0)])
def test_whole_cloud_plane_fit_matches_pcl(bun0, oracles, offset):
    # k = 397: every neighbourhood is the whole cloud; translated by +100 m it must not lose precision.
    o = oracles["normals"]["k397_flipped"]
    shift = np.asarray(offset)
    normals, curvature = estimate_normals_and_curvature(bun0 + shift, k=397, viewpoint=shift)
    np.testing.assert_allclose(normals, np.broadcast_to(o["normal"], normals.shape), atol=o["tol"])
    np.testing.assert_allclose(curvature, o["curvature"], atol=o["tol"])
    np.testing.assert_allclose(
        np.abs(normals[0]), oracles["normals"]["plane_all_points"]["normal_abs"], atol=1e-4
    )


def test_translated_cloud_and_viewpoint_give_same_normals(bun0):
    shift = np.array([123.0, -45.0, 98.0])
    n1 = estimate_normals(bun0, k=15)
    n2 = estimate_normals(bun0 + shift, k=15, viewpoint=shift)
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->i", n1, n2)), 1.0, atol=1e-6)
    np.testing.assert_allclose(n1, n2, atol=5e-4)


def test_normals_face_the_viewpoint(bun0):
    vp = np.array([0.0, 1.0, 0.0])
    n = estimate_normals(bun0, k=6, viewpoint=vp)
    assert (np.einsum("ij,ij->i", vp - bun0, n) >= 0).all()
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)


def test_default_is_six_neighbours(bun0):
    np.testing.assert_array_equal(estimate_normals(bun0), estimate_normals(bun0, k=6))


def test_too_few_neighbours_gives_nan_rows(bun0):
    cloud = np.vstack([bun0, [[5.0, 5.0, 5.0], [5.001, 5.0, 5.0]], [[np.nan, 0, 0]]])
    n = estimate_normals(cloud, radius=0.04)
    assert np.isnan(n[-3:]).all()
    assert np.isfinite(n[:397]).all()


def test_k_and_radius_together_are_refused(bun0):
    with pytest.raises(ConfigError):
        estimate_normals(bun0, k=6, radius=0.04)
