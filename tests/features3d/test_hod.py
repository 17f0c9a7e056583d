"""HoD / HoD-S: a hand-computed example, shapes, invariance, distinctiveness and invalid neighbourhoods."""

import sys
from pathlib import Path

import numpy as np
import pytest

from atr.errors import InputError
from atr.features3d._hod import hod

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _surfaces import corresponding_vs_random, random_rigid, surface  # noqa: E402


def test_hand_computed_example():
    # Keypoint at the origin, four points at 0.5 m on ±x, y, z: pair distances 0.5 (4 pairs), 0.5√2 (5), 1.0 (1).
    pts = np.array([[0, 0, 0], [0.5, 0, 0], [0, 0.5, 0], [0, 0, 0.5], [-0.5, 0, 0]], dtype=float)
    d = hod(pts, np.array([0]), radius=1.0)[0]
    assert d.shape == (240,)
    coarse, fine = d[:40], d[40:]
    # distance / (2R) = 0.25, 0.3536, 0.5 -> coarse bins 10, 14, 20; fine bins 50, 70, 100
    expected_c = np.zeros(40)
    expected_c[[10, 14, 20]] = [0.4, 0.5, 0.1]
    expected_f = np.zeros(200)
    expected_f[[50, 70, 100]] = [0.4, 0.5, 0.1]
    np.testing.assert_allclose(coarse, expected_c, atol=1e-7)
    np.testing.assert_allclose(fine, expected_f, atol=1e-7)
    np.testing.assert_array_equal(hod(pts, np.array([0]), 1.0, short=True)[0], coarse)


def test_shapes_and_normalisation():
    pts, _ = surface()
    kps = np.arange(0, 4000, 40)
    full = hod(pts, kps, 0.08)
    short = hod(pts, kps, 0.08, short=True)
    assert full.shape == (100, 240) and short.shape == (100, 40) and full.dtype == np.float32
    np.testing.assert_allclose(full[:, :40].sum(axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(full[:, 40:].sum(axis=1), 1.0, atol=1e-5)
    np.testing.assert_array_equal(short, full[:, :40])
    # coarse = fine summed in groups of 5
    np.testing.assert_allclose(
        full[:, 40:].reshape(100, 40, 5).sum(axis=2), full[:, :40], atol=1e-6
    )


def test_rigid_transform_invariance():
    pts, _ = surface()
    rot, t = random_rigid(np.random.default_rng(1))
    kps = np.arange(0, 4000, 20)
    a = hod(pts, kps, 0.08)
    b = hod(pts @ rot.T + t, kps, 0.08)
    # Only distances enter; float32 rounding may move a rare pair across a fine bin edge.
    assert np.abs(a - b).max() < 5e-3
    assert np.median(np.abs(a - b).max(axis=1)) < 1e-6


def test_corresponding_points_closer_than_random():
    corr, rand = corresponding_vs_random(lambda p, n, k: hod(p, k, 0.1), 2, 5, 200)
    # Distances alone are weakly distinctive on a smooth surface: the margin is smaller than FPFH's.
    assert corr < 0.5 * rand


def test_invalid_neighbourhoods_and_inputs():
    pts, _ = surface()
    out = hod(pts, np.array([[5.0, 5.0, 5.0], [np.nan, 0, 0], pts[0]]), 0.08)
    assert np.isnan(out[:2]).all() and np.isfinite(out[2]).all()
    assert np.isnan(hod(pts, np.array([0]), 1e-6)).all()  # the keypoint alone
    assert hod(pts, np.zeros(0, dtype=np.int64), 0.08).shape == (0, 240)
    with pytest.raises(InputError):
        hod(pts, np.array([0]), 0.0)
    with pytest.raises(InputError):
        hod(pts, np.array([len(pts)]), 0.08)
