"""FPFH properties: rigid-transform invariance, distinctiveness, NaN rows, keypoint forms, bad inputs."""

import sys
from pathlib import Path

import numpy as np
import pytest

from atr.errors import InputError
from atr.features3d._fpfh import fpfh

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _surfaces import corresponding_vs_random, random_rigid, surface  # noqa: E402


def test_rigid_transform_invariance():
    pts, nrm = surface()
    rot, t = random_rigid(np.random.default_rng(1))
    kps = np.arange(0, 4000, 10)
    a = fpfh(pts, nrm, kps, 0.06)
    b = fpfh(pts @ rot.T + t, nrm @ rot.T, kps, 0.06)
    err = np.abs(a - b).max(axis=1)
    # Bins are hard: a float32 rounding can move one pair; the rows stay within a fraction of a percent point.
    assert np.median(err) < 1e-3
    assert np.mean(err < 0.5) >= 0.95


def test_corresponding_points_closer_than_random():
    corr, rand = corresponding_vs_random(lambda p, n, k: fpfh(p, n, k, 0.1), 3, 4, 300)
    assert corr < 0.1 * rand


def test_keypoint_forms_and_subsets_agree():
    pts, nrm = surface()
    kps = np.arange(0, 4000, 3)
    full = fpfh(pts, nrm, np.arange(4000), 0.05)
    np.testing.assert_array_equal(fpfh(pts, nrm, kps, 0.05), full[kps])
    np.testing.assert_array_equal(fpfh(pts, nrm, pts[kps], 0.05), full[kps])


def test_too_few_neighbours_give_nan():
    pts, nrm = surface()
    pts = np.vstack([pts, [[3.0, 3.0, 3.0]]])  # an isolated point
    nrm = np.vstack([nrm, [[0.0, 0.0, 1.0]]])
    out = fpfh(pts, nrm, np.array([4000, 0]), 0.05)
    assert np.isnan(out[0]).all() and np.isfinite(out[1]).all()
    far = fpfh(pts, nrm, np.array([[9.0, 9.0, 9.0], [np.nan, 0.0, 0.0]]), 0.05)
    assert np.isnan(far).all()


def test_non_finite_surface_points_are_ignored():
    pts, nrm = surface()
    ref = fpfh(pts, nrm, np.arange(0, 4000, 50), 0.05)
    pts2 = np.vstack([pts, [[np.nan, 0, 0]]])
    nrm2 = np.vstack([nrm, [[0, 0, 1.0]]])
    np.testing.assert_array_equal(fpfh(pts2, nrm2, np.arange(0, 4000, 50), 0.05), ref)


def test_bad_inputs():
    pts, nrm = surface(200)
    with pytest.raises(InputError):
        fpfh(pts, nrm, np.array([0]), 0.0)
    with pytest.raises(InputError):
        fpfh(pts, nrm[:10], np.array([0]), 0.05)
    with pytest.raises(InputError):
        fpfh(pts, None, np.array([0]), 0.05)
    with pytest.raises(InputError):
        fpfh(pts, nrm, np.array([[0.0, 1.0]]), 0.05)
