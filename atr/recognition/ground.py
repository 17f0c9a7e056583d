"""The ground under a scene (docs/recognition.md, "Ground"): per-cell lowest points and their percentiles.

Only occupied cells of the horizontal grid are materialised (sorted cell keys, not a dense raster), so
time and memory grow with the number of points, never with the area the cloud spans: a handful of
points kilometres apart costs as little as a handful of points metres apart.
"""

from __future__ import annotations

import numpy as np

from atr.errors import InputError

_MAX_SPAN_CELLS = 2**30
"""Largest horizontal span of a cloud in cells; larger spans overflow the int64 cell keys."""

_CHUNK_VALUES = 1 << 20
"""Values gathered at once by the window percentile (bounds its working memory to ~8 MB)."""


def lowest_per_cell(points: np.ndarray, cell_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The lowest point of each occupied cell of a horizontal grid: the terrain samples of a scene.

    Args:
        points: (N, 3) float, metres, finite, N >= 1.
        cell_m: grid cell edge, metres (> 0).

    Returns:
        (M, 2) cell centres, metres, and (M,) the lowest z in each, metres; cells in (x, y) index order.

    Raises:
        InputError: the cloud spans more than 2^30 cells horizontally.

    """
    cells = _occupied_cells(np.asarray(points, np.float64), cell_m)
    return (cells.ij + 0.5) * cell_m, cells.lowest_z


def height_above_ground(
    points: np.ndarray, cell_m: float, window_m: float, percentile: float
) -> np.ndarray:
    """Height of each point above the local ground, metres (world frame, z up).

    The ground under a point is estimated on a horizontal grid of ``cell_m`` cells: each cell's lowest
    point (the ground if the cell shows any), then the ``percentile`` of those cell values within
    ``window_m`` around the cell. A vehicle, a tree or a roof covers only part of a window wider than the
    vehicle, so the low percentile returns the ground around it, while isolated points below the ground
    (reconstruction outliers) do not drag it down as a plain minimum would. Empty cells count as higher
    than every occupied one, so in a sparsely sampled window the estimate rises towards the highest
    occupied cells: sparse regions stand lower than they are. This keeps isolated background points out
    of the keypoints, and also a target seen edge-on at long range; taking the percentile of the occupied
    cells only was measured and not kept (docs/recognition.md, "Ground in sparse clouds"). When the
    percentile falls on an empty cell, the window's lowest occupied cell is the ground.

    The rank is that of ``scipy.ndimage.percentile_filter`` over the square window of
    (2 round(window_m / cell_m) + 1)^2 cells, computed on the occupied cells only.

    Args:
        points: (N, 3) float, metres, finite.
        cell_m: grid cell edge, metres (> 0).
        window_m: half-size of the percentile window, metres (>= cell_m).
        percentile: percentile of the cell values taken as the ground, in [0, 100].

    Returns:
        (N,) float64 heights, metres (negative below the estimated ground).

    Raises:
        InputError: the cloud spans more than 2^30 cells horizontally.

    """
    pts = np.asarray(points, np.float64)
    if len(pts) == 0:
        return np.zeros(0)
    cells = _occupied_cells(pts, cell_m)
    w = max(1, int(round(window_m / cell_m)))
    ground = _window_rank(cells, w, _percentile_rank((2 * w + 1) ** 2, percentile))
    return pts[:, 2] - ground[cells.of_point]


def terrain_height_at(
    cell_xy: np.ndarray,
    cell_lowest_z: np.ndarray,
    query_xy: np.ndarray,
    window_m: float,
    percentile: float,
) -> np.ndarray:
    """Height of the terrain at each query position, metres: ``height_above_ground``'s ground estimate
    (a low percentile of the cells' lowest points) over a window wider than a building, so that the
    streets and yards around a building set it and its roof does not.

    Args:
        cell_xy: (M, 2) cell centres from ``lowest_per_cell``, metres.
        cell_lowest_z: (M,) their lowest z, metres.
        query_xy: (Q, 2) positions, metres.
        window_m: half-size of the square window around a query, metres.
        percentile: percentile of the cell values taken as the terrain, in [0, 100].

    Returns:
        (Q,) float64 heights, metres; NaN where the window holds no cell.

    """
    query = np.atleast_2d(np.asarray(query_xy, np.float64))
    out = np.full(len(query), np.nan)
    for q, xy in enumerate(query):
        inside = np.all(np.abs(cell_xy - xy) <= window_m, axis=1)
        if inside.any():
            out[q] = np.percentile(cell_lowest_z[inside], percentile)
    return out


class _Cells:
    """The occupied cells of a horizontal grid, in (i, j) order.

    Attributes:
        ij: (M, 2) int64 cell indices (floor of x / cell, y / cell).
        lowest_z: (M,) lowest z of the points in each cell, metres.
        of_point: (N,) the cell of each point.

    """

    def __init__(self, ij: np.ndarray, lowest_z: np.ndarray, of_point: np.ndarray) -> None:
        self.ij, self.lowest_z, self.of_point = ij, lowest_z, of_point


def _occupied_cells(points: np.ndarray, cell_m: float) -> _Cells:
    ij_float = np.floor(points[:, :2] / cell_m)
    lo, hi = ij_float.min(axis=0), ij_float.max(axis=0)
    if not (np.all(hi - lo < _MAX_SPAN_CELLS) and np.all(np.abs([lo, hi]) < 2.0**62)):
        raise InputError(
            f"the cloud spans x, y in [{lo * cell_m}, {(hi + 1) * cell_m}] m; the ground grid holds "
            f"at most {_MAX_SPAN_CELLS * cell_m:g} m at {cell_m} m cells, within +-{2.0**62 * cell_m:g} m"
        )
    ij = ij_float.astype(np.int64)
    order = np.lexsort((ij[:, 1], ij[:, 0]))
    ij_sorted = ij[order]
    first = np.ones(len(order), bool)
    first[1:] = np.any(ij_sorted[1:] != ij_sorted[:-1], axis=1)
    starts = np.flatnonzero(first)
    of_point = np.empty(len(order), np.int64)
    of_point[order] = np.cumsum(first) - 1
    lowest_z = np.minimum.reduceat(points[order, 2], starts)
    return _Cells(ij_sorted[starts], lowest_z, of_point)


def _percentile_rank(window_cells: int, percentile: float) -> int:
    """The 0-based rank ``scipy.ndimage.percentile_filter`` takes among ``window_cells`` values."""
    if percentile == 100.0:
        return window_cells - 1
    return int(float(window_cells) * percentile / 100.0)


def _window_rank(cells: _Cells, w: int, rank: int) -> np.ndarray:
    """Per occupied cell, the ``rank``-th smallest lowest z of the (2w+1)^2 cells around it, empty cells
    counting as +inf; the window's smallest value where that rank falls on an empty cell.
    """
    ij = cells.ij - cells.ij.min(axis=0)
    width = (
        int(ij[:, 1].max()) + 2 * w + 1
    )  # j shifted by w, so a neighbour never wraps into the next row
    key = ij[:, 0] * width + (ij[:, 1] + w)  # ascending: the cells are in (i, j) order
    offsets = np.array(
        [di * width + dj for di in range(-w, w + 1) for dj in range(-w, w + 1)], np.int64
    )
    values = np.append(cells.lowest_z, np.inf)  # index M: an empty cell
    out = np.empty(len(key))
    step = max(1, _CHUNK_VALUES // len(offsets))
    for start in range(0, len(key), step):
        wanted = key[start : start + step, None] + offsets[None, :]
        found = np.minimum(np.searchsorted(key, wanted), len(key) - 1)
        window = values[np.where(key[found] == wanted, found, len(key))]
        ranked = np.partition(window, rank, axis=1)[:, rank]
        out[start : start + step] = np.where(np.isfinite(ranked), ranked, window.min(axis=1))
    return out
