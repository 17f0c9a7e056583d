"""Our steps of the online phase around the paper's (docs/recognition.md): the scene as the steps see it,
ground removal, keypoint selection, the template views a keypoint meets, the heading window and where a
ground vehicle may stand. ``recognize`` in ``atr.recognition.matcher`` chains them with ``steps``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from atr.errors import ConfigError, InputError
from atr.recognition import _backend
from atr.recognition.attention import AttentionSizes, largest_footprint_m, vehicle_blobs
from atr.recognition.config import RecognitionConfig
from atr.recognition.ground import height_above_ground, lowest_per_cell, terrain_height_at
from atr.recognition.steps import (
    Correspondences,
    PointSet,
    YawWindow,
    filter_smooth_surfaces,
    uniform_subsample,
)
from atr.recognition.template import Template


class EmptyScene(Exception):  # noqa: N818 - a reason to stop, not a failure
    """The scene holds too little to recognise anything; the message says why."""


@dataclass
class Scene:
    """A scene cloud as the steps see it, filled in step by step.

    Attributes:
        surface: the described surface: subsampled vertices (above the ground for ground vehicles).
        viewpoint_m: (3,) camera position, metres, or None.
        height: (S,) height of each surface vertex above the ground, metres; None without the prior.
        band: (S,) bool, vertices within the height band a target occupies; None without the prior.
        terrain: cell centres and lowest z of the subsampled scene (``lowest_per_cell``), or None.
        kp_idx: (K,) indices of the keypoints into the surface.
        ground: (G, 3) the subsampled vertices taken for the ground (not described); None without the
            prior.

    """

    surface: PointSet
    viewpoint_m: np.ndarray | None
    height: np.ndarray | None = None
    band: np.ndarray | None = None
    terrain: tuple[np.ndarray, np.ndarray] | None = None
    kp_idx: np.ndarray | None = None
    ground: np.ndarray | None = None

    @property
    def normals(self) -> np.ndarray | None:
        """(S, 3) unit normals of the surface (``estimate_normals``), or None before."""
        return self.surface.normals

    @property
    def keypoints(self) -> np.ndarray:
        """(K, 3) keypoint positions, metres."""
        return self.surface.points_m[self.kp_idx]

    @property
    def upright(self) -> bool:
        """Whether the ground-vehicle prior applies (the targets stand upright on the ground)."""
        return self.band is not None


def validated_cloud(
    scene_points_m: np.ndarray, scene_sigma_m: np.ndarray | None, config: RecognitionConfig
) -> tuple[np.ndarray, np.ndarray | None]:
    """The scene as float64 (N, 3) and its sigma as (N,); raise InputError on anything else."""
    pts = np.asarray(scene_points_m)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError(f"scene points must be an (N, 3) array; got shape {pts.shape}")
    if not np.issubdtype(pts.dtype, np.number):
        raise InputError(f"scene points must be numeric; got dtype {pts.dtype}")
    if len(pts) > config.matcher.max_scene_points:
        raise InputError(
            f"scene has {len(pts)} points; at most max_scene_points = "
            f"{config.matcher.max_scene_points}"
        )
    pts = pts.astype(np.float64, copy=False)
    if scene_sigma_m is None:
        return pts, None
    sigma = np.asarray(scene_sigma_m, np.float64)
    if sigma.shape != (len(pts),):
        raise InputError(
            f"scene_sigma_m must have shape ({len(pts)},) like the scene; got {sigma.shape}"
        )
    return pts, sigma


def check_resolutions(templates: Sequence[Template], config: RecognitionConfig) -> None:
    """Raise ConfigError when a template was built at another resolution than the matcher runs at."""
    resolution_m = config.template.resolution_m
    for tpl in templates:
        res = tpl.params.get("resolution_m", resolution_m)
        if abs(float(res) - resolution_m) > 1e-9 * max(1.0, resolution_m):
            raise ConfigError(
                f"template {tpl.target}/{tpl.descriptor} was built at resolution {res} m; "
                f"the matcher runs at {resolution_m} m"
            )


def subsampled_scene(
    pts: np.ndarray,
    sigma: np.ndarray | None,
    viewpoint_m: np.ndarray | None,
    config: RecognitionConfig,
    stats: dict,
) -> Scene:
    """Finite points, uniformly subsampled (§II-B-2); raise EmptyScene when too few remain."""
    finite = np.isfinite(pts).all(axis=1)
    if sigma is not None:
        finite &= np.isfinite(sigma)
    stats["scene_points"] = int(len(pts))
    stats["dropped_nonfinite"] = int(len(pts) - finite.sum())
    pts = pts[finite]
    if len(pts) == 0:
        raise EmptyScene("scene has no finite points")
    chosen = uniform_subsample(pts, config.template.resolution_m)
    if sigma is not None:
        sigma = sigma[finite][chosen]
    stats["subsampled_points"] = int(len(chosen))
    if len(chosen) < config.template.normal_k + 1:
        raise EmptyScene(
            f"scene has {len(chosen)} vertices after {config.template.resolution_m} m subsampling; "
            f"at least {config.template.normal_k + 1} are needed"
        )
    return Scene(PointSet(pts[chosen], sigma), viewpoint_m)


def remove_ground(
    scene: Scene, templates: Sequence[Template], config: RecognitionConfig, stats: dict
) -> Scene:
    """Ground vehicles: drop the ground from the description surface and mark the height band a target
    occupies (docs/recognition.md, "Ground"). Applies when every template says it stands on the ground.
    """
    if not (config.template.ground_vehicles and all(t.params.get("on_ground") for t in templates)):
        return scene
    g, res_m = config.ground, config.template.resolution_m
    surface = scene.surface.points_m
    height = height_above_ground(
        surface, g.k_ground_cell * res_m, g.k_ground_window * res_m, g.ground_percentile
    )
    terrain = lowest_per_cell(surface, g.k_ground_cell * res_m)
    top = max(float(np.asarray(tpl.points_m)[:, 2].max()) for tpl in templates)
    above = height >= config.ground_cut_m
    sigma = None if scene.surface.sigma_m is None else scene.surface.sigma_m[above]
    height = height[above]
    band = (height >= g.k_keypoint_min_height * res_m) & (height <= top + config.ground_cut_m)
    stats["above_ground_points"] = int(above.sum())
    if above.sum() < config.template.normal_k + 1:
        raise EmptyScene(f"only {int(above.sum())} scene vertices stand above the ground")
    if g.attention:
        stats["band_points"] = int(band.sum())
        band = vehicle_blobs(surface[above], height, band, attention_sizes(templates, config))
        stats["attended_points"] = int(band.sum())
    return Scene(
        PointSet(surface[above], sigma),
        scene.viewpoint_m,
        height,
        band,
        terrain,
        ground=surface[~above],
    )


def attention_sizes(templates: Sequence[Template], config: RecognitionConfig) -> AttentionSizes:
    """What a vehicle can look like from above (``atr.recognition.attention``), from the templates."""
    g = config.ground
    cell_m = g.k_attention_cell * config.template.resolution_m
    top = max(float(np.asarray(tpl.points_m)[:, 2].max()) for tpl in templates)
    return AttentionSizes(
        cell_m=cell_m,
        top_m=top + config.ground_cut_m + cell_m,  # a cell of slack for depth noise on a roof
        footprint_m=g.k_attention_footprint
        * max(largest_footprint_m(tpl.points_m) for tpl in templates),
    )


def estimate_normals(scene: Scene, config: RecognitionConfig) -> None:
    """Normals of the surface: a plane fit on ``normal_k`` neighbours, facing the camera (§II-B-2)."""
    scene.surface.normals = _backend.estimate_normals(
        scene.surface.points_m, config.template.normal_k, scene.viewpoint_m
    )


def select_keypoints(
    scene: Scene, config: RecognitionConfig, rng: np.random.Generator, stats: dict
) -> None:
    """Keypoints: vertices off smooth surfaces (§II-B-2) within the height band, evenly thinned to
    ``max_scene_keypoints``; raise EmptyScene when fewer than a group remain.
    """
    m = config.matcher
    keep = filter_smooth_surfaces(
        scene.surface.points_m, scene.normals, config.template.normal_k, m.smooth_angle_rad
    )
    if scene.band is not None:
        keep &= scene.band
    kp_idx = np.flatnonzero(keep)
    if len(kp_idx) > m.max_scene_keypoints:
        kp_idx = np.sort(rng.choice(kp_idx, size=m.max_scene_keypoints, replace=False))
    stats["keypoints"] = int(len(kp_idx))
    scene.kp_idx = kp_idx
    if len(kp_idx) < m.min_group_size:
        raise EmptyScene(f"only {len(kp_idx)} scene vertices survive the smooth-surface filter")


@dataclass(frozen=True)
class TemplateViews:
    """The views of a template and the elevation ring each scene keypoint is matched in.

    Attributes:
        slices: (points slice, keypoints slice) of each view (``Template.view_slices``).
        azimuths_deg: azimuth of each view, degrees; None when unknown or unused.
        elevations_deg: elevation ring of each view, degrees (all 0 when unused).
        keypoints_of_ring: for each ring (degrees), the scene keypoints matched against its views.

    """

    slices: list[tuple[slice, slice]]
    azimuths_deg: Sequence[float] | None
    elevations_deg: Sequence[float]
    keypoints_of_ring: dict[float, np.ndarray]


def template_views(tpl: Template, scene: Scene, ring_reach_deg: float = 0.0) -> TemplateViews:
    """Each scene keypoint meets the views of the elevation ring nearest the camera's elevation seen
    from it (the camera position is known), and of every other ring within ``ring_reach_deg`` of that
    elevation; without a camera or views, every view.
    """
    views = tpl.view_slices()
    view_az = tpl.params.get("view_azimuths_deg")
    view_el = tpl.params.get("view_elevations_deg")
    every = np.arange(len(scene.kp_idx))
    if not (
        scene.viewpoint_m is not None
        and scene.upright
        and view_az is not None
        and view_el is not None
        and len(view_az) == len(views) == len(view_el)
    ):
        return TemplateViews(views, None, [0.0] * len(views), {0.0: every})
    keypoints = scene.keypoints
    rings = np.unique(np.asarray(view_el, np.float64))
    rel = np.asarray(scene.viewpoint_m, np.float64) - keypoints
    cam_el = np.degrees(np.arctan2(rel[:, 2], np.linalg.norm(rel[:, :2], axis=1)))
    off_deg = np.abs(cam_el[:, None] - rings[None, :])
    meets = off_deg <= ring_reach_deg
    meets[every, np.argmin(off_deg, axis=1)] = True
    keypoints_of_ring = {float(r): np.flatnonzero(meets[:, i]) for i, r in enumerate(rings)}
    return TemplateViews(views, view_az, view_el, keypoints_of_ring)


def heading_window(
    scene: Scene, views: TemplateViews, view: int, corr: Correspondences, margin_deg: float
) -> YawWindow | None:
    """The headings a correspondence of ``view`` may vote for: the camera sees the target from the
    view's azimuth, so heading = direction to the camera minus that azimuth, within half the view
    spacing and a margin. None (every heading) when the views' azimuths are unknown.
    """
    if views.azimuths_deg is None:
        return None
    to_cam = np.asarray(scene.viewpoint_m, np.float64)[:2] - scene.keypoints[corr.scene, :2]
    centre = np.arctan2(to_cam[:, 1], to_cam[:, 0]) - np.radians(views.azimuths_deg[view])
    half = np.pi / len(set(views.azimuths_deg)) + np.radians(margin_deg)
    return YawWindow(centre, half)


_PLACE_ITERATIONS = 10  # at most; the band's median settles within a few
_PLACE_SETTLED = 0.01  # of the band: a step smaller than this ends the iteration


class GroundCheck:
    """Where a ground vehicle may stand: on the scene's ground, and that ground not a roof."""

    def __init__(self, scene: Scene, config: RecognitionConfig) -> None:
        """Index the scene's ground (only with the ground-vehicle prior; otherwise anything passes)."""
        self.config = config
        self.terrain = scene.terrain
        self.ground_xy: cKDTree | None = None
        self.ground_points: cKDTree | None = None
        if scene.upright:
            surface = scene.surface.points_m
            self.ground_xy = cKDTree(surface[:, :2])
            self.ground_z = surface[:, 2] - scene.height
            self.surface_z = surface[:, 2]
            if scene.ground is not None and len(scene.ground):
                self.ground_points = cKDTree(scene.ground[:, :2])
                self.ground_points_z = scene.ground[:, 2]

    def placed(self, T_scene_model: np.ndarray) -> np.ndarray:
        """The pose with its height set to the height of the ground around it (a ground vehicle's
        origin lies on the ground under it); unchanged without enough ground in reach.

        The ground points are the vertices less than ``ground_cut_m`` above a low percentile of the
        lowest points: in a noisy cloud that cut keeps the ground's lower half and drops its upper
        tail, so their median stands low. From that median the height moves to the median of every
        vertex within ``place_band_m`` of it, ground or not, until it settles: a band symmetric
        about the estimate has no such cut, and most of a vehicle's body stands higher, out of it.
        """
        if self.ground_points is None:
            return T_scene_model
        xy, c = T_scene_model[:2, 3], self.config
        near = self.ground_points.query_ball_point(xy, c.place_radius_m)
        if len(near) < c.ground.min_place_points:
            return T_scene_model
        heights = self.ground_points_z[near]
        z = float(np.median(heights))
        band_m = c.place_band_m
        if band_m > 0:
            above = self.surface_z[self.ground_xy.query_ball_point(xy, c.place_radius_m)]
            heights = np.concatenate([heights, above])
            for _ in range(_PLACE_ITERATIONS):
                inside = heights[np.abs(heights - z) <= band_m]
                z_next = float(np.median(inside)) if len(inside) else z
                settled = abs(z_next - z) <= _PLACE_SETTLED * band_m
                z = z_next
                if settled:
                    break
        T = T_scene_model.copy()
        T[2, 3] = z
        return T

    def stands(self, T_scene_model: np.ndarray) -> bool:
        """Whether a target at this pose stands on the ground and at most ``k_terrain_step`` above
        the terrain around it (docs/recognition.md, "Roofs").
        """
        if self.ground_xy is None:
            return True
        c, xy = self.config, T_scene_model[:2, 3]
        # a ground vehicle's origin (on the ground under it) must lie on the scene's ground
        _, nb = self.ground_xy.query(xy, k=min(10, len(self.ground_z)))
        z_ground = float(np.median(self.ground_z[np.atleast_1d(nb)]))
        if abs(T_scene_model[2, 3] - z_ground) > c.ground.k_height_tol * c.template.resolution_m:
            return False
        if self.terrain is None:
            return True
        z_terrain = terrain_height_at(
            *self.terrain, xy, c.terrain_window_m, c.ground.ground_percentile
        )[0]
        return bool(np.isnan(z_terrain) or T_scene_model[2, 3] - z_terrain <= c.terrain_step_m)
