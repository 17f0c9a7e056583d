"""Online phase of the 3D ATR module (paper §II-B-2): recognise templates in a scene point cloud.

``recognize`` reads as the paper's list of steps and ours; each step is a named function in
``atr.recognition.steps`` (the paper's) or ``atr.recognition.scene`` (ours: ground, views, headings).
Several templates (the target and its look-alikes) are matched against one scene description, and where
hypotheses of different targets share a place it goes to the template that explains it best
(``atr.recognition.competition``), so the output says *which* target is there, not only that something is.
"""

from __future__ import annotations

import time
from collections.abc import Collection, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from atr.errors import InputError
from atr.recognition import _backend, steps
from atr.recognition.attention import Blob, vehicle_places
from atr.recognition.competition import Candidate, CompetitionSettings, compete_for_places
from atr.recognition.config import MatcherConfig, RecognitionConfig
from atr.recognition.scene import (
    EmptyScene,
    GroundCheck,
    Scene,
    TemplateViews,
    attention_sizes,
    check_resolutions,
    estimate_normals,
    heading_window,
    remove_ground,
    select_keypoints,
    subsampled_scene,
    template_views,
    validated_cloud,
)
from atr.recognition.steps import Correspondences, Hypothesis
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
    "cue",
    "compete",
)
"""Keys of ``RecognitionResult.stage_times_ms`` (plus "total")."""


@dataclass
class Detection:
    """One recognised target instance.

    Attributes:
        target: template target name.
        descriptor: descriptor that found it.
        T_world_target: (4, 4) float64, maps target-frame (template) coordinates into the scene's world frame.
        score: the place competition's F-measure of support and explanation, in [0, 1] (higher is better;
            compares targets and places; ``atr.recognition.competition``).
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

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        t_start = time.perf_counter()
        try:
            yield
        finally:
            self.ms[name] += (time.perf_counter() - t_start) * 1e3

    def result(self) -> dict[str, float]:
        out = dict(self.ms)
        out["total"] = (time.perf_counter() - self._t0) * 1e3
        return out


def recognize(
    scene_points_m: np.ndarray,
    templates: Sequence[Template],
    config: RecognitionConfig,
    *,
    seed: int,
    viewpoint_m: np.ndarray | None = None,
    scene_sigma_m: np.ndarray | None = None,
    places_T_world_target: Sequence[np.ndarray] = (),
) -> RecognitionResult:
    """Recognise the templates' targets in a scene cloud (§II-B-2).

    Steps: uniform subsampling -> (ground vehicles: ground removal) -> normals (plane fit on
    ``normal_k`` neighbours) -> smooth-surface filter -> per template: description with its descriptor ->
    kNNDR matching per view -> grouping -> RANSAC per group -> ICP verification and acceptance ->
    the place competition across targets.

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
        places_T_world_target: (4, 4) world-from-target poses where every template is also laid and
            refined by ICP (``verify_places``), its fits competing with the searched ones (ours: the
            held tracks' poses in a track-guided flight's whole scenes, ``atr.tracking.guided_search``).

    Returns:
        RecognitionResult; empty detections with ``stats["reason"]`` when the scene is too small.

    Raises:
        InputError: the scene is not an (N, 3) numeric array or exceeds ``max_scene_points``, or
            ``scene_sigma_m`` is not (N,).
        ConfigError: a template was built at another resolution than ``config.resolution_m``.

    """
    clock = _Clock()
    stats: dict[str, Any] = {}
    pts, sigma = validated_cloud(scene_points_m, scene_sigma_m, config)
    check_resolutions(templates, config)
    rng = np.random.default_rng(seed)
    try:
        scene = _grounded_scene(pts, sigma, viewpoint_m, templates, config, clock, stats)
        with clock.stage("normals"):
            estimate_normals(scene, config)
        with clock.stage("filter"):
            select_keypoints(scene, config, rng, stats)
    except EmptyScene as reason:
        stats["reason"] = str(reason)
        return RecognitionResult([], clock.result(), stats)
    search = _Search(scene, config, rng, clock)
    stats["templates"] = [search.find(tpl) for tpl in templates]
    if len(places_T_world_target):
        stats["laid"] = [search.confirm(tpl, places_T_world_target) for tpl in templates]
    if config.matcher.cue_places and scene.upright:
        with clock.stage("cue"):
            places = _unexplained_places(search, templates)
            stats["cued_places"] = len(places)
            for entry, tpl in zip(stats["templates"], templates, strict=True):
                entry["cued_accepted"] = search.cue(tpl, places)
    return _compete(search, config, clock, stats)


def warm_up(config: RecognitionConfig) -> None:
    """Load the compiled kernels of the scene's normals and description and start their thread pools,
    on a small synthetic cloud. A process pays for it once, in its first scene otherwise: the matcher
    service's first whole search took 0.73 s cold (normals 247 ms, describe 140 ms), 0.41 s warmed up.
    """
    rng = np.random.default_rng(0)
    points_m = rng.uniform(-10.0, 10.0, (4000, 3)) * np.array([1.0, 1.0, 0.1])
    normals = _backend.estimate_normals(points_m, config.template.normal_k, None)
    _backend.describe(
        config.descriptor,
        points_m,
        normals,
        np.arange(0, len(points_m), 40),
        config.support_radius_m,
    )


def _unexplained_places(search: _Search, templates: Sequence[Template]) -> list[Blob]:
    """The scene's vehicle-sized blobs with no accepted hypothesis of any template on them."""
    scene, config = search.scene, search.config
    places = vehicle_places(
        scene.surface.points_m,
        scene.height,
        scene.band,
        attention_sizes(templates, config),
        config.matcher.min_overlap_vertices,
    )
    centres_xy = np.array([c.centre_m[:2] for _, c in search.candidates]).reshape(-1, 2)
    return [
        p
        for p in places
        if not len(centres_xy)
        or np.min(np.linalg.norm(centres_xy - p.centre_m[:2], axis=1)) > config.nms_m
    ]


def verify_places(
    scene_points_m: np.ndarray,
    templates: Sequence[Template],
    config: RecognitionConfig,
    places_T_world_target: Sequence[np.ndarray],
    *,
    seed: int,
    viewpoint_m: np.ndarray | None = None,
    scene_sigma_m: np.ndarray | None = None,
    targets_per_place: Sequence[Collection[str]] | None = None,
) -> RecognitionResult:
    """Confirm targets where they are expected (ours: the track-guided scenes of
    ``atr.tracking.guided_search``): the templates are laid at each place's pose and refined by ICP,
    with no description, matching, grouping or RANSAC; acceptance and the place competition are
    ``recognize``'s, so a place goes to the template that explains it best, as there.

    Args:
        scene_points_m, templates, config, seed, viewpoint_m, scene_sigma_m: as ``recognize``.
        places_T_world_target: (4, 4) world-from-target poses to try (e.g. the tracks' fused poses).
        targets_per_place: per place, the targets whose templates are laid there (the classes the
            place has been given to); None: every template at every place.

    Returns:
        RecognitionResult with the same stages as ``recognize`` (describe, match, group and ransac 0).

    Raises:
        As ``recognize``; InputError: ``targets_per_place`` does not hold one set per place.

    """
    if targets_per_place is not None and len(targets_per_place) != len(places_T_world_target):
        raise InputError(
            f"{len(targets_per_place)} target sets for {len(places_T_world_target)} places"
        )
    clock = _Clock()
    stats: dict[str, Any] = {}
    pts, sigma = validated_cloud(scene_points_m, scene_sigma_m, config)
    check_resolutions(templates, config)
    rng = np.random.default_rng(seed)
    try:
        scene = _grounded_scene(pts, sigma, viewpoint_m, templates, config, clock, stats)
    except EmptyScene as reason:
        stats["reason"] = str(reason)
        return RecognitionResult([], clock.result(), stats)
    search = _Search(scene, config, rng, clock)
    stats["templates"] = [
        search.confirm(
            tpl,
            [
                T
                for k, T in enumerate(places_T_world_target)
                if targets_per_place is None or tpl.target in targets_per_place[k]
            ],
        )
        for tpl in templates
    ]
    return _compete(search, config, clock, stats)


def _grounded_scene(
    pts: np.ndarray,
    sigma: np.ndarray | None,
    viewpoint_m: np.ndarray | None,
    templates: Sequence[Template],
    config: RecognitionConfig,
    clock: _Clock,
    stats: dict[str, Any],
) -> Scene:
    """The scene subsampled and, for ground vehicles, without its ground; EmptyScene when too little
    is left or there is no template.
    """
    with clock.stage("subsample"):
        scene = subsampled_scene(pts, sigma, viewpoint_m, config, stats)
    if not templates:
        raise EmptyScene("no templates given")
    with clock.stage("ground"):
        return remove_ground(scene, templates, config, stats)


def _compete(
    search: _Search, config: RecognitionConfig, clock: _Clock, stats: dict[str, Any]
) -> RecognitionResult:
    """The place competition across the verified candidates of every template; the detections."""
    stats["verified"] = search.verified
    with clock.stage("compete"):
        winners = compete_for_places(
            [candidate for _, candidate in search.candidates],
            search.scene.surface,
            CompetitionSettings(
                nms_m=config.nms_m,
                overlap_m=config.overlap_m,
                ground_slab_m=config.ground_slab_m,
            ),
        )
    detections = sorted(
        (replace(search.candidates[i][0], score=score) for i, score in winners),
        key=lambda d: -d.score,
    )
    stats["detections"] = len(detections)
    return RecognitionResult(detections, clock.result(), stats)


class _Search:
    """The per-template steps on one described scene; collects candidates and the verified log."""

    def __init__(
        self, scene: Scene, config: RecognitionConfig, rng: np.random.Generator, clock: _Clock
    ) -> None:
        self.scene, self.config, self.rng, self.clock = scene, config, rng, clock
        self.ground = GroundCheck(scene, config)
        self.described: dict[tuple[str, float], np.ndarray] = {}
        self.candidates: list[tuple[Detection, Candidate]] = []
        self.verified: list[tuple] = []

    def find(self, tpl: Template) -> dict[str, Any]:
        """Describe, match, group, hypothesise and verify one template; its counts per stage."""
        with self.clock.stage("describe"):
            scene_desc = self._describe(tpl)
        with self.clock.stage("match"):
            views = template_views(tpl, self.scene, self.config.matcher.ring_reach_deg)
            matches = _match_views(
                scene_desc,
                tpl.descriptors,
                views.slices,
                views.elevations_deg,
                views.keypoints_of_ring,
                self.config,
            )
        model_kp = np.asarray(tpl.keypoints_m, np.float64)
        with self.clock.stage("group"):
            groups = [
                self._group(views, vi, model_kp[ksl], corr)
                for vi, ((_, ksl), corr) in enumerate(zip(views.slices, matches, strict=True))
            ]
        with self.clock.stage("ransac"):
            hyps, n_ransac = self._hypotheses(views, model_kp, matches, groups)
        with self.clock.stage("icp"):
            accepted = self._verify(tpl, views, hyps, skip_fitted=True)
        return {
            "target": tpl.target,
            "descriptor": tpl.descriptor,
            "views": len(views.slices),
            "correspondences": int(sum(len(c) for c in matches)),
            "groups": int(sum(len(g) for g in groups)),
            "hypotheses": n_ransac,
            "distinct_hypotheses": len(hyps),
            "accepted": accepted,
        }

    def confirm(self, tpl: Template, places_T_world_target: Sequence[np.ndarray]) -> dict[str, Any]:
        """Verify one template at given poses, each with the view the camera sees it from."""
        views = TemplateViews(tpl.view_slices(), None, [], {})
        hyps = [
            (_facing_view(tpl, T, self.scene.viewpoint_m), Hypothesis(np.asarray(T, float), 0, 0))
            for T in places_T_world_target
        ]
        with self.clock.stage("icp"):
            accepted = self._verify(tpl, views, hyps)
        return {"target": tpl.target, "hypotheses": len(hyps), "accepted": accepted}

    def cue(self, tpl: Template, places: Sequence[Blob]) -> int:
        """Verify one template laid on each cued place at ``cue_headings`` headings: the view the
        camera sees at that heading, its centroid on the blob's; the number accepted.
        """
        if not places:
            return 0
        model_all = np.asarray(tpl.points_m, np.float64)
        slices = tpl.view_slices()
        views = TemplateViews(slices, None, [], {})
        centroid_m = model_all.mean(axis=0)
        view_centroids_m = [model_all[points].mean(axis=0) for points, _ in slices]
        n = self.config.matcher.cue_headings
        hyps, segments = [], []
        for place in places:
            for turn in range(n):
                yaw = place.axis_yaw_rad + 2.0 * np.pi * turn / n
                T = np.eye(4)
                T[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
                T[:3, 3] = place.centre_m - T[:3, :3] @ centroid_m
                vi = _facing_view(tpl, T, self.scene.viewpoint_m)
                T[:3, 3] = place.centre_m - T[:3, :3] @ view_centroids_m[vi]
                hyps.append((vi, Hypothesis(T, 0, 0)))
                segments.append(place.idx)
        return self._verify(tpl, views, hyps, segments)

    def _describe(self, tpl: Template) -> np.ndarray:
        key = (tpl.descriptor, float(tpl.radius_m))
        if key not in self.described:
            s = self.scene
            self.described[key] = _backend.describe(
                tpl.descriptor, s.surface.points_m, s.normals, s.kp_idx, tpl.radius_m
            )
        return self.described[key]

    def _group(
        self, views: TemplateViews, vi: int, model_kp: np.ndarray, corr: Correspondences
    ) -> list[np.ndarray]:
        c, m, s = self.config, self.config.matcher, self.scene
        if not s.upright:
            return steps.group_geometrically_consistent(
                s.keypoints, model_kp, corr, c.consensus_m, m.min_group_size, m.max_groups
            )
        res_m = c.template.resolution_m
        settings = steps.HoughSettings(
            cell_m=m.k_hough_cell * res_m,
            yaw_bin_rad=np.radians(m.hough_yaw_bin_deg),
            height_tol_m=c.ground.k_height_tol * res_m,
            min_size=m.min_group_size,
            max_groups=m.max_groups,
        )
        window = heading_window(s, views, vi, corr, m.view_yaw_margin_deg)
        return steps.group_upright_hough(
            s.keypoints, s.height[s.kp_idx], model_kp, corr, settings, window
        )

    def _hypotheses(
        self,
        views: TemplateViews,
        model_kp: np.ndarray,
        matches: list[Correspondences],
        groups: list[list[np.ndarray]],
    ) -> tuple[list[tuple[int, Hypothesis]], int]:
        """RANSAC on the largest groups over all views (stable: view order breaks ties), then one
        of each set of repeated hypotheses; also the count before repeats were dropped.
        """
        c, m = self.config, self.config.matcher
        ranked = sorted(
            ((vi, g) for vi, view_groups in enumerate(groups) for g in view_groups),
            key=lambda vg: -len(vg[1]),
        )[: m.max_groups]
        settings = steps.RansacSettings(
            m.ransac_iterations, c.ransac_inlier_m, upright=self.scene.upright
        )
        hyps: list[tuple[int, Hypothesis]] = []
        for vi, g in ranked:
            h = steps.ransac_per_group(
                self.scene.keypoints,
                model_kp[views.slices[vi][1]],
                matches[vi],
                g,
                settings,
                self.rng,
            )
            if h is not None and h.inliers >= m.min_group_size:
                hyps.append((vi, h))
        distinct = steps.drop_repeated_hypotheses(
            hyps, c.same_hypothesis_m, np.radians(m.same_hypothesis_deg)
        )
        return distinct, len(hyps)

    def _verify(
        self,
        tpl: Template,
        views: TemplateViews,
        hyps: list[tuple[int, Hypothesis]],
        segments: Sequence[np.ndarray] | None = None,
        skip_fitted: bool = False,
    ) -> int:
        """ICP verification and acceptance (§II-B-2 overlap, our clutter and ground rules); a
        hypothesis cued on a blob (``segments``: its vertices) must also explain the blob. With
        ``skip_fitted``, a hypothesis where the template already has ``max_fits_per_place`` fits is
        not verified.
        """
        if not hyps:
            return 0
        c, m = self.config, self.config.matcher
        settings = steps.VerifySettings(
            icp_gate_m=c.icp_gate_m,
            overlap_m=c.overlap_m,
            icp_iterations=m.icp_iterations,
            ground_slab_m=c.ground_slab_m,
            k_clutter_sigma=m.k_clutter_sigma,
            icp_reach_m=c.icp_reach_m,
            point_to_plane=m.icp_point_to_plane,
            plane_max_sigma_m=c.plane_max_sigma_m,
            plane_min_spread=m.plane_min_normal_spread,
        )
        model_all = np.asarray(tpl.points_m, np.float64)
        model = steps.PointSet(model_all)  # the whole model: what explains the scene at a place
        box_lo_m, box_hi_m = model_all.min(axis=0), model_all.max(axis=0)
        centroid_m = model_all.mean(axis=0)
        extent = model_extent_m(tpl)
        view_models: dict[int, steps.PointSet] = {}
        accepted = 0
        for n, (vi, h) in enumerate(hyps):
            if skip_fitted and self._place_is_fitted(
                tpl.target, h.T_scene_model[:3, :3] @ centroid_m + h.T_scene_model[:3, 3]
            ):
                continue
            if vi not in view_models:
                view_models[vi] = steps.PointSet(model_all[views.slices[vi][0]])
            v = steps.verify_with_icp(
                view_models[vi], self.scene.surface, h.T_scene_model, settings
            )
            self.verified.append(
                (
                    tpl.target,
                    vi,
                    round(v.overlap, 3),
                    v.overlap_vertices,
                    round(v.clutter, 3),
                    *(round(float(x), 2) for x in v.T_scene_model[:3, 3]),
                )
            )
            # the ground rule last: most hypotheses fail the fit, and the terrain costs more to look up
            if (
                _acceptable(v, m)
                and (segments is None or self._cued_fit(model, v.T_scene_model, segments[n]))
                and self.ground.stands(v.T_scene_model)
            ):
                accepted += 1
                T_world_target = self.ground.placed(v.T_scene_model)
                det = Detection(
                    target=tpl.target,
                    descriptor=tpl.descriptor,
                    T_world_target=T_world_target,
                    score=0.0,  # the place competition's score, once every template is verified
                    overlap=float(v.overlap),
                    inliers=int(h.inliers),
                )
                centre_m = v.T_scene_model[:3, :3] @ centroid_m + v.T_scene_model[:3, 3]
                candidate = Candidate(
                    target=tpl.target,
                    model=model,
                    box_lo_m=box_lo_m,
                    box_hi_m=box_hi_m,
                    T_scene_model=v.T_scene_model,
                    centre_m=centre_m,
                    extent_m=extent,
                    support=float(v.overlap),
                    strength=float(v.overlap_vertices * (1.0 - v.clutter)),
                )
                self.candidates.append((det, candidate))
        return accepted

    def _place_is_fitted(self, target: str, centre_m: np.ndarray) -> bool:
        """Whether ``max_fits_per_place`` accepted fits of this target already stand within ``nms_m``
        of a hypothesis's centre: the competition takes one template's strongest fit per place, and
        the hypotheses verified first come from the largest groups.
        """
        most = self.config.matcher.max_fits_per_place
        if most <= 0:
            return False
        near = sum(
            1
            for _, c in self.candidates
            if c.target == target
            and np.linalg.norm(c.centre_m[:2] - centre_m[:2]) < self.config.nms_m
        )
        return near >= most

    def _cued_fit(self, model: steps.PointSet, T_scene_model: np.ndarray, idx: np.ndarray) -> bool:
        """Whether a hypothesis cued on a blob stands upright (``cue_max_tilt_deg``) and explains at
        least 1 - ``max_clutter`` of the blob's vertices, each within the clutter measure's reach: a
        small template laid on a part of a larger vehicle leaves the rest of its blob unexplained,
        though its own box holds little else.
        """
        c = self.config
        if T_scene_model[2, 2] < np.cos(np.radians(c.matcher.cue_max_tilt_deg)):
            return False
        surface = self.scene.surface
        R, t = T_scene_model[:3, :3], T_scene_model[:3, 3]
        local = (surface.points_m[idx] - t) @ R  # R^T (p - t): into the model frame
        reach_m = np.full(len(idx), c.overlap_m)
        if surface.sigma_m is not None:
            reach_m = np.maximum(reach_m, c.matcher.k_clutter_sigma * surface.sigma_m[idx])
        d, _ = model.tree.query(local, distance_upper_bound=float(reach_m.max()))
        return bool(np.mean(d <= reach_m) >= 1.0 - c.matcher.max_clutter)


def _facing_view(tpl: Template, T_world_target: np.ndarray, viewpoint_m: np.ndarray | None) -> int:
    """The template view nearest the direction the camera sees a target at this pose from (view 0
    when the template or the scene does not say).
    """
    azimuths = tpl.params.get("view_azimuths_deg")
    elevations = tpl.params.get("view_elevations_deg")
    if viewpoint_m is None or not azimuths or not elevations:
        return 0
    T = np.asarray(T_world_target, np.float64)
    to_camera = T[:3, :3].T @ (np.asarray(viewpoint_m, np.float64) - T[:3, 3])  # target frame
    azimuth = np.arctan2(to_camera[1], to_camera[0])
    elevation = np.arctan2(to_camera[2], np.hypot(to_camera[0], to_camera[1]))
    d_az = np.angle(np.exp(1j * (azimuth - np.radians(np.asarray(azimuths, np.float64)))))
    d_el = elevation - np.radians(np.asarray(elevations, np.float64))
    return int(np.argmin(d_az**2 + d_el**2))


def _acceptable(v: steps.Verification, m: MatcherConfig) -> bool:
    """The paper's overlap test (§II-B-2) and our clutter bound."""
    return (
        v.overlap >= m.min_overlap
        and v.overlap_vertices >= m.min_overlap_vertices
        and v.clutter <= m.max_clutter
    )


def _match_views(
    scene_desc: np.ndarray,
    model_desc: np.ndarray,
    views: list[tuple[slice, slice]],
    view_el: Sequence[float],
    keypoints_of_ring: dict[float, np.ndarray],
    config: RecognitionConfig,
) -> list[Correspondences]:
    """KNNDR of each scene keypoint against the views of its elevation rings.

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
    for ring, rows in keypoints_of_ring.items():
        in_ring = np.flatnonzero(view_el_arr == ring)
        if len(rows) == 0 or len(in_ring) == 0:
            continue
        cols = np.concatenate([np.arange(views[v][1].start, views[v][1].stop) for v in in_ring])
        owner = np.concatenate([np.full(views[v][1].stop - views[v][1].start, v) for v in in_ring])
        d2 = steps.descriptor_sq_distances(take(scene_desc, rows), take(model_desc, cols))
        if config.knn_across_views:
            c = steps.knndr_from_distances(d2, config.knndr_k, config.knndr_ratio)
            for v in in_ring:
                sel = np.flatnonzero(owner[c.model] == v)
                out[v] = Correspondences(
                    rows[c.scene[sel]], cols[c.model[sel]] - views[v][1].start, c.distance[sel]
                )
        else:
            start = 0
            for v in in_ring:
                n = views[v][1].stop - views[v][1].start
                c = steps.knndr_from_distances(
                    d2[:, start : start + n],
                    config.knndr_k,
                    config.knndr_ratio,
                    config.max_correspondences,
                )
                out[v] = Correspondences(rows[c.scene], c.model, c.distance)
                start += n
    return out
