"""Where a scene is looked at: vertical cylinders of the world frame around the places a target is held.

Track-guided search (``atr.tracking.guided_search``) decides them; the SfM step matches only the image band
they project to (``atr.sfm.dense``) and the matcher searches only the points inside them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


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
