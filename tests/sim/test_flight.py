import numpy as np
import pytest

from atr.io.mesh import load_mesh, save_mesh
from atr.sim import build_world, scenario, simulate_flight
from atr.sim.render import project
from atr.sim.scenarios import custom_scenario
from atr.sim.vehicles import truck_6x6


def _frames(cfg, seed, **kw):
    return list(simulate_flight(scenario(1, 3), seed=seed, frames=2, config=cfg, **kw))


def _sig(frames):
    parts = []
    for f in frames:
        parts += [
            f.image.tobytes(),
            f.imu_t_ns.tobytes(),
            f.gyro_radps.tobytes(),
            f.accel_mps2.tobytes(),
            f.T_world_cam.tobytes(),
            f.lidar_points_m.tobytes() if f.lidar_points_m is not None else b"",
        ]
        parts += [t.T_world_target.tobytes() + repr(t.visible_fraction).encode() for t in f.targets]
    return b"".join(parts)


def test_same_seed_identical_bytes_different_seed_different_world(small_cfg, world_s1r3):
    a = _frames(small_cfg, 0, lidar=True, noise="shot,gaussian:10", world=world_s1r3)
    b = _frames(small_cfg, 0, lidar=True, noise="shot,gaussian:10")  # world rebuilt from the seed
    assert _sig(a) == _sig(b)
    other = build_world(scenario(1, 3), 1, config=small_cfg)
    assert not np.allclose(other.T_world_target, world_s1r3.T_world_target)
    assert other.static.n_triangles != world_s1r3.static.n_triangles or not np.array_equal(
        other.static.vertices, world_s1r3.static.vertices
    )
    c = _frames(small_cfg, 1, world=other)
    assert c[0].image.tobytes() != a[0].image.tobytes()


def test_frame_contents_and_imu_batches(small_cfg, world_s1r3):
    sc = scenario(1, 3)
    fr = list(simulate_flight(sc, seed=0, frames=3, config=small_cfg, world=world_s1r3))
    per = round(small_cfg.frame_interval_s(sc.range_m) * small_cfg.imu_rate_hz)
    assert [len(f.imu_t_ns) for f in fr] == [1, per, per]
    assert fr[1].imu_t_ns[-1] == fr[1].stamp_ns and fr[2].imu_t_ns[0] > fr[1].stamp_ns
    step_ns = round(1e9 / small_cfg.imu_rate_hz)
    assert np.all(np.diff(np.concatenate([f.imu_t_ns for f in fr])) == step_ns)
    for f in fr:
        assert f.image.shape == (240, 320, 3) and f.image.dtype == np.uint8
        np.testing.assert_allclose(f.T_world_cam, f.T_world_imu @ small_cfg.T_imu_cam_matrix)
        assert f.targets[0].name == "t72" and f.targets[0].visible_fraction > 0.5
        assert f.lidar_points_m is None
    # frames and truth are a pure function of (scenario, seed): a shorter flight is a prefix
    fr2 = list(simulate_flight(sc, seed=0, frames=2, config=small_cfg, world=world_s1r3))
    assert _sig(fr2) == _sig(fr[:2])


def test_target_mesh_file_appears_in_frame_and_truth(small_cfg, tmp_path):
    path = tmp_path / "truck.obj"
    save_mesh(truck_6x6(), path)
    mesh = load_mesh(path)
    sc = custom_scenario(50.0, 30.0, n_scenes=1)
    world = build_world(sc, 4, target_mesh=mesh, target_name="truck", config=small_cfg)
    f = next(simulate_flight(sc, seed=4, frames=1, config=small_cfg, world=world))
    assert [t.name for t in f.targets] == ["truck"]
    assert f.targets[0].visible_fraction > 0.8
    T = f.targets[0].T_world_target
    lo, hi = mesh.bounds()
    centre = T[:3, :3] @ (0.5 * (lo + hi)) + T[:3, 3]
    u, v = project(centre[None], f.K, f.T_world_cam)[0]
    assert 0 <= u < 320 and 0 <= v < 240
    # a loaded mesh gets the default material: the pixels at the truck differ from the ground around
    # it
    r = 4
    patch = f.image[int(v) - r : int(v) + r, int(u) - r : int(u) + r].reshape(-1, 3).mean(axis=0)
    ring = f.image[int(v) - 30 : int(v) + 30, int(u) - 30 : int(u) + 30].reshape(-1, 3).mean(axis=0)
    assert np.abs(patch - ring).max() > 3.0


def test_bad_frames_argument(small_cfg, world_s1r3):
    from atr.errors import ConfigError

    with pytest.raises(ConfigError):
        next(simulate_flight(scenario(1, 3), frames=0, config=small_cfg, world=world_s1r3))


def test_target_mesh_with_origin_above_its_base_stands_on_the_ground(small_cfg):
    from atr.sim.mesh import pose

    lifted = truck_6x6().transformed(pose(None, (0.0, 0.0, -1.5)))  # origin 1.5 m above the wheels
    sc = custom_scenario(50.0, 30.0, n_scenes=1)
    world = build_world(sc, 4, target_mesh=lifted, config=small_cfg)
    assert world.target.bounds()[0][2] == pytest.approx(0.0, abs=1e-9)
    assert world.T_world_target[2, 3] == pytest.approx(1.5)


def test_world_lists_where_its_vehicles_stand(world_s1r3):
    vehicles = world_s1r3.vehicles
    names = [v.name for v in vehicles]
    confusers = [n for n in names if n != "car"]
    # each confuser once at most (one standing inside the run's occluder building is removed with it)
    assert sorted(set(confusers)) == sorted(confusers) and 0 < len(confusers) <= 2
    assert set(confusers) <= {"ifv", "truck6x6"} and "car" in names
    target_xy = world_s1r3.T_world_target[:2, 3]
    static = world_s1r3.static.vertices
    for v in vehicles:
        xy = np.asarray(v.position_m[:2])
        if v.name != "car":
            # confusers stand on open ground 14 m or more from the target (docs/sim.md)
            assert np.linalg.norm(xy - target_xy) >= 14.0
        # the static mesh has the vehicle's body there: vertices within its radius, above its base
        near = static[np.linalg.norm(static[:, :2] - xy, axis=1) <= v.radius_m]
        assert (near[:, 2] > v.position_m[2] + 1.0).any(), v


def test_clutter_meshes_are_listed_by_their_index(small_cfg):
    sc = custom_scenario(50.0, 30.0, n_scenes=1)
    world = build_world(sc, 4, clutter_meshes=[truck_6x6()], config=small_cfg)
    assert "clutter-0" in [v.name for v in world.vehicles]


def test_unrendered_frame_keeps_imu_and_truth(small_cfg, world_s1r3):
    from atr.sim.flight import FlightSimulator
    from atr.sim.noise import parse_noise

    sim = FlightSimulator(scenario(1, 3), world_s1r3, small_cfg, seed=0, frames=2)
    noise = parse_noise("gaussian:10")
    shown = sim.frame(1, lidar=True, noise=noise)
    skipped = sim.frame(1, lidar=True, noise=noise, rendered=False)
    assert skipped.image.shape == (0, 0, 3) and skipped.lidar_points_m is None
    assert shown.image.shape == (240, 320, 3) and shown.lidar_points_m is not None
    shown.image, shown.lidar_points_m = skipped.image, None
    assert _sig([shown]) == _sig([skipped])


def test_navigation_fix_errors_wander_with_their_std_and_correlation():
    from atr.sim.config import SimConfig
    from atr.sim.flight import nav_fix_errors
    from atr.sim.noise import GNSS_INS_ERRORS as E

    cfg = SimConfig(**E, nav_error_correlation_s=2.0)
    e = nav_fix_errors(40000, 0.5, cfg, np.random.default_rng(0))
    tilt, heading = E["nav_tilt_sigma_deg"], E["nav_heading_sigma_deg"]
    expected = np.r_[
        [E["nav_position_sigma_m"]] * 2,
        E["nav_altitude_sigma_m"],
        [E["nav_velocity_sigma_mps"]] * 3,
        np.radians([tilt, tilt, heading]),
    ]
    assert np.allclose(e.std(axis=0), expected, rtol=0.05)
    lag1 = [np.corrcoef(e[:-1, i], e[1:, i])[0, 1] for i in range(9)]
    assert np.allclose(lag1, np.exp(-0.5 / 2.0), atol=0.02)  # Gauss-Markov, not white


def test_a_noisy_navigation_fix_leaves_every_sensor_and_the_truth_unchanged(small_cfg, world_s1r3):
    import dataclasses

    from atr.sim.flight import FlightSimulator

    noisy_cfg = dataclasses.replace(small_cfg, nav_position_sigma_m=2.0, nav_heading_sigma_deg=0.5)
    exact = FlightSimulator(scenario(1, 3), world_s1r3, small_cfg, seed=0, frames=2).frame(1)
    noisy = FlightSimulator(scenario(1, 3), world_s1r3, noisy_cfg, seed=0, frames=2).frame(1)
    assert _sig([noisy]) == _sig([exact])  # images, IMU, truth: the same draws
    T_exact, v_exact = exact.nav_fix()
    assert T_exact is exact.T_world_imu and v_exact is exact.v_world_imu_mps  # no errors: the truth
    T_nav, v_nav = noisy.nav_fix()
    assert 0.0 < np.linalg.norm(T_nav[:2, 3] - exact.T_world_imu[:2, 3]) < 20.0
    assert T_nav[2, 3] == exact.T_world_imu[2, 3]  # no altitude error asked for
    assert np.allclose(T_nav[:3, :3] @ T_nav[:3, :3].T, np.eye(3))
    assert not np.allclose(T_nav[:3, :3], exact.T_world_imu[:3, :3])


@pytest.mark.parametrize("field", ["nav_tilt_sigma_deg", "nav_error_correlation_s"])
def test_bad_navigation_errors_are_refused_by_name(field):
    from atr.errors import ConfigError
    from atr.sim.config import SimConfig

    with pytest.raises(ConfigError, match=field):
        SimConfig(**{field: -1.0})
