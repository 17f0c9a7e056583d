"""Fixed-radius neighbour search shared by the descriptors (CSR output, numba, parallel over queries).

scipy's cKDTree returns Python lists of lists for a radius query, which costs more than the descriptors
themselves at 1,000 keypoints; Open3D's KDTreeFlann answers one query per Python call. So this module has its own
uniform hash grid (cell edge = the search radius), filled once per cloud and searched in parallel by numba.

Conventions (those of PCL's kd-tree radius search, see docs/features3d.md):
- a neighbour is a surface point with squared distance <= radius²; the query point itself is included
  (distance 0) when it belongs to the surface;
- neighbours are returned sorted by distance, ties by index (PCL's "sorted" tree). The order only changes the
  float summation order of the descriptors, never which bin a point goes to.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from atr.errors import InputError


@dataclass(frozen=True)
class Neighbourhoods:
    """Radius neighbourhoods of a set of query points, in compressed-sparse-row form.

    Attributes:
        offsets: (K+1,) int64; the neighbours of query i are entries offsets[i]:offsets[i+1].
        indices: (M,) int64 indices into the surface points.
        sq_dists: (M,) float64 squared distances, metres².

    """

    offsets: np.ndarray
    indices: np.ndarray
    sq_dists: np.ndarray

    def counts(self) -> np.ndarray:
        """Number of neighbours of each query, (K,) int64."""
        return np.diff(self.offsets)


@numba.njit(cache=True)
def _cell_keys(cells: np.ndarray, dims: np.ndarray) -> np.ndarray:
    n = cells.shape[0]
    keys = np.empty(n, dtype=np.int64)
    for i in range(n):
        keys[i] = (cells[i, 0] * dims[1] + cells[i, 1]) * dims[2] + cells[i, 2]
    return keys


@numba.njit(cache=True)
def _find_cell(unique_keys: np.ndarray, key: np.int64) -> int:
    pos = np.searchsorted(unique_keys, key)
    if pos < unique_keys.shape[0] and unique_keys[pos] == key:
        return pos
    return -1


@numba.njit(cache=True)
def _visit(
    surface: np.ndarray,
    order: np.ndarray,
    unique_keys: np.ndarray,
    starts: np.ndarray,
    origin: np.ndarray,
    dims: np.ndarray,
    cell: float,
    q: np.ndarray,
    r2: float,
    out_idx: np.ndarray,
    out_d2: np.ndarray,
    write: bool,
) -> int:
    count = 0
    cx = int(np.floor((q[0] - origin[0]) / cell))
    cy = int(np.floor((q[1] - origin[1]) / cell))
    cz = int(np.floor((q[2] - origin[2]) / cell))
    for ix in range(max(cx - 1, 0), min(cx + 2, dims[0])):
        for iy in range(max(cy - 1, 0), min(cy + 2, dims[1])):
            for iz in range(max(cz - 1, 0), min(cz + 2, dims[2])):
                c = _find_cell(unique_keys, (ix * dims[1] + iy) * dims[2] + iz)
                if c < 0:
                    continue
                for t in range(starts[c], starts[c + 1]):
                    j = order[t]
                    dx = surface[j, 0] - q[0]
                    dy = surface[j, 1] - q[1]
                    dz = surface[j, 2] - q[2]
                    d2 = dx * dx + dy * dy + dz * dz
                    if d2 <= r2:
                        if write:
                            out_idx[count] = j
                            out_d2[count] = d2
                        count += 1
    return count


@numba.njit(cache=True)
def _sort_by_distance(idx: np.ndarray, d2: np.ndarray) -> None:
    """In-place Shell sort by the total order (distance, index); compiles much faster than np.argsort."""
    n = idx.shape[0]
    gap = 1
    while gap < n // 3:
        gap = 3 * gap + 1
    while gap >= 1:
        for t in range(gap, n):
            ki = idx[t]
            kd = d2[t]
            u = t
            while u >= gap and (d2[u - gap] > kd or (d2[u - gap] == kd and idx[u - gap] > ki)):
                idx[u] = idx[u - gap]
                d2[u] = d2[u - gap]
                u -= gap
            idx[u] = ki
            d2[u] = kd
        gap //= 3


@numba.njit(cache=True, parallel=True)
def _search(surface, order, unique_keys, starts, origin, dims, cell, queries, r2, sort):
    # Two passes: count each query's neighbours to size the flat output, then fill it.
    k = queries.shape[0]
    counts = _count(surface, order, unique_keys, starts, origin, dims, cell, queries, r2)
    offsets = np.zeros(k + 1, dtype=np.int64)
    for i in range(k):
        offsets[i + 1] = offsets[i] + counts[i]
    indices = np.empty(offsets[k], dtype=np.int64)
    sq_dists = np.empty(offsets[k], dtype=np.float64)
    for i in numba.prange(k):
        a = offsets[i]
        b = offsets[i + 1]
        _visit(
            surface,
            order,
            unique_keys,
            starts,
            origin,
            dims,
            cell,
            queries[i],
            r2,
            indices[a:b],
            sq_dists[a:b],
            True,
        )
        if sort and b - a > 1:
            _sort_by_distance(indices[a:b], sq_dists[a:b])
    return offsets, indices, sq_dists


@numba.njit(cache=True, parallel=True)
def _count(surface, order, unique_keys, starts, origin, dims, cell, queries, r2):
    k = queries.shape[0]
    counts = np.zeros(k, dtype=np.int64)
    dummy_i = np.empty(0, dtype=np.int64)
    dummy_d = np.empty(0, dtype=np.float64)
    for i in numba.prange(k):
        counts[i] = _visit(
            surface,
            order,
            unique_keys,
            starts,
            origin,
            dims,
            cell,
            queries[i],
            r2,
            dummy_i,
            dummy_d,
            False,
        )
    return counts


class RadiusSearch:
    """A uniform-grid index over a surface, for repeated fixed-radius queries.

    Args:
        surface: (N, 3) float, metres. Non-finite points are never returned as neighbours.
        radius: search radius, metres (> 0); the grid cell edge.

    """

    def __init__(self, surface: np.ndarray, radius: float) -> None:
        surface = np.ascontiguousarray(surface, dtype=np.float64)
        if surface.ndim != 2 or surface.shape[1] != 3:
            raise InputError(f"surface shape {surface.shape} must be (N, 3)")
        if not radius > 0 or not np.isfinite(radius):
            raise InputError(f"search radius {radius} m must be a finite value > 0")
        self.surface = surface
        self.radius = float(radius)
        finite = np.flatnonzero(np.isfinite(surface).all(axis=1))
        pts = surface[finite]
        if pts.shape[0] == 0:
            self._origin = np.zeros(3)
            self._dims = np.ones(3, dtype=np.int64)
            self._order = np.empty(0, dtype=np.int64)
            self._keys = np.empty(0, dtype=np.int64)
            self._starts = np.zeros(1, dtype=np.int64)
            return
        origin = pts.min(axis=0)
        extent = pts.max(axis=0) - origin
        dims = np.floor(extent / radius).astype(np.int64) + 1
        if float(np.prod(dims.astype(np.float64))) > 2.0**62:
            raise InputError(
                f"cloud extent {extent} m is too large for search radius {radius} m "
                "(more than 2^62 grid cells)"
            )
        cells = np.floor((pts - origin) / radius).astype(np.int64)
        cells = np.minimum(cells, dims - 1)
        keys = _cell_keys(cells, dims)
        perm = np.argsort(keys, kind="stable")
        sorted_keys = keys[perm]
        unique_keys, first = np.unique(sorted_keys, return_index=True)
        self._origin = origin
        self._dims = dims
        self._order = finite[perm].astype(np.int64)
        self._keys = unique_keys.astype(np.int64)
        self._starts = np.append(first, sorted_keys.shape[0]).astype(np.int64)

    def query(
        self, queries: np.ndarray, radius: float | None = None, sort: bool = True
    ) -> Neighbourhoods:
        """Neighbours within ``radius`` (≤ the grid radius) of each query point.

        Args:
            queries: (K, 3) float, metres. A non-finite query has no neighbours.
            radius: metres; defaults to the grid radius. Must not exceed it.
            sort: sort each neighbourhood by (distance, index).

        Returns:
            Neighbourhoods in CSR form.

        """
        r, q = self._prepare(queries, radius)
        offsets, indices, d2 = _search(
            self.surface,
            self._order,
            self._keys,
            self._starts,
            self._origin,
            self._dims,
            self.radius,
            q,
            r * r,
            sort,
        )
        return Neighbourhoods(offsets, indices, d2)

    def count(self, queries: np.ndarray, radius: float | None = None) -> np.ndarray:
        """Number of neighbours within ``radius`` (≤ the grid radius) of each query, (K,) int64."""
        r, q = self._prepare(queries, radius)
        return _count(
            self.surface,
            self._order,
            self._keys,
            self._starts,
            self._origin,
            self._dims,
            self.radius,
            q,
            r * r,
        )

    def _prepare(self, queries: np.ndarray, radius: float | None) -> tuple[float, np.ndarray]:
        r = self.radius if radius is None else float(radius)
        if not 0 < r <= self.radius * (1 + 1e-12):
            raise InputError(f"query radius {r} m must be in (0, {self.radius}] m")
        queries = np.ascontiguousarray(queries, dtype=np.float64).reshape(-1, 3)
        # A non-finite query is moved outside the grid, where it finds nothing.
        bad = ~np.isfinite(queries).all(axis=1)
        if bad.any():
            queries = queries.copy()
            queries[bad] = self._origin - 4 * self.radius
        return r, queries


def radius_neighbours(
    surface: np.ndarray, queries: np.ndarray, radius: float, sort: bool = True
) -> Neighbourhoods:
    """Neighbours of each query within ``radius`` in ``surface`` (query point included when in surface).

    Args:
        surface: (N, 3) float, metres.
        queries: (K, 3) float, metres.
        radius: metres, > 0.
        sort: sort each neighbourhood by (distance, index).

    Returns:
        Neighbourhoods in CSR form.

    """
    return RadiusSearch(surface, radius).query(queries, sort=sort)


def count_within(surface: np.ndarray, which: np.ndarray, radius: float) -> np.ndarray:
    """Number of surface points within ``radius`` of surface[which] (each point counts itself).

    Args:
        surface: (N, 3) float, metres.
        which: (M,) int indices into surface.
        radius: metres, > 0.

    Returns:
        (M,) int64 counts.

    """
    return RadiusSearch(surface, radius).count(np.asarray(surface, dtype=np.float64)[which])
