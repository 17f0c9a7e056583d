"""FPFH and PFH pair features against PCL: the oracles of pcl-descriptor-oracles.md §7-§8, PCL 1.13's own output,
and Open3D's compute_fpfh_feature (with its known differences)."""

import json
from pathlib import Path

import numpy as np
import pytest

from atr.features3d._fpfh import fpfh, pfh_histogram, pfh_pair_features, spfh

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT / ".." / "shared"
BUN0 = SHARED / "data" / "pcl" / "bun0.pcd"
DATA = ROOT / "tests" / "data" / "features3d"
ORACLES = json.loads((Path(__file__).resolve().parent / "pcl_fpfh_oracles.json").read_text())

pytestmark = pytest.mark.skipif(
    not BUN0.exists(), reason="shared PCL test data (shared/data/pcl) is absent"
)


def read_ascii_pcd(path: Path) -> np.ndarray:
    lines = path.read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("DATA")) + 1
    return np.array([[float(v) for v in line.split()] for line in lines[start:] if line.strip()])


@pytest.fixture(scope="module")
def bun0():
    d = read_ascii_pcd(BUN0)
    return d[:, :3], d[:, 3:6]


def test_pair_features_oracle(bun0):
    pts, nrm = bun0
    f = pfh_pair_features(pts[0], nrm[0], pts[12], nrm[12])
    np.testing.assert_allclose(f, [-0.072575, -0.040221, 0.068133, 0.006130], atol=1e-4)


def test_pair_features_coincident_points_are_rejected(bun0):
    pts, nrm = bun0
    assert pfh_pair_features(pts[3], nrm[3], pts[3], nrm[5]) == (0.0, 0.0, 0.0, 0.0)


def test_pair_features_symmetric(bun0):
    pts, nrm = bun0
    a = pfh_pair_features(pts[0], nrm[0], pts[12], nrm[12])
    b = pfh_pair_features(pts[12], nrm[12], pts[0], nrm[0])
    np.testing.assert_allclose(a, b, atol=1e-6)


def test_pfh_signature_all_points_k3(bun0):
    pts, nrm = bun0
    h = pfh_histogram(pts, nrm, np.arange(len(pts)), subdivisions=3)
    expected = ORACLES["pfh_all_points_k3"]
    tol = np.full(27, 1e-2)
    tol[[4, 22]] = 2e-2
    tol[23:27] = 1e-4
    assert np.all(np.abs(h - expected) <= tol)
    assert abs(h.sum() - 100) < 1e-2


def test_spfh_of_point0_all_neighbours(bun0):
    pts, nrm = bun0
    row = spfh(pts, nrm, np.array([0]), radius=1.0)[0]  # 1 m covers the whole bunny: k = 397
    expected = ORACLES["spfh_point0_all_neighbours"]
    np.testing.assert_allclose(row, expected, atol=1e-4)


def test_spfh_weighting_with_fake_distances(bun0):
    pts, nrm = bun0
    rows = spfh(pts, nrm, np.arange(len(pts)), radius=1.0)
    w = 1.0 / np.arange(1, len(pts), dtype=np.float32)  # d_i = i, row 0 skipped
    acc = (rows[1:] * w[:, None]).sum(axis=0)
    for f in range(3):
        acc[f * 11 : (f + 1) * 11] *= 100.0 / acc[f * 11 : (f + 1) * 11].sum()
    expected = ORACLES["spfh_weighted_by_index"]
    np.testing.assert_allclose(acc, expected, atol=1e-2)


def test_fpfh_all_neighbours_point0(bun0):
    pts, nrm = bun0
    f = fpfh(pts, nrm, np.array([0]), radius=1.0)[0]
    expected = ORACLES["fpfh_point0_all_neighbours"]
    np.testing.assert_allclose(f, expected, atol=1e-2)
    for part in range(3):
        assert abs(f[part * 11 : (part + 1) * 11].sum() - 100) < 1e-3


@pytest.mark.parametrize("radius", [0.02, 0.04])
def test_fpfh_equals_pcl_113_radius_search(bun0, radius):
    """PCL 1.13 FPFHEstimation, radius search, all 397 points (tests/data/features3d, SOURCE file)."""
    pts, nrm = bun0
    ref = np.load(DATA / f"pcl113_fpfh_bun0_r{radius}.npy")
    ours = fpfh(pts, nrm, np.arange(len(pts)), radius)
    assert ours.shape == (397, 33) and ours.dtype == np.float32
    np.testing.assert_allclose(ours, ref, atol=1e-4)


def test_fpfh_against_open3d(bun0):
    """Open3D = PCL's FPFH + the point's own SPFH (added after the normalisation, so parts sum to 200)."""
    o3d = pytest.importorskip("open3d")
    pts, nrm = bun0
    radius = 0.02
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    pc.normals = o3d.utility.Vector3dVector(nrm)
    theirs = np.asarray(
        o3d.pipelines.registration.compute_fpfh_feature(
            pc, o3d.geometry.KDTreeSearchParamRadius(radius)
        ).data
    ).T
    ours = fpfh(pts, nrm, np.arange(len(pts)), radius)
    own = spfh(pts, nrm, np.arange(len(pts)), radius)
    # The known difference, stated: Open3D's sub-histograms sum to 200, ours (PCL's) to 100.
    np.testing.assert_allclose(theirs.reshape(-1, 3, 11).sum(axis=2), 200.0, atol=1e-6)
    np.testing.assert_allclose(ours.reshape(-1, 3, 11).sum(axis=2), 100.0, atol=1e-3)
    # What should agree: float32 (ours) vs double (Open3D) arithmetic only.
    np.testing.assert_allclose(ours + own, theirs, atol=1e-3)
