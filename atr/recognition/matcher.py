"""Online phase of the 3D ATR module (paper §II-B-2): recognise templates in a scene point cloud.

``recognize`` reads as the paper's list of steps; each step is a public function in
``atr.recognition.steps``. Several templates (the T-72 and its confusers) are matched against one scene
description, and where hypotheses of different targets overlap only the best-scoring one is reported, so the
output says *which* target is there, not only that something is.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from atr.errors import ConfigError, InputError
from atr.recognition import _backend
from atr.recognition.config import RecognitionConfig
from atr.recognition.steps import (
    Correspondences,
    descriptor_sq_distances,
    drop_repeated_hypotheses,
    filter_smooth_surfaces,
    group_geometrically_consistent,
    group_upright_hough,
    height_above_ground,
    knndr_from_distances,
    lowest_per_cell,
    ransac_per_group,
    terrain_height_at,
    uniform_subsample,
    verify_with_icp,
)
from atr.recognition.template import Template, model_extent_m

STAGES: tuple[str, ...] = (
    "subsample",
    "ground",
    "normals",
    "filter",
    "describe",
    "match",
    "group",
    "ransac",
    "icp",
)
"""Keys of ``RecognitionResult.stage_times_ms`` (plus "total")."""


@dataclass
class Detection:
    """One recognised target instance.

    Attributes:
        target: template target name.
        descriptor: descriptor that found it.
        T_world_target: (4, 4) float64, maps target-frame (template) coordinates into the scene's world frame.
        score: overlapping model vertices x (1 - clutter) after ICP (higher is better; compares targets).
        overlap: fraction of the template's vertices with a scene vertex within the overlap distance.
        inliers: RANSAC inlier correspondences of the winning hypothesis.

    """

    target: str
    descriptor: str
    T_world_target: np.ndarray
    score: float
    overlap: float
    inliers: int

    def to_dict(self) -> dict[str, Any]:
        """JSON/msgpack-friendly dict with the contract's field names (pose as nested lists)."""
        return {
            "target": self.target,
            "descriptor": self.descriptor,
            "T_world_target": np.asarray(self.T_world_target, np.float64).tolist(),
            "score": float(self.score),
            "overlap": float(self.overlap),
            "inliers": int(self.inliers),
        }


@dataclass
class RecognitionResult:
    """Output of ``recognize``.

    Attributes:
        detections: accepted detections, best score first (empty when nothing is accepted).
        stage_times_ms: wall time per stage (``STAGES`` and "total"), milliseconds; not deterministic.
        stats: counts per stage, and "reason" when the result is empty because of the input.

    """

    detections: list[Detection]
    stage_times_ms: dict[str, float]
    stats: dict[str, Any] = field(default_factory=dict)


class _Clock:
    def __init__(self) -> None:
        self.ms = dict.fromkeys(STAGES, 0.0)
        self._t0 = time.perf_counter()

    def add(self, stage: str, t_start: float) -> float:
        now = time.perf_counter()
        self.ms[stage] += (now - t_start) * 1e3
        return now

    def result(self) -> dict[str, float]:
        out = dict(self.ms)
        out["total"] = (time.perf_counter() - self._t0) * 1e3
        return out


def _validate_scene(scene_points_m: np.ndarray, config: RecognitionConfig) -> np.ndarray:
    pts = np.asarray(scene_points_m)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError(f"scene points must be an (N, 3) array; got shape {pts.shape}")
    if not np.issubdtype(pts.dtype, np.number):
        raise InputError(f"scene points must be numeric; got dtype {pts.dtype}")
    if len(pts) > config.max_scene_points:
        raise InputError(
            f"scene has {len(pts)} points; at most max_scene_points = {config.max_scene_points}"
        )
    return pts.astype(np.float64, copy=False)


def recognize(
    scene_points_m: np.ndarray,
    templates: Sequence[Template],
    config: RecognitionConfig,
    *,
    seed: int,
    viewpoint_m: np.ndarray | None = None,
    scene_sigma_m: np.ndarray | None = None,
) -> RecognitionResult:
    """Recognise the templates' targets in a scene cloud (§II-B-2).

    Steps: uniform subsampling -> normals (plane fit on ``normal_k`` neighbours) -> smooth-surface filter ->
    description with each template's descriptor -> kNNDR matching -> geometric-consistency grouping ->
    RANSAC per group -> ICP verification and overlap test -> non-maximum suppression across targets.

    Args:
        scene_points_m: (N, 3) world-frame scene points, metres. Non-finite rows are dropped (counted in
            ``stats["dropped_nonfinite"]``).
        templates: templates to look for, built with the same ``config.resolution_m``.
        config: recognition configuration.
        seed: seed of the RANSAC generator (e.g. the cloud's seq); same seed -> same detections.
        viewpoint_m: (3,) sensor position used to orient scene normals; None orients them up (+z).
        scene_sigma_m: optional (N,) 1-sigma position uncertainty per scene point, metres (the SfM
            cloud's ``sigma_m``); verification then does not count a point's noise as clutter
            (``config.k_clutter_sigma``). None (e.g. LIDAR): the fixed overlap distance.

    Returns:
        RecognitionResult; empty detections with ``stats["reason"]`` when the scene is too small.

    Raises:
        InputError: the scene is not an (N, 3) numeric array or exceeds ``max_scene_points``, or
            ``scene_sigma_m`` is not (N,).
        ConfigError: a template was built at another resolution than ``config.resolution_m``.

    """
    clock = _Clock()
    stats: dict[str, Any] = {}
    pts = _validate_scene(scene_points_m, config)
    sigma = None
    if scene_sigma_m is not None:
        sigma = np.asarray(scene_sigma_m, np.float64)
        if sigma.shape != (len(pts),):
            raise InputError(
                f"scene_sigma_m must have shape ({len(pts)},) like the scene; got {sigma.shape}"
            )
    for tpl in templates:
        res = tpl.params.get("resolution_m", config.resolution_m)
        if abs(float(res) - config.resolution_m) > 1e-9 * max(1.0, config.resolution_m):
            raise ConfigError(
                f"template {tpl.target}/{tpl.descriptor} was built at resolution {res} m; "
                f"the matcher runs at {config.resolution_m} m"
            )
    rng = np.random.default_rng(seed)

    def empty(reason: str) -> RecognitionResult:
        stats["reason"] = reason
        return RecognitionResult([], clock.result(), stats)

    t = time.perf_counter()
    finite = np.isfinite(pts).all(axis=1)
    if sigma is not None:
        finite &= np.isfinite(sigma)
    stats["scene_points"] = int(len(pts))
    stats["dropped_nonfinite"] = int(len(pts) - finite.sum())
    pts = pts[finite]
    if len(pts) == 0:
        return empty("scene has no finite points")
    chosen = uniform_subsample(pts, config.resolution_m)
    surface = pts[chosen]
    if sigma is not None:
        sigma = sigma[finite][chosen]
    stats["subsampled_points"] = int(len(surface))
    t = clock.add("subsample", t)
    if len(surface) < config.normal_k + 1:
        return empty(
            f"scene has {len(surface)} vertices after {config.resolution_m} m subsampling; "
            f"at least {config.normal_k + 1} are needed"
        )
    if not templates:
        return empty("no templates given")

    band = None
    terrain = None
    if config.ground_vehicles and all(tpl.params.get("on_ground") for tpl in templates):
        # Ground vehicles: drop the ground from the description surface, keep keypoints in the band
        # of heights a target occupies (docs/recognition.md, "Ground").
        height = height_above_ground(
            surface,
            config.k_ground_cell * config.resolution_m,
            config.k_ground_window * config.resolution_m,
            config.ground_percentile,
        )
        terrain = lowest_per_cell(surface, config.k_ground_cell * config.resolution_m)
        top = max(float(np.asarray(tpl.points_m)[:, 2].max()) for tpl in templates)
        above = height >= config.ground_cut_m
        surface, height = surface[above], height[above]
        if sigma is not None:
            sigma = sigma[above]
        band = (height >= config.k_keypoint_min_height * config.resolution_m) & (
            height <= top + config.ground_cut_m
        )
        stats["above_ground_points"] = int(len(surface))
        if len(surface) < config.normal_k + 1:
            return empty(f"only {len(surface)} scene vertices stand above the ground")
    t = clock.add("ground", t)

    normals = _backend.estimate_normals(surface, config.normal_k, viewpoint_m)
    t = clock.add("normals", t)
    keep = filter_smooth_surfaces(surface, normals, config.normal_k, config.smooth_angle_rad)
    if band is not None:
        keep &= band
    kp_idx = np.flatnonzero(keep)
    if len(kp_idx) > config.max_scene_keypoints:
        kp_idx = np.sort(rng.choice(kp_idx, size=config.max_scene_keypoints, replace=False))
    stats["keypoints"] = int(len(kp_idx))
    t = clock.add("filter", t)
    if len(kp_idx) < config.min_group_size:
        return empty(f"only {len(kp_idx)} scene vertices survive the smooth-surface filter")
    keypoints = surface[kp_idx]
    kp_height = None if band is None else height[kp_idx]
    ground_xy = None if band is None else cKDTree(surface[:, :2])
    ground_z = None if band is None else surface[:, 2] - height

    scene_tree = cKDTree(surface)
    scene_desc: dict[tuple[str, float], np.ndarray] = {}
    candidates: list[tuple[Detection, np.ndarray, float]] = []
    per_target: list[dict[str, Any]] = []
    hyp_log: list[tuple] = []
    for tpl in templates:
        key = (tpl.descriptor, float(tpl.radius_m))
        t = time.perf_counter()
        if key not in scene_desc:
            scene_desc[key] = _backend.describe(
                tpl.descriptor, surface, normals, kp_idx, tpl.radius_m
            )
        t = clock.add("describe", t)
        views = tpl.view_slices()
        view_az = tpl.params.get("view_azimuths_deg")
        view_el = tpl.params.get("view_elevations_deg")
        if not (
            viewpoint_m is not None
            and band is not None
            and view_az is not None
            and view_el is not None
            and len(view_az) == len(views) == len(view_el)
        ):
            view_az = None
            view_el = [0.0] * len(views)
            ring_of_vertex = np.zeros(len(keypoints))
        else:
            # each scene vertex is matched with the views of the ring nearest the camera's elevation
            # seen from it (the camera position is known)
            rings = np.unique(np.asarray(view_el, np.float64))
            rel = np.asarray(viewpoint_m, np.float64) - keypoints
            cam_el = np.degrees(np.arctan2(rel[:, 2], np.linalg.norm(rel[:, :2], axis=1)))
            ring_of_vertex = rings[np.argmin(np.abs(cam_el[:, None] - rings[None, :]), axis=1)]
        matches = _match_views(
            scene_desc[key], tpl.descriptors, views, view_el, ring_of_vertex, config
        )
        t = clock.add("match", t)
        model_kp_all = np.asarray(tpl.keypoints_m, np.float64)
        view_groups = []
        for vi, ((_, ksl), corr) in enumerate(zip(views, matches, strict=True)):
            if band is None:
                groups = group_geometrically_consistent(
                    keypoints,
                    model_kp_all[ksl],
                    corr,
                    config.consensus_m,
                    config.min_group_size,
                    config.max_groups,
                )
            else:
                yaw_centre = None
                half = float(np.pi)
                if view_az is not None:
                    # the camera sees the target from the view's azimuth: heading = direction to the
                    # camera minus that azimuth (within half the view spacing and a margin)
                    to_cam = np.asarray(viewpoint_m, np.float64)[:2] - keypoints[corr.scene, :2]
                    yaw_centre = np.arctan2(to_cam[:, 1], to_cam[:, 0]) - np.radians(view_az[vi])
                    half = np.pi / len(set(view_az)) + np.radians(config.view_yaw_margin_deg)
                groups = group_upright_hough(
                    keypoints,
                    kp_height,
                    model_kp_all[ksl],
                    corr,
                    cell_m=config.k_hough_cell * config.resolution_m,
                    yaw_bin_rad=np.radians(config.hough_yaw_bin_deg),
                    height_tol_m=config.k_height_tol * config.resolution_m,
                    min_size=config.min_group_size,
                    max_groups=config.max_groups,
                    yaw_centre_rad=yaw_centre,
                    yaw_half_width_rad=half,
                )
            view_groups.append(groups)
        t = clock.add("group", t)
        # the largest groups over all views go to RANSAC (stable: view order breaks ties)
        ranked = sorted(
            ((vi, g) for vi, groups in enumerate(view_groups) for g in groups),
            key=lambda vg: -len(vg[1]),
        )[: config.max_groups]
        hyps: list[tuple[int, Any]] = []
        for vi, g in ranked:
            h = ransac_per_group(
                keypoints,
                model_kp_all[views[vi][1]],
                matches[vi],
                g,
                config.ransac_iterations,
                config.ransac_inlier_m,
                rng,
                upright=band is not None,
            )
            if h is not None and h.inliers >= config.min_group_size:
                hyps.append((vi, h))
        n_ransac = len(hyps)
        hyps = drop_repeated_hypotheses(
            hyps, config.same_hypothesis_m, np.radians(config.same_hypothesis_deg)
        )
        t = clock.add("ransac", t)
        model_all = np.asarray(tpl.points_m, np.float64)
        extent = model_extent_m(tpl)
        view_cache: dict[int, tuple[np.ndarray, cKDTree]] = {}
        accepted = 0
        for vi, h in hyps:
            if vi not in view_cache:
                pts_v = model_all[views[vi][0]]
                view_cache[vi] = (pts_v, cKDTree(pts_v))
            model_pts, model_tree = view_cache[vi]
            v = verify_with_icp(
                model_pts,
                surface,
                h.T_scene_model,
                config.icp_gate_m,
                config.overlap_m,
                config.icp_iterations,
                ground_slab_m=config.ground_slab_m,
                scene_tree=scene_tree,
                model_tree=model_tree,
                scene_sigma_m=sigma,
                k_clutter_sigma=config.k_clutter_sigma,
                icp_reach_m=config.icp_reach_m,
            )
            on_ground = True
            if ground_xy is not None:
                # a ground vehicle's origin (on the ground under it) must lie on the scene's ground
                _, nb = ground_xy.query(v.T_scene_model[:2, 3], k=min(10, len(ground_z)))
                z_ground = float(np.median(ground_z[np.atleast_1d(nb)]))
                on_ground = (
                    abs(v.T_scene_model[2, 3] - z_ground)
                    <= config.k_height_tol * config.resolution_m
                )
            if on_ground and terrain is not None:
                # ... and that ground must be the terrain, not a roof (docs/recognition.md, "Roofs")
                z_terrain = terrain_height_at(
                    *terrain,
                    v.T_scene_model[:2, 3],
                    config.terrain_window_m,
                    config.ground_percentile,
                )[0]
                on_ground = bool(
                    np.isnan(z_terrain)
                    or v.T_scene_model[2, 3] - z_terrain <= config.terrain_step_m
                )
            hyp_log.append(
                (
                    tpl.target,
                    vi,
                    round(v.overlap, 3),
                    v.overlap_vertices,
                    round(v.clutter, 3),
                    *(round(float(x), 2) for x in v.T_scene_model[:3, 3]),
                )
            )
            if (
                on_ground
                and v.overlap >= config.min_overlap
                and v.overlap_vertices >= config.min_overlap_vertices
                and v.clutter <= config.max_clutter
            ):
                accepted += 1
                det = Detection(
                    target=tpl.target,
                    descriptor=tpl.descriptor,
                    T_world_target=v.T_scene_model,
                    score=float(v.overlap_vertices * (1.0 - v.clutter)),
                    overlap=float(v.overlap),
                    inliers=int(h.inliers),
                )
                centre_m = model_all.mean(axis=0)
                centre_w = v.T_scene_model[:3, :3] @ centre_m + v.T_scene_model[:3, 3]
                candidates.append((det, centre_w, extent))
        t = clock.add("icp", t)
        per_target.append(
            {
                "target": tpl.target,
                "descriptor": tpl.descriptor,
                "views": len(views),
                "correspondences": int(sum(len(c) for c in matches)),
                "groups": int(sum(len(g) for g in view_groups)),
                "hypotheses": n_ransac,
                "distinct_hypotheses": len(hyps),
                "accepted": accepted,
            }
        )
    stats["templates"] = per_target
    stats["verified"] = hyp_log
    detections = suppress_non_maxima(candidates, config.nms_m)
    stats["detections"] = len(detections)
    return RecognitionResult(detections, clock.result(), stats)


def _match_views(
    scene_desc: np.ndarray,
    model_desc: np.ndarray,
    views: list[tuple[slice, slice]],
    view_el: Sequence[float],
    ring_of_vertex: np.ndarray,
    config: RecognitionConfig,
) -> list[Correspondences]:
    """KNNDR of each scene keypoint against the views of its elevation ring.

    ``config.knn_across_views``: the k nearest are taken over all views of the ring together (one
    neighbour list per keypoint, then split by view); otherwise each view has its own k nearest.
    Returns one Correspondences per view, model indices local to the view.
    """
    out: list[Correspondences] = [
        Correspondences(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)) for _ in views
    ]

    def take(a: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """a[idx]; a slice (no copy of the descriptors) when idx is a run of consecutive rows."""
        if len(idx) and np.array_equal(idx, np.arange(idx[0], idx[0] + len(idx))):
            return a[idx[0] : idx[0] + len(idx)]
        return a[idx]

    view_el_arr = np.asarray(view_el, np.float64)
    for ring in np.unique(ring_of_vertex):
        rows = np.flatnonzero(ring_of_vertex == ring)
        in_ring = np.flatnonzero(view_el_arr == ring)
        if len(rows) == 0 or len(in_ring) == 0:
            continue
        cols = np.concatenate([np.arange(views[v][1].start, views[v][1].stop) for v in in_ring])
        owner = np.concatenate([np.full(views[v][1].stop - views[v][1].start, v) for v in in_ring])
        d2 = descriptor_sq_distances(take(scene_desc, rows), take(model_desc, cols))
        if config.knn_across_views:
            c = knndr_from_distances(d2, config.knndr_k, config.knndr_ratio)
            for v in in_ring:
                sel = np.flatnonzero(owner[c.model] == v)
                out[v] = Correspondences(
                    rows[c.scene[sel]], cols[c.model[sel]] - views[v][1].start, c.distance[sel]
                )
        else:
            start = 0
            for v in in_ring:
                n = views[v][1].stop - views[v][1].start
                c = knndr_from_distances(
                    d2[:, start : start + n],
                    config.knndr_k,
                    config.knndr_ratio,
                    config.max_correspondences,
                )
                out[v] = Correspondences(rows[c.scene], c.model, c.distance)
                start += n
    return out


def suppress_non_maxima(
    candidates: Sequence[tuple[Detection, np.ndarray, float]], nms_m: float
) -> list[Detection]:
    """Keep the best-scoring detection per location, across targets.

    Two candidates are at one location when their target centres are closer than
    max(``nms_m``, half the larger target extent).

    Args:
        candidates: (detection, world centre (3,), target extent metres) triples.
        nms_m: minimum suppression distance, metres.

    Returns:
        Kept detections, best score first (ties keep input order).

    """
    order = sorted(range(len(candidates)), key=lambda i: -candidates[i][0].score)
    kept: list[int] = []
    for i in order:
        _, ci, ei = candidates[i]
        clash = False
        for j in kept:
            _, cj, ej = candidates[j]
            if np.linalg.norm(ci - cj) < max(nms_m, 0.5 * max(ei, ej)):
                clash = True
                break
        if not clash:
            kept.append(i)
    return [candidates[i][0] for i in kept]
