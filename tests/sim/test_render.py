import numpy as np

from atr.sim.mesh import box
from atr.sim.render import Renderer, project

from .conftest import look_at, toy_world


def test_world_point_projects_where_renderer_draws_it(small_cfg):
    """Ground points (z = 0 plane) seen through pixel centres project back to those pixels, and the
    rendered depth there equals their distance along the optical axis."""
    world = toy_world([], small_cfg)
    ren = Renderer(world, small_cfg)
    T = look_at([-30.0, -25.0, 28.0], [8.0, 6.0, 0.0])
    _, depth = ren.render(T)
    K = small_cfg.K
    rng = np.random.default_rng(0)
    uv = np.column_stack(
        [rng.integers(0, small_cfg.width_px, 200), rng.integers(0, small_cfg.height_px, 200)]
    )
    rays_cam = np.column_stack(
        [(uv[:, 0] - K[0, 2]) / K[0, 0], (uv[:, 1] - K[1, 2]) / K[1, 1], np.ones(len(uv))]
    )
    rays_w = rays_cam @ T[:3, :3].T
    s = -T[2, 3] / rays_w[:, 2]  # intersection with z = 0
    P = T[:3, 3] + rays_w * s[:, None]
    on_ground = (s > 0) & (np.hypot(P[:, 0], P[:, 1]) > 8.0)  # away from the tank
    assert on_ground.sum() > 100
    np.testing.assert_allclose(project(P[on_ground], K, T), uv[on_ground], atol=1e-6)
    d = depth[uv[on_ground, 1], uv[on_ground, 0]]
    np.testing.assert_allclose(d, s[on_ground], rtol=1e-4)


def test_target_pixels_are_target_coloured_and_shadowed_ground_is_darker(small_cfg):
    world = toy_world([box((4.0, 4.0, 20.0), (-15.0, -10.0, 10.0), 2)], small_cfg)
    ren = Renderer(world, small_cfg)
    T = look_at([-40.0, 0.0, 25.0], [0.0, 0.0, 1.0])
    lin, depth = ren.render(T)
    c = np.array(small_cfg.K[:2, 2]).round().astype(int)
    d_centre = depth[c[1], c[0]]
    assert d_centre < np.linalg.norm(T[:3, 3] - [0, 0, 1]) + 2.0  # the tank is in the middle
    assert np.isfinite(depth).all()  # looking down: no sky
    assert lin.min() >= 0 and 0.05 < lin.mean() < 1.0


def test_same_world_renders_identically(small_cfg):
    world = toy_world([], small_cfg)
    T = look_at([-30.0, 10.0, 20.0], [0.0, 0.0, 1.0])
    a, _ = Renderer(world, small_cfg).render(T)
    b, _ = Renderer(world, small_cfg).render(T)
    assert a.tobytes() == b.tobytes()


def test_distorted_lens_projection_matches_render(small_cfg):
    """With lens distortion, a ground point seen through a pixel projects back to that pixel with
    OpenCV's distortion model, and the rendered depth there is the point's depth."""
    from dataclasses import replace

    import cv2

    cfg = replace(small_cfg, dist_coeffs=(-0.12, 0.03, 0.001, -0.0005, 0.0))
    world = toy_world([], cfg)
    ren = Renderer(world, cfg)
    T = look_at([-30.0, -25.0, 28.0], [8.0, 6.0, 0.0])
    _, depth = ren.render(T)
    K, dist = cfg.K, np.array(cfg.dist_coeffs)
    uv = np.array([[5, 7], [300, 12], [160, 120], [20, 230], [310, 235], [100, 60]], float)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)
    xy = cv2.undistortPoints(uv.reshape(-1, 1, 2), K, dist, None, None, None, crit).reshape(-1, 2)
    rays_w = np.column_stack([xy, np.ones(len(xy))]) @ T[:3, :3].T
    s = -T[2, 3] / rays_w[:, 2]
    P = T[:3, 3] + rays_w * s[:, None]
    np.testing.assert_allclose(project(P, K, T, dist), uv, atol=1e-4)
    np.testing.assert_allclose(depth[uv[:, 1].astype(int), uv[:, 0].astype(int)], s, rtol=1e-4)
    # the corners really moved: distortion is not a no-op
    assert np.abs(project(P, K, T) - uv).max() > 2.0
