"""Attention: where in a scene a ground vehicle can stand, found before any template is matched (ours).

Fielded ATR chains cue first and recognise second. Here the cue is geometric and costs one pass over the
grid: after the ground is removed, a vehicle is a blob of points of vehicle height whose footprint is
vehicle-sized. Columns that rise above the tallest template are walls, roofs or trees, not vehicles; what
stays in the height band is split into connected blobs on a ground grid, and a blob whose footprint is
larger than a vehicle's (a low wall, a hedge, a long shed) is not searched. Keypoints are then taken only
in the kept blobs, so description, matching, grouping, RANSAC and ICP see fewer of them; the description
surface itself is untouched (a keypoint's support still reaches every vertex around it).
``vehicle_places`` gives the same blobs one by one, for the matcher's cued places (templates laid on a
blob no descriptor explained).

The sizes come from the templates (their tallest point and their largest footprint), never constants.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class AttentionSizes:
    """What a vehicle can look like from above, from the templates.

    Attributes:
        cell_m: ground grid cell, metres.
        top_m: a column with a point higher than this above the ground is not a vehicle, metres.
        footprint_m: a blob whose footprint's diagonal is longer than this is not a vehicle, metres.

    """

    cell_m: float
    top_m: float
    footprint_m: float


def largest_footprint_m(model_points_m: np.ndarray) -> float:
    """The longest diagonal the grid can see of a model's footprint, at any heading, metres.

    A length x width footprint turned by an angle fills a grid-aligned box whose diagonal is at most
    length + width (at 45 degrees), so that is the bound, with the model's own x-y extent.
    """
    xy = np.asarray(model_points_m, np.float64)[:, :2]
    return float(np.sum(xy.max(axis=0) - xy.min(axis=0)))


def vehicle_blobs(
    points_m: np.ndarray, height_m: np.ndarray, band: np.ndarray, sizes: AttentionSizes
) -> np.ndarray:
    """Which scene vertices lie in a blob a vehicle could be.

    Args:
        points_m: (S, 3) vertices above the ground, metres (z up).
        height_m: (S,) their height above the ground, metres.
        band: (S,) bool, the vertices within the height band a target occupies.
        sizes: the cell, the tallest vehicle and the largest footprint.

    Returns:
        (S,) bool: band vertices in a column no taller than a vehicle, in a connected blob of such columns
        whose footprint diagonal is at most ``sizes.footprint_m``, or in a column next to one (so a
        vehicle's edge is not cut by the grid).

    """
    S = len(points_m)
    if S == 0 or not band.any():
        return np.zeros(S, bool)
    cells, labels, kept_label = _vehicle_columns(points_m, height_m, band, sizes)
    kept = ndimage.binary_dilation(kept_label[labels], structure=np.ones((3, 3), bool))
    return band & kept[tuple(cells.T)]


@dataclass(frozen=True)
class Blob:
    """One place a vehicle can stand: a kept blob of vehicle-height columns.

    Attributes:
        idx: indices of its band vertices into the scene.
        centre_m: (3,) centroid of those vertices, metres.
        axis_yaw_rad: heading of the longest horizontal axis of their spread (a side seen level, a
            roof seen from above: a vehicle's length or its width), radians.

    """

    idx: np.ndarray
    centre_m: np.ndarray
    axis_yaw_rad: float


def vehicle_places(
    points_m: np.ndarray,
    height_m: np.ndarray,
    band: np.ndarray,
    sizes: AttentionSizes,
    min_points: int,
) -> list[Blob]:
    """The blobs of ``vehicle_blobs`` one by one, each with at least ``min_points`` band vertices,
    in a fixed order (by grid label), with where they sit and which way they run.
    """
    if len(points_m) == 0 or not band.any():
        return []
    cells, labels, kept_label = _vehicle_columns(points_m, height_m, band, sizes)
    label_of_vertex = np.where(band, labels[tuple(cells.T)], 0)
    label_of_vertex[~kept_label[label_of_vertex]] = 0
    places = []
    for label in np.unique(label_of_vertex[label_of_vertex > 0]):
        idx = np.flatnonzero(label_of_vertex == label)
        if len(idx) < min_points:
            continue
        xyz = np.asarray(points_m, np.float64)[idx]
        xy = xyz[:, :2] - xyz[:, :2].mean(axis=0)
        _, vectors = np.linalg.eigh(xy.T @ xy)
        major = vectors[:, -1]
        places.append(Blob(idx, xyz.mean(axis=0), float(np.arctan2(major[1], major[0]))))
    return places


def _vehicle_columns(
    points_m: np.ndarray, height_m: np.ndarray, band: np.ndarray, sizes: AttentionSizes
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each vertex's grid cell, the blob label of each cell (0: none) and which labels are kept
    (index 0, no blob, never is).
    """
    cells = np.floor(points_m[:, :2] / sizes.cell_m).astype(np.int64)
    origin = cells.min(axis=0)
    cells -= origin
    shape = tuple(cells.max(axis=0) + 1)
    tall = np.zeros(shape, bool)
    tall[tuple(cells[height_m > sizes.top_m].T)] = True
    occupied = np.zeros(shape, bool)
    occupied[tuple(cells[band].T)] = True
    occupied &= ~tall
    labels, n = ndimage.label(occupied, structure=np.ones((3, 3), bool))
    if n == 0:
        return cells, labels, np.zeros(1, bool)
    # Footprint of each blob from its cells' bounding box, measured to the cells' outer edges.
    spans = ndimage.find_objects(labels)
    diagonal_m = np.array(
        [
            np.hypot(sl[0].stop - sl[0].start, sl[1].stop - sl[1].start) * sizes.cell_m
            for sl in spans
        ]
    )
    kept_label = np.concatenate([[False], diagonal_m <= sizes.footprint_m])
    return cells, labels, kept_label
