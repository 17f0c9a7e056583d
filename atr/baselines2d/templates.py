"""2D templates of the target (paper §III-D): 12 crops of the template run, one per 30° of azimuth.

The template run is scenario 1 run 3 by default, the 30° obliquity run ("templates are derived from 30°
obliquity", §III-D-1); run 1 (0°, the paper's "first trial") is the sensitivity option
(`Baseline2dConfig.template_run`).

For each azimuth step the frame of the run whose viewing azimuth (the camera's bearing in the target's own
frame) is nearest is rendered, and the target's projected bounding box (plus a margin) is cropped. Only the
frames needed are rendered: the run's camera poses come from its orbit exactly as `simulate_flight` computes them.
A template also keeps where the target's origin (the ground point under its centre, what T_error is measured
on) projects inside the crop; the detector maps that point into the scene.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from atr.baselines2d.config import Baseline2dConfig
from atr.baselines2d.features import Features2d, detect_and_describe
from atr.errors import InputError
from atr.sim.config import SimConfig
from atr.sim.flight import true_imu_pose
from atr.sim.mesh import Mesh
from atr.sim.render import Renderer, to_srgb8
from atr.sim.scenarios import scenario as scenario_preset
from atr.sim.world import World, build_world


@dataclass(frozen=True)
class TemplateView:
    """One cropped view of the target.

    Attributes:
        target: target name.
        azimuth_deg: the template's azimuth step, degrees (0, 30, ...).
        frame_azimuth_deg: viewing azimuth of the frame it was cropped from, degrees.
        frame: frame index in the template run.
        image: (h, w, 3) uint8 RGB crop.
        reference_px: (2,) float64 the target origin's projection in crop pixels.
        scale: size of the view relative to the frame it was cropped from (1: as rendered; 0.5: as the
            target would look from twice the range).
        keep_box_px: (4,) float64 x0, y0, x1, y1 of the target's box in crop pixels when the crop holds
            context around it (a scaled view), whose keypoints are dropped; None: keep every keypoint.

    """

    target: str
    azimuth_deg: float
    frame_azimuth_deg: float
    frame: int
    image: np.ndarray
    reference_px: np.ndarray
    scale: float = 1.0
    keep_box_px: np.ndarray | None = None


@dataclass(frozen=True)
class Template2d:
    """A template view described with one Table IV combination."""

    view: TemplateView
    features: Features2d


def viewing_azimuth_deg(T_world_target: np.ndarray, camera_position_m: np.ndarray) -> float:
    """Bearing of the camera in the target's frame, degrees in [0, 360) (0: ahead, counter-clockwise)."""
    d = T_world_target[:3, :3].T @ (
        np.asarray(camera_position_m, np.float64) - T_world_target[:3, 3]
    )
    return float(np.degrees(np.arctan2(d[1], d[0])) % 360.0)


def project(points_world_m: np.ndarray, K: np.ndarray, T_world_cam: np.ndarray) -> np.ndarray:
    """(N, 2) pixel positions of world points (N, 3); NaN behind the camera."""
    T_cam_world = np.linalg.inv(T_world_cam)
    p = points_world_m @ T_cam_world[:3, :3].T + T_cam_world[:3, 3]
    uv = p @ np.asarray(K).T
    with np.errstate(divide="ignore", invalid="ignore"):
        out = uv[:, :2] / uv[:, 2:3]
    out[p[:, 2] <= 0] = np.nan
    return out


def _frame_pose(world: World, cfg: SimConfig, t_s: float) -> np.ndarray:
    T_world_imu, _ = true_imu_pose(world.orbit, t_s)
    return T_world_imu @ cfg.T_imu_cam_matrix


def crop_template_views(
    seed: int,
    sim_config: SimConfig,
    config: Baseline2dConfig,
    *,
    target_mesh: Mesh | None = None,
    target_name: str | None = None,
    clutter_meshes: tuple[Mesh | tuple[str, Mesh], ...] = (),
) -> list[TemplateView]:
    """Render and crop the template views from the template run (scenario 1 run 3 by default).

    Args:
        seed: world seed (the templates come from the evaluated world, as in the paper).
        sim_config: simulator settings (camera).
        config: number of templates, crop margin, visibility floor.
        target_mesh: mesh replacing the T-72, as for `simulate_flight`.
        target_name: name of that target.
        clutter_meshes: extra confuser meshes (or (name, mesh) pairs), as for `build_world`.

    Returns:
        Up to `n_templates` views per scale of `config.template_scales`, in azimuth order (the scales of
        one azimuth together); a step with no frame seeing the target well is skipped.

    Raises:
        InputError: no frame of the run sees the target.

    """
    sc = scenario_preset(config.template_scenario, config.template_run)
    world = build_world(
        sc,
        seed,
        target_mesh=target_mesh,
        target_name=target_name,
        clutter_meshes=clutter_meshes,
        config=sim_config,
    )
    renderer = Renderer(world, sim_config)
    interval = sim_config.frame_interval_s(sc.range_m)
    poses = [_frame_pose(world, sim_config, k * interval) for k in range(sc.n_frames)]
    azimuths = np.array([viewing_azimuth_deg(world.T_world_target, T[:3, 3]) for T in poses])
    K = sim_config.K
    views: list[TemplateView] = []
    for step in range(config.n_templates):
        wanted = step * config.azimuth_step_deg
        gap = np.abs((azimuths - wanted + 180.0) % 360.0 - 180.0)
        for k in np.argsort(gap, kind="stable")[:3]:  # nearest frame first; skip occluded ones
            if gap[k] > config.azimuth_step_deg / 2:
                break
            T = poses[int(k)]
            if renderer.visible_fraction(T) < config.min_template_visible_fraction:
                continue
            scaled = _crop(renderer, world, K, T, sim_config, config)
            if not scaled:
                continue
            views.extend(
                TemplateView(
                    world.target_name, wanted, float(azimuths[k]), int(k), *view, scale, box
                )
                for scale, (*view, box) in zip(config.template_scales, scaled, strict=True)
            )
            break
    if not views:
        raise InputError(
            f"no frame of scenario {sc.scenario} run {sc.run} (seed {seed}) sees the target"
        )
    return views


def _crop(
    renderer: Renderer,
    world: World,
    K: np.ndarray,
    T_world_cam: np.ndarray,
    cfg: SimConfig,
    config: Baseline2dConfig,
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray | None]]:
    """(image, reference_px, keep_box_px) of the frame's view at each of `config.template_scales`;
    empty when the target's box is off the image or under 8 px.
    """
    uv = project(world.target.vertices, K, T_world_cam)
    if np.isnan(uv).any():
        return []
    lo, hi = uv.min(0), uv.max(0)
    margin = config.crop_margin_frac * (hi - lo)
    size = np.array([cfg.width_px - 1, cfg.height_px - 1], np.float64)
    box_lo = np.floor(np.maximum(lo - margin, 0))
    box_hi = np.ceil(np.minimum(hi + margin, size))
    if (box_hi - box_lo < 8).any():
        return []
    frame = to_srgb8(renderer.render(T_world_cam)[0])
    origin = project(world.T_world_target[None, :3, 3], K, T_world_cam)[0]
    views = []
    for scale in config.template_scales:
        if scale == 1.0:  # the paper's crop: the box and its margin, every keypoint kept
            x0, y0 = box_lo.astype(int)
            x1, y1 = box_hi.astype(int)
            crop = frame[y0 : y1 + 1, x0 : x1 + 1].copy()
            views.append((crop, origin - box_lo, None))
            continue
        # Context around the box, so that the descriptors' sampling patterns fit around keypoints
        # on the silhouette after shrinking; keypoints outside the box are dropped when described.
        context = config.scaled_template_context_px / scale
        c_lo = np.floor(np.maximum(box_lo - context, 0))
        c_hi = np.ceil(np.minimum(box_hi + context, size))
        x0, y0 = c_lo.astype(int)
        x1, y1 = c_hi.astype(int)
        crop = frame[y0 : y1 + 1, x0 : x1 + 1]
        shape = np.round(np.array(crop.shape[1::-1]) * scale).astype(int)
        small = cv2.resize(crop, tuple(int(v) for v in shape), interpolation=cv2.INTER_AREA)
        box = np.concatenate([box_lo - c_lo, box_hi - c_lo]) * scale
        views.append((small, (origin - c_lo) * scale, box))
    return views


def describe_templates(
    views: list[TemplateView], pair: str, config: Baseline2dConfig
) -> list[Template2d]:
    """Describe every template view with one Table IV combination (a view's keypoints outside its
    `keep_box_px` dropped).
    """
    return [Template2d(v, _inside(detect_and_describe(v.image, pair, config), v)) for v in views]


def _inside(features: Features2d, view: TemplateView) -> Features2d:
    if view.keep_box_px is None:
        return features
    x0, y0, x1, y1 = view.keep_box_px
    xy = features.xy_px
    keep = (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)
    return Features2d(xy[keep], features.descriptors[keep], features.binary)


def template_storage_bytes(templates: list[Template2d]) -> int:
    """Storage of the templates' features (keypoint positions + descriptors), bytes (Table V)."""
    return sum(t.features.nbytes for t in templates)
