"""Where a scene is looked at: vertical cylinders of the world frame around the places a target is held.

Track-guided search (``atr.tracking.guided_search``) decides them; the SfM step matches only the image band
they project to (``atr.sfm.dense``) and the matcher searches only the points inside them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from atr.errors import InputError


@dataclass(frozen=True)
class SearchRegion:
    """A vertical cylinder of the world frame.

    Attributes:
        centre_m: (2,) x, y of its axis, metres.
        radius_m: its radius, metres.
        z_min_m, z_max_m: the heights it spans, metres: where a vehicle standing at the place can have
            surface (the SfM step projects this span into the images; the point test takes any height).

    """

    centre_m: np.ndarray
    radius_m: float
    z_min_m: float
    z_max_m: float

    def outline_m(self, n_around: int = 16) -> np.ndarray:
        """(2 n_around, 3) points on its top and bottom circles: what an image band must contain."""
        angles = np.linspace(0.0, 2.0 * np.pi, n_around, endpoint=False)
        # a polygon inscribed in the circle falls short of it between vertices: circumscribe it instead
        r = self.radius_m / np.cos(np.pi / n_around)
        ring = self.centre_m + r * np.c_[np.cos(angles), np.sin(angles)]
        return np.r_[
            np.c_[ring, np.full(n_around, self.z_min_m)],
            np.c_[ring, np.full(n_around, self.z_max_m)],
        ]


def points_in_regions(points_m: np.ndarray, regions: Sequence[SearchRegion]) -> np.ndarray:
    """(N,) bool: which points lie inside any region (at any height)."""
    inside = np.zeros(len(points_m), bool)
    for region in regions:
        d2 = np.sum((points_m[:, :2] - region.centre_m) ** 2, axis=1)
        inside |= d2 <= region.radius_m**2
    return inside


def regions_to_array(regions: Sequence[SearchRegion]) -> np.ndarray:
    """(R, 5) float64 rows [x, y, radius, z_min, z_max] (metres): the regions as messages carry them."""
    rows = [
        [*np.asarray(r.centre_m, np.float64).tolist(), r.radius_m, r.z_min_m, r.z_max_m]
        for r in regions
    ]
    return np.array(rows, np.float64).reshape(-1, 5)


def regions_from_array(rows: np.ndarray) -> list[SearchRegion]:
    """The regions of (R, 5) rows [x, y, radius, z_min, z_max] (``regions_to_array``'s inverse).

    Raises:
        InputError: not (R, 5), not finite, a radius not above 0 or z_max below z_min.

    """
    array = np.asarray(rows, np.float64)
    if array.ndim != 2 or array.shape[1] != 5:
        raise InputError(
            f"search regions of shape {array.shape}, expected (R, 5) rows [x, y, radius, z_min, z_max]"
        )
    if not np.all(np.isfinite(array)):
        raise InputError("search regions hold non-finite values; expected finite metres")
    for x, y, radius, z_min, z_max in array:
        if radius <= 0.0 or z_max < z_min:
            raise InputError(
                f"search region at ({x:.2f}, {y:.2f}) has radius {radius} m and heights {z_min}..{z_max} m; "
                "expected a radius > 0 and z_min <= z_max"
            )
    return [
        SearchRegion(row[:2].copy(), float(row[2]), float(row[3]), float(row[4])) for row in array
    ]
