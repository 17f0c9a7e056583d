"""Offline phase (paper §II-A): a 3D template from a CAD mesh or from a model point cloud.

Mesh -> dense surface sampling -> hidden point removal (Katz et al. 2007, Open3D) from aerial viewpoint(s)
-> uniform subsampling at ``resolution_m`` -> normals (plane fit on ``normal_k`` neighbours) -> description
of every vertex with one descriptor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import open3d as o3d

from atr.errors import InputError
from atr.recognition import _backend
from atr.recognition.config import DESCRIPTORS, RecognitionConfig, TemplateConfig
from atr.recognition.steps import uniform_subsample

TEMPLATE_VERSION = 2
"""Bumped whenever the template recipe changes, so that caches keyed by parameters are invalidated."""

DESCRIPTOR_ARRAYS = ("descriptors", "descriptor_low", "descriptor_step")
"""A Template dict's descriptor arrays: the rows, and their offsets and steps when compact."""


@dataclass
class Template:
    """What the template store serves: one target described with one descriptor.

    Attributes:
        target: target name ("t72", "ifv", ...).
        descriptor: descriptor name (one of ``DESCRIPTORS``).
        points_m: (N, 3) float32, the viewed and subsampled model P_m in the target's frame, metres.
        normals: (N, 3) float32 unit normals of ``points_m``.
        keypoints_m: (K, 3) float32, described vertices, metres.
        descriptors: (K, L) float32, one row per keypoint (rows with NaN were dropped).
        radius_m: descriptor support radius, metres.
        params: scalars and short lists describing how it was built (resolution_m, views, version...).

    """

    target: str
    descriptor: str
    points_m: np.ndarray
    normals: np.ndarray
    keypoints_m: np.ndarray
    descriptors: np.ndarray
    radius_m: float
    params: dict[str, Any] = field(default_factory=dict)

    def to_dict(self, compact: bool = False) -> dict[str, Any]:
        """A dict of numpy arrays and scalars (msgpack-friendly through the project codec).

        ``compact`` stores the descriptors as uint8 codes with a per-row offset and step
        (``quantize_descriptors``): a quarter of the bytes; ``from_dict`` decodes them.
        """
        descriptors: dict[str, np.ndarray] = {
            "descriptors": np.ascontiguousarray(self.descriptors, np.float32)
        }
        if compact:
            codes, low, step = quantize_descriptors(self.descriptors)
            descriptors = {"descriptors": codes, "descriptor_low": low, "descriptor_step": step}
        return {
            "target": self.target,
            "descriptor": self.descriptor,
            "points_m": np.ascontiguousarray(self.points_m, np.float32),
            "normals": np.ascontiguousarray(self.normals, np.float32),
            "keypoints_m": np.ascontiguousarray(self.keypoints_m, np.float32),
            **descriptors,
            "radius_m": float(self.radius_m),
            "params": dict(self.params),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Template:
        """Inverse of ``to_dict``; raises InputError on a missing field or inconsistent shapes."""
        try:
            t = cls(
                target=str(d["target"]),
                descriptor=str(d["descriptor"]),
                points_m=np.asarray(d["points_m"], np.float32).reshape(-1, 3),
                normals=np.asarray(d["normals"], np.float32).reshape(-1, 3),
                keypoints_m=np.asarray(d["keypoints_m"], np.float32).reshape(-1, 3),
                descriptors=_decoded_descriptors(d),
                radius_m=float(d["radius_m"]),
                params=dict(d.get("params", {})),
            )
        except (KeyError, ValueError, TypeError) as exc:
            raise InputError(f"template dict is malformed: {exc!r}") from exc
        if t.descriptors.ndim != 2 or len(t.descriptors) != len(t.keypoints_m):
            raise InputError(
                f"template has {len(t.keypoints_m)} keypoints but descriptors of shape "
                f"{t.descriptors.shape}; expected ({len(t.keypoints_m)}, L)"
            )
        if len(t.normals) != len(t.points_m):
            raise InputError(f"template has {len(t.points_m)} points but {len(t.normals)} normals")
        vp, vk = t.params.get("view_points"), t.params.get("view_keypoints")
        if vp is not None or vk is not None:
            if (
                vp is None
                or vk is None
                or len(vp) != len(vk)
                or sum(int(x) for x in vp) != len(t.points_m)
                or sum(int(x) for x in vk) != len(t.keypoints_m)
            ):
                raise InputError(
                    f"template view counts {vp} / {vk} do not add up to {len(t.points_m)} points / "
                    f"{len(t.keypoints_m)} keypoints"
                )
        return t

    def view_slices(self) -> list[tuple[slice, slice]]:
        """(points slice, keypoints slice) of each view; one view spanning everything when not multi-view.

        A multi-view template (``build_template`` with several HPR viewpoints) stacks its views:
        ``params["view_points"]`` and ``params["view_keypoints"]`` hold the row counts of each view in
        ``points_m``/``normals`` and in ``keypoints_m``/``descriptors``.
        """
        np_, nk = self.params.get("view_points"), self.params.get("view_keypoints")
        if not np_ or not nk or len(np_) != len(nk):
            return [(slice(0, len(self.points_m)), slice(0, len(self.keypoints_m)))]
        p_off = np.concatenate([[0], np.cumsum(np.asarray(np_, np.int64))])
        k_off = np.concatenate([[0], np.cumsum(np.asarray(nk, np.int64))])
        return [
            (slice(int(p_off[i]), int(p_off[i + 1])), slice(int(k_off[i]), int(k_off[i + 1])))
            for i in range(len(np_))
        ]


def quantize_descriptors(descriptors: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Descriptors as uint8 codes with a per-row offset and step: row = low + code x step.

    Each row spans its own [min, max] in 255 steps, so the decoded value is within half a step (1/510 of the
    row's range) of the original; a descriptor's bins keep their order and the nearest-neighbour search its
    neighbours. Returns codes (K, L) uint8, low (K,) float32, step (K,) float32.
    """
    d = np.asarray(descriptors, np.float32)
    if d.ndim != 2:
        raise InputError(f"descriptors must be (K, L); got shape {d.shape}")
    if len(d) == 0:
        return np.zeros(d.shape, np.uint8), np.zeros(0, np.float32), np.zeros(0, np.float32)
    low = d.min(axis=1)
    span = d.max(axis=1) - low
    step = np.where(span > 0, span / 255.0, 1.0).astype(np.float32)
    codes = np.rint((d - low[:, None]) / step[:, None])
    return np.clip(codes, 0, 255).astype(np.uint8), low.astype(np.float32), step


def dequantize_descriptors(codes: np.ndarray, low: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Inverse of ``quantize_descriptors``: (K, L) float32."""
    c, lo, st = np.asarray(codes), np.asarray(low, np.float32), np.asarray(step, np.float32)
    if c.ndim != 2 or lo.shape != (len(c),) or st.shape != (len(c),):
        raise InputError(
            f"compact descriptors {c.shape} need one offset and one step per row; got {lo.shape}, "
            f"{st.shape}"
        )
    return (lo[:, None] + c.astype(np.float32) * st[:, None]).astype(np.float32)


def _decoded_descriptors(d: dict[str, Any]) -> np.ndarray:
    """A Template dict's descriptors as float32, decoding uint8 codes (``to_dict(compact=True)``)."""
    descriptors = np.asarray(d["descriptors"])
    if descriptors.dtype != np.uint8:
        return descriptors.astype(np.float32)
    if "descriptor_low" not in d or "descriptor_step" not in d:
        raise InputError("uint8 template descriptors need descriptor_low and descriptor_step")
    return dequantize_descriptors(descriptors, d["descriptor_low"], d["descriptor_step"])


def template_from_message(message: dict[str, Any]) -> Template:
    """The Template a Template message describes (what the template store serves), as the matcher uses it:
    compact descriptors decoded, the message's resolution among the params.
    """
    params = message.get("params", {}) | {"resolution_m": message["resolution_m"]}
    return Template.from_dict(message | {"params": params})


def message_storage_bytes(message: dict[str, Any]) -> int:
    """Bytes of a Template message's descriptors (with their offsets and steps when compact) and keypoints:
    the template storage a store holds and a link carries for the matching (Table V's quantity).
    """
    names = (*DESCRIPTOR_ARRAYS, "keypoints_m")
    return int(sum(np.asarray(message[n]).nbytes for n in names if n in message))


def sample_mesh_surface(
    vertices: np.ndarray, triangles: np.ndarray, samples_per_m2: float, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Area-uniform random points on a triangle mesh, with the face normal of each point.

    Args:
        vertices: (V, 3) metres.
        triangles: (M, 3) vertex indices.
        samples_per_m2: sampling density, points per square metre.
        seed: seed of the generator.

    Returns:
        points (P, 3) float64 metres, normals (P, 3) float64 unit (winding-oriented face normals).

    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(triangles, np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise InputError(
            f"mesh must be vertices (V, 3) and triangles (M, 3); got {v.shape}, {f.shape}"
        )
    if f.min() < 0 or f.max() >= len(v):
        raise InputError(
            f"triangle indices span [{f.min()}, {f.max()}], vertices are 0..{len(v) - 1}"
        )
    if not np.isfinite(v).all():
        raise InputError("mesh vertices contain NaN or infinity")
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    cross = np.cross(b - a, c - a)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    total = float(area.sum())
    if total <= 0:
        raise InputError("mesh has zero surface area")
    n = max(int(math.ceil(total * samples_per_m2)), 1)
    rng = np.random.default_rng(seed)
    tri = rng.choice(len(f), size=n, p=area / total)
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    pts = (1 - s)[:, None] * a[tri] + (s * (1 - r2))[:, None] * b[tri] + (s * r2)[:, None] * c[tri]
    nrm = cross[tri] / np.maximum(2.0 * area[tri], 1e-300)[:, None]
    return pts, nrm


def aerial_viewpoints(centre: np.ndarray, config: TemplateConfig | RecognitionConfig) -> np.ndarray:
    """HPR viewpoints (V, 3), metres: ``template_distance_m`` from ``centre`` at every configured
    elevation (outer loop) and azimuth (inner loop), z up.
    """
    out = []
    for el_deg in config.template_elevations_deg:
        el = math.radians(el_deg)
        for az_deg in config.template_azimuths_deg:
            az = math.radians(az_deg)
            d = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
            out.append(np.asarray(centre, np.float64) + config.template_distance_m * d)
    return np.array(out)


def hidden_point_removal(
    points: np.ndarray, viewpoints: np.ndarray, radius_factor: float
) -> np.ndarray:
    """Indices of points visible from at least one viewpoint (Katz et al. 2007, via Open3D).

    Args:
        points: (N, 3) metres.
        viewpoints: (V, 3) metres.
        radius_factor: spherical-flip radius as a multiple of each viewpoint's distance to the points.

    Returns:
        (M,) int64 sorted unique indices.

    """
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, np.float64)))
    centre = np.asarray(points).mean(0)
    seen: set[int] = set()
    for vp in np.asarray(viewpoints, np.float64).reshape(-1, 3):
        radius = radius_factor * float(np.linalg.norm(vp - centre))
        _, idx = cloud.hidden_point_removal(vp, radius)
        seen.update(int(i) for i in idx)
    return np.array(sorted(seen), np.int64)


def template_from_points(
    points: np.ndarray,
    target: str,
    descriptor: str,
    config: TemplateConfig | RecognitionConfig,
    *,
    orientation_normals: np.ndarray | None = None,
    viewpoint: np.ndarray | None = None,
    params: dict[str, Any] | None = None,
) -> Template:
    """A template from an already-viewed model cloud P_m (subsampled, normals, every vertex described).

    Args:
        points: (N, 3) model points in the target frame, metres (non-finite rows are dropped).
        target: target name.
        descriptor: descriptor name.
        config: the template settings (resolution, normal_k, k_support_radius), or a
            RecognitionConfig, whose template part alone is read.
        orientation_normals: optional (N, 3) normals whose sign the estimated normals adopt (e.g. the mesh
            face normals, outward); otherwise normals face ``viewpoint`` (None = up, +z).
        viewpoint: (3,) metres, see above.
        params: extra entries for ``Template.params``.

    Returns:
        The template.

    """
    if descriptor not in DESCRIPTORS:
        raise InputError(f"descriptor {descriptor!r} must be one of {DESCRIPTORS}")
    pts = np.asarray(points, np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError(f"model points must be (N, 3); got {pts.shape}")
    finite = np.isfinite(pts).all(axis=1)
    pts = pts[finite]
    sub = uniform_subsample(pts, config.resolution_m)
    if len(sub) < config.normal_k + 1:
        raise InputError(
            f"model has {len(sub)} vertices after {config.resolution_m} m subsampling; "
            f"at least {config.normal_k + 1} are needed"
        )
    p_m = pts[sub]
    normals = _backend.estimate_normals(p_m, config.normal_k, viewpoint)
    if orientation_normals is not None:
        ref = np.asarray(orientation_normals, np.float64)[finite][sub]
        normals[np.einsum("ij,ij->i", normals, ref) < 0] *= -1.0
    radius = config.support_radius_m
    desc = _backend.describe(descriptor, p_m, normals, np.arange(len(p_m)), radius)
    ok = np.isfinite(desc).all(axis=1)
    info = {
        "version": TEMPLATE_VERSION,
        "resolution_m": config.resolution_m,
        "normal_k": config.normal_k,
        "k_support_radius": config.k_support_radius,
    }
    info.update(params or {})
    return Template(
        target=target,
        descriptor=descriptor,
        points_m=p_m.astype(np.float32),
        normals=normals.astype(np.float32),
        keypoints_m=p_m[ok].astype(np.float32),
        descriptors=desc[ok].astype(np.float32),
        radius_m=radius,
        params=info,
    )


def _view_points(
    dense: np.ndarray,
    face_normals: np.ndarray,
    viewpoint: np.ndarray,
    config: TemplateConfig | RecognitionConfig,
) -> np.ndarray:
    """Indices of the dense samples seen from one viewpoint: HPR, then only faces that face it."""
    visible = hidden_point_removal(dense, viewpoint[None, :], config.hpr_radius_factor)
    if len(visible) == 0:
        return visible
    # HPR keeps some samples of hidden faces at grazing angles: a visible surface faces the view.
    facing = np.einsum("ij,ij->i", viewpoint[None, :] - dense[visible], face_normals[visible]) > 0
    return visible[facing] if facing.sum() >= config.normal_k + 1 else visible


def build_template(
    mesh_vertices: np.ndarray,
    mesh_triangles: np.ndarray,
    target: str,
    descriptor: str,
    config: TemplateConfig | RecognitionConfig,
) -> Template:
    """Offline phase §II-A: CAD mesh -> simulated aerial views P_m -> subsampled, described template.

    One HPR view per configured azimuth (``template_azimuths_deg``) and elevation (``template_elevations_deg``). Each
    view is subsampled, given normals and described on its own visible surface, as the scene will be; the
    views are stacked in one Template (``Template.view_slices``) and the matcher treats each view as a
    template of its own (its own kNNDR, groups and overlap), so that a target seen from any azimuth of
    the orbit meets the view that shows what the camera sees (docs/recognition.md).

    Args:
        mesh_vertices: (V, 3) target-frame vertices, metres, z up.
        mesh_triangles: (M, 3) vertex indices.
        target: target name.
        descriptor: descriptor name.
        config: the template settings (resolution, HPR views, sampling density), or a
            RecognitionConfig, whose template part alone is read.

    Returns:
        The template; ``params`` records the views used and their row counts.

    """
    dense, face_normals = sample_mesh_surface(
        mesh_vertices, mesh_triangles, config.template_samples_per_m2, seed=0
    )
    lo, hi = dense.min(0), dense.max(0)
    centre = 0.5 * (lo + hi)
    views = aerial_viewpoints(centre, config)
    parts: list[Template] = []
    # Vehicle frame (origin on the ground, z up): the ground-cut band is dropped, as the matcher drops
    # the scene's ground (RecognitionConfig.ground_vehicles).
    on_ground = config.ground_vehicles and abs(float(lo[2])) <= config.resolution_m
    above = dense[:, 2] >= lo[2] + (config.ground_cut_m if on_ground else -1.0)
    for vp in views:
        kept = _view_points(dense, face_normals, vp, config)
        kept = kept[above[kept]]
        if len(kept) == 0:
            raise InputError(
                f"no point of target {target!r} is visible from viewpoint {vp.tolist()}"
            )
        parts.append(
            template_from_points(
                dense[kept], target, descriptor, config, orientation_normals=face_normals[kept]
            )
        )
    info = dict(parts[0].params)
    info.update(
        {
            "source": "mesh",
            "template_elevations_deg": list(config.template_elevations_deg),
            "view_azimuths_deg": [
                a for _ in config.template_elevations_deg for a in config.template_azimuths_deg
            ],
            "view_elevations_deg": [
                e for e in config.template_elevations_deg for _ in config.template_azimuths_deg
            ],
            "template_azimuths_deg": list(config.template_azimuths_deg),
            "template_distance_m": config.template_distance_m,
            "dense_points": int(len(dense)),
            "extent_m": [float(x) for x in (hi - lo)],
            "on_ground": bool(on_ground),
            "view_points": [int(len(p.points_m)) for p in parts],
            "view_keypoints": [int(len(p.keypoints_m)) for p in parts],
        }
    )
    return Template(
        target=target,
        descriptor=descriptor,
        points_m=np.concatenate([p.points_m for p in parts]),
        normals=np.concatenate([p.normals for p in parts]),
        keypoints_m=np.concatenate([p.keypoints_m for p in parts]),
        descriptors=np.concatenate([p.descriptors for p in parts]),
        radius_m=parts[0].radius_m,
        params=info,
    )


def model_extent_m(template: Template) -> float:
    """Largest extent of the template's points, metres (used to size non-maximum suppression)."""
    p = np.asarray(template.points_m, np.float64)
    return float(np.linalg.norm(p.max(0) - p.min(0))) if len(p) else 0.0
