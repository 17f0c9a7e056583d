import numpy as np

from atr.sim.mesh import box
from atr.sim.render import Renderer

from .conftest import look_at, toy_world


def _smear_width(ren, rng_m, wall_x):
    """Lateral width (m) of the band of LIDAR points floating between a wall edge and the ground."""
    # sensor looks straight down at a wall top edge (wall top at z = 10, ground at z = 0)
    T = look_at([wall_x, 0.0, 10.0 + rng_m], [wall_x, 0.0001, 0.0])
    # a fine grid (1 cm at 50 m) so the smear band is resolved at both ranges
    pts = ren.lidar_scan(
        T, spacing_m=0.01 * rng_m / 50.0, range_m=rng_m, rng=np.random.default_rng(0)
    )
    mixed = (pts[:, 2] > 0.3) & (pts[:, 2] < 9.7)
    return np.ptp(pts[mixed, 0]) if mixed.any() else 0.0, pts


def test_footprint_smear_grows_with_range(small_cfg):
    # wall top spans x < 20; ground beyond. Looking down at the edge x = 20.
    world = toy_world([box((20.0, 40.0, 10.0), (10.0, 0.0, 5.0), 2)], small_cfg)
    ren = Renderer(world, small_cfg)
    w50, p50 = _smear_width(ren, 50.0, 20.0)
    w200, p200 = _smear_width(ren, 200.0, 20.0)
    spot50 = small_cfg.lidar_aperture_m + 60.0 * small_cfg.lidar_divergence_mrad * 1e-3
    spot200 = small_cfg.lidar_aperture_m + 210.0 * small_cfg.lidar_divergence_mrad * 1e-3
    assert w200 > 2.0 * w50
    assert w50 < 1.5 * spot50 and 0.5 * spot200 < w200 < 1.5 * spot200
    assert len(p50) > 0.9 * small_cfg.lidar_grid**2


def test_point_spacing_matches_table_ii(small_cfg):
    world = toy_world([], small_cfg)
    ren = Renderer(world, small_cfg)
    for rng_m, spacing in ((50.0, 0.11), (200.0, 0.30)):
        T = look_at([60.0, 0.0, rng_m], [60.0, 0.0001, 0.0])  # open ground east of the tank
        pts = ren.lidar_scan(T, spacing, rng_m, np.random.default_rng(1))
        ground = pts[pts[:, 2] < 0.1]
        y0 = ground[np.argmin(np.abs(ground[:, 1])), 1]
        row = ground[np.abs(ground[:, 1] - y0) < 0.25 * spacing]
        assert len(row) > 0.9 * small_cfg.lidar_grid
        step = np.median(np.diff(np.sort(row[:, 0])))
        assert step == np.clip(step, 0.95 * spacing, 1.05 * spacing)


def test_crowns_are_partly_penetrable(small_cfg):
    from atr.sim.world import tree

    t = tree(np.random.default_rng(0), 10.0)
    world = toy_world([t.transformed(np.diag([1.0, 1.0, 1.0, 1.0]) @ _shift(30.0, 0.0))], small_cfg)
    ren = Renderer(world, small_cfg)
    T = look_at([30.0, 0.0, 60.0], [30.0, 0.0001, 0.0])
    pts = ren.lidar_scan(T, 0.05, 50.0, np.random.default_rng(2))
    under = np.hypot(pts[:, 0] - 30.0, pts[:, 1]) < 1.5  # under the crown
    ground = under & (pts[:, 2] < 0.1)
    crown = under & (pts[:, 2] > 4.0)
    assert ground.sum() > 0.05 * under.sum()  # some beams reach the ground through gaps
    assert crown.sum() > 0.3 * under.sum()  # most are returned by the crown


def _shift(x, y):
    T = np.eye(4)
    T[:2, 3] = (x, y)
    return T
