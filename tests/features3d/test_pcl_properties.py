"""PCL's own property tests (oracle notes §1): a subset computed alone equals the subset of the full run."""

import numpy as np
import pytest

from atr.features3d import describe, shot_lrf

ALL = np.arange(397)
SUBSET = ALL[::3]

CASES = {
    "shot": {},
    "usc": {"minimal_radius": 0.004, "point_density_radius": 0.008},
    "3dsc-farthest": {"minimal_radius": 0.004, "point_density_radius": 0.008, "x_axis": "farthest"},
}


@pytest.mark.parametrize("case", CASES)
def test_subset_index_list_and_half_subset_are_bit_identical(bun0, bun0_normals, case):
    name = case.split("-")[0]
    params = CASES[case]
    full = describe(name, bun0, bun0_normals, ALL, 0.04, **params)
    sub = describe(
        name, bun0, bun0_normals, SUBSET, 0.04, **params
    )  # index list on the full surface
    half = describe(name, bun0, bun0_normals, SUBSET[: len(SUBSET) // 2], 0.04, **params)
    np.testing.assert_array_equal(full[SUBSET], sub)
    np.testing.assert_array_equal(full[SUBSET[: len(SUBSET) // 2]], half)
    assert np.isfinite(full).all(axis=1).mean() > 0.95


def test_3dsc_random_axis_all_points_is_repeatable(bun0, bun0_normals):
    # Released PCL draws the axis from one generator in keypoint order: only whole runs are comparable.
    a = describe("3dsc", bun0, bun0_normals, ALL, 0.04)
    b = describe("3dsc", bun0, bun0_normals, ALL, 0.04)
    np.testing.assert_array_equal(a, b)


def test_shot_lrf_subset_is_bit_identical(bun0):
    np.testing.assert_array_equal(shot_lrf(bun0, ALL, 0.01)[SUBSET], shot_lrf(bun0, SUBSET, 0.01))
