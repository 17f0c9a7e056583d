"""Search regions: vertical cylinders of the world frame, and the outline an image band must hold."""

from __future__ import annotations

import numpy as np
import pytest

from atr.errors import InputError
from atr.regions import SearchRegion, points_in_regions, regions_from_array, regions_to_array


def test_regions_are_vertical_cylinders() -> None:
    region = SearchRegion(np.array([10.0, -5.0]), 3.0, 0.0, 3.0)
    points = np.array(
        [[10.0, -5.0, 0.0], [12.9, -5.0, 50.0], [10.0, -2.1, -3.0], [13.1, -5.0, 0.0], [0, 0, 0]]
    )
    assert points_in_regions(points, [region]).tolist() == [True, True, True, False, False]
    two = [region, SearchRegion(np.zeros(2), 0.5, 0.0, 3.0)]
    assert points_in_regions(points, two).tolist() == [True, True, True, False, True]
    assert points_in_regions(points, []).tolist() == [False] * 5


def test_outline_encloses_the_cylinder() -> None:
    region = SearchRegion(np.array([4.0, 1.0]), 2.5, -0.5, 3.0)
    outline = region.outline_m(8)
    assert outline.shape == (16, 3)
    assert sorted(set(outline[:, 2].tolist())) == [-0.5, 3.0]
    # every point of the circle lies inside the outline's polygon: its edges' midpoints are at radius_m
    ring = outline[:8, :2] - region.centre_m
    midpoints = 0.5 * (ring + np.roll(ring, 1, axis=0))
    assert np.allclose(np.linalg.norm(midpoints, axis=1), region.radius_m)


def test_regions_travel_as_rows_and_bad_rows_are_named() -> None:
    regions = [
        SearchRegion(np.array([1.0, 2.0]), 3.0, -0.5, 3.5),
        SearchRegion(np.array([-4.0, 0.5]), 2.0, 0.0, 1.0),
    ]
    rows = regions_to_array(regions)
    assert rows.shape == (2, 5)
    back = regions_from_array(rows)
    assert [r.centre_m.tolist() for r in back] == [[1.0, 2.0], [-4.0, 0.5]]
    assert [(r.radius_m, r.z_min_m, r.z_max_m) for r in back] == [(3.0, -0.5, 3.5), (2.0, 0.0, 1.0)]
    assert regions_to_array([]).shape == (0, 5) and regions_from_array(np.zeros((0, 5))) == []
    with pytest.raises(InputError, match=r"shape \(2, 4\)"):
        regions_from_array(rows[:, :4])
    with pytest.raises(InputError, match="non-finite"):
        regions_from_array(np.where(rows == 3.0, np.nan, rows))
    with pytest.raises(InputError, match="radius -3.0"):
        regions_from_array(rows * np.array([1, 1, -1, 1, 1]))
