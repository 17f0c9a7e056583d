"""Camera rendering, target visibility and LIDAR scans of a built world, by ray casting (Open3D/Embree).

One primary ray per pixel through a pinhole camera finds the surface, a second ray towards the sun
decides its shadow; the colour is the procedural albedo (`_shading.py`) lit by sun and sky, attenuated
by haze with range, mapped to sRGB.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d

from atr.errors import InputError
from atr.sim._shading import albedo
from atr.sim.config import SimConfig
from atr.sim.visibility import _EPS_M, raycasting_scene, target_samples
from atr.sim.world import World

_SUN_RGB = np.array([1.00, 0.93, 0.82], np.float32)  # direct sun irradiance (relative, linear RGB)
_SKY_RGB = np.array([0.30, 0.36, 0.48], np.float32)  # diffuse sky irradiance on an upward surface
_HAZE_RGB = np.array([0.62, 0.67, 0.74], np.float32)  # colour of distant haze (linear)
_ZENITH_RGB = np.array([0.16, 0.28, 0.55], np.float32)  # sky radiance straight up (linear)
_SHADOW_BIAS_M = 0.02  # shadow rays start this far off the surface (plus 2e-4 x range)
_GRAZING_COS_MIN = 0.08  # the pixel footprint stretches as 1/cos(incidence), capped here


class Renderer:
    """Renders camera images and LIDAR scans of one world and reports target visibility.

    Args:
        world: the built world.
        config: simulator settings (image size, intrinsics, haze, exposure, LIDAR).
    """

    def __init__(self, world: World, config: SimConfig | None = None) -> None:
        self.world = world
        self.cfg = config or SimConfig()
        self.scene, ids = raycasting_scene([world.static, world.target])
        self._static_id, self._target_id = ids
        self.target_scene, _ = raycasting_scene([world.target])
        self._mat_static = world.static.material
        self._mat_target = world.target.material
        self.K = self.cfg.K
        u, v = np.meshgrid(np.arange(self.cfg.width_px, dtype=np.float64),
                           np.arange(self.cfg.height_px, dtype=np.float64))
        self._dirs_cam = np.column_stack([(u.ravel() - self.K[0, 2]) / self.K[0, 0],
                                          (v.ravel() - self.K[1, 2]) / self.K[1, 1],
                                          np.ones(u.size)])
        self._samples = target_samples(world.target_local, world.T_world_target, self.cfg.target_samples)

    # ------------------------------------------------------------------------------------------ camera

    def render(self, T_world_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Render one frame.

        Args:
            T_world_cam: (4, 4) world-from-camera pose (OpenCV camera axes).

        Returns:
            image (H, W, 3) float32 linear RGB in [0, 1] after exposure (before the sRGB curve), and
            depth (H, W) float32 z-depth along the optical axis, metres (inf where the sky shows).
        """
        cfg = self.cfg
        R = np.asarray(T_world_cam, dtype=np.float64)[:3, :3]
        o = np.asarray(T_world_cam, dtype=np.float64)[:3, 3]
        d_world = self._dirs_cam @ R.T
        rays = np.empty((d_world.shape[0], 6), np.float32)
        rays[:, :3] = o
        rays[:, 3:] = d_world
        ans = self.scene.cast_rays(o3d.core.Tensor(rays))
        t = ans["t_hit"].numpy()
        hit = np.isfinite(t)
        idx = np.nonzero(hit)[0]
        prim = ans["primitive_ids"].numpy()[idx].astype(np.int64)
        geom = ans["geometry_ids"].numpy()[idx]
        nrm = ans["primitive_normals"].numpy()[idx].astype(np.float64)
        dirs = d_world[idx]
        th = t[idx].astype(np.float64)
        pos = o + dirs * th[:, None]
        ray_len = np.linalg.norm(dirs, axis=1)
        dist = th * ray_len
        # face the camera: imported meshes and thin parts may have either winding
        cos_i = np.einsum("ij,ij->i", nrm, dirs) / ray_len
        flip = cos_i > 0
        nrm[flip] *= -1.0
        cos_i = np.abs(cos_i)
        mat = np.where(geom == self._target_id, self._mat_target[np.minimum(prim, len(self._mat_target) - 1)],
                       self._mat_static[np.minimum(prim, len(self._mat_static) - 1)]).astype(np.int16)
        footprint = dist / self.K[0, 0] / np.maximum(cos_i, _GRAZING_COS_MIN)
        alb = albedo(mat, pos, nrm, footprint, self.world.ground_rects, self.world.seed)
        # sun and shadows: a second ray cast towards the sun
        sun = self.world.sun_dir
        ndl = nrm @ sun
        lit_idx = np.nonzero(ndl > 0)[0]
        sh_rays = np.empty((lit_idx.size, 6), np.float32)
        sh_rays[:, :3] = pos[lit_idx] + nrm[lit_idx] * (_SHADOW_BIAS_M + 2e-4 * dist[lit_idx])[:, None]
        sh_rays[:, 3:] = sun
        occluded = self.scene.test_occlusions(o3d.core.Tensor(sh_rays)).numpy()
        direct = np.zeros(idx.size, np.float32)
        direct[lit_idx] = np.where(occluded, 0.0, ndl[lit_idx])
        sky = (0.55 + 0.45 * nrm[:, 2]).astype(np.float32)
        rad = alb * (direct[:, None] * _SUN_RGB + sky[:, None] * _SKY_RGB)
        if cfg.haze_visibility_m is not None:
            f = np.exp(-3.912 * dist / cfg.haze_visibility_m).astype(np.float32)[:, None]
            rad = rad * f + _HAZE_RGB * 0.45 * (1.0 - f)
        img = np.empty((t.size, 3), np.float32)
        img[idx] = rad * cfg.exposure
        miss = np.nonzero(~hit)[0]
        if miss.size:
            dm = d_world[miss]
            el = np.clip(dm[:, 2] / np.linalg.norm(dm, axis=1), -1.0, 1.0)
            w = np.clip(el, 0.0, 1.0) ** 0.5
            img[miss] = ((1 - w)[:, None] * _HAZE_RGB + w[:, None] * _ZENITH_RGB) * 0.75
        depth = np.where(hit, t, np.inf).astype(np.float32)
        H, W = cfg.height_px, cfg.width_px
        return img.reshape(H, W, 3), depth.reshape(H, W)

    # ------------------------------------------------------------------------------------------ truth

    def visible_fraction(self, T_world_cam: np.ndarray) -> float:
        """Share of the target's camera-facing surface seen in this frame (0..1), by ray casting."""
        T = np.asarray(T_world_cam, dtype=np.float64)
        o = T[:3, 3]
        pts = self._samples
        d = pts - o
        dist = np.linalg.norm(d, axis=1)
        dirs = d / dist[:, None]
        rays = np.concatenate([np.broadcast_to(o, d.shape), dirs], axis=1).astype(np.float32)
        tol = _EPS_M + 1e-4 * dist
        t_alone = self.target_scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
        self_vis = t_alone >= dist - tol
        n_self = int(self_vis.sum())
        if n_self == 0:
            return 0.0
        t_full = self.scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
        seen = self_vis & (t_full >= dist - tol)
        pc = (pts - o) @ T[:3, :3]
        in_front = pc[:, 2] > 0.1
        uv = pc[:, :2] / np.where(in_front, pc[:, 2], 1.0)[:, None] * self.K[0, 0] + self.K[:2, 2]
        inside = in_front & (uv[:, 0] >= 0) & (uv[:, 0] <= self.cfg.width_px - 1) & (uv[:, 1] >= 0) & (
            uv[:, 1] <= self.cfg.height_px - 1)
        return float((seen & inside).sum() / n_self)

    # ------------------------------------------------------------------------------------------ LIDAR

    def lidar_scan(self, T_world_sensor: np.ndarray, spacing_m: float, range_m: float,
                   rng: np.random.Generator) -> np.ndarray:
        """A LIDAR scan: a square grid of beams around the sensor's boresight (its z axis).

        Each beam's spot grows with range (aperture + range x divergence); its return is the mean of
        `lidar_sub_rays` sub-ray ranges spread over the spot, so a spot straddling an edge returns a
        point between the two surfaces (mixed pixel). Sub-rays that miss are ignored; a beam whose sub-rays
        all miss gives no return. Gaussian range noise is added.

        Args:
            T_world_sensor: (4, 4) world-from-sensor pose, OpenCV axes (z boresight).
            spacing_m: point spacing at range_m, metres (Table II resolution).
            range_m: range at which the spacing holds, metres.
            rng: noise generator.

        Returns:
            (P, 3) float64 points in the world frame, metres.
        """
        if spacing_m <= 0 or range_m <= 0:
            raise InputError(f"LIDAR spacing {spacing_m} m and range {range_m} m must be > 0")
        cfg = self.cfg
        n = cfg.lidar_grid
        step = spacing_m / range_m
        a = (np.arange(n) - 0.5 * (n - 1)) * step
        ax, ay = np.meshgrid(a, a)
        d_cam = np.column_stack([np.tan(ax.ravel()), np.tan(ay.ravel()), np.ones(n * n)])
        d_cam /= np.linalg.norm(d_cam, axis=1, keepdims=True)
        T = np.asarray(T_world_sensor, dtype=np.float64)
        R, o = T[:3, :3], T[:3, 3]
        centre = d_cam @ R.T
        # fixed sub-ray pattern over the unit disc: centre plus a ring (sunflower layout)
        k = cfg.lidar_sub_rays
        j = np.arange(k)
        rr = np.sqrt((j + 0.5) / k)
        th = j * 2.399963229728653
        offs = np.column_stack([rr * np.cos(th), rr * np.sin(th)])  # unit-disc offsets
        # two axes perpendicular to each beam
        e1 = np.cross(centre, R[:, 1])
        e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
        e2 = np.cross(centre, e1)
        # first pass: central ray range, to size the spot
        rays = np.empty((n * n, 6), np.float32)
        rays[:, :3] = o
        rays[:, 3:] = centre
        t0 = self.scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy().astype(np.float64)
        t0 = np.where(np.isfinite(t0), t0, range_m)
        half_angle = 0.5 * (cfg.lidar_aperture_m / np.maximum(t0, 1.0) + cfg.lidar_divergence_mrad * 1e-3)
        sub = (centre[:, None, :] + half_angle[:, None, None] * (
            offs[None, :, 0:1] * e1[:, None, :] + offs[None, :, 1:2] * e2[:, None, :]))
        sub /= np.linalg.norm(sub, axis=2, keepdims=True)
        srays = np.empty((n * n * k, 6), np.float32)
        srays[:, :3] = o
        srays[:, 3:] = sub.reshape(-1, 3)
        ts = self.scene.cast_rays(o3d.core.Tensor(srays))["t_hit"].numpy().reshape(n * n, k)
        ok = np.isfinite(ts) & (ts < cfg.lidar_max_range_m)
        cnt = ok.sum(axis=1)
        keep = cnt > 0
        rng_m = np.where(ok, ts, 0.0).sum(axis=1)[keep] / cnt[keep]
        rng_m = rng_m + rng.normal(0.0, cfg.lidar_range_noise_m, rng_m.shape)
        return o + centre[keep] * rng_m[:, None]


def to_srgb8(img_linear: np.ndarray) -> np.ndarray:
    """Linear [0, 1] RGB -> sRGB uint8 (IEC 61966-2-1 curve)."""
    x = np.clip(img_linear, 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (s * 255.0 + 0.5).astype(np.uint8)


def project(points_world: np.ndarray, K: np.ndarray, T_world_cam: np.ndarray) -> np.ndarray:
    """Pinhole projection of (N, 3) world points to (N, 2) pixel coordinates (NaN behind the camera)."""
    T = np.asarray(T_world_cam, dtype=np.float64)
    pc = (np.asarray(points_world, dtype=np.float64) - T[:3, 3]) @ T[:3, :3]
    z = np.where(pc[:, 2] > 1e-9, pc[:, 2], np.nan)
    return np.column_stack([K[0, 0] * pc[:, 0] / z + K[0, 2], K[1, 1] * pc[:, 1] / z + K[1, 2]])
