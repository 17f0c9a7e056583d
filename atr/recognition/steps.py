"""The steps of the online 3D ATR module (paper §II-B-2), each a pure function on numpy arrays.

uniform_subsample -> filter_smooth_surfaces -> (describe) -> match_knndr -> group_geometrically_consistent
-> ransac_per_group -> verify_with_icp. ``recognize`` in ``atr.recognition.matcher`` chains them.

Geometric-consistency grouping follows the idea of PCL's GeometricConsistencyGrouping (Chen & Bhanu 2007);
the kNNDR rule, RANSAC on a group and the overlap test are written here because no library has them in this
form. Open3D provides k-NN normals and ICP.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from atr.errors import InputError
from atr.recognition import _kernels


def uniform_subsample(points: np.ndarray, leaf_m: float) -> np.ndarray:
    """Uniform subsampling: per occupied voxel of edge ``leaf_m``, the point closest to the voxel centre.

    Same rule as PCL's UniformSampling, with a defined output order (voxels sorted by their integer keys).

    Args:
        points: (N, 3) float, metres; must be finite.
        leaf_m: voxel edge, metres, > 0.

    Returns:
        (M,) int64 indices into ``points``, M <= N.

    """
    if leaf_m <= 0:
        raise InputError(f"subsampling leaf {leaf_m} m must be > 0")
    pts = np.asarray(points, np.float64)
    if len(pts) == 0:
        return np.zeros(0, np.int64)
    raw = np.floor(pts / leaf_m)
    d2 = np.sum((pts - (raw + 0.5) * leaf_m) ** 2, axis=1)
    cell = (raw - raw.min(axis=0)).astype(np.int64)
    dims = cell.max(axis=0) + 1
    if float(np.prod(dims.astype(np.float64))) < 2.0**62:
        key = (cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]
        _, inverse = np.unique(key, return_inverse=True)
    else:  # astronomically large extent: fall back to row-unique
        _, inverse = np.unique(cell, axis=0, return_inverse=True)
    inverse = inverse.ravel()
    order = np.lexsort((np.arange(len(pts)), d2, inverse))
    first = np.ones(len(order), bool)
    first[1:] = inverse[order[1:]] != inverse[order[:-1]]
    return order[first].astype(np.int64)


def filter_smooth_surfaces(
    points: np.ndarray, normals: np.ndarray, k: int, min_angle_rad: float
) -> np.ndarray:
    """Smooth-surface filter: keep vertices whose normal varies against their neighbours' normals.

    The variation of a vertex is the mean angle between its normal and the normals of its k nearest
    neighbours, sign-blind (a normal and its flip are the same surface).

    Args:
        points: (N, 3) float, metres.
        normals: (N, 3) float, unit normals.
        k: neighbours compared with each vertex.
        min_angle_rad: vertices with a mean variation below this are smooth and dropped, radians.

    Returns:
        (N,) bool, True = kept (not smooth).

    """
    n = len(points)
    if n == 0:
        return np.zeros(0, bool)
    kk = min(k + 1, n)
    _, nbr = cKDTree(points).query(points, k=kk)
    nbr = np.asarray(nbr).reshape(n, kk)[:, 1:]
    if nbr.shape[1] == 0:
        return np.ones(n, bool)
    cos = np.abs(np.einsum("ij,ikj->ik", normals, normals[nbr]))
    variation = np.arccos(np.clip(cos, 0.0, 1.0)).mean(axis=1)
    return variation >= min_angle_rad


@dataclass(frozen=True)
class Correspondences:
    """Scene-model keypoint correspondences.

    Attributes:
        scene: (C,) int64 indices of scene keypoints.
        model: (C,) int64 indices of model keypoints.
        distance: (C,) float64 descriptor distances (L2), best first.

    """

    scene: np.ndarray
    model: np.ndarray
    distance: np.ndarray

    def __len__(self) -> int:
        return len(self.scene)


def descriptor_sq_distances(scene_desc: np.ndarray, model_desc: np.ndarray) -> np.ndarray:
    """Squared L2 distances between every scene and model descriptor, (S, M) float32.

    One float32 matrix product (BLAS): |s|^2 + |m|^2 - 2 s.m, clipped at 0. Descriptors are up to 1980
    long, where k-d trees are no faster than brute force; float32 keeps 6-7 significant digits, far more
    than the kNNDR ratio needs. Rows with NaN give NaN distances.
    """
    s = np.ascontiguousarray(scene_desc, np.float32)
    m = np.ascontiguousarray(model_desc, np.float32)
    d2 = s @ m.T
    d2 *= -2.0
    d2 += np.einsum("ij,ij->i", s, s)[:, None]
    d2 += np.einsum("ij,ij->i", m, m)[None, :]
    np.maximum(d2, 0.0, out=d2)
    return d2


def knndr_from_distances(
    d2: np.ndarray, k: int, ratio: float, max_correspondences: int | None = None
) -> Correspondences:
    """KNNDR on a precomputed (S, M) squared-distance matrix (see ``match_knndr``).

    Rows or columns with non-finite distances (NaN descriptors) are ignored.

    Raises:
        InputError: ``k`` < 1, or ``ratio`` > 1 (the result would depend on how ties are broken).

    """
    if k < 1 or ratio > 1:
        raise InputError(f"kNNDR needs k >= 1 and ratio <= 1; got k = {k}, ratio = {ratio}")
    empty = Correspondences(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    if d2.ndim != 2 or d2.shape[0] == 0 or d2.shape[1] < 2:
        return empty
    cols = _kernels.finite_columns(d2)  # columns of NaN descriptors take no part
    kk = min(k, len(cols))
    if kk < 2:  # nothing lies below the nearest
        return empty
    if len(cols) < d2.shape[1]:
        d2 = d2[:, cols]
    # Each row's k-th smallest distance (NaN last): its value does not depend on how ties are broken.
    d_k = np.partition(d2, kk - 1, axis=1)[:, kk - 1]
    sc, mo, di = _kernels.knndr_keep(d2, d_k, kk, float(ratio))
    mo = cols[mo]
    # best first, ties by scene then model index (the kernel's order, which a stable sort keeps)
    o = _kernels.stable_argsort_nonnegative((di + 0.0).view(np.int64))
    if max_correspondences is not None:
        o = o[:max_correspondences]
    return Correspondences(sc[o], mo[o], di[o])


def match_knndr(
    scene_desc: np.ndarray,
    model_desc: np.ndarray,
    k: int,
    ratio: float,
    max_correspondences: int | None = None,
) -> Correspondences:
    """k-nearest-neighbour distance-ratio matching (§II-B-2, k = 10).

    For each scene descriptor, its k nearest model descriptors d_1 <= ... <= d_k are found; the j-th (j < k)
    is kept when d_j < ratio * d_k, i.e. clearly closer than the k-th, which stands for the background of
    unrelated descriptors. With k = 2 this is Lowe's NNDR; larger k lets a scene vertex keep several model
    candidates on a target with repeated structure (road wheels, symmetric hull).

    Args:
        scene_desc: (S, L) float, rows with NaN are ignored.
        model_desc: (M, L) float, rows with NaN are ignored.
        k: neighbours considered (capped at M).
        ratio: distance-ratio threshold in (0, 1].
        max_correspondences: keep only this many best (smallest distance) correspondences.

    Returns:
        Correspondences sorted by distance (ties by scene then model index).

    """
    s = np.asarray(scene_desc)
    m = np.asarray(model_desc)
    if s.ndim != 2 or m.ndim != 2 or s.shape[1] != m.shape[1]:
        raise InputError(f"descriptor shapes {s.shape} and {m.shape} must be (S, L) and (M, L)")
    s_ok = np.flatnonzero(np.isfinite(s).all(axis=1))
    m_ok = np.flatnonzero(np.isfinite(m).all(axis=1))
    if len(s_ok) == 0 or len(m_ok) < 2:
        return Correspondences(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    c = knndr_from_distances(
        descriptor_sq_distances(s[s_ok], m[m_ok]), k, ratio, max_correspondences
    )
    return Correspondences(s_ok[c.scene], m_ok[c.model], c.distance)


@numba.njit(cache=True)
def _gc_groups(scene_xyz, model_xyz, consensus, min_size):  # pragma: no cover - compiled
    n = scene_xyz.shape[0]
    taken = np.zeros(n, np.bool_)
    labels = -np.ones(n, np.int64)
    members = np.empty(n, np.int64)
    n_groups = 0
    for i in range(n):
        if taken[i]:
            continue
        members[0] = i
        size = 1
        for j in range(n):
            if j == i or taken[j]:
                continue
            good = True
            for q in range(size):
                a = members[q]
                ds = np.sqrt(
                    (scene_xyz[a, 0] - scene_xyz[j, 0]) ** 2
                    + (scene_xyz[a, 1] - scene_xyz[j, 1]) ** 2
                    + (scene_xyz[a, 2] - scene_xyz[j, 2]) ** 2
                )
                dm = np.sqrt(
                    (model_xyz[a, 0] - model_xyz[j, 0]) ** 2
                    + (model_xyz[a, 1] - model_xyz[j, 1]) ** 2
                    + (model_xyz[a, 2] - model_xyz[j, 2]) ** 2
                )
                if abs(ds - dm) > consensus:
                    good = False
                    break
            if good:
                members[size] = j
                size += 1
        if size >= min_size:
            for q in range(size):
                taken[members[q]] = True
                labels[members[q]] = n_groups
            n_groups += 1
    return labels, n_groups


def group_geometrically_consistent(
    scene_keypoints: np.ndarray,
    model_keypoints: np.ndarray,
    corr: Correspondences,
    consensus_m: float,
    min_size: int,
    max_groups: int | None = None,
) -> list[np.ndarray]:
    """Group correspondences into geometrically consistent sets (PCL GeometricConsistencyGrouping idea).

    Seeds are taken best descriptor distance first; a correspondence joins a seed's group when, against every
    member already in it, the scene distance and the model distance differ by less than ``consensus_m``
    (rigid motions preserve distances). Groups of at least ``min_size`` claim their members.

    Args:
        scene_keypoints: (S, 3) metres.
        model_keypoints: (M, 3) metres.
        corr: correspondences, best first.
        consensus_m: distance-preservation tolerance, metres.
        min_size: smallest group kept.
        max_groups: keep the largest this many groups (ties: earlier seed first).

    Returns:
        list of (G_i,) int64 arrays of indices into ``corr``, largest first.

    """
    if len(corr) < min_size:
        return []
    labels, n_groups = _gc_groups(
        np.ascontiguousarray(scene_keypoints[corr.scene], np.float64),
        np.ascontiguousarray(model_keypoints[corr.model], np.float64),
        float(consensus_m),
        int(min_size),
    )
    groups = [np.flatnonzero(labels == g) for g in range(n_groups)]
    groups.sort(key=lambda g: -len(g))  # stable: equal sizes keep seed order
    return groups if max_groups is None else groups[:max_groups]


@dataclass(frozen=True)
class HoughSettings:
    """Settings of the upright Hough grouping (``group_upright_hough``).

    Attributes:
        cell_m: position cell of the accumulator, metres.
        yaw_bin_rad: heading bin, radians.
        height_tol_m: largest difference between the scene height and the model height, metres.
        min_size: smallest group kept.
        max_groups: keep the largest this many groups (None: all).

    """

    cell_m: float
    yaw_bin_rad: float
    height_tol_m: float
    min_size: int
    max_groups: int | None = None


@dataclass(frozen=True)
class YawWindow:
    """The headings a correspondence may vote for: within ``half_width_rad`` of its ``centre_rad``.

    Attributes:
        centre_rad: (C,) expected heading per correspondence, radians (e.g. from the template view's
            azimuth and the camera's direction).
        half_width_rad: half-width of the window, radians.

    """

    centre_rad: np.ndarray
    half_width_rad: float


def group_upright_hough(
    scene_keypoints: np.ndarray,
    scene_heights: np.ndarray,
    model_keypoints: np.ndarray,
    corr: Correspondences,
    settings: HoughSettings,
    yaw_window: YawWindow | None = None,
) -> list[np.ndarray]:
    """Geometrically consistent groups for an upright target on the ground, by Hough voting.

    A ground vehicle's pose has four degrees of freedom that matter (position and heading; its tilt
    follows the gentle terrain). A correspondence (scene s, model m) is consistent with a pose only if
    s stands as high above the ground as m above the model's base (``height_tol_m``); for each heading
    bin theta it then fixes the position ``s_xy - R(theta) m_xy``. Every correspondence votes in a
    (heading, x, y) accumulator; a peak holds the correspondences that agree on one pose, i.e. a group
    whose members are pairwise consistent (the role of PCL's geometric-consistency or Hough 3D
    grouping, with the upright prior making each vote two-dimensional instead of six).

    Args:
        scene_keypoints: (S, 3) metres, world frame (z up).
        scene_heights: (S,) metres above the local ground (``height_above_ground``).
        model_keypoints: (M, 3) metres, template frame (origin on the ground, z up).
        corr: correspondences.
        settings: accumulator cells, height tolerance and group sizes.
        yaw_window: optional headings each correspondence may vote for; None: every heading.

    Returns:
        list of (G_i,) int64 arrays of indices into ``corr``, largest first.

    """
    min_size = settings.min_size
    if len(corr) < min_size:
        return []
    s = np.asarray(scene_keypoints, np.float64)[corr.scene]
    hs = np.asarray(scene_heights, np.float64)[corr.scene]
    m = np.asarray(model_keypoints, np.float64)[corr.model]
    ok = np.flatnonzero(np.abs(hs - m[:, 2]) <= settings.height_tol_m)
    if len(ok) < min_size:
        return []
    n_bins = max(1, int(round(2 * np.pi / settings.yaw_bin_rad)))
    centres = (np.arange(n_bins) + 0.5) * (2 * np.pi / n_bins)
    window = _heading_bins_allowed(yaw_window, ok, centres)
    ci, cell, nx, ny = _kernels.hough_votes(
        np.ascontiguousarray(s),
        np.ascontiguousarray(m),
        ok,
        window,
        np.cos(centres),
        np.sin(centres),
        float(settings.cell_m),
    )
    if len(ci) == 0:
        return []
    return _claim_peaks(cell, ci, (n_bins, nx, ny), len(corr), settings)


def _heading_bins_allowed(
    yaw_window: YawWindow | None, ok: np.ndarray, centres: np.ndarray
) -> np.ndarray:
    """(len(ok), bins) int8: 1 where correspondence ``ok[i]`` may vote for heading bin b."""
    n_bins = len(centres)
    if yaw_window is None:
        return np.ones((len(ok), n_bins), np.int8)
    limit = yaw_window.half_width_rad + 0.5 * (2 * np.pi / n_bins)
    yaw = np.asarray(yaw_window.centre_rad, np.float64)[ok]
    window = _kernels.yaw_window(yaw, centres, limit)
    if (window < 0).any():  # too close to call arithmetically: the exact rule decides
        r, b = np.nonzero(window < 0)
        window[r, b] = np.abs(np.angle(np.exp(1j * (centres[b] - yaw[r])))) <= limit
    return window


def _claim_peaks(
    cell: np.ndarray,
    ci: np.ndarray,
    shape: tuple[int, int, int],
    n_corr: int,
    settings: HoughSettings,
) -> list[np.ndarray]:
    """Groups from the accumulator's votes (cell, correspondence), largest first.

    ``shape`` is the accumulator's (heading bins, x cells, y cells).
    """
    # A correspondence votes at most once per bin, so a cell's votes are distinct correspondences.
    # Peaks are taken most votes first, ties in (bin, x, y) order.
    by_cell = _kernels.stable_argsort_nonnegative(cell)
    cell, ci = cell[by_cell], ci[by_cell]
    peaks, counts = _kernels.count_runs(cell, settings.min_size)
    peaks = peaks[np.argsort(-counts, kind="stable")]
    n_bins, nx, ny = shape
    members, sizes = _kernels.claim_hough_groups(
        cell,
        ci,
        peaks,
        n_bins,
        nx,
        ny,
        n_corr,
        settings.min_size,
        -1 if settings.max_groups is None else settings.max_groups,
    )
    groups = np.split(members, np.cumsum(sizes)[:-1]) if len(sizes) else []
    groups.sort(key=lambda g: -len(g))  # stable: equal sizes keep peak order
    return groups


def rigid_transform(model_xyz: np.ndarray, scene_xyz: np.ndarray) -> np.ndarray:
    """Least-squares rigid transform (Kabsch) mapping model points onto scene points; (4, 4) float64."""
    mc, sc = model_xyz.mean(0), scene_xyz.mean(0)
    H = (model_xyz - mc).T @ (scene_xyz - sc)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    R = Vt.T @ D @ U.T
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = sc - R @ mc
    return T


@dataclass(frozen=True)
class Hypothesis:
    """A transformation hypothesis from one correspondence group.

    Attributes:
        T_scene_model: (4, 4) float64, maps model coordinates into the scene.
        inliers: RANSAC inliers among the group's correspondences.
        group_size: correspondences in the group.

    """

    T_scene_model: np.ndarray
    inliers: int
    group_size: int


def upright_rigid_transform(model_xyz: np.ndarray, scene_xyz: np.ndarray) -> np.ndarray:
    """Least-squares transform made of a turn about the vertical and a translation; (4, 4) float64.

    The pose of a vehicle standing on the ground: its heading (2D Procrustes on the horizontal
    coordinates) and its position. It cannot tilt.
    """
    mc, sc = model_xyz.mean(0), scene_xyz.mean(0)
    yaw = _upright_yaw(model_xyz[None] - mc, scene_xyz[None] - sc)[0]
    T = np.eye(4)
    T[:3, :3] = _turns_about_z(np.array([yaw]))[0]
    T[:3, 3] = sc - T[:3, :3] @ mc
    return T


def _upright_yaw(model_centred: np.ndarray, scene_centred: np.ndarray) -> np.ndarray:
    """Least-squares heading (K,) turning each of K centred model sets (K, n, 3) onto its scene set."""
    a, b = model_centred[..., :2], scene_centred[..., :2]
    dot = np.sum(a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1], axis=-1)
    cross = np.sum(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0], axis=-1)
    return np.arctan2(cross, dot)


def _turns_about_z(yaw: np.ndarray) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.zeros((len(yaw), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


@dataclass(frozen=True)
class RansacSettings:
    """Settings of RANSAC on one group (``ransac_per_group``).

    Attributes:
        iterations: samples of 3 correspondences drawn (§II-B-2: 1000).
        inlier_m: a correspondence is an inlier when its scene residual is below this, metres.
        upright: fit a heading and a translation only (a vehicle standing on the ground), not a full
            rigid transform.

    """

    iterations: int
    inlier_m: float
    upright: bool = False


def ransac_per_group(
    scene_keypoints: np.ndarray,
    model_keypoints: np.ndarray,
    corr: Correspondences,
    group: np.ndarray,
    settings: RansacSettings,
    rng: np.random.Generator,
) -> Hypothesis | None:
    """RANSAC on one consistent group (§II-B-2, 1000 iterations) -> a transformation hypothesis.

    Each iteration fits a transform to 3 random correspondences; the one with most inliers (scene
    residual < ``inlier_m``) is refitted on its inliers. The transform is rigid (Kabsch, the paper's), or
    with ``upright`` a heading and a translation only (``upright_rigid_transform``): a ground vehicle
    stands on the ground, and a side view's nearly coplanar keypoints otherwise let the 3-point fit tilt
    the model by tens of degrees (docs/recognition.md).

    Args:
        scene_keypoints: (S, 3) metres.
        model_keypoints: (M, 3) metres.
        corr: correspondences.
        group: (G,) indices into ``corr``.
        settings: iterations, inlier distance, upright or rigid.
        rng: draws the samples (the only randomness of the matcher).

    Returns:
        The hypothesis, or None when the group has fewer than 3 correspondences or no non-degenerate sample.

    """
    iterations, inlier_m, upright = settings.iterations, settings.inlier_m, settings.upright
    s = np.asarray(scene_keypoints[corr.scene[group]], np.float64)
    m = np.asarray(model_keypoints[corr.model[group]], np.float64)
    n = len(group)
    if n < 3:
        return None
    idx = rng.integers(0, n, size=(iterations, 3))
    ok = (idx[:, 0] != idx[:, 1]) & (idx[:, 0] != idx[:, 2]) & (idx[:, 1] != idx[:, 2])
    idx = idx[ok]
    if len(idx) == 0:
        return None
    if upright:
        mc, sc, dot, cross = _kernels.sample_upright_sums(m, s, idx)
        R = _turns_about_z(np.arctan2(cross, dot))
        t = sc - np.einsum("kij,kj->ki", R, mc)
    else:
        mc, sc, H = _kernels.sample_cross_covariances(m, s, idx)
        U, _, Vt = np.linalg.svd(H)
        R, t = _kernels.kabsch_poses(U, Vt, mc, sc)
    best, best_count = _kernels.most_inliers(R, t, m, s, float(inlier_m) ** 2)
    if best_count < 3:
        return None
    R_best_T = np.ascontiguousarray(R[best].T)  # C order as before: BLAS rounds by layout
    mask = np.sum(((m @ R_best_T + t[best]) - s) ** 2, axis=1) < inlier_m**2
    T = (upright_rigid_transform if upright else rigid_transform)(m[mask], s[mask])
    final = np.sum(((m @ T[:3, :3].T + T[:3, 3]) - s) ** 2, axis=1) < inlier_m**2
    return Hypothesis(T_scene_model=T, inliers=int(max(final.sum(), best_count)), group_size=n)


def drop_repeated_hypotheses(
    hypotheses: Sequence[tuple[int, Hypothesis]], same_m: float, same_rad: float
) -> list[tuple[int, Hypothesis]]:
    """Keep the first of hypotheses of one view that place the model alike.

    Groups of neighbouring Hough cells often lead RANSAC to the same pose; ICP from starts this close
    ends alike, so verifying each again costs time and changes nothing (docs/recognition.md).

    Args:
        hypotheses: (view index, hypothesis) pairs, best first.
        same_m: two poses closer than this in translation, metres ...
        same_rad: ... and in rotation angle, radians, are one.

    Returns:
        The hypotheses kept, in their order.

    """
    kept: list[tuple[int, Hypothesis]] = []
    for view, h in hypotheses:
        T = h.T_scene_model
        repeated = False
        for kept_view, k in kept:
            if kept_view != view:
                continue
            R_between = k.T_scene_model[:3, :3].T @ T[:3, :3]
            angle = np.arccos(np.clip((np.trace(R_between) - 1.0) / 2.0, -1.0, 1.0))
            if np.linalg.norm(k.T_scene_model[:3, 3] - T[:3, 3]) < same_m and angle < same_rad:
                repeated = True
                break
        if not repeated:
            kept.append((view, h))
    return kept


@dataclass(frozen=True)
class Verification:
    """Outcome of ICP verification of one hypothesis.

    Attributes:
        T_scene_model: (4, 4) float64 after ICP refinement.
        overlap: fraction of model vertices with a scene vertex within the overlap distance.
        overlap_vertices: how many model vertices overlap.
        clutter: fraction of the scene vertices inside the model's box (above its ground slab) that no model
            vertex explains; 0 when the box holds no scene vertex.
        rmse_m: RMS distance of the overlapping vertices, metres.

    """

    T_scene_model: np.ndarray
    overlap: float
    overlap_vertices: int
    clutter: float
    rmse_m: float


@dataclass(frozen=True)
class VerifySettings:
    """Settings of ICP verification (``verify_with_icp``).

    Attributes:
        icp_gate_m: ICP maximum correspondence distance, metres.
        overlap_m: overlap distance, metres.
        icp_iterations: ICP iteration cap.
        ground_slab_m: height above the model's lowest point ignored by the clutter measure, metres.
        k_clutter_sigma: a scene vertex with a sigma counts as explained by the model within
            max(``overlap_m``, this x its sigma): noise is not clutter.
        icp_reach_m: when given, ICP runs on the scene vertices within the model's radius +
            ``icp_gate_m`` + this distance of the placed model's centre, not on the whole scene:
            Open3D builds a kd-tree of its target at every call, which on a LIDAR scene costs far more
            than the ICP itself. ICP can only pair vertices within the gate of the moving model, so the
            result is the same as on the whole scene as long as the model's centre moves less than this;
            a hypothesis whose refined centre moved further is refined again on the whole scene.
        point_to_plane: ICP minimises the distances to the scene's local planes instead of to its
            points: two surfaces sampled apart do not hold each other at the sampling's offsets. The
            planes are the scene's own normals (``PointSet.normals``) when it has them, else estimated
            from neighbours within ``icp_gate_m`` at each call.
        plane_max_sigma_m: with ``point_to_plane``, a scene with per-point sigma is fitted to its
            planes only where the median sigma of the vertices ICP fits is at most this, and to its
            points elsewhere (None: planes everywhere).
        plane_min_spread: with ``point_to_plane``, the planes are fitted only where the normals of the
            vertices ICP fits spread over all three directions: the smallest eigenvalue of their mean
            outer product (1/3 for normals spread evenly, 0 for one plane or two) at least this; else
            the points. Planes that all share a direction (flat ground, one wall, a dihedral) leave
            the pose free along it, and Open3D's solve then returns different poses from run to run.

    """

    icp_gate_m: float
    overlap_m: float
    icp_iterations: int
    ground_slab_m: float = 0.0
    k_clutter_sigma: float = 0.0
    icp_reach_m: float | None = None
    point_to_plane: bool = False
    plane_max_sigma_m: float | None = None
    plane_min_spread: float = 0.0


@dataclass
class PointSet:
    """Points with their kd-tree (built on first use, then reused), optional per-point sigma and normals.

    Attributes:
        points_m: (N, 3) float64, metres.
        sigma_m: optional (N,) 1-sigma position uncertainty of each point, metres (SfM gives it).
        normals: optional (N, 3) unit normals of the surface the points sample.

    """

    points_m: np.ndarray
    sigma_m: np.ndarray | None = None
    normals: np.ndarray | None = None
    _tree: cKDTree | None = None

    @property
    def tree(self) -> cKDTree:
        """kd-tree of ``points_m``."""
        if self._tree is None:
            self._tree = cKDTree(self.points_m)
        return self._tree


def verify_with_icp(
    model: PointSet, scene: PointSet, T_scene_model: np.ndarray, settings: VerifySettings
) -> Verification:
    """Apply a hypothesis to the model, refine it with ICP against the scene, measure the fit (§II-B-2).

    Two measures: the model side (how many model vertices have a scene vertex within ``overlap_m``, or
    within the scene's own spacing in the model's box when a sparse scene samples the target more coarsely:
    the paper's overlapping vertices) and the scene side (how much of what the scene holds inside the model's
    bounding box is *not* explained by the model: a box-shaped model laid on a building fits the wall but
    leaves the rest of the building unexplained). The bottom ``ground_slab_m`` of the box is ignored on the
    scene side, because the ground the target stands on is never part of the model.

    Args:
        model: model vertices P_m in the target frame, metres.
        scene: scene vertices, metres; with ``sigma_m``, a scene vertex counts as explained by the
            model within max(``overlap_m``, ``k_clutter_sigma`` x its sigma).
        T_scene_model: (4, 4) initial hypothesis.
        settings: ICP gate, iterations and reach; overlap distance, ground slab and clutter sigma.

    Returns:
        The refined pose and its fit with the scene.

    """
    model_points = np.asarray(model.points_m, np.float64)
    scene_points = np.asarray(scene.points_m, np.float64)
    T_initial = np.asarray(T_scene_model, np.float64)
    scene_tree, model_tree = scene.tree, model.tree
    overlap_m = settings.overlap_m
    T = _refine_with_icp(model_points, scene, T_initial, settings)
    R, t = T[:3, :3], T[:3, 3]
    # Scene side: scene vertices inside the model's box, in the model frame.
    lo, hi = model_points.min(0), model_points.max(0)
    centre = 0.5 * (lo + hi)
    near = scene_tree.query_ball_point(
        R @ centre + t, float(np.linalg.norm(hi - lo)) / 2 + overlap_m
    )
    inside_local = np.zeros((0, 3))
    explain_m = np.full(0, overlap_m)
    if near:
        near_idx = np.sort(near)
        local = (np.asarray(scene_points)[near_idx] - t) @ R  # R^T (p - t)
        inside = inside_model_box(local, np.eye(4), lo, hi, settings.ground_slab_m)
        inside_local = local[inside]
        explain_m = np.full(len(inside_local), overlap_m)
        if scene.sigma_m is not None:
            sigma = np.asarray(scene.sigma_m, np.float64)[near_idx[inside]]
            explain_m = np.maximum(explain_m, settings.k_clutter_sigma * sigma)
    # A sparse scene (a far target in a two-view cloud) samples the target more coarsely than the
    # model's resolution; a model vertex then overlaps when a scene vertex lies within the scene's own
    # spacing there (median nearest-neighbour distance inside the box), never less than overlap_m.
    model_side_m = overlap_m
    if len(inside_local) >= 3:
        spacing, _ = cKDTree(inside_local).query(inside_local, k=2)
        model_side_m = max(overlap_m, float(np.median(spacing[:, 1])))
    moved = model_points @ R.T + t
    d, _ = scene_tree.query(moved, distance_upper_bound=model_side_m)
    hit = np.isfinite(d)
    n_hit = int(hit.sum())
    rmse = float(np.sqrt(np.mean(d[hit] ** 2))) if n_hit else float("inf")
    clutter = 0.0
    if len(inside_local):
        dm, _ = model_tree.query(inside_local, distance_upper_bound=float(explain_m.max()))
        clutter = float(np.mean(~(dm <= explain_m)))
    return Verification(T, n_hit / max(len(model_points), 1), n_hit, clutter, rmse)


def inside_model_box(
    points_m: np.ndarray,
    T_scene_model: np.ndarray,
    lo_m: np.ndarray,
    hi_m: np.ndarray,
    ground_slab_m: float,
) -> np.ndarray:
    """(N,) bool: which scene points lie inside the placed model's box, above its bottom slab.

    Args:
        points_m: (N, 3) scene points.
        T_scene_model: (4, 4) model pose in the scene.
        lo_m, hi_m: (3,) the box corners in the model frame.
        ground_slab_m: the box's bottom this high is left out (the ground the target stands on).

    """
    R, t = T_scene_model[:3, :3], T_scene_model[:3, 3]
    local = (np.asarray(points_m, np.float64) - t) @ R  # R^T (p - t)
    box_lo = np.array(lo_m, np.float64)
    box_lo[2] += ground_slab_m
    return np.all((local >= box_lo) & (local <= hi_m), axis=1)


def _refine_with_icp(
    model_points: np.ndarray, scene: PointSet, T_initial: np.ndarray, settings: VerifySettings
) -> np.ndarray:
    """ICP of the model onto the scene from ``T_initial``: on the neighbourhood within reach, or on the
    whole scene when the pose moved further (``VerifySettings.icp_reach_m``).
    """
    scene_points, scene_tree = scene.points_m, scene.tree
    icp_gate_m, icp_reach_m = settings.icp_gate_m, settings.icp_reach_m
    src = _open3d_cloud(model_points)

    def icp(index: np.ndarray | None) -> np.ndarray:
        """ICP onto the scene's vertices ``index`` (None: all of them)."""
        target = _open3d_cloud(scene_points if index is None else scene_points[index])
        estimation = o3d.pipelines.registration.TransformationEstimationPointToPoint()
        if _to_planes(scene, index, settings):
            if scene.normals is None:
                target.estimate_normals(
                    o3d.geometry.KDTreeSearchParamHybrid(radius=float(icp_gate_m), max_nn=16)
                )
            else:
                normals = scene.normals if index is None else scene.normals[index]
                target.normals = o3d.utility.Vector3dVector(np.asarray(normals, np.float64))
            if normal_spread(np.asarray(target.normals)) >= settings.plane_min_spread:
                estimation = o3d.pipelines.registration.TransformationEstimationPointToPlane()
        # Open3D sums the point-to-plane normal equations in parallel, in an order that varies from
        # run to run; one thread sums them in one order, so a replay gives the same bytes
        threads = o3d.utility.get_max_threads()
        o3d.utility.set_max_threads(1)
        try:
            result = o3d.pipelines.registration.registration_icp(
                src,
                target,
                float(icp_gate_m),
                T_initial,
                estimation,
                o3d.pipelines.registration.ICPConvergenceCriteria(
                    max_iteration=int(settings.icp_iterations)
                ),
            )
        finally:
            o3d.utility.set_max_threads(threads)
        return np.asarray(result.transformation, np.float64).copy()

    T = None
    if icp_reach_m is not None:
        model_centre = model_points.mean(axis=0)
        model_radius = float(np.linalg.norm(model_points - model_centre, axis=1).max())
        placed_centre = T_initial[:3, :3] @ model_centre + T_initial[:3, 3]
        near = scene_tree.query_ball_point(placed_centre, model_radius + icp_gate_m + icp_reach_m)
        # nothing within reach: ICP would find no pair on the whole scene either
        T = T_initial.copy() if not near else icp(np.sort(near))
        if np.linalg.norm(T[:3, :3] @ model_centre + T[:3, 3] - placed_centre) > icp_reach_m:
            T = None
    if T is None:
        T = icp(None)
    return T


def normal_spread(normals: np.ndarray) -> float:
    """Smallest eigenvalue of the mean outer product of unit normals (N, 3): how much of their
    direction the least-covered axis gets; 1/3 for normals spread evenly, 0 when they all lie in one
    plane (one or two families of parallel planes leave a translation unconstrained). 0 for none.
    """
    n = np.asarray(normals, np.float64)
    if len(n) == 0:
        return 0.0
    return float(np.linalg.eigvalsh(n.T @ n / len(n))[0])


def _to_planes(scene: PointSet, index: np.ndarray | None, settings: VerifySettings) -> bool:
    """Whether ICP onto the scene's vertices ``index`` (None: all) fits to their planes."""
    if not settings.point_to_plane:
        return False
    if settings.plane_max_sigma_m is None or scene.sigma_m is None:
        return True
    sigma = scene.sigma_m if index is None else scene.sigma_m[index]
    return bool(len(sigma)) and float(np.median(sigma)) <= settings.plane_max_sigma_m


def _open3d_cloud(points_m: np.ndarray) -> o3d.geometry.PointCloud:
    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points_m))
