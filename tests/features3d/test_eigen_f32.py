"""The float32 replica of Eigen 3.4's EigenSolver<Matrix3f> against the compiled Eigen and PCL, bit for bit.

The stored matrices and outputs are described in tests/data/SOURCE_features3d_fpfh_rops.md; they were recorded
by tests/data/features3d/eigen34_solver_probe.cpp and pcl113_rops_axes_probe.cpp.
"""

from pathlib import Path

import numpy as np
import pytest

from atr.features3d._eigen_f32 import eigen_solver_3x3
from atr.features3d._rops import _pcl_major_minor

DATA = Path(__file__).resolve().parents[1] / "data" / "features3d"


@pytest.fixture(scope="module")
def matrices() -> np.ndarray:
    m = np.load(DATA / "eigen34_solver_input.npy")
    assert m.dtype == np.float32 and m.shape[1:] == (3, 3)
    return m


def _bits(x: np.ndarray) -> np.ndarray:
    # Compare bit patterns: equal values with different signs of zero, or different NaNs, count as different.
    return np.ascontiguousarray(x, dtype=np.float32).view(np.uint32)


def test_matches_compiled_eigen_bit_for_bit(matrices):
    """Eigenvalues and normalised eigenvectors (real and imaginary parts) equal Eigen's, bit for bit."""
    ref = np.load(DATA / "eigen34_solver_output.npy")
    assert ref.shape == (len(matrices), 25) and (ref[:, 0] == 1.0).all()
    # The set must keep exercising the complex-pair paths, not only symmetric matrices.
    assert (ref[:, 4:7] != 0).any(axis=1).sum() >= 100
    ours = np.empty_like(ref)
    for k, m in enumerate(matrices):
        ok, re, im, vre, vim = eigen_solver_3x3(m)
        assert ok
        ours[k] = np.concatenate(([1.0], re, im, vre.ravel(), vim.ravel()))
    differing = np.flatnonzero((_bits(ours) != _bits(ref)).any(axis=1))
    assert differing.size == 0, f"{differing.size} matrices differ, first {differing[:10]}"


def test_rops_axes_match_pcl_bit_for_bit(matrices):
    """PCL's own computeEigenVectors (its ranking by real part included) gives our major and minor axes."""
    ref = np.load(DATA / "pcl113_rops_axes.npy")
    assert ref.shape == (len(matrices), 3, 3)
    for k, m in enumerate(matrices):
        ok, major, minor = _pcl_major_minor(m)
        assert ok
        np.testing.assert_array_equal(_bits(major), _bits(ref[k, 0]), err_msg=f"matrix {k}")
        np.testing.assert_array_equal(_bits(minor), _bits(ref[k, 2]), err_msg=f"matrix {k}")


def test_eigenpairs_of_symmetric_matrices():
    """Independent of the recorded outputs: A v = λ v to float32 accuracy, unit vectors, real spectrum."""
    rng = np.random.default_rng(0)
    for _ in range(200):
        a = rng.normal(size=(3, 3))
        a = ((a + a.T) * 10.0 ** rng.uniform(-6, 3)).astype(np.float32)
        ok, re, im, vre, vim = eigen_solver_3x3(a)
        assert ok and (im == 0).all() and (vim == 0).all()
        scale = np.abs(a).max()
        a64 = a.astype(np.float64)
        for j in range(3):
            v = vre[:, j].astype(np.float64)
            assert abs(np.linalg.norm(v) - 1.0) < 1e-6
            assert np.abs(a64 @ v - re[j] * v).max() < 1e-5 * scale
        np.testing.assert_allclose(np.sort(re), np.linalg.eigvalsh(a64), atol=1e-5 * scale)


def test_zero_matrix_gives_identity():
    """Eigen's shortcut for a matrix below FLT_MIN: zero eigenvalues, the identity as eigenvectors."""
    ok, re, im, vre, vim = eigen_solver_3x3(np.zeros((3, 3), dtype=np.float32))
    assert ok
    np.testing.assert_array_equal(re, 0.0)
    np.testing.assert_array_equal(im, 0.0)
    np.testing.assert_array_equal(vre, np.eye(3))
