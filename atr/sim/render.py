"""Camera rendering, target visibility and LIDAR scans of a built world, by ray casting
(Open3D/Embree).

One primary ray per pixel through a pinhole camera finds the surface, a second ray towards the sun
decides its shadow; the colour is the procedural albedo (`_shading.py`) lit by sun and sky,
attenuated by haze with range, mapped to sRGB.
"""

from __future__ import annotations

import cv2
import numpy as np
import open3d as o3d

from atr.errors import InputError
from atr.sim._shading import compose, make_rays, srgb8, surface_points
from atr.sim.config import SimConfig
from atr.sim.visibility import _EPS_M, raycasting_scene, target_samples
from atr.sim.world import World

_SUN_RGB = np.array([1.25, 1.16, 1.02], np.float32)  # direct sun irradiance (relative, linear RGB)
_SKY_RGB = np.array([0.24, 0.29, 0.40], np.float32)  # diffuse sky irradiance on an upward surface
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
        u, v = np.meshgrid(
            np.arange(self.cfg.width_px, dtype=np.float64),
            np.arange(self.cfg.height_px, dtype=np.float64),
        )
        self.dist = np.asarray(self.cfg.dist_coeffs, dtype=np.float64)
        if np.any(self.dist != 0):  # each pixel's ray through the distorted lens
            pix = np.column_stack([u.ravel(), v.ravel()]).reshape(-1, 1, 2)
            crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)
            xy = cv2.undistortPoints(pix, self.K, self.dist, None, None, None, crit).reshape(-1, 2)
        else:
            xy = np.column_stack(
                [
                    (u.ravel() - self.K[0, 2]) / self.K[0, 0],
                    (v.ravel() - self.K[1, 2]) / self.K[1, 1],
                ]
            )
        # z = 1: t_hit is the z-depth
        self._dirs_cam = np.column_stack([xy, np.ones(u.size)])
        self._samples = target_samples(
            world.target_local, world.T_world_target, self.cfg.target_samples
        )

    # camera ---------------------------------------------------------------------------------------

    def render(self, T_world_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Render one frame.

        Args:
            T_world_cam: (4, 4) world-from-camera pose (OpenCV camera axes).

        Returns:
            image (H, W, 3) float32 linear RGB in [0, 1] after exposure (before the sRGB curve), and
            depth (H, W) float32 z-depth along the optical axis, metres (inf where the sky shows).

        """
        cfg = self.cfg
        T = np.asarray(T_world_cam, dtype=np.float64)
        rays = make_rays(
            self._dirs_cam, np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3])
        )
        ans = self.scene.cast_rays(o3d.core.Tensor.from_numpy(rays))
        t = ans["t_hit"].numpy()
        pos, nrm, mat, fp, dist, ndl, sh = surface_points(
            rays,
            t,
            ans["primitive_ids"].numpy(),
            ans["geometry_ids"].numpy(),
            ans["primitive_normals"].numpy(),
            self._mat_static,
            self._mat_target,
            self._target_id,
            float(self.K[0, 0]),
            _GRAZING_COS_MIN,
            self.world.sun_dir,
            _SHADOW_BIAS_M,
        )
        # sun and shadows: a second ray cast towards the sun, only from surfaces facing it
        lit = np.nonzero(ndl > 0)[0]
        sh_lit = np.ascontiguousarray(sh[lit])
        occluded = self.scene.test_occlusions(o3d.core.Tensor.from_numpy(sh_lit)).numpy()
        direct = np.zeros(t.size)
        direct[lit] = np.where(occluded, 0.0, ndl[lit])
        haze_k = 0.0 if cfg.haze_visibility_m is None else 3.912 / cfg.haze_visibility_m
        img = compose(
            mat,
            pos,
            nrm,
            fp,
            dist,
            direct,
            rays,
            self.world.ground_rects,
            self.world.seed,
            _SUN_RGB,
            _SKY_RGB,
            _HAZE_RGB,
            _ZENITH_RGB,
            haze_k,
            cfg.exposure,
        )
        depth = (t.astype(np.float32)).reshape(cfg.height_px, cfg.width_px)
        return img.reshape(cfg.height_px, cfg.width_px, 3), depth

    # truth ----------------------------------------------------------------------------------------

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
        t_alone = self.target_scene.cast_rays(o3d.core.Tensor.from_numpy(rays))["t_hit"].numpy()
        self_vis = t_alone >= dist - tol
        n_self = int(self_vis.sum())
        if n_self == 0:
            return 0.0
        t_full = self.scene.cast_rays(o3d.core.Tensor.from_numpy(rays))["t_hit"].numpy()
        seen = self_vis & (t_full >= dist - tol)
        pc = (pts - o) @ T[:3, :3]
        in_front = pc[:, 2] > 0.1
        uv = project(pts, self.K, T, self.dist)
        inside = (
            in_front
            & (uv[:, 0] >= 0)
            & (uv[:, 0] <= self.cfg.width_px - 1)
            & (uv[:, 1] >= 0)
            & (uv[:, 1] <= self.cfg.height_px - 1)
        )
        return float((seen & inside).sum() / n_self)

    # LIDAR ----------------------------------------------------------------------------------------

    def lidar_scan(
        self, T_world_sensor: np.ndarray, spacing_m: float, range_m: float, rng: np.random.Generator
    ) -> np.ndarray:
        """A LIDAR scan: a square grid of beams around the sensor's boresight (its z axis).

        Each beam's spot grows with range (aperture + range x divergence); its return is the mean of
        `lidar_sub_rays` sub-ray ranges spread over the spot, so a spot straddling an edge returns a
        point between the two surfaces (mixed pixel). Sub-rays that miss are ignored; a beam whose
        sub-rays
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
        t0 = self.scene.cast_rays(o3d.core.Tensor.from_numpy(rays))["t_hit"].numpy()
        t0 = t0.astype(np.float64)
        t0 = np.where(np.isfinite(t0), t0, range_m)
        spot_rad = cfg.lidar_aperture_m / np.maximum(t0, 1.0) + cfg.lidar_divergence_mrad * 1e-3
        half_angle = 0.5 * spot_rad
        sub = centre[:, None, :] + half_angle[:, None, None] * (
            offs[None, :, 0:1] * e1[:, None, :] + offs[None, :, 1:2] * e2[:, None, :]
        )
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
    a = np.ascontiguousarray(img_linear, dtype=np.float32)
    return srgb8(a.reshape(-1, 3)).reshape(a.shape)


def project(
    points_world: np.ndarray,
    K: np.ndarray,
    T_world_cam: np.ndarray,
    dist_coeffs: np.ndarray | None = None,
) -> np.ndarray:
    """Projection of (N, 3) world points to (N, 2) pixels (NaN behind the camera).

    Args:
        points_world: (N, 3) metres; K: (3, 3) intrinsics; T_world_cam: (4, 4) camera pose.
        dist_coeffs: OpenCV distortion (k1, k2, p1, p2[, k3...]); None or zeros: pinhole.

    """
    T = np.asarray(T_world_cam, dtype=np.float64)
    pc = (np.asarray(points_world, dtype=np.float64) - T[:3, 3]) @ T[:3, :3]
    z = np.where(pc[:, 2] > 1e-9, pc[:, 2], np.nan)
    if dist_coeffs is not None and np.any(np.asarray(dist_coeffs) != 0):
        pts = np.ascontiguousarray(pc / z[:, None])
        uv, _ = cv2.projectPoints(
            np.nan_to_num(pts),
            np.zeros(3),
            np.zeros(3),
            K,
            np.asarray(dist_coeffs, dtype=np.float64),
        )
        uv = uv.reshape(-1, 2)
        uv[~np.isfinite(z)] = np.nan
        return uv
    return np.column_stack([K[0, 0] * pc[:, 0] / z + K[0, 2], K[1, 1] * pc[:, 1] / z + K[1, 2]])
